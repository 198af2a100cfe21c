"""Property tests: valid lias-planar-uwb files, mutated at random (lines deleted, duplicated or
swapped, the file truncated, characters replaced, garbage fields inserted), make every reader
and loader either succeed with consistent output or raise DataFormatError - nothing else."""

import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from tests.fixtures import lias as fx
from uwbwb import DataFormatError
from uwbwb.datasets import lias

FUZZ = settings(max_examples=60, deadline=None)
CHARS = list("0123456789.,:- \n") + ["x", "e", "+", ";", "é", "\r", "|", "#"]
GARBAGE = ["", "abc", "1.5", "-2", "nan", "inf", "1e999", " ", "0", "652.8", "2022-08-15 9:00:00.000"]


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    root = tmp_path_factory.mktemp("lias_fuzz")
    rng = np.random.default_rng(11)
    fx.make_tree(root, rng=rng, sessions=[fx.session_814(rng, files=((1, 0), (2, 120)))], static_rows=30,
                 dynamic={"fast": dict(duration_s=4.0, uwb_rate_hz=25.0, mocap_rate_hz=30.0,
                                       clock_offset_s=0.2, mocap_lead_s=0.5, mocap_tail_s=0.5)})
    planar = root / "lias-planar-uwb" / "Planar_Dataset"
    return {
        "root": root,
        "uwb": planar / "Dynamic/UWB_dynamic_exp_fast.csv",
        "mocap": planar / "Dynamic/motion_capture_dynamic_exp_fast.csv",
        "dyn_readme": planar / "Dynamic/README.md",
        "static": planar / "Static/8.14/UWB_static_exp_8_14_pos2_deg_120.csv",
        "static_readme": planar / "Static/README.md",
    }


def mutate(text: str, data) -> str:
    """Apply one to three random edits to ``text``."""
    for _ in range(data.draw(st.integers(1, 3), label="n_edits")):
        lines = text.split("\n")
        kind = data.draw(st.sampled_from(["delete", "duplicate", "swap", "truncate", "replace",
                                          "insert_field"]), label="edit")
        i = data.draw(st.integers(0, len(lines) - 1), label="line")
        if kind == "delete":
            del lines[i]
        elif kind == "duplicate":
            lines.insert(i, lines[i])
        elif kind == "swap":
            j = data.draw(st.integers(0, len(lines) - 1), label="other line")
            lines[i], lines[j] = lines[j], lines[i]
        elif kind == "insert_field":
            fields = lines[i].split(",")
            k = data.draw(st.integers(0, len(fields)), label="field")
            fields.insert(k, data.draw(st.sampled_from(GARBAGE), label="garbage"))
            lines[i] = ",".join(fields)
        text = "\n".join(lines)
        if kind == "truncate":
            text = text[: data.draw(st.integers(0, len(text)), label="cut")]
        elif kind == "replace" and text:
            k = data.draw(st.integers(0, len(text) - 1), label="char")
            text = text[:k] + data.draw(st.sampled_from(CHARS), label="new char") + text[k + 1:]
    return text


def _write_mutant(src: Path, data, dest: Path) -> Path:
    dest.write_text(mutate(src.read_text(encoding="utf-8"), data), encoding="utf-8")
    return dest


def _check_range_log(log, n_anchors):
    assert log.range_m.shape == (log.t_s.size, n_anchors)
    assert np.all(np.diff(log.t_s) > 0) and np.all(np.isfinite(log.t_s))
    r = log.range_m[np.isfinite(log.range_m)]
    assert np.all(r >= 0)


@FUZZ
@given(data=st.data())
def test_read_uwb_csv_mutants(base, data):
    with tempfile.TemporaryDirectory() as tmp:
        path = _write_mutant(base["uwb"], data, Path(tmp) / "UWB_dynamic_exp_fuzz.csv")
        try:
            t_s, r, t0 = lias.read_uwb_csv(path)
        except DataFormatError as err:
            assert str(path) in str(err)
            event(f"DataFormatError: {err.problem[:40]}")
            return
    event("loaded")
    assert t_s.ndim == 1 and r.shape == (t_s.size, 8, 3) and t_s.size > 0
    assert np.all(np.diff(t_s) > 0) and np.all(np.isfinite(t_s))
    assert not np.any(np.isinf(r)) and np.all(r[np.isfinite(r)] > 0)


@FUZZ
@given(data=st.data())
def test_read_mocap_csv_mutants(base, data):
    with tempfile.TemporaryDirectory() as tmp:
        path = _write_mutant(base["mocap"], data, Path(tmp) / "motion_capture_dynamic_exp_fuzz.csv")
        try:
            t_s, pos, quat, t0 = lias.read_mocap_csv(path)
        except DataFormatError as err:
            assert str(path) in str(err)
            event(f"DataFormatError: {err.problem[:40]}")
            return
    event("loaded")
    assert pos.shape == (t_s.size, 3) and quat.shape == (t_s.size, 4) and t_s.size > 0
    assert np.all(np.diff(t_s) > 0) and np.all(np.isfinite(pos))
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=0.011)


def _in_copy(base, key, data, load):
    """Mutate one file of a copy of the base tree and run ``load(data_dir)`` on it."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "data"
        shutil.copytree(base["root"], root)
        target = root / base[key].relative_to(base["root"])
        _write_mutant(base[key], data, target)
        try:
            out = load(root)
        except DataFormatError as err:
            event(f"DataFormatError: {err.problem[:40]}")
            return None
    event("loaded")
    return out


@FUZZ
@given(data=st.data(), key=st.sampled_from(["uwb", "mocap", "dyn_readme"]))
def test_load_dynamic_mutants(base, data, key):
    rec = _in_copy(base, key, data, lambda root: lias.load_dynamic("fast", root))
    if rec is None:
        return
    assert rec.tags and set(rec.truth) == set(rec.ranges)
    for tag in rec.tags:
        log, truth = rec.ranges[tag], rec.truth[tag]
        _check_range_log(log, len(rec.anchors))
        assert truth.t_s.size > 0 and np.all(np.isfinite(truth.pos_m))
        assert log.t_s[0] <= truth.t_s[0] and truth.t_s[-1] <= log.t_s[-1]
    assert np.isfinite(rec.meta["clock_offset_s"])


@FUZZ
@given(data=st.data(), key=st.sampled_from(["static", "static_readme"]))
def test_load_static_mutants(base, data, key):
    recs = _in_copy(base, key, data, lambda root: lias.load_static("8.14", root))
    if recs is None:
        return
    assert [r.name for r in recs] == ["8.14/pos1_deg_0", "8.14/pos2_deg_120"]
    for rec in recs:
        for tag in rec.tags:
            _check_range_log(rec.ranges[tag], len(rec.anchors))
            np.testing.assert_array_equal(rec.truth[tag].t_s, rec.ranges[tag].t_s)
            assert np.all(np.isfinite(rec.truth[tag].pos_m))
