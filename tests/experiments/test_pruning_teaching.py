"""Notebook 02's sections, headlines, panels and exercises (uwbwb.experiments.pruning)."""

from __future__ import annotations

import dataclasses
import tempfile

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

import uwbwb as uw  # noqa: E402
from uwbwb import calibration  # noqa: E402
from uwbwb.experiments import pruning as ex  # noqa: E402
from uwbwb.experiments.pruning import exercises, headlines, panels, verdicts  # noqa: E402
from uwbwb.filters.pruning import PruningConfig  # noqa: E402
from uwbwb.sim import rig, tours  # noqa: E402
from tests.test_teaching import assert_reads_predictions


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _small():
    return ex.study.SyntheticConfig(tours=(2,), paces=("fast",), tags=("H",),
                              pruning=PruningConfig(dim=2, res_dropout=0.02, rm_dropout=0.05))


# --------------------------------------------------------------------------- sections


@pytest.fixture(scope="module")
def room():
    data = uw.datasets.load_lias_room(tempfile.mkdtemp(), "fast", "8.14", stand_in=rig.RigConfig(duration_s=15.0),
                                      static_duration_s=3.0, rng=np.random.default_rng(0))
    static = [dataclasses.replace(r, meta={**r.meta, "site": i % 2}) for i, r in enumerate(data.static[:6])]
    return data.dynamic, static


def test_lias_sections_run_the_same_comparison_as_the_runs_they_call(room):
    dynamic, static = room
    cfg = PruningConfig(dim=2)
    st = ex.sections.lias_static(static, label="lias-planar-uwb/x", tags=("t0",), config=cfg, stride=50)
    assert list(st.runs) == ["raw", "calibrated (LOSO)"] and st.mount.per_tag_m == pytest.approx({"t0": 0.97}, abs=0.01)
    direct = ex.real.run_static_poses(static, heights_m=st.mount.per_tag_m, tags=("t0",), config=cfg, stride=50)
    pd.testing.assert_frame_equal(st.table.loc["raw"], ex.scoring.heuristic_summary(direct.poses))
    assert set(st.epochs["raw"].n_epochs) == {st.epochs["raw"].n_epochs.iloc[0]}     # same epochs for all
    assert set(st.range_stats.tag_id) == {"t0"} and {"median_m", "sigma_m"} <= set(st.range_stats.columns)
    raw_only = ex.sections.lias_static(static, label="x", tags=("t0",), config=cfg, stride=50, loso=False)
    assert list(raw_only.runs) == ["raw"]
    dy = ex.sections.lias_dynamic(dynamic, raw_only, tags=("t0",), config=cfg, stride=20, calibrated=False)
    assert dy.calibration is None and list(dy.runs) == ["raw"]
    assert set(dy.table.index.get_level_values(0)) == {"raw"}
    assert dy.label == dynamic.label
    with pytest.raises(ValueError, match="recordings"):
        ex.sections.lias_static([], label="x", tags=("t0",), config=cfg, stride=50)
    with pytest.raises(ValueError, match="stride"):
        ex.sections.lias_static(static, label="x", tags=("t0",), config=cfg, stride=0)


# --------------------------------------------------------------------------- headlines


def _results(*, converged=True, same_walks=True, pruning_wins=True, control_ok=True, lias_same=True):
    stops = pd.DataFrame({"heuristic": ["none", "residual"], "converged": [True, converged], "err_m": [1.0, 0.5]})
    moves = pd.DataFrame({"heuristic": ["none", "residual"], "converged": [True, converged]})
    n = 3 if same_walks else 2
    track = pd.DataFrame({"kind": "move", "heuristic": ["none"] * 3 + ["residual"] * n, "err_m": 0.3})
    syn = ex.study.SyntheticResult(stops, moves, track, {})
    table = pd.DataFrame({"stop_median_m": [1.0, 0.5, 0.8] if pruning_wins else [1.0, 1.5, 1.2]},
                         index=pd.Index(["none", "residual", "percentile"], name="heuristic"))
    control = pd.DataFrame({"all_median_m": [0.2, 0.22 if control_ok else 0.4, 0.3],
                            "stop_median_m": [0.2, 0.2, 0.5 if control_ok else 0.1]},
                           index=pd.Index(["none", "residual", "percentile"], name="heuristic"))
    epochs = pd.DataFrame({"n_epochs": [10, 10 if lias_same else 9]}, index=["none", "point"])
    lias = ex.sections.LiasStatic("x", [], None, pd.DataFrame(), {"raw": None}, pd.DataFrame(), {"raw": epochs})
    return dict(synthetic=syn, synthetic_table=table, synthetic_dim=2, control=control, lias_static=lias)


def test_checks_pass_and_each_one_can_fail():
    assert headlines.checks(_results(), fast=True) == []
    for kw, words in (({"converged": False}, "converges"), ({"same_walks": False}, "same walk packets"),
                      ({"pruning_wins": False}, "beats plain NLS"), ({"control_ok": False}, "outlier-free"),
                      ({"lias_same": False}, "LIAS static")):
        fail = headlines.checks(_results(**kw), fast=False)
        assert fail and any(words in f for f in fail), (kw, fail)
    assert len(headlines.checks(_results(control_ok=False), fast=True)) == 2      # residual and percentile


def test_rows_of_results_say_their_kind_and_the_3d_rows_only_beside_a_2d_run():
    syn_table = pd.DataFrame({"stop_median_m": [1.2, 0.5, 0.6, 0.4], "all_p90_m": [3.0, 2.0, 2.5, np.nan]},
                             index=pd.Index(["none", "percentile", "robust_mean", "residual"], name="heuristic"))
    ranks = {"synthetic": verdicts.Ranking((), pd.Series({"residual": 1, "percentile": 1, "robust_mean": 1}))}
    res = dict(synthetic_table=syn_table, synthetic_dim=2, other_table=syn_table, rankings=ranks)
    rows = headlines.rows(res)
    assert {r["kind"] for r in rows} == {"reproduced"}
    s = uw.metrics.Summary("02_pruning_nls", fast=True)
    for r in rows:
        s.add(**r)
    assert len(s) == len(rows)
    three_d = {**res, "synthetic_dim": 3}
    assert not any("(3-D, no height)" in r["quantity"] and "known" in r["quantity"] for r in headlines.rows(three_d))
    assert len(headlines.rows(three_d)) < len(rows)                  # no second geometry when the first is 3-D


# --------------------------------------------------------------------------- panels


def test_panels_offer_only_what_the_run_has():
    cfg = dataclasses.replace(_small(), heuristics=("none", "residual"))
    xp = ex.panels.TourExplorer(ex.study.SyntheticResult(pd.DataFrame(), pd.DataFrame(), pd.DataFrame(), {}), cfg, seed=0)
    p = panels.tour_panel(xp, res_retention=0.9, rm_retention=0.5)
    opts = {k: c.options for k, c in p.controls.items() if hasattr(c, "options")}
    assert [v for _, v in opts["heuristic"]] == ["none", "residual"]             # the run's heuristics only
    assert [v for _, v in opts["node"]] == ["L", "H"] and [v for _, v in opts["pace"]] == ["slow", "fast"]


# --------------------------------------------------------------------------- exercises


@pytest.fixture(scope="module")
def tour2():
    return tours.simulate_tour(tours.TourConfig(tour=2, pace="fast"), rng=np.random.default_rng(0))


def test_pruning_off_raises_the_stop_error_and_equals_plain_nls(tour2):
    cfg = dataclasses.replace(_small(), pruning=PruningConfig(dim=2))
    check = exercises.pruning_off(*tour2, cfg, node="H", retention=1.0)
    assert check.holds, check
    n = dict(check.numbers)
    assert n["retention 1 (m)"] == pytest.approx(n["plain NLS (m)"])          # nothing pruned: plain NLS
    same = exercises.pruning_off(*tour2, cfg, node="H", retention=0.9)
    assert not same.holds                                                  # no change: the check cannot hold
    for c in (check, same):
        assert_reads_predictions(c)
    with pytest.raises(ValueError, match="retention"):
        exercises.pruning_off(*tour2, cfg, retention=0.0)


def test_without_nlos_the_fifth_percentile_loses_to_plain_nls():
    check = exercises.no_nlos(dataclasses.replace(_small(), pruning=PruningConfig(dim=2)), seed=0)
    assert check.holds, check
    n = dict(check.numbers)
    assert n["without NLOS, 5th percentile (m)"] > n["without NLOS, plain NLS (m)"]
    assert n["with NLOS, 5th percentile (m)"] < n["with NLOS, plain NLS (m)"]
    # a site without NLOS: both tours are NLOS-free, so the 5th percentile loses to plain NLS in both and the claim
    # (it beats plain NLS with NLOS) does not hold
    cfg = dataclasses.replace(_small(), pruning=PruningConfig(dim=2))
    clear = exercises.no_nlos(dataclasses.replace(cfg, tour=dataclasses.replace(cfg.tour, p_nlos_in=0.0,
                                                                                p_nlos_out=0.0)), seed=0)
    c = dict(clear.numbers)
    assert clear.holds is False, clear
    assert c["with NLOS, 5th percentile (m)"] > c["with NLOS, plain NLS (m)"]
    assert c["with NLOS, plain NLS (m)"] == c["without NLOS, plain NLS (m)"] == n["without NLOS, plain NLS (m)"]
    for ch in (check, clear):
        assert_reads_predictions(ch)
    with pytest.raises(ValueError, match="seed"):
        exercises.no_nlos(_small(), seed=-1)


# --------------------------------------------------------------------------- figures


def test_polar_charts_state_their_unit_and_angle_convention():
    stops = pd.DataFrame({"heuristic": ["none", "residual"] * 2, "label": ["K0", "K0", "K1", "K1"],
                          "err_m": [0.5, 0.2, 1.0, 0.3], "bearing_deg": [0.0, 90.0, 180.0, -90.0]})
    fig = ex.figures.plot_polar_errors(stops)
    for ax in fig.axes:
        assert ax.get_title() and "(m)" in ax.get_ylabel() and "°" in ax.get_xlabel()
        assert ax.get_theta_offset() == 0.0 and ax.get_theta_direction() == 1     # 0° = +x, counter-clockwise
        assert ax.yaxis.get_major_formatter()(0.5, 0).endswith(" m")
    assert any("counter-clockwise" in t.get_text() for t in fig.texts)


def test_hanyang_histogram_spans_the_data_and_has_a_y_label():
    rng = np.random.default_rng(0)
    e = np.r_[rng.normal(0.2, 0.05, 400), rng.normal(0.3, 0.05, 400)]
    samples = pd.DataFrame({"condition": ["LOS"] * 400 + ["NLOS"] * 400, "range_error_m": e, "height_m": 1.0,
                            "true_range_m": 10.0, "range_m": 10.0 + e, "file": ["a"] * 400 + ["b"] * 400})
    axes = ex.figures.plot_hanyang(samples, calibration.percentile_by_file(samples))
    lo, hi = axes[0].get_xlim()
    assert hi - lo < 1.5 * (e.max() - e.min()) and lo < np.percentile(e, 1) and hi > np.percentile(e, 99)
    for ax in axes:
        assert ax.get_title() and "(m)" in ax.get_xlabel() and ax.get_ylabel()


def test_robust_mean_cloud_draws_the_anchors_when_given(tour2):
    from uwbwb.filters.pruning import localize

    rec, truth = tour2
    stop = [s for s in truth.segments if s.kind == "stop"][0]
    log = rec.ranges["H"].between(stop.t_start_s + rec.meta["config"].period_s, stop.t_end_s)
    r = localize(log, rec.anchors, "robust_mean", PruningConfig(dim=2), stationary=True, z_m=2.0)
    ax = ex.figures.plot_robust_mean_cloud(r, truth_xy=stop.start_xy_m, anchors=rec.anchors)
    assert "anchors" in [ln.get_label() for ln in ax.lines]
    assert "anchors" not in [ln.get_label() for ln in ex.figures.plot_robust_mean_cloud(r).lines]
