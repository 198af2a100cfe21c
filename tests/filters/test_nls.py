"""Resolution routine of Zupanec et al. (eq. 1): P0 + v by nonlinear least squares."""

from __future__ import annotations

import numpy as np
import pytest

from uwbwb import RangeLog
from uwbwb.types import RangeSamples
from uwbwb.filters import nls
from uwbwb.geometry import multilaterate

# six anchors on a ceiling inclined along x (3.9 m .. 4.5 m): coplanar, as in the paper's cafeteria
XY = np.array([[1.0, 1.0], [12.0, 0.5], [18.0, 6.0], [14.0, 11.0], [3.0, 10.0], [8.0, 5.0]])
CEILING = np.column_stack([XY, 3.9 + 0.6 * XY[:, 0] / 18.0])
# the same with scattered heights (not coplanar)
SCATTER = CEILING + np.array([0, 0, 0, 0, 0, 1.5])[:, None] * np.array([0, 0, 1])


def _walk(A, P0, v, *, t_end_s=10.0, dt_s=0.13, sigma_m=0.0, rng=None):
    t = np.arange(0.0, t_end_s, dt_s)
    pos = P0 + np.outer(t, v)
    r = np.linalg.norm(pos[:, None] - A, axis=-1)
    if sigma_m:
        r = r + sigma_m * rng.standard_normal(r.shape)
    return RangeLog(t, r, tuple(str(i + 1) for i in range(len(A))))


def _fd_grad(f, x, h=1e-6):
    g = np.zeros_like(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        g[i] = (f(x + e) - f(x - e)) / (2 * h)
    return g


@pytest.mark.parametrize("method", ["bfgs", "least_squares"])
@pytest.mark.parametrize("anchors", [CEILING, SCATTER], ids=["coplanar", "scattered"])
def test_noise_free_walk_is_recovered_in_3d(method, anchors):
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0])
    fit = nls.fit_trajectory(_walk(anchors, P0, v), anchors, method=method, z_m=1.5)
    assert fit.converged, fit.report()
    np.testing.assert_allclose(fit.p0_m, P0, atol=1e-4)
    np.testing.assert_allclose(fit.vel_mps, v, atol=1e-5)
    assert fit.residual_rms_m < 1e-5 and fit.n_used == 77 * 6


def test_coplanar_anchors_without_height_hint_start_below_the_ceiling():
    P0, v = np.array([9.0, 6.0, 2.0]), np.array([-0.5, 0.2, 0.0])
    fit = nls.fit_trajectory(_walk(CEILING, P0, v), CEILING)       # hint: 1 m below the lowest anchor
    np.testing.assert_allclose(fit.p0_m, P0, atol=1e-4)
    P_init, _ = nls.initial_guess(RangeSamples.from_ranges(_walk(CEILING, P0, v)), CEILING)
    assert P_init[2] < CEILING[:, 2].min()


def test_initial_guess_is_close_and_not_zero(rng):
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0])
    s = RangeSamples.from_ranges(_walk(CEILING, P0, v, sigma_m=0.1, rng=rng))
    P, vel = nls.initial_guess(s, CEILING, z_m=1.3)
    assert np.linalg.norm(P[:2] - P0[:2]) < 0.5 and np.linalg.norm(vel[:2] - v[:2]) < 0.1
    fit = nls.fit_trajectory(s, CEILING, z_m=1.3)
    np.testing.assert_allclose(fit.theta0, np.r_[P, vel])


def test_dim2_holds_the_height_and_matches_3d_for_exact_height():
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0])
    fit = nls.fit_trajectory(_walk(CEILING, P0, v), CEILING, dim=2, z_m=1.3)
    assert fit.p0_m[2] == 1.3 and fit.vel_mps[2] == 0.0 and fit.theta.shape == (4,)
    np.testing.assert_allclose(fit.p0_m, P0, atol=1e-5)
    with pytest.raises(ValueError, match="z_m"):
        nls.fit_trajectory(_walk(CEILING, P0, v), CEILING, dim=2)


def test_static_equals_multilateration_of_one_epoch(rng):
    p = np.array([6.0, 4.0, 1.8])
    r = np.linalg.norm(p - SCATTER, axis=1) + 0.05 * rng.standard_normal(6)
    fit = nls.fit_trajectory(RangeSamples.from_ranges(r[None], [0.0]), SCATTER, static=True, z_m=1.5)
    ref = multilaterate(r[None], SCATTER, dim=3, x0=np.array([6.0, 4.0, 1.5]))
    np.testing.assert_allclose(fit.p0_m, ref.pos_m[0], atol=1e-6)
    assert np.all(fit.vel_mps == 0)


def test_static_fit_of_moving_data_lands_mid_walk():
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([1.0, 0.0, 0.0])
    fit = nls.fit_trajectory(_walk(SCATTER, P0, v), SCATTER, static=True, dim=2, z_m=1.3)
    assert abs(fit.p0_m[0] - (4.0 + 5.0)) < 0.3          # the middle of the 0..10 s walk


def test_methods_agree_and_covariance_is_honest(rng):
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0])
    log = _walk(SCATTER, P0, v, t_end_s=20.0, sigma_m=0.1, rng=rng)
    a = nls.fit_trajectory(log, SCATTER, method="bfgs")
    b = nls.fit_trajectory(log, SCATTER, method="least_squares")
    np.testing.assert_allclose(a.theta, b.theta, atol=1e-5)
    assert a.converged and b.converged
    err = a.theta - np.r_[P0, v]
    sd = np.sqrt(np.diag(a.cov))
    assert np.all(np.abs(err) < 4 * sd)
    assert 0.08 < a.residual_rms_m < 0.12
    assert a.cost_m2 == pytest.approx(a.residual_rms_m ** 2 * a.n_used)


def test_position_at_and_trajectory():
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0])
    log = _walk(SCATTER, P0, v).between(2.0, 8.0)
    fit = nls.fit_trajectory(log, SCATTER)
    assert fit.t0_s == log.t_s[0]
    np.testing.assert_allclose(fit.position_at(log.t_s[0]), P0 + v * log.t_s[0], atol=1e-4)
    tr = fit.to_trajectory(name="seg")
    assert len(tr) == 2 and tr.name == "seg"
    np.testing.assert_allclose(tr.vel_mps[0], v, atol=1e-5)
    assert "converged" in fit.report()


def test_bad_parameters():
    log = _walk(SCATTER, np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0]))
    with pytest.raises(ValueError, match="method"):
        nls.fit_trajectory(log, SCATTER, method="newton")
    with pytest.raises(ValueError, match="robust loss"):
        nls.fit_trajectory(log, SCATTER, loss="soft_l1")
    with pytest.raises(ValueError, match="cannot determine"):
        nls.fit_trajectory(RangeSamples.from_ranges(log).select(slice(0, 4)), SCATTER)
    with pytest.raises(ValueError, match="anchors"):
        nls.fit_trajectory(log, SCATTER[:5])


def test_robust_loss_resists_an_nlos_anchor(rng):
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0])
    log = _walk(SCATTER, P0, v, sigma_m=0.05, rng=rng)
    r = log.range_m.copy()
    r[::3, 2] += 3.0                                      # every third range to anchor 3: NLOS
    log = RangeLog(log.t_s, r, log.anchor_ids)
    plain = nls.fit_trajectory(log, SCATTER, method="least_squares")
    robust = nls.fit_trajectory(log, SCATTER, method="least_squares", loss="soft_l1", f_scale_m=0.1)
    assert np.linalg.norm(robust.p0_m - P0) < 0.5 * np.linalg.norm(plain.p0_m - P0)


def test_fit_to_estimates_propagates_the_line_covariance(rng):
    P0, v = np.array([4.0, 3.0, 1.3]), np.array([0.7, 0.4, 0.0])
    log = _walk(CEILING, P0, v, sigma_m=0.1, rng=rng)
    fit = nls.fit_trajectory(log, CEILING, dim=2, z_m=1.3)
    est = fit.to_estimates(log.t_s)
    assert est.name == "NLS" and (est.status == 0).all()
    np.testing.assert_allclose(est.pos_m, fit.position_at(log.t_s)[:, :2])
    np.testing.assert_allclose(est.pos_cov_m2[0], fit.cov[:2, :2], rtol=1e-12)     # at t0: the P0 block
    tau = log.t_s[-1] - fit.t0_s
    A = np.hstack([np.eye(2), tau * np.eye(2)])
    np.testing.assert_allclose(est.pos_cov_m2[-1], A @ fit.cov @ A.T, rtol=1e-12)
    np.testing.assert_allclose(est.vel_mps[5], fit.vel_mps[:2])
