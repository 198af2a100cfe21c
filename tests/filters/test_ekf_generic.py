"""The generic EKF: linear-case exactness, RTS smoother, NEES/NIS consistency, gating, results."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from uwbwb.filters import kalman
from uwbwb.filters.ekf import Ekf, Linearisation, nis_consistency
from uwbwb.filters.kalman import Gaussian
from uwbwb.models.motion import RandomForce, RandomJerk, ReceiverMotion, VelocityKick
from uwbwb.types import EstimateStatus, Estimates

R_M2 = 0.3 ** 2


class PositionFix:
    """Linear model: the position of a constant-velocity state, measured with noise R (NaN = missing)."""

    def __init__(self, motion, var_m2=R_M2):
        self.H = motion.H_pos
        self.var = var_m2

    def linearise(self, x, z):
        z = np.asarray(z, float)
        if not np.all(np.isfinite(z)):
            return None
        return Linearisation(z, self.H @ x, self.H, self.var * np.eye(z.size))


class RangeToOrigin:
    """Nonlinear model: range from the origin to the position."""

    def __init__(self, motion, var_m2=0.01):
        self.motion, self.var = motion, var_m2

    def linearise(self, x, z):
        p = self.motion.position(x)
        r = np.linalg.norm(p)
        H = np.zeros((1, x.size))
        H[0, : p.size] = p / r
        return Linearisation([z], [r], H, [[self.var]])


def _simulate(motion, T=200, dt=0.1, *, rng):
    t = np.arange(T) * dt
    x = motion.sample_path(motion.initial_state([0.0, 0.0], [1.0, 0.5]), t, rng=rng)
    z = motion.position(x) + np.sqrt(R_M2) * rng.standard_normal((T, motion.dim))
    return t, x, z


def _x0(motion, x_true0, rng):
    P0 = motion.initial_covariance(1.0, 1.0)
    return Gaussian(x_true0 + np.linalg.cholesky(P0) @ rng.standard_normal(motion.n_x), P0)


def test_linear_case_equals_textbook_kalman_loop():
    rng = np.random.default_rng(1)
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    t, x, z = _simulate(motion, rng=rng)
    x0 = _x0(motion, x[0], rng)
    run = Ekf(motion, PositionFix(motion), pos_index=(0, 1), vel_index=(2, 3), gate_prob=None).run(t, z, x0)
    # hand-written textbook loop (no filterpy)
    H, R = motion.H_pos, R_M2 * np.eye(2)
    m, P = x0.x.copy(), x0.P.copy()
    for k in range(t.size):
        if k:
            F, Q = motion.F(t[k] - t[k - 1]), motion.Q(t[k] - t[k - 1])
            m, P = F @ m, F @ P @ F.T + Q
        np.testing.assert_allclose(run.x_prior[k], m, atol=1e-10)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        m, P = m + K @ (z[k] - H @ m), (np.eye(4) - K @ H) @ P
        np.testing.assert_allclose(run.x_post[k], m, atol=1e-9)
        np.testing.assert_allclose(run.P_post[k], P, atol=1e-9)
    assert np.all(run.status == EstimateStatus.UPDATED)
    assert np.all(run.dof == 2)


def test_rts_smoother_equals_the_batch_map_estimate():
    """For a linear-Gaussian model the smoothed means are the joint MAP: solve the whole normal equations."""
    rng = np.random.default_rng(2)
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    t, x, z = _simulate(motion, T=40, rng=rng)
    x0 = _x0(motion, x[0], rng)
    sm = Ekf(motion, PositionFix(motion), pos_index=(0, 1), gate_prob=None).run(t, z, x0).smooth()
    n, T = motion.n_x, t.size
    # information form of -log p(x_0..T-1 | z): prior, dynamics and measurement terms
    A = np.zeros((n * T, n * T))
    b = np.zeros(n * T)
    P0i = np.linalg.inv(x0.P)
    A[:n, :n] += P0i
    b[:n] += P0i @ x0.x
    H, Ri = motion.H_pos, np.eye(2) / R_M2
    for k in range(T):
        s = slice(n * k, n * k + n)
        A[s, s] += H.T @ Ri @ H
        b[s] += H.T @ Ri @ z[k]
        if k:
            F, Qi = motion.F(t[k] - t[k - 1]), np.linalg.inv(motion.Q(t[k] - t[k - 1]))
            p = slice(n * (k - 1), n * k)
            A[p, p] += F.T @ Qi @ F
            A[s, s] += Qi
            A[p, s] -= F.T @ Qi
            A[s, p] -= Qi @ F
    x_map = np.linalg.solve(A, b).reshape(T, n)
    np.testing.assert_allclose(sm.x_post, x_map, atol=1e-7)
    # and the smoothed covariances are the diagonal blocks of the inverse information matrix
    cov = np.linalg.inv(A)
    for k in (0, T // 2, T - 1):
        np.testing.assert_allclose(sm.P_post[k], cov[n * k:n * k + n, n * k:n * k + n], atol=1e-8)


def test_monte_carlo_nees_and_nis_inside_chi2_bounds():
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    ekf = Ekf(motion, PositionFix(motion), pos_index=(0, 1), vel_index=(2, 3), gate_prob=None)
    rng = np.random.default_rng(3)
    n_runs, nees, nis, dof = 50, [], [], []
    for _ in range(n_runs):
        t, x, z = _simulate(motion, T=100, rng=rng)
        run = ekf.run(t, z, _x0(motion, x[0], rng))
        nees.append(run.nees(x))
        nis.append(run.nis)
        dof.append(run.dof)
    mean_nees = np.mean(nees, axis=0)                 # (T,): average over runs, χ²(n_runs·4)/n_runs
    lo, hi = chi2.ppf([0.0005, 0.9995], n_runs * 4) / n_runs
    assert np.mean((mean_nees > lo) & (mean_nees < hi)) > 0.97
    c = nis_consistency(np.concatenate(nis), np.concatenate(dof))
    assert c["verdict"] == "consistent", c


def test_overconfident_filter_is_reported_as_such():
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    rng = np.random.default_rng(4)
    t, x, z = _simulate(motion, T=300, rng=rng)
    small_R = Ekf(motion, PositionFix(motion, var_m2=R_M2 / 10), pos_index=(0, 1), gate_prob=None)
    assert small_R.run(t, z, _x0(motion, x[0], rng)).nis_consistency()["verdict"] == "over-confident"
    large_R = Ekf(motion, PositionFix(motion, var_m2=R_M2 * 10), pos_index=(0, 1), gate_prob=None)
    assert large_R.run(t, z, _x0(motion, x[0], rng)).nis_consistency()["verdict"] == "under-confident"


def test_default_gate_rejects_an_absurd_measurement_and_none_uses_it():
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    rng = np.random.default_rng(5)
    t, x, z = _simulate(motion, T=60, rng=rng)
    z = z.copy()
    z[30] = [1e6, 0.0]
    x0 = _x0(motion, x[0], rng)
    gated = Ekf(motion, PositionFix(motion), pos_index=(0, 1)).run(t, z, x0)
    assert gated.status[30] == EstimateStatus.GATED and gated.dof[30] == 0
    np.testing.assert_array_equal(gated.x_post[30], gated.x_prior[30])
    assert np.abs(gated.x_post[:, :2] - x[:, :2]).max() < 5.0
    blind = Ekf(motion, PositionFix(motion), pos_index=(0, 1), gate_prob=None).run(t, z, x0)
    assert blind.status[30] == EstimateStatus.UPDATED and blind.x_post[30, 0] > 1e4


def test_after_max_gated_epochs_the_filter_takes_the_next_one():
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    rng = np.random.default_rng(6)
    t, x, z = _simulate(motion, T=40, rng=rng)
    z = z + np.where(np.arange(40)[:, None] >= 10, 100.0, 0.0)    # the target "jumps" 100 m at epoch 10
    run = Ekf(motion, PositionFix(motion), pos_index=(0, 1), max_gated=3).run(t, z, _x0(motion, x[0], rng))
    assert list(run.status[10:14]) == [EstimateStatus.GATED] * 3 + [EstimateStatus.UPDATED]


def test_missing_measurements_predict_only_and_nonlinear_update_converges():
    motion = RandomForce(psd_m2ps3=0.01, dim=2)
    rng = np.random.default_rng(7)
    t = np.arange(100) * 0.1
    x = motion.sample_path(motion.initial_state([3.0, 4.0], [0.2, -0.1]), t, rng=rng)
    z = np.linalg.norm(motion.position(x), axis=1)       # ranges to the origin only: weakly observable
    pos_fix = np.full((100, 2), np.nan)
    pos_fix[::10] = motion.position(x)[::10]            # an exact-ish fix every 10th epoch
    lin = PositionFix(motion, var_m2=1e-4)
    rng_model = RangeToOrigin(motion)

    class Both:
        def linearise(self, xs, k):
            a, b = lin.linearise(xs, pos_fix[k]), rng_model.linearise(xs, z[k])
            return b if a is None else Linearisation(np.r_[a.z, b.z], np.r_[a.h, b.h], np.vstack([a.H, b.H]),
                                                     np.diag(np.r_[np.diag(a.R), np.diag(b.R)]))

    run = Ekf(motion, Both(), pos_index=(0, 1)).run(t, np.arange(100), _x0(motion, x[0], rng))
    assert np.linalg.norm(run.x_post[-1, :2] - x[-1, :2]) < 0.1
    only_pred = Ekf(motion, lin, pos_index=(0, 1)).run(t, pos_fix, Gaussian(x[0], motion.initial_covariance(0.1, 0.1)))
    assert set(np.unique(only_pred.status)) == {EstimateStatus.UPDATED, EstimateStatus.PREDICTED}
    assert np.all(only_pred.dof[only_pred.status == EstimateStatus.PREDICTED] == 0)


def test_to_estimates_and_late_start():
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    rng = np.random.default_rng(8)
    t, x, z = _simulate(motion, T=20, rng=rng)
    run = Ekf(motion, PositionFix(motion), pos_index=(0, 1), vel_index=(2, 3)).run(
        t, z, _x0(motion, x[5], rng), start=5, name="EKF-RF")
    est = run.to_estimates()
    assert isinstance(est, Estimates) and est.name == "EKF-RF"
    assert est.coverage == pytest.approx(15 / 20)
    assert np.all(np.isnan(est.pos_m[:5])) and np.all(est.status[:5] == EstimateStatus.NO_ESTIMATE)
    np.testing.assert_array_equal(est.vel_mps[5:], run.x_post[5:, 2:])
    assert est.pos_cov_m2.shape == (20, 2, 2)
    sm = run.smooth()
    assert np.all(np.isnan(sm.x_post[:5])) and np.all(np.isfinite(sm.x_post[5:]))
    frame = est.to_frame()
    assert list(frame["status"][:6]) == ["no_estimate"] * 5 + ["updated"]
    assert len(est.to_trajectory()) == 15


def test_parameters_are_checked():
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    with pytest.raises(ValueError, match="gate_prob"):
        Ekf(motion, PositionFix(motion), pos_index=(0, 1), gate_prob=1.5)
    with pytest.raises(ValueError, match="pos_index"):
        Ekf(motion, PositionFix(motion), pos_index=(0, 9))
    with pytest.raises(ValueError, match="measurements for"):
        Ekf(motion, PositionFix(motion), pos_index=(0, 1)).run(np.arange(3.0), [[0, 0]] * 2,
                                                                 Gaussian(np.zeros(4), np.eye(4)))


def test_kalman_update_refuses_nan_singular_and_negative_noise():
    s = Gaussian([0.0, 0.0], np.eye(2))
    H = np.array([[1.0, 0.0]])
    with pytest.raises(ValueError, match="non-finite"):
        kalman.update(s, [np.nan], H, [[1.0]])
    with pytest.raises(ValueError, match="positive variances"):
        kalman.update(s, [1.0], H, [[-1.0]])
    with pytest.raises(ValueError, match="not positive definite"):
        kalman.update(Gaussian([0.0, 0.0], np.zeros((2, 2))), [1.0, 1.0], np.eye(2), [[1.0, 1.0], [1.0, 1.0]])


def test_estimates_validates_status_and_positions():
    t = np.arange(3.0)
    with pytest.raises(ValueError, match="finite exactly where"):
        Estimates(t, [[0, 0], [np.nan, np.nan], [1, 1]], [0, 0, 0])
    with pytest.raises(ValueError, match="unknown codes"):
        Estimates(t, np.zeros((3, 2)), [0, 7, 0])
    e = Estimates(t, [[0, 0], [np.nan, np.nan], [1, 1]], [0, 3, 1], info={"nis": [1.0, np.nan, 2.0]})
    assert e.coverage == pytest.approx(2 / 3)
    assert e.status_counts() == {"updated": 1, "predicted": 1, "gated": 0, "no_estimate": 1}
    assert len(e.select(e.has_estimate)) == 2


def test_position_components_default_to_the_transition_models_declared_layout():
    for motion, pos in ((RandomForce(1.0, dim=3), (0, 1, 2)), (RandomJerk(1.0, dim=2), (0, 1)),
                        (VelocityKick(0.3), (0, 1)), (ReceiverMotion(), (0, 1, 2))):
        assert Ekf(motion, PositionFix(RandomForce(1.0, dim=len(pos)))).pos_index == pos == motion.layout.pos_index
    assert Ekf(RandomForce(1.0), PositionFix(RandomForce(1.0)), (1, 0)).pos_index == (1, 0)   # explicit wins

    class NoLayout:                       # F and Q only: the position cannot be read from the model
        n_x = 4

        def F(self, dt_s):
            return np.eye(4)

        def Q(self, dt_s):
            return np.eye(4)

    two_d = Ekf(RandomForce(1.0, dim=2), PositionFix(RandomForce(1.0)))
    with pytest.raises(ValueError, match="layout has 3"):       # a resolved default does not follow a new model
        replace(two_d, transition=RandomForce(1.0, dim=3))
    assert replace(two_d, transition=RandomForce(1.0, dim=3), pos_index=None).pos_index == (0, 1, 2)
    with pytest.raises(ValueError, match="declares no state layout"):
        Ekf(NoLayout(), PositionFix(RandomForce(1.0)))
    assert Ekf(NoLayout(), PositionFix(RandomForce(1.0)), (0, 1)).vel_index is None
