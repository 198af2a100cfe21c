"""Tests of the iasl-uwb-imu loader (uwbwb.datasets.iasl)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.conftest import real_dataset
from tests.fixtures import iasl as fx
from uwbwb import Anchors, DataFormatError, DataNotFoundError, RangeLog, Trajectory
from uwbwb.datasets import iasl, iasl_files



@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """A 30-s two-scenario dataset with known registration parameters."""
    base = tmp_path_factory.mktemp("iasl")
    truth = fx.write_dataset(base / iasl.NAME, rng=np.random.default_rng(7), duration_s=30.0)
    return base, truth


@pytest.fixture(scope="module")
def loaded(synthetic):
    base, _ = synthetic
    return {s: iasl.load_scenario(s, data_dir=base) for s in ("scenario1", "scenario2")}


def assert_error_at(excinfo, path: Path, line: int | None) -> None:
    assert str(path) in str(excinfo.value)
    if line is not None:
        assert excinfo.value.line == line
        assert f"line {line}" in str(excinfo.value)


def _lines(path: Path) -> list[str]:
    return path.read_text().split("\n")


def _put(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines))
    return path


# --- listing and anchors ---------------------------------------------------------------------

def test_list_recordings_globs_scenario_folders(synthetic, tmp_path):
    base, _ = synthetic
    df = iasl.list_recordings(base)
    assert list(df["name"]) == ["scenario1", "scenario2"]
    assert df[["has_uwb", "has_imu", "has_gt"]].all().all()
    # any folder name, natural order, partial folders listed, unrelated folders ignored
    root = tmp_path / iasl.NAME
    for name in ("run10", "run2"):
        (root / name).mkdir(parents=True)
        (root / name / "uwb.csv").write_text("")
    (root / "notes").mkdir()
    df = iasl.list_recordings(tmp_path)
    assert list(df["name"]) == ["run2", "run10"]
    assert not df["has_gt"].any() and df["anchors_path"].isna().all()


def test_read_anchors(synthetic):
    base, _ = synthetic
    anchors = iasl.read_anchors(base / iasl.NAME / "uwb.yaml")
    assert anchors.ids == tuple(f"a{k}" for k in range(1, 9))
    np.testing.assert_array_equal(anchors.pos_m, fx.ANCHORS_M)


@pytest.mark.parametrize("text, line", [
    ("stdV: 1\n\nanchorPositions: [0, 1, 2, 3]\n", 3),      # not a multiple of 3
    ("stdV: 1\n", None),                                   # key missing
    ("anchorPositions: [0, 1,\n                  x]\n", 2),  # not a number
    ("anchorPositions: [0, 1, .inf]\n", 1),
    ("anchorPositions: [0, 1, 2\nstdV: 1\n", 2),             # not YAML
    ("- 1\n- 2\n", None),                                 # not a mapping
])
def test_read_anchors_errors(tmp_path, text, line):
    path = tmp_path / "uwb.yaml"
    path.write_text(text)
    with pytest.raises(DataFormatError) as exc:
        iasl.read_anchors(path)
    assert_error_at(exc, path, line)


# --- low-level readers -----------------------------------------------------------------------

def test_read_uwb_blank_first_line_and_zero_ranges(synthetic):
    base, truth = synthetic
    path = base / iasl.NAME / "scenario2" / "uwb.csv"
    assert path.read_text().startswith("\nLocal Time\t")
    uwb = iasl.read_uwb(path)
    log = uwb.ranges
    assert log.anchor_ids == tuple(f"a{k}" for k in range(1, 9))
    assert len(log) == truth["scenario2"].n_uwb
    np.testing.assert_allclose(np.diff(log.t_s), 0.02)
    assert log.t_s[0] == 0.0 and uwb.local_time0_ms == 2823613
    assert np.isnan(log.range_m).sum() == truth["scenario2"].n_zero_ranges
    assert [(s.name, s.n_affected) for s in uwb.cleaning] == [("zero ranges -> missing", 5)]
    assert uwb.device.pos_m.shape == (len(log), 3) and uwb.system_time_ms.shape == (len(log),)


def test_headers_are_optional(synthetic, tmp_path):
    base, _ = synthetic
    folder = base / iasl.NAME / "scenario1"
    for name, reader in (("uwb.csv", iasl.read_uwb), ("imu.csv", iasl.read_imu), ("gt.csv", iasl.read_gt)):
        lines = _lines(folder / name)
        assert not lines[0][0].isdigit()
        bare = _put(tmp_path / name, lines[1:])
        with_header, without = reader(folder / name), reader(bare)
        for a, b in zip(_arrays(with_header), _arrays(without)):
            np.testing.assert_array_equal(a, b)


def _arrays(parsed):
    if isinstance(parsed, iasl_files.UwbFile):
        return parsed.ranges.t_s, parsed.ranges.range_m, parsed.device.pos_m
    if isinstance(parsed, iasl_files.ImuFile):
        return parsed.imu.t_s, parsed.imu.acc_mps2, parsed.imu.gyro_radps
    return parsed.truth.t_s, parsed.truth.pos_m, parsed.truth.rot


def test_spread_whole_seconds_rule():
    stamps = np.array([10, 10, 11, 11, 11, 11, 12, 12, 12, 12, 13], float)
    t, rate = iasl.spread_whole_seconds(stamps)
    assert rate == 4.0
    expected = [11 - 1.5 / 4, 11 - 0.5 / 4,                 # first second: its last rows
                11.125, 11.375, 11.625, 11.875, 12.125, 12.375, 12.625, 12.875,
                13 + 0.5 / 4]                               # last second: its first row
    np.testing.assert_allclose(t, expected)
    t1, _ = iasl.spread_whole_seconds(np.array([5.0, 5.0]))
    np.testing.assert_allclose(t1, [5.25, 5.75])


def test_read_imu_spreads_whole_second_stamps(synthetic):
    base, truth = synthetic
    path = base / iasl.NAME / "scenario1" / "imu.csv"
    assert "\t 0." in path.read_text() or "\t -" in path.read_text()  # upstream leading spaces
    imu = iasl.read_imu(path)
    assert len(imu.imu) == truth["scenario1"].n_imu
    assert imu.unix_time0_s == 1718170318.0 and imu.rate_hz == 19.0
    assert np.all(np.diff(imu.imu.t_s) > 0) and 0 < imu.imu.t_s[0] < 1
    (step,) = imu.cleaning
    assert step.name == "spread whole-second IMU stamps" and step.n_affected == len(imu.imu)
    assert np.median(imu.imu.acc_mps2[:, 2]) < -9  # z down, as upstream


def test_read_imu_distinct_stamps_kept_and_fractional_repeats_rejected(tmp_path):
    row = "\t 0.1\t 0.2\t -9.8\t 0.0\t 0.0\t 0.0"
    path = _put(tmp_path / "imu.csv", [f"{t}{row}" for t in ("100.0", "100.05", "100.1")])
    imu = iasl.read_imu(path)
    np.testing.assert_allclose(imu.imu.t_s, [0.0, 0.05, 0.1])
    assert imu.cleaning == ()
    bad = _put(tmp_path / "imu2.csv", [f"{t}{row}" for t in ("100.5", "100.5", "101")])
    with pytest.raises(DataFormatError) as exc:
        iasl.read_imu(bad)
    assert_error_at(exc, bad, 1)


def test_read_gt_drops_zero_rows_and_transposes_rotation(synthetic):
    base, truth = synthetic
    path = base / iasl.NAME / "scenario2" / "gt.csv"
    gt = iasl.read_gt(path)
    info = truth["scenario2"]
    assert len(gt.truth) == info.n_gt_rows - info.n_dropouts
    assert [(s.name, s.n_affected) for s in gt.cleaning] == [("drop mocap dropouts", 2)]
    assert not np.any(np.isclose(gt.truth.t_s, 3.3)) and not np.any(np.isclose(gt.truth.t_s, 5.6))
    first = np.array(_lines(path)[0].split("\t")[4:], float).reshape(3, 3)
    np.testing.assert_array_equal(gt.truth.rot[0], first.T)
    _, rot = fx.flight(gt.truth.t_s[:1])
    np.testing.assert_allclose(gt.truth.rot[0], rot[0], atol=1e-5)  # body-to-world


def test_rows_sorted_and_duplicates_counted(synthetic, tmp_path):
    base, _ = synthetic
    lines = _lines(base / iasl.NAME / "scenario1" / "uwb.csv")
    lines = [lines[0], lines[2], lines[1], lines[3], lines[3]] + lines[4:10]
    uwb = iasl.read_uwb(_put(tmp_path / "uwb.csv", lines))
    assert [(s.name, s.n_affected) for s in uwb.cleaning] == [("rows sorted by time", 2), ("repeated rows dropped", 1)]
    assert len(uwb.ranges) == 9


def _bad_uwb_cases(good: list[str]) -> dict[str, tuple[list[str], int | None]]:
    row = good[1].split("\t")
    swapped = row[:]
    swapped[6] = "x"
    negative = row[:]
    negative[5] = "-1.0"
    conflict = good[2].split("\t")
    conflict[0] = row[0]
    return {
        "field missing": ([good[0], good[1], "\t".join(row[:-1])], 3),
        "extra field": ([good[0], "\t".join(row + ["1"])], 2),
        "not a number": ([good[0], good[1], "\t".join(swapped)], 3),
        "nan": ([good[0], "\t".join(row[:8] + ["nan"] + row[9:])], 2),
        "negative range": ([good[0], "\t".join(negative)], 2),
        "bad header": (["Local Time\tSystem Time\tX\tY\tZ\t" + "\t".join(good[0].split("\t")[5:])] + good[1:3], 1),
        "header only": ([good[0]], 1),
        "empty": ([""], None),
        "same time, other values": ([good[0], good[1], "\t".join(conflict)], 3),
        "commas": ([good[0], good[1].replace("\t", ",")], 2),
    }


@pytest.mark.parametrize("case", ["field missing", "extra field", "not a number", "nan", "negative range",
                                  "bad header", "header only", "empty", "same time, other values", "commas"])
def test_read_uwb_errors(synthetic, tmp_path, case):
    base, _ = synthetic
    good = _lines(base / iasl.NAME / "scenario1" / "uwb.csv")
    lines, line = _bad_uwb_cases(good)[case]
    path = _put(tmp_path / "uwb.csv", lines)
    with pytest.raises(DataFormatError) as exc:
        iasl.read_uwb(path)
    assert_error_at(exc, path, line)


def test_read_uwb_anchor_count_must_match(synthetic):
    base, _ = synthetic
    path = base / iasl.NAME / "scenario1" / "uwb.csv"
    with pytest.raises(DataFormatError, match="8 distance columns but 7 anchors"):
        iasl.read_uwb(path, anchor_ids=[f"a{k}" for k in range(7)])


@pytest.mark.parametrize("name, edit, line", [
    ("imu.csv", lambda ls: ls[:3] + [ls[3] + "\t1"] + ls[4:], 4),
    ("imu.csv", lambda ls: ls[:2] + [ls[2].replace("\t ", "\t x", 1)] + ls[3:], 3),
    ("gt.csv", lambda ls: ls[:5] + [ls[5].rsplit("\t", 1)[0]] + ls[6:], 6),
    ("gt.csv", lambda ls: [ls[0]] + ["1\t" + "\t".join(["0"] * 12)], None),  # only dropouts
])
def test_read_imu_gt_errors(synthetic, tmp_path, name, edit, line):
    base, _ = synthetic
    path = _put(tmp_path / name, edit(_lines(base / iasl.NAME / "scenario1" / name)))
    reader = iasl.read_imu if name == "imu.csv" else iasl.read_gt
    with pytest.raises(DataFormatError) as exc:
        reader(path)
    assert_error_at(exc, path, line)


# --- registration ----------------------------------------------------------------------------

@pytest.mark.parametrize("scenario", ["scenario1", "scenario2"])
def test_registration_recovers_known_frame_and_clocks(loaded, synthetic, scenario):
    _, truth = synthetic
    info = truth[scenario]
    rec = loaded[scenario]
    reg = rec.meta["registration"]
    np.testing.assert_allclose(reg.translation_m, info.translation_m, atol=0.01)
    assert reg.time_offset_s == pytest.approx(info.gt_offset_s, abs=0.01)
    assert reg.range_bias_m == pytest.approx(info.range_bias_m, abs=0.01)
    assert reg.rms_m == pytest.approx(0.03, abs=0.005)   # the synthetic range noise
    assert abs(reg.yaw_check_deg) < 0.3
    assert abs(reg.half_offsets_s[0] - reg.half_offsets_s[1]) < 0.02
    assert set(reg.per_anchor_median_m) == set(rec.anchors.ids)
    al = rec.meta["imu_alignment"]
    assert al.offset_s == pytest.approx(info.imu_offset_s, abs=0.03)
    assert al.peak_corr > 0.99 and not al.second_peak_corr >= al.peak_corr
    # the attitude convention: gyro axes are a signed permutation of the body rates
    np.testing.assert_allclose(np.abs(al.gyro_axes_corr), np.eye(3), atol=0.1)
    assert rec.meta["imu_time_offset_s"] == al.offset_s
    assert rec.meta["truth_time_offset_s"] == reg.time_offset_s


def test_registered_recording_is_consistent(loaded):
    rec = loaded["scenario1"]
    log, traj = rec.ranges["tag"], rec.truth["tag"]
    assert rec.tags == ("tag",) and len(rec.anchors) == 8
    # predicted ranges from the registered truth match the measured ones (bias removed)
    pos = traj.interp(log.t_s)
    ok = np.all(np.isfinite(pos), axis=1)
    pred = np.linalg.norm(pos[ok, None] - rec.anchors.pos_m[None], axis=2)
    resid = log.range_m[ok] - pred - rec.meta["registration"].range_bias_m
    assert np.sqrt(np.nanmean(resid ** 2)) < 0.04
    imu = iasl.read_imu(Path(rec.meta["source"]["imu"])).imu
    np.testing.assert_array_equal(rec.imu.t_s, imu.t_s + rec.meta["imu_time_offset_s"])
    np.testing.assert_array_equal(rec.imu.gyro_radps, imu.gyro_radps)
    assert [s.name for s in rec.cleaning] == ["drop mocap dropouts", "spread whole-second IMU stamps"]
    assert isinstance(rec.meta["device_estimate"], Trajectory)
    assert rec.meta["imu_noise"]["stdV"] == pytest.approx(0.0015387262937311438)


def _bursty_flight(offset_s: float, seed: int):
    """Ranges (10 Hz, 3 cm noise, six anchors) and an IMU on its own clock (``t_uwb = t_imu +
    offset_s``, 100 Hz) of a non-periodic flight: vertical and horizontal acceleration bursts."""
    from scipy.ndimage import gaussian_filter1d

    from uwbwb.types import Anchors, ImuLog, RangeLog

    rng = np.random.default_rng(seed)
    anchors = Anchors(tuple("abcdef"), np.array([[0, 0, 0.2], [8, 0, 2.5], [8, 6, 0.3], [0, 6, 2.6],
                                                 [4, -1, 1.5], [4, 7, 0.1]], float))
    dt, T = 0.01, 6000
    acc = gaussian_filter1d(rng.normal(0, 1.0, (T, 3)) * (rng.random((T, 1)) < 0.05), 15, axis=0) * 8
    acc -= acc.mean(axis=0)
    vel = np.cumsum(acc, axis=0) * dt
    vel -= gaussian_filter1d(vel, 300, axis=0)                  # stay in the room
    pos = np.array([4.0, 3.0, 1.3]) + np.cumsum(vel, axis=0) * dt
    acc = np.gradient(np.gradient(pos, dt, axis=0), dt, axis=0)
    t = np.arange(T) * dt
    f = acc + [0, 0, 9.80665] + rng.normal(0, 0.05, (T, 3))
    imu = ImuLog(t - offset_s, f, np.zeros((T, 3)))
    k = np.arange(0, T, 10)
    r = np.linalg.norm(pos[k, None] - anchors.pos_m[None], axis=2) + rng.normal(0, 0.03, (k.size, 6))
    return imu, RangeLog(t[k], r, anchors.ids), anchors


@pytest.mark.parametrize("offset_s", [-0.43, 0.27, 1.9])
def test_imu_clock_from_the_ranges_alone_recovers_a_known_offset(offset_s):
    from uwbwb.datasets.registration import align_imu_to_ranges

    imu, ranges, anchors = _bursty_flight(offset_s, seed=int(100 * abs(offset_s)))
    al = align_imu_to_ranges(imu, ranges, anchors)
    # precision, not bias: 3 cm ranges differentiated twice; −34…+62 ms over four such flights
    assert al.offset_s == pytest.approx(offset_s, abs=0.08)
    assert len(al.half_offsets_s) == 2 and all(abs(h - offset_s) < 0.15 for h in al.half_offsets_s)
    assert "no motion capture" in al.method and al.gyro_axes_corr is None


def test_imu_clock_from_ranges_in_the_loader_uses_no_truth_and_refuses_periodic_motion(synthetic):
    """The fixture flights are sums of sines: the specific-force correlation has near-equal peaks
    seconds apart, and the loader says so instead of returning one of them."""
    base, _ = synthetic
    with pytest.raises(DataFormatError, match="ambiguous"):
        iasl.load_scenario("scenario1", data_dir=base, imu_clock="ranges")
    with pytest.raises(DataFormatError, match="imu.csv"):
        iasl.load_scenario("scenario1", data_dir=base, register=False, imu_clock="ranges")
    assert iasl.load_scenario("scenario1", data_dir=base, register=False).meta.get("imu_alignment") is None
    with pytest.raises(ValueError, match="imu_clock must be"):
        iasl.load_scenario("scenario1", data_dir=base, imu_clock="mocap")


def test_imu_clock_from_ranges_refuses_what_it_cannot_estimate():
    from uwbwb.datasets.registration import RegistrationError, align_imu_to_ranges
    from uwbwb.types import Anchors, ImuLog, RangeLog

    anchors = Anchors(("a", "b", "c", "d"), np.array([[0, 0, 0], [5, 0, 0], [0, 5, 0], [0, 0, 3.0]]))
    t = np.arange(0, 10, 0.1)
    imu = ImuLog(np.arange(0, 10, 0.01), np.tile([0, 0, 9.8], (1000, 1)), np.zeros((1000, 3)))
    with pytest.raises(RegistrationError, match="converged 3-D fixes"):
        align_imu_to_ranges(imu, RangeLog(t, np.full((t.size, 4), np.nan), anchors.ids), anchors)
    with pytest.raises(ValueError, match="smooth_s"):
        align_imu_to_ranges(imu, RangeLog(t, np.full((t.size, 4), np.nan), anchors.ids), anchors, smooth_s=0)


# --- scenario loader -------------------------------------------------------------------------

def test_load_scenario_unregistered_keeps_raw_clocks(synthetic):
    base, _ = synthetic
    rec = iasl.load_scenario("scenario1", data_dir=base, register=False)
    gt = iasl.read_gt(base / iasl.NAME / "scenario1" / "gt.csv")
    np.testing.assert_array_equal(rec.truth["tag"].pos_m, gt.truth.pos_m)
    assert rec.truth["tag"].t_s[0] == 0.1
    assert "registration" not in rec.meta and rec.meta["registered"] is False


def test_load_scenario_missing_parts(synthetic, tmp_path):
    base, _ = synthetic
    with pytest.raises(DataNotFoundError, match="scenario1"):
        iasl.load_scenario("nope", data_dir=base)
    root = tmp_path / iasl.NAME
    (root / "s").mkdir(parents=True)
    (root / "uwb.yaml").write_text(fx.YAML_TEXT)
    src = base / iasl.NAME / "scenario1"
    (root / "s" / "uwb.csv").write_bytes((src / "uwb.csv").read_bytes())
    with pytest.raises(DataNotFoundError, match="gt.csv"):
        iasl.load_scenario("s", data_dir=tmp_path)
    rec = iasl.load_scenario("s", data_dir=tmp_path, register=False)
    assert rec.truth == {} and rec.imu is None


def test_unregistrable_data_is_a_format_error_naming_the_file(synthetic, tmp_path):
    base, _ = synthetic
    root = tmp_path / iasl.NAME
    (root / "s").mkdir(parents=True)
    (root / "uwb.yaml").write_text(fx.YAML_TEXT)
    src = base / iasl.NAME / "scenario1"
    for name in ("uwb.csv", "imu.csv"):
        (root / "s" / name).write_bytes((src / name).read_bytes())
    lines = _lines(src / "gt.csv")
    _put(root / "s" / "gt.csv", lines[:4])  # three mocap rows: no overlap worth the name
    with pytest.raises(DataFormatError) as exc:
        iasl.load_scenario("s", data_dir=tmp_path)
    assert_error_at(exc, root / "s" / "gt.csv", None)


def test_sample_tree_loads(tmp_path):
    fx.write_sample(tmp_path / iasl.NAME)
    rec = iasl.load_scenario("scenario1", data_dir=tmp_path)
    reg = rec.meta["registration"]
    np.testing.assert_allclose(reg.translation_m, (4.45, 4.02, 0.15), atol=0.03)
    assert reg.time_offset_s == pytest.approx(-1.3, abs=0.03)
    assert [s.name for s in rec.cleaning] == ["zero ranges -> missing", "drop mocap dropouts",
                                              "spread whole-second IMU stamps"]


# --- real data -------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def real():
    root = real_dataset(iasl.NAME)
    names = list(iasl.list_recordings(root.parent)["name"])
    return {name: iasl.load_scenario(name, data_dir=root.parent) for name in names}


@pytest.mark.realdata
def test_real_scenarios_load_and_register(real):
    assert len(real) >= 1
    for name, rec in real.items():
        assert len(rec.anchors) == 8, name
        log = rec.ranges["tag"]
        assert log.n_anchors == 8 and len(log) > 1000
        reg = rec.meta["registration"]
        # README: mocap frame is offset by roughly (+4.45, +4.02, 0) m from the anchor frame
        np.testing.assert_allclose(reg.translation_m[:2], (4.45, 4.02), atol=0.15)
        assert abs(reg.translation_m[2]) < 0.4
        assert reg.rms_m < 0.15 and reg.robust_sigma_m < 0.12
        assert abs(reg.yaw_check_deg) < 3.0
        assert abs(reg.half_offsets_s[0] - reg.half_offsets_s[1]) < 0.05
        al = rec.meta["imu_alignment"]
        assert al.peak_corr > 0.9 and al.second_peak_corr < 0.6
        assert abs(al.acc_offset_s - al.offset_s) < 0.15
        # gt rotation read as body-to-world after transposing: gyro axes are a signed permutation
        assert np.all(np.max(np.abs(al.gyro_axes_corr), axis=1) > 0.9)
        names = [s.name for s in rec.cleaning]
        assert "spread whole-second IMU stamps" in names
        assert np.all(np.diff(rec.imu.t_s) > 0)
