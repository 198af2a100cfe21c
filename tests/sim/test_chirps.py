import numpy as np
import pytest

from uwbwb.models import doppler as dm
from uwbwb.sim import chirps as sc


@pytest.fixture(scope="module")
def model():
    return dm.DopplerModel.for_layout(dm.cubic_layout())


def _clean(model, track, duration_s, seed=0):
    return sc.simulate_chirps(model, track, duration_s, rng=np.random.default_rng(seed), jitter=False,
                              p_miss=0.0, spurious_rate_hz=0.0, chirp_s=0.0)


def test_eq1_matches_finite_differences_of_simulated_arrivals(model):
    """Constant velocity: the period between two arrivals minus P is eq 1 at the middle of the period."""
    track = sc.LineTrack((-1.0, 0.3, 0.2), (0.5, 0.7, 0.1))
    rec = _clean(model, track, 4.0)
    checked, err_mid, err_end = 0, [], []
    for i in range(model.n_beacons):
        t = rec.t_s[rec.source == i]
        np.testing.assert_allclose(np.diff(rec.emit_s[rec.source == i]), model.period_s[i], atol=1e-12)
        dp_sim = np.diff(t) - model.period_s[i]
        dp_eq1 = model.delta_p(track.pos_m(t[1:]), track.vel(t[1:]), np.full(t.size - 1, i), instantaneous=False)
        np.testing.assert_allclose(dp_sim, dp_eq1, atol=5e-3 * np.abs(dp_sim).max())   # 0.5 % of ΔP
        assert np.abs(dp_sim).max() > 1e-4
        err_mid.append(np.abs(dp_sim - dp_eq1))
        err_end.append(np.abs(dp_sim - model.delta_p(track.pos_m(t[1:]), track.vel(t[1:]), np.full(t.size - 1, i))))
        checked += t.size - 1
    assert checked > 40
    # the period is an average: eq 1 at the middle of the period fits far better than at its end
    assert np.mean(np.concatenate(err_mid)) < 0.2 * np.mean(np.concatenate(err_end))


def test_arrivals_carry_the_propagation_delay(model):
    track = sc.LineTrack((0.0, 0.0, 0.0), (0.3, -0.2, 0.0))
    rec = _clean(model, track, 2.0)
    T = model.beacons.pos_m[rec.source]
    np.testing.assert_allclose(rec.t_s - rec.emit_s, np.linalg.norm(track.pos_m(rec.t_s) - T, axis=1) / model.v_s_mps,
                               rtol=1e-12)


def test_misses_spurious_and_collisions_are_counted(model):
    track, _ = sc.rectangle_track()
    rec = sc.simulate_chirps(model, track, 200.0, rng=np.random.default_rng(3), p_miss=0.2, spurious_rate_hz=2.0,
                             chirp_s=0.01)
    c = rec.counts
    assert c["missed"] / c["emitted"] == pytest.approx(0.2, abs=0.03)
    assert c["spurious"] == pytest.approx(400, abs=70)
    assert c["collided"] > 0
    assert c["detected"] == c["emitted"] - c["missed"] + c["spurious"] - c["collided"] == rec.t_s.size
    assert np.all(np.diff(rec.t_s) >= 0.01)
    assert np.all(np.isnan(rec.emit_s[rec.source < 0]))


def test_same_seed_same_recording(model):
    track, _ = sc.rectangle_track()
    a = sc.simulate_chirps(model, track, 10.0, rng=np.random.default_rng(5))
    b = sc.simulate_chirps(model, track, 10.0, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(a.t_s, b.t_s)
    np.testing.assert_array_equal(a.source, b.source)


def test_rectangle_is_walked_clockwise_with_corners_three_seconds_apart():
    track, apex = sc.rectangle_track()
    t_bl = track.time_at(apex["bottom-left"])
    t_tl = track.time_at(apex["top-left"], after_s=t_bl)
    assert t_tl - t_bl == pytest.approx(3.0, abs=1e-3)
    assert track.vel(t_bl + 1.5)[1] > 0.5 * track.speed_mps         # going up the left side
    np.testing.assert_allclose(np.linalg.norm(track.vel(np.linspace(0, 20, 50)), axis=1), track.speed_mps)
    p = track.pos_m(t_bl)
    assert p[0] < -1.3 and p[1] < -0.8


@pytest.mark.parametrize("kwargs, name", [({"p_miss": 1.0}, "p_miss"), ({"p_miss": -0.1}, "p_miss"),
                                          ({"spurious_rate_hz": -1.0}, "spurious_rate_hz"),
                                          ({"chirp_s": np.nan}, "chirp_s"), ({"phase_s": np.zeros(3)}, "phase_s")])
def test_bad_simulator_parameters_are_named(model, kwargs, name):
    track, _ = sc.rectangle_track()
    with pytest.raises(ValueError, match=name):
        sc.simulate_chirps(model, track, 2.0, rng=np.random.default_rng(0), **kwargs)
    with pytest.raises(ValueError, match="duration_s"):
        sc.simulate_chirps(model, track, -1.0, rng=np.random.default_rng(0))
