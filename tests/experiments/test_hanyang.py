"""The Hanyang dynamic study: reproduction of the authors' numbers, the external rows, the boards, the verdicts."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.fixtures import hanyang as fx
from uwbwb.datasets import hanyang_dynamic as hd
from uwbwb.errors import DataFormatError
from uwbwb.experiments.hanyang import authors, estimators, sections, study
from uwbwb.scoreboard.interface import GEOMETRY, MAX_TDOA_OVER_RANGES
from uwbwb.scoreboard.sources import external_estimators
from uwbwb.scoreboard.verdicts import DIFFERENCE_RULE, EDGE_BOUND_LABEL
from uwbwb.types import EstimateStatus, Estimates


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    data = tmp_path_factory.mktemp("hy") / "data"
    rng = np.random.default_rng(8)
    cases = fx.write_dynamic_tree(data / "hanyang-outdoor-uwb", rng=rng)
    fx.write_dataset(data / "hanyang-outdoor-uwb", rng=rng, distances_m=(2, 4, 10, 20))
    return data, cases


def test_reproduction_matches_an_independent_implementation_of_the_authors_definition(tree):
    data, cases = tree
    for c in cases:
        df = authors.reproduce_authors(c.name, data).set_index(["method", "metric"])
        for method, v in c.rmsd.items():
            assert df.loc[(method, "RMSE 2-D"), "reproduced_m"] == pytest.approx(v["rmse_2d_m"], abs=1e-6)
            assert df.loc[(method, "RMSE 3-D"), "reproduced_m"] == pytest.approx(v["rmse_m"], abs=1e-6)
            assert df.loc[(method, "RMSE 2-D"), "published_m"] == pytest.approx(v["rmse_2d_m"], abs=1e-12)
        assert (df["verdict"] == "agree").all()


@pytest.mark.parametrize("shift_m, verdict", [(0.009, "agree"), (-0.009, "agree"), (0.011, "DISAGREE"),
                                              (np.nan, "no published value")])
def test_reproduction_verdict_flips_at_the_tolerance(tree, tmp_path, shift_m, verdict):
    """The published RMSE_2d of the LS moved by ``shift_m``: within REPRO_TOL_M it agrees, beyond it it does not."""
    import shutil

    data, cases = tree
    other = tmp_path / "data"
    shutil.copytree(data, other)
    path = other / "hanyang-outdoor-uwb" / "Dynamic_measurements" / cases[0].name / "RMSD_results.txt"
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("LS RMSE_2d")]
    if np.isfinite(shift_m):
        lines.append(f"LS RMSE_2d: {cases[0].rmsd['LS']['rmse_2d_m'] + shift_m:.9f}")
    path.write_text("\n".join(lines) + "\n")
    df = authors.reproduce_authors(cases[0].name, other).set_index(["method", "metric"])
    assert authors.REPRO_TOL_M == 0.01 and df.loc[("LS", "RMSE 2-D"), "verdict"] == verdict
    assert df.loc[("LS", "RMSE 3-D"), "verdict"] == "agree"


def test_rmsd_file_parsing(tmp_path):
    p = tmp_path / "RMSD_results.txt"
    p.write_text("LS RMSE: 1.5 m\nLS RMSE_2d: 1.0\nInsufficient data for ESKF RMSE calculation\nESKF RMSE_2d: 0.9\n")
    assert authors.read_rmsd_results(p) == {"LS": {"rmse_m": 1.5, "rmse_2d_m": 1.0}, "ESKF": {"rmse_2d_m": 0.9}}
    p.write_text("LS RMSE: 1.5 m\nLS RMSE 2d = 1.0\n")
    with pytest.raises(DataFormatError) as err:
        authors.read_rmsd_results(p)
    assert err.value.line == 2


@pytest.mark.parametrize("text, message, line", [("LS RMSE: -1.5 m\n", "non-negative number", 1),
                                                 ("LS RMSE: nan m\n", "non-negative number", 1),
                                                 ("LS RMSE: 1.5 m\nLS RMSE: 1.6 m\n", "given twice", 2)])
def test_rmsd_values_that_cannot_be_rmses_are_refused_naming_the_line(tmp_path, text, message, line):
    p = tmp_path / "RMSD_results.txt"
    p.write_text(text)
    with pytest.raises(DataFormatError, match=message) as err:
        authors.read_rmsd_results(p)
    assert err.value.line == line and str(p) in str(err.value)


def test_rmsd_file_that_is_not_text_or_not_a_file_is_a_format_error(tmp_path):
    p = tmp_path / "RMSD_results.txt"
    p.write_bytes(b"LS RMSE: \xff\xfe 1.5 m\n")
    with pytest.raises(DataFormatError, match="UTF-8"):
        authors.read_rmsd_results(p)
    d = tmp_path / "folder"
    d.mkdir()
    with pytest.raises(DataFormatError, match="found a folder"):
        authors.read_rmsd_results(d)


def test_authors_window_follows_their_rules(tree):
    data, cases = tree
    rec = hd.load_dynamic_case(cases[0].name, data, register=False)
    t0, t1 = authors.authors_window(rec.truth["tag"], "A")
    p = rec.truth["tag"].interp([t0, t1])
    assert p[0, 0] > 49.3 and p[0, 1] > -5 and p[1, 0] <= 12 and p[1, 1] > 3.4
    with pytest.raises(ValueError, match="never meets the start rule"):
        authors.authors_window(rec.truth["tag"].select(slice(0, 10)), "A")


def test_tuning_case_is_never_the_scored_one():
    cases = ["LOS/Trajectory_A/Case_1", "LOS/Trajectory_B/Case_3", "NLOS/Trajectory_A/Case_1",
             "NLOS/Trajectory_B/Case_3"]
    assert study.tuning_case(cases[0], cases) == cases[1]
    assert study.tuning_case(cases[3], cases) == cases[2]
    assert study.tuning_case(cases[0], cases[:1] + cases[2:3]) == cases[2]
    with pytest.raises(ValueError, match="not allowed"):
        study.tuning_case(cases[0], cases[:1])


def test_external_rows_are_interpolated_onto_the_board_epochs_without_extrapolation(tree):
    data, cases = tree
    rec = hd.load_dynamic_case(cases[0].name, data)
    t = np.array([1.0, 1.1, 1.2, 2.0, 2.1])
    est = Estimates(t, np.column_stack([t, 2 * t, np.ones(5)]), np.zeros(5, np.int8), "LS")
    from dataclasses import replace

    from uwbwb.scoreboard.protocol import fit_calibration
    rec = replace(rec, meta={**rec.meta, "authors_estimates": {"LS": est}})
    cal = fit_calibration(rec, dim=2)
    log = rec.ranges["tag"]
    theirs, eskf = external_estimators(rec, ("LS", "ESKF"))  # the case holds no ESKF here: a row that says so
    assert theirs.name == "authors LS (external)" and theirs.external
    assert eskf.applies(rec, "tag", cal) == "no outside estimates for tag 'tag'"
    assert external_estimators(replace(rec, meta={k: v for k, v in rec.meta.items() if k != "authors_estimates"}),
                               ("LS", "ESKF")) == []        # not a Hanyang case: no authors' rows at all
    out = theirs.estimate(rec, "tag", cal)
    assert np.array_equal(out.t_s, log.t_s)
    inside = (log.t_s >= 1.0) & (log.t_s <= 1.2)
    np.testing.assert_allclose(out.pos_m[inside], np.column_stack([log.t_s[inside], 2 * log.t_s[inside]]))
    gap = (log.t_s > 1.2) & (log.t_s < 2.0)                 # 0.8 s between two outputs: no estimate
    assert gap.any() and np.all(out.status[gap] == EstimateStatus.NO_ESTIMATE)
    assert np.all(out.status[log.t_s > 2.1] == EstimateStatus.NO_ESTIMATE)


def test_the_ratio_interval_of_the_one_block_bootstrap_brackets_the_truth():
    from uwbwb.metrics import block_bootstrap_difference

    rng = np.random.default_rng(0)
    e = np.abs(rng.normal(0, 1, 400))
    same = block_bootstrap_difference(e, e * 1.0, rng=np.random.default_rng(1))
    assert same["ratio_lo"] == pytest.approx(1.0) and same["ratio_hi"] == pytest.approx(1.0)
    half = block_bootstrap_difference(0.5 * e + 0.05 * np.abs(rng.normal(0, 1, 400)), e, rng=np.random.default_rng(1))
    assert half["ratio_hi"] < 1.0 and half["ratio_lo"] > 0.4
    assert np.isnan(block_bootstrap_difference(e[:10], e[:10], rng=np.random.default_rng(1))["ratio_lo"])


def test_authors_front_end_gates_jumps_and_holds_ranges():
    t = 0.1 * np.arange(12)
    r = np.full((12, 2), np.nan)
    r[:, 0] = [10.0, 10.1, 13.0, 13.0, 13.0, 13.0, 13.0, 13.1, np.nan, np.nan, np.nan, np.nan]
    r[::3, 1] = 5.0
    out, rep = authors.authors_front_end(t, r)
    # four jumps rejected (held at 10.1 within 0.3 s), the fifth accepted and kept
    np.testing.assert_allclose(out[:, 0], [10.0, 10.1, 10.1, 10.1, 10.1, np.nan, 13.0, 13.1, 13.1, 13.1, 13.1, np.nan])
    np.testing.assert_allclose(out[:, 1], np.where(np.arange(12) < 12, 5.0, np.nan))
    assert rep["n_rejected"].sum() == 4 and rep["n_rejected"][2:6].tolist() == [1, 1, 1, 1]
    assert rep["n_held"].sum() == 3 + 3 + 8
    out2, rep2 = authors.authors_front_end(t, r, jump_m=5.0)
    assert rep2["n_rejected"].sum() == 0 and out2[2, 0] == 13.0


def test_static_model_is_fitted_from_the_static_files(tree):
    data, _ = tree
    m = estimators.static_range_model("LOS", data)
    assert m.bias_m == pytest.approx(0.22, abs=0.05) and m.scale == pytest.approx(1.0, abs=0.01)
    np.testing.assert_allclose(m.correct(m.scale * 10.0 + m.bias_m), 10.0)


def test_case_board_scores_ours_and_theirs_on_the_same_epochs(tree):
    data, cases = tree
    case = cases[2].name                                  # NLOS A, tuned on NLOS B
    tune = study.tuning_case(case, [c.name for c in cases])
    assert tune == cases[3].name
    est = [e for e in study.study_estimators(fast=True) if e.name in
           ("raw LS", "LS", "EKF-RF ranges", "NLS residual pruning")]
    board = study.case_board(case, tune, data, fast=True, estimators=est, authors=("LS",))
    assert board.label == f"hanyang-outdoor-uwb/{case}" and tune in board.calibration.source
    assert board.calibration.dim == 2
    # the tag height is the tuning case's, given to the scored case
    assert board.calibration.tag_height_m["tag"] == pytest.approx(1.0 + 0.0, abs=0.1)
    df = board.table().set_index("method")
    assert (df["coverage"].between(0, 1)).all() and df.loc["authors LS (external)", "n_scored"] > 0
    scored = hd.load_dynamic_case(case, data)
    t0, t1 = authors.authors_window(scored.truth["tag"], scored.meta["trajectory"])
    e = board.entry("raw LS", "tag")
    assert e.estimates.t_s[0] >= t0 and e.estimates.t_s[-1] < min(t1, t0 + study.FAST_SPAN_S)
    ratios = study.ratio_table({case: board})
    assert set(ratios["A"]) == {"raw LS", "LS", "EKF-RF ranges", "NLS residual pruning"}
    assert set(ratios["B"]) == {"authors LS (external)"} and ratios["best"].sum() == 1 and (ratios["A / B"] > 0).all()
    with pytest.raises(ValueError, match="not allowed"):
        study.case_board(case, case, data, fast=True, estimators=est)


def test_residual_pruning_on_the_board_starts_from_the_nls_lines(tree):
    data, cases = tree
    case, tune = cases[2].name, cases[3].name
    nls, pruned = [e for e in study.study_estimators(fast=True) if e.name in ("NLS", "NLS residual pruning")]
    assert pruned.fits is nls.fits                        # the board's NLS row and residual pruning share the lines
    shared = study.case_board(case, tune, data, fast=True, estimators=[nls, pruned], authors=())
    alone = [type(nls)(windows_s=nls.windows_s), estimators.PrunedNls(windows_s=pruned.windows_s)]
    apart = study.case_board(case, tune, data, fast=True, estimators=alone, authors=())
    for m in ("NLS", "NLS residual pruning"):
        np.testing.assert_array_equal(shared.entry(m, "tag").estimates.pos_m, apart.entry(m, "tag").estimates.pos_m)
    assert len(nls.fits) < len(alone[0].fits) + len(alone[1].fits)        # windows both fit were solved once


# ------------------------------------------------------------------ notebook sections

def test_sections_say_why_they_did_not_run(tmp_path):
    from uwbwb.errors import DataNotFoundError
    from uwbwb.experiments.hanyang import sections

    assert "not found" in sections.scoreboard_section(None, tmp_path, fast=True).absent
    root = tmp_path / "hanyang-outdoor-uwb"
    fx.write_dataset(root, rng=np.random.default_rng(1))
    assert "no Dynamic_measurements" in sections.pruning_section(None, tmp_path, fast=True).absent
    fx.write_dynamic_tree(root, rng=np.random.default_rng(1), cases=fx.DYNAMIC_CASES[:1], speed_mps=8.0)
    assert "one dynamic case" in sections.motion_section(None, tmp_path, fast=True).absent
    fx.write_dynamic_tree(root, rng=np.random.default_rng(1), cases=fx.DYNAMIC_CASES[1:2], speed_mps=8.0)
    with pytest.raises(DataNotFoundError, match="LOS/Trajectory_B/Case_4"):
        sections.pruning_section("NLOS/Trajectory_A/Case_9", tmp_path, fast=True)


def test_sections_run_on_a_generated_tree_and_record_their_rows(tree):
    import uwbwb as uw
    from uwbwb.experiments.hanyang import sections

    data, cases = tree
    summary = uw.metrics.Summary("06_scoreboard", fast=True)
    sec = sections.scoreboard_section(None, data, fast=True)
    sec.record(summary)
    assert sec.absent is None and list(sec.boards) == [cases[0].name]           # FAST: one case
    assert set(sec.tables["reproduction"]["verdict"]) == {"agree"}
    label = f"hanyang-outdoor-uwb/{cases[0].name}"
    assert {r["data"] for r in summary.frame().to_dict("records")} == {label, label + sections.EXTERNAL,
                                                                       "hanyang-outdoor-uwb/1 cases"}
    kinds = dict(zip(summary.frame()["quantity"], summary.frame()["kind"]))
    values = dict(zip(summary.frame()["quantity"], summary.frame()["value"]))
    assert kinds["authors LS RMSE_2d, published"] == "input"
    # numbers of the authors' estimates are never "reproduced", and their data label says external
    for r in summary.frame().to_dict("records"):
        assert (r["kind"] == "input") == r["data"].endswith(sections.EXTERNAL), r
    assert kinds["authors LS RMSE_2d, recomputed (their definition)"] == "input"
    declared = sec.tables["declared"]
    for theirs, ref in zip(("authors LS", "authors ESKF"), study.AUTHORS_ROWS):   # declared before scoring
        r = declared[(declared["B"] == ref) & ~declared["case"].str.startswith("mean")].iloc[0]
        assert kinds[_labelled(f"RMSE_2d ratio ours (declared before scoring: EKF-RF ranges) / {theirs}", r)] == (
            "reproduced")
        (mean,) = [q for q in kinds if q.startswith(f"RMSE_2d ratio ours (declared before scoring: EKF-RF ranges) / "
                                                    f"{theirs}, mean over the cases scored (epochs both covered")]
        assert mean.endswith(f"; {EDGE_BOUND_LABEL} of 1 of 1 cases)" if r["verdict"].startswith("edge-bound") else
                             "(epochs both covered)")
    assert list(declared["B"]) == list(study.AUTHORS_ROWS) * 2
    # the picks' rows are the ratio table's: one best and one chosen, both against the authors' LS, each labelled
    # with the table's qualifiers (the pair's epochs; edge-bound where the verdict is), both RMSEs beside
    ratios = sec.tables["ratios"]
    for pick, what in (("best", "best on the scored case"), ("chosen", "picked on the tuning case")):
        r = ratios[ratios[pick]]
        assert len(r) == 1 and r["B"].iloc[0] == "authors LS (external)"
        q = _labelled(f"RMSE_2d ratio ours ({what}) / authors LS", r.iloc[0])
        assert values[q] == r["A / B"].iloc[0] and kinds[q] == "reproduced"
        a = r["A"].iloc[0]
        assert values[f"RMSE_2d, our ranges-only method {what} ({a}; epochs both covered with authors LS)"] == (
            r["RMSE A (m)"].iloc[0])
        assert values[f"RMSE_2d, authors LS (epochs both covered with {a})"] == r["RMSE B (m)"].iloc[0]
        # its interval's ends beside it, the table's own (where the table has an interval)
        ends = (r["A / B 95 % low"].iloc[0], r["A / B 95 % high"].iloc[0])
        assert ((values.get(f"{q}, 95 % low"), values.get(f"{q}, 95 % high")) == ends if np.isfinite(ends).all()
                else f"{q}, 95 % low" not in values)
    assert ratios.loc[ratios["best"], "A / B"].iloc[0] == ratios.loc[ratios["B"] == "authors LS (external)", "A / B"].min()
    methods = set(ratios["A"])
    assert "raw LS, authors' front end (jump gate + hold)" in methods
    assert not any("external" in m for m in methods)
    assert any(m.startswith("authors LS, latency removed") for m in sec.boards[cases[0].name].methods)
    nolat = ratios[ratios["B"].str.startswith("authors LS, latency removed")]
    assert set(nolat["A"]) == methods and np.isfinite(nolat["A / B"]).all()
    assert len(sec.tables["static_models"]) >= 1
    effect = sec.tables["static_effect"]
    assert set(effect["A"]) == {"LS static LOS model", "LS static NLOS model"} and set(effect["B"]) == {"raw LS", "LS"}
    assert sec.facts["tuning"][cases[0].name] != cases[0].name
    # the boards carry the common bound of every board of notebook 06 (one per recording, fitted on the tuning
    # case's truth), placed by the one placement rule
    board = sec.boards[cases[0].name]
    full = board.table().set_index("method")
    ran = full[full["n_scored"] > 0]
    assert board.calibration.params("common bound")["model"] in ("RW", "RF", "RJ")
    assert (ran["common_bound_m"] > 0).all() and ran["common_bound_common_m"].nunique() == 1
    assert set(sec.tables["placement"]["method"]) == set(ran.index)
    assert set(sec.tables["own_bound"]["method"]) == set(ran.index[ran["bound_m"] > 0])
    # the TDoA methods do not run on the 2 m cluster: the calibration part's TDoA CRLB against the ranges', in the note
    geo = board.calibration.params(GEOMETRY)["tag"]
    assert geo["tdoa_over_ranges"] > MAX_TDOA_OVER_RANGES
    for m in ("TDoA LS", "EKF-RW", "EKF-RF", "EKF-RJ"):
        assert full.loc[m, "n_scored"] == 0 and full.loc[m, "note"].startswith("not run: TDoAs uninformative here")
        assert f"{geo['tdoa_over_ranges']:.3g}× the ranges'" in full.loc[m, "note"]
    assert full.loc["raw LS", "bound_over_ranges_crlb"] == pytest.approx(1.0)
    # the UWB/INS filters are on the board and say why they did not run; every tuned EKF says where its pick lies
    assert full.loc[["loose", "tight"], "note"].str.contains("needs an IMU").all()
    assert full.loc["EKF-RF ranges", "tuning_pick"].startswith("σ_w ")
    prune = sections.pruning_section(None, data, fast=True)
    assert prune.facts["case"].startswith("NLOS/") and {"NLS residual pruning", "NLS robust mean"} <= set(
        prune.tables["ablation"]["A"])
    s2 = uw.metrics.Summary("02_pruning_nls", fast=True)
    prune.record(s2)
    label = f"hanyang-outdoor-uwb/{prune.facts['case']}"
    assert len(s2) == len(prune.rows) > 0 and {r["data"] for r in prune.rows} == {label, label + sections.EXTERNAL}
    theirs = [r for r in prune.rows if r["quantity"] == "RMSE_2d, authors LS (external) (epochs it covered)"]
    pv = {r["quantity"]: r["value"] for r in prune.rows}
    for r in prune.tables["ablation"].to_dict("records"):          # each ratio with the table's interval ends
        q = _labelled(f"RMSE_2d ratio {r['A']} / {r['B']}", r)      # the table's: on the pair's epochs, edge-bound
        assert pv[q] == r["A / B"]
        if np.isfinite([r["A / B 95 % low"], r["A / B 95 % high"]]).all():
            assert (pv[f"{q}, 95 % low"], pv[f"{q}, 95 % high"]) == (r["A / B 95 % low"], r["A / B 95 % high"])
    assert len(theirs) == 1 and theirs[0]["kind"] == "input" and theirs[0]["data"] == label + sections.EXTERNAL
    own = prune.boards[prune.facts["case"]].table().set_index("method")    # each RMSE row: the board's, coverage beside
    for m, r in own[np.isfinite(own["rmse_m"])].iterrows():
        assert pv[f"RMSE_2d, {m} (epochs it covered)"] == r["rmse_m"]
        assert pv[f"epoch coverage, {m} (share of the scored epochs)"] == r["coverage"]
    motion = sections.motion_section(cases[1].name, data, fast=True)
    assert set(motion.tables["models"]["A"]) == {"EKF-RW ranges", "EKF-RF ranges", "EKF-RJ ranges"}
    mv = {r["quantity"]: r["value"] for r in motion.rows}
    for r in motion.tables["models"].to_dict("records"):           # on the epochs each EKF and raw LS both covered
        assert mv[f"RMSE_2d, {r['A']} (epochs both covered with raw LS)"] == r["RMSE A (m)"]
        assert mv[_labelled(f"RMSE_2d ratio {r['A']} / raw LS", r)] == r["A / B"]
    assert motion.boards[cases[1].name].table().set_index("method").loc["EKF-RF", "note"].startswith("not run: TDoAs")
    assert motion.facts["tuned_on"] == cases[0].name


def _labelled(quantity: str, r) -> str:
    """A ratio row's summary label from its difference-table row: the pair's epochs, and edge-bound where the
    table's verdict is."""
    edge = "; edge-bound at the tuning picks" if r["verdict"].startswith("edge-bound: ") else ""
    return f"{quantity} (epochs both covered{edge})"


def test_a_ratio_row_carries_the_edge_bound_qualifier_of_its_verdict():
    """The board's grid_edge makes the difference table's verdict edge-bound; the summary rows of that ratio (and its
    interval's ends) say so, those of a pair whose picks lie inside their grids do not, nor do the RMSE rows."""
    n = 400
    rng = np.random.default_rng(3)
    errs = {"A": np.abs(rng.normal(1.0, 0.3, n)), "authors LS (external)": np.abs(rng.normal(2.0, 0.3, n)),
            "C": np.abs(rng.normal(1.0, 0.3, n))}
    board = _fake_board("d/X", errs, {m: np.ones(n, bool) for m in errs})
    table = board.table()
    table["grid_edge"], table["tuning_pick"] = [True, None, False], ["σ_w 1: on the grid's edge", "—", "σ_w 2"]
    t = study.ratio_table({"X": board}).set_index("A")
    assert t.loc["A", "verdict"] == "edge-bound: A more accurate at the picks (A: σ_w 1: on the grid's edge)"
    assert t.loc["C", "verdict"] == "C more accurate"
    rows = {r["quantity"]: r["value"] for m in "AC" for r in sections._ratio_rows(f"ratio {m}", t.loc[m], "d/X")}
    assert rows["ratio A (epochs both covered; edge-bound at the tuning picks)"] == t.loc["A", "A / B"]
    assert rows["ratio A (epochs both covered; edge-bound at the tuning picks), 95 % low"] == t.loc["A", "A / B 95 % low"]
    assert rows["ratio C (epochs both covered)"] == t.loc["C", "A / B"]
    assert len(rows) == 6


def _fake_board(label, errors, has):
    """A board-like object whose entries have the given horizontal errors and coverage masks."""
    from types import SimpleNamespace

    from uwbwb.scoreboard.board import Entry

    ents = {}
    for m, err in errors.items():
        n = err.size
        pos = np.where(has[m][:, None], np.column_stack([err, np.zeros(n)]), np.nan)
        status = np.where(has[m], int(EstimateStatus.UPDATED), int(EstimateStatus.NO_ESTIMATE)).astype(np.int8)
        ents[m] = Entry(m, "tag", Estimates(0.1 * np.arange(n), pos, status, m), None, np.zeros((n, 2)))
    table = pd.DataFrame({"method": list(ents), "n_scored": [int(e.scored.sum()) for e in ents.values()],
                          "coverage": [e.scored.mean() for e in ents.values()]})
    return SimpleNamespace(label=label, calibration=SimpleNamespace(source="d/T"), tags=("tag",), mode="FAST",
                           external=("authors LS (external)",), ran=lambda tag=None: list(ents.values()),
                           entry=lambda m, tag: ents[m], table=lambda: table)


def test_ratio_is_on_the_pairs_epochs_whatever_else_is_on_the_board():
    n = 400
    t = np.arange(n)
    errs = {"A": np.where(t < 200, 1.0, 3.0), "authors LS (external)": np.full(n, 2.0), "C": np.ones(n)}
    has = {"A": np.ones(n, bool), "authors LS (external)": np.ones(n, bool), "C": t < 200}
    with_c = study.ratio_table({"X": _fake_board("d/X", errs, has)}).set_index("A")
    del errs["C"], has["C"]
    without_c = study.ratio_table({"X": _fake_board("d/X", errs, has)}).set_index("A")
    # A on its own epochs with the authors' LS: sqrt((200·1 + 200·9)/400) = sqrt(5), whether C is there or not
    for t_ in (with_c, without_c):
        assert t_.loc["A", "RMSE A (m)"] == pytest.approx(np.sqrt(5.0)) and t_.loc["A", "epochs"] == n
        assert t_.loc["A", "A / B"] == pytest.approx(np.sqrt(5.0) / 2.0)
    assert with_c.loc["C", "epochs"] == 200 and with_c.loc["C", "coverage A"] == pytest.approx(0.5)
    assert with_c.loc["C", "coverage B"] == pytest.approx(1.0)
    # held: C keeps its last position (error 1) on the 200 epochs it has none
    assert with_c.loc["C", "held epochs"] == n and with_c.loc["C", "held filled"] == 200
    assert with_c.loc["C", "held A / B"] == pytest.approx(0.5) and with_c.loc["A", "held filled"] == 0
    assert with_c["best"].sum() == 1 and with_c.loc["C", "best"] and not with_c["chosen"].any()


def test_the_fair_pick_is_made_on_the_tuning_case_alone(tree, tmp_path):
    """Perturbing the scored case's reference inside its window changes neither our estimates nor the pick."""
    import shutil

    data, cases = tree
    case, tune = cases[2].name, cases[3].name
    est = [e for e in study.study_estimators(fast=True) if e.name in ("raw LS", "LS")]

    def run(d):
        board = study.case_board(case, tune, d, fast=True, estimators=est, authors=("LS",))
        pick, pick_board = study.pick_on_tuning_case(tune, d, fast=True, estimators=est)
        return board, pick, pick_board

    b0, p0, pb0 = run(data)
    other = tmp_path / "data"
    shutil.copytree(data, other)
    path = other / "hanyang-outdoor-uwb" / "Dynamic_measurements" / case / "trajectory.csv"
    df = pd.read_csv(path)
    ref = hd.load_dynamic_case(case, data, register=False).truth["tag"]
    assert len(ref) == len(df)
    t0, t1 = authors.authors_window(ref, "A")
    inside = (ref.t_s > t0 + 0.4 * (t1 - t0)) & (ref.t_s < t0 + 0.6 * (t1 - t0))
    assert inside.sum() > 10
    df.loc[inside, "x"] += 0.7
    df.to_csv(path, index=False, float_format="%.17g")
    b1, p1, pb1 = run(other)
    assert p0 == p1 and p0 in ("raw LS", "LS")
    assert pb0.label == pb1.label and tune in pb0.calibration.source
    for m in ("raw LS", "LS"):
        e0, e1 = b0.entry(m, "tag").estimates, b1.entry(m, "tag").estimates
        both, i0, i1 = np.intersect1d(e0.t_s, e1.t_s, return_indices=True)
        assert both.size > 0.9 * e0.t_s.size
        np.testing.assert_array_equal(e0.pos_m[i0], e1.pos_m[i1])
    # the truth did change: the scores on the scored case differ
    r0, r1 = (b.table().set_index("method").loc["raw LS", "rmse_m"] for b in (b0, b1))
    assert r0 != pytest.approx(r1, abs=1e-6)


def test_the_declared_method_is_written_down_before_scoring():
    """The rule itself: the board's range EKF-RF with its χ² gate, the board's grid (FAST: every other value)."""
    from uwbwb.scoreboard.estimators import EKF_GRIDS, RangeEkfEstimator, default_estimators

    assert study.DECLARED_METHOD == RangeEkfEstimator("RF", update="gate")
    assert study.DECLARED_METHOD in default_estimators(fast=False)
    (fast,) = [e for e in default_estimators(fast=True) if e.name == study.DECLARED_METHOD.name]
    assert fast.grid == tuple(EKF_GRIDS["RF"][::2])
    assert study.AUTHORS_ROWS == ("authors LS (external)", "authors ESKF (external, +IMU)")


def test_declared_method_table_per_case_and_reference_with_its_verdict_rule_and_mean(tree):
    """Two rows per case (against the authors' LS and ESKF), each verdict the rule applied to its own interval; then
    one mean row per reference whose ratio is the mean of the cases' and whose verdict counts theirs. A case folder
    (not a name) runs with its tuning case given."""
    data, cases = tree
    names = [c.name for c in cases[:2]]
    (method,) = [e for e in study.study_estimators(fast=True) if e.name == study.DECLARED_METHOD.name]

    def board(case, tune):
        return study.case_board(case, tune, data, fast=True, estimators=[method])

    table = study.declared_method_table({n: board(n, study.tuning_case(n, names)) for n in names}, seed=0)
    per = table[~table["case"].str.startswith("mean")]
    assert list(per["case"]) == [n for n in names for _ in range(2)]
    assert list(per["B"]) == list(study.AUTHORS_ROWS) * 2 and (per["A"] == "EKF-RF ranges").all()
    for r in per.to_dict("records"):
        assert r["A / B"] == pytest.approx(r["RMSE A (m)"] / r["RMSE B (m)"])
        assert 0 < r["coverage A"] <= 1 and 0 < r["coverage B"] <= 1 and r["rule"] == DIFFERENCE_RULE
    mean = table[table["case"] == "mean over 2 cases"].set_index("B")
    for ref in study.AUTHORS_ROWS:
        g = per[per["B"] == ref]
        assert mean.loc[ref, "A / B"] == pytest.approx(g["A / B"].mean())
        counts = g["verdict"].value_counts()
        assert mean.loc[ref, "verdict"] == ", ".join(f"{v}: {k}" for v, k in counts.items())

    folder = study.declared_method_table({str(cases[0].folder): board(str(cases[0].folder), names[1])}, seed=0)
    np.testing.assert_allclose(folder["A / B"].iloc[:2], per["A / B"].iloc[:2])
