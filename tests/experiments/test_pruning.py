"""Experiments of notebook 02 (NLS trajectory estimation with pruning heuristics)."""

from __future__ import annotations

import dataclasses
import re
import types

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
    return ex.study.SyntheticConfig(tours=(1,), paces=("fast",), tags=("H",), tour=base,
                              pruning=PruningConfig(dim=2, res_dropout=0.02, rm_dropout=0.05))


def test_noise_free_tour_is_recovered_by_every_heuristic():
    res = ex.study.run_synthetic(_small(**QUIET), rng=np.random.default_rng(0))
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
    a = ex.study.run_synthetic(cfg, rng=np.random.default_rng(5))
    b = ex.study.run_synthetic(cfg, rng=np.random.default_rng(5))
    pd.testing.assert_frame_equal(a.stops, b.stops)
    table = ex.scoring.heuristic_summary(a.stops, a.moves, a.track)
    assert list(table.index) == ["none", "percentile", "robust_mean", "residual", "point"]
    for h in ("robust_mean", "residual"):       # same packets; the NLOS outliers live in the tail
        assert table.loc[h, "all_p90_m"] < table.loc["none", "all_p90_m"]
    assert np.isnan(table.loc["percentile", "vel_err_median_mps"])
    assert not table.loc["percentile", "all_includes_walks"] and table.loc["residual", "all_includes_walks"]
    best = table.loc[["percentile", "robust_mean", "residual"], "stop_median_m"].min()
    assert best < table.loc["none", "stop_median_m"]
    # every estimator that covers walks is scored on the same packets
    walks = table[table.all_includes_walks]
    assert set(walks.index) == {"none", "robust_mean", "residual", "point"} and walks.n_epochs.nunique() == 1
    assert (table.coverage <= 1).all() and table.loc["none", "coverage"] == 1.0


def test_3d_comparison_on_the_same_packets_reports_height_errors():
    cfg = _small()
    two = ex.study.run_synthetic(cfg, rng=np.random.default_rng(5))
    with pytest.raises(ValueError, match="robust mean"):
        dataclasses.replace(cfg, pruning=PruningConfig(dim=3))
    cfg3 = dataclasses.replace(cfg, heuristics=("none", "percentile", "residual"),
                               pruning=dataclasses.replace(cfg.pruning, dim=3))
    three = ex.study.run_recordings(two.recordings, cfg3)
    assert three.dim == 3 and set(three.stops.heuristic) == {"none", "percentile", "residual"}
    # same packets: identical epoch sets per estimator
    key = ["experiment", "tag", "segment", "t_s"]
    a = two.track[two.track.heuristic == "none"][key].reset_index(drop=True)
    b = three.track[three.track.heuristic == "none"][key].reset_index(drop=True)
    pd.testing.assert_frame_equal(a, b)
    assert (two.stops.err_z_m == 0).all() and (three.stops.err_z_m != 0).all()
    np.testing.assert_allclose(three.stops.err_3d_m, np.hypot(three.stops.err_m, three.stops.err_z_m))
    t = ex.scoring.heuristic_summary(three.stops, three.moves, three.track)
    assert t.loc["percentile", "stop_err_z_median_m"] > 0.3     # short percentile ranges lift the node


def test_epoch_summary_lists_the_estimators_in_table_order():
    ep = pd.DataFrame({"heuristic": ["point"] * 2 + ["extra"] * 2 + ["none"] * 2, "err_m": [1.0, np.nan] * 3})
    assert list(metrics.epoch_summary(ep, by="heuristic", order=ex.scoring.ESTIMATORS).index) == [
        "none", "point", "extra"]


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
    s, m, tr = ex.study.run_tour(rec, truth, cfg)
    track = pd.concat(tr)
    first = track[(track.segment == 0) & (track.heuristic == "none")]
    assert len(first) > 2 and first.err_m.isna().all()
    assert 0 not in {r["segment"] for r in s}
    cov = metrics.epoch_summary(track, by="heuristic").coverage
    assert cov["none"] < 1.0 and cov["point"] < 1.0


def test_a_stops_only_run_gives_the_stops_of_the_full_run():
    cfg = _small()
    rec, truth = tours.simulate_tour(dataclasses.replace(cfg.tour, tour=1, pace="fast"), rng=np.random.default_rng(3))
    s, m, tr = ex.study.run_tour(rec, truth, cfg)
    s1, m1, tr1 = ex.study.run_tour(rec, truth, dataclasses.replace(cfg, kinds=("stop",)))
    assert m and not m1 and set(pd.concat(tr1).kind) == {"stop"}
    pd.testing.assert_frame_equal(pd.DataFrame(s1), pd.DataFrame(s))
    with pytest.raises(ValueError, match="kinds"):
        dataclasses.replace(cfg, kinds=("walk",))


def test_summary_on_a_constructed_table():
    stops = pd.DataFrame({"heuristic": ["none"] * 3 + ["residual"] * 3 + ["percentile"] * 3,
                          "err_m": [1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 0.5, 0.6, 0.9]})
    t = ex.scoring.heuristic_summary(stops)
    assert list(t.index) == ["none", "percentile", "residual"]
    assert t.loc["none", "stop_median_m"] == 2.0 and t.loc["residual", "stop_p90_m"] == pytest.approx(0.28)


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
    raw = ex.real.run_static_poses(recs, heights_m=H, stride=3)
    assert len(raw.poses) == 6 * 4 and set(raw.poses.columns) >= {"err_m", "bearing_deg", "site", "calibrated"}
    # every estimator scored on every thinned epoch of every pose
    n_ep = sum(len(r.ranges["t0"].select(slice(None, None, 3))) for r in recs)
    assert (raw.epochs.groupby("heuristic").size() == n_ep).all() and len(raw.epochs) == 5 * n_ep
    cals = ex.study.loso_calibrations(recs, stride=2, fit_scale=False)
    for site, cal in cals.items():
        assert not any(f"pos{site}_" in s for s in cal.source)          # never the evaluated site
        assert len(cal.source) == 4
    calib = ex.real.run_static_poses(recs, heights_m=H, stride=3, calibrations=cals)
    assert calib.poses.calibrated.all()
    assert calib.poses.err_m.median() < 0.5 * raw.poses.err_m.median()
    es = metrics.epoch_summary(calib.epochs, by="heuristic")
    assert es.loc["point", "coverage"] == 1.0 and es.loc["point", "median_m"] > es.loc["none", "median_m"]
    with pytest.raises(ValueError, match="calibration for site"):
        ex.real.run_static_poses(recs, heights_m=H, calibrations={1: cals[1]})
    with pytest.raises(ValueError, match="two sites"):
        ex.study.loso_calibrations([r for r in recs if r.meta["site"] == 1])
    with pytest.raises(ValueError, match="not from the evaluated recording"):
        ex.real.run_static_poses(recs, heights_m=None)


def test_dynamic_segments_on_a_noise_free_tour():
    rec, truth = tours.simulate_tour(dataclasses.replace(tours.TourConfig(tour=1, pace="slow"), **QUIET),
                                     rng=np.random.default_rng(3))
    segs = geometry.straight_segments(rec.truth["L"], tol_m=0.05)
    assert len(segs) == len(tours.TOURS[1]) - 1                      # the four walks
    out = ex.real.run_dynamic_segments(rec, segs, heights_m={"L": 1.3}, tags=["L"], heuristics=("none", "residual"),
                                  config=PruningConfig(dim=2, res_dropout=0.02))
    assert len(out.pieces) == 2 * len(segs)
    assert out.pieces.mean_err_m.max() < 0.1 and out.pieces.vel_err_mps.max() < 0.02
    es = metrics.epoch_summary(out.epochs, by="heuristic")
    assert set(es.index) == {"none", "residual", "point"} and es.n_epochs.nunique() == 1
    # fits cover the walks only, point fixes every epoch (the stops too)
    assert out.run_coverage["none"] < 0.9 * out.run_coverage["point"] and out.run_coverage["point"] > 0.95
    with pytest.raises(ValueError, match="stationary"):
        ex.real.run_dynamic_segments(rec, segs, heights_m={"L": 1.3}, heuristics=("percentile",))


def test_figures_draw():
    cfg = _small()
    res = ex.study.run_synthetic(cfg, rng=np.random.default_rng(1))
    rec, truth = res.recordings["tour1-fast"]
    fig = ex.figures.plot_polar_errors(res.stops, ncols=5)
    assert len(fig.axes) == len(tours.TOURS[1])
    ax = ex.figures.plot_segment_fits(res.moves, res.stops, truth_xy=rec.truth["H"].pos_m, anchors=rec.anchors)
    assert len([c for c in ax.texts if c.arrow_patch is not None]) == len(tours.TOURS[1]) - 1
    ex.figures.plot_coverage(tour=2)
    model = truth.model
    e = rng_err = np.random.default_rng(0).normal(0, 0.5, 500)
    ex.figures.plot_error_histogram(e, model, 0.3)
    ax = ex.figures.plot_error_cdf_percentile(rng_err, model=model, p_nlos=0.3)
    assert "P5" in ax.get_legend().get_texts()[0].get_text()
    log = rec.ranges["H"].between(0.13, 10.0)
    r = localize(log, rec.anchors, "robust_mean", stationary=True, z_m=2.0)
    ex.figures.plot_robust_mean_cloud(r, truth_xy=tours.TOURS[1][0])
    assert ex.figures.heuristic_color("point") != ex.figures.heuristic_color("none")


def test_hanyang_figure_draws_whatever_conditions_there_are():
    samples = pd.DataFrame({"condition": ["LOS"] * 40, "range_error_m": np.linspace(0.1, 0.4, 40),
                            "height_m": 1.0, "true_range_m": 10.0, "range_m": 10.0 + np.linspace(0.1, 0.4, 40),
                            "file": "a"})
    axes = ex.figures.plot_hanyang(samples, calibration.percentile_by_file(samples))
    assert len(axes) == 3 and len(axes[2].lines) == 3          # zero line + LOS median + LOS percentile
    axes = ex.figures.plot_hanyang(samples.iloc[:5], calibration.percentile_by_file(samples.iloc[:5]))
    assert len(axes[2].lines) == 1                              # no file long enough: only the zero line


def test_tour_explorer_serves_the_run_and_caches_other_settings():
    cfg = _small()
    res = ex.study.run_synthetic(cfg, rng=np.random.default_rng(1))
    xp = ex.panels.TourExplorer(res, cfg, seed=0)
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
    xp = ex.panels.PieceExplorer(rec, segs, heights_m={"L": 1.3}, config=PruningConfig(dim=2, res_dropout=0.02), stride=2)
    fig, out = xp.render(0, "L", "none", 0.9, 0.5, 2.0, "raw")
    assert out["mean error (m)"] < 0.1
    ranges = ex.panels.piece_panel(xp, tags=["L"], res_retention=0.9, rm_retention=0.5).controls["ranges"].options
    assert [v for _, v in ranges] == ["raw"]                                # no calibration: raw ranges only
    wrong = ex.panels.PieceExplorer(rec, segs, heights_m={"L": 0.3}, config=PruningConfig(dim=2), stride=2)
    assert wrong.render(0, "L", "none", 0.9, 0.5, 2.0, "raw")[1]["mean error (m)"] > out["mean error (m)"]
    with pytest.raises(ValueError, match="calibration"):
        xp.piece(0, "L", "none", 0.9, 0.5, 2.0, "calibrated")


@pytest.mark.realdata
def test_lias_static_pose_and_dynamic_segment():
    root = real_dataset("lias-planar-uwb")
    from uwbwb.datasets import lias

    recs = lias.load_static("8.14", data_dir=root.parent, site=5, yaw_deg=0)
    heights = calibration.tag_mount_height(recs).per_tag_m
    out = ex.real.run_static_poses(recs, heights_m=heights, tags=["t0"], stride=100).poses
    assert len(out) == 4 and out.err_m.max() < 0.6
    dyn = lias.load_dynamic("fast", data_dir=root.parent)
    segs = geometry.straight_segments(dyn.truth["t0"])
    assert len(segs) >= 10 and segs.duration_s.sum() > 0.5 * (dyn.truth["t0"].t_s[-1] - dyn.truth["t0"].t_s[0])
    res = ex.real.run_dynamic_segments(dyn, segs.head(3), heights_m=heights, tags=["t0"], heuristics=("none",),
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


# --------------------------------------------------------------------------- section 10: verdicts by intervals

HS = ["none", "percentile", "robust_mean", "residual"]


def _long(offsets: dict, *, n_series: int = 12, n: int = 8, seed: int = 5, kind: str = "stop") -> pd.DataFrame:
    """Errors of each heuristic on ``n_series`` experiments × ``n`` stops (or packets): a common random base plus
    the heuristic's offset; offset None: the base in reverse (the same median, other pairs: a tie)."""
    rng = np.random.default_rng(seed)
    rows = []
    for e in range(n_series):
        base = np.abs(rng.normal(0.5, 0.2, n))
        for h, off in offsets.items():
            err = base[::-1] if off is None else base + off
            rows.append(pd.DataFrame({"experiment": f"e{e}", "tag": "H", "segment": np.arange(n), "kind": kind,
                                      "t_s": 0.13 * np.arange(n), "heuristic": h, "err_m": err}))
    return pd.concat(rows, ignore_index=True)


def _syn(stops=None, track=None):
    empty = pd.DataFrame(columns=["experiment", "tag", "segment", "kind", "t_s", "heuristic", "err_m"])
    return ex.study.SyntheticResult(empty if stops is None else stops, pd.DataFrame(),
                                    empty if track is None else track, {})


def _row(table, start):
    rows = table[table["claim"].str.startswith(start)]
    assert len(rows) == 1, (start, list(table["claim"]))
    return rows.iloc[0]


@pytest.mark.parametrize("gaps_m, verdict", [((0.3, 0.3), "as in the paper"), ((-0.3, 0.3), "differs"),
                                             ((None, 0.3), "not resolved")])
def test_the_ranking_row_decides_each_step_by_its_interval(gaps_m, verdict):
    """Each step of the paper's order (residual < robust mean < percentile) needs its median-difference interval
    below 0: a reversed step says "differs", a step inside the noise "not resolved"; one experiment: no interval."""
    g0, g1 = gaps_m
    stops = _long({"none": 1.0, "residual": 0.0, "robust_mean": g0, "percentile": (g0 or 0.0) + g1})
    t = ex.verdicts.verdict_table(_syn(stops))
    row = _row(t, "ranking of the heuristics")
    assert row.verdict == verdict, row.ours
    assert "each experiment's series of stops one block" in row.rule and row["paper kind"] == "input"
    pairs = t.loc[row.name + 1:row.name + 3]                                   # a row per pair of the ranking
    assert pairs["claim"].str.startswith("pair of the ranking above: ").all() and (pairs["n"] == 96).all()
    assert pairs.iloc[0].claim.startswith("pair of the ranking above: residual pruning − robust mean, median stop")
    assert pairs.iloc[1].verdict == "robust mean lower"                       # robust mean − 5th percentile < 0
    one = ex.verdicts.verdict_table(_syn(stops[stops.experiment == "e0"]))
    assert _row(one, "ranking of the heuristics").verdict == "no interval"      # FAST: one experiment, one block


@pytest.mark.parametrize("offset_m, verdict", [(-0.3, "NLS better"), (0.3, "NLS worse"), (None, "not significant")])
def test_residual_pruning_against_the_point_fixes_on_common_packets(offset_m, verdict):
    track = _long({"point": 0.0, "residual": offset_m, "none": -1.0}, n=30, kind="move")
    track.loc[(track.heuristic == "residual") & (track.segment < 3), "err_m"] = np.nan     # not covered
    t = ex.verdicts.verdict_table(_syn(track=track))
    row = _row(t, "residual pruning (fixed in advance) vs the point-based fixes")
    assert row.verdict == verdict, row.ours
    both = track.pivot_table(index=["experiment", "segment", "t_s"], columns="heuristic", values="err_m").dropna()
    assert row.n == 324 == len(both)                                            # plain NLS is lower, not picked
    assert row.ours == pytest.approx(both["residual"].median() - both["point"].median())
    assert (row["95 % low"] <= row.ours <= row["95 % high"]) == (verdict != "no interval")
    one = ex.verdicts.verdict_table(_syn(track=track[track.experiment == "e0"]))
    assert _row(one, "residual pruning (fixed in advance)").verdict == "no interval"


@pytest.mark.parametrize("level_m, verdict", [(1.0, "agrees"), (5.0, "differs"), (3.4, "not resolved")])
def test_the_4_m_row_takes_the_interval_over_experiments_and_names_the_noise(level_m, verdict):
    rng = np.random.default_rng(1)
    track = _long({"residual": 0.0}, n=40)
    track["err_m"] = level_m * track["err_m"] / 0.5                             # p90 per experiment ≈ 1.5 × level
    if verdict == "not resolved":
        track["err_m"] *= np.repeat(rng.uniform(0.2, 1.3, 12), 40)             # experiments straddle 4 m
    cfg = tours.TourConfig(nlos_mean_m=2.5, p_nlos_out=0.3, nlos_dwell_s=3.0)
    t = ex.verdicts.verdict_table(_syn(track=track), tour=cfg)
    row = _row(t, "residual pruning: 90 % of all distance errors under 4 m")
    assert row.verdict == verdict, row.ours
    assert row["paper kind"] == "input" and row["ours kind"] == "reproduced"
    assert "NLOS excess N(2.5 m, 1 m)" in row.assumption and "30 % of links outside" in row.assumption
    assert "Student-t" in row.rule
    one = ex.verdicts.verdict_table(_syn(track=track[track.experiment == "e0"]))
    assert _row(one, "residual pruning: 90 %").verdict == "no interval"        # one experiment: FAST
    assert "N(" not in _row(one, "residual pruning: 90 %").assumption          # no configuration: named only


@pytest.mark.parametrize("levels_m, verdicts", [((0.5, 1.0, 2.0), ["agrees"] * 3), ((5.0, 6.0, 7.0), ["differs"] * 3),
                                                ((0.5, 1.0, 6.0), ["agrees", "agrees", "differs"])])
def test_the_scaled_excess_rows_decide_each_excess_by_its_interval(levels_m, verdicts):
    parts = [_long({"residual": 0.0}, n=40).assign(err_m=lambda d, v=v: v * d.err_m / 0.5, nlos_mean_m=m)
             for v, m in zip(levels_m, (1.25, 2.5, 5.0))]
    scaled = "residual pruning: 90 % of all distance errors under 4 m, as the simulated NLOS excess is scaled: "
    t = ex.verdicts.verdict_table(_syn(), excess=pd.concat(parts, ignore_index=True))
    rows = t[t["claim"].str.startswith(scaled)]
    assert list(rows.verdict) == verdicts, list(rows.ours)
    assert [c[len(scaled):].split(" (")[0] for c in rows.claim] == ["1.25 m", "2.5 m", "5 m"] and (rows.n == 12).all()
    one = pd.concat([p[p.experiment == "e0"] for p in parts])
    t = ex.verdicts.verdict_table(_syn(), excess=one)
    assert list(t.loc[t["claim"].str.startswith(scaled), "verdict"]) == ["no interval"] * 3


@pytest.mark.parametrize("gap_m, dz_m, same, height", [(0.3, 0.8, "same", "too high"),
                                                       (-0.3, -0.8, "changes", "too low"),
                                                       (None, None, "not resolved", "not significant")])
def test_the_3d_rows_decide_the_known_order_and_the_height_error_by_intervals(gap_m, dz_m, same, height):
    known = _long({"none": 1.0, "residual": 0.0, "percentile": 0.3})                # known order: residual < percentile
    three = _long({"none": 1.0, "residual": 0.0, "percentile": gap_m}, seed=6)
    three["err_3d_m"] = three["err_m"]
    rng = np.random.default_rng(2)
    three["err_z_m"] = (rng.normal(0.0, 0.1, len(three)) if dz_m is None else dz_m + 0.1 * rng.standard_normal(len(three)))
    t = ex.verdicts.verdict_table(_syn(known), other=_syn(three))
    assert _row(t, "the known-height ranking in 3-D").verdict == same
    assert _row(t, "5th percentile in 3-D").verdict == height


def test_the_3d_row_reads_the_tied_known_height_ranking():
    """An order of medians that no known-height interval resolves (a tie in the ranking) is no order to keep: even
    resolved in 3-D, the row says "not resolved", and it shows both rankings."""
    known = _long({"none": 1.0, "residual": 0.0, "percentile": None, "robust_mean": 0.6})
    three = _long({"none": 1.0, "residual": 0.0, "percentile": 0.3}, seed=6).assign(err_z_m=0.0)
    three["err_3d_m"] = three["err_m"]
    ranks = ex.verdicts.rankings(_syn(known))
    assert ranks["synthetic"].rank["residual"] == ranks["synthetic"].rank["percentile"] == 1
    row = _row(ex.verdicts.verdict_table(_syn(known), other=_syn(three), ranks=ranks), "the known-height ranking in 3-D")
    assert row.verdict == "not resolved"
    assert row.ours == f"known height: {ranks['synthetic'].text()}; 3-D: residual pruning 1, 5th percentile 2"


@pytest.mark.parametrize("gap_m, verdict", [(0.3, "same"), (-0.3, "changes"), (None, "not resolved")])
def test_the_persistence_row_asks_whether_the_best_stays_best(gap_m, verdict):
    base = _long({"percentile": 0.0, "residual": 0.3, "robust_mean": 0.4}).assign(nlos_dwell_s=3.0)
    long = _long({"percentile": 0.0, "residual": gap_m, "robust_mean": 0.6}, seed=7).assign(nlos_dwell_s=30.0)
    t = ex.verdicts.verdict_table(_syn(), persistence=pd.concat([base, long]))
    row = _row(t, "the best heuristic at 3 s NLOS episodes (5th percentile) still best at 30 s")
    assert row.verdict == verdict, row.ours


def test_the_persistence_row_names_no_best_the_base_intervals_do_not_resolve():
    """A lowest median at 3 s inside the noise is not "the best": the row says which tie and decides nothing."""
    base = _long({"percentile": 0.0, "residual": None, "robust_mean": 0.4}).assign(nlos_dwell_s=3.0)
    long = _long({"percentile": 0.0, "residual": 0.3, "robust_mean": 0.6}, seed=7).assign(nlos_dwell_s=30.0)
    row = _row(ex.verdicts.verdict_table(_syn(), persistence=pd.concat([base, long])), "the best heuristic at 3 s")
    assert row.verdict == "not resolved" and ": tied) still best at 30 s" in row.claim, row.ours
    assert "5th percentile" in row.claim and "residual pruning" in row.claim


def _poses(offsets, n=14, seed=3):
    """LIAS-like runs: ``n`` poses, one error per pose and heuristic, scored at 5 epochs each."""
    rng = np.random.default_rng(seed)
    base = np.abs(rng.normal(0.2, 0.05, n))
    runs = {}
    for k, off in offsets.items():
        poses = pd.concat([pd.DataFrame({"recording": [f"p{i}" for i in range(n)], "tag": "t0", "heuristic": h,
                                         "err_m": base[::-1] if o is None else base + o}) for h, o in off.items()])
        epochs = poses.loc[poses.index.repeat(5)].assign(t_s=lambda d: d.groupby(["recording", "heuristic"]).cumcount())
        runs[k] = ex.real.StaticResult(poses, epochs.reset_index(drop=True))
    return types.SimpleNamespace(runs=runs)


@pytest.mark.parametrize("cal_m, point_m, verdicts", [(-0.1, 0.1, ("calibration better", "NLS better")),
                                                      (0.2, -0.1, ("pruning better", "NLS worse")),
                                                      (None, None, ("not significant", "not significant"))])
def test_the_lias_static_rows_decide_pose_by_pose(cal_m, point_m, verdicts):
    tie = None if cal_m is None else 0.0
    lias = _poses({"raw": {"none": 0.0, "residual": tie, "point": point_m},
                   "calibrated (LOSO)": {"none": cal_m, "point": 0.0}})
    t = ex.verdicts.verdict_table(_syn(), lias=lias)
    assert _row(t, "LIAS static: range calibration").verdict == verdicts[0]
    assert _row(t, "LIAS static, raw ranges: plain NLS (fixed in advance) vs point fixes").verdict == verdicts[1]
    assert _row(t, "LIAS static, raw ranges").assumption == "—"                   # real ranges: no simulator


def _dynamic(offsets, seed=8):
    rng = np.random.default_rng(seed)
    rows = []
    for seg in range(6):
        t = np.arange(60) * 0.1
        base = np.abs(rng.normal(0.5, 0.2, t.size))
        for h, off in offsets.items():
            e = (base[::-1] if off is None else base + off + rng.normal(0, 0.02, t.size)).copy()
            if h != "point":
                e[:5] = np.nan                                       # not covered: out of the pairing
            rows.append(pd.DataFrame({"segment": seg, "tag": "t0", "t_s": t, "heuristic": h, "err_m": e}))
    return pd.concat(rows, ignore_index=True)


@pytest.mark.parametrize("offset_m, verdict", [(-0.2, "NLS better"), (0.2, "NLS worse"), (None, "not significant")])
def test_the_lias_dynamic_point_row_decides_by_the_median_difference_on_common_epochs(offset_m, verdict):
    """Plain NLS (fixed in advance) vs point fixes on the epochs both covered; a lower heuristic is not picked."""
    epochs = _dynamic({"point": 0.0, "none": offset_m, "residual": -1.0 if offset_m is not None else None})
    dyn = types.SimpleNamespace(runs={"raw": ex.real.DynamicResult(pd.DataFrame(), epochs, pd.Series(dtype=float))})
    row = _row(ex.verdicts.verdict_table(_syn(), lias_dyn=dyn),
               "LIAS dynamic, raw ranges: plain NLS (fixed in advance) vs point fixes")
    assert row.verdict == verdict, row.ours
    assert row.n == 330


@pytest.mark.parametrize("offset_m, verdict", [(-0.2, "residual pruning better"), (0.2, "plain NLS better"),
                                               (None, "not significant")])
def test_the_lias_dynamic_pruning_row_fixes_residual_pruning_in_advance(offset_m, verdict):
    epochs = _dynamic({"point": -1.0, "none": 0.0, "robust_mean": -0.5, "residual": offset_m})
    dyn = types.SimpleNamespace(runs={"raw": ex.real.DynamicResult(pd.DataFrame(), epochs, pd.Series(dtype=float))})
    row = _row(ex.verdicts.verdict_table(_syn(), lias_dyn=dyn), "LIAS dynamic, raw ranges: residual pruning (fixed in advance) vs plain NLS")
    assert row.verdict == verdict, row.ours


def _hanyang(gap_m, seed=4):
    rng = np.random.default_rng(seed)
    rows = []
    for height in (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0):
        for r in np.arange(2.0, 42.0, 4.0):
            los = 0.1 + 0.05 * rng.standard_normal()
            nlos = los + gap_m if gap_m is not None else 0.1 + 0.05 * rng.standard_normal()
            rows += [{"condition": "LOS", "height_m": height, "true_range_m": r, "median_err_m": los},
                     {"condition": "NLOS", "height_m": height, "true_range_m": r, "median_err_m": nlos}]
    return pd.DataFrame(rows)


@pytest.mark.parametrize("gap_m, verdict", [(0.3, "NLOS larger"), (-0.3, "NLOS smaller"), (None, "not significant")])
def test_the_hanyang_row_pairs_files_by_height_and_range(gap_m, verdict):
    row = _row(ex.verdicts.verdict_table(_syn(), hanyang=_hanyang(gap_m)), "Hanyang static")
    assert row.verdict == verdict, row.ours
    los_only = _hanyang(0.3).query("condition == 'LOS'")
    assert not ex.verdicts.verdict_table(_syn(), hanyang=los_only)["claim"].str.startswith("Hanyang").any()


def test_the_verdict_table_says_every_kind():
    t = ex.verdicts.verdict_table(_syn(_long({"residual": 0.0, "robust_mean": 0.3, "percentile": 0.6})))
    assert list(t.columns) == ["claim", "paper", "paper kind", "ours", "95 % low", "95 % high", "n", "ours kind",
                               "assumption", "rule", "verdict"]
    assert set(t["ours kind"]) == {"reproduced"}
    assert (t["paper kind"] == np.where(t["paper"] == "—", "—", "input")).all()


@pytest.mark.parametrize("gap_m, lead", [(0.3, "residual pruning"), (None, "not resolved: ")])
def test_the_wins_table_names_a_leader_only_when_its_interval_lies_below_0(gap_m, lead):
    epochs = _long({"none": 1.0, "residual": 0.0, "robust_mean": gap_m, "percentile": 0.6, "point": 0.9}, n=30)
    w = ex.verdicts.wins_table({"a": (epochs, ["experiment", "tag"], "segment")})
    assert w.loc["a", "best of all"].startswith(lead) and w.loc["a", "best heuristic"].startswith(lead)
    assert list(w.columns[:5]) == ["none", "percentile", "robust_mean", "residual", "point"]
    assert w.loc["a", "residual"] == pytest.approx(epochs.query("heuristic == 'residual'").err_m.median())
    one = ex.verdicts.wins_table({"a": (epochs[epochs.experiment == "e0"], ["experiment", "tag"], "segment")})
    assert one.loc["a", "best of all"].startswith("no interval: ")              # one block: FAST


def test_headline_rows_say_their_kind_and_name_the_noise_beside_the_paper_4_m():
    t = pd.DataFrame({"stop_median_m": [1.157, 0.321, 0.515, 0.604, np.nan], "all_p90_m": [1.9, 0.6, 1.5, 1.7, 2.9],
                      "coverage": 1.0}, index=pd.Index([*HS, "point"], name="heuristic"))
    stops = _long({"none": 1.0, "percentile": 0.0, "robust_mean": 0.3, "residual": 0.6})
    res = dict(synthetic=_syn(stops), synthetic_table=t, synthetic_dim=2, control=t, tour=tours.TourConfig(
        nlos_mean_m=2.5, p_nlos_out=0.3), other_table=t.loc[["none", "percentile", "residual"]].assign(
        stop_err_z_median_m=1.0), rankings=ex.verdicts.rankings(_syn(stops)))
    rows = ex.headlines.rows(res)
    assert rows and {r["kind"] for r in rows} == {"reproduced"} and all(np.isfinite(r["value"]) for r in rows)
    four = [r for r in rows if r["paper_value"] == 4.0]
    assert len(four) == 1 and "follows from assumed noise: NLOS excess N(2.5 m, 1 m)" in four[0]["quantity"]
    assert "30 % of links outside" in four[0]["quantity"]
    q = {r["quantity"]: r["value"] for r in rows}
    rank = "rank by median stationary error among the three heuristics (1 = best; tied where not resolved)"
    assert [q[f"{rank}, {ex.scoring.LABELS[h]} (known height)"] for h in ("percentile", "robust_mean", "residual")] \
        == [1, 2, 3]                                                                  # every step resolved
    assert {r["paper_value"] for r in rows if r["quantity"].startswith("rank")} == {1, 2, 3}
    assert q["90 % of all distance errors, residual pruning minus point-based (known height)"] == pytest.approx(-1.2)
    assert "median stationary height error |dz|, 5th percentile (3-D, no height)" in q
    for quantity in q:      # every accuracy row on an estimator's own packets has that estimator's coverage beside it
        if "covered packets" in quantity:
            lab, geo = re.match(r".*, (.+) \((known height|3-D, no height), covered packets", quantity).groups()
            assert q[f"packet coverage, {lab} ({geo})"] == 1.0, quantity
    assert not any("3-D" in r["quantity"] for r in ex.headlines.rows({**res, "synthetic_dim": 3})
                   if "(3-D, no height)" in r["quantity"] and "known" in r["quantity"])
    s = metrics.Summary("02_pruning_nls", fast=True)
    for r in rows:
        s.add(**r)
    assert len(s.frame()) == len(rows)


@pytest.mark.parametrize("offsets, ranks", [((0.0, 0.3, 0.6), (1, 2, 3)), ((0.0, None, 0.6), (1, 1, 3)),
                                            ((0.6, None, 0.0), (3, 1, 1)), ((0.0, None, None), (1, 1, 1))])
def test_the_ranks_tie_the_heuristics_no_interval_separates(offsets, ranks):
    """Ranks (residual pruning, robust mean, 5th percentile) by every pair's median-difference interval: a pair
    inside the noise shares a rank, so no rank states an order the intervals do not resolve; one block: all 1."""
    stops = _long({"none": 1.0, **dict(zip(("residual", "robust_mean", "percentile"), offsets))})
    r = ex.verdicts.ranking(stops, ["experiment", "tag"], rng=np.random.default_rng(0))
    assert tuple(r.rank[["residual", "robust_mean", "percentile"]]) == ranks, [(d["a"], d["b"], d["side"]) for d in r.pairs]
    assert [(d["a"], d["b"]) for d in r.pairs][:2] == [("residual", "robust_mean"), ("robust_mean", "percentile")]
    for d in r.pairs:                      # a strict order between two ranks only where their interval resolves it
        ra, rb = r.rank[d["a"]], r.rank[d["b"]]
        assert ra == rb or d["side"] == ("below" if ra < rb else "above")
    one = ex.verdicts.ranking(stops[stops.experiment == "e0"], ["experiment", "tag"], rng=np.random.default_rng(0))
    assert set(one.rank) == {1}                                                    # FAST: no interval, no order


def test_a_tie_that_hides_a_resolved_pair_says_so_in_its_text_and_rows():
    """Not transitive: robust mean ≈ 5th percentile ≈ residual pruning, yet robust mean resolved better than residual
    pruning. Tied groups rank all three 1; the ranking's text and every rank row then name the hidden pair."""
    pair = lambda a, b, side: {"a": a, "b": b, "side": side, "d_m": 0.0, "lo_m": 0.0, "hi_m": 0.0}
    r = ex.verdicts.Ranking((pair("residual", "robust_mean", "above"), pair("robust_mean", "percentile", "none"),
                             pair("residual", "percentile", "none")),
                            pd.Series({"robust_mean": 1, "percentile": 1, "residual": 1}, name="rank"))
    assert r.hidden() == [("robust_mean", "residual")]
    assert r.text().endswith("; inside the tie, robust mean resolved better than residual pruning")
    clear = ex.verdicts.Ranking(r.pairs[1:], r.rank)
    assert clear.hidden() == [] and clear.note() == ""
    assert ex.verdicts.Ranking(r.pairs, pd.Series({"robust_mean": 1, "percentile": 1, "residual": 3})).hidden() == []


def test_every_summary_row_is_the_number_of_the_table_it_comes_from():
    """Each headline row equals the cell of the notebook table it is read from (synthetic, LIAS static, Hanyang
    static), and every rank row is the rank the verdict table's ranking row shows, from the same object."""
    offsets = {"none": 1.0, "percentile": 0.4, "robust_mean": None, "residual": 0.0}
    stops, track = _long(offsets), _long({**offsets, "point": 0.8}, n=20, seed=6)
    syn, table, tour = _syn(stops, track), ex.scoring.heuristic_summary(stops, None, track), tours.TourConfig()
    flat = stops.heuristic != "robust_mean"                          # the same packets in 3-D: no robust mean
    other = ex.scoring.heuristic_summary(stops[flat].assign(err_z_m=0.2, err_3d_m=stops.err_m[flat] + 0.1), None,
                                         track[track.heuristic != "robust_mean"])
    lias = _poses({"raw": {"none": 0.0, "percentile": 0.05, "robust_mean": None, "residual": 0.1, "point": 0.0}})
    lias.table = pd.concat({k: ex.scoring.heuristic_summary(v.poses) for k, v in lias.runs.items()})
    lias.epochs = {k: metrics.epoch_summary(v.epochs, by="heuristic", order=ex.scoring.ESTIMATORS)
                   for k, v in lias.runs.items()}
    lias.label = "lias-planar-uwb/8.14"
    hy = pd.DataFrame({"median_err_m": [0.24, 0.28], "pq_err_m": [0.2, 0.25]}, index=["LOS", "NLOS"])
    ranks = ex.verdicts.rankings(syn, lias, seed=3)
    rows = ex.headlines.rows(dict(synthetic=syn, synthetic_table=table, synthetic_dim=2, tour=tour, rankings=ranks,
                                  other_table=other, lias_static=lias, hanyang=hy,
                                  hanyang_label="hanyang-outdoor-uwb/static"))
    got = {(r["quantity"], r["data"]): r["value"] for r in rows}
    want, H = {}, ex.headlines
    note = "; follows from assumed noise: " + ex.verdicts.noise(tour)
    for decl, t, data, fmt in [(H.SYNTHETIC, table, "synthetic", {"geo": "known height"}),
                               (H.THREE_D, other, "synthetic", {}),
                               (H.LIAS_POSES, lias.table.loc["raw"], lias.label, {"k": "raw"}),
                               (H.LIAS_EPOCHS, lias.epochs["raw"], lias.label, {"k": "raw"}),
                               (H.HANYANG, hy, "hanyang-outdoor-uwb/static", {})]:
        for h in t.index:
            for q, col, _ in decl:
                if col in t and np.isfinite(t.loc[h, col]):
                    lab = ex.scoring.LABELS.get(h, h)
                    want[q.format(lab=lab, note=note if h == "residual" else "", **fmt), data] = t.loc[h, col]
    rank = "rank by median stationary error among the three heuristics (1 = best; tied where not resolved)"
    for key, where, data in (("synthetic", " (known height)", "synthetic"), ("raw", ", raw", lias.label)):
        for h, v in ranks[key].rank.items():
            want[f"{rank}, {ex.scoring.LABELS[h]}{where}", data] = v
    want["90 % of all distance errors, residual pruning minus point-based (known height)", "synthetic"] = (
        table.loc["residual", "all_p90_m"] - table.loc["point", "all_p90_m"])
    assert got == want
    assert ranks["synthetic"].rank["residual"] == ranks["synthetic"].rank["robust_mean"] == 1     # a tie, not 1 and 2
    t = ex.verdicts.verdict_table(syn, lias=lias, ranks=ranks, seed=3)
    for claim, key in (("ranking of the heuristics", "synthetic"), ("LIAS static, raw ranges: the heuristics ranked",
                                                                    "raw")):
        assert _row(t, claim).ours == ranks[key].text()
    assert t.equals(ex.verdicts.verdict_table(syn, lias=lias, seed=3))                 # the same object by default
