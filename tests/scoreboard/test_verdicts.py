"""Verdicts follow from the intervals: each flips when a value crosses its threshold, in the tables."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from uwbwb.scoreboard import calibrate, score
from uwbwb.scoreboard import synthetic as syn
from uwbwb.scoreboard.estimators import CalibratedLs, ExternalEstimates
from uwbwb.metrics.errors import BLOCK_LAG_FACTOR, MIN_BLOCKS, block_ids, block_length
from uwbwb.scoreboard.verdicts import DIFFERENCE_COLUMNS, difference_table, own_bound_table, pair_rng, placement_table
from uwbwb.types import Trajectory


def _table_board(rows):
    """A stand-in board whose table holds the given (method, ratio, se) rows."""
    import pandas as pd

    df = pd.DataFrame([{"method": m, "n_scored": 5, "rmse_over_common": r, "rmse_over_common_se": se}
                       for m, r, se in rows])
    return SimpleNamespace(table=lambda: df)


@pytest.mark.parametrize("ratio, se, expected", [(1.30, 0.10, "above the bound"), (1.15, 0.10, "on the bound"),
                                                 (0.85, 0.10, "on the bound"), (0.70, 0.10, "below the bound"),
                                                 (float("nan"), 0.1, "no common bound on its epochs"),
                                                 (3.0, float("nan"), "no verdict (fewer than 10 blocks)")])
def test_placement_flips_at_two_standard_errors(ratio, se, expected):
    t = placement_table({"rec": _table_board([("M", ratio, se)])})
    assert t.loc[0, "verdict"] == expected and t.loc[0, "method"] == "M" and t.loc[0, "recording"] == "rec"


@pytest.mark.parametrize("ratio, se, measured, measured_se, expected", [
    (0.95, 0.05, 1.0, 0.05, "not below its own bound"),
    (0.85, 0.05, 1.0, 0.05, "below its own bound; not below it at the measured noise"),
    (0.85, 0.05, 0.91, 0.05, "below its own bound; not below it at the measured noise"),
    (0.85, 0.05, 0.89, 0.05, "below its own bound, also at the measured noise: cause not measured"),
    (0.85, 0.05, float("nan"), float("nan"), "below its own bound; noise not measured: cause not measured"),
    (0.50, float("nan"), 0.6, float("nan"), "no verdict (fewer than 10 blocks)")])
def test_own_bound_verdict_flips_at_two_standard_errors_and_names_no_cause_it_did_not_measure(
        ratio, se, measured, measured_se, expected):
    import pandas as pd

    df = pd.DataFrame([{"method": "M", "n_scored": 5, "rmse_over_bound": ratio, "rmse_over_bound_se": se,
                        "rmse_over_bound_measured": measured, "rmse_over_bound_measured_se": measured_se,
                        "bias_share": 0.1}])
    t = own_bound_table({"rec": SimpleNamespace(table=lambda: df)})
    assert t.loc[0, "verdict"] == expected and t.loc[0, "bias share"] == 0.1


@pytest.mark.parametrize("ratio, se, where", [(1.30, 0.10, "above"), (1.15, 0.10, "on"), (0.70, 0.10, "below"),
                                              (0.85, 0.10, "on")])
def test_placement_and_own_bound_decide_through_the_one_interval_rule(monkeypatch, ratio, se, where):
    """Both tables hand the interval ratio ± 2 se to metrics.interval_side (null 1) and take its side: a stand-in
    rule that answers the opposite side turns their verdicts over."""
    import pandas as pd

    from uwbwb.metrics import interval_side
    from uwbwb.scoreboard import verdicts

    df = pd.DataFrame([{"method": "M", "n_scored": 5, "rmse_over_common": ratio, "rmse_over_common_se": se,
                        "rmse_over_bound": ratio, "rmse_over_bound_se": se, "bias_share": 0.0}])
    boards = {"rec": SimpleNamespace(table=lambda: df)}
    words = {"above": "above the bound", "below": "below the bound", "on": "on the bound"}
    calls = []

    def spy(lo, hi, null=0.0):
        calls.append((lo, hi, null))
        return interval_side(lo, hi, null)

    monkeypatch.setattr(verdicts, "interval_side", spy)
    assert placement_table(boards).loc[0, "verdict"] == words[where]
    assert calls == [(pytest.approx(ratio - 2 * se), pytest.approx(ratio + 2 * se), 1.0)]
    assert own_bound_table(boards).loc[0, "verdict"].startswith("below" if where == "below" else "not below")
    flipped = {"above": "below", "below": "above", "contains": "contains", "none": "none"}
    monkeypatch.setattr(verdicts, "interval_side", lambda lo, hi, null=0.0: flipped[interval_side(lo, hi, null)])
    assert placement_table(boards).loc[0, "verdict"] == words[{"above": "below", "below": "above"}.get(where, where)]


def _board(offset_m):
    """LS against an outside method whose estimates are the truth plus a known constant offset."""
    cfg = syn.SyntheticConfig(duration_s=20.0)
    rec = syn.simulate(cfg, rng=np.random.default_rng(4))
    tr = rec.truth["tag"]
    ext = ExternalEstimates("shifted truth", {"tag": Trajectory(tr.t_s, tr.pos_m + [offset_m, 0.0, 0.0])})
    ests = [CalibratedLs(), ext]
    return score(rec, rec, estimators=ests, rate_hz=None,
                 calibration=syn.exact_calibration(cfg, calibrate(rec, ests, rate_hz=None, dim=2)))


@pytest.mark.parametrize("offset_m, verdict", [(0.005, "b"), (0.2, "a")])
def test_the_difference_table_on_a_board_follows_the_errors(offset_m, verdict):
    """An outside method 5 mm off beats LS (σ 5 cm); 20 cm off it loses — and the interval says so, in the
    table's verdict column."""
    b = _board(offset_m)
    ext = "shifted truth (external)"
    t = difference_table({"syn": b}, [("LS", ext), ("LS", "not on this board")], seed=0)
    assert len(t) == 1                                    # a pair that did not run has no row
    f = t.iloc[0]
    assert f["epochs"] == len(b.entry("LS", "tag").estimates)
    assert f["verdict"] == ("LS more accurate" if verdict == "a" else f"{ext} more accurate")
    assert f["95 % low (mm)"] <= f["A − B (mm)"] <= f["95 % high (mm)"]
    assert f["A − B (mm)"] == pytest.approx(1000 * (f["RMSE A (m)"] - f["RMSE B (m)"]))
    assert (f["95 % high (mm)"] < 0) == (verdict == "a") and (f["95 % low (mm)"] > 0) == (verdict == "b")


def test_block_length_follows_the_autocorrelation():
    rng = np.random.default_rng(1)
    white = rng.normal(size=2000)
    ar = np.zeros(2000)
    for k in range(1, ar.size):
        ar[k] = 0.95 * ar[k - 1] + rng.normal()
    assert block_length(white) == BLOCK_LAG_FACTOR
    # AR(1) with φ = 0.95: ACF φ^k < 0.05 from k ≈ 59
    assert 30 * BLOCK_LAG_FACTOR < block_length(ar) < 120 * BLOCK_LAG_FACTOR


def _fake_board(err_a, err_b):
    n = err_a.size
    import pandas as pd

    ent = {m: SimpleNamespace(skipped=None, scored=np.ones(n, bool), error_m=e) for m, e in (("A", err_a), ("B", err_b))}
    table = pd.DataFrame({"method": ["A", "B"], "n_scored": [n, n]})
    return SimpleNamespace(tags=("t",), mode="FAST", entry=lambda m, tag: ent[m], table=lambda: table)


@pytest.mark.parametrize("n, verdict", [(2 * (MIN_BLOCKS - 1), "none"), (400, "a")])
def test_difference_verdict_needs_min_blocks(n, verdict):
    """The same clear difference (A 3 cm, B 10 cm, white errors: blocks of 2) has no verdict with fewer
    than MIN_BLOCKS blocks and a verdict with enough."""
    rng = np.random.default_rng(2)
    a, b = np.abs(rng.normal(0.03, 0.005, n)), np.abs(rng.normal(0.10, 0.005, n))
    row = difference_table({"r": _fake_board(a, b)}, [("A", "B")], seed=0).iloc[0]
    assert (row["blocks"] >= MIN_BLOCKS) == (verdict != "none")
    assert row["verdict"] == ("A more accurate" if verdict == "a" else f"no verdict (fewer than {MIN_BLOCKS} blocks)")


def test_external_rows_are_inputs_in_the_summary(tmp_path):
    """An outside method's numbers are not reproduced here: kind ``input``, data marked external."""
    from uwbwb.metrics import Summary

    b = _board(0.005)
    assert b.external == ("shifted truth (external)",)
    s = Summary("06_scoreboard", fast=True)
    b.to_summary(s)
    df = s.frame()
    ext = df[df["quantity"].str.contains("(external)", regex=False)]
    own = df[~df["quantity"].str.contains("(external)", regex=False)]
    assert len(ext) and set(ext["kind"]) == {"input"} and ext["data"].str.endswith("(external estimates)").all()
    assert len(own) and set(own["kind"]) == {"reproduced"} and not own["data"].str.contains("external").any()
    csv = b.write(tmp_path, figure=False)["csv"].read_text()
    assert "shifted truth (external)" in csv and ",input" in csv and ",reproduced" in csv


def test_no_common_epochs_give_a_row_that_says_so_not_an_error():
    """Methods that never covered the same epoch: no interval, no verdict, and the table says why."""
    n = 50
    ent = {"A": SimpleNamespace(skipped=None, scored=np.arange(n) < 25, error_m=np.ones(n)),
           "B": SimpleNamespace(skipped=None, scored=np.arange(n) >= 25, error_m=np.ones(n))}
    import pandas as pd

    board = SimpleNamespace(tags=("t",), mode="FAST", entry=lambda m, tag: ent[m],
                            table=lambda: pd.DataFrame({"method": ["A", "B"], "n_scored": [25, 25]}))
    row = difference_table({"r": board}, [("A", "B")], seed=0).iloc[0]
    assert row["epochs"] == 0 and np.isnan(row["95 % low (mm)"]) and row["verdict"] == "no epochs both covered"


def test_a_pairs_interval_does_not_depend_on_what_else_the_table_holds():
    """05 and 06 put the same flight's tight − loose in tables of different pairs and boards: one evaluation, one
    interval — the bootstrap's draws come from the seed and the pair's names only."""
    rng = np.random.default_rng(4)
    n = 600
    a, b, c = (np.abs(rng.normal(m, 0.01, n)) for m in (0.050, 0.052, 0.070))
    ent = {m: SimpleNamespace(skipped=None, scored=np.ones(n, bool), error_m=e) for m, e in (("A", a), ("B", b), ("C", c))}
    import pandas as pd

    board = SimpleNamespace(tags=("t",), mode="FAST", entry=lambda m, tag: ent[m],
                            table=lambda: pd.DataFrame({"method": ["A", "B", "C"], "n_scored": [n, n, n]}))
    alone = difference_table({"flight": board}, [("A", "B")], seed=0).iloc[0]
    crowded = difference_table({"other": board, "flight": board}, [("C", "B"), ("A", "C"), ("A", "B")], seed=0)
    row = crowded[(crowded["recording"] == "flight") & (crowded["A"] == "A") & (crowded["B"] == "B")].iloc[0]
    assert (row["95 % low (mm)"], row["95 % high (mm)"]) == (alone["95 % low (mm)"], alone["95 % high (mm)"])
    other = difference_table({"flight": board}, [("A", "B")], seed=1).iloc[0]
    assert other["95 % low (mm)"] != alone["95 % low (mm)"]                # the seed still matters


def test_the_difference_table_gives_the_ratio_and_its_interval_from_the_same_replicates():
    """A / B is RMSE A / RMSE B on the epochs both covered, and its interval is the one rule's (the same draws as the
    difference): it lies below 1 exactly where the difference's lies below 0, on either side of 1 where that holds 0."""
    from uwbwb.metrics import block_bootstrap_difference

    rng = np.random.default_rng(3)
    n = 400
    for scale, side in ((0.5, "below"), (1.0, "contains")):
        b = np.abs(rng.normal(0.10, 0.02, n))
        a = scale * b + (0 if scale < 1 else 1e-3 * rng.normal(0, 1, n))
        row = difference_table({"r": _fake_board(np.abs(a), b)}, [("A", "B")], seed=0).iloc[0]
        d = block_bootstrap_difference(np.abs(a), b, rng=pair_rng(0, "r", "A", "B"))
        assert row["A / B"] == pytest.approx(d["rmse_a_m"] / d["rmse_b_m"])
        assert (row["A / B 95 % low"], row["A / B 95 % high"]) == (d["ratio_lo"], d["ratio_hi"])
        assert (row["A / B 95 % high"] < 1) == (side == "below") == (row["95 % high (mm)"] < 0)
        assert (row["A / B 95 % low"] <= 1 <= row["A / B 95 % high"]) == (side == "contains")


def test_a_difference_whose_tuning_pick_lies_on_a_grid_edge_is_edge_bound(monkeypatch):
    """The same rule as notebook 05's ablation: a verdict at a pick on its grid's edge says so (and names the pick);
    a pick inside the grid leaves the verdict bare."""
    b = _board(0.2)
    ext = "shifted truth (external)"
    bare = difference_table({"syn": b}, [("LS", ext)], seed=0).loc[0, "verdict"]
    assert bare == "LS more accurate"
    table = b.table()
    for edge, expected in ((False, bare), (True, f"edge-bound: {bare} at the picks (LS: Q × 3: on the grid's edge)")):
        t = table.copy()
        t["grid_edge"] = [edge if m == "LS" else None for m in t["method"]]
        t["tuning_pick"] = ["Q × 3: on the grid's edge" if m == "LS" else "—" for m in t["method"]]
        monkeypatch.setattr(type(b), "table", lambda self, t=t: t)
        assert difference_table({"syn": b}, [("LS", ext)], seed=0).loc[0, "verdict"] == expected


def test_an_edge_bound_summary_row_reads_the_same_in_every_notebook():
    """Notebook 05's real-data rows and the Hanyang ratio rows (notebooks 02, 03, 06) add one wording to the quantity
    of a row whose verdict is edge-bound, :data:`~uwbwb.scoreboard.verdicts.EDGE_BOUND_LABEL`."""
    import pandas as pd

    from uwbwb.experiments.hanyang import sections
    from uwbwb.experiments.uwb_ins import realdata
    from uwbwb.scoreboard import verdicts

    v = "edge-bound: A more accurate at the picks (A: σ_w 1: on the grid's edge)"
    clock = pd.DataFrame([{"A": "loose (ranges clock)", "B": "loose", "A − B (mm)": 1.0, "95 % low (mm)": 0.5,
                           "95 % high (mm)": 2.0, "verdict": v}])
    q05 = realdata._clock_rows(clock, 0.0, "x")[1]["quantity"]
    hanyang = sections._ratio_rows("ratio A", {"A / B": 1.1, "verdict": v}, "x")[0]["quantity"]
    assert q05.endswith(f" ({verdicts.EDGE_BOUND_LABEL})") and hanyang.endswith(f"; {verdicts.EDGE_BOUND_LABEL})")
    assert verdicts.edge_bound(verdicts.EDGE_BOUND_LABEL)


def test_the_placement_table_shows_its_blocks_and_says_why_a_difference_has_others():
    """Each interval's blocks follow the series it is on: the placement's one method's squared error on its own
    epochs (the board's ``rmse_over_common_blocks``, the count its standard error is formed from), a difference's the
    paired difference on the epochs both covered. Both tables show their count, and the placement's rule says why
    the two differ."""
    from uwbwb.scoreboard.verdicts import PLACEMENT_RULE, block_se_ratio

    b = _board(0.2)
    place = placement_table({"syn": b}).set_index("method")
    e = b.entry("LS", "tag")
    tr = e.trace_m2("common")[e.scored]
    have = np.isfinite(tr)
    se, nb = block_se_ratio([e.error_m[e.scored][have] ** 2], [tr[have]])
    assert place.loc["LS", "blocks"] == nb == b.table().set_index("method").loc["LS", "rmse_over_common_blocks"]
    assert place.loc["LS", "standard error"] == se
    diff = difference_table({"syn": b}, [("LS", "shifted truth (external)")], seed=0).iloc[0]
    sq = (e.error_m[e.scored] ** 2 - b.entry("shifted truth (external)", "tag").error_m[e.scored] ** 2)
    assert diff["blocks"] == block_ids([sq])[1]        # the same epochs, its own series
    assert "paired difference" in PLACEMENT_RULE and place.loc["LS", "rule"] == PLACEMENT_RULE


def test_a_difference_table_with_no_pair_that_ran_keeps_its_columns():
    """No board (a recording absent): the table is empty but has its header, so a notebook can select columns."""
    t = difference_table({}, [("A", "B")], seed=0)
    assert t.empty and list(t.columns) == list(DIFFERENCE_COLUMNS)
    assert list(t.drop(columns="rule").columns) == [c for c in DIFFERENCE_COLUMNS if c != "rule"]
