import numpy as np
import pytest

from uwbwb.models.ins import GRAVITY_MPS2
from uwbwb.sim import robot


def test_motion_is_consistent_and_follows_the_paper_path():
    m = robot.broken_line()
    t = np.arange(0.0, m.duration_s, 0.01)
    pos, vel, acc, yaw, rate = m.state(t)
    h = 1e-5
    p1, v1, _, y1, _ = m.state(t + h)
    p0, v0, _, y0, _ = m.state(t - h)
    inner = (t > h) & (t < m.duration_s - h)
    np.testing.assert_allclose(((p1 - p0) / (2 * h))[inner], vel[inner], atol=1e-5)
    np.testing.assert_allclose(((v1 - v0) / (2 * h))[inner], acc[inner], atol=1e-4)
    np.testing.assert_allclose(((y1 - y0) / (2 * h))[inner], rate[inner], atol=1e-4)
    assert np.linalg.norm(vel[:, :2], axis=1).max() == pytest.approx(0.3, abs=1e-9)
    for w in robot.PAPER_WAYPOINTS_M:                       # passes every waypoint
        assert np.linalg.norm(pos[:, :2] - w, axis=1).min() < 1e-3
    turns = [s for s in m.segments if s[0] == "turn"]
    assert len(turns) == 4 and [np.sign(s[3]["dyaw"]) for s in turns] == [1, -1, 1, -1]
    assert set(np.round(np.degrees(yaw), 6)) >= {0.0, 90.0}


def test_ideal_imu_at_rest_reads_gravity_up():
    f, w, _, _ = robot.ideal_imu(robot.hold(duration_s=1.0), np.arange(0, 1.0, 0.01))
    np.testing.assert_allclose(f, np.tile([0, 0, GRAVITY_MPS2], (len(f), 1)))
    np.testing.assert_allclose(w, 0.0)


def test_simulation_degradations_and_reproducibility():
    cfg = robot.RobotConfig(outage_start_s=5.0, outage_s=3.0, nlos_station=2, nlos_start_s=10.0, nlos_s=2.0)
    a = robot.simulate(robot.broken_line(), cfg, rng=np.random.default_rng(1))
    b = robot.simulate(robot.broken_line(), cfg, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(a.tdoa.tdoa_m, b.tdoa.tdoa_m)
    np.testing.assert_array_equal(a.imu.acc_mps2, b.imu.acc_mps2)
    assert np.all(a.tdoa.n_tdoa[a.outage] <= 1) and a.outage.sum() == pytest.approx(3.0 * 50, abs=1)
    true_r = cfg.tdoa_model().ranges(a.truth.pos_m)
    res = a.ranges.range_m - true_r
    assert np.all(res[a.outlier] > 0.25)                     # multipath excess is positive
    clean = ~a.outlier & np.isfinite(res)
    clean[:, 2] &= ~a.nlos
    assert abs(np.nanstd(res[clean]) - cfg.sigma_toa_m) < 0.005
    assert np.nanmedian(res[a.nlos & ~a.outlier[:, 2], 2]) == pytest.approx(cfg.nlos_bias_m, abs=0.02)
    assert a.imu.t_s.size == pytest.approx(a.motion.duration_s * cfg.imu_rate_hz, abs=2)


def test_config_is_checked():
    with pytest.raises(ValueError, match="imu_rate_hz"):
        robot.RobotConfig(imu_rate_hz=10.0)
    with pytest.raises(ValueError, match="too short"):
        robot.broken_line(((0, 0), (0.1, 0)))
