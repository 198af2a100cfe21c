import numpy as np
import pytest

from uwbwb.filters import kalman
from uwbwb.filters import setnoise as F
from uwbwb.filters.twins import setnoise_case
from uwbwb.models.motion import VelocityKick
from uwbwb.models.setnoise import SetNoiseModel
from uwbwb.types import SetFixLog

_case = setnoise_case   # a straight-line run through a two-set model: (t, z, mu, sigma, truth)


# --------------------------------------------------------------------------- steps

def test_predict_is_eq3():
    state = F.pf_init([1.0, 2.0], 4)
    p = state.particles.copy()
    p[:, 2:] = [[0.5, -0.25]] * 4
    moved = F.pf_predict(F.ParticleState(p, state.logw), 0.2, VelocityKick(0.0), rng=np.random.default_rng(0))
    np.testing.assert_allclose(moved.particles[:, :2], [[1.1, 1.95]] * 4)   # old velocity moves the position
    np.testing.assert_allclose(moved.particles[:, 2:], [[0.5, -0.25]] * 4)
    kicked = F.pf_predict(F.pf_init([0.0, 0.0], 20000), 0.1, VelocityKick(0.3), rng=np.random.default_rng(1))
    np.testing.assert_allclose(kicked.particles[:, :2], 0.0)            # positions see the kick one step later
    np.testing.assert_allclose(kicked.particles[:, 2:].std(0), 0.3, rtol=0.03)


def test_update_weights_are_eq9_normalised():
    p = np.zeros((3, 4))
    p[:, 0] = [0.0, 0.5, 1.0]
    state = F.ParticleState(p, np.full(3, -np.log(3)))
    out = F.pf_update(state, [0.6, 0.1], [0.1, 0.1], [0.5, 1.0])
    # x-residuals (x + 0.1 - 0.6)/0.5 = -1, 0, 1 ; y-residual (0 + 0.1 - 0.1) = 0
    w = np.exp(-0.5 * np.array([1.0, 0.0, 1.0]))
    np.testing.assert_allclose(np.exp(out.logw), w / w.sum())
    np.testing.assert_allclose(F.pf_estimate(out)[0], 0.5)


# --------------------------------------------------------------------------- implementations agree

@pytest.mark.parametrize("resampler", ["multinomial", "systematic"])
def test_sweep_reproduces_the_reference_filter(resampler):
    t, z, mu, sd, truth = _case(T=40)
    ref = F.reference_pf(t, z, mu, sd, truth[0], 0.2, rng=np.random.default_rng(7).spawn(1)[0],
                         n_particles=300, resampler=resampler)
    sw = F.pf_sweep(t, z, mu, sd, truth[0], 0.2, rng=np.random.default_rng(7), n_particles=300,
                    resampler=resampler, dtype=np.float64)
    assert ref.resampled.sum() > 3                                  # the comparison covers resampling
    np.testing.assert_allclose(sw.pos_m[0, 0, 0], ref.pos_m, atol=1e-9)
    assert sw.n_resampled[0, 0, 0] == ref.resampled.sum()
    assert sw.ess_mean[0, 0, 0] == pytest.approx(ref.ess.mean())


def test_sweep_trials_do_not_depend_on_blocking_and_seed_reproduces():
    t, z, mu, sd, truth = _case(T=30)
    args = (t, z, np.stack([mu, mu]), np.stack([sd, 2 * sd]), truth[0], [0.1, 0.4])
    one_block = F.pf_sweep(*args, rng=np.random.default_rng(3), n_trials=3, n_particles=100)
    per_trial = F.pf_sweep(*args, rng=np.random.default_rng(3), n_trials=3, n_particles=100, block_particles=1)
    np.testing.assert_allclose(one_block.pos_m, per_trial.pos_m, atol=1e-5)
    np.testing.assert_array_equal(one_block.n_resampled, per_trial.n_resampled)
    threaded = F.pf_sweep(*args, rng=np.random.default_rng(3), n_trials=3, n_particles=100, block_particles=1,
                          n_threads=2)
    np.testing.assert_array_equal(threaded.pos_m, per_trial.pos_m)
    again = F.pf_sweep(*args, rng=np.random.default_rng(3), n_trials=3, n_particles=100)
    np.testing.assert_array_equal(one_block.pos_m, again.pos_m)
    other = F.pf_sweep(*args, rng=np.random.default_rng(4), n_trials=3, n_particles=100)
    assert not np.allclose(one_block.pos_m, other.pos_m)
    assert one_block.pos_m.shape == (2, 3, 2, 30, 2)
    assert not np.allclose(one_block.pos_m[:, 0], one_block.pos_m[:, 1])  # trials are independent


def test_independent_noise_option_gives_a_valid_filter():
    t, z, mu, sd, truth = _case(T=60)
    kf = F.kf_sweep(t, z, mu, sd, truth[0], 0.2).pos_m[0]
    for crn in (True, False):
        sw = F.pf_sweep(t, z, mu, sd, truth[0], [0.2, 0.2], rng=np.random.default_rng(5), n_trials=4,
                        n_particles=2000, common_random_numbers=crn)
        gap = np.sqrt(np.mean((sw.pos_m[0] - kf) ** 2))
        assert gap < 0.02, (crn, gap)
        # the process noise is common, the resampling variates are not: without resampling,
        # two runs with the same σ_d coincide exactly under CRN
        never = F.pf_sweep(t[:10], z[:10], mu[:10], sd[:10], truth[0], [0.2, 0.2], rng=np.random.default_rng(5),
                           n_particles=50, common_random_numbers=crn, ess_fraction=0.0)
        assert np.array_equal(never.pos_m[0, 0, 0], never.pos_m[0, 0, 1]) == crn


# --------------------------------------------------------------------------- Kalman filter

def test_kf_sweep_matches_the_filterpy_edge_step_by_step():
    t, z, mu, sd, truth = _case(T=25)
    sigma_d = 0.3
    res = F.kf_sweep(t, z, mu, sd, truth[0], [0.05, sigma_d])
    motion = VelocityKick(sigma_d)
    state = kalman.Gaussian(motion.initial_state(truth[0]), np.zeros((4, 4)))
    for k in range(t.size):
        if k:
            state = kalman.predict(state, motion.F(t[k] - t[k - 1]), motion.Q(t[k] - t[k - 1]))
        state, inn = kalman.update(state, z[k] - mu[k], motion.H_pos, np.diag(sd[k] ** 2))
        np.testing.assert_allclose(res.state[1, k], state.x, atol=1e-12)
        np.testing.assert_allclose(res.cov[1, k], state.P, atol=1e-12)
        assert res.nis[1, k] == pytest.approx(inn.nis, abs=1e-9)


def test_kf_leading_model_axes_and_known_start():
    t, z, mu, sd, truth = _case(T=20)
    res = F.kf_sweep(t, z, np.stack([mu, 0 * mu]), np.stack([sd, sd]), truth[0], [0.1, 0.2, 0.3])
    assert res.state.shape == (2, 3, 20, 4) and res.cov.shape == (2, 3, 20, 4, 4)
    np.testing.assert_allclose(res.pos_m[..., 0, :], np.broadcast_to(truth[0], (2, 3, 2)))  # P0 = 0
    assert res.mean_error_m(truth).shape == (2, 3)


def test_pf_converges_to_kf_as_K_grows():
    t, z, mu, sd, truth = _case(T=80)
    kf = F.kf_sweep(t, z, mu, sd, truth[0], 0.3).pos_m[0]
    gaps = []
    for K in (50, 3000):
        sw = F.pf_sweep(t, z, mu, sd, truth[0], 0.3, rng=np.random.default_rng(11), n_trials=6, n_particles=K)
        gaps.append(np.sqrt(np.mean((sw.pos_m[0, :, 0] - kf) ** 2)))
    assert gaps[1] < 0.4 * gaps[0]
    assert gaps[1] < 0.01


def test_set_noise_filters_beat_raw_and_baseline_on_model_data():
    t, z, mu, sd, truth = _case(T=150, seed=4)
    raw = np.linalg.norm(z - truth, axis=1).mean()
    fixed = np.broadcast_to([0.0, 0.0], mu.shape)
    wide = np.broadcast_to([0.2, 0.2], sd.shape)
    kf = F.kf_sweep(t, z, np.stack([fixed, mu]), np.stack([wide, sd]), truth[0], 0.1).mean_error_m(truth)[:, 0]
    assert kf[1] < kf[0] < raw


# --------------------------------------------------------------------------- one-run wrappers and checks

def test_run_wrappers_use_the_model():
    t, z, mu, sd, truth = _case(T=30)
    sets = np.where(mu[:, 0] > 0, 3, 5)
    fixes = SetFixLog(t, z, sets, tuple("01234567"), truth, "rec")
    model = SetNoiseModel([3, 5], [[0.08, -0.03], [-0.05, 0.06]], [[0.10, 0.08], [0.15, 0.12]], [50, 50],
                          [0.0, 0.0], [0.2, 0.2], 100)
    pf = F.run_set_noise_pf(fixes, model, truth[0], 0.2, rng=np.random.default_rng(0), n_particles=200)
    base = F.run_set_noise_pf(fixes, model.facility_only(), truth[0], 0.2, rng=np.random.default_rng(0),
                              n_particles=200)
    kf = F.run_set_noise_kf(fixes, model, truth[0], 0.2)
    assert (pf.name, base.name, kf.name) == ("set-noise PF", "baseline PF", "set-noise KF")
    df = pf.to_frame()
    assert list(df.columns) == ["t_s", "x_m", "y_m", "vx_mps", "vy_mps", "ess", "resampled"]
    assert np.all((df["ess"] >= 1) & (df["ess"] <= 200))
    assert not np.allclose(pf.pos_m, base.pos_m)
    assert np.isnan(kf.ess).all() and kf.pos_m.shape == (30, 2)


def test_bad_arguments_are_reported():
    t, z, mu, sd, truth = _case(T=10)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="ess_fraction must be a number in \\[0, 1\\]"):
        F.pf_sweep(t, z, mu, sd, truth[0], 0.1, rng=rng, ess_fraction=50)
    with pytest.raises(ValueError, match="unknown resampler"):
        F.reference_pf(t, z, mu, sd, truth[0], 0.1, rng=rng, resampler="residual")
    with pytest.raises(ValueError, match="strictly increasing"):
        F.kf_sweep(t[::-1], z, mu, sd, truth[0], 0.1)
    with pytest.raises(ValueError, match="positive"):
        F.kf_sweep(t, z, mu, 0 * sd, truth[0], 0.1)
    with pytest.raises(ValueError, match="shape"):
        F.pf_sweep(t, z[:5], mu, sd, truth[0], 0.1, rng=rng)
    with pytest.raises(ValueError, match="one filter"):
        F.reference_pf(t, z, np.stack([mu, mu]), np.stack([sd, sd]), truth[0], 0.1, rng=rng)


def test_filter_runs_give_the_common_result_type():
    t, z, mu, sd, truth = _case(T=30)
    sets = np.where(mu[:, 0] > 0, 3, 5)
    fixes = SetFixLog(t, z, sets, tuple("01234567"), truth, "rec")
    model = SetNoiseModel([3, 5], [[0.08, -0.03], [-0.05, 0.06]], [[0.10, 0.08], [0.15, 0.12]], [50, 50],
                          [0.0, 0.0], [0.2, 0.2], 100)
    kf = F.run_set_noise_kf(fixes, model, truth[0], 0.2)
    est = kf.to_estimates()
    assert est.name == "set-noise KF" and (est.status == 0).all()
    np.testing.assert_array_equal(est.pos_m, kf.pos_m)
    np.testing.assert_array_equal(est.vel_mps, kf.state[:, 2:])
    np.testing.assert_array_equal(est.pos_cov_m2, kf.meta["cov"][:, :2, :2])
    np.testing.assert_array_equal(est.info["nis"], kf.meta["nis"])
    assert est.info["dof"].tolist() == [2] * t.size
    pf = F.run_set_noise_pf(fixes, model, truth[0], 0.2, rng=np.random.default_rng(0), n_particles=200).to_estimates()
    assert pf.pos_cov_m2 is None and set(pf.info) == {"ess", "resampled"} and pf.coverage == 1.0


def test_kf_run_keeps_covariance_and_nis_as_fields_and_meta_reads_them():
    t, z, mu, sd, truth = _case(T=30)
    fixes = SetFixLog(t, z, np.where(mu[:, 0] > 0, 3, 5), tuple("01234567"), truth, "rec")
    model = SetNoiseModel([3, 5], [[0.08, -0.03], [-0.05, 0.06]], [[0.10, 0.08], [0.15, 0.12]], [50, 50],
                          [0.0, 0.0], [0.2, 0.2], 100)
    kf = F.run_set_noise_kf(fixes, model, truth[0], 0.2)
    sweep = F.kf_sweep(t, z, *F.model_noise(fixes, model), truth[0], 0.2)
    np.testing.assert_array_equal(kf.cov, sweep.cov[0])
    np.testing.assert_array_equal(kf.nis, sweep.nis[0])
    assert kf.meta["cov"] is kf.cov and kf.meta["nis"] is kf.nis and kf.dof.tolist() == [2] * t.size
    assert kf.nis_consistency()["n"] == t.size and kf.nis_consistency()["sum_dof"] == 2 * t.size
    old = F.FilterRun(kf.t_s, kf.state, kf.ess, kf.resampled, "old", {"cov": kf.cov, "nis": kf.nis})
    assert old.cov is kf.cov and old.nis is kf.nis                       # an older caller's meta still works
    pf = F.run_set_noise_pf(fixes, model, truth[0], 0.2, rng=np.random.default_rng(0), n_particles=50)
    assert pf.cov is None and pf.nis is None and pf.dof is None and "cov" not in pf.meta
    with pytest.raises(ValueError, match="together"):
        F.FilterRun(kf.t_s, kf.state, kf.ess, kf.resampled, cov=kf.cov)
    with pytest.raises(ValueError, match="shape"):
        F.FilterRun(kf.t_s, kf.state, kf.ess, kf.resampled, cov=kf.cov[:, :2, :2], nis=kf.nis)
