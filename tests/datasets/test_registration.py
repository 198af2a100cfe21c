"""Tests of uwbwb.datasets.registration: clock offsets, frames and IMU alignment."""

from __future__ import annotations

import numpy as np
import pytest

from tests.fixtures import iasl as fx
from uwbwb import Anchors, RangeLog, Trajectory
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
