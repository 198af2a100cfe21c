"""Every estimator of the package, from one registry, held to the same contract.

For each method and each fixture tree (a generated ``lias-planar-uwb`` room and a generated
``iasl-uwb-imu`` flight, opened through :func:`uwbwb.datasets.open`):

* it returns :class:`~uwbwb.types.Estimates` on the scored recording's epochs, every status a
  valid :class:`~uwbwb.types.EstimateStatus`, positions NaN exactly where there is no estimate,
  and at least some estimates;
* the same seed gives the same numbers (a second run, bit for bit);
* moving the scoring truth changes nothing (estimators see measurements and the calibration,
  never the truth of what they are scored on).

The registry is the scoreboard's (:func:`uwbwb.scoreboard.estimators.default_estimators`, every
method wrapped into one interface) plus the TDoA EKF under each gate policy of
:mod:`uwbwb.filters.gating`. A new method joins by being added there (or to :data:`EXTRA`).
Methods that do not apply to a recording (the UWB/INS filters without an IMU, the planar
set-noise filters in 3-D) must say why, and every method must run on at least one tree.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.fixtures import iasl as fx_iasl
from tests.fixtures import lias as fx_lias
from uwbwb import datasets
from uwbwb.filters.ekf import TdoaEkf
from uwbwb.filters.gating import AnchorDropping, ChiSquareEpoch, ChiSquarePerMeasurement, NoGate
from uwbwb.models.motion import RandomForce
from uwbwb.scoreboard.board import calibrate
from uwbwb.scoreboard.estimators import RangeEkfEstimator, TdoaEkfEstimator, default_estimators
from uwbwb.scoreboard.interface import BaseEstimator, _tdoa_model
from uwbwb.scoreboard.protocol import scored_tags, split_in_time
from uwbwb.types import EstimateStatus, Estimates, TdoaLog, pseudo_tdoa

RATE_HZ = 10.0
SEED = 7


class GatedTdoaEkf(BaseEstimator):
    """The TDoA EKF (random force) on calibrated ranges with a given gate policy."""

    def __init__(self, gate):
        self.gate = gate
        self.name = f"EKF-RF {type(gate).__name__}"

    def estimate(self, rec, tag, cal):
        log = rec.ranges_of(tag, cal.range_calibration)
        d, ref = pseudo_tdoa(log.range_m, 0)
        model = _tdoa_model(rec, tag, cal)
        return TdoaEkf(RandomForce(0.5, dim=cal.dim), model, gate=self.gate).run(
            TdoaLog(log.t_s, d, ref, rec.anchors.ids)).to_estimates()


#: Methods beside the scoreboard's: the TDoA EKF under every gate policy.
EXTRA = (GatedTdoaEkf(NoGate()), GatedTdoaEkf(ChiSquareEpoch(0.9999)),
         GatedTdoaEkf(ChiSquarePerMeasurement(0.9999)), GatedTdoaEkf(AnchorDropping(0.9999, min_rows=2)))


def registry():
    """The scoreboard's methods (FAST sizes; each EKF tuned over one driving-noise value, since tuning is not
    what this test is about and costs a filter run per grid value) and :data:`EXTRA`."""
    methods = []
    for e in default_estimators(fast=True, seed=SEED):
        if isinstance(e, (TdoaEkfEstimator, RangeEkfEstimator)):
            e = replace(e, grid=(e.grid[len(e.grid) // 2],))
        methods.append(e)
    return [*methods, *EXTRA]


NAMES = [e.name for e in registry()]


def _moved(rec, offset_m):
    """The recording with every truth trajectory moved by ``offset_m`` (measurements untouched)."""
    truth = {t: replace(tr, pos_m=tr.pos_m + np.asarray(offset_m)[: tr.pos_m.shape[1]]) for t, tr in rec.truth.items()}
    return replace(rec, truth=truth)


@pytest.fixture(scope="module")
def trees(tmp_path_factory):
    """``{tree: (scored recording, tag, calibration)}`` for the two fixture trees."""
    root = tmp_path_factory.mktemp("data")
    rng = np.random.default_rng(20)
    fx_lias.make_tree(root, rng=rng, dynamic={"fast": {"duration_s": 10.0, "clock_offset_s": 0.1}},
                      sessions=[fx_lias.session_814(rng, files=((1, 0),))], static_rows=24)
    fx_iasl.write_dataset(root / "iasl-uwb-imu", rng=rng, duration_s=32.0)
    out = {}
    lias = datasets.open("lias-planar-uwb/fast", root)
    cal_part, test = split_in_time(lias, 0.5)
    out["lias"] = (cal_part, test)
    cal_rec, test = datasets.open_pair("iasl-uwb-imu/scenario1", "iasl-uwb-imu/scenario2", root)
    out["iasl"] = (cal_rec, test)
    ready = {}
    for key, (cal_rec, test) in out.items():
        tag = scored_tags(test)[0]
        cal_rec = cal_rec.between(-np.inf, np.inf)
        cal = calibrate(cal_rec, registry(), [tag], rate_hz=RATE_HZ)
        ready[key] = (test.decimate(rate_hz=RATE_HZ), tag, cal)
    return ready


def _same(a: Estimates, b: Estimates) -> bool:
    arrays = [(a.t_s, b.t_s), (a.pos_m, b.pos_m), (a.status, b.status)]
    if a.pos_cov_m2 is not None or b.pos_cov_m2 is not None:
        arrays.append((a.pos_cov_m2, b.pos_cov_m2))
    return all(x is not None and y is not None and x.shape == y.shape and x.tobytes() == y.tobytes()
               for x, y in arrays)


@pytest.mark.parametrize("tree", ["lias", "iasl"])
@pytest.mark.parametrize("name", NAMES)
def test_estimator_contract(trees, tree, name):
    rec, tag, cal = trees[tree]
    method = next(e for e in registry() if e.name == name)
    why = method.applies(rec, tag, cal)
    if why is not None:
        assert isinstance(why, str) and why
        pytest.skip(f"{name} does not apply to the {tree} tree: {why}")
    est = method.estimate(rec, tag, cal)
    assert isinstance(est, Estimates)
    assert set(np.unique(est.status)) <= {int(s) for s in EstimateStatus}
    no = est.status == EstimateStatus.NO_ESTIMATE
    assert np.all(np.isnan(est.pos_m[no])) and np.all(np.isfinite(est.pos_m[~no]))
    assert est.has_estimate.sum() > 0, f"{name} gave no estimate on the {tree} tree"
    assert est.t_s[0] >= rec.ranges[tag].t_s[0] - 1e-9 and est.t_s[-1] <= rec.ranges[tag].t_s[-1] + 1e-9
    again = next(e for e in registry() if e.name == name).estimate(rec, tag, cal)
    assert _same(est, again), f"{name}: the same seed gave different numbers"
    moved = method.estimate(_moved(rec, [0.7, -0.4, 0.2]), tag, cal)
    assert _same(est, moved), f"{name}: moving the scoring truth changed the estimates"


def test_every_method_runs_on_some_tree(trees):
    ran = {e.name: [k for k, (rec, tag, cal) in trees.items() if e.applies(rec, tag, cal) is None]
           for e in registry()}
    assert all(ran.values()), {n: k for n, k in ran.items() if not k}


def test_registry_names_are_unique():
    assert len(NAMES) == len(set(NAMES))


def test_every_result_type_gives_the_common_result_with_no_argument():
    """One result family: every run or result turns into :class:`Estimates` with ``to_estimates()``
    (sweeps into an ``EstimatesBatch`` of them), and every run type's NIS consistency has the keys
    of :func:`uwbwb.metrics.nis_consistency`."""
    from uwbwb import metrics
    from uwbwb.filters import nls, pruning, tdoa_ls
    from uwbwb.filters.doppler import pf as doppler_pf
    from uwbwb.filters.eskf.result import FusionRun, _empty
    from uwbwb.filters.setnoise import kf as setnoise_kf
    from uwbwb.filters.setnoise import pf as setnoise_pf
    from uwbwb.geometry import multilaterate
    from uwbwb.models.tdoa import TdoaModel
    from uwbwb.types import EstimatesBatch, RangeLog

    rng = np.random.default_rng(3)
    T, t = 12, np.arange(12) * 0.2
    anchors = np.array([[0, 0, 0.5], [10, 0, 2.5], [0, 10, 2.0], [10, 10, 0.2], [5, -3, 3.0]])
    truth = np.column_stack([np.linspace(2, 5, T), np.linspace(3, 4, T), np.full(T, 1.0)])
    r = np.linalg.norm(truth[:, None] - anchors[None], axis=-1) + rng.normal(0, 0.02, (T, 5))
    ids = tuple("abcde")
    log = RangeLog(t, r, ids)
    tdoa = TdoaLog(t, *pseudo_tdoa(r, 0), ids)
    model = TdoaModel(anchors, sigma_m=0.05, dim=3)
    sw = setnoise_kf.kf_sweep(t, truth[:, :2], np.zeros((T, 2)), np.full((T, 2), 0.1), truth[0, :2], [0.1, 0.3])
    kf_run = setnoise_pf.FilterRun(t, sw.state[0], np.full(T, np.nan), np.zeros(T, bool), "KF", cov=sw.cov[0],
                                   nis=sw.nis[0])
    singles = {
        "multilateration": multilaterate(r, anchors, dim=3, t_s=t, name="ML"),
        "TDoA LS": tdoa_ls.tdoa_least_squares(tdoa, model, name="TDoA"),
        "NLS line": nls.fit_trajectory(log, anchors, dim=3),
        "pruning": pruning.localize(log, anchors, "none", stationary=False),
        "KalmanRun": TdoaEkf(RandomForce(0.5, dim=3), model).run(tdoa),
        "FusionRun": FusionRun(t, name="fusion", **_empty(T, 15)),
        "FilterRun (PF)": setnoise_pf.reference_pf(t, truth[:, :2], np.zeros((T, 2)), np.full((T, 2), 0.1),
                                                   truth[0, :2], 0.2, rng=rng, n_particles=50),
        "FilterRun (KF)": kf_run,
    }
    for what, res in singles.items():
        est = res.to_estimates()
        assert type(est) is Estimates and est.has_estimate.any() or what == "FusionRun", what
    pf_sw = setnoise_pf.pf_sweep(t, truth[:, :2], np.zeros((T, 2)), np.full((T, 2), 0.1), truth[0, :2], [0.1, 0.3],
                                 rng=rng, n_trials=2, n_particles=20)
    runs = doppler_pf.PfRuns(t, np.repeat(truth[None], 3, axis=0), np.zeros((3, T), np.int8))
    for what, res, n in (("KFSweep", sw, 2), ("PFSweep", pf_sw, 4), ("PfRuns", runs, 3)):
        batch = res.to_estimates()
        assert type(batch) is EstimatesBatch and len(batch) == n, what
        assert all(type(e) is Estimates and len(e) == T for e in batch), what
    np.testing.assert_array_equal(sw.to_estimates()[0].pos_cov_m2, kf_run.to_estimates().pos_cov_m2)
    keys = set(metrics.nis_consistency([1.0], [1]))
    for what in ("KalmanRun", "FusionRun", "FilterRun (PF)", "FilterRun (KF)"):
        assert set(singles[what].nis_consistency()) == keys, what
    assert singles["FilterRun (KF)"].nis_consistency()["n"] == T
    assert singles["FilterRun (PF)"].nis_consistency()["verdict"] == "no updates"
