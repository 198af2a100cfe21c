"""Manifest: building, reading, validation and verification of dataset files."""

from __future__ import annotations

import hashlib

import pandas as pd
import pytest

from tests.conftest import real_dataset
from uwbwb.datasets import manifest as mf
from uwbwb.errors import DataFormatError

SYNTHETIC = {
    "toy-a": {"README.md": b"# toy a\n", "sub/x.csv": b"1,2,3\n4,5,6\n", "sub/deep/y.csv": bytes(range(256)) * 9,
              "empty.txt": b""},
    "toy-b": {"LICENSE": b"MIT\n", "data b/z 1.csv": b"t,range_m\n0.0,1.5\n"},
}


def _write_tree(base, trees=SYNTHETIC):
    for name, files in trees.items():
        for rel, data in files.items():
            path = base / name / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
    return base


@pytest.fixture
def src(tmp_path):
    return _write_tree(tmp_path / "src")


@pytest.fixture
def built(src, tmp_path):
    out = tmp_path / "manifest.csv"
    mf.build(src, out, datasets=["toy-a", "toy-b"])
    return out


def test_build_lists_every_file_with_size_and_sha(built):
    df = mf.load_manifest(built)
    assert tuple(df.columns) == mf.COLUMNS
    assert df["size_bytes"].dtype == "int64"
    for name, files in SYNTHETIC.items():
        rows = df[df["dataset"] == name].set_index("path")
        assert sorted(rows.index) == sorted(files)
        assert list(df.loc[df["dataset"] == name, "path"]) == sorted(files)  # deterministic order
        for rel, data in files.items():
            assert rows.at[rel, "size_bytes"] == len(data)
            assert rows.at[rel, "sha256"] == hashlib.sha256(data).hexdigest()


def test_build_one_dataset_keeps_the_other_rows(src, built):
    (src / "toy-b" / "LICENSE").write_bytes(b"Apache-2.0\n")
    mf.build(src, built, datasets=["toy-b"])
    df = mf.load_manifest(built)
    assert set(df["dataset"]) == {"toy-a", "toy-b"}
    assert (df["dataset"] == "toy-a").sum() == len(SYNTHETIC["toy-a"])
    lic = df[(df["dataset"] == "toy-b") & (df["path"] == "LICENSE")]
    assert lic["sha256"].item() == hashlib.sha256(b"Apache-2.0\n").hexdigest()


def test_build_refuses_partial_downloads_and_missing_folders(src, tmp_path):
    (src / "toy-a" / "sub" / "x.csv.part").write_bytes(b"1,2")
    with pytest.raises(ValueError, match=r"x\.csv\.part.*partial download"):
        mf.build(src, tmp_path / "m.csv", datasets=["toy-a"])
    with pytest.raises(ValueError, match="lacks dataset folder.*toy-c"):
        mf.build(src, tmp_path / "m.csv", datasets=["toy-c"])


def test_maintainer_command_builds(src, tmp_path, capsys):
    out = tmp_path / "cmd.csv"
    assert mf._main(["build", str(src), "--out", str(out), "--dataset", "toy-a", "--dataset", "toy-b"]) == 0
    assert len(mf.load_manifest(out)) == sum(map(len, SYNTHETIC.values()))
    assert "wrote" in capsys.readouterr().out
    assert mf._main(["build", str(tmp_path / "nowhere"), "--out", str(out)]) == 1
    assert "lacks dataset folder" in capsys.readouterr().err


def test_verify_reports_each_status(src, built):
    root = src / "toy-a"
    (root / "README.md").unlink()                               # missing
    (root / "sub" / "x.csv").write_bytes(b"1,2,3\n")            # wrong size
    y = root / "sub" / "deep" / "y.csv"
    data = bytearray(y.read_bytes())
    data[100] ^= 0xFF
    y.write_bytes(bytes(data))                                  # same size, other bytes
    report = mf.verify("toy-a", root, manifest=built).set_index("path")
    assert report.at["README.md", "status"] == "missing"
    assert pd.isna(report.at["README.md", "actual_size_bytes"])
    assert report.at["sub/x.csv", "status"] == "size_mismatch"
    assert report.at["sub/x.csv", "actual_size_bytes"] == 6
    assert report.at["sub/deep/y.csv", "status"] == "sha_mismatch"
    assert report.at["empty.txt", "status"] == "ok"
    assert list(report["status"].cat.categories) == list(mf.STATUSES)


def test_verify_ignores_extra_files_and_rejects_unknown_dataset(src, built):
    (src / "toy-b" / "mine.csv").write_text("extra\n")
    report = mf.verify("toy-b", src / "toy-b", manifest=built)
    assert (report["status"] == "ok").all() and "mine.csv" not in set(report["path"])
    with pytest.raises(ValueError, match="unknown dataset 'nope'.*toy-a, toy-b"):
        mf.verify("nope", src, manifest=built)


GOOD_SHA = "0" * 64


@pytest.mark.parametrize("body, problem, line", [
    ("dataset,path,size\n", "header must be", 1),
    (f"d,a.csv,1,{GOOD_SHA}\nd,/abs.csv,1,{GOOD_SHA}\n", "must be relative", 3),
    (f"d,a/../b.csv,1,{GOOD_SHA}\n", r"'\.\.' component", 2),
    (f"d,a\\b.csv,1,{GOOD_SHA}\n", "forward slashes", 2),
    (f"d,a.csv,-1,{GOOD_SHA}\n", "non-negative integer", 2),
    (f"d,a.csv,1.5,{GOOD_SHA}\n", "non-negative integer", 2),
    ("d,a.csv,1,ABC\n", "64 lowercase hex", 2),
    (f"d,a.csv,1,{GOOD_SHA}\nd,a.csv,1,{GOOD_SHA}\n", "duplicate row for d/a.csv", 3),
    (f",a.csv,1,{GOOD_SHA}\n", "empty dataset name", 2),
])
def test_load_manifest_rejects_bad_rows_naming_the_line(tmp_path, body, problem, line):
    path = tmp_path / "bad.csv"
    header = "" if body.startswith("dataset,") else "dataset,path,size_bytes,sha256\n"
    path.write_text(header + body)
    with pytest.raises(DataFormatError, match=problem) as info:
        mf.load_manifest(path)
    assert info.value.line == line and info.value.path == path


def test_committed_manifest_and_metadata_agree():
    df = mf.load_manifest()
    infos = mf.load_datasets_info()
    assert list(dict.fromkeys(df["dataset"])) == list(infos) == [
        "lias-planar-uwb", "iasl-uwb-imu", "hanyang-outdoor-uwb"]
    for name, info in infos.items():
        paths = set(df.loc[df["dataset"] == name, "path"])
        assert "README.md" in paths, name
        assert info.base_url.startswith("https://") and info.base_url.endswith("/")
        assert info.citation and info.loader.startswith("uwbwb.datasets.")
    assert not infos["iasl-uwb-imu"].redistributable
    assert infos["lias-planar-uwb"].license == "MIT" and infos["hanyang-outdoor-uwb"].license == "Apache-2.0"
    assert {"LICENSE", "Planar_Dataset/Static/README.md"} <= set(df.loc[df["dataset"] == "lias-planar-uwb", "path"])
    assert "uwb.yaml" in set(df.loc[df["dataset"] == "iasl-uwb-imu", "path"])


def test_datasets_json_errors_name_the_problem(tmp_path):
    path = tmp_path / "d.json"
    path.write_text('{"datasets": {"x": {"repository": "r"}}}')
    with pytest.raises(DataFormatError, match="dataset 'x': missing keys"):
        mf.load_datasets_info(path)
    path.write_text('{"datasets": ')
    with pytest.raises(DataFormatError, match="invalid JSON"):
        mf.load_datasets_info(path)


@pytest.mark.realdata
@pytest.mark.parametrize("name", ["lias-planar-uwb", "iasl-uwb-imu", "hanyang-outdoor-uwb"])
def test_real_dataset_matches_manifest(name):
    root = real_dataset(name)
    report = mf.verify(name, root)
    bad = report[report["status"] != "ok"]
    assert bad.empty, f"{name} at {root}:\n{bad.to_string(index=False)}"
