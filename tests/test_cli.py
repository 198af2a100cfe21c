"""Command line: ``datasets`` on a temporary data dir, ``fetch`` from a local server, argument errors."""

from __future__ import annotations

import json
import sys
import types

import numpy as np
import pandas as pd
import pytest

from tests.datasets.test_fetch import serving
from uwbwb import cli
from uwbwb import reproduce as rp
from uwbwb.datasets import manifest as mf

TREES = {
    "toy-a": {"README.md": b"# a\n", "run1.csv": b"1,2\n3,4\n", "run2.csv": b"5,6\n", "sub/run3.csv": b"7\n"},
    "toy-b": {"README.md": b"# b\n", "x.csv": b"0\n"},
    "toy-c": {"README.md": b"# c\n"},
}
FAKE_LOADER = "fake_toy_loader_for_cli_tests"


def _info(name, loader):
    return {"repository": f"https://example.org/{name}", "license": "MIT", "redistributable": name != "toy-b",
            "base_url": f"https://example.org/{name}/raw/", "citation": f"{name} et al.", "loader": loader,
            "note": f"{name} is for evaluation only"}


@pytest.fixture
def toy_project(tmp_path, monkeypatch):
    """A manifest + metadata for three toy datasets, of which the data dir holds two."""
    published = tmp_path / "published"
    for name, files in TREES.items():
        for rel, data in files.items():
            (published / name / rel).parent.mkdir(parents=True, exist_ok=True)
            (published / name / rel).write_bytes(data)
    datasets_json = tmp_path / "datasets.json"
    datasets_json.write_text(json.dumps({"datasets": {
        "toy-a": _info("toy-a", FAKE_LOADER), "toy-b": _info("toy-b", "uwbwb.datasets.no_such_loader"),
        "toy-c": _info("toy-c", "")}}))
    monkeypatch.setattr(mf, "DATASETS_PATH", datasets_json)
    manifest_csv = tmp_path / "manifest.csv"
    mf.build(published, manifest_csv)
    monkeypatch.setattr(mf, "MANIFEST_PATH", manifest_csv)

    data = tmp_path / "data"
    for name in ("toy-a", "toy-b"):
        for rel, payload in TREES[name].items():
            (data / name / rel).parent.mkdir(parents=True, exist_ok=True)
            (data / name / rel).write_bytes(payload)

    calls = []
    loader = types.ModuleType(FAKE_LOADER)
    loader.NAME = "toy-a"

    def list_recordings(data_dir=None):
        calls.append(data_dir)
        root = data_dir / "toy-a"
        return pd.DataFrame({"name": ["run1", "run2", "sub/run3"], "duration_s": [1.5, 2.0, float("nan")],
                             "path": [root / "run1.csv", root / "run2.csv", root / "sub" / "run3.csv"]})

    loader.list_recordings = list_recordings
    monkeypatch.setitem(sys.modules, FAKE_LOADER, loader)
    return types.SimpleNamespace(data=data, published=published, manifest=manifest_csv, loader_calls=calls)


def _sections(text):
    """Output of ``datasets`` split into {dataset name: its lines}."""
    out, name = {}, None
    for line in text.splitlines():
        if line and not line.startswith(" "):
            name = line.strip()
            out[name] = []
        elif name and line:
            out[name].append(line.strip())
    return out


def test_datasets_reports_location_checksums_and_recordings(toy_project, capsys):
    (toy_project.data / "toy-a" / "run2.csv").unlink()
    (toy_project.data / "toy-a" / "run1.csv").write_bytes(b"1,2\n3,5\n")  # same size, other bytes
    code = cli.main(["datasets", "--data-dir", str(toy_project.data)])
    out = _sections(capsys.readouterr().out)
    assert code == 1  # a file is missing and one differs
    a, b, c = out["toy-a"], out["toy-b"], out["toy-c"]
    assert f"found:      {toy_project.data / 'toy-a'}  [DATA_DIR argument]" in a
    assert "checksums:  2 ok, 1 missing, 1 mismatch (of 4 files in the manifest)" in a
    assert "missing: run2.csv" in a and "sha_mismatch: run1.csv" in a
    assert "recordings: 3 (paths relative to the dataset root)" in a
    assert "name      duration_s  path" in a
    assert "run1             1.5  run1.csv" in a
    assert "sub/run3              sub/run3.csv" in a  # NaN shown blank
    assert toy_project.loader_calls == [toy_project.data]
    assert "checksums:  2 ok, 0 missing, 0 mismatch (of 2 files in the manifest)" in b
    assert any("recording listing unavailable" in line and "no_such_loader" in line for line in b)
    assert "note:       toy-b is for evaluation only" in b  # not redistributable
    assert any(line.startswith("found:      not found") and "fetch toy-c" in line for line in c)


def test_datasets_all_ok_exits_zero_and_no_verify_checks_presence_only(toy_project, capsys):
    assert cli.main(["datasets", "--data-dir", str(toy_project.published)]) == 0
    out = _sections(capsys.readouterr().out)
    assert "checksums:  1 ok, 0 missing, 0 mismatch (of 1 files in the manifest)" in out["toy-c"]
    assert any("recording listing unavailable (no loader registered" in line for line in out["toy-c"])

    (toy_project.published / "toy-a" / "run1.csv").write_bytes(b"changed\n")
    (toy_project.published / "toy-b" / "x.csv").unlink()
    assert cli.main(["datasets", "--no-verify", "--data-dir", str(toy_project.published)]) == 1
    out = _sections(capsys.readouterr().out)
    assert "files:      4 of 4 present (checksums not verified)" in out["toy-a"]
    assert "files:      1 of 2 present (checksums not verified)" in out["toy-b"]
    assert "missing: x.csv" in out["toy-b"]


def test_datasets_listing_is_shortened_unless_all(toy_project, capsys, monkeypatch):
    monkeypatch.setattr(cli, "MAX_RECORDINGS_SHOWN", 2)
    cli.main(["datasets", "--no-verify", "--data-dir", str(toy_project.data)])
    a = _sections(capsys.readouterr().out)["toy-a"]
    assert "... and 1 more (--all lists every one)" in a and not any(line.startswith("sub/run3") for line in a)
    cli.main(["datasets", "--no-verify", "--all", "--data-dir", str(toy_project.data)])
    a = _sections(capsys.readouterr().out)["toy-a"]
    assert any(line.startswith("sub/run3") for line in a) and not any("more" in line for line in a)


def test_datasets_survives_a_loader_that_raises(toy_project, capsys):
    def broken(data_dir=None):
        raise ValueError("cannot parse anything")

    sys.modules[FAKE_LOADER].list_recordings = broken
    cli.main(["datasets", "--no-verify", "--data-dir", str(toy_project.data)])
    a = _sections(capsys.readouterr().out)["toy-a"]
    assert any("recording listing failed" in line and "cannot parse anything" in line for line in a)


def test_datasets_with_the_committed_manifest_on_an_empty_dir(tmp_path, capsys):
    assert cli.main(["datasets", "--data-dir", str(tmp_path)]) == 1
    out = _sections(capsys.readouterr().out)
    assert set(out) == {"lias-planar-uwb", "iasl-uwb-imu", "hanyang-outdoor-uwb"}
    for name, lines in out.items():
        assert any(line.startswith("found:      not found") for line in lines), name


@pytest.fixture
def server():
    with serving(dict(TREES["toy-a"])) as srv:
        yield srv


def test_fetch_command_downloads_and_reports(toy_project, server, tmp_path, capsys):
    dest = tmp_path / "fetched"
    code = cli.main(["fetch", "toy-a", "--dest", str(dest), "--base-url", server.base_url, "--quiet"])
    out = capsys.readouterr().out
    assert code == 0
    assert "toy-a: 4 file(s) downloaded" in out and "cite: toy-a et al." in out
    assert (dest / "toy-a" / "sub" / "run3.csv").read_bytes() == TREES["toy-a"]["sub/run3.csv"]

    server.not_found.add("run2.csv")
    (dest / "toy-a" / "run2.csv").unlink()
    assert cli.main(["fetch", "toy-a", "--dest", str(dest), "--base-url", server.base_url, "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "error: run2.csv: HTTP 404" in err and f"{server.base_url}run2.csv" in err


@pytest.mark.parametrize("argv, message", [
    ([], "usage:"),
    (["nonsense"], "invalid choice"),
    (["fetch"], "the following arguments are required: NAME"),
    (["fetch", "no-such-dataset"], "unknown dataset 'no-such-dataset'; choose from: lias-planar-uwb"),
    (["fetch", "iasl-uwb-imu", "--timeout", "0"], "must be positive"),
    (["datasets", "--bogus"], "unrecognized arguments: --bogus"),
    (["reproduce", "-p", "N"], "expected 2 arguments"),
    (["reproduce", "-p", "2x", "1"], "parameter names must be Python identifiers"),
    (["reproduce", "-p", "SUMMARY_PATH", "x.json"], "set by the runner"),
    (["reproduce", "--timeout", "soon"], "expected seconds"),
    (["reproduce", "--only", "zz"], "no notebook matches 'zz'"),
])
def test_argument_errors_exit_2_with_a_message(argv, message, capsys, tmp_path, monkeypatch):
    (tmp_path / "00_quickstart.ipynb").write_text("{}")
    monkeypatch.setattr(rp, "NOTEBOOKS_DIR", tmp_path)
    assert cli.main(argv) == 2
    assert message in capsys.readouterr().err


def test_help_exits_zero(capsys):
    assert cli.main(["--help"]) == 0
    assert "reproduce" in capsys.readouterr().out


def test_score_prints_no_runtime_warning_on_sound_recordings(tmp_path, capsys):
    """A sound recording, with and without an IMU, scores with no RuntimeWarning reaching the console (an empty
    slice, a division by zero or an invalid value inside a method would print one to every user)."""
    import warnings

    from tests.fixtures import iasl as fx
    from uwbwb.datasets import tidy
    from uwbwb.scoreboard import synthetic as syn

    from dataclasses import replace

    from uwbwb.types import Trajectory

    rec = syn.simulate(syn.SyntheticConfig(duration_s=30.0), rng=np.random.default_rng(5))
    tr = rec.truth["tag"]
    tidy.write_recording(replace(rec, truth={"tag": Trajectory(tr.t_s, tr.pos_m, name="truth")}), tmp_path / "run")
    fx.write_dataset(tmp_path / "iasl-uwb-imu", rng=np.random.default_rng(6), duration_s=40.0)
    runs = (["score", str(tmp_path / "run"), "--rate-hz", "5"],
            ["score", "iasl-uwb-imu/scenario2", "--calibrate-on", "iasl-uwb-imu/scenario1", "--data-dir", str(tmp_path),
             "--methods", "LS", "EKF-RF", "loose", "tight"])
    for k, argv in enumerate(runs):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert cli.main([*argv, "--out", str(tmp_path / f"out{k}"), "--fast", "--quiet"]) == 0, capsys.readouterr().err
        assert not [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)], argv
        assert "Warning" not in capsys.readouterr().err


def test_score_puts_the_authors_estimates_of_a_hanyang_case_folder_on_the_board_as_external_rows(tmp_path, capsys):
    """A Hanyang case folder (or its name) brings the dataset authors' LS and ESKF: external rows of the board,
    scored beside the methods asked for, their numbers *input*."""
    from tests.fixtures import hanyang as fx

    cases = fx.write_dynamic_tree(tmp_path / "hanyang-outdoor-uwb", rng=np.random.default_rng(8),
                                  cases=fx.DYNAMIC_CASES[:1], speed_mps=4.0)
    for k, target in enumerate((str(cases[0].folder), f"hanyang-outdoor-uwb/{cases[0].name}")):
        out = tmp_path / f"out{k}"
        assert cli.main(["score", target, "--data-dir", str(tmp_path), "--methods", "raw LS", "--fast", "--quiet",
                         "--out", str(out)]) == 0, capsys.readouterr().err
        board = pd.read_csv(out / "scoreboard.csv").set_index("method")
        theirs = ["authors LS (external)", "authors ESKF (external, +IMU)"]
        assert list(board.index) == ["raw LS", *theirs]
        assert (board.loc[theirs, "n_scored"] > 0).all() and set(board.loc[theirs, "kind"]) == {"input"}
        assert board.loc["raw LS", "kind"] == "reproduced"
