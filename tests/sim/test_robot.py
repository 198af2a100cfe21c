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


def test_gauss_markov_bias_has_its_sigma_and_correlation_time():
    b = robot.gauss_markov(20000, 4, sigma=0.05, tau_s=30.0, dt_s=0.02, rng=np.random.default_rng(2))
    assert b.shape == (20000, 4)
    assert np.std(b[0]) < 0.2                                  # starts stationary, not at zero
    lag = 50                                                   # 1 s: correlation exp(-1/30)
    x, y = b[:-lag].ravel(), b[lag:].ravel()
    assert np.corrcoef(x, y)[0, 1] == pytest.approx(np.exp(-1 / 30), abs=0.02)
    long = robot.gauss_markov(200000, 1, sigma=0.05, tau_s=1.0, dt_s=0.02, rng=np.random.default_rng(3))
    assert np.std(long) == pytest.approx(0.05, rel=0.05)


def test_range_bias_is_added_only_when_asked_and_leaves_the_other_draws_alone():
    motion = robot.hold(duration_s=20.0)
    plain = robot.simulate(motion, robot.RobotConfig(outlier_rate=0.0), rng=np.random.default_rng(5))
    biased = robot.simulate(motion, robot.RobotConfig(outlier_rate=0.0, range_bias_sigma_m=0.05),
                            rng=np.random.default_rng(5))
    np.testing.assert_array_equal(plain.imu.acc_mps2, biased.imu.acc_mps2)
    d = biased.ranges.range_m - plain.ranges.range_m           # the bias itself: smooth, ~5 cm
    ok = np.isfinite(d)
    assert 0.01 < np.nanstd(d) < 0.15 and np.nanmax(np.abs(np.diff(np.where(ok, d, 0), axis=0)[ok[1:] & ok[:-1]])) < 0.02
    with pytest.raises(ValueError, match="range_bias_tau_s"):
        robot.RobotConfig(range_bias_tau_s=0.0)
    with pytest.raises(ValueError, match="outlier_excess_m"):
        robot.RobotConfig(outlier_excess_m=(2.0, 1.0))


def test_mismatch_changes_the_world_not_the_model():
    from uwbwb.sim import mismatch

    model = robot.RobotConfig()
    assert mismatch.case("matched").matched and mismatch.case("matched").world(model) == model
    w = mismatch.case("IMU 10× worse").world(model)
    assert w.imu.acc_noise_density == pytest.approx(10 * model.imu.acc_noise_density)
    assert w.imu.mag_heading_sigma_rad == model.imu.mag_heading_sigma_rad
    assert mismatch.case("UWB σ 2×").world(model).sigma_toa_m == pytest.approx(2 * model.sigma_toa_m)
    gm = mismatch.case("range bias GM 5 cm, 30 s").world(model)
    assert (gm.range_bias_sigma_m, gm.range_bias_tau_s) == (0.05, 30.0)
    assert mismatch.case("multipath up to 12 m").world(model).outlier_excess_m == (0.3, 12.0)
    assert not any(c.matched for c in mismatch.CASES[1:])
    with pytest.raises(ValueError, match="unknown mismatch case 'nope'"):
        mismatch.case("nope")
