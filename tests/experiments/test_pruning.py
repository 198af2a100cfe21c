"""Experiments of notebook 02 (NLS trajectory estimation with pruning heuristics)."""

from __future__ import annotations

import dataclasses

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from tests.conftest import real_dataset  # noqa: E402
from uwbwb import Anchors, RangeLog, Recording, Trajectory, calibration, geometry, metrics  # noqa: E402
from uwbwb.experiments import pruning as ex  # noqa: E402
from uwbwb.filters.pruning import PruningConfig, localize  # noqa: E402
from uwbwb.sim import tours  # noqa: E402

QUIET = dict(sigma_m=0.0, bias_range_m=(0.0, 0.0), resolution_m=0.0, p_nlos_in=0.0, p_nlos_out=0.0,
             p_err_in=0.0, p_err_out=0.0)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _small(**tour_kw):
    base = dataclasses.replace(tours.TourConfig(), **tour_kw)
    return ex.SyntheticConfig(tours=(1,), paces=("fast",), tags=("H",), tour=base,
                              pruning=PruningConfig(dim=2, res_dropout=0.02, rm_dropout=0.05))


def test_noise_free_tour_is_recovered_by_every_heuristic():
    res = ex.run_synthetic(_small(**QUIET), rng=np.random.default_rng(0))
    n_kp = len(tours.TOURS[1])
    assert set(res.stops.heuristic) == {"none", "percentile", "robust_mean", "residual"}
    assert len(res.stops) == 4 * n_kp and len(res.moves) == 3 * (n_kp - 1)
    assert "percentile" not in set(res.moves.heuristic)
    assert res.stops.err_m.max() < 0.01 and res.stops.converged.all()
    # walks: ranges of a packet are taken up to 130 ms before its stamp -> centimetre-level model error
    assert res.moves.mean_err_m.max() < 0.1
    assert res.moves.vel_err_mps.max() < 0.02
    np.testing.assert_allclose(res.moves.speed_ratio, 1.0, atol=0.02)
    assert set(res.track[res.track.kind == "move"].heuristic) == {"none", "robust_mean", "residual", "point"}
    assert set(res.track[res.track.kind == "stop"].heuristic) == set(res.stops.heuristic) | {"point"}
    assert set(res.recordings) == {"tour1-fast"} and res.dim == 2
    # the point-based baseline fixes noise-free packets exactly (at the known height)
    pt = res.track[res.track.heuristic == "point"]
    assert pt.err_m.notna().all() and pt.err_m.max() < 0.2      # walks: the 130 ms ranging spread
    assert pt[pt.kind == "stop"].err_m.max() < 0.01


def test_pruning_beats_plain_nls_with_nlos_and_same_seed_same_numbers():
    cfg = _small()
    a = ex.run_synthetic(cfg, rng=np.random.default_rng(5))
    b = ex.run_synthetic(cfg, rng=np.random.default_rng(5))
    pd.testing.assert_frame_equal(a.stops, b.stops)
    table = ex.heuristic_summary(a.stops, a.moves, a.track)
    assert list(table.index) == ["none", "percentile", "robust_mean", "residual", "point"]
    for h in ("robust_mean", "residual"):       # same packets; the NLOS outliers live in the tail
        assert table.loc[h, "all_p90_m"] < table.loc["none", "all_p90_m"]
    assert np.isnan(table.loc["percentile", "vel_err_median_mps"])
    assert not table.loc["percentile", "all_includes_walks"] and table.loc["residual", "all_includes_walks"]
    assert table.loc["residual", "walk_p90_m"] > 0
    best = table.loc[["percentile", "robust_mean", "residual"], "stop_median_m"].min()
    assert best < table.loc["none", "stop_median_m"]
    # every estimator that covers walks is scored on the same packets
    walks = table[table.all_includes_walks]
    assert set(walks.index) == {"none", "robust_mean", "residual", "point"} and walks.n_epochs.nunique() == 1
    assert (table.coverage <= 1).all() and table.loc["none", "coverage"] == 1.0
    assert list(ex.rank_heuristics(table).sort_values().index) == list(
        table.loc[["percentile", "robust_mean", "residual"], "stop_median_m"].sort_values().index)


def test_3d_comparison_on_the_same_packets_reports_height_errors():
    cfg = _small()
    two = ex.run_synthetic(cfg, rng=np.random.default_rng(5))
    with pytest.raises(ValueError, match="robust mean"):
        dataclasses.replace(cfg, pruning=PruningConfig(dim=3))
    cfg3 = dataclasses.replace(cfg, heuristics=("none", "percentile", "residual"),
                               pruning=dataclasses.replace(cfg.pruning, dim=3))
    three = ex.run_recordings(two.recordings, cfg3)
    assert three.dim == 3 and set(three.stops.heuristic) == {"none", "percentile", "residual"}
    # same packets: identical epoch sets per estimator
    key = ["experiment", "tag", "segment", "t_s"]
    a = two.track[two.track.heuristic == "none"][key].reset_index(drop=True)
    b = three.track[three.track.heuristic == "none"][key].reset_index(drop=True)
    pd.testing.assert_frame_equal(a, b)
    assert (two.stops.err_z_m == 0).all() and (three.stops.err_z_m != 0).all()
    np.testing.assert_allclose(three.stops.err_3d_m, np.hypot(three.stops.err_m, three.stops.err_z_m))
    t = ex.heuristic_summary(three.stops, three.moves, three.track)
    assert t.loc["percentile", "stop_err_z_median_m"] > 0.3     # short percentile ranges lift the node


def test_epoch_summary_lists_the_estimators_in_table_order():
    ep = pd.DataFrame({"heuristic": ["point"] * 2 + ["extra"] * 2 + ["none"] * 2, "err_m": [1.0, np.nan] * 3})
    assert list(ex.epoch_summary(ep).index) == ["none", "point", "extra"]


def test_segments_with_too_few_ranges_count_as_not_covered():
    cfg = dataclasses.replace(_small(**QUIET), heuristics=("none",))
    rec, truth = tours.simulate_tour(dataclasses.replace(cfg.tour, tour=1, pace="fast"), rng=np.random.default_rng(2))
    ranges = dict(rec.ranges)
    log = ranges["H"]
    stop = truth.segments[0]
    R = log.range_m.copy()
    inside = (log.t_s >= stop.t_start_s) & (log.t_s <= stop.t_end_s)
    R[np.flatnonzero(inside)[1:]] = np.nan                       # one packet (6 ranges) left in the first stop
    ranges["H"] = RangeLog(log.t_s, R, log.anchor_ids, log.tag_id)
    rec = dataclasses.replace(rec, ranges=ranges)
    s, m, tr = ex.run_tour(rec, truth, cfg)
    track = pd.concat(tr)
    first = track[(track.segment == 0) & (track.heuristic == "none")]
    assert len(first) > 2 and first.err_m.isna().all()
    assert 0 not in {r["segment"] for r in s}
    cov = ex.epoch_summary(track).coverage
    assert cov["none"] < 1.0 and cov["point"] < 1.0


def test_outlier_free_control_and_sensitivity_shapes():
    cfg = _small()
    ctl = ex.outlier_free_control(cfg, seed=1)
    assert "point" not in ctl.index and {"none", "residual"} <= set(ctl.index)
    sens = ex.sensitivity(dataclasses.replace(cfg, heuristics=("none", "residual")), dwell_s=(0.0, 30.0), seed=1)
    assert list(sens.index) == [0.0, 30.0] and list(sens.columns) == ["none", "residual"]


def test_nlos_excess_sensitivity_scales_only_the_excess():
    cfg = _small()
    ex_t = ex.nlos_excess_sensitivity(cfg, (0.5, 1.0, 2.0), seed=1)
    base = cfg.tour.nlos_mean_m
    assert list(ex_t.index) == [0.5 * base, base, 2 * base] and list(ex_t.factor) == [0.5, 1.0, 2.0]
    r = ex.run_synthetic(cfg, rng=np.random.default_rng(1))        # the same seed: the factor-1 row is its number
    own = ex.heuristic_summary(r.stops, r.moves, r.track).loc["residual", "all_p90_m"]
    assert ex_t.loc[base, "all_p90_m"] == own
    assert ex_t.all_p90_m.is_monotonic_increasing                   # the same draws, a larger excess
    with pytest.raises(ValueError, match="positive"):
        ex.nlos_excess_sensitivity(cfg, (0.0,), seed=1)


def test_summary_and_ranks_on_a_constructed_table():
    stops = pd.DataFrame({"heuristic": ["none"] * 3 + ["residual"] * 3 + ["percentile"] * 3,
                          "err_m": [1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 0.5, 0.6, 0.9]})
    t = ex.heuristic_summary(stops)
    assert list(t.index) == ["none", "percentile", "residual"]
    assert t.loc["none", "stop_median_m"] == 2.0 and t.loc["residual", "stop_p90_m"] == pytest.approx(0.28)
    assert ex.rank_heuristics(t).to_dict() == {"residual": 1.0, "percentile": 2.0}      # plain NLS not ranked
    wins = ex.wins_table({"a": t.stop_median_m})
    assert wins.loc["a", "best of all"] == wins.loc["a", "best heuristic"] == ex.LABELS["residual"]


def _static_recordings(rng, n_sites=3, T=300):
    anchors = Anchors(tuple(f"a{i}" for i in range(6)),
                      np.array([[0, 0, 1.0], [6, 0, 1.05], [6, 5, 1.0], [0, 5, 1.02], [3, -1, 1.0], [3, 6, 1.05]]))
    bias = rng.uniform(0.1, 0.4, 6)
    recs = []
    for site in range(1, n_sites + 1):
        for yaw in (0, 90):
            p = np.array([1.0 + site, 1.0 + 0.7 * site + 0.01 * yaw, 0.97])
            r = np.linalg.norm(p - anchors.pos_m, axis=1) + bias + 0.02 * rng.standard_normal((T, 6))
            t = np.arange(T) * 0.01
            recs.append(Recording("synthetic", f"s/pos{site}_deg_{yaw}", anchors,
                                  {"t0": RangeLog(t, r, anchors.ids, "t0")},
                                  {"t0": Trajectory(t, np.tile(p, (T, 1)))}, meta={"site": site, "yaw_deg": yaw}))
    return recs


H = {"t0": 0.97}


def test_static_poses_raw_vs_leave_one_site_out_calibration(rng):
    recs = _static_recordings(rng)
    raw = ex.run_static_poses(recs, heights_m=H, stride=3)
    assert len(raw.poses) == 6 * 4 and set(raw.poses.columns) >= {"err_m", "bearing_deg", "site", "calibrated"}
    # every estimator scored on every thinned epoch of every pose
    n_ep = sum(len(r.ranges["t0"].select(slice(None, None, 3))) for r in recs)
    assert (raw.epochs.groupby("heuristic").size() == n_ep).all() and len(raw.epochs) == 5 * n_ep
    cals = ex.loso_calibrations(recs, stride=2, fit_scale=False)
    for site, cal in cals.items():
        assert not any(f"pos{site}_" in s for s in cal.source)          # never the evaluated site
        assert len(cal.source) == 4
    calib = ex.run_static_poses(recs, heights_m=H, stride=3, calibrations=cals)
    assert calib.poses.calibrated.all()
    assert calib.poses.err_m.median() < 0.5 * raw.poses.err_m.median()
    es = ex.epoch_summary(calib.epochs)
    assert es.loc["point", "coverage"] == 1.0 and es.loc["point", "median_m"] > es.loc["none", "median_m"]
    with pytest.raises(ValueError, match="calibration for site"):
        ex.run_static_poses(recs, heights_m=H, calibrations={1: cals[1]})
    with pytest.raises(ValueError, match="two sites"):
        ex.loso_calibrations([r for r in recs if r.meta["site"] == 1])
    with pytest.raises(ValueError, match="not from the evaluated recording"):
        ex.run_static_poses(recs, heights_m=None)


def test_range_error_stats_find_the_bias_and_the_long_outliers(rng):
    recs = _static_recordings(rng)
    st = ex.range_error_stats(recs, stride=1)
    assert len(st) == 6 and (st.bias_m > 0.05).all() and (st.frac_long == 0).all()
    long = []
    for r in recs:
        log = r.ranges["t0"]
        R = log.range_m.copy()
        R[::10, 0] += 2.0                                              # 10 % NLOS-like excess on anchor a0
        long.append(dataclasses.replace(r, ranges={"t0": RangeLog(log.t_s, R, log.anchor_ids, "t0")}))
    st = ex.range_error_stats(long, stride=1).set_index("anchor")
    assert st.loc["a0", "frac_long"] == pytest.approx(0.1, abs=0.01) and st.loc["a1", "frac_long"] == 0


def test_dynamic_segments_on_a_noise_free_tour():
    rec, truth = tours.simulate_tour(dataclasses.replace(tours.TourConfig(tour=1, pace="slow"), **QUIET),
                                     rng=np.random.default_rng(3))
    segs = geometry.straight_segments(rec.truth["L"], tol_m=0.05)
    assert len(segs) == len(tours.TOURS[1]) - 1                      # the four walks
    out = ex.run_dynamic_segments(rec, segs, heights_m={"L": 1.3}, tags=["L"], heuristics=("none", "residual"),
                                  config=PruningConfig(dim=2, res_dropout=0.02))
    assert len(out.pieces) == 2 * len(segs)
    assert out.pieces.mean_err_m.max() < 0.1 and out.pieces.vel_err_mps.max() < 0.02
    es = ex.epoch_summary(out.epochs)
    assert set(es.index) == {"none", "residual", "point"} and es.n_epochs.nunique() == 1
    # fits cover the walks only, point fixes every epoch (the stops too)
    assert out.run_coverage["none"] < 0.9 * out.run_coverage["point"] and out.run_coverage["point"] > 0.95
    with pytest.raises(ValueError, match="stationary"):
        ex.run_dynamic_segments(rec, segs, heights_m={"L": 1.3}, heuristics=("percentile",))


def test_figures_draw():
    cfg = _small()
    res = ex.run_synthetic(cfg, rng=np.random.default_rng(1))
    rec, truth = res.recordings["tour1-fast"]
    fig = ex.plot_polar_errors(res.stops, ncols=5)
    assert len(fig.axes) == len(tours.TOURS[1])
    ax = ex.plot_segment_fits(res.moves, res.stops, truth_xy=rec.truth["H"].pos_m, anchors=rec.anchors)
    assert len([c for c in ax.texts if c.arrow_patch is not None]) == len(tours.TOURS[1]) - 1
    ex.plot_coverage(tour=2)
    model = truth.model
    e = rng_err = np.random.default_rng(0).normal(0, 0.5, 500)
    ex.plot_error_histogram(e, model, 0.3)
    ax = ex.plot_error_cdf_percentile(rng_err, model=model, p_nlos=0.3)
    assert "P5" in ax.get_legend().get_texts()[0].get_text()
    log = rec.ranges["H"].between(0.13, 10.0)
    r = localize(log, rec.anchors, "robust_mean", stationary=True, z_m=2.0)
    ex.plot_robust_mean_cloud(r, truth_xy=tours.TOURS[1][0])
    assert len(ex.error_cdf_by_heuristic(res.stops)) == 4
    assert list(ex.error_cdf_by_heuristic(res.track)) == [ex.LABELS[h] for h in ex.ESTIMATORS]
    assert ex.heuristic_color("point") != ex.heuristic_color("none")


def test_hanyang_figure_draws_whatever_conditions_there_are():
    samples = pd.DataFrame({"condition": ["LOS"] * 40, "range_error_m": np.linspace(0.1, 0.4, 40),
                            "height_m": 1.0, "true_range_m": 10.0, "range_m": 10.0 + np.linspace(0.1, 0.4, 40),
                            "file": "a"})
    axes = ex.plot_hanyang(samples, calibration.percentile_by_file(samples))
    assert len(axes) == 3 and len(axes[2].lines) == 3          # zero line + LOS median + LOS percentile
    axes = ex.plot_hanyang(samples.iloc[:5], calibration.percentile_by_file(samples.iloc[:5]))
    assert len(axes[2].lines) == 1                              # no file long enough: only the zero line


def test_tour_explorer_serves_the_run_and_caches_other_settings():
    cfg = _small()
    res = ex.run_synthetic(cfg, rng=np.random.default_rng(1))
    xp = ex.TourExplorer(res, cfg, seed=0)
    p = cfg.pruning
    args = (1, "fast", "H", "residual", p.res_retention, 100 * p.res_dropout, p.rm_retention, 100 * p.rm_dropout)
    st, mv = xp.rows(*args)
    assert xp.n_solved == 0 and len(st) == len(tours.TOURS[1])
    pd.testing.assert_frame_equal(st, res.stops[res.stops.heuristic == "residual"])
    other = (*args[:4], 0.8, *args[5:])
    fig, out = xp.render(*other[3:], *other[:3])
    assert xp.n_solved == 1 and np.isfinite(out["median stop error (m)"])
    xp.render(*other[3:], *other[:3])
    assert xp.n_solved == 1 and xp.rows.cache_info().hits >= 1       # cached
    xp.rows(3, "slow", "L", "none", *args[4:])                        # a tour the run did not simulate
    assert xp.n_solved == 2 and xp.experiment.cache_info().currsize == 2


def test_piece_explorer_uses_the_given_height_not_the_truth():
    rec, truth = tours.simulate_tour(dataclasses.replace(tours.TourConfig(tour=1, pace="slow"), **QUIET),
                                     rng=np.random.default_rng(3))
    segs = geometry.straight_segments(rec.truth["L"], tol_m=0.05)
    xp = ex.PieceExplorer(rec, segs, heights_m={"L": 1.3}, config=PruningConfig(dim=2, res_dropout=0.02), stride=2)
    fig, out = xp.render(0, "L", "none", 0.9, 0.5, 2.0, "raw")
    assert out["mean error (m)"] < 0.1 and xp.range_options == ["raw"]
    wrong = ex.PieceExplorer(rec, segs, heights_m={"L": 0.3}, config=PruningConfig(dim=2), stride=2)
    assert wrong.render(0, "L", "none", 0.9, 0.5, 2.0, "raw")[1]["mean error (m)"] > out["mean error (m)"]
    with pytest.raises(ValueError, match="calibration"):
        xp.piece(0, "L", "none", 0.9, 0.5, 2.0, "calibrated")


@pytest.mark.realdata
def test_lias_static_pose_and_dynamic_segment():
    root = real_dataset("lias-planar-uwb")
    from uwbwb.datasets import lias

    recs = lias.load_static("8.14", data_dir=root.parent, site=5, yaw_deg=0)
    heights = calibration.tag_mount_height(recs).per_tag_m
    out = ex.run_static_poses(recs, heights_m=heights, tags=["t0"], stride=100).poses
    assert len(out) == 4 and out.err_m.max() < 0.6
    dyn = lias.load_dynamic("fast", data_dir=root.parent)
    segs = geometry.straight_segments(dyn.truth["t0"])
    assert len(segs) >= 10 and segs.duration_s.sum() > 0.5 * (dyn.truth["t0"].t_s[-1] - dyn.truth["t0"].t_s[0])
    res = ex.run_dynamic_segments(dyn, segs.head(3), heights_m=heights, tags=["t0"], heuristics=("none",),
                                  stride=10).pieces
    assert len(res) == 3 and res.mean_err_m.max() < 0.6 and res.vel_err_mps.max() < 0.3


@pytest.mark.realdata
def test_hanyang_percentile_lands_near_the_truth_in_los():
    root = real_dataset("hanyang-outdoor-uwb")
    from uwbwb.datasets import hanyang

    df = hanyang.load_static(data_dir=root.parent, height_m=1.0)
    out = calibration.percentile_by_file(df)
    los, nlos = out[out.condition == "LOS"], out[out.condition == "NLOS"]
    assert len(los) > 10 and len(nlos) > 10
    assert abs(los.pq_err_m.median()) < 0.3
    assert nlos.median_err_m.median() > los.median_err_m.median()


# --------------------------------------------------------------------------- section 10: facts, then words

HS = ["none", "percentile", "robust_mean", "residual"]


def _summary(stop_median, all_p90=(1.9, 0.6, 1.5, 1.7), speed=(0.997, np.nan, 1.02, 1.0), point=None):
    t = pd.DataFrame({"stop_median_m": stop_median, "all_p90_m": all_p90, "speed_ratio_median": speed,
                      "all_median_m": np.asarray(all_p90) / 2, "coverage": 1.0,
                      "all_includes_walks": [True, False, True, True]},
                     index=pd.Index(HS, name="heuristic"))
    if point is not None:
        t.loc["point"] = {"stop_median_m": np.nan, "all_p90_m": point, "speed_ratio_median": np.nan,
                          "all_median_m": point / 2, "coverage": 0.97, "all_includes_walks": True}
    return t


def _three_d():
    return pd.DataFrame({"stop_median_m": [1.2, 0.3, 0.6], "stop_err_z_median_m": [1.6, 1.1, 0.6],
                         "stop_err_z_bias_m": [1.6, 1.1, -0.6],
                         "stop_err_3d_median_m": [2.3, 1.2, 1.4]},
                        index=pd.Index(["none", "percentile", "residual"], name="heuristic"))


def _hanyang(los_offset, nlos_offset, slope=0.004):
    rng = np.arange(2.0, 62.0, 4.0)
    rows = [{"condition": c, "true_range_m": r, "median_err_m": off + slope * r, "pq_err_m": off + slope * r - 0.03}
            for c, off in (("LOS", los_offset), ("NLOS", nlos_offset)) for r in rng]
    return pd.DataFrame(rows)


def _lias():
    static = pd.concat({"raw": _summary([0.169, 0.131, 0.235, 0.243]),
                        "calibrated (LOSO)": _summary([0.050, 0.041, 0.069, 0.038])})
    dynamic = pd.DataFrame({"mean_err_m": [0.157, 0.247, 0.254, 0.075, 0.078, 0.076],
                            "speed_ratio": [1.081, 1.106, 1.075, 1.001, 1.007, 1.007]},
                           index=pd.MultiIndex.from_product([["raw", "calibrated"],
                                                             ["none", "residual", "robust_mean"]]))
    ranges = pd.DataFrame({"bias_m": np.linspace(0.05, 0.45, 24), "spread_m": 0.05, "n": 100,
                           "frac_long": [0.0] * 23 + [0.24]})
    epochs = {"raw": pd.DataFrame({"median_m": [0.17, 0.21], "coverage": [1.0, 0.99]}, index=["none", "point"])}
    dyn_epochs = {"raw": (pd.DataFrame({"median_m": [0.16, 0.19], "coverage": [1.0, 1.0]}, index=["none", "point"]),
                          pd.Series({"none": 0.4, "point": 0.98}))}
    return dict(lias_static=static, lias_dynamic=dynamic, lias_ranges=ranges, lias_static_epochs=epochs,
                lias_dynamic_epochs=dyn_epochs)


PERSIST = pd.DataFrame([[0.72, 0.52, 0.44, 0.50], [1.26, 0.48, 0.50, 0.76], [0.67, 0.72, 0.58, 0.73]],
                       index=[0.0, 3.0, 30.0], columns=HS)


def test_comparison_facts_follow_the_tables():
    syn = _summary([1.157, 0.321, 0.515, 0.604], point=2.9)
    f = ex.comparison_facts(syn, synthetic_other=_three_d(), persistence=PERSIST, hanyang=_hanyang(0.12, 0.16),
                            **_lias())
    assert f["ranking"] == ("percentile", "robust_mean", "residual") and not f["paper_ranking"]
    assert f["point_best_nls"] == "robust_mean" and f["nls_beats_point_p90"]
    assert f["point"]["point"]["coverage"] == 0.97
    g = f["geometry"]
    assert g["percentile_dz_m"] == 1.1 and g["percentile_h_3d_m"] == 0.3 and g["percentile_h_known_m"] == 0.321
    assert g["ranking_3d"] == ("percentile", "residual") and g["ranking_3d_by_3d_error"] == ("percentile", "residual")
    assert g["ranking_known"] == ("percentile", "robust_mean", "residual") and g["percentile_dz_bias_m"] == 1.1
    assert f["lias_point_verdict"] == {"raw": "better than"}
    assert f["lias_dynamic_point"]["raw"]["verdict"] == "better than"
    p = f["persistence"]
    assert (p["base_s"], p["long_s"]) == (3.0, 30.0) and p["worse"] == ["percentile", "robust_mean"]
    assert (p["best_base"], p["best_long"]) == ("percentile", "robust_mean")
    assert p["lead_long_m"] == pytest.approx(0.14)
    r = f["lias_ranges"]
    assert r["frac_positive"] == 1.0 and r["frac_long"] == pytest.approx(0.01)
    assert r["bias_p10_m"] == pytest.approx(0.09, abs=0.01) and r["bias_p90_m"] == pytest.approx(0.41, abs=0.01)
    s = f["lias_static"]
    assert s["helps"] == ["percentile"] and s["hurts"] == ["robust_mean", "residual"]
    assert s["cal_gain_m"] > s["prune_gain_m"] and s["cal_spread_m"] == pytest.approx(0.031)
    assert f["lias_dynamic"]["raw"]["verdict"] == "plain NLS beats every heuristic"
    assert f["lias_dynamic"]["calibrated"]["verdict"] == "plain NLS is as good as any heuristic"
    assert f["lias_dynamic_point"]["raw"]["run_coverage"] == {"none": 0.4, "point": 0.98}
    assert dict(f["speed_ratios"])["the raw LIAS pieces"] == 1.081
    h = f["hanyang"]
    assert h["gap_m"] == pytest.approx(0.04) and h["span_m"] == 56.0
    assert min(h["growth_m"].values()) == pytest.approx(0.224)


def _row(table, start):
    rows = table[table["claim"].str.startswith(start)]
    assert len(rows) == 1, (start, list(table["claim"]))
    return rows.iloc[0]


def test_verdict_table_states_the_facts():
    syn = _summary([1.157, 0.321, 0.515, 0.604], point=2.9)
    t = ex.verdict_table(ex.comparison_facts(syn, synthetic_other=_three_d(), persistence=PERSIST,
                                             hanyang=_hanyang(0.12, 0.16), **_lias()))
    assert list(t.columns) == ["claim", "paper", "paper kind", "ours", "ours kind", "assumption", "rule", "verdict"]
    assert set(t["ours kind"]) == {"reproduced"}
    assert (t["paper kind"] == np.where(t["paper"] == "—", "—", "input")).all()
    four = t.set_index("claim").loc["residual pruning: 90 % of all distance errors under 4 m"]
    assert four["paper kind"] == "input" and "not the paper's" in four.assumption
    assert _row(t, "LIAS static, raw ranges").assumption == "—"     # real ranges: no simulator assumption
    rank = _row(t, "ranking of the heuristics")
    assert rank.verdict == "differs" and rank.ours.index("the 5th percentile (0.32 m)") < rank.ours.index("the robust mean")
    assert _row(t, "best trajectory NLS vs the point-based fixes").verdict == "NLS better"
    assert "2.90" in _row(t, "best trajectory NLS vs the point-based fixes").ours
    assert _row(t, "ranking in 3-D").verdict == "same" and _row(t, "5th percentile in 3-D").verdict == "too high"
    assert _row(t, "best heuristic as NLOS episodes lengthen").verdict == "changes"
    assert _row(t, "LIAS static, raw ranges").verdict == "NLS better"
    assert _row(t, "LIAS dynamic, raw ranges: best trajectory").verdict == "NLS better"
    assert _row(t, "LIAS static: range calibration").verdict == "calibration larger"
    assert _row(t, "LIAS dynamic, raw ranges: plain NLS").verdict == "plain NLS beats every heuristic"
    assert _row(t, "Hanyang static").verdict == "NLOS larger"


def _excess(p90):
    return pd.DataFrame({"factor": [0.5, 1.0, 2.0], "all_p90_m": p90},
                        index=pd.Index([1.25, 2.5, 5.0], name="nlos_mean_m"))


@pytest.mark.parametrize("p90, verdict", [((1.0, 1.7, 3.9), "agrees at each"), ((4.1, 4.5, 6.0), "differs at each"),
                                          ((1.0, 1.7, 4.0), "depends on the assumed excess")])
def test_the_4_m_row_names_the_simulated_excess_and_follows_it(p90, verdict):
    syn = _summary([1.157, 0.321, 0.515, 0.604], point=2.9)
    cfg = tours.TourConfig(nlos_mean_m=2.5, p_nlos_out=0.3, nlos_dwell_s=3.0)
    t = ex.verdict_table(ex.comparison_facts(syn, tour=cfg, excess=_excess(list(p90))))
    row = _row(t, "residual pruning: 90 % of all distance errors under 4 m, as the simulated NLOS excess")
    assert row.verdict == verdict and row.ours.startswith(" / ".join(f"{p:.2f}" for p in p90))
    four = t.set_index("claim").loc["residual pruning: 90 % of all distance errors under 4 m"]
    assert "NLOS excess N(2.5 m, 1 m)" in four.assumption and "30 % of links outside" in four.assumption
    assert "TourConfig" in four.assumption and "next row" in four.assumption
    plain = ex.verdict_table(ex.comparison_facts(syn))               # no configuration, no sensitivity: named only
    assert not plain["claim"].str.contains("as the simulated NLOS excess").any()
    assert "N(" not in _row(plain, "residual pruning: 90 %").assumption


def test_verdicts_when_the_paper_ranking_comes_out():
    persistence = pd.DataFrame([[1.0, 0.6, 0.65, 0.5], [1.2, 0.9, 0.8, 0.6]], index=[3.0, 30.0], columns=HS)
    syn = _summary([1.0, 0.8, 0.6, 0.4], speed=(1.10, np.nan, 1.1, 1.1), point=1.2)
    f = ex.comparison_facts(syn, persistence=persistence, hanyang=_hanyang(0.0, 1.0, slope=0.0))
    assert f["paper_ranking"] and f["persistence"]["worse"] == HS and f["persistence"]["best_long"] == "residual"
    assert not f["nls_beats_point_p90"] and "geometry" not in f and "lias_static" not in f
    t = ex.verdict_table(f)
    assert _row(t, "ranking of the heuristics").verdict == "as in the paper"
    assert _row(t, "best trajectory NLS vs the point-based fixes").verdict == "NLS not better"
    assert not t["claim"].str.contains("LIAS").any()


def test_verdicts_with_one_hanyang_condition_only_and_low_point_coverage():
    low = _summary([1.0, 0.8, 0.6, 0.4], point=2.0)
    low.loc["point", "coverage"] = 0.7
    assert "70 %" in _row(ex.verdict_table(ex.comparison_facts(low)), "best trajectory NLS vs the point").ours
    f = ex.comparison_facts(_summary([1.0, 0.8, 0.6, 0.4]), hanyang=_hanyang(0.0, 1.0).query("condition == 'LOS'"))
    assert f["hanyang"]["conditions"] == ["LOS"] and "gap_m" not in f["hanyang"]
    assert not ex.verdict_table(f)["claim"].str.startswith("Hanyang").any()


def test_headline_rows_say_their_kind_and_never_a_paper_bound(rng):
    syn = _summary([1.157, 0.321, 0.515, 0.604], point=2.9)
    rows = ex.headline_rows(synthetic=syn, synthetic_dim=2, synthetic_3d=_three_d().assign(all_p90_m=1.0))
    assert rows and {r["kind"] for r in rows} == {"reproduced"}
    assert all(np.isfinite(r["value"]) for r in rows)
    ranks = {r["quantity"]: r for r in rows if r["quantity"].startswith("rank")}
    assert len(ranks) == 3 and {r["paper_value"] for r in ranks.values()} == {1, 2, 3}
    q = {r["quantity"]: r["value"] for r in rows}
    rank = "rank by median stationary error among the three heuristics (1 = best)"
    assert q[f"{rank}, 5th percentile (known height)"] == 1
    assert "packet coverage, point-based (per packet) (known height)" in q
    assert q["90 % of all distance errors, residual pruning minus point-based (known height)"] == pytest.approx(-1.2)
    assert "median stationary height error |dz|, 5th percentile (3-D, no height)" in q
    s = metrics.Summary("02_pruning_nls", fast=True)
    for r in rows:
        s.add(**r)
    assert len(s.frame()) == len(rows)


def test_hanyang_table_per_condition():
    df = pd.DataFrame({"condition": ["LOS"] * 100 + ["NLOS"] * 100 + ["LOS"] * 5,
                       "height_m": 1.0, "true_range_m": [10.0] * 200 + [20.0] * 5,
                       "range_m": np.r_[10.0 + np.linspace(0, 0.99, 100), 12.0 + np.linspace(0, 0.99, 100),
                                        np.full(5, 20.0)],
                       "file": ["a"] * 100 + ["b"] * 100 + ["c"] * 5})
    out = calibration.percentile_by_file(df, q=5)
    assert ex.hanyang_table(calibration.percentile_by_file(df[df.file == "c"])).empty
    t = ex.hanyang_table(out)
    assert list(t.index) == ["LOS", "NLOS"] and list(t.n_files) == [1, 1]


@pytest.mark.parametrize("gaps_m, verdict", [((0.3, 0.3), "as in the paper"), ((-0.3, 0.3), "differs"),
                                             ((0.0, 0.3), "not resolved")])
def test_the_ranking_row_decides_each_step_by_its_interval(gaps_m, verdict):
    """With the per-stop errors, each step of the paper's order (residual < robust mean < percentile) needs its
    median-difference interval below 0: a reversed step says "differs", a step inside the noise "not resolved"."""
    rng = np.random.default_rng(5)
    rows = []
    for e in range(12):                                 # 12 series: each resampled whole, at least MIN_BLOCKS
        base = np.abs(rng.normal(0.5, 0.2, 6))
        tie = base[::-1]        # gap 0: the same errors at other stops, so the medians tie and the pairs differ
        errs = {"none": base + 1.0, "residual": base, "robust_mean": base + gaps_m[0] if gaps_m[0] else tie,
                "percentile": base + gaps_m[0] + gaps_m[1]}
        for h, err in errs.items():
            for k, v in enumerate(err):
                rows.append({"experiment": f"e{e}", "tag": "H", "segment": k, "heuristic": h, "err_m": v})
    stops = pd.DataFrame(rows)
    syn = ex.heuristic_summary(stops)
    t = ex.verdict_table(ex.comparison_facts(syn, stops=stops))
    row = _row(t, "ranking of the heuristics")
    assert row.verdict == verdict, row.ours
    assert "block-bootstrap rule, each experiment's series of stops one block" in row.rule


@pytest.mark.parametrize("offset_m, verdict", [(-0.2, "NLS better"), (0.2, "NLS worse"), (0.0, "not significant")])
def test_the_lias_dynamic_point_row_decides_by_the_median_difference_on_common_epochs(offset_m, verdict):
    """Given the dynamic run's epoch table, plain NLS (fixed in advance) vs point fixes is decided by the interval
    of the median difference on the epochs both covered (not by a 5 mm tolerance); epochs the fit missed are left
    out; a heuristic with a lower median is not picked instead."""
    rng = np.random.default_rng(8)
    rows = []
    for seg in range(6):
        t = np.arange(60) * 0.1
        point = np.abs(rng.normal(0.5, 0.2, t.size))
        fit = point[::-1] + offset_m if offset_m == 0.0 else point + offset_m + rng.normal(0, 0.02, t.size)
        fit = fit.copy()
        fit[:5] = np.nan                               # not covered: out of the pairing
        for h, e in (("point", point), ("none", fit), ("residual", fit - 1.0)):
            rows.append(pd.DataFrame({"segment": seg, "tag": "t0", "t_s": t, "heuristic": h, "err_m": e}))
    epochs = pd.concat(rows, ignore_index=True)
    summary = ex.epoch_summary(epochs)
    f = ex.comparison_facts(_summary([1.0, 0.8, 0.6, 0.4]), lias_dynamic_epochs={"raw": (summary, {"none": 0.9})},
                            lias_dynamic_errors={"raw": epochs})
    assert f["lias_dynamic_point"]["raw"]["paired"]["n"] == 6 * 55
    assert f["lias_dynamic_point"]["raw"]["paired"]["a"] == "none"
    row = _row(ex.verdict_table(f), "LIAS dynamic, raw ranges: plain NLS (fixed in advance) vs point fixes")
    assert row.verdict == verdict, row.ours
