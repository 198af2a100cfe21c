from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from uwbwb import metrics
from uwbwb.calibration import empirical_tdoa_covariance, fit_range_sigma
from uwbwb.experiments import motion_models as mm
from uwbwb.models.tdoa import TdoaModel
from uwbwb.sim import walk
from uwbwb.types import Anchors, RangeLog, TagRun, Trajectory

def test_synthetic_acquisitions(office_runs):
    cal, test = office_runs
    assert [r.tag for r in test] == ["tag1", "tag2"] and all(r.raw is not None for r in test)
    assert test[0].name == "office" and cal[0].name == "office (calibration)"
    assert test[0].data == "synthetic" and test[0].dim == 2 and test[0].z_m == pytest.approx(1.8)
    assert test[0].dt_s == pytest.approx(0.1)
    assert not np.allclose(np.nan_to_num(cal[0].ranges.range_m), np.nan_to_num(test[0].ranges.range_m))
    again, _ = mm.synthetic_acquisition("office", seed=1, duration_s=25.0)
    np.testing.assert_array_equal(again[1].ranges.range_m, test[1].ranges.range_m)


def test_tag_runs_thinning_window_height_and_validation(office_runs):
    cfg = walk.office(duration_s=20.0)
    rec, _ = walk.simulate_walk(cfg, rng=np.random.default_rng(4))
    heights = {m.tag_id: m.height_m for m in cfg.tags}
    raw = {t: walk.device_output(rec.ranges[t], rec.anchors, z_m=heights[t]) for t in rec.tags}
    full = mm.tag_runs(rec, dim=2, z_m=heights, raw=raw)
    slow = mm.tag_runs(rec, dim=2, z_m=heights, raw=raw, rate_hz=2.0)
    assert slow[0].dt_s == pytest.approx(0.5) and len(slow[0].ranges) == int(np.ceil(len(full[0].ranges) / 5))
    np.testing.assert_array_equal(slow[1].ranges.t_s, rec.decimate(5).ranges["tag2"].t_s)   # the one thinning rule
    assert set(slow[0].raw.t_s) <= set(slow[0].ranges.t_s) and len(slow[0].truth) == len(full[0].truth)
    assert mm.tag_runs(rec, dim=2, z_m=heights, rate_hz=50.0)[0].ranges.t_s.size == len(full[0].ranges)
    assert [r.z_m for r in full] == [1.8, 1.3]
    with pytest.raises(ValueError, match="tag height"):       # 2-D needs a height that is not the test truth's
        mm.tag_runs(rec, dim=2)
    assert mm.tag_runs(rec, dim=3)[0].z_m == 0.0
    run = office_runs[1][0]
    part = run.between(5.0, 10.0, name="part")
    assert part.name == "part" and part.ranges.t_s.min() >= 5.0 and part.ranges.t_s.max() < 10.0
    assert part.truth.t_s[0] <= 5.0 and part.truth.t_s[-1] >= 10.0
    other = Anchors(tuple("BCDEFG"), run.anchors.pos_m)
    with pytest.raises(ValueError, match="differ"):
        replace(run, anchors=other)


def test_true_ranges_and_sigma_fit_on_los_data(los_run):
    r = los_run.ranges.range_m - los_run.true_range_m()
    assert abs(np.nanmean(r)) < 0.01
    sig = fit_range_sigma(los_run)
    np.testing.assert_allclose(sig, 0.05, rtol=0.15)
    true = los_run.true_range_m()                      # the notebook's check: TDoA errors against the model's Σ
    empirical = empirical_tdoa_covariance(los_run.tdoa(2).tdoa_m, true - true[:, [2]], 2)
    model = TdoaModel.for_tag(los_run, sig).covariance(np.delete(np.arange(6), 2), 2)
    assert empirical.shape == model.shape == (5, 5)
    np.testing.assert_allclose(empirical, model, atol=0.0015)          # σ²(I + 11ᵀ) with σ ≈ 5 cm
    assert np.all(np.diag(empirical) > 1.5 * empirical[0, 1])


def test_raw_multilateration_is_exact_on_exact_ranges():
    anchors = Anchors(tuple("ABCD"), np.array([[0, 0, 2.5], [10, 0, 2.5], [10, 8, 2.4], [0, 8, 2.6]]))
    t = np.arange(20) * 0.1
    pos = np.column_stack([2 + 0.5 * t, 3 + 0.2 * t, np.full(t.size, 1.2)])
    r = np.linalg.norm(pos[:, None] - anchors.pos_m, axis=-1)
    run = TagRun("synthetic", "x", "t", RangeLog(t, r, anchors.ids, "t"), Trajectory(t, pos), anchors, 2, 1.2)
    raw = mm.estimate(run, 0.1, {"RW": 1.0}, gate_prob=None, models=("RW",)).estimates("raw")   # no device output
    np.testing.assert_allclose(raw.pos_m, pos[:, :2], atol=1e-6)


def test_estimate_calibrate_and_tables(office_runs):
    cal, test = office_runs
    grids = {"RW": [0.1, 1.0], "RF": [1.0], "RJ": [1.0, 10.0]}
    study = mm.run_study(cal, test, grids=grids, gate_prob=None, progress=False)
    curves = study.curves
    assert len(curves) == 2 * 5
    assert list(curves.columns) == ["run", "tag", "model", "sigma", "sigma_unit", "psd", "psd_unit", "cep95_m",
                                    "rmse_m"]
    np.testing.assert_allclose(curves.psd, curves.sigma ** 2 * 0.1)
    assert set(curves.psd_unit) == {"m²/s", "m²/s³", "m²/s⁵"}
    best = study.best
    assert set(best) == {"RW", "RF", "RJ"} and best["RF"] == 1.0
    # a random walk driven by 0.1 m/s cannot follow a 0.8 m/s walker
    rw = curves[curves.model == "RW"].groupby("sigma").cep95_m.mean()
    assert rw[0.1] > rw[1.0] and best["RW"] == 1.0
    # the tuning is the board's (CEP95 criterion): the pick minimises the mean CEP95 over the tags
    p = study.calibration.params("EKF-RJ")
    assert p["criterion"] == "cep95" and best["RJ"] == p["grid"][int(np.argmin(p["grid_cep95_m"]))]
    np.testing.assert_allclose(curves[curves.model == "RJ"].groupby("sigma").cep95_m.mean(), p["grid_cep95_m"])
    np.testing.assert_array_equal(study.calibration.sigma("tag1"), fit_range_sigma(cal[0]))

    est = mm.estimate(test[0], study.calibration.sigma("tag1"), best, gate_prob=None)
    assert est.methods == ("raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ") == mm.METHODS
    c = est.cep95()
    assert all(0 < v < 3 for v in c.values())
    assert c["EKF-RW"] < c["raw"]
    assert min(est.coverage().values()) > 0.95
    nis = est.nis()
    assert list(nis.index) == ["EKF-RW", "EKF-RF", "EKF-RJ"] and (nis["n"] > 200).all()
    assert set(nis["verdict"]) <= {"consistent", "over-confident", "under-confident"}
    assert (nis["mean_lo"] < 1).all() and (nis["mean_hi"] > 1).all()
    table = study.table(["raw", "LS", "EKF-RW"])
    assert table.loc[("office", "tag1"), "LS"] == pytest.approx(c["LS"])


def test_the_tuned_filter_is_the_study_filter(office_runs):
    """The tuning scores the filter the study tests: tested on its own calibration runs, each EKF's CEP95 and RMSE
    per tag are the tuning's at that σ_w. The tuning runs every tag at the calibration's one rate (1 / median
    epoch step over the tags), a test run at its own: on these runs the steps differ in their last bits, hence
    the tolerance."""
    cal, _ = office_runs
    study = mm.run_study(cal, cal, grids={"RW": [1.0], "RF": [2.0], "RJ": [5.0]}, gate_prob=None, progress=False)
    for run in cal:
        res = study.result_for(run.name, run.tag)
        for m in mm.MODELS:
            tuned = study.calibration.params(mm.ekf_name(m))["grid_by_tag"][run.tag]
            errors = res.scores[mm.ekf_name(m)].own_m
            want = [[metrics.rmse(errors)], [metrics.cep95(errors)]]
            np.testing.assert_allclose([tuned["rmse"], tuned["cep95"]], want, rtol=1e-12)


def test_ranking_and_the_thesis_tables():
    table = pd.DataFrame({"EKF-RW": [0.4, 0.5], "EKF-RF": [0.7, 0.3], "EKF-RJ": [1.0, 0.45]},
                         index=pd.MultiIndex.from_tuples([("office", "tag1"), ("agv1", "tag1")], names=["run", "tag"]))
    assert list(mm.ranking(table)) == ["RW < RF < RJ", "RF < RJ < RW"]
    # values equal as the table prints them share a place: no order the printed numbers do not show
    close = pd.DataFrame({"EKF-RW": [0.4406], "EKF-RF": [0.4399], "EKF-RJ": [0.45]})
    assert list(mm.ranking(close, decimals=2)) == ["RF = RW < RJ"]
    assert list(mm.ranking(close)) == ["RF < RW < RJ"]                  # at the default 3 decimals they differ
    assert mm.PAPER_MODELS_CEP95[("office", "tag2")] == {"EKF-RW": 0.48, "EKF-RF": 1.13, "EKF-RJ": 1.14}
    assert mm.PAPER_METHODS_CEP95[("office", "tag2")]["raw"] == 2.03


def test_sigma_fit_methods_and_common_mode(los_run):
    # a range error common to all anchors cancels in every TDoA: the 'tdoa' fit ignores it, 'rms' does not
    shifted = replace(los_run, ranges=RangeLog(los_run.ranges.t_s, los_run.ranges.range_m + 0.4,
                                               los_run.ranges.anchor_ids, los_run.tag))
    np.testing.assert_allclose(fit_range_sigma(shifted), fit_range_sigma(los_run), atol=1e-9)
    assert np.all(fit_range_sigma(shifted, method="rms") > 0.35)
    np.testing.assert_allclose(fit_range_sigma(shifted, method="robust"), 0.05, rtol=0.15)
    assert np.all(fit_range_sigma(los_run, floor_m=0.2) == 0.2)
    with pytest.raises(ValueError, match="method"):
        fit_range_sigma(los_run, method="mad")


def test_study(office_runs):
    cal, test = office_runs
    grids = {"RW": [1.0], "RF": [1.0, 3.0], "RJ": [3.0]}
    study = mm.run_study(cal, test, grids=grids, gate_prob=None, progress=False)
    assert study.best == {"RW": 1.0, "RF": study.best["RF"], "RJ": 3.0}
    assert set(study.calibration.range_sigma_m) == {"tag1", "tag2"} and study.calibration.sigma("tag1").shape == (6,)
    table = study.table()
    assert list(table.columns) == ["raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ"] and len(table) == 2
    assert study.result_for("office", "tag2").run.tag == "tag2"
    assert list(study.coverage().columns) == [*mm.METHODS, "common"]
    assert study.nis().index.names == ["run/tag", "method"] and len(study.nis()) == 6
    with pytest.raises(KeyError, match="no test result"):
        study.result_for("office", "tag9")
    with pytest.raises(ValueError, match="no calibration run"):
        mm.run_study(cal[:1], test, grids=grids, gate_prob=None, progress=False)
    with pytest.raises(ValueError, match="one per tag"):
        mm.run_study(cal + cal[:1], test, grids=grids, gate_prob=None, progress=False)
    with pytest.raises(TypeError, match="gate_prob"):
        mm.run_study(cal, test, grids=grids, progress=False)          # the gate is always the caller's choice


def _outage(run, t0_s, t1_s, keep=2):
    """``run`` with all but ``keep`` anchors missing in ``[t0_s, t1_s)``: LS fails there, the EKF coasts."""
    r = run.ranges.range_m.copy()
    r[(run.ranges.t_s >= t0_s) & (run.ranges.t_s < t1_s), keep:] = np.nan
    return replace(run, ranges=RangeLog(run.ranges.t_s, r, run.ranges.anchor_ids, run.tag), raw=None)


def test_scoring_on_common_epochs_with_coverage_beside(office_runs):
    cal, test = office_runs
    run = _outage(test[0], 10.0, 14.0)
    est = mm.estimate(run, fit_range_sigma(cal[0]), {"RW": 1.0, "RF": 3.0, "RJ": 10.0}, gate_prob=None)
    cov = est.coverage()
    assert cov["EKF-RW"] > cov["LS"] + 0.1 and cov["common"] == pytest.approx(cov["LS"], abs=0.01)
    scores, t_s = est.scores, run.ranges.t_s
    t = t_s[scores["LS"].common]
    assert not np.any((t >= 10.0) & (t < 14.0))                            # LS's outage is not scored
    common = est.common_errors()
    assert len({e.size for e in common.values()}) == 1 and common["LS"].size == t.size
    ekf_own = scores["EKF-RW"].scored
    in_outage = ekf_own & (t_s >= 10.0) & (t_s < 14.0)
    assert in_outage.sum() > 30                                              # the EKF coasted there ...
    assert common["EKF-RW"].size == ekf_own.sum() - in_outage.sum()        # ... and is scored without them
    own = metrics.cep95(scores["LS"].own_m)
    assert own == pytest.approx(est.cep95()["LS"])                           # LS's own epochs are the common ones
    table = mm.Study(None, {}, [est]).coverage()
    assert table.loc[("office", "tag1"), "LS"] == pytest.approx(100 * cov["LS"])
    board = est.board.table().set_index("method")                          # coverage and NIS are the board's
    assert [cov[m] for m in est.methods] == pytest.approx(list(board.loc[list(est.methods), "coverage"]))
    nis = est.nis()
    assert list(nis["mean_nis_over_dof"]) == pytest.approx(list(board.loc[nis.index, "nis_over_dof"]))
    assert list(nis["verdict"]) == list(board.loc[nis.index, "nis_verdict"])
    with pytest.raises(ValueError, match="no epoch where every estimator"):
        mm.estimate(_outage(test[0], -1.0, 1e9), fit_range_sigma(cal[0]), {"RW": 1.0}, gate_prob=None,
                    models=("RW",)).cep95()


def test_nis_verdict_follows_the_noise_level(los_run):
    # pure LOS noise: with the fitted σ the filter is near consistent; with σ × 3 it is under-confident and
    # with σ / 3 over-confident (the χ² interval for ~1500 innovations is about ±7 % around 1)
    sig = fit_range_sigma(los_run)
    verdict = {}
    for k in (1 / 3, 1.0, 3.0):
        est = mm.estimate(los_run, sig * k, {"RW": 1.0}, gate_prob=None, models=("RW",))
        verdict[k] = est.nis().loc["EKF-RW"]
    assert verdict[3.0]["verdict"] == "under-confident" and verdict[1 / 3]["verdict"] == "over-confident"
    assert verdict[3.0]["mean_nis_over_dof"] < verdict[1.0]["mean_nis_over_dof"] < verdict[1 / 3]["mean_nis_over_dof"]
    assert 0.5 < verdict[1.0]["mean_nis_over_dof"] < 2.0


def test_summary_rows_say_their_kind(office_runs):
    cal, test = office_runs
    est = mm.estimate(test[0], fit_range_sigma(cal[0]), {"RW": 1.0, "RF": 3.0, "RJ": 10.0}, gate_prob=None)
    rows = mm.headlines.summary_rows([est], data="synthetic", paper=True)
    by_q = {r["quantity"]: r for r in rows}
    assert by_q["CEP95 office tag1 EKF-RW"]["paper_value"] == 0.41
    assert by_q["CEP95 office tag1 EKF-RW"]["value"] == pytest.approx(est.cep95()["EKF-RW"])
    assert by_q["coverage office tag1 LS"]["unit"] == "%" and by_q["coverage office tag1 LS"]["paper_value"] is None
    assert "mean NIS/dof office tag1 EKF-RJ" in by_q
    assert {r["kind"] for r in rows} == {"reproduced"}
    real = mm.headlines.summary_rows([est], data="lias-planar-uwb/x", label="{tag} {method} (calibrated, test part {run})")
    assert "CEP95 tag1 LS (calibrated, test part office)" in {r["quantity"] for r in real}
    assert all(r["paper_value"] is None for r in real)
    sig = {r["quantity"]: r for r in mm.headlines.sigma_rows({"RW": 1.6, "RF": 4.5, "RJ": 15.0}, "office")}
    assert sig["driving sigma RW (office)"]["kind"] == "target"               # the simulated speed equals it
    assert sig["driving sigma RF (office)"]["kind"] == "reproduced"
    assert sig["driving sigma RW (office)"]["paper_value"] == 0.83 and sig["driving sigma RJ (office)"]["unit"] == "m/s³"


def test_a_new_tdoa_estimator_of_the_registry_joins_every_table(office_runs, monkeypatch):
    """Notebook 03 takes its methods from the one registry: an estimator added there with ``tdoa = True`` is
    tuned, run, scored and summarised by the study without a change to this package."""
    from dataclasses import dataclass

    from uwbwb.scoreboard import estimators as registry

    @dataclass(frozen=True)
    class Twin(registry.TdoaLs):           # a newcomer's TDoA method: here the LS fix under another name
        name: str = "TDoA LS twin"

    board = registry.default_estimators()
    monkeypatch.setattr(mm.results, "default_estimators", lambda: [*board, Twin()])
    cal, test = office_runs
    study = mm.run_study(cal, test, grids={"RW": [1.0], "RF": [3.0], "RJ": [10.0]}, gate_prob=None, progress=False)
    table = study.table()
    assert list(table.columns) == [*mm.METHODS, "TDoA LS twin"]
    np.testing.assert_array_equal(table["TDoA LS twin"], table["LS"])
    assert "TDoA LS twin" in study.coverage().columns
    rows = {r["quantity"] for r in mm.headline_rows(mm.Results(synthetic={"office": study}))}
    assert {"CEP95 office tag1 TDoA LS twin", "coverage office tag2 TDoA LS twin"} <= rows
