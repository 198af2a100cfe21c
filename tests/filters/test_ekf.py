import copy

import numpy as np
import pytest

from uwbwb.filters import kalman
from uwbwb.filters.ekf import Ekf, TdoaEkf, TdoaMeasurement, kernels
from uwbwb.filters.gating import AnchorDropping, ChiSquareEpoch, ChiSquarePerMeasurement, NoGate, Robust
from uwbwb.filters.twins import TWINS
from uwbwb.models.motion import RandomForce, RandomJerk, RandomWalk
from uwbwb.models.tdoa import TdoaModel
from uwbwb.types import EstimateStatus, TdoaLog, pseudo_tdoa

ANCHORS = np.array([[0.0, 0.0, 3.0], [30.0, 0.0, 0.5], [30.0, 30.0, 3.0], [0.0, 30.0, 0.5],
                    [15.0, -2.0, 2.0], [15.0, 32.0, 1.0], [-2.0, 15.0, 2.0], [32.0, 15.0, 1.5]])
IDS = tuple(f"a{i}" for i in range(8))


def _log(model, pos, t, *, sigma=0.0, rng=None, p_missing=0.0, ref=0):
    r = model.ranges(pos)
    if sigma:
        r = r + sigma * rng.standard_normal(r.shape)
    if p_missing:
        r[rng.random(r.shape) < p_missing] = np.nan
    d, refs = pseudo_tdoa(r, ref)
    return TdoaLog(t, d, refs, IDS)


@pytest.mark.parametrize("motion,truth", [
    (RandomWalk(1e-3), lambda t: np.tile([12.0, 17.0], (t.size, 1))),
    (RandomForce(1e-3), lambda t: np.column_stack([5 + 0.8 * t, 10 + 0.3 * t])),
    (RandomJerk(1e-3), lambda t: np.column_stack([5 + 0.2 * t + 0.05 * t ** 2, 20 - 0.4 * t])),
])
def test_noise_free_trajectory_converges_to_truth(motion, truth):
    # exact TDoAs of a trajectory the model can follow without error -> estimate converges to it
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 20, 0.1)
    pos = truth(t)
    ekf = TdoaEkf(motion, model)
    x0 = ekf.init(pos[0] + np.array([1.5, -1.0]))       # start 1.8 m off, at rest
    res = ekf.run(_log(model, pos, t), x0=x0)
    err = np.linalg.norm(res.pos_m - pos, axis=1)
    assert err[-1] < 2e-3 and err[-20:].max() < 5e-3
    assert err[0] > 0.01


@pytest.mark.parametrize("motion", [RandomWalk(0.05), RandomForce(1e-3), RandomJerk(1e-4)])
def test_nis_is_chi2_consistent_with_the_true_model(motion):
    rng = np.random.default_rng(2024)
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 60, 0.1)
    x = motion.sample_path(motion.initial_state([15.0, 15.0]), t, rng=rng)
    log = _log(model, motion.position(x), t, sigma=0.1, rng=rng, p_missing=0.1)
    ekf = TdoaEkf(motion, model, init_pos_sigma_m=0.5, init_vel_sigma_mps=0.1, init_acc_sigma_mps2=0.05)
    res = ekf.run(log, x0=kalman.Gaussian(x[0], ekf.init(x[0, :2]).P))
    c = res.nis_consistency()
    assert c["n"] == 600 and c["sum_dof"] > 2500
    # under the hypothesis the mean is 1 +- ~0.03 and the fraction 0.95 +- ~0.01
    assert 0.9 < c["mean_nis_over_dof"] < 1.1
    assert 0.92 < c["fraction_inside"] < 0.98
    # the filter's own covariance matches its errors (NEES per epoch ~ dim)
    e = res.pos_m - motion.position(x)
    nees = np.einsum("ti,tij,tj->t", e, np.linalg.inv(res.pos_cov_m2), e)
    assert 1.7 < nees.mean() < 2.3


def test_update_is_joseph_form_ekf_equations():
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    ekf = TdoaEkf(RandomForce(0.1), model)
    prior = kalman.Gaussian(np.array([10.0, 12.0, 0.5, -0.2]), np.diag([0.3, 0.4, 0.1, 0.1]))
    row = model.h(np.array([10.3, 11.8]), 1)
    row[5] = np.nan
    post, info = ekf.update(prior, (row, 1))
    z, h, Hp, R, _ = model.epoch(row, prior.x[:2], 1)
    H = np.hstack([Hp, np.zeros_like(Hp)])
    S = H @ prior.P @ H.T + R
    K = prior.P @ H.T @ np.linalg.inv(S)
    IKH = np.eye(4) - K @ H
    np.testing.assert_allclose(post.x, prior.x + K @ (z - h))
    np.testing.assert_allclose(post.P, IKH @ prior.P @ IKH.T + K @ R @ K.T, atol=1e-12)
    assert info.dof == 6 and info.n_rejected == 0 and info.status == EstimateStatus.UPDATED
    assert info.nis == pytest.approx((z - h) @ np.linalg.solve(S, z - h))


def test_predict_uses_motion_model():
    ekf = TdoaEkf(RandomJerk(0.3), TdoaModel(ANCHORS, 0.1))
    s = kalman.Gaussian(np.arange(6.0), np.eye(6))
    out = ekf.predict(s, 0.2)
    F, Q = ekf.motion.F(0.2), ekf.motion.Q(0.2)
    np.testing.assert_allclose(out.x, F @ s.x)
    np.testing.assert_allclose(out.P, F @ s.P @ F.T + Q)


def test_estimate_does_not_depend_on_reference_when_correlation_is_modelled(rng):
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 10, 0.1)
    pos = np.column_stack([5 + 0.8 * t, 10 + 0.3 * t])
    r = model.ranges(pos) + 0.1 * rng.standard_normal((t.size, 8))
    logs = [TdoaLog(t, *pseudo_tdoa(r, k), IDS) for k in (0, 5)]
    a, b = (TdoaEkf(RandomForce(0.5), model).run(lg) for lg in logs)
    np.testing.assert_allclose(a.x_post, b.x_post, atol=1e-9)
    np.testing.assert_allclose(a.nis, b.nis, atol=1e-9)
    naive = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0, correlated=False)
    c, d = (TdoaEkf(RandomForce(0.5), naive).run(lg) for lg in logs)
    assert np.abs(c.x_post - d.x_post).max() > 1e-3


def test_chi2_gate_rejects_nlos_outliers(rng):
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 30, 0.1)
    pos = np.column_stack([8 + 0.5 * t, 10 + 0.2 * t])
    r = model.ranges(pos) + 0.1 * rng.standard_normal((t.size, 8))
    hit = np.zeros(t.size, bool)
    hit[50::10] = True
    r[hit, 3] += 3.0                                    # strong positive NLOS bias on anchor 3
    r[hit & (np.arange(t.size) % 20 == 10), 0] += 3.0   # ...and sometimes on the reference too
    log = TdoaLog(t, *pseudo_tdoa(r, 0), IDS)
    plain = TdoaEkf(RandomForce(0.2), model, gate_prob=None).run(log)
    gated = TdoaEkf(RandomForce(0.2), model, gate_prob=0.999).run(log)
    assert gated.n_rejected[hit].sum() >= hit.sum() + (hit & (np.arange(t.size) % 20 == 10)).sum()
    assert gated.n_rejected[~hit].sum() <= 5          # false alarms ~ 0.1 % of epochs
    e_plain = np.linalg.norm(plain.pos_m - pos, axis=1)[hit].mean()
    e_gated = np.linalg.norm(gated.pos_m - pos, axis=1)[hit].mean()
    assert e_gated < 0.5 * e_plain


def test_gate_skips_epoch_when_too_few_measurements_remain():
    model = TdoaModel(ANCHORS[:4], 0.1, dim=2, z_m=1.0)
    ekf = TdoaEkf(RandomWalk(0.1), model, gate_prob=0.99)
    prior = ekf.init(np.array([10.0, 10.0]))
    prior = kalman.Gaussian(prior.x, 0.01 * prior.P)
    row = model.h(np.array([20.0, 20.0]), 0)            # 14 m away: everything inconsistent
    post, info = ekf.update(prior, (row, 0))
    assert info.dof == 0 and np.isnan(info.nis) and info.n_rejected > 0
    assert info.status == EstimateStatus.GATED
    np.testing.assert_array_equal(post.x, prior.x)


def test_run_result_frame_and_trajectory(rng):
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 5, 0.1)
    pos = np.column_stack([5 + 0.8 * t, 10 + 0.3 * t])
    r = model.ranges(pos) + 0.1 * rng.standard_normal((t.size, 8))
    r[:3] = np.nan                                      # no data at first: initialise at epoch 3
    res = TdoaEkf(RandomForce(0.5), model).run(TdoaLog(t, *pseudo_tdoa(r, 0), IDS), name="mine")
    assert not res.started[:3].any() and res.started[3:].all()
    assert (res.status[:3] == EstimateStatus.NO_ESTIMATE).all() and (res.status[3:] == EstimateStatus.UPDATED).all()
    df = res.to_frame()
    assert list(df.columns) == ["t_s", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m", "sd_y_m", "status", "nis", "dof",
                                "n_rejected"]
    est = res.to_estimates()
    assert est.name == "mine" and est.coverage == pytest.approx(1 - 3 / t.size)
    np.testing.assert_array_equal(est.pos_m[3:], res.x_post[3:, :2])
    traj = res.to_trajectory()
    assert traj.name == "mine" and len(traj) == t.size - 3 and traj.vel_mps is not None
    assert res.dof[3] == 7 and np.isnan(res.nis[:3]).all()


def test_three_dimensional_filter(rng):
    model = TdoaModel(ANCHORS, 0.1, dim=3)
    t = np.arange(0, 20, 0.1)
    pos = np.column_stack([5 + 0.8 * t, 10 + 0.3 * t, 1.0 + 0.05 * t])
    r = model.ranges(pos) + 0.05 * rng.standard_normal((t.size, 8))
    res = TdoaEkf(RandomForce(0.05, dim=3), model).run(TdoaLog(t, *pseudo_tdoa(r, 0), IDS))
    assert res.pos_m.shape == (t.size, 3)
    assert np.sqrt(np.mean((res.pos_m[50:] - pos[50:]) ** 2)) < 0.1


def test_configuration_errors():
    with pytest.raises(ValueError, match="3-D"):
        TdoaEkf(RandomWalk(dim=3), TdoaModel(ANCHORS, dim=2))
    with pytest.raises(ValueError, match="gate_prob"):
        TdoaEkf(RandomWalk(), TdoaModel(ANCHORS), gate_prob=1.5)
    log = TdoaLog([0.0], [[0.0, 1.0, 2.0]], [0], ("a", "b", "c"))
    with pytest.raises(ValueError, match="anchors"):
        TdoaEkf(RandomWalk(), TdoaModel(ANCHORS)).run(log)


def test_gate_is_bypassed_after_max_skipped_epochs():
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 10, 0.1)
    pos = np.tile([12.0, 17.0], (t.size, 1))
    log = _log(model, pos, t)
    x0 = kalman.Gaussian(np.array([17.0, 12.0]), 0.01 * np.eye(2))     # 7 m off and overconfident
    stuck = TdoaEkf(RandomWalk(1e-6), model, gate_prob=0.99, max_skipped=10 ** 6).run(log, x0=x0)
    assert np.all(stuck.dof == 0) and np.linalg.norm(stuck.pos_m[-1] - pos[-1]) > 5
    back = TdoaEkf(RandomWalk(1e-6), model, gate_prob=0.99, max_skipped=3).run(log, x0=x0)
    assert np.all(back.dof[:3] == 0) and back.dof[3] == 7          # 4th epoch used ungated
    err = np.linalg.norm(back.pos_m - pos, axis=1)
    assert err[-1] < 1.0 and err[-1] < err[3] < err[2]              # pulled back towards the target


def test_tdoa_ekf_keeps_priors_so_smoothing_and_nees_work():
    rng = np.random.default_rng(7)
    motion = RandomForce(0.05)
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 30, 0.1)
    x = motion.sample_path(motion.initial_state([15.0, 15.0], [0.3, -0.2]), t, rng=rng)
    log = _log(model, motion.position(x), t, sigma=0.1, rng=rng, p_missing=0.1)
    ekf = TdoaEkf(motion, model)
    res = ekf.run(log, x0=kalman.Gaussian(x[0], ekf.init(x[0, :2]).P))
    np.testing.assert_allclose(res.x_prior[1:], np.einsum("tij,tj->ti", res.F[1:], res.x_post[:-1]), atol=1e-12)
    smooth = res.smooth()
    err = lambda r: np.sqrt(np.mean(np.sum((r.pos_m - motion.position(x)) ** 2, axis=1)))  # noqa: E731
    assert err(smooth) < 0.8 * err(res)
    nees = res.nees(motion.position(x), index=res.pos_index)
    assert 1.6 < np.nanmean(nees) < 2.4                        # χ²(2) on average
    assert res.nis_consistency()["verdict"] == "consistent"


def test_gated_epochs_are_reported_as_such_in_the_common_result(rng):
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 20, 0.1)
    pos = np.column_stack([8 + 0.5 * t, 10 + 0.2 * t])
    r = model.ranges(pos) + 0.1 * rng.standard_normal((t.size, 8))
    r[100, :] += np.array([0.0, 9.0, -7.0, 8.0, -9.0, 7.0, -8.0, 9.0])      # nothing consistent left
    r[50:52] = np.nan                                                     # nothing measured
    res = TdoaEkf(RandomForce(0.2), model, gate_prob=0.999).run(TdoaLog(t, *pseudo_tdoa(r, 0), IDS))
    est = res.to_estimates()
    assert est.status[100] == EstimateStatus.GATED and res.n_rejected[100] > 0 and res.dof[100] == 0
    assert (est.status[50:52] == EstimateStatus.PREDICTED).all()
    np.testing.assert_array_equal(res.x_post[100], res.x_prior[100])
    assert est.status_counts()["updated"] == t.size - 3


# ------------------------------------------------------------------ the compiled loop (uwbwb.filters.ekf.kernels)
EKF_TWINS = [n for n in TWINS if n.startswith("ekf.TdoaEkf.run[")]


def _fields(run):
    return {f: getattr(run, f) for f in ("x_prior", "P_prior", "x_post", "P_post", "F", "nis", "dof", "status",
                                         "n_rejected")}


@pytest.mark.parametrize("name", EKF_TWINS)
def test_compiled_run_equals_the_python_loop(name, monkeypatch):
    # from the default start (the first LS fix, after five epochs without TDoAs), not only from a given prior
    # (the twin): the kernel's run against the Python loop it declines to (kernels.run returns None)
    twin = TWINS[name]
    ekf, log, _ = twin.inputs()
    d, ref = log.tdoa_m.copy(), log.ref.copy()
    d[:5], ref[:5] = np.nan, -1
    log = TdoaLog(log.t_s, d, ref, log.anchor_ids)
    fast = ekf.run(log)
    declined = []
    monkeypatch.setattr(kernels, "run", lambda *args: declined.append(args[5]) or None)
    slow = ekf.run(log)
    assert declined == [5] and np.isnan(fast.x_post[:5]).all() and (fast.status[:5] == EstimateStatus.NO_ESTIMATE).all()
    assert not twin.mismatches(_fields(fast), _fields(slow))
    assert (fast.name, fast.pos_index, fast.vel_index) == (slow.name, slow.pos_index, slow.vel_index)


@pytest.mark.parametrize("gate,compiled", [
    (NoGate(), True), (ChiSquareEpoch(0.999), True), (ChiSquarePerMeasurement(0.999, 2), True),
    (AnchorDropping(0.999, 2), True), (None, True),
    (Robust(), True), (Robust("cauchy", gate=AnchorDropping(0.999, 2)), True), ("sequential", False)])
def test_the_compiled_loop_runs_exactly_where_it_applies(gate, compiled, monkeypatch, rng):
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 5, 0.1)
    log = _log(model, np.column_stack([5 + 0.5 * t, 10 + 0.2 * t]), t, sigma=0.1, rng=rng, p_missing=0.1)
    if gate == "sequential":
        ekf = copy.copy(TdoaEkf(RandomForce(0.1), model))
        object.__setattr__(ekf, "sequential", True)
    else:
        ekf = TdoaEkf(RandomForce(0.1), model) if gate is None else TdoaEkf(RandomForce(0.1), model, gate=gate)
    calls = []
    real = kernels.run
    monkeypatch.setattr(kernels, "run", lambda *args: calls.append(1) or real(*args))
    x0 = ekf.init([5.2, 9.9])
    got = ekf.run(log, x0=x0)
    assert ekf.compiled == compiled and bool(calls) == compiled
    want = Ekf.run(ekf, log.t_s, TdoaMeasurement.epochs(log), x0)
    np.testing.assert_allclose(got.x_post, want.x_post, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got.status, want.status)
    if not compiled:                        # the Python loop itself: the same numbers, bit for bit
        np.testing.assert_array_equal(got.P_post, want.P_post)


def test_where_the_compiled_loop_stops_the_python_loop_decides():
    # a prior with a NaN: the kernel stops at the first update and the Python loop raises its own error
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 2, 0.1)
    log = _log(model, np.tile([12.0, 17.0], (t.size, 1)), t)
    ekf = TdoaEkf(RandomWalk(0.1), model, gate=NoGate())
    x0 = kalman.Gaussian(np.array([np.nan, 17.0]), np.eye(2))
    assert ekf.compiled and kernels.run(ekf, log.t_s, log.tdoa_m, log.ref, x0, 0, "EKF-RW") is None
    with pytest.raises(ValueError, match="non-finite"):
        ekf.run(log, x0=x0)
