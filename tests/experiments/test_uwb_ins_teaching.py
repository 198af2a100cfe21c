"""Notebook 05's teaching pieces and real-data protocol helpers: exercises (the claim and its flip),
the panel back end, the loose-filter tuning, the covariance inflation and the board reconciliation."""

import numpy as np
import pandas as pd
import pytest

from tests.fixtures import iasl as fx
from uwbwb.experiments.uwb_ins import exercises, panels, realtune
from uwbwb.filters import alignment, imu_calibration
from uwbwb.types import Estimates, Trajectory
from tests.test_teaching import assert_reads_predictions


def test_outage_exercise_holds_and_its_claim_can_fail():
    check = exercises.outage_loose_vs_tight(seed=0, outage_s=3.0)
    loose, tight = check.numbers["loose max in outage (m)"], check.numbers["tight max in outage (m)"]
    assert check.holds == (loose > 2.0 * tight) and check.holds
    strict = exercises.outage_loose_vs_tight(seed=0, outage_s=3.0, factor=loose / tight * 1.01)
    assert not strict.holds
    for c in (check, strict):
        assert_reads_predictions(c)
    with pytest.raises(ValueError, match="outage_s"):
        exercises.outage_loose_vs_tight(seed=0, outage_s=0.0)


def test_gate_exercise_compares_the_same_run_with_and_without_the_gate():
    check = exercises.gate_off(seed=0, outlier_rate=0.1, duration_s=4.0)
    with_gate, without = check.numbers["tight RMSE with gate (m)"], check.numbers["tight RMSE without gate (m)"]
    assert check.holds == (without > with_gate) and check.holds
    assert_reads_predictions(check)
    clean = exercises.gate_off(seed=0, outlier_rate=0.0, duration_s=4.0)     # nothing to gate: no big difference
    assert clean.numbers["tight RMSE without gate (m)"] < 2 * clean.numbers["tight RMSE with gate (m)"] + 0.01


def test_panel_offers_the_notebooks_outage_and_says_what_to_see():
    panel = panels.build_panel(seed=0, grade="consumer", outlier_rate=0.02, outage_s=5.0, outlier_c_m=0.1,
                               gate_prob=0.999, loose_window=5, stations_m=np.zeros((4, 3)))
    assert panel.controls["outage_s"].max == 5.0 and panel.values["outage_s"] == 5.0
    note = panels.panel_note(panel)
    assert "outage" in note and "RMSE" in note
    comp = panels.panel_comparison("dynamic", "consumer", 1.0, 1.0, 0.1, 0.02, 5.0, True, "tight", **panel.fixed)
    assert "max tight in outage (m)" in panels.readout(comp, "tight")
    with pytest.raises(ValueError, match="OUTAGE_S"):
        panels.build_panel(seed=0, grade="consumer", outlier_rate=0.02, outage_s=40.0, outlier_c_m=0.1,
                           gate_prob=0.999, loose_window=5, stations_m=np.zeros((4, 3)))


def _fake(nees_scale: float, nis: float, n: int = 400, seed: int = 0) -> alignment.Comparison:
    """A comparison whose "tight" errors are drawn with covariance ``nees_scale`` × its reported one."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.02
    P = np.tile(np.eye(3) * 1e-4, (n, 1, 1))
    e = rng.normal(size=(n, 3)) * np.sqrt(1e-4 * nees_scale)
    truth = Trajectory(t, np.zeros((n, 3)), name="truth")
    est = Estimates(t, e, np.full(n, 1, np.int8), "tight", P, info={"nis": np.full(n, nis), "dof": np.ones(n)})
    return alignment.Comparison("fake", truth, {"tight": est}, {}, {"scored": np.ones(n, bool)})


def test_inflation_is_fitted_on_one_comparison_and_applied_on_the_other():
    f = realtune.nees_inflation(_fake(20.0, 2.0, seed=1), _fake(20.0, 2.0, seed=2))
    assert f["k"] == pytest.approx(20.0, rel=0.15) and f["nees_test"] == pytest.approx(60.0, rel=0.15)
    assert f["nees_test_scaled"] == pytest.approx(3.0, rel=0.2) and f["inside_test_scaled"] > 0.85 > f["inside_test"]
    assert f["scaled_consistent"]
    # a scale that does not transfer is said so
    h = realtune.nees_inflation(_fake(2.0, 1.0, seed=1), _fake(40.0, 1.0, seed=2))
    assert not h["scaled_consistent"] and h["inside_test_scaled"] < f["prob"] - realtune.CONSISTENT_POINTS


def test_each_filters_scales_touch_only_itself(tmp_path):
    from uwbwb.datasets import iasl

    root = tmp_path / "iasl-uwb-imu"
    root.mkdir()
    (root / "uwb.yaml").write_text(fx.YAML_TEXT)
    fx.write_scenario(root / "flight_a", rng=np.random.default_rng(8), duration_s=30.0)
    rec = iasl.load_scenario("flight_a", tmp_path)
    cal = imu_calibration.calibrate_iasl(rec)
    base = alignment.compare_iasl(rec, cal, still_s=1.0, align_s=10.0)
    for name in alignment.TUNABLE:                                     # (q, r) moves that filter and no other
        comp = alignment.compare_iasl(rec, cal, still_s=1.0, align_s=10.0, scales={name: (10.0, 3.0)})
        for other in base.estimates:
            same = np.array_equal(comp.estimates[other].pos_m, base.estimates[other].pos_m, equal_nan=True)
            assert same == (other != name), (name, other)
    one = alignment.compare_iasl(rec, cal, still_s=1.0, align_s=10.0, scales={n: (1.0, 1.0) for n in alignment.TUNABLE})
    for other in base.estimates:                                      # (1, 1) is the untuned filter, bit for bit
        np.testing.assert_array_equal(one.estimates[other].pos_m, base.estimates[other].pos_m)
    assert realtune.summary_rows({"k": 2.0, "nees_test_scaled": 3.0}, data="x", cal_label="a")[0]["value"] == 2.0
    with pytest.raises(ValueError, match="unknown filters"):
        alignment.compare_iasl(rec, cal, still_s=1.0, align_s=10.0, scales={"UWB-only": (1.0, 1.0)})


def test_the_real_data_tables_read_the_boards_tuning_and_estimates(tmp_path):
    """Notebook 05's real-data section is one scoreboard: its tuning table, summary rows and Comparison come from it."""
    from uwbwb import scoreboard as sb
    from uwbwb.datasets import iasl
    from uwbwb.experiments.uwb_ins import realdata, realfair
    from uwbwb.scoreboard.estimators import CalibratedLs, UwbInsFilter

    fx.write_dataset(tmp_path / "iasl-uwb-imu", rng=np.random.default_rng(8), duration_s=30.0)
    cal_rec, test = iasl.load_scenario("scenario1", tmp_path), iasl.load_scenario("scenario2", tmp_path)
    grid, cache = ((0.1, 1.0), (1.0, 1.0), (10.0, 1.0)), {}
    ests = [CalibratedLs(), *(UwbInsFilter(k, cache, grid) for k in ("loose", "tight", "INS-only"))]
    b = sb.score(test, cal_rec, estimators=ests, rate_hz=10.0, fast=True)
    table = realfair.tuning_table(b)
    assert list(table.index) == ["loose", "tight"]                   # LS and INS-only tune nothing
    for name in table.index:
        p = b.calibration.params(name)
        assert (table.loc[name, "Q ×"], table.loc[name, "R ×"]) == (p["q_scale"], p["r_scale"])
        assert table.loc[name, "RMSE picked (m)"] == min(p["grid_rmse_m"]) <= table.loc[name, "RMSE at Q × 1, R × 1 (m)"]
        assert table.loc[name, "edge"] == ("on the edge" if p["grid_edge"] else "—")
    rows = realfair.summary_rows(b, None, data="x", cal_label="scenario1", cal_data="cal")
    assert [r["value"] for r in rows[:2]] == [b.calibration.params("loose")["q_scale"], b.calibration.params("loose")["r_scale"]]
    assert len(rows) == 4 and all("3-point grid" in r["quantity"] and r["data"] == "cal" for r in rows)
    comp = realdata.board_comparison(b)
    assert list(comp.estimates) == ["LS", "loose", "tight", "INS-only"] and b.entry("INS-only", "tag").bound is None
    for e in b.ran("tag"):                                            # the board's errors, epoch for epoch
        np.testing.assert_array_equal(comp.errors(e.method)[e.scoring], e.error_m[e.scoring])
    assert comp.rejected["eq4"] == int(np.sum(b.entry("tight", "tag").estimates.info["n_outliers"]))
    with pytest.raises(ValueError, match="kind"):
        UwbInsFilter("EKF + gate")


def test_difference_rows_are_the_cells_of_the_table_shown():
    import pandas as pd

    from uwbwb.experiments.uwb_ins import realfair

    v = pd.DataFrame([{"recording": "iasl-uwb-imu/scenario2", "A": "tight", "B": "loose", "A − B (mm)": -0.96,
                       "95 % low (mm)": -3.7, "95 % high (mm)": 3.1, "verdict": "not significant"}])
    rows = {r["quantity"]: r for r in realfair.difference_rows(v, rate_hz=5.0)}
    q = "horizontal RMSE difference tight − loose (scoreboard, 5 Hz)"
    assert {k: r["value"] for k, r in rows.items()} == {q: -0.96, q + ", 95 % interval low": -3.7,
                                                        q + ", 95 % interval high": 3.1}
    assert {r["data"] for r in rows.values()} == {"iasl-uwb-imu/scenario2"}


def test_the_clock_verdict_follows_the_interval_of_the_change():
    from uwbwb.experiments.uwb_ins import realfair

    assert realfair.clock_verdict(-0.9, 0.4) == "no detectable change"
    assert realfair.clock_verdict(1.0, 4.0) == "worse without the motion capture"
    assert realfair.clock_verdict(-3.0, -1.0) == "better without the motion capture"
    assert realfair.clock_verdict(np.nan, np.nan).startswith("no verdict")

    def res(tight, loose):
        rows = {"UWB-only": (0.01, -0.02, 0.03), "EKF + gate": (0.02, -0.01, 0.04), "tight": tight, "loose": loose,
                "INS-only": (200.0, 100.0, 300.0)}
        t = pd.DataFrame({m: {"motion-capture clock (m)": 0.05, "ranges clock (m)": 0.05 + c / 1e3, "change (mm)": c,
                              "lo (mm)": lo, "hi (mm)": hi, "epochs": 900} for m, (c, lo, hi) in rows.items()}).T
        return {"offsets": {"truth_s": -0.44, "ranges_s": -0.48, "peak": 0.8, "rival": 0.6, "halves_s": (-0.47, -0.49)},
                "start_s": (22.0, 22.05),
                "table": t}

    class NoTuning:                                         # a board whose methods tuned nothing
        methods = ()
    rows = realfair.summary_rows(NoTuning(), res((0.1, -0.2, 0.5), (2.5, 1.0, 4.0)), data="x", cal_label="c")
    assert [r["unit"] for r in rows] == ["ms"] + ["mm"] * 6 and rows[0]["value"] == pytest.approx(-40.0)
    q = "horizontal RMSE change of tight with the IMU clock from the ranges"     # the table's cells, interval too
    assert {r["quantity"]: r["value"] for r in rows if r["quantity"].startswith(q)} == {
        q: 0.1, q + ", 95 % interval low": -0.2, q + ", 95 % interval high": 0.5}


def test_figures_draw_truth_only_where_it_exists_and_keep_uwb_spikes_off_the_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from uwbwb.experiments.uwb_ins import figures

    n = 50
    t = np.arange(n) * 0.1
    truth = np.column_stack([np.linspace(1, 3, n), np.full(n, 2.0)])
    scored = np.arange(n) >= 5
    truth[~scored] = 0.0                                     # as compare_iasl stores epochs without truth
    uwb = truth + 0.005
    uwb[20] = [40.0, -30.0]                                  # one multipath spike
    est = {"UWB-only": Estimates(t, uwb, np.ones(n, np.int8), "UWB-only"),
           "tight": Estimates(t, truth + 0.01, np.ones(n, np.int8), "tight")}
    comp = alignment.Comparison("c", Trajectory(t, truth, name="truth"), est, {}, {"scored": scored})
    fig, (a, b) = plt.subplots(1, 2)
    figures.track(comp, ("UWB-only", "tight"), ax=a)
    line = next(ln for ln in a.lines if ln.get_label() == "truth")
    assert np.isnan(line.get_xdata()[:5]).all() and a.get_xlim()[1] < 10      # no segment from (0, 0); spike off
    assert any("1 UWB-only fixes outside" in x.get_text() for x in a.texts)
    figures.error_vs_time(comp, ("UWB-only", "tight"), ax=b, ylim_m=None)
    assert b.get_ylim()[1] < 1.0 and any("UWB-only: 1 epochs above" in x.get_text() for x in b.texts)
    assert a.get_title() and b.get_title()
    plt.close(fig)
