"""Tests of the hanyang-outdoor-uwb static loader (uwbwb.datasets.hanyang)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import real_dataset
from tests.fixtures import hanyang as fx
from uwbwb import DataFormatError
from uwbwb.datasets import hanyang



@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    base = tmp_path_factory.mktemp("hanyang")
    infos = fx.write_dataset(base / hanyang.NAME, rng=np.random.default_rng(11))
    return base, infos


def assert_error_at(excinfo, path: Path, line: int | None) -> None:
    assert str(path) in str(excinfo.value)
    if line is not None:
        assert excinfo.value.line == line
        assert f"line {line}" in str(excinfo.value)


def test_list_recordings_reads_condition_height_and_true_range_from_the_path(synthetic):
    base, infos = synthetic
    df = hanyang.list_recordings(base)
    assert len(df) == len(infos) == 12
    by_file = {Path(i.path).relative_to(base / hanyang.NAME).as_posix(): i for i in infos}
    for row in df.itertuples():
        info = by_file[row.file]
        assert (row.condition, row.height_m, row.true_range_m) == (info.condition, info.height_m,
                                                                    info.true_range_m)
        assert row.n_samples == info.n_samples and row.n_summary_lines == info.n_summary
        assert row.header_only == (info.n_samples == 0)
        assert row.summary_matches is (None if info.n_summary == 0 else True)
    assert df["header_only"].sum() == 2
    assert set(df["height_m"]) == {0.5, 0.625}
    # sorted numerically by distance, not by name ("10m" after "4m")
    assert list(df["true_range_m"][:3]) == [2.0, 4.0, 10.0]


def test_true_range_and_height_parse_from_names(tmp_path):
    fx.write_static_file(tmp_path / hanyang.NAME / "Static_measurements" / "LOS" / "height_187.5cm" / "12.5m.csv",
                         rng=np.random.default_rng(0), true_range_m=12.5, n=5)
    df = hanyang.list_recordings(tmp_path)
    assert (df["true_range_m"][0], df["height_m"][0]) == (12.5, 1.875)
    bad = tmp_path / hanyang.NAME / "Static_measurements" / "LOS" / "height_187.5cm" / "twelve.csv"
    bad.write_text(fx.HEADER + "\n")
    with pytest.raises(DataFormatError) as exc:
        hanyang.list_recordings(tmp_path)
    assert_error_at(exc, bad, None)


def test_load_static_counts_every_quirk(synthetic):
    base, infos = synthetic
    df = hanyang.load_static(base)
    assert len(df) == sum(i.n_samples for i in infos)  # only empty records and summaries are dropped
    assert list(df.columns[: len(hanyang.SAMPLE_COLUMNS)]) == list(hanyang.SAMPLE_COLUMNS)
    steps = {s.name: s.n_affected for s in df.attrs["cleaning"]}
    assert steps == {"summary lines": 6 * sum(i.n_summary > 0 for i in infos), "trailing NUL bytes": 37,
                     "garbled diagnostic fields -> NaN": 1, "empty records": 1, "RSSI(dBm) -inf -> NaN": 1,
                     "header-only files": 2}
    assert df.attrs["n_files"] == 12
    np.testing.assert_allclose(df["range_error_m"], df["range_m"] - df["true_range_m"])
    # each file's measured ranges come back in order, its true range from the name
    for info in infos:
        rel = Path(info.path).relative_to(base / hanyang.NAME).as_posix()
        got = df[df["file"] == rel]
        np.testing.assert_array_equal(got["range_m"], info.ranges_m)
        assert (got["true_range_m"] == info.true_range_m).all()
        assert (got["t_s"].iloc[:1] == 0).all() and np.all(np.diff(got["t_s"]) > 0)
    assert df["rssi_dbm"].isna().sum() == 1 and df["anchor_id"].isna().sum() == 1
    assert df["rssi_fp_dbm"].notna().all() and df["range_m"].notna().all()


def test_load_static_selects(synthetic):
    base, infos = synthetic
    nlos = hanyang.load_static(base, condition="NLOS")
    assert set(nlos["condition"]) == {"NLOS"}
    one = hanyang.load_static(base, height_m=0.625)
    both = hanyang.load_static(base, condition="LOS", height_m=[0.5, 0.625])
    assert set(one["height_m"]) == {0.625} and set(both["condition"]) == {"LOS"}
    assert len(both) == sum(i.n_samples for i in infos if i.condition == "LOS")
    with pytest.raises(ValueError, match="known"):
        hanyang.load_static(base, condition="los")
    with pytest.raises(ValueError, match="known"):
        hanyang.load_static(base, height_m=0.55)


def test_header_only_file_has_no_samples_but_the_columns(synthetic):
    base, _ = synthetic
    path = base / hanyang.NAME / "Static_measurements" / "LOS" / "height_62.5cm" / "10m.csv"
    assert path.read_text().count("\n") == 1
    sf = hanyang.read_static_file(path)
    assert sf.header_only and sf.samples.empty and sf.cleaning == ()
    assert {"line", "t_s", "range_m", "rssi_dbm", "anchor_id"} <= set(sf.samples.columns)


def test_summary_is_kept_and_checked(synthetic):
    base, infos = synthetic
    info = next(i for i in infos if i.n_summary and i.condition == "LOS")
    sf = hanyang.read_static_file(info.path)
    assert sf.summary["Distance Mean"] == pytest.approx(np.mean(info.ranges_m), abs=1e-12)
    assert sf.summary["Distance Std"] == pytest.approx(np.std(info.ranges_m, ddof=1), abs=1e-12)
    neg = hanyang.read_static_file(base / hanyang.NAME / "Static_measurements" / "NLOS" / "height_62.5cm" / "2m.csv")
    assert neg.summary["RSSI(dBm) Mean"] == -np.inf and neg.summary["RSSI(dBm) Std"] is None


def test_sorting_and_duplicates_are_counted(tmp_path):
    path = tmp_path / "4m.csv"
    fx.write_static_file(path, rng=np.random.default_rng(1), true_range_m=4, n=6, summary="none")
    lines = path.read_text().splitlines()
    path.write_text("\n".join([lines[0], lines[2], lines[1], lines[3], lines[3]] + lines[4:]) + "\n")
    sf = hanyang.read_static_file(path)
    assert [(s.name, s.n_affected) for s in sf.cleaning] == [("rows sorted by time", 2), ("repeated rows dropped", 1)]
    assert len(sf.samples) == 6 and list(sf.samples["line"][:2]) == [3, 2]


def _cases(lines: list[str]) -> dict[str, tuple[list[str], int | None]]:
    row = lines[1].split(",")
    text_range = row[:4] + ["ten"] + row[5:]
    inf_time = ["inf"] + row[1:]
    conflict = lines[2].split(",")
    conflict[0] = row[0]
    return {
        "sample after summary": (lines + [lines[1]], len(lines) + 1),
        "field missing": ([lines[0], lines[1], ",".join(row[:-1])], 3),
        "range not a number": ([lines[0], ",".join(text_range)], 2),
        "time not finite": ([lines[0], ",".join(inf_time)], 2),
        "required column missing": ([lines[0].replace("Distance", "Dist")] + lines[1:], 1),
        "empty": ([""], 1),
        "same time, other values": ([lines[0], lines[1], ",".join(conflict)], 3),
        "summary with extra values": (lines[:-1] + [lines[-1] + ",7"], len(lines)),
        "summary value not a number": (lines[:-1] + [lines[-1].split(",")[0] + ",abc"], len(lines)),
    }


@pytest.mark.parametrize("case", ["sample after summary", "field missing", "range not a number",
                                  "time not finite", "required column missing", "empty",
                                  "same time, other values", "summary with extra values",
                                  "summary value not a number"])
def test_read_static_file_errors(tmp_path, case):
    good = tmp_path / "good.csv"
    fx.write_static_file(good, rng=np.random.default_rng(2), true_range_m=6, n=5)
    lines, line = _cases(good.read_text().splitlines())[case]
    path = tmp_path / "6m.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataFormatError) as exc:
        hanyang.read_static_file(path)
    assert_error_at(exc, path, line)


def test_nul_inside_the_text_is_an_error(tmp_path):
    path = tmp_path / "6m.csv"
    fx.write_static_file(path, rng=np.random.default_rng(2), true_range_m=6, n=5)
    data = path.read_bytes().split(b"\n")
    data[3] = data[3][:10] + b"\0" + data[3][10:]
    path.write_bytes(b"\n".join(data))
    with pytest.raises(DataFormatError, match=re.escape(f"{path}, line 4")):
        hanyang.read_static_file(path)


def test_sample_tree_loads(tmp_path):
    fx.write_sample(tmp_path / hanyang.NAME)
    df = hanyang.load_static(tmp_path)
    assert len(df) == 120 and df.attrs["n_files"] == 12


# --- real data -------------------------------------------------------------------------------

def _independent_counts(static: Path) -> tuple[int, int]:
    """Samples (lines starting with a digit) and files without any, counted from the raw bytes."""
    n_samples = n_empty = 0
    for path in static.glob("*/height_*cm/*.csv"):
        lines = path.read_bytes().rstrip(b"\0").decode().splitlines()[1:]
        k = sum(1 for ln in lines if ln[:1].isdigit())
        n_samples += k
        n_empty += k == 0
    return n_samples, n_empty


@pytest.mark.realdata
def test_real_static_files_all_load():
    root = real_dataset(hanyang.NAME)
    listing = hanyang.list_recordings(root.parent)
    df = hanyang.load_static(root.parent)
    n_samples, n_empty = _independent_counts(root / hanyang.STATIC_DIR)
    assert len(df) == n_samples == listing["n_samples"].sum()
    steps = {s.name: s.n_affected for s in df.attrs["cleaning"]}
    assert steps["header-only files"] == n_empty == listing["header_only"].sum() > 0
    assert steps["summary lines"] == listing["n_summary_lines"].sum()
    assert set(df["condition"]) == {"LOS", "NLOS"}
    assert df["range_m"].notna().all() and df["t_unix_s"].notna().all()
    assert listing["summary_matches"].dropna().mean() > 0.95
    # UWB ranging bias is positive, a few decimetres, in both conditions
    med = df.groupby("condition")["range_error_m"].median()
    assert ((med > 0.05) & (med < 0.6)).all()
