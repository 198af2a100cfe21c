"""The range measurement adapter of the generic EKF (:mod:`uwbwb.filters.ekf.ranges`)."""

import numpy as np
import pytest

from uwbwb.filters.ekf import Ekf, kernels
from uwbwb.filters.ekf.ranges import RangeMeasurement, run_ranges
from uwbwb.filters.gating import Robust
from uwbwb.filters.twins import TWINS
from uwbwb.models.motion import make_motion_model
from uwbwb.types import EstimateStatus, RangeLog

ANCHORS_M = np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.2], [2.0, 2.0, 1.0], [0.0, 2.0, 1.4]])


def test_range_measurement_jacobian_matches_finite_differences():
    rng = np.random.default_rng(2)
    for model in ("RW", "RF", "RJ"):
        motion = make_motion_model(model, sigma=1.0, dt_s=0.1, dim=2)
        meas = RangeMeasurement(ANCHORS_M, np.full(4, 0.1), motion, 1.1)
        x = rng.normal(0, 5, motion.n_x)
        row = np.array([10.0, np.nan, 12.0, 11.0])
        lin = meas.linearise(x, row)
        assert lin.z.size == 3 and np.array_equal(meas.components(row), [0, 2, 3])
        num = np.empty_like(lin.H)
        for j in range(x.size):
            dx = np.zeros_like(x)
            dx[j] = 1e-6
            num[:, j] = (meas.linearise(x + dx, row).h - meas.linearise(x - dx, row).h) / 2e-6
        np.testing.assert_allclose(lin.H, num, atol=1e-7)
        np.testing.assert_allclose(lin.R, np.diag(np.full(3, 0.01)))
        assert meas.linearise(x, np.full(4, np.nan)) is None
        two = meas.linearise_components(x, row, np.array([0, 3]))
        np.testing.assert_allclose(two.h, lin.h[[0, 2]])
        np.testing.assert_allclose(two.H, lin.H[[0, 2]])


def test_a_2d_range_model_needs_the_tag_height_and_epochs_are_the_rows():
    motion = make_motion_model("RF", sigma=1.0, dt_s=0.1, dim=2)
    with pytest.raises(ValueError, match="tag height"):
        RangeMeasurement(ANCHORS_M, np.full(4, 0.1), motion)
    log = RangeLog(np.array([0.0, 0.1]), np.array([[1.0, 2.0, np.nan, 3.0], [1.1, 2.1, 2.5, np.nan]]),
                   ("A0", "A1", "A2", "A3"), "tag")
    rows = RangeMeasurement.epochs(log)
    assert len(rows) == 2 and np.array_equal(rows[1], log.range_m[1], equal_nan=True)


@pytest.mark.parametrize("name", [n for n in TWINS if n.startswith("ekf.RangeEkf.run[")])
def test_compiled_run_equals_the_python_loop(name, monkeypatch):
    # from a later start through run_ranges (the twin starts at 0 in the kernel): the compiled run against the
    # Python loop it declines to (kernels.run returns None)
    twin = TWINS[name]
    ekf, log, x0 = twin.inputs()
    fast = run_ranges(ekf, log, x0, start=5, name="R")
    declined = []
    monkeypatch.setattr(kernels, "run", lambda *args: declined.append(args[5]) or None)
    slow = run_ranges(ekf, log, x0, start=5, name="R")
    assert declined == [5] and np.isnan(fast.x_post[:5]).all() and (fast.status[:5] == EstimateStatus.NO_ESTIMATE).all()
    fields = ("x_prior", "P_prior", "x_post", "P_post", "F", "nis", "dof", "status", "n_rejected")
    assert not twin.mismatches({f: getattr(fast, f) for f in fields}, {f: getattr(slow, f) for f in fields})
    assert (fast.name, fast.pos_index, fast.vel_index) == (slow.name, slow.pos_index, slow.vel_index)


def test_a_sequential_robust_update_takes_the_python_loop():
    ekf, log, x0 = TWINS["ekf.RangeEkf.run[anchor dropping, RF 2-D]"].inputs()
    robust = Ekf(ekf.transition, ekf.measurement, gate=Robust(gate=ekf.gate))
    sequential = Ekf(ekf.transition, ekf.measurement, gate=Robust(gate=ekf.gate), sequential=True)
    assert kernels.run(sequential, log.t_s, log.range_m, None, x0, 0, "R") is None
    assert kernels.run(robust, log.t_s, log.range_m, None, x0, 0, "R") is not None
