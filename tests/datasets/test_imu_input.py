"""IMU input is checked: non-finite samples, spikes, deg/s gyros, mg accelerations, a z-down body
frame and gaps each give an error naming the file, a counted cleaning step, or a warning with the
evidence (uwbwb.datasets.imu_checks, uwbwb.models.imu.check_body_imu)."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import real_dataset
from tests.fixtures import iasl as fx
from uwbwb import DataFormatError
from uwbwb.datasets import iasl
from uwbwb.datasets.imu_checks import ImuGapWarning, check_imu_samples
from uwbwb.models.imu import ImuConvention, check_body_imu, imu_evidence
from uwbwb.models.ins import GRAVITY_MPS2
from uwbwb.types import ImuLog

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    """A 30-s synthetic i-ASL scenario (z-down UM7 axes, m/s², rad/s, ~19 Hz)."""
    base = tmp_path_factory.mktemp("iasl_imu")
    fx.write_scenario(base / iasl.NAME / "scenario1", rng=np.random.default_rng(11), duration_s=30.0)
    (base / iasl.NAME / "uwb.yaml").write_text(fx.YAML_TEXT)
    return base


def _rows(path: Path) -> tuple[list[str], np.ndarray]:
    """Header line and the numbers of an ``imu.csv``, shape ``(T, 7)``."""
    lines = path.read_text().split("\n")
    return lines[0], np.array([[float(v) for v in ln.split("\t")] for ln in lines[1:] if ln.strip()])


def _write(path: Path, header: str, values: np.ndarray) -> Path:
    lines = [header] + ["\t".join([str(int(r[0]))] + [f" {float(v)!r}" for v in r[1:]]) for r in values]
    path.write_text("\n".join(lines))
    return path


def _edited(tree: Path, tmp_path: Path, edit) -> Path:
    """A copy of the scenario whose ``imu.csv`` numbers went through ``edit``; returns the new imu.csv."""
    dest = tmp_path / iasl.NAME
    shutil.copytree(tree / iasl.NAME, dest)
    path = dest / "scenario1" / "imu.csv"
    header, values = _rows(path)
    return _write(path, header, edit(values.copy()))


def _body(tree: Path) -> ImuLog:
    """The synthetic log in body axes and SI, as the i-ASL calibration makes it (z-down → z-up)."""
    raw = iasl.read_imu(tree / iasl.NAME / "scenario1" / "imu.csv").imu
    return ImuConvention(R_body_sensor=np.diag([1.0, -1.0, -1.0])).to_body(raw, check=False)


# --- a clean log passes, and its evidence is what the physics says ----------------------------

def test_clean_log_passes_with_its_evidence(tree):
    imu = iasl.read_imu(tree / iasl.NAME / "scenario1" / "imu.csv")
    ev = imu.checks.evidence
    assert abs(ev.gravity_mps2 - 1.056 * GRAVITY_MPS2) < 0.5      # the fixture's 5.6 % scale error
    assert ev.median_fz < -9                                     # z down, as upstream
    assert ev.rate_scale > 0.5 and not ev.gyro_looks_deg
    assert imu.checks.gaps_s.shape == (0, 2)
    assert [s.name for s in imu.cleaning] == ["spread whole-second IMU stamps"]
    check_body_imu(_body(tree))


# --- NaN / inf -------------------------------------------------------------------------------

@pytest.mark.parametrize("bad", ["nan", "inf"])
def test_non_finite_sample_in_file_names_line_and_column(tree, tmp_path, bad):
    path = _edited(tree, tmp_path, lambda v: v)
    lines = path.read_text().split("\n")
    fields = lines[5].split("\t")
    fields[4] = f" {bad}"
    lines[5] = "\t".join(fields)
    path.write_text("\n".join(lines))
    with pytest.raises(DataFormatError) as exc:
        iasl.read_imu(path)
    assert exc.value.line == 6 and "Angular velocity X" in str(exc.value) and str(path) in str(exc.value)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_sample_in_a_log_is_refused_before_integration(tree, bad):
    raw = iasl.read_imu(tree / iasl.NAME / "scenario1" / "imu.csv").imu
    acc = raw.acc_mps2.copy()
    acc[100, 1] = bad
    with pytest.raises(ValueError, match=r"acc_mps2 must be finite: 1 sample\(s\)"):
        ImuLog(raw.t_s, acc, raw.gyro_radps)          # the container refuses it: no filter can receive it


# --- a 1e6 m/s² spike ------------------------------------------------------------------------

def test_spike_beyond_full_scale_is_dropped_and_counted(tree, tmp_path):
    def spike(v):
        v[200, 3] = 1e6
        return v
    path = _edited(tree, tmp_path, spike)
    clean = iasl.read_imu(tree / iasl.NAME / "scenario1" / "imu.csv")
    imu = iasl.read_imu(path)
    step = [s for s in imu.cleaning if s.name == "IMU spikes dropped"]
    assert len(step) == 1 and step[0].n_affected == 1 and "lines 202" in step[0].detail
    assert len(imu.imu) == len(clean.imu) - 1
    assert np.abs(imu.imu.acc_mps2).max() < 20
    with pytest.raises(ValueError, match="beyond the full scale"):
        check_body_imu(ImuLog(clean.imu.t_s, np.where(np.arange(len(clean.imu))[:, None] == 5, 1e6,
                                                       _body(tree).acc_mps2), _body(tree).gyro_radps))


# --- gyro in deg/s ---------------------------------------------------------------------------

def test_gyro_in_deg_per_s_is_an_error_with_the_rate_scale(tree, tmp_path):
    def to_deg(v):
        v[:, 4:7] /= DEG
        return v
    path = _edited(tree, tmp_path, to_deg)
    with pytest.raises(DataFormatError, match="deg/s") as exc:
        iasl.read_imu(path)
    assert str(path) in str(exc.value) and "π/180" in str(exc.value)
    body = _body(tree)
    with pytest.raises(ValueError, match="deg/s"):
        check_body_imu(ImuLog(body.t_s, body.acc_mps2, body.gyro_radps / DEG))


def test_rate_scale_tells_rad_from_deg_whatever_the_motion():
    # a pendulum-like tilt of ±0.3 rad at 0.5 Hz: gravity direction rotates by the gyro rate
    t = np.arange(0.0, 20.0, 0.01)
    th = 0.3 * np.sin(2 * np.pi * 0.5 * t)
    thd = 0.3 * 2 * np.pi * 0.5 * np.cos(2 * np.pi * 0.5 * t)
    acc = GRAVITY_MPS2 * np.column_stack([np.zeros_like(t), np.sin(th), np.cos(th)])
    gyro = np.column_stack([thd, np.zeros_like(t), np.zeros_like(t)])
    assert imu_evidence(t, acc, gyro).rate_scale == pytest.approx(1.0, rel=0.02)
    assert imu_evidence(t, acc, gyro / DEG).rate_scale == pytest.approx(DEG, rel=0.02)
    assert imu_evidence(t, acc, gyro / DEG).gyro_looks_deg and not imu_evidence(t, acc, gyro).gyro_looks_deg


def test_a_log_at_rest_makes_no_claim_about_the_gyro_unit():
    # no tilt: the fit has nothing to explain, however many samples (no false "deg/s")
    rng = np.random.default_rng(3)
    t = np.arange(200_000) * 0.01
    acc = np.array([0.0, 0.0, GRAVITY_MPS2]) + rng.normal(0, 0.02, (t.size, 3))
    gyro = rng.normal(0, 0.01, (t.size, 3))
    ev = imu_evidence(t, acc, gyro)
    assert ev.rate_scale_se < 0.05 and not ev.gyro_looks_deg
    check_body_imu(ImuLog(t, acc, gyro))


# --- accelerations in mg (or g) --------------------------------------------------------------

@pytest.mark.parametrize("factor, guess", [(1000.0 / GRAVITY_MPS2, "mg"), (1.0 / GRAVITY_MPS2, "looks like g")])
def test_accelerations_not_in_mps2_are_an_error_with_the_magnitude(tree, tmp_path, factor, guess):
    def scale(v):
        v[:, 1:4] *= factor
        return v
    path = _edited(tree, tmp_path, scale)
    with pytest.raises(DataFormatError, match=r"not in m/s² \(mg\? g\?\): median \|f\| = ") as exc:
        iasl.read_imu(path)
    assert guess in str(exc.value) and str(path) in str(exc.value)
    body = _body(tree)
    with pytest.raises(ValueError, match="not in m/s²"):
        check_body_imu(ImuLog(body.t_s, body.acc_mps2 * factor, body.gyro_radps))


def test_a_saturating_accelerometer_is_not_called_a_unit_error(tree):
    """1.3 % of the samples clipped at 16 g in an m/s² log were reported as "not in m/s²"."""
    body = _body(tree)
    acc = body.acc_mps2.copy()
    clipped = np.arange(0, acc.shape[0], 75)[: int(0.013 * acc.shape[0])]
    acc[clipped, 0] = 20 * GRAVITY_MPS2
    with pytest.raises(ValueError, match=r"\(1\.\d %\) have an accelerometer component beyond the full scale "
                                         r"16 g, while the others read m/s² .*a saturating sensor") as exc:
        check_body_imu(ImuLog(body.t_s, acc, body.gyro_radps))
    assert "not in m/s²" not in str(exc.value)


# --- z-down frame ----------------------------------------------------------------------------

def test_z_down_body_frame_is_refused_with_the_measured_gravity(tree):
    raw = iasl.read_imu(tree / iasl.NAME / "scenario1" / "imu.csv").imu
    with pytest.raises(ValueError, match=r"z-down frame: median f_z = -1\d"):
        ImuConvention().to_body(raw)       # the UM7's z-down axes taken as the z-up body
    ImuConvention(R_body_sensor=np.diag([1.0, -1.0, -1.0]), acc_scale=1 / 1.056).to_body(raw)


# --- gaps ------------------------------------------------------------------------------------

def _with_gap(v):
    sec = np.unique(v[:, 0])
    return v[(v[:, 0] != sec[10]) & (v[:, 0] != sec[11])]      # two whole seconds missing


def test_gap_is_an_error_listing_it(tree, tmp_path):
    path = _edited(tree, tmp_path, _with_gap)
    with pytest.raises(DataFormatError, match=r"1 gap\(s\) between IMU samples longer than") as exc:
        iasl.read_imu(path)
    assert str(path) in str(exc.value) and "coast across them" in str(exc.value)
    assert exc.value.line is not None


def test_gap_kept_on_request_is_warned_and_listed(tree, tmp_path):
    path = _edited(tree, tmp_path, _with_gap)
    with pytest.warns(ImuGapWarning, match="longest 2"):
        rec = iasl.load_scenario("scenario1", data_dir=tmp_path, register=False, imu_gaps="warn")
    (gap,) = rec.meta["imu_gaps_s"]
    assert 2.0 < gap[1] - gap[0] < 2.2
    assert not np.any((rec.imu.t_s > gap[0]) & (rec.imu.t_s < gap[1]))


def test_rows_missing_inside_a_second_are_a_gap_too(tree, tmp_path):
    def thin(v):
        sec = np.unique(v[:, 0])
        inside = np.flatnonzero(v[:, 0] == sec[8])
        return np.delete(v, inside[3:13], axis=0)          # 10 of ~19 rows of one second lost
    path = _edited(tree, tmp_path, thin)
    with pytest.raises(DataFormatError, match=r"1 whole second\(s\) hold fewer than") as exc:
        iasl.read_imu(path)
    assert str(path) in str(exc.value) and exc.value.line is not None
    with pytest.warns(ImuGapWarning, match="samples lost inside a second"):
        imu = iasl.read_imu(path, gaps="warn")
    (gap,) = imu.checks.gaps_s
    assert gap[1] - gap[0] == 1.0


def test_gap_policy_and_limit_are_validated(tree):
    with pytest.raises(ValueError, match="gaps must be one of"):
        iasl.load_scenario("scenario1", data_dir=tree, register=False, imu_gaps="ignore")
    t = np.arange(50) * 0.05
    acc = np.tile([0.0, 0.0, GRAVITY_MPS2], (50, 1))
    with pytest.raises(ValueError, match="gaps must be one of"):
        check_imu_samples("x.csv", t, acc, np.zeros((50, 3)), np.arange(50) + 1, gaps="ignore")
    with pytest.raises(ValueError, match="max_gap_s"):
        check_imu_samples("x.csv", t, acc, np.zeros((50, 3)), np.arange(50) + 1, max_gap_s=0)


# --- real data: no false alarm ---------------------------------------------------------------

@pytest.mark.realdata
def test_real_iasl_imu_passes_every_check():
    root = real_dataset(iasl.NAME)
    for name in iasl.list_recordings(root.parent)["name"]:
        imu = iasl.read_imu(root / name / iasl.IMU_FILE)
        ev = imu.checks.evidence
        assert ev.gravity_ok and not ev.gyro_looks_deg and ev.median_fz < 0, name
        assert imu.checks.gaps_s.shape == (0, 2), name
        assert not [s for s in imu.cleaning if s.name == "IMU spikes dropped"], name
