"""Tests of uwbwb.datasets.registration: clock offsets, frames and IMU alignment."""

from __future__ import annotations

import numpy as np
import pytest

from tests.fixtures import iasl as fx
from uwbwb import Anchors, DataFormatError, ImuLog, RangeLog, Trajectory
from uwbwb.datasets import iasl, lias, registration
from uwbwb.geometry import linear_multilaterate


def test_loaders_use_the_shared_estimators():
    assert iasl.register_truth is registration.register_truth and iasl.align_imu is registration.align_imu
    assert iasl.RegistrationError is registration.RegistrationError
    assert not hasattr(iasl, "multilaterate_linear")    # one linear multilateration: uwbwb.geometry


def test_linear_multilateration_used_for_the_start_values():
    """The start of register_truth's offset scan: 3-D fixes, NaN with fewer than 4 ranges."""
    rng = np.random.default_rng(0)
    p = rng.uniform([1, 1, 0.5], [7, 7, 2], (20, 3))
    r = np.linalg.norm(p[:, None] - fx.ANCHORS_M[None], axis=2)
    r[3, :5] = np.nan      # 3 ranges left: no fix
    r[4, [0, 6]] = np.nan  # 6 ranges: still a fix
    fix = linear_multilaterate(r, fx.ANCHORS_M, dim=3)
    assert np.isnan(fix[3]).all()
    keep = np.arange(20) != 3
    np.testing.assert_allclose(fix[keep], p[keep], atol=1e-9)


def test_register_truth_fits_a_yaw_when_asked():
    rng = np.random.default_rng(3)
    t_mocap = np.round(np.arange(0.1, 25.0, 0.1), 1)
    pos, rot = fx.flight(t_mocap)
    truth = Trajectory(t_mocap, pos, rot=rot)
    yaw = np.radians(4.0)
    rz = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    t_uwb = np.arange(0.0, 24.0, 0.02)
    p = fx.flight(t_uwb - 0.4)[0] @ rz.T + [4.4, 4.0, 0.1]
    r = np.linalg.norm(p[:, None] - fx.ANCHORS_M[None], axis=2) + rng.normal(0, 0.02, (t_uwb.size, 8))
    a = Anchors(tuple(f"a{k}" for k in range(1, 9)), fx.ANCHORS_M)
    log = RangeLog(t_uwb, r, a.ids)
    plain = registration.register_truth(log, a, truth, fit_range_bias=False)
    assert plain.yaw_check_deg == pytest.approx(4.0, abs=0.2)
    assert plain.yaw_check_rms_m < plain.rms_m - 0.01
    fitted = registration.register_truth(log, a, truth, fit_yaw=True, fit_range_bias=False)
    assert np.degrees(fitted.yaw_rad) == pytest.approx(4.0, abs=0.1)
    assert fitted.time_offset_s == pytest.approx(0.4, abs=0.01)
    np.testing.assert_allclose(fitted.translation_m, [4.4, 4.0, 0.1], atol=0.01)
    assert fitted.yaw_check_deg is None
    moved = fitted.apply(truth)
    np.testing.assert_allclose(moved.t_s, truth.t_s + fitted.time_offset_s)
    np.testing.assert_allclose(moved.rot[:, 2, 2], truth.rot[:, 2, 2])


def test_registration_needs_overlap():
    t = np.arange(0.0, 10.0, 0.1)
    pos, rot = fx.flight(t)
    a = Anchors(tuple(f"a{k}" for k in range(1, 9)), fx.ANCHORS_M)
    log = RangeLog(t[:5], np.full((5, 8), 5.0), a.ids)
    with pytest.raises(registration.RegistrationError):
        registration.register_truth(log, a, Trajectory(t, pos + 4, rot=rot))




def test_clock_offset_and_convention_recovered_from_a_rigid_body():
    """Synthetic trolley: three tags on a yawing body, motion capture stamped 0.3 s late."""
    rng = np.random.default_rng(1)
    anchors = np.array([[0, 0, 2.0], [8, 0, 0.3], [8, 6, 2.0], [0, 6, 0.3], [4, -1, 1.0], [4, 7, 1.5]])
    offsets = np.array([[0.3, 0.0, 0.1], [-0.2, 0.25, 0.1], [-0.2, -0.25, 0.1]])
    t_m = np.arange(0.0, 30.0, 0.01)
    yaw = 0.5 * np.sin(0.3 * t_m)
    pos = np.column_stack([4 + 2 * np.cos(0.2 * t_m), 3 + 2 * np.sin(0.2 * t_m), np.full(t_m.size, 0.9)])
    quat = np.column_stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)])    # wxyz, yaw only
    t_u = np.arange(1.0, 28.0, 0.01)
    true_offset_s = 0.3                        # motion-capture stamp - UWB stamp of one instant
    tags = registration.body_points(
        np.column_stack([np.interp(t_u + true_offset_s, t_m, c) for c in pos.T]),
        registration.frame_rotation(np.column_stack([np.interp(t_u + true_offset_s, t_m, c) for c in quat.T]),
                                    "wxyz", "none"), offsets)
    r = np.linalg.norm(anchors[None, :, None, :] - tags[:, None], axis=-1) + 0.2 + rng.normal(0, 0.02, (t_u.size, 6, 3))
    fit = registration.fit_clock_offset_and_convention(
        "synthetic.csv", t_u, r, anchors, t_m, pos, quat, offsets, orders=registration.QUAT_ORDERS,
        flips=tuple(registration.BODY_FLIPS), max_offset_s=2.0, min_overlap=0.5, max_rows=3000)
    assert (fit.order, fit.flip) == ("wxyz", "none")
    assert fit.clock_offset_s == pytest.approx(true_offset_s, abs=0.005)


def _yaw_flight(seed: int, t_s: np.ndarray) -> np.ndarray:
    """A yaw rate (rad/s) that wanders at random: no period for a wrong lag to match."""
    k = np.exp(-0.5 * (np.arange(-60, 61) / 20.0) ** 2)
    return 3.0 * np.convolve(np.random.default_rng(seed).normal(0, 1, t_s.size), k / k.sum(), "same")


def _imu_and_truth(yaw_rate_imu, offset_s=0.4):
    t = np.arange(0, 60, 0.05)
    yaw = np.cumsum(_yaw_flight(1, t)) * 0.05
    rot = np.zeros((t.size, 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = (np.cos(yaw), -np.sin(yaw), np.sin(yaw),
                                                                         np.cos(yaw), 1.0)
    truth = Trajectory(t, np.zeros((t.size, 3)), rot=rot, name="truth")
    ti = np.arange(0, 60, 0.01)
    gyro = np.column_stack([np.zeros((ti.size, 2)), yaw_rate_imu(t, ti)])
    gyro += np.random.default_rng(5).normal(0, 0.02, gyro.shape)
    return ImuLog(ti - offset_s, np.tile([0, 0, 9.81], (ti.size, 1)), gyro), truth


def test_imu_alignment_finds_its_own_flight():
    imu, truth = _imu_and_truth(lambda t, ti: np.interp(ti, t, _yaw_flight(1, t)))
    al = registration.align_imu(imu, truth)
    assert al.offset_s == pytest.approx(0.4, abs=0.03) and al.peak_corr > 0.99


@pytest.mark.parametrize("what, yaw_rate", [("another flight's IMU", lambda t, ti: np.interp(ti, t, _yaw_flight(2, t))),
                                            ("a motionless IMU", lambda t, ti: np.zeros(ti.size))])
def test_imu_alignment_refuses_a_weak_peak_with_its_numbers(what, yaw_rate):
    imu, truth = _imu_and_truth(yaw_rate)
    with pytest.raises(registration.RegistrationError,
                       match=r"too weak to fix the IMU clock: its best peak is 0\.\d+ \(at [+-]\d+\.\d+ s\), under 0\.6"):
        registration.align_imu(imu, truth)


def test_the_loader_names_the_imu_file_whose_clock_it_cannot_fix(tmp_path):
    fx.write_dataset(tmp_path / iasl.NAME, rng=np.random.default_rng(7), duration_s=30.0)
    path = tmp_path / iasl.NAME / "scenario1" / "imu.csv"
    lines = path.read_text().splitlines()
    rng = np.random.default_rng(1)
    still = [lines[0]] + ["\t".join([row.split("\t")[0], *(f"{v:.5f}" for v in rng.normal([0, 0, -9.81], 0.05)),
                                     *(f"{v:.5f}" for v in rng.normal(0, 0.01, 3))]) for row in lines[1:]]
    path.write_text("\n".join(still) + "\n")
    with pytest.raises(DataFormatError, match=rf"{path}: cannot align the IMU clock: the gyro-rate correlation is "
                                              r"too weak .* best peak is 0\.\d+"):
        iasl.load_scenario("scenario1", data_dir=tmp_path)


def test_residual_spread_median_abs_keeps_the_bias_per_candidate():
    # the input checks' statistic: per candidate truth, the median over anchors of each anchor's median |residual|
    residual_spread = registration.residual_spread
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 20.0, 201)
    pos = np.column_stack([np.cos(t / 3), np.sin(t / 3), np.full(t.size, 1.0)]) * [4.0, 3.0, 1.0]
    a = np.array([[0.0, 0.0, 2.5], [8.0, 0.0, 2.5], [0.0, 6.0, 2.5], [8.0, 6.0, 0.5]])
    true_r = np.linalg.norm(pos[:, None] - a[None], axis=-1)
    r = true_r + [0.2, 0.0, -0.1, 0.3] + 0.01 * rng.standard_normal(true_r.shape)   # per-anchor biases
    shifts = np.array([[0.0, 0.0, 0.0], [0.5, -0.5, 0.0]])
    pts = pos[:, None, :] + shifts[None]
    got = residual_spread(t, np.broadcast_to(r[..., None], (*r.shape, 2)), a, t, pts, [0.0, 1.0], 0.6,
                          statistic="median_abs")
    assert got.shape == (2, 2)
    want = [np.median(np.median(np.abs(r - np.linalg.norm(pos[:, None] + s - a[None], axis=-1)), axis=0))
            for s in shifts]
    np.testing.assert_allclose(got[0], want, rtol=1e-9)
    assert got[0, 0] == pytest.approx(0.15, abs=0.02)      # the biases stay in (the spread would remove them)
    assert np.isfinite(got[1]).all() and (got[1] > got[0]).all()
    assert np.isinf(residual_spread(t, r[..., None], a, t, pos[:, None], [15.0], 0.6, statistic="median_abs")).all()
    with pytest.raises(ValueError, match="statistic"):
        residual_spread(t, r[..., None], a, t, pos[:, None], [0.0], 0.6, statistic="mean")
