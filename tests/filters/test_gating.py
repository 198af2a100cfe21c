"""Gate policies: decision rules at their thresholds, release rule, equivalence with the gate_prob settings."""

import numpy as np
import pytest
from scipy.stats import chi2, multivariate_normal

from uwbwb.filters import kalman
from uwbwb.filters.ekf import Ekf, Linearisation, TdoaEkf, TdoaMeasurement
from uwbwb.filters.gating import (AnchorDropping, ChiSquareEpoch, ChiSquarePerMeasurement, NoGate, gate_from_prob,
                                  ungated_update)
from uwbwb.filters.kalman import Gaussian
from uwbwb.models.motion import RandomForce, RandomWalk
from uwbwb.models.tdoa import TdoaModel
from uwbwb.types import EstimateStatus, TdoaLog, pseudo_tdoa

ANCHORS = np.array([[0.0, 0.0, 3.0], [30.0, 0.0, 0.5], [30.0, 30.0, 3.0], [0.0, 30.0, 0.5],
                    [15.0, -2.0, 2.0], [15.0, 32.0, 1.0]])
IDS = tuple(f"a{i}" for i in range(6))


class PositionFix:
    """Linear model: the position of the state, noise ``var_m2`` per axis (NaN = missing epoch)."""

    def __init__(self, motion, var_m2=0.09):
        self.H, self.var = motion.H_pos, var_m2

    def linearise(self, x, z):
        z = np.asarray(z, float)
        if not np.all(np.isfinite(z)):
            return None
        return Linearisation(z, self.H @ x, self.H, self.var * np.eye(z.size))


def _scalar(z):
    """Prior N(0, 1), measurement z with noise 1: S = 2, NIS = z² / 2."""
    return Gaussian([0.0], [[1.0]]), Linearisation([z], [0.0], [[1.0]], [[1.0]])


@pytest.mark.parametrize("prob", [0.9, 0.9999])
def test_chi_square_epoch_rejects_exactly_above_its_quantile(prob):
    thr = chi2.ppf(prob, 1)
    gate = ChiSquareEpoch(prob)
    assert gate.threshold(1) == pytest.approx(thr)
    below, above = np.sqrt(2 * thr) * (1 - 1e-6), np.sqrt(2 * thr) * (1 + 1e-6)
    post, info = gate.update(*_scalar(below))
    assert info.status == EstimateStatus.UPDATED and info.dof == 1 and post.x[0] == pytest.approx(below / 2)
    prior, lin = _scalar(above)
    post, info = gate.update(prior, lin)
    assert info.status == EstimateStatus.GATED and info.dof == 0 and post is prior
    assert info.nis == pytest.approx(above ** 2 / 2)


def test_no_gate_uses_any_measurement():
    post, info = NoGate().update(*_scalar(1e3))
    assert info.status == EstimateStatus.UPDATED and post.x[0] == pytest.approx(500.0)


def test_per_measurement_gate_drops_only_the_inconsistent_component():
    motion = RandomForce(0.5, dim=2)
    prior = Gaussian(np.array([1.0, 2.0, 0.0, 0.0]), np.diag([0.04, 0.04, 1.0, 1.0]))
    H, R = motion.H_pos, 0.01 * np.eye(2)
    S_ii = 0.05
    z = np.array([1.0 + 0.5 * np.sqrt(S_ii), 2.0 + 10 * np.sqrt(S_ii)])     # x fine, y 10 sigma off
    lin = Linearisation(z, H @ prior.x, H, R)
    gate = ChiSquarePerMeasurement(0.999)
    assert gate.keep(lin.innovation, np.full(2, S_ii)).tolist() == [True, False]
    post, info = gate.update(prior, lin)
    want, _ = kalman.update(prior, z[:1], H[:1], R[:1, :1], h_x=lin.h[:1])
    np.testing.assert_array_equal(post.x, want.x)
    np.testing.assert_array_equal(post.P, want.P)
    assert info.status == EstimateStatus.UPDATED and info.dof == 1 and info.n_rejected == 1
    # both off: the epoch is gated; with min_rows=2 one bad row is enough to gate it
    both = Linearisation(lin.h + 10 * np.sqrt(S_ii), lin.h, H, R)
    post, info = gate.update(prior, both)
    assert info.status == EstimateStatus.GATED and info.n_rejected == 2 and post is prior
    post, info = ChiSquarePerMeasurement(0.999, min_rows=2).update(prior, lin)
    assert info.status == EstimateStatus.GATED and post is prior
    # all consistent: the same numbers as no gate
    ok = Linearisation(lin.h + 0.1, lin.h, H, R)
    a, b = gate.update(prior, ok), ungated_update(prior, ok)
    np.testing.assert_array_equal(a[0].x, b[0].x)
    assert a[1] == b[1]


def test_release_rule_flips_at_max_gated():
    for gate in (NoGate(3), ChiSquareEpoch(0.99, 3), ChiSquarePerMeasurement(0.99, max_gated=3),
                 AnchorDropping(0.99, max_gated=3)):
        assert [gate.active(n) for n in range(5)] == [True, True, True, False, False]
    assert not ChiSquareEpoch(0.99, max_gated=0).active(0)


@pytest.mark.parametrize("make", [
    lambda: ChiSquareEpoch(1.5), lambda: ChiSquareEpoch(0.9, max_gated=-1), lambda: NoGate(max_gated=2.5),
    lambda: ChiSquarePerMeasurement(0.9, min_rows=0), lambda: AnchorDropping(0.0),
    lambda: AnchorDropping(0.9, min_rows=True)])
def test_bad_policy_parameters_are_refused(make):
    with pytest.raises(ValueError, match="prob|max_gated|min_rows"):
        make()


def _fix_data(rng):
    motion = RandomForce(0.5, dim=2)
    t = np.arange(80) * 0.1
    x = motion.sample_path(motion.initial_state([0.0, 0.0], [1.0, 0.5]), t, rng=rng)
    z = motion.position(x) + 0.3 * rng.standard_normal((t.size, 2))
    z[30::15] += 5.0
    return motion, t, z, Gaussian(x[0], motion.initial_covariance(1.0, 1.0))


def test_ekf_gate_prob_is_the_chi_square_epoch_policy(rng):
    motion, t, z, x0 = _fix_data(rng)
    fix = PositionFix(motion)
    for kw, policy in ((dict(gate_prob=0.99, max_gated=2), ChiSquareEpoch(0.99, 2)),
                       (dict(gate_prob=None, max_gated=4), NoGate(4)), ({}, ChiSquareEpoch())):
        a = Ekf(motion, fix, pos_index=(0, 1), **kw)
        b = Ekf(motion, fix, pos_index=(0, 1), gate=policy)
        assert a.gate == policy and (b.gate_prob, b.max_gated) == (a.gate_prob, a.max_gated)
        ra, rb = a.run(t, z, x0), b.run(t, z, x0)
        for f in ("x_post", "P_post", "nis", "dof", "status"):
            np.testing.assert_array_equal(getattr(ra, f), getattr(rb, f))
    gated = Ekf(motion, fix, pos_index=(0, 1), gate=ChiSquareEpoch(0.99)).run(t, z, x0)
    assert (gated.status == EstimateStatus.GATED).sum() >= 4
    per = Ekf(motion, fix, pos_index=(0, 1), gate=ChiSquarePerMeasurement(0.99)).run(t, z, x0)
    assert per.n_rejected.sum() >= 8 and set(per.dof[per.n_rejected == 1]) == {1}


def test_conflicting_or_unusable_gates_are_refused(rng):
    motion = RandomForce(0.5, dim=2)
    fix = PositionFix(motion)
    with pytest.raises(ValueError, match="not both"):
        Ekf(motion, fix, pos_index=(0, 1), gate_prob=0.9, gate=NoGate())
    with pytest.raises(ValueError, match="re-linearise"):
        Ekf(motion, fix, pos_index=(0, 1), gate=AnchorDropping(0.99))
    with pytest.raises(ValueError, match="gate policy"):
        Ekf(motion, fix, pos_index=(0, 1), gate=0.99)
    with pytest.raises(ValueError, match="gate_prob"):
        gate_from_prob(2.0, 10, "X")


def _tdoa_log(rng):
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 8, 0.1)
    pos = np.column_stack([8 + 0.5 * t, 10 + 0.2 * t])
    r = model.ranges(pos) + 0.1 * rng.standard_normal((t.size, 6))
    r[20::7, 3] += 3.0
    return model, TdoaLog(t, *pseudo_tdoa(r, 0), IDS)


def test_tdoa_ekf_settings_are_the_anchor_dropping_policy(rng):
    model, log = _tdoa_log(rng)
    a = TdoaEkf(RandomWalk(0.3), model, gate_prob=0.99, min_tdoa=3, max_skipped=4)
    b = TdoaEkf(RandomWalk(0.3), model, gate=AnchorDropping(0.99, min_rows=3, max_gated=4))
    assert a.gate == b.gate and b.gate_prob == 0.99 and b.max_gated == 4
    ra, rb = a.run(log), b.run(log)
    np.testing.assert_array_equal(ra.x_post, rb.x_post)
    np.testing.assert_array_equal(ra.n_rejected, rb.n_rejected)
    assert ra.n_rejected.sum() >= 8
    assert TdoaEkf(RandomWalk(0.3), model).gate == AnchorDropping(0.9999, min_rows=2, max_gated=10)
    with pytest.raises(ValueError, match="not both"):
        TdoaEkf(RandomWalk(0.3), model, gate_prob=0.9, gate=NoGate())


def test_tdoa_ekf_runs_with_every_policy(rng):
    model, log = _tdoa_log(rng)
    none = TdoaEkf(RandomWalk(0.3), model, gate_prob=None).run(log)
    runs = {type(g).__name__: TdoaEkf(RandomWalk(0.3), model, gate=g).run(log)
            for g in (NoGate(), ChiSquareEpoch(0.99), ChiSquarePerMeasurement(0.99), AnchorDropping(0.99))}
    np.testing.assert_array_equal(runs["NoGate"].x_post, none.x_post)
    assert (runs["ChiSquareEpoch"].status == EstimateStatus.GATED).sum() > 0
    assert runs["ChiSquarePerMeasurement"].n_rejected.sum() > 0
    assert runs["AnchorDropping"].n_rejected.sum() > 0


def test_update_info_log_likelihood_is_the_innovation_density(rng):
    """``UpdateInfo.log_likelihood`` is ``log N(y; 0, S)`` of the update's innovation (scipy's
    density), for an epoch used and one the epoch gate rejected; NaN without an innovation."""
    prior = Gaussian(np.array([1.0, 2.0, 0.5]), np.diag([0.3, 0.2, 0.5]))
    H = np.array([[1.0, 0.0, 0.2], [0.0, 1.0, -0.1]])
    R = np.array([[0.1, 0.02], [0.02, 0.05]])
    for shift in (0.1, 30.0):
        z = H @ prior.x + shift * rng.standard_normal(2)
        lin = Linearisation(z, H @ prior.x, H, R)
        S = H @ prior.P @ H.T + R
        want = multivariate_normal(np.zeros(2), S).logpdf(z - H @ prior.x)
        for policy in (NoGate(), ChiSquareEpoch(0.99)):
            _, info = policy.update(prior, lin)
            assert info.log_likelihood == pytest.approx(want, rel=1e-12)
        assert info.status == (EstimateStatus.UPDATED if shift < 1 else EstimateStatus.GATED)
    assert np.isnan(ChiSquarePerMeasurement(0.99).update(prior, lin)[1].log_likelihood)   # gated row by row


def test_linear_linearisation_is_the_textbook_linear_update(rng, monkeypatch):
    """``linear=True`` forms ``y = z − H x⁻`` as :func:`kalman.update` without ``h_x`` (the same call,
    the same bits); the nonlinear form ``z − h`` agrees to rounding. ``rows`` is the marginal of the
    chosen rows."""
    prior = Gaussian(rng.standard_normal(4), np.diag([0.3, 0.2, 0.5, 0.1]))
    H, R = np.eye(4)[:3], np.diag([0.1, 0.2, 0.3])
    z = H @ prior.x + rng.standard_normal(3)
    lin = Linearisation(z, H @ prior.x, H, R, linear=True)
    want, _ = kalman.update(prior, z, H, R)
    post, _ = ungated_update(prior, lin)
    np.testing.assert_array_equal(post.x, want.x)
    np.testing.assert_array_equal(post.P, want.P)
    other, _ = ungated_update(prior, Linearisation(z, H @ prior.x, H, R))
    np.testing.assert_allclose(other.x, want.x, rtol=1e-12)
    seen = []
    plain = kalman.update
    monkeypatch.setattr(kalman, "update", lambda *a, h_x=None: seen.append(h_x) or plain(*a, h_x=h_x))
    ungated_update(prior, lin)
    ChiSquareEpoch(0.99).update(prior, lin)
    ungated_update(prior, Linearisation(z, H @ prior.x, H, R))
    assert seen[0] is None and seen[1] is None and seen[2] is not None
    part = lin.rows(np.array([True, False, True]))
    np.testing.assert_array_equal(part.R, np.diag([0.1, 0.3]))
    assert part.linear and part.z.tolist() == z[[0, 2]].tolist()
    with pytest.raises(ValueError, match="Linearisation.linear"):
        Linearisation(z, H @ prior.x, H, R, linear="yes")


# ----------------------------------------------------------------- sequential updates through the engine
def _linear_case(rng, correlated):
    """A 5-state prior and a linear 4-row measurement, ``R`` diagonal or with correlated rows."""
    A = rng.standard_normal((5, 5))
    prior = Gaussian(rng.standard_normal(5), A @ A.T + 0.5 * np.eye(5))
    H = rng.standard_normal((4, 5))
    R = np.diag([0.1, 0.2, 0.3, 0.05])
    if correlated:
        R = R + 0.04 * (np.ones((4, 4)) - np.eye(4))      # a common reference: equal off-diagonals
    z = H @ prior.x + rng.standard_normal(4)
    return prior, H, R, z


@pytest.mark.parametrize("correlated", [False, True])
def test_sequential_update_is_update_sequential_bit_for_bit_and_the_batch_update_to_rounding(rng, correlated):
    """``ungated_update(..., sequential=True)`` is :func:`kalman.update_sequential` on the same
    arrays (same bits, its per-row NIS in ``nis_rows``, their sum as ``nis``); for a linear
    measurement it equals the batch update to rounding, NIS and log-likelihood included."""
    prior, H, R, z = _linear_case(rng, correlated)
    for lin, h_x in ((Linearisation(z, H @ prior.x, H, R), H @ prior.x),
                     (Linearisation(z, H @ prior.x, H, R, linear=True), None)):
        want, rows = kalman.update_sequential(prior, z, H, R, h_x=h_x)
        post, info = ungated_update(prior, lin, sequential=True)
        assert post.x.tobytes() == want.x.tobytes() and post.P.tobytes() == want.P.tobytes()
        assert info.nis_rows.tobytes() == rows.tobytes() and info.nis == float(rows.sum())
        assert info.dof == 4 and info.status == EstimateStatus.UPDATED
        batch, binfo = ungated_update(prior, lin)
        assert binfo.nis_rows is None
        np.testing.assert_allclose(post.x, batch.x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(post.P, batch.P, rtol=1e-12, atol=1e-12)
        assert info.nis == pytest.approx(binfo.nis, rel=1e-12)
        assert info.log_likelihood == pytest.approx(binfo.log_likelihood, rel=1e-12)


def test_ekf_sequential_updates_through_every_policy_and_the_batch_path_is_unchanged(rng):
    """``Ekf(sequential=True)`` passes ``sequential`` to the gate policy (and to the ungated
    update); the default Ekf makes exactly the batch call, as before."""
    motion = RandomForce(0.5, dim=2)
    prior = Gaussian(np.array([1.0, 2.0, 0.0, 0.0]), np.diag([0.04, 0.04, 1.0, 1.0]))
    z = np.array([1.1, 1.95])
    for policy in (NoGate(), ChiSquareEpoch(0.99), ChiSquarePerMeasurement(0.99)):
        seq = Ekf(motion, PositionFix(motion), gate=policy, sequential=True)
        post, info = seq.update(prior, z)
        lin = PositionFix(motion).linearise(prior.x, z)
        want, rows = kalman.update_sequential(prior, lin.z, lin.H, lin.R, h_x=lin.h)
        assert post.x.tobytes() == want.x.tobytes() and info.nis_rows.tobytes() == rows.tobytes()
        post_u, info_u = seq.update(prior, z, gate=False)
        assert post_u.x.tobytes() == want.x.tobytes() and info_u.nis_rows is not None
        batch, binfo = Ekf(motion, PositionFix(motion), gate=policy).update(prior, z)
        plain, _ = policy.update(prior, lin)
        assert batch.x.tobytes() == plain.x.tobytes() and binfo.nis_rows is None
        np.testing.assert_allclose(post.P, batch.P, rtol=1e-12, atol=1e-14)
    with pytest.raises(ValueError, match="Ekf.sequential"):
        Ekf(motion, PositionFix(motion), sequential="yes")


def test_stack_and_the_row_test_of_no_gate():
    """``Linearisation.stack`` stacks rows with a block-diagonal ``R`` (linear only if every part
    is); ``NoGate`` as a row test keeps every row with a defined statistic."""
    a = Linearisation([1.0, 2.0], [0.5, 1.5], np.eye(2, 3), [[0.1, 0.02], [0.02, 0.2]], linear=True)
    b = Linearisation([3.0], [2.5], [[0.0, 0.0, 1.0]], [[0.3]])
    s = Linearisation.stack([a, b])
    np.testing.assert_array_equal(s.z, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(s.H, np.eye(3))
    np.testing.assert_array_equal(s.R, [[0.1, 0.02, 0.0], [0.02, 0.2, 0.0], [0.0, 0.0, 0.3]])
    assert not s.linear and Linearisation.stack([a, a]).linear
    with pytest.raises(ValueError, match="at least one"):
        Linearisation.stack([])
    assert NoGate().threshold() == np.inf
    np.testing.assert_array_equal(NoGate().keep([1e6, np.nan, 0.0], [1.0, 1.0, 1.0]), [True, False, True])
    np.testing.assert_array_equal(ChiSquarePerMeasurement(0.99).keep([2.0, 3.0], [1.0, 1.0]),
                                  [2.0 ** 2 <= chi2.ppf(0.99, 1), 3.0 ** 2 <= chi2.ppf(0.99, 1)])


def test_numpy_scalar_probabilities_are_accepted_and_stored_as_float():
    for policy in (ChiSquareEpoch(np.float32(0.99)), ChiSquarePerMeasurement(np.float64(0.99)),
                   AnchorDropping(np.float32(0.99))):
        assert type(policy.prob) is float and abs(policy.prob - 0.99) < 1e-6
    assert type(gate_from_prob(np.float32(0.999), 10, "Owner").prob) is float
    for bad in (np.True_, True, 1.0, np.float64(np.nan), "0.9"):
        with pytest.raises(ValueError, match="must be in"):
            ChiSquareEpoch(bad)
        with pytest.raises(ValueError, match="Owner.gate_prob"):
            gate_from_prob(bad, 10, "Owner")


def test_screen_is_the_decision_update_makes(rng):
    """Each χ² policy's ``screen`` keeps the rows its ``update`` uses (the posterior of ``ungated_update``
    on them, bit for bit) and rejects the epochs it gates, with the same ``GATED`` info (NIS to rounding)."""
    model, log = _tdoa_log(rng)
    ekf = TdoaEkf(RandomWalk(0.3), model, gate_prob=None)
    run = ekf.run(log)
    meas = ekf.measurement
    epochs = TdoaMeasurement.epochs(log)
    seen = set()
    for policy in (NoGate(), ChiSquareEpoch(0.99), ChiSquarePerMeasurement(0.99, min_rows=4), AnchorDropping(0.99)):
        for k in np.flatnonzero(run.started)[1:]:
            prior = Gaussian(run.x_prior[k], run.P_prior[k])
            m = epochs[k]
            lin = meas.linearise(prior.x, m)
            parts = (meas.components(m), lambda keep: meas.linearise_components(prior.x, m, keep))
            kept, n_rejected, gated = policy.screen(prior, lin, parts)
            post, info = policy.update(prior, lin, parts)
            assert info.n_rejected == n_rejected
            if kept is None:
                assert post is prior and info.status == gated.status == EstimateStatus.GATED and info.dof == 0
                assert info.n_rejected == gated.n_rejected
                np.testing.assert_allclose(info.nis, gated.nis, rtol=1e-12)     # ChiSquareEpoch: NIS formed apart
            else:
                assert gated is None and info.status == EstimateStatus.UPDATED and info.dof == kept.z.size
                assert post.x.tobytes() == ungated_update(prior, kept)[0].x.tobytes()
            seen.add((type(policy).__name__, kept is None, n_rejected > 0))
    assert ("ChiSquareEpoch", True, False) in seen and ("ChiSquarePerMeasurement", False, True) in seen
    assert ("AnchorDropping", False, True) in seen
