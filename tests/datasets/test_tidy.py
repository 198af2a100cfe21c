"""Tests of the generic tidy CSV format (uwbwb.datasets.tidy)."""

from __future__ import annotations

import dataclasses
import filecmp
import re
from pathlib import Path

import numpy as np
import pytest

from tests.fixtures.iasl import write_tidy_sample
from uwbwb import Anchors, DataFormatError, RangeLog, Recording, Trajectory
from uwbwb.datasets import PROJECT_ROOT, tidy

SAMPLE = PROJECT_ROOT / "data" / "samples" / "tidy"

ANCHORS = "anchor_id,x_m,y_m,z_m\nA1,0,0,0\nA2,5,0,0\nA10,0,5,2.5\n"


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def assert_error_at(excinfo, path: Path, line: int | None) -> None:
    msg = str(excinfo.value)
    assert str(path) in msg
    if line is not None:
        assert excinfo.value.line == line
        assert f"line {line}" in msg


def random_recording(rng: np.random.Generator) -> Recording:
    anchors = Anchors(("A1", "A2", "A10", "b"), rng.normal(0, 5, (4, 3)))
    ranges, truth = {}, {}
    for tag, n in (("t1", 40), ("t 2", 25)):
        t = np.cumsum(rng.uniform(1e-3, 0.2, n)) + rng.uniform(-5, 5)
        r = rng.uniform(0, 30, (n, 4)) * 10.0 ** rng.integers(-3, 3, (n, 4))
        r[rng.random(r.shape) < 0.3] = np.nan
        r[3] = np.nan  # an epoch with no range at all
        r[5, 1] = 0.0
        ranges[tag] = RangeLog(t, r, anchors.ids, tag)
        truth[tag] = Trajectory(t, rng.normal(0, 3, (n, 3)), name="truth")
    return Recording("tidy", "rand", anchors, ranges, truth)


# --- round trip ------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_recording_round_trips_exactly(tmp_path, seed):
    rec = random_recording(np.random.default_rng(seed))
    paths = tidy.write_recording(rec, tmp_path)
    # the random ranges span many magnitudes (exact float text round trip), some beyond MAX_RANGE_M
    back = tidy.load_recording(paths["ranges"], paths["anchors"], paths["truth"], name="rand", max_range_m=np.inf)
    assert back.anchors.ids == rec.anchors.ids
    np.testing.assert_array_equal(back.anchors.pos_m, rec.anchors.pos_m)
    assert set(back.ranges) == set(rec.ranges)
    for tag, log in rec.ranges.items():
        got = back.ranges[tag]
        assert got.anchor_ids == log.anchor_ids and got.tag_id == tag
        np.testing.assert_array_equal(got.t_s, log.t_s)
        np.testing.assert_array_equal(got.range_m, log.range_m)  # NaN pattern included
        np.testing.assert_array_equal(back.truth[tag].pos_m, rec.truth[tag].pos_m)
        np.testing.assert_array_equal(back.truth[tag].t_s, rec.truth[tag].t_s)
    # the empty epochs come back through one ERR row each, counted
    assert [s.n_affected for s in back.cleaning] == [2]


def test_two_dimensional_truth_round_trips(tmp_path):
    traj = Trajectory(np.array([0.0, 0.5, 1.0]), np.array([[1.0, 2.0], [1.5, 2.5], [0.1, 1e-7]]), name="truth")
    path = tidy.write_truth_csv(tmp_path / "truth.csv", traj)
    assert path.read_text().splitlines()[0] == "t_s,x_m,y_m,tag_id"
    back = tidy.read_truth_csv(path)["tag"]
    assert back.dim == 2
    np.testing.assert_array_equal(back.pos_m, traj.pos_m)


def test_writers_refuse_what_the_format_cannot_hold(tmp_path):
    t = np.arange(3.0)
    traj = Trajectory(t, np.zeros((3, 3)), rot=np.broadcast_to(np.eye(3), (3, 3, 3)))
    with pytest.raises(ValueError, match="attitudes"):
        tidy.write_truth_csv(tmp_path / "t.csv", traj)
    tidy.write_truth_csv(tmp_path / "t.csv", dataclasses.replace(traj, rot=None))
    with pytest.raises(ValueError, match="commas"):
        tidy.write_anchors_csv(tmp_path / "a.csv", Anchors(("a,1",), np.zeros((1, 3))))
    with pytest.raises(ValueError, match="identifiers"):
        tidy.write_ranges_csv(tmp_path / "r.csv", RangeLog(t, np.ones((3, 1)), (" a",), "tag"))


# --- reading valid files ---------------------------------------------------------------------

def test_minimal_ranges_file_defaults(tmp_path):
    anchors = tidy.read_anchors_csv(_write(tmp_path, "a.csv", ANCHORS))
    assert anchors.ids == ("A1", "A2", "A10")
    np.testing.assert_array_equal(anchors.pos_m[2], [0, 5, 2.5])
    ranges = _write(tmp_path, "r.csv", "t_s,anchor_id,range_m\n0,A2,1.5\n0,A1,2\n0.1,A10,3\n")
    logs = tidy.read_ranges_csv(ranges, anchors)
    assert list(logs) == ["tag"]
    log = logs["tag"]
    np.testing.assert_array_equal(log.t_s, [0.0, 0.1])
    np.testing.assert_array_equal(log.range_m, [[2.0, 1.5, np.nan], [np.nan, np.nan, 3.0]])
    # without anchors: columns are the identifiers found, in natural order
    assert tidy.read_ranges_csv(ranges)["tag"].anchor_ids == ("A1", "A2", "A10")


def test_err_rows_are_missing_and_counted(tmp_path):
    a = _write(tmp_path, "a.csv", ANCHORS)
    r = _write(tmp_path, "r.csv", "t_s,anchor_id,range_m,status,tag_id\n"
                                  "0,A1,2,OK,x\n0,A2,,ERR,x\n0,A1,7,OK,y\n1,A2,-3,ERR,y\n")
    rec = tidy.load_recording(r, a)
    np.testing.assert_array_equal(rec.ranges["x"].range_m, [[2.0, np.nan, np.nan]])
    np.testing.assert_array_equal(rec.ranges["y"].t_s, [0.0, 1.0])  # the ERR-only epoch exists
    assert np.isnan(rec.ranges["y"].range_m[1]).all()
    assert [(s.name, s.n_affected) for s in rec.cleaning] == [("ERR status rows", 2)]
    logs, cleaning = tidy.read_ranges_csv(r, with_cleaning=True)
    assert cleaning == rec.cleaning


def test_comments_blank_lines_bom_crlf_and_spaces(tmp_path):
    text = "\ufeff# surveyed 2024\r\n\r\nanchor_id, x_m ,y_m,z_m\r\n A1 ,1, 2 ,3\r\n# note\r\nB,4,5,6"
    anchors = tidy.read_anchors_csv(_write(tmp_path, "a.csv", text))
    assert anchors.ids == ("A1", "B")
    np.testing.assert_array_equal(anchors.pos_m, [[1, 2, 3], [4, 5, 6]])


def test_truth_tags_and_load_recording(tmp_path):
    a = _write(tmp_path, "a.csv", ANCHORS)
    r = _write(tmp_path, "r.csv", "t_s,anchor_id,range_m,tag_id\n0,A1,1,p\n0,A1,1,q\n")
    good = _write(tmp_path, "t.csv", "t_s,x_m,y_m,tag_id\n0,1,2,p\n0,3,4,q\n0.5,1,2,p\n")
    rec = tidy.load_recording(r, a, good)
    assert rec.name == "r" and rec.dataset == "tidy"
    np.testing.assert_array_equal(rec.truth["p"].t_s, [0.0, 0.5])
    bad = _write(tmp_path, "t2.csv", "t_s,x_m,y_m,tag_id\n0,1,2,p\n0,3,4,z\n")
    with pytest.raises(DataFormatError) as exc:
        tidy.load_recording(r, a, bad)
    assert_error_at(exc, bad, None)
    assert "'z'" in str(exc.value)


def test_committed_sample_loads_and_regenerates(tmp_path):
    rec = tidy.load_recording(SAMPLE / "ranges.csv", SAMPLE / "anchors.csv", SAMPLE / "truth.csv")
    assert rec.tags == ("front", "back") and len(rec.anchors) == 8
    assert rec.truth["front"].dim == 3
    assert [s.n_affected for s in rec.cleaning] == [1]
    paths = write_tidy_sample(tmp_path)
    for key, path in paths.items():
        assert filecmp.cmp(path, SAMPLE / path.name, shallow=False), f"{path.name} differs from the generator"


# --- every bad input is a DataFormatError naming file and line --------------------------------

RANGES_CASES = {
    "time goes backwards": ("t_s,anchor_id,range_m\n1,A1,1\n0.5,A2,1\n", 3),
    "repeated key": ("t_s,anchor_id,range_m,tag_id\n0,A1,1,t\n0,A2,1,t\n0,A1,2,t\n", 4),
    "unknown anchor": ("t_s,anchor_id,range_m\n0,A1,1\n0,A3,1\n", 3),
    "negative range": ("t_s,anchor_id,range_m\n0,A1,-0.1\n", 2),
    "non-numeric range": ("t_s,anchor_id,range_m\n0,A1,1\n0.1,A1,1.2.3\n", 3),
    "non-numeric time": ("t_s,anchor_id,range_m\nnow,A1,1\n", 2),
    "nan literal": ("t_s,anchor_id,range_m\n0,A1,nan\n", 2),
    "inf literal": ("t_s,anchor_id,range_m\ninf,A1,1\n", 2),
    "too many fields": ("t_s,anchor_id,range_m\n0,A1,1,OK\n", 2),
    "too few fields": ("t_s,anchor_id,range_m,status\n0,A1,1\n", 2),
    "bad status": ("t_s,anchor_id,range_m,status\n0,A1,1,ok\n", 2),
    "empty OK range": ("t_s,anchor_id,range_m,status\n0,A1,,OK\n", 2),
    "empty anchor id": ("t_s,anchor_id,range_m\n0, ,1\n", 2),
    "empty tag id": ("t_s,anchor_id,range_m,tag_id\n0,A1,1,\n", 2),
    "wrong header": ("time,anchor,range\n0,A1,1\n", 1),
    "header order": ("t_s,anchor_id,range_m,tag_id,status\n0,A1,1,t,OK\n", 1),
    "header only": ("# c\nt_s,anchor_id,range_m\n", 2),
    "empty file": ("", None),
    "only comments": ("# nothing\n\n", None),
    "not utf-8": (b"t_s,anchor_id,range_m\n0,A\xff1,1\n", 2),
}


@pytest.mark.parametrize("case", list(RANGES_CASES))
def test_bad_ranges_file(tmp_path, case):
    text, line = RANGES_CASES[case]
    path = tmp_path / "ranges.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    anchors = tidy.read_anchors_csv(_write(tmp_path, "a.csv", ANCHORS))
    with pytest.raises(DataFormatError) as exc:
        tidy.read_ranges_csv(path, anchors)
    assert_error_at(exc, path, line)


ANCHORS_CASES = {
    "duplicate id": ("anchor_id,x_m,y_m,z_m\nA,0,0,0\nB,1,1,1\nA,2,2,2\n", 4),
    "non-numeric": ("anchor_id,x_m,y_m,z_m\nA,0,zero,0\n", 2),
    "missing column": ("anchor_id,x_m,y_m\nA,0,0\n", 1),
    "wrong field count": ("anchor_id,x_m,y_m,z_m\nA,0,0\n", 2),
    "no anchors": ("anchor_id,x_m,y_m,z_m\n", 1),
}


@pytest.mark.parametrize("case", list(ANCHORS_CASES))
def test_bad_anchors_file(tmp_path, case):
    text, line = ANCHORS_CASES[case]
    path = _write(tmp_path, "anchors.csv", text)
    with pytest.raises(DataFormatError) as exc:
        tidy.read_anchors_csv(path)
    assert_error_at(exc, path, line)


TRUTH_CASES = {
    "time goes backwards": ("t_s,x_m,y_m\n0,0,0\n1,0,0\n0.5,0,0\n", 4),
    "repeated time of a tag": ("t_s,x_m,y_m,z_m,tag_id\n0,0,0,0,a\n0,1,1,1,b\n0,2,2,2,a\n", 4),
    "non-numeric": ("t_s,x_m,y_m\n0,0,-\n", 2),
    "bad header": ("t_s,y_m,x_m\n0,0,0\n", 1),
}


@pytest.mark.parametrize("case", list(TRUTH_CASES))
def test_bad_truth_file(tmp_path, case):
    text, line = TRUTH_CASES[case]
    path = _write(tmp_path, "truth.csv", text)
    with pytest.raises(DataFormatError) as exc:
        tidy.read_truth_csv(path)
    assert_error_at(exc, path, line)


def test_error_message_names_the_column(tmp_path):
    path = _write(tmp_path, "r.csv", "t_s,anchor_id,range_m\n0,A1,abc\n")
    with pytest.raises(DataFormatError, match=re.escape(f"{path}, line 2, column range_m")):
        tidy.read_ranges_csv(path)


@pytest.mark.parametrize("seed", [0, 1])
def test_typed_reader_agrees_with_the_field_by_field_reader(tmp_path, seed, monkeypatch):
    rec = random_recording(np.random.default_rng(seed))
    paths = tidy.write_recording(rec, tmp_path)
    text = paths["ranges"].read_text().splitlines()
    # comments, blank lines and spaces around fields: the typed reader must still count lines right
    text = [text[0], "# a note", ""] + [" " + ln.replace(",", " , ", 1) for ln in text[1:4]] + text[4:]
    paths["ranges"].write_text("\n".join(text) + "\n")
    fast = tidy._fast_table
    used = []
    monkeypatch.setattr(tidy, "_fast_table", lambda *a, **k: used.append(fast(*a, **k)) or used[-1])
    typed = tidy.read_ranges_csv(paths["ranges"], with_cleaning=True, max_range_m=np.inf)
    truth = tidy.read_truth_csv(paths["truth"])
    assert len(used) == 2 and all(t is not None for t in used)    # both files took the typed path
    monkeypatch.setattr(tidy, "_fast_table", lambda *a, **k: None)
    fields = tidy.read_ranges_csv(paths["ranges"], with_cleaning=True, max_range_m=np.inf)
    assert typed[1] == fields[1]
    for tag, log in typed[0].items():
        np.testing.assert_array_equal(log.t_s, fields[0][tag].t_s)
        np.testing.assert_array_equal(log.range_m, fields[0][tag].range_m)
        np.testing.assert_array_equal(truth[tag].pos_m, tidy.read_truth_csv(paths["truth"])[tag].pos_m)
    # an error after the comment lines names the right line in both readers
    bad = text[:10] + [text[10].split(",")[0] + ",A1,-1,OK,front"] + text[11:]
    paths["ranges"].write_text("\n".join(bad) + "\n")
    with pytest.raises(DataFormatError, match="line 11"):
        tidy.read_ranges_csv(paths["ranges"])
    monkeypatch.undo()
    with pytest.raises(DataFormatError, match="line 11"):
        tidy.read_ranges_csv(paths["ranges"])


@pytest.mark.parametrize("line, problem", [
    ("0.1,A1,2.5,", "4 comma-separated fields, expected 3"),  # an empty extra field
    ('0.1,"A1,x",2.5', "4 comma-separated fields, expected 3"),         # quotes are not quoting: a comma splits
    ('0.1,"A1",2.5', "anchor '\"A1\"' is not in the anchors file"),
    ("0.1\r0.2,A1,2.5", "is not a finite number"),           # a lone CR is not a line end
])
def test_typed_reader_is_exactly_as_strict_as_the_format(tmp_path, line, problem):
    path = _write(tmp_path, "ranges.csv", "t_s,anchor_id,range_m\n0,A1,2.5\n" + line + "\n")
    anchors = tidy.read_anchors_csv(_write(tmp_path, "a.csv", ANCHORS))
    with pytest.raises(DataFormatError, match=re.escape(problem)) as exc:
        tidy.read_ranges_csv(path, anchors)
    assert exc.value.line == 3
