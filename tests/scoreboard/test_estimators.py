"""The board's adapters: the EKFs' tuning criterion, and the UWB/INS adapters (what they run per grid point)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.fixtures import iasl as fx
from uwbwb.datasets import iasl
from uwbwb.filters import alignment
from uwbwb.scoreboard import Calibration, calibrate
from uwbwb.scoreboard.estimators import INS_GRID_FAST, TdoaEkfEstimator, TdoaLs, UwbInsFilter
from uwbwb.sim import walk


def _office(sigma_m=0.1):
    """A simulated office walk and a calibration of it without range calibration (ranges as logged)."""
    cfg = walk.office(duration_s=20.0)
    rec, _ = walk.simulate_walk(cfg, rng=np.random.default_rng(3))
    sigma = np.broadcast_to(sigma_m, (len(rec.anchors),))
    return rec, Calibration("office", 2, {m.tag_id: m.height_m for m in cfg.tags}, None,
                            {t: sigma for t in rec.tags}, 10.0)


def test_ekf_tuning_minimises_the_mean_over_tags_of_its_criterion():
    rec, cal = _office()
    tags = list(rec.tags)
    assert rec.ranges_of(tags[0], cal.range_calibration) is rec.ranges[tags[0]]     # no range calibration: as logged
    grid = (0.05, 1.0, 20.0)
    for criterion, key in (("rmse", "grid_rmse_m"), ("cep95", "grid_cep95_m")):
        p = TdoaEkfEstimator("RW", gate_prob=None, grid=grid, criterion=criterion).tune(rec, tags, cal)
        for c in ("rmse", "cep95"):                                         # both means, from each tag's scores
            np.testing.assert_allclose(p[f"grid_{c}" + "_m"], np.mean([p["grid_by_tag"][t][c] for t in tags], axis=0))
        assert p["criterion"] == criterion and p["sigma_w"] == grid[int(np.argmin(p[key]))] == 1.0
    with pytest.raises(ValueError, match="criterion"):
        TdoaEkfEstimator("RW", grid=grid, criterion="mae").tune(rec, tags, cal)


def test_tdoa_methods_offer_the_diagonal_shortcut():
    """With the reference-correlated Σ the TDoA fix and filter do not depend on the reference anchor; with its
    diagonal (``correlated=False``, notebook 03's exercise) they do."""
    rec, cal = _office(np.linspace(0.05, 0.3, 6))
    cal = cal.with_tuned("EKF-RW", {"sigma_w": 1.0})
    for make in (lambda **k: TdoaLs(**k), lambda **k: TdoaEkfEstimator("RW", gate_prob=None, **k)):
        pos = {(c, ref): make(ref=ref, correlated=c).estimate(rec, "tag1", cal).pos_m for c in (True, False)
               for ref in (0, 2)}
        np.testing.assert_allclose(pos[True, 0], pos[True, 2], atol=1e-6)
        assert np.nanmax(np.abs(pos[False, 0] - pos[False, 2])) > 1e-3


def _flights(tmp_path):
    fx.write_dataset(tmp_path / "iasl-uwb-imu", rng=np.random.default_rng(21), duration_s=30.0)
    return (iasl.load_scenario("scenario1", tmp_path).decimate(rate_hz=10.0),
            iasl.load_scenario("scenario2", tmp_path).decimate(rate_hz=10.0))


def test_uwb_ins_tuning_aligns_once_and_runs_only_its_own_filter_per_grid_point(tmp_path, monkeypatch):
    cal_rec, _ = _flights(tmp_path)
    calls = {"align": 0, "filters": []}
    align, run = alignment.align_iasl, alignment.run_fusion_filter

    def counted_align(*a, **k):
        calls["align"] += 1
        return align(*a, **k)

    def counted_run(name, *a, **k):
        calls["filters"].append(name)
        return run(name, *a, **k)

    monkeypatch.setattr(alignment, "align_iasl", counted_align)
    monkeypatch.setattr(alignment, "run_fusion_filter", counted_run)
    calibrate(cal_rec, [UwbInsFilter("tight", {}, INS_GRID_FAST)], rate_hz=None)
    assert calls["align"] == 1                                   # one start-up for the whole grid
    assert calls["filters"] == ["tight"] * len(INS_GRID_FAST)    # one filter run per grid point, its own


def test_an_ekf_with_knobs_tunes_the_fusion_filters_pairs_about_its_fitted_motion_and_the_calibrated_noise():
    """``knobs``: each (Q ×, R ×) point is the EKF at σ_w = √(Q ×) × the σ_w fitted to the calibration truth, with
    every range σ × √(R ×); the pick is the lowest mean RMSE, its edge knobs named; ``estimate`` runs the pick."""
    from uwbwb.scoreboard.estimators import INS_GRID, RangeEkfEstimator, default_estimators, edge_knobs
    from uwbwb.scoreboard.reference import REFERENCE

    rec, cal = _office()
    tags = list(rec.tags)
    with pytest.raises(ValueError, match="fitted to the calibration truth"):
        TdoaEkfEstimator("RW", gate_prob=None, knobs=((1.0, 1.0),)).tune(rec, tags, cal)
    cal = cal.with_tuned(REFERENCE, {"sigma_w_per_model": {"RW": 0.5}})
    grid = ((0.1, 1.0), (1.0, 1.0), (1.0, 2.25), (1.0, 4.0), (100.0, 4.0))
    p = TdoaEkfEstimator("RW", gate_prob=None, knobs=grid).tune(rec, tags, cal)
    for (q, r), rmse in zip(grid, p["grid_rmse_m"]):
        noisier = replace(cal, range_sigma_m={t: s * np.sqrt(r) for t, s in cal.range_sigma_m.items()})
        plain = TdoaEkfEstimator("RW", gate_prob=None, grid=(0.5 * np.sqrt(q),)).tune(rec, tags, noisier)
        assert rmse == pytest.approx(plain["grid_rmse_m"][0], rel=1e-12)
    best = int(np.argmin(p["grid_rmse_m"]))
    assert (p["q_scale"], p["r_scale"]) == grid[best] and p["sigma_w"] == pytest.approx(0.5 * np.sqrt(grid[best][0]))
    assert p["edge_knobs"] == edge_knobs(grid, best) and p["grid_edge"] == bool(p["edge_knobs"])
    assert edge_knobs(grid, 2) == () and edge_knobs(grid, 4) == ("Q × at its highest", "R × at its highest")
    assert edge_knobs(grid, 1) == ("R × at its lowest",)
    ekf = TdoaEkfEstimator("RW", gate_prob=None, knobs=grid)
    tuned = cal.with_tuned(ekf.name, {**p, "q_scale": 1.0, "r_scale": 4.0, "sigma_w": 0.5})
    noisier = replace(cal.with_tuned(ekf.name, {"sigma_w": 0.5}), range_sigma_m={t: 2.0 * s for t, s in cal.range_sigma_m.items()})
    np.testing.assert_array_equal(ekf.estimate(rec, tags[0], tuned).pos_m,
                                  TdoaEkfEstimator("RW", gate_prob=None).estimate(rec, tags[0], noisier).pos_m)
    ests = default_estimators(fast=False, equal_knobs=True)              # every EKF on the fusion filters' grid
    ekfs = [e for e in ests if isinstance(e, (TdoaEkfEstimator, RangeEkfEstimator))]
    assert len(ekfs) == 6 and all(e.knobs == INS_GRID for e in ekfs)
    assert all(e.knobs is None for e in default_estimators() if isinstance(e, (TdoaEkfEstimator, RangeEkfEstimator)))
