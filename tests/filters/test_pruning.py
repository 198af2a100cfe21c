"""Pruning heuristics of Zupanec et al. (sec. 2.5), each on a case with a known answer."""

from __future__ import annotations

from dataclasses import replace
from math import comb

import numpy as np
import pytest

from uwbwb import RangeLog
from uwbwb.types import RangeSamples
from uwbwb.filters import nls, pruning

XY = np.array([[1.0, 1.0], [12.0, 0.5], [18.0, 6.0], [14.0, 11.0], [3.0, 10.0], [7.0, 4.5]])
ANCHORS = np.column_stack([XY, 3.9 + 0.6 * XY[:, 0] / 18.0])
IDS = tuple(str(i + 1) for i in range(6))
P_TRUE = np.array([7.0, 4.0, 2.0])


def _static_log(rng, *, T=80, sigma_m=0.05, p_nlos=0.0, nlos_m=(1.0, 4.0), p=P_TRUE):
    r_true = np.linalg.norm(p - ANCHORS, axis=1)
    r = r_true + sigma_m * rng.standard_normal((T, 6))
    nlos = rng.random((T, 6)) < p_nlos
    r = r + nlos * rng.uniform(*nlos_m, (T, 6))
    return RangeLog(np.arange(T) * 0.13, r, IDS), nlos


def test_drop_schedule():
    s = pruning.drop_schedule(1000, 0.5, 0.01)
    assert s.sum() == 500 and set(s) == {10} and s.size == 50
    s = pruning.drop_schedule(1001, 0.9, 0.005)
    assert 1001 - s.sum() == 901 and s[-1] <= 5
    assert pruning.drop_schedule(10, 1.0, 0.1).size == 0
    assert pruning.drop_schedule(7, 0.5, 0.01).tolist() == [1, 1, 1]   # at least one per step


def test_config_validates():
    with pytest.raises(ValueError, match="percentile"):
        pruning.PruningConfig(percentile=0)
    with pytest.raises(ValueError, match="retention"):
        pruning.PruningConfig(res_retention=1.5)
    with pytest.raises(ValueError, match="dropout"):
        pruning.PruningConfig(rm_dropout=0)
    with pytest.raises(ValueError, match="tuple_size"):
        pruning.PruningConfig(tuple_size=2)


# ------------------------------------------------------------------ 5th percentile


def test_percentile_ranges_per_anchor():
    r = np.array([[1.0, 5.0], [2.0, np.nan], [3.0, 7.0]])
    np.testing.assert_allclose(pruning.percentile_ranges(r, 50), [2.0, 6.0])
    r[:, 1] = np.nan
    out = pruning.percentile_ranges(r, 5)
    assert out[0] == pytest.approx(1.1) and np.isnan(out[1])


def test_percentile_heuristic_ignores_the_nlos_mode(rng):
    # 40 % of ranges carry +1..4 m NLOS: their 5th percentile is still a LOS range
    log, _ = _static_log(rng, p_nlos=0.4, sigma_m=0.03)
    cfg = pruning.PruningConfig()
    pct = pruning.localize(log, ANCHORS, "percentile", cfg, stationary=True, z_m=2.0)
    plain = pruning.localize(log, ANCHORS, "none", cfg, stationary=True, z_m=2.0)
    d = pct.detail
    r_true = np.linalg.norm(P_TRUE - ANCHORS, axis=1)
    # the 5th percentile of a LOS Gaussian sits 1.645 sigma short of the truth
    np.testing.assert_allclose(d, r_true - 1.645 * 0.03, atol=0.04)
    assert np.linalg.norm(pct.p0_m[:2] - P_TRUE[:2]) < 0.15
    assert np.linalg.norm(plain.p0_m - P_TRUE) > 3 * np.linalg.norm(pct.p0_m[:2] - P_TRUE[:2])
    assert pct.n_used == 6 and np.all(pct.vel_mps == 0)


def test_percentile_refuses_moving_segments(rng):
    log, _ = _static_log(rng)
    with pytest.raises(ValueError, match="stationary"):
        pruning.localize(log, ANCHORS, "percentile", stationary=False)


# ------------------------------------------------------------------ robust mean


def test_robust_mean_keeps_the_cluster_and_drops_the_scatter(rng):
    inliers = np.array([1.0, 2.0]) + 0.05 * rng.standard_normal((700, 2))
    outliers = np.array([1.0, 2.0]) + rng.uniform(1.0, 6.0, (300, 1)) * \
        np.column_stack([np.cos(a := rng.uniform(0, 2 * np.pi, 300)), np.sin(a)])
    pts = np.vstack([inliers, outliers])
    res = pruning.robust_mean(pts, retention=0.5, dropout=0.01)
    assert res.kept.sum() == 500 and res.n_iter == 50
    assert not res.kept[700:].any()                           # every outlier pruned
    np.testing.assert_allclose(res.center_m, [1.0, 2.0], atol=0.01)
    assert np.linalg.norm(res.history_m[0] - [1.0, 2.0]) > 5 * np.linalg.norm(res.center_m - [1.0, 2.0])


def test_robust_mean_on_a_moving_cloud_fits_the_line(rng):
    t = np.repeat(np.arange(0, 10, 0.13), 20)
    pts = np.array([2.0, 1.0]) + np.outer(t, [0.5, -0.2]) + 0.1 * rng.standard_normal((t.size, 2))
    bad = rng.random(t.size) < 0.2
    pts[bad] += rng.uniform(2, 5, (bad.sum(), 2))
    res = pruning.robust_mean(pts, t_s=t, retention=0.5, dropout=0.01)
    np.testing.assert_allclose(res.vel_mps, [0.5, -0.2], atol=0.01)
    np.testing.assert_allclose(res.center_m, [2.0, 1.0], atol=0.05)
    assert res.kept[bad].sum() == 0


def test_tuple_fixes_noise_free_and_collinear_tuples_skipped():
    r = np.tile(np.linalg.norm(P_TRUE - ANCHORS, axis=1), (4, 1))
    r[1, 0] = np.nan
    cloud = pruning.tuple_fixes(r, ANCHORS, z_m=2.0, t_s=np.arange(4.0))
    assert cloud.tuples.shape == (comb(6, 3), 3) and cloud.skipped_tuples.size == 0
    assert len(cloud) == 4 * 20 - comb(5, 2)                  # epoch 1 lacks anchor 1: 10 triplets fail
    assert cloud.n_failed == comb(5, 2)
    np.testing.assert_allclose(cloud.pos_m, np.tile(P_TRUE[:2], (len(cloud), 1)), atol=1e-6)
    # three anchors in a row are skipped, not localised
    A = ANCHORS.copy()
    A[5, :2] = (A[0, :2] + A[1, :2]) / 2
    cloud = pruning.tuple_fixes(np.linalg.norm(P_TRUE - A, axis=1)[None], A, z_m=2.0)
    assert cloud.skipped_tuples.tolist() == [[0, 1, 5]] and len(cloud) == 19


def test_robust_mean_pipeline_removes_an_nlos_anchor(rng):
    log, _ = _static_log(rng, sigma_m=0.05)
    r = log.range_m.copy()
    r[:, 3] += 2.5                                            # anchor 4 always NLOS
    log = RangeLog(log.t_s, r, IDS)
    res = pruning.localize(log, ANCHORS, "robust_mean", stationary=True, z_m=2.0)
    plain = pruning.localize(log, ANCHORS, "none", pruning.PruningConfig(dim=2), stationary=True, z_m=2.0)
    cloud, rm = res.detail
    assert len(cloud) == 80 * 20 and res.n_used == 800
    # the 10 triplets without anchor 4 agree; the retained half consists of them
    clean = ~np.isin(cloud.tuples[cloud.tuple_index], 3).any(axis=1)
    assert clean[rm.kept].mean() > 0.95
    assert np.linalg.norm(res.p0_m - P_TRUE) < 0.1 < np.linalg.norm(plain.p0_m - P_TRUE)
    assert res.p0_m[2] == 2.0
    with pytest.raises(ValueError, match="z_m"):
        pruning.localize(log, ANCHORS, "robust_mean", stationary=True)


# ------------------------------------------------------------------ residual pruning


@pytest.mark.parametrize("static", [True, False])
def test_residual_pruning_drops_exactly_the_injected_outliers(rng, static):
    T = 120
    v = np.zeros(3) if static else np.array([0.6, 0.3, 0.0])
    t = np.arange(T) * 0.13
    pos = P_TRUE + np.outer(t, v)
    r = np.linalg.norm(pos[:, None] - ANCHORS, axis=-1) + 0.03 * rng.standard_normal((T, 6))
    out = np.zeros((T, 6), bool)
    out.flat[rng.choice(T * 6, 36, replace=False)] = True     # 5 % NLOS, +1.5..4 m
    r[out] += rng.uniform(1.5, 4.0, out.sum())
    log = RangeLog(t, r, IDS)
    s = RangeSamples.from_ranges(log)
    rp = pruning.residual_pruning(s, ANCHORS, retention=0.9, dropout=0.005, static=static, z_m=2.0)
    assert rp.kept.sum() == int(np.ceil(0.9 * T * 6)) and rp.n_rounds == 18
    injected = out[np.nonzero(np.isfinite(r))]                # unrolled order = row-major
    assert not rp.kept[injected].any()
    assert np.linalg.norm(rp.fit.p0_m - P_TRUE) < 0.05
    if not static:
        np.testing.assert_allclose(rp.fit.vel_mps[:2], v[:2], atol=0.01)
    plain = nls.fit_trajectory(s, ANCHORS, static=static, z_m=2.0)
    assert np.linalg.norm(plain.p0_m - P_TRUE) > 3 * np.linalg.norm(rp.fit.p0_m - P_TRUE)
    assert rp.rms_history_m[-1] < 0.2 * rp.rms_history_m[0]


def test_localize_every_heuristic_and_bad_name(rng):
    log, _ = _static_log(rng, p_nlos=0.1)
    cfg = pruning.PruningConfig(dim=2)
    for h in pruning.HEURISTICS:
        res = pruning.localize(log, ANCHORS, h, cfg, stationary=True, z_m=2.0)
        assert res.heuristic == h and res.label == pruning.LABELS[h]
        assert np.linalg.norm(res.p0_m[:2] - P_TRUE[:2]) < 1.0
        assert res.t0_s == 0.0 and res.t_end_s == log.t_s[-1]
    with pytest.raises(ValueError, match="heuristic"):
        pruning.localize(log, ANCHORS, "median", stationary=True)


def test_residual_pruning_from_the_plain_fit_given(rng):
    # the caller's plain NLS of the segment is residual pruning's first solve: the same result, that fit not solved again
    log, _ = _static_log(rng, p_nlos=0.1)
    s = RangeSamples.from_ranges(log)
    plain = nls.fit_trajectory(s, ANCHORS, dim=2, z_m=2.0)
    own = pruning.residual_pruning(s, ANCHORS, dim=2, z_m=2.0)
    given = pruning.residual_pruning(s, ANCHORS, dim=2, z_m=2.0, fit=plain)
    np.testing.assert_array_equal(given.kept, own.kept)
    np.testing.assert_array_equal(given.rms_history_m, own.rms_history_m)
    np.testing.assert_array_equal(given.fit.p0_m, own.fit.p0_m)
    cfg = pruning.PruningConfig(dim=2)
    assert pruning.localize(s, ANCHORS, "none", cfg, stationary=False, z_m=2.0, fit=plain).fit is plain
    res = pruning.localize(s, ANCHORS, "residual", cfg, stationary=False, z_m=2.0, fit=plain)
    np.testing.assert_array_equal(res.detail.kept, own.kept)
    marked = pruning.residual_pruning(s, ANCHORS, dim=2, z_m=2.0, fit=replace(plain, residual_rms_m=123.0))
    assert marked.rms_history_m[0] == 123.0                          # the fit given is the one used
