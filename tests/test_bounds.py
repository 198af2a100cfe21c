"""Cramér–Rao bounds: the posterior recursion against a reference case and a Kalman-filter
Monte Carlo, the snapshot bounds against hand computations."""

import numpy as np
import pytest

from uwbwb import bounds
from uwbwb.filters import kalman
from uwbwb.models.motion import RandomForce
from uwbwb.models.tdoa import TdoaModel


# ----------------------------------------------------------------------------- reference case
# A constant-velocity target, state [x, vx, y, vy], observed in x and y:
#   q = 0.05 (PSD of the white acceleration), dt = 1 s, and the continuous white-noise
#   acceleration discretisation Q = q [[dt³/3, dt²/2], [dt²/2, dt]] per axis;
#   H picks x and y, R = diag(5, 5), prior covariance diag(5, 10, 5, 10), 21 epochs with the
#   prior alone at the first (no measurement there) and predict + update at each later one.
# Published bound (an established tracking framework's own PCRLB test):
#   position sqrt(C_xx + C_yy): 3.16227766 at the start, 1.89934607 at the end;
#   velocity sqrt(C_vxvx + C_vyvy): 4.47213595 at the start, 0.63338613 at the end.
REF = {"q": 0.05, "dt_s": 1.0, "R": np.diag([5.0, 5.0]), "P0": np.diag([5.0, 10.0, 5.0, 10.0]), "steps": 21}


def _reference_matrices():
    dt, q = REF["dt_s"], REF["q"]
    F1 = np.array([[1.0, dt], [0.0, 1.0]])
    Q1 = q * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    F, Q = np.kron(np.eye(2), F1), np.kron(np.eye(2), Q1)
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    return F, Q, H


def test_pcrlb_reproduces_the_reference_case():
    F, Q, H = _reference_matrices()
    T = REF["steps"]
    info = np.broadcast_to(H.T @ np.linalg.inv(REF["R"]) @ H, (T, 4, 4)).copy()
    info[0] = 0.0                                           # the prior alone at the start
    C = bounds.pcrlb(REF["P0"], np.broadcast_to(F, (T, 4, 4)), np.broadcast_to(Q, (T, 4, 4)), info)
    pos = np.sqrt(C[:, 0, 0] + C[:, 2, 2])
    vel = np.sqrt(C[:, 1, 1] + C[:, 3, 3])
    assert pos[0] == pytest.approx(3.16227766, abs=1e-8)
    assert pos[-1] == pytest.approx(1.89934607, abs=1e-8)
    assert vel[0] == pytest.approx(4.47213595, abs=1e-8)
    assert vel[-1] == pytest.approx(0.63338613, abs=1e-8)
    assert np.all(np.diff(pos[1:]) <= 1e-12)               # information only accumulates here


def test_tracking_bound_with_the_package_motion_model_gives_the_reference_numbers():
    """Same case through uwbwb.models.motion (derivative-major state [x, y, vx, vy])."""
    motion = RandomForce(psd_m2ps3=REF["q"], dim=2)
    T = REF["steps"]
    t = np.arange(T) * REF["dt_s"]
    info = np.broadcast_to(np.linalg.inv(REF["R"]), (T, 2, 2)).copy()
    info[0] = 0.0
    P0 = np.diag([5.0, 5.0, 10.0, 10.0])
    C = bounds.tracking_bound(motion, t, info, P0)
    assert bounds.rmse_bound_m(C)[0] == pytest.approx(3.16227766, abs=1e-8)
    assert bounds.rmse_bound_m(C)[-1] == pytest.approx(1.89934607, abs=1e-8)


def test_pcrlb_matches_a_kalman_filter_monte_carlo_in_the_linear_case():
    """Linear-Gaussian: the Kalman filter is efficient, so its mean squared error over runs with
    a fresh true track and fresh noise each time must match the PCRLB within Monte Carlo error."""
    F, Q, H = _reference_matrices()
    R, P0, T = REF["R"], REF["P0"], REF["steps"]
    rng = np.random.default_rng(2024)
    n_runs = 400
    x0_mean = np.array([1.0, 0.5, -2.0, 0.2])
    L0, LQ, LR = np.linalg.cholesky(P0), np.linalg.cholesky(Q), np.linalg.cholesky(R)
    sq_err = np.empty((n_runs, T))
    for r in range(n_runs):
        x = x0_mean + L0 @ rng.standard_normal(4)          # truth drawn from the prior
        state = kalman.Gaussian(x0_mean, P0)
        for k in range(T):
            if k:
                x = F @ x + LQ @ rng.standard_normal(4)
                state = kalman.predict(state, F, Q)
                state, _ = kalman.update(state, H @ x + LR @ rng.standard_normal(2), H, R)
            sq_err[r, k] = (state.x[0] - x[0]) ** 2 + (state.x[2] - x[2]) ** 2
    info = np.broadcast_to(H.T @ np.linalg.inv(R) @ H, (T, 4, 4)).copy()
    info[0] = 0.0
    C = bounds.pcrlb(P0, np.broadcast_to(F, (T, 4, 4)), np.broadcast_to(Q, (T, 4, 4)), info)
    bound_sq = C[:, 0, 0] + C[:, 2, 2]
    mse = sq_err.mean(axis=0)
    se = sq_err.std(axis=0, ddof=1) / np.sqrt(n_runs)
    z = (mse - bound_sq) / se
    assert np.all(np.abs(z) < 4.0), f"MSE vs PCRLB in standard errors per epoch: {np.round(z, 2).tolist()}"
    # over all epochs at once (runs are independent; epochs within a run are not, so use run means)
    run_mean = sq_err.mean(axis=1)
    z_all = (run_mean.mean() - bound_sq.mean()) / (run_mean.std(ddof=1) / np.sqrt(n_runs))
    assert abs(z_all) < 3.0, f"time-averaged MSE {run_mean.mean():.4f} vs bound {bound_sq.mean():.4f} (z = {z_all:.2f})"


def test_pcrlb_handles_a_singular_process_noise():
    """Q driving only the velocity (as the set-noise filters' model) is singular; the bound still exists."""
    dt, s2 = 0.1, 0.04
    F = np.kron(np.eye(2), np.array([[1.0, dt], [0.0, 1.0]]))
    Q = np.diag([0.0, s2, 0.0, s2])
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    T = 50
    info = np.broadcast_to(H.T @ H / 0.01, (T, 4, 4))
    C = bounds.pcrlb(np.eye(4), np.broadcast_to(F, (T, 4, 4)), np.broadcast_to(Q, (T, 4, 4)), info)
    assert np.all(np.isfinite(C)) and np.all(np.linalg.eigvalsh(C) > 0)
    # the Kalman filter with the same matrices reaches exactly this covariance
    state = kalman.Gaussian(np.zeros(4), np.eye(4))
    for k in range(T):
        if k:
            state = kalman.predict(state, F, Q)
        state, _ = kalman.update(state, np.zeros(2), H, np.eye(2) * 0.01)
    np.testing.assert_allclose(state.P, C[-1], rtol=1e-9, atol=1e-12)


def test_pcrlb_rejects_bad_shapes_and_prior():
    F = np.broadcast_to(np.eye(2), (3, 2, 2))
    with pytest.raises(ValueError, match="positive definite"):
        bounds.pcrlb(np.zeros((2, 2)), F, F, np.zeros((3, 2, 2)))
    with pytest.raises(ValueError, match="do not fit"):
        bounds.pcrlb(np.eye(2), F[:2], F, np.zeros((3, 2, 2)))


# ----------------------------------------------------------------------------- snapshot bounds

def test_range_crlb_two_anchor_case_by_hand():
    """Tag at the origin, anchor 1 along +x, anchor 2 at 45°, both in the tag's plane, σ = 1 m.

    u1 = (1, 0), u2 = (1, 1)/√2  →  I = [[3/2, 1/2], [1/2, 1/2]], det = 1/2,
    I⁻¹ = [[1, −1], [−1, 3]], RMSE bound = sqrt(4) = 2 m. With σ = 0.1 m everything scales by σ².
    """
    anchors = np.array([[-3.0, 0.0, 1.5], [-2.0, -2.0, 1.5]])  # the unit vectors point anchor → tag
    for sigma, scale in ((1.0, 1.0), (0.1, 0.01)):
        info = bounds.range_information(np.zeros(2), anchors, sigma, z_m=1.5)
        np.testing.assert_allclose(info, np.array([[1.5, 0.5], [0.5, 0.5]]) / scale, atol=1e-12)
        C = bounds.crlb(info)
        np.testing.assert_allclose(C, np.array([[1.0, -1.0], [-1.0, 3.0]]) * scale, atol=1e-12)
        assert bounds.rmse_bound_m(C) == pytest.approx(2.0 * np.sqrt(scale))
    # per-anchor sigmas weight the rows: σ = (1, 2) → I = [[1 + 1/8, 1/8], [1/8, 1/8]]
    info = bounds.range_information(np.zeros(2), anchors, [1.0, 2.0], z_m=1.5)
    np.testing.assert_allclose(info, [[1.125, 0.125], [0.125, 0.125]], atol=1e-12)
    # one anchor alone does not determine a 2-D position
    assert np.all(np.isnan(bounds.crlb(bounds.range_information(np.zeros(2), anchors, 1.0, z_m=1.5,
                                                                 mask=np.array([True, False])))))


def test_range_information_uses_the_horizontal_part_at_a_known_height():
    """An anchor 1 m above the tag plane and 1 m away horizontally: u = (1, 0, 1)/√2 → u_xy = (1/√2, 0)."""
    info = bounds.range_information(np.zeros(2), np.array([[-1.0, 0.0, 1.0]]), 1.0, z_m=0.0)
    np.testing.assert_allclose(info, [[0.5, 0.0], [0.0, 0.0]], atol=1e-12)


def test_tdoa_information_equals_H_sigma_inverse_H_for_every_reference(rng):
    anchors = rng.uniform([-5, -5, 0], [5, 5, 3], size=(6, 3))
    model = TdoaModel(anchors, sigma_m=rng.uniform(0.05, 0.3, 6), dim=2, z_m=1.0)
    pos = rng.uniform(-3, 3, size=(5, 2))
    mask = rng.random((5, 6)) < 0.8
    mask[:, :4] = True
    info = bounds.tdoa_information(pos, model, mask=mask)
    for t in range(5):
        used = np.flatnonzero(mask[t])
        row = np.where(mask[t], 0.0, np.nan)
        for ref in used:
            _, _, H, R, _ = model.epoch(row, pos[t], int(ref), used)
            np.testing.assert_allclose(info[t], H.T @ np.linalg.solve(R, H), rtol=1e-9, atol=1e-9)


def test_tdoa_bound_by_hand_symmetric_three_anchors():
    """Three anchors at 120° around the tag, in its plane, equal σ: Σ u_i = 0, so the common-offset
    term vanishes and the TDoA bound equals the range bound, (2σ²/3) I."""
    ang = np.deg2rad([90.0, 210.0, 330.0])
    anchors = np.column_stack([4 * np.cos(ang), 4 * np.sin(ang), np.zeros(3)])
    sigma = 0.2
    model = TdoaModel(anchors, sigma, dim=2, z_m=0.0)
    C_tdoa = bounds.crlb(bounds.tdoa_information(np.zeros(2), model))
    C_range = bounds.crlb(bounds.range_information(np.zeros(2), anchors, sigma, z_m=0.0))
    np.testing.assert_allclose(C_tdoa, 2 * sigma ** 2 / 3 * np.eye(2), atol=1e-12)
    np.testing.assert_allclose(C_range, C_tdoa, atol=1e-12)
    # off the centre the TDoA bound is strictly larger (the ranges' offset information is lost)
    p = np.array([1.5, 0.5])
    assert bounds.rmse_bound_m(bounds.crlb(bounds.tdoa_information(p, model))) > \
        bounds.rmse_bound_m(bounds.crlb(bounds.range_information(p, anchors, sigma, z_m=0.0)))


def test_line_crlb_at_the_window_centre_is_the_snapshot_bound_over_K():
    """A static tag seen K times: the fitted line's position at the window's mean time is the mean
    of K independent fixes (intercept and slope decorrelate there), so its bound is I⁻¹ / K."""
    anchors = np.array([[0.0, 0.0, 2.0], [6.0, 0.0, 2.0], [0.0, 5.0, 2.0], [6.0, 5.0, 2.5]])
    K = 21
    t = np.linspace(0.0, 2.0, K)
    pos = np.broadcast_to([2.0, 1.5], (K, 2))
    C = bounds.line_crlb(t, pos, anchors, 0.1, z_m=1.0)
    snap = bounds.crlb(bounds.range_information(pos[0], anchors, 0.1, z_m=1.0))
    np.testing.assert_allclose(C[K // 2], snap / K, rtol=1e-10)
    assert np.all(bounds.rmse_bound_m(C[[0, -1]]) > bounds.rmse_bound_m(C[K // 2]))   # wider at the ends


def test_bound_aggregate_refuses_nan_epochs():
    b = bounds.Bound(np.arange(3.0), np.stack([np.eye(2), np.full((2, 2), np.nan), 4 * np.eye(2)]), "test")
    assert b.aggregate_m(np.array([True, False, True])) == pytest.approx(np.sqrt((2 + 8) / 2))
    with pytest.raises(ValueError, match="no bound"):
        b.aggregate_m()


def test_motion_log_likelihood_picks_the_model_and_noise_that_drew_the_track():
    """A random-force track (σ_w = 0.5 m/s² at 10 Hz): RF beats RW and RJ, at σ_w within a grid step."""
    from uwbwb.models.motion import RandomForce, make_motion_model

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 60.0, 0.1)
    motion = RandomForce(psd_m2ps3=0.5 ** 2 * 0.1, dim=2)
    x = motion.sample_path(motion.initial_state(np.zeros(2), rng.standard_normal(2)), t, rng=rng)
    pos = x[:, :2] + 0.005 * rng.standard_normal((t.size, 2))
    grid = np.geomspace(0.05, 5.0, 21)
    best = {}
    for name in ("RW", "RF", "RJ"):
        ll = bounds.motion_log_likelihood([make_motion_model(name, sigma=s, dt_s=0.1, dim=2) for s in grid],
                                          t, pos, 0.005, skip=3)
        best[name] = (grid[int(np.argmax(ll))], ll.max())
    assert max(best, key=lambda m: best[m][1]) == "RF"
    assert best["RF"][0] == pytest.approx(0.5, rel=0.3)


def test_motion_log_likelihood_checks_its_input():
    from uwbwb.models.motion import make_motion_model

    m = make_motion_model("RF", sigma=1.0, dt_s=0.1, dim=2)
    with pytest.raises(ValueError, match="share n_x"):
        bounds.motion_log_likelihood([m, make_motion_model("RW", sigma=1.0, dt_s=0.1, dim=2)],
                                     np.arange(3.0), np.zeros((3, 2)), 0.01)
    with pytest.raises(ValueError, match="sigma_obs_m"):
        bounds.motion_log_likelihood([m], np.arange(3.0), np.zeros((3, 2)), 0.0)
