"""The particle engine (:class:`uwbwb.filters.particle.ParticleFilter`): against the Kalman filter on a
linear-Gaussian case, its resampling rule, its batch axes, its hooks, and the set-noise PF's steps."""

import numpy as np
import pytest

from uwbwb.filters import particle as P
from uwbwb.filters import setnoise as F
from uwbwb.filters.twins import setnoise_case
from uwbwb.models.motion import VelocityKick

Q_M2PS, R_M2 = 0.5, 0.3          # random-walk intensity (m²/s) and measurement variance (m²)


def _walk(particles, dt_s, *, rng):
    """1-D random walk ``x ← x + N(0, q·dt)``."""
    return particles + np.sqrt(Q_M2PS * dt_s) * rng.standard_normal(particles.shape)


def _gauss(particles, z):
    """``log N(z; x, r)`` up to a constant, for particles ``(..., K, 1)`` and ``z (...)``."""
    return -0.5 * (particles[..., 0] - np.asarray(z)[..., None]) ** 2 / R_M2


def _still(particles, dt_s, *, rng):
    return particles


def _kalman(t, z, m0, p0):
    m, p, out = m0, p0, []
    for k in range(t.size):
        if k:
            p = p + Q_M2PS * (t[k] - t[k - 1])
        g = p / (p + R_M2)
        m, p = m + g * (z[k] - m), (1 - g) * p
        out.append((m, p))
    return np.array(out).T


def test_linear_gaussian_mean_matches_the_kalman_filter_within_monte_carlo_error():
    rng = np.random.default_rng(11)
    t = np.cumsum(rng.uniform(0.05, 0.2, 40))
    x = np.cumsum(np.sqrt(Q_M2PS * np.diff(t, prepend=t[0])) * rng.standard_normal(t.size))
    z = x + np.sqrt(R_M2) * rng.standard_normal(t.size)
    K = 4000
    prior = rng.normal(0.0, 1.0, (K, 1))                        # N(0, 1) prior, as the KF's
    run = P.ParticleFilter(_walk, _gauss).run(prior, np.full(K, -np.log(K)), t, list(z), rng=rng)
    m, p = _kalman(t, z, 0.0, 1.0)
    assert run.estimate.shape == (t.size, 1) and run.ess.shape == run.resampled.shape == (t.size,)
    # Monte Carlo error of the mean ~ σ/√ESS ≈ 0.02 σ; 0.15 σ leaves a wide margin, a wrong update does not
    assert np.max(np.abs(run.estimate[:, 0] - m) / np.sqrt(p)) < 0.15
    assert run.resampled.any() and not run.resampled.all()      # the ESS rule acted, and not at every fix
    wrong = P.ParticleFilter(_walk, lambda x, z: 0.5 * _gauss(x, z)).run(     # the variance doubled
        prior, np.full(K, -np.log(K)), t, list(z), rng=np.random.default_rng(11))
    assert np.max(np.abs(wrong.estimate[:, 0] - m) / np.sqrt(p)) > 0.15


def test_resamples_exactly_the_rows_whose_ess_falls_below_the_threshold():
    K = 100
    x = np.broadcast_to(np.linspace(-1.0, 1.0, K)[:, None], (3, K, 1)).copy()
    flat = np.full((3, K), -np.log(K))
    sharp = [0.0, 20.0, 0.1]         # per-row likelihood sharpness: flat, peaked, mild

    def ll(particles, z):
        return -np.asarray(sharp)[:, None] * particles[..., 0] ** 2 * z
    pf = P.ParticleFilter(_still, ll, ess_fraction=0.5)
    new_x, new_logw, ep = pf.step(x, flat, None, 1.0, rng=np.random.default_rng(0))
    expected_ess = P.effective_sample_size(flat + ll(x, 1.0))
    np.testing.assert_allclose(ep.ess, expected_ess)
    assert expected_ess[1] < 0.5 * K < expected_ess[2]
    np.testing.assert_array_equal(ep.resampled, expected_ess < 0.5 * K)
    np.testing.assert_array_equal(new_x[[0, 2]], x[[0, 2]])       # kept rows: same particles, their weights
    np.testing.assert_allclose(new_logw[1], -np.log(K))
    assert np.ptp(new_logw[2]) > 0 and np.abs(new_x[1]).max() < 1.0     # the peaked row drew from the centre
    never = P.ParticleFilter(_still, ll, ess_fraction=0.0).step(x, flat, None, 1.0, rng=np.random.default_rng(0))
    assert not never[2].resampled.any()


def test_batch_rows_are_filtered_independently():
    # a noiseless transition and no resampling: no random number is shared, so every row of a
    # batch is the filter run on that row alone, bit for bit
    rng = np.random.default_rng(4)
    t = np.arange(6.0)
    z = rng.normal(size=(6, 4))
    x = rng.normal(size=(4, 50, 1))
    logw = rng.normal(size=(4, 50))
    pf = P.ParticleFilter(_still, _gauss, ess_fraction=0.0)
    batch = pf.run(x, logw, t, list(z), rng=np.random.default_rng(0))
    assert batch.estimate.shape == (4, 6, 1) and batch.ess.shape == (4, 6)
    for i in range(4):
        one = pf.run(x[i], logw[i], t, list(z[:, i]), rng=np.random.default_rng(1))
        np.testing.assert_array_equal(batch.estimate[i], one.estimate)
        np.testing.assert_array_equal(batch.ess[i], one.ess)
    # with noise, the same seed gives the same numbers
    a, b = (P.ParticleFilter(_walk, _gauss).run(x, logw, t, list(z), rng=np.random.default_rng(9)) for _ in "ab")
    np.testing.assert_array_equal(a.estimate, b.estimate)


def test_prediction_times_follow_t0():
    seen = []

    def record(particles, dt_s, *, rng):
        seen.append(dt_s)
        return particles
    pf = P.ParticleFilter(record, _gauss)
    x, logw = np.zeros((5, 1)), np.zeros(5)
    pf.run(x, logw, [1.0, 1.5, 3.0], [0.0, 0.0, 0.0], rng=np.random.default_rng(0))
    assert seen == [0.5, 1.5]                                       # no prediction before the first update
    seen.clear()
    pf.run(x, logw, [1.0, 1.5, 3.0], [0.0, 0.0, 0.0], rng=np.random.default_rng(0), t0_s=1.0)
    assert seen == [0.0, 0.5, 1.5]                                  # the cloud's own time given: predict over 0 s
    with pytest.raises(ValueError, match="non-decreasing"):
        pf.run(x, logw, [1.0, 0.5], [0.0, 0.0], rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="no epochs"):
        pf.run(x, logw, [], [], rng=np.random.default_rng(0))


def test_constraint_zeroes_impossible_particles_and_restarts_a_lost_row():
    def positive(particles, logw, *, rng):
        ok = particles[..., 0] > 0
        lost = ~ok.any(axis=-1)
        particles = np.where(lost[..., None, None], rng.uniform(0.0, 1.0, particles.shape), particles)
        return particles, np.where(ok | lost[..., None], logw, -np.inf), lost
    x = np.stack([np.linspace(-1.0, 1.0, 40), np.linspace(-2.0, -1.0, 40)])[..., None]
    pf = P.ParticleFilter(_still, _gauss, constrain=positive, ess_fraction=0.0)
    _, logw, ep = pf.step(x, np.zeros((2, 40)), None, np.zeros(2), rng=np.random.default_rng(0))
    np.testing.assert_array_equal(ep.restarted, [False, True])
    assert np.all(np.isneginf(logw[0][x[0, :, 0] <= 0])) and np.all(np.isfinite(logw[1]))
    assert np.all(ep.estimate > 0)


def test_tempering_keeps_the_requested_ess_and_is_off_by_default():
    K = 500
    x = np.random.default_rng(2).uniform(-5.0, 5.0, (2, K, 1))
    sharp = lambda particles, z: -0.5 * (particles[..., 0] - z) ** 2 / 1e-4     # noqa: E731
    full = P.ParticleFilter(_still, sharp, ess_fraction=0.0).step(x, np.zeros((2, K)), None, 0.0,
                                                                  rng=np.random.default_rng(0))[2]
    tempered = P.ParticleFilter(_still, sharp, ess_fraction=0.0, temper_ess=0.1).step(
        x, np.zeros((2, K)), None, 0.0, rng=np.random.default_rng(0))[2]
    np.testing.assert_array_equal(full.beta, 1.0)
    assert np.all(full.ess < 0.1 * K)
    assert np.all(tempered.beta < 1.0) and np.all(tempered.ess >= 0.1 * K)
    assert np.all(tempered.ess < 0.11 * K)                          # the largest β that keeps it, not a smaller one


def test_reference_pf_is_the_textbook_steps_bit_for_bit():
    t, z, mu, sd, truth = setnoise_case(40)
    for resampler in P.RESAMPLERS:
        rng = np.random.default_rng(3)
        ref = F.reference_pf(t, z, mu, sd, truth[0], 0.2, rng=rng, n_particles=200, resampler=resampler)
        after = rng.random()
        rng = np.random.default_rng(3)                              # the steps written out, one epoch at a time
        motion, state = VelocityKick(0.2, dim=2), F.pf_init(truth[0], 200)
        est, ess, res = [], [], []
        for k in range(t.size):
            if k:
                state = F.pf_predict(state, t[k] - t[k - 1], motion, rng=rng)
            state = F.pf_update(state, z[k], mu[k], sd[k])
            est.append(F.pf_estimate(state))
            ess.append(P.effective_sample_size(state.logw))
            state, done = F.pf_resample(state, rng=rng, method=resampler)
            res.append(done)
        np.testing.assert_array_equal(ref.state, est)
        np.testing.assert_array_equal(ref.ess, ess)
        np.testing.assert_array_equal(ref.resampled, res)
        assert rng.random() == after                                # the same number of draws
        assert 3 < ref.resampled.sum() < t.size


@pytest.mark.parametrize("kw, match", [({"ess_fraction": 1.5}, "ess_fraction"), ({"method": "stratified"}, "method"),
                                       ({"temper_ess": 1.0}, "temper_ess"), ({"roughening": -0.1}, "roughening"),
                                       ({"constrain": 3}, "constrain")])
def test_bad_settings_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        P.ParticleFilter(_still, _gauss, **kw)
