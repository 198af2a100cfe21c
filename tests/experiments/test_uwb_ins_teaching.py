"""Notebook 05's teaching pieces and its real-data section: exercises (the claim and its flip), the panel back end,
the fusion filters' scales, and one board of the i-ASL flight shared with notebook 06."""

import numpy as np
import pandas as pd
import pytest

from tests.fixtures import iasl as fx
import json
from pathlib import Path

from uwbwb import scoreboard as sb
from uwbwb.notebook_params import SPECS
from uwbwb.scoreboard import teaching as sbt
from uwbwb.datasets import iasl
from uwbwb.experiments.uwb_ins import exercises, panels, realdata
from uwbwb.filters import alignment, imu_calibration
from uwbwb.types import Estimates, Trajectory
from tests.test_teaching import assert_reads_predictions


def test_outage_exercise_holds_and_its_claim_can_fail():
    check = exercises.outage_loose_vs_tight(seed=0, outage_s=3.0)
    loose, tight = check.numbers["loose max in outage (m)"], check.numbers["tight max in outage (m)"]
    assert check.holds == (loose > 2.0 * tight) and check.holds
    strict = exercises.outage_loose_vs_tight(seed=0, outage_s=3.0, factor=loose / tight * 1.01)
    assert not strict.holds
    # no multipath and an outage of 2-3 epochs: the loose filter has no time to coast away on its entry velocity,
    # both stay at their ordinary centimetre error and the claim fails at the default factor
    brief = exercises.outage_loose_vs_tight(seed=0, outage_s=0.05, outlier_rate=0.0)
    b_loose, b_tight = brief.numbers["loose max in outage (m)"], brief.numbers["tight max in outage (m)"]
    assert brief.holds is False, brief
    assert b_loose <= 2.0 * b_tight and max(b_loose, b_tight) < 0.05 and b_loose < 0.1 * loose
    for c in (check, strict, brief):
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
    # without multipath the gate only rejects a few good TDoAs: the ungated RMSE is not higher, the claim fails
    assert clean.holds is False, clean
    assert clean.numbers["tight RMSE without gate (m)"] <= clean.numbers["tight RMSE with gate (m)"]
    assert_reads_predictions(clean)


def test_panel_offers_the_notebooks_outage_and_reads_the_outage():
    panel = panels.build_panel(seed=0, grade="consumer", outlier_rate=0.02, outage_s=5.0, outlier_c_m=0.1,
                               gate_prob=0.999, loose_window=5, stations_m=np.zeros((4, 3)))
    assert panel.controls["outage_s"].max == 5.0 and panel.values["outage_s"] == 5.0
    comp = panels.panel_comparison("dynamic", "consumer", 1.0, 1.0, 0.1, 0.02, 5.0, True, "tight", **panel.fixed)
    assert "max tight in outage (m)" in panels.readout(comp, "tight")
    with pytest.raises(ValueError, match="OUTAGE_S"):
        panels.build_panel(seed=0, grade="consumer", outlier_rate=0.02, outage_s=40.0, outlier_c_m=0.1,
                           gate_prob=0.999, loose_window=5, stations_m=np.zeros((4, 3)))


def test_each_filters_scales_reach_it_and_the_start_is_shared(tmp_path):
    from uwbwb.datasets import iasl

    root = tmp_path / "iasl-uwb-imu"
    root.mkdir()
    (root / "uwb.yaml").write_text(fx.YAML_TEXT)
    fx.write_scenario(root / "flight_a", rng=np.random.default_rng(8), duration_s=30.0)
    rec = iasl.load_scenario("flight_a", tmp_path)
    cal = imu_calibration.calibrate_iasl(rec)
    start = alignment.align_iasl(rec, cal, still_s=1.0, align_s=10.0)
    for name in alignment.TUNABLE + ("INS-only",):                     # (q, r) moves every tunable filter
        base = alignment.run_fusion_filter(name, start, rec, cal)[1]
        scaled = alignment.run_fusion_filter(name, start, rec, cal, scales=(10.0, 3.0))[1]
        assert base.t_s[0] == rec.ranges["tag"].t_s[start.k0]          # every filter starts where the alignment ends
        same = np.array_equal(scaled.pos_m, base.pos_m, equal_nan=True)
        assert same == (name == "INS-only"), name                     # INS-only has no knob
    with pytest.raises(ValueError, match="name must be one of"):
        alignment.run_fusion_filter("UWB-only", start, rec, cal)


def _code_cells(notebook: str) -> list[tuple[str, list]]:
    """The notebook's code cells: (source, tags)."""
    nb = json.loads((Path(__file__).parents[2] / "notebooks" / notebook).read_text(encoding="utf-8"))
    return [("".join(c["source"]), c["metadata"].get("tags", [])) for c in nb["cells"] if c["cell_type"] == "code"]


def _iasl_cell(notebook: str) -> str:
    """The code of the notebook's cell that builds its i-ASL board."""
    return next(c for c, _ in _code_cells(notebook) if "sb.score(" in c and "iasl.load_scenario(IASL_SCENARIO" in c)


def _defaults(notebook: str) -> dict:
    """The notebook's parameter defaults (its cell tagged ``parameters``: assignments only)."""
    params: dict = {}
    exec(next(c for c, tags in _code_cells(notebook) if "parameters" in tags), params)
    return params


#: Notebook 05's real-data rows and the pairs of its verdict table.
ROWS_05 = ("LS", "EKF-RF", "loose", "tight", "tight (ranges)", "INS-only")
PAIRS_05 = (("tight", "loose"), ("tight", "EKF-RF"), ("loose", "EKF-RF"), ("EKF-RF", "LS"))


def test_05_and_06_score_the_flight_on_one_board_and_print_the_same_verdicts(tmp_path):
    """Notebook 05's board (its rows, its four fusion filters) and notebook 06's (every method) of one flight give
    the same tuning, the same estimates and the same difference table; every filter is tuned on one (Q ×, R ×) grid;
    05's tables and summary rows are cells of that board."""
    for nb in ("05_uwb_ins_fusion.ipynb", "06_scoreboard.ipynb"):       # the cells build them as this test does
        assert "equal_knobs=True" in _iasl_cell(nb) and "rate_hz=RATE_HZ" in _iasl_cell(nb)
        assert any("sb.verdicts.difference_table(" in c and "seed=SEED)" in c for c, _ in _code_cells(nb))
    # at their defaults the two print one comparison: the same seed and rate (FAST: the same cap), and 05's fusion
    # settings are the ones 06's board builds its filters with
    p05, p06 = _defaults("05_uwb_ins_fusion.ipynb"), _defaults("06_scoreboard.ipynb")
    assert (p05["SEED"], p05["RATE_HZ"]) == (p06["SEED"], p06["RATE_HZ"])
    assert SPECS["05_uwb_ins_fusion"]["RATE_HZ"].fast_cap == SPECS["06_scoreboard"]["RATE_HZ"].fast_cap
    assert alignment.FusionSettings(outlier_c_m=p05["OUTLIER_C_M"], gate_prob=p05["GATE_PROB"],
                                    loose_window=p05["LOOSE_WINDOW"]) == alignment.FusionSettings()
    assert "ins_settings=SETTINGS" in _iasl_cell("05_uwb_ins_fusion.ipynb")
    assert "ins_settings" not in _iasl_cell("06_scoreboard.ipynb")
    # 150 s: long enough that the IMU filters' pairs get ten blocks and a verdict (30 s: "no verdict" on both sides)
    fx.write_dataset(tmp_path / "iasl-uwb-imu", rng=np.random.default_rng(8), duration_s=150.0)
    cal, test = iasl.load_scenario("scenario1", tmp_path), iasl.load_scenario("scenario2", tmp_path)
    est05 = [e for e in sb.default_estimators(fast=True, ins_kinds=("loose", "tight", "tight (ranges)", "INS-only"),
                                              ins_settings=alignment.FusionSettings(), equal_knobs=True)
             if e.name in ROWS_05]
    b05 = sb.score(test, cal, estimators=est05, rate_hz=5.0, fast=True)
    b06 = sb.score(test, cal, estimators=sb.default_estimators(fast=True, equal_knobs=True), rate_hz=5.0, fast=True)
    v05, v06 = (sb.verdicts.difference_table({test.label: b}, PAIRS_05, seed=0) for b in (b05, b06))
    assert len(v05) == len(PAIRS_05)
    pd.testing.assert_frame_equal(v05, v06)                             # intervals and verdict strings
    # 06's own table (its pairs, its order) prints 05's rows for the pairs both notebooks show
    t06 = sb.verdicts.difference_table({test.label: b06}, sbt.PAIRS, seed=0).set_index(["A", "B"])
    shared = [p for p in PAIRS_05 if p in sbt.PAIRS]
    assert set(shared) >= {("tight", "loose"), ("tight", "EKF-RF")}
    assert not v05["verdict"].str.startswith("no ").any()             # each pair compared by a verdict, not a blank
    pd.testing.assert_frame_equal(v05.set_index(["A", "B"]).loc[shared], t06.loc[shared])
    for m in ("EKF-RF", "loose", "tight"):
        p05, p06 = b05.calibration.params(m), b06.calibration.params(m)
        assert p05["grid"] == p06["grid"] == sb.estimators.INS_GRID_FAST      # one grid of (Q ×, R ×) for all
        assert (p05["q_scale"], p05["r_scale"]) == (p06["q_scale"], p06["r_scale"])
        assert "R ×" in b05.table().set_index("method").loc[m, "tuning_pick"]
    # 05's tables read that board: the common-epoch RMSE is the board's, each summary row a cell of a table shown
    t = realdata.common_table(b05)
    board_t = b05.table().set_index("method")
    np.testing.assert_array_equal(t["horizontal RMSE (m)"], board_t.loc[t.index, "rmse_common_m"])
    rows = {r["quantity"]: r for r in realdata.summary_rows(b05, cal_label="scenario1", cal_data=cal.label, rate_hz=5.0,
                                                            verdicts=v05)}
    rmse = {k: r["value"] for k, r in rows.items() if r["unit"] == "m" and "RMSE" in k}
    assert rmse == {f"{c.split(' (')[0]} {m}, common epochs (calibrated on scenario1)": t.loc[m, c] for m in t.index
                    for c in ("horizontal RMSE (m)", "vertical RMSE (m)", "3-D RMSE (m)") if np.isfinite(t.loc[m, c])}
    q = [k for k in rows if k.startswith("EKF-RF R multiplier")]
    assert len(q) == 1 and rows[q[0]]["value"] == b05.calibration.params("EKF-RF")["r_scale"] and rows[q[0]]["data"] == cal.label
    for _, r in v05.iterrows():       # an edge-bound verdict (the table's) is said in the row's quantity
        edge = f"; {sb.verdicts.EDGE_BOUND_LABEL}" if r["verdict"].startswith("edge-bound") else ""
        key = f"horizontal RMSE difference {r['A']} − {r['B']} (scoreboard, 5 Hz{edge})"
        assert rows[key]["value"] == r["A − B (mm)"]
        if np.isfinite(r["95 % low (mm)"]):
            assert rows[key + ", 95 % interval low"]["value"] == r["95 % low (mm)"]
    comp = realdata.board_comparison(b05)
    assert list(comp.estimates) == list(ROWS_05) and b05.entry("INS-only", "tag").bound is None
    for e in b05.ran("tag"):                                            # the board's errors, epoch for epoch
        np.testing.assert_array_equal(comp.errors(e.method)[e.scoring], e.error_m[e.scoring])
    assert comp.rejected["eq4"] == int(np.sum(b05.entry("tight", "tag").estimates.info["n_outliers"]))
    with pytest.raises(ValueError, match="kind"):
        sb.estimators.UwbInsFilter("EKF + gate")


def test_clock_rows_are_the_cells_of_the_clock_table():
    """The IMU clock's rows: the offset, and per IMU filter but INS-only the change (ranges clock − motion capture)
    with its interval ends, read from the board's difference table of ``m (ranges clock)`` against ``m``."""
    clock = pd.DataFrame([{"A": f"{m} (ranges clock)", "B": m, "A − B (mm)": c, "95 % low (mm)": lo,
                           "95 % high (mm)": hi, "verdict": v} for m, (c, lo, hi, v) in
                          {"loose": (2.5, np.nan, np.nan, "edge-bound: not significant at the picks (loose: Q × 100)"),
                           "tight": (0.1, -0.2, 0.5, "not significant"),
                           "INS-only": (9.0, 1.0, 20.0, "not significant")}.items()])
    rows = realdata._clock_rows(clock, -40.0, "x")
    assert [r["unit"] for r in rows] == ["ms", "mm", "mm", "mm", "mm"] and rows[0]["value"] == -40.0
    q = "horizontal RMSE change of tight with the IMU clock from the ranges"
    assert {r["quantity"]: r["value"] for r in rows if r["quantity"].startswith(q)} == {
        q: 0.1, q + ", 95 % interval low": -0.2, q + ", 95 % interval high": 0.5}
    assert not any("INS-only" in r["quantity"] for r in rows)
    # an edge-bound verdict is said in the quantity, the others are not
    assert [r["quantity"] for r in rows if "edge-bound" in r["quantity"]] == [
        "horizontal RMSE change of loose with the IMU clock from the ranges (edge-bound at the tuning picks)"]


def test_figures_draw_truth_only_where_it_exists_and_keep_uwb_spikes_off_the_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from uwbwb.experiments.uwb_ins import figures

    n = 50
    t = np.arange(n) * 0.1
    truth = np.column_stack([np.linspace(1, 3, n), np.full(n, 2.0)])
    scored = np.arange(n) >= 5
    truth[~scored] = 0.0                                     # as board_comparison stores epochs without truth
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
    figures.error_vs_time(comp, ("UWB-only", "tight"), ax=b)
    assert b.get_ylim()[1] < 1.0 and any("UWB-only: 1 epochs above" in x.get_text() for x in b.texts)
    assert a.get_title() and b.get_title()
    plt.close(fig)
