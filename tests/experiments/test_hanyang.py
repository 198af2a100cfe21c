"""The Hanyang dynamic study: reproduction of the authors' numbers, the external rows, the boards, the verdicts."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.fixtures import hanyang as fx
from uwbwb.datasets import hanyang_dynamic as hd
from uwbwb.errors import DataFormatError
from uwbwb.experiments.hanyang import facts, study
from uwbwb.models.motion import make_motion_model
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
        df = study.reproduce_authors(c.name, data).set_index(["method", "metric"])
        for method, v in c.rmsd.items():
            assert df.loc[(method, "RMSE 2-D"), "reproduced_m"] == pytest.approx(v["rmse_2d_m"], abs=1e-6)
            assert df.loc[(method, "RMSE 3-D"), "reproduced_m"] == pytest.approx(v["rmse_m"], abs=1e-6)
            assert df.loc[(method, "RMSE 2-D"), "published_m"] == pytest.approx(v["rmse_2d_m"], abs=1e-12)
        f = facts.reproduction_facts(df.reset_index())
        assert f["agree"] and "agree with" in facts.reproduction_sentence(f)


def test_reproduction_verdict_flips_with_the_difference():
    repro = pd.DataFrame({"data": ["d/x", "d/x"], "published_m": [1.0, np.nan], "diff_m": [0.009, 5.0]})
    assert facts.reproduction_facts(repro)["agree"]
    repro["diff_m"] = [0.011, 0.0]
    f = facts.reproduction_facts(repro)
    assert not f["agree"] and "DISAGREE" in facts.reproduction_sentence(f)


def test_rmsd_file_parsing(tmp_path):
    p = tmp_path / "RMSD_results.txt"
    p.write_text("LS RMSE: 1.5 m\nLS RMSE_2d: 1.0\nInsufficient data for ESKF RMSE calculation\nESKF RMSE_2d: 0.9\n")
    assert study.read_rmsd_results(p) == {"LS": {"rmse_m": 1.5, "rmse_2d_m": 1.0}, "ESKF": {"rmse_2d_m": 0.9}}
    p.write_text("LS RMSE: 1.5 m\nLS RMSE 2d = 1.0\n")
    with pytest.raises(DataFormatError) as err:
        study.read_rmsd_results(p)
    assert err.value.line == 2


def test_authors_window_follows_their_rules(tree):
    data, cases = tree
    rec = hd.load_dynamic_case(cases[0].name, data, register=False)
    t0, t1 = study.authors_window(rec.truth["tag"], "A")
    p = rec.truth["tag"].interp([t0, t1])
    assert p[0, 0] > 49.3 and p[0, 1] > -5 and p[1, 0] <= 12 and p[1, 1] > 3.4
    with pytest.raises(ValueError, match="never meets the start rule"):
        study.authors_window(rec.truth["tag"].select(slice(0, 10)), "A")


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
    out = study.AuthorsEstimator("LS").estimate(rec, "tag", cal)
    assert np.array_equal(out.t_s, log.t_s)
    inside = (log.t_s >= 1.0) & (log.t_s <= 1.2)
    np.testing.assert_allclose(out.pos_m[inside], np.column_stack([log.t_s[inside], 2 * log.t_s[inside]]))
    gap = (log.t_s > 1.2) & (log.t_s < 2.0)                 # 0.8 s between two outputs: no estimate
    assert gap.any() and np.all(out.status[gap] == EstimateStatus.NO_ESTIMATE)
    assert np.all(out.status[log.t_s > 2.1] == EstimateStatus.NO_ESTIMATE)
    assert study.AuthorsEstimator("ESKF").applies(rec, "tag", cal) is not None


def test_range_measurement_jacobian_matches_finite_differences():
    rng = np.random.default_rng(2)
    anchors = np.array(list(fx.DYNAMIC_ANCHORS.values()))
    for model in ("RW", "RF"):
        motion = make_motion_model(model, sigma=1.0, dt_s=0.1, dim=2)
        meas = study.RangeMeasurement(anchors, np.full(4, 0.1), motion, 1.1)
        x = rng.normal(0, 5, motion.n_x)
        row = np.array([10.0, np.nan, 12.0, 11.0])
        lin = meas.linearise(x, row)
        assert lin.z.size == 3
        num = np.empty_like(lin.H)
        for j in range(x.size):
            dx = np.zeros_like(x)
            dx[j] = 1e-6
            num[:, j] = (meas.linearise(x + dx, row).h - meas.linearise(x - dx, row).h) / 2e-6
        np.testing.assert_allclose(lin.H, num, atol=1e-7)
        assert meas.linearise(x, np.full(4, np.nan)) is None


def test_block_bootstrap_ratio_brackets_the_truth():
    rng = np.random.default_rng(0)
    e = np.abs(rng.normal(0, 1, 400))
    lo, hi = study.block_bootstrap_ratio(e, e * 1.0, rng=np.random.default_rng(1))
    assert lo == pytest.approx(1.0) and hi == pytest.approx(1.0)
    lo, hi = study.block_bootstrap_ratio(0.5 * e + 0.05 * np.abs(rng.normal(0, 1, 400)), e, rng=np.random.default_rng(1))
    assert hi < 1.0 and lo > 0.4
    assert np.isnan(study.block_bootstrap_ratio(e[:10], e[:10], rng=np.random.default_rng(1))[0])
    a = study.block_bootstrap_ratio(e, 1.1 * e, rng=np.random.default_rng(3))
    assert a == study.block_bootstrap_ratio(e, 1.1 * e, rng=np.random.default_rng(3))


@pytest.mark.parametrize("lo, hi, verdict", [(0.7, 0.95, "better"), (0.9, 1.1, "not significant"),
                                             (1.02, 1.3, "worse"), (np.nan, np.nan, "no interval")])
def test_ratio_verdict_flips_at_one(lo, hi, verdict):
    ratios = pd.DataFrame([{"case": "X", "method": "EKF", "best": True, "ratio": (lo + hi) / 2 if np.isfinite(lo) else 1.0,
                            "ratio_lo": lo, "ratio_hi": hi, "rmse_2d_m": 0.5, "authors_ls_rmse_2d_m": 0.6}])
    f = facts.ratio_facts(ratios)
    assert f["cases"][0]["verdict"] == verdict
    assert verdict in facts.ratio_sentence(f)


@pytest.mark.parametrize("his, answer", [((0.95, 0.99), "yes"), ((0.95, 1.01), "no"), ((1.2, 1.3), "no")])
def test_static_answer_is_yes_only_if_it_helps_everywhere(his, answer):
    effect = pd.DataFrame([{"case": f"c{k}", "method": "LS static LOS model", "ratio_vs_raw_ls": h - 0.05,
                            "ratio_vs_raw_ls_lo": h - 0.1, "ratio_vs_raw_ls_hi": h} for k, h in enumerate(his)])
    f = facts.static_facts(effect)
    assert f["answer"] == answer and f"**{answer}**" in facts.static_sentence(f)


def test_static_model_is_fitted_from_the_static_files(tree):
    data, _ = tree
    m = study.static_range_model("LOS", data)
    assert m.bias_m == pytest.approx(0.22, abs=0.05) and m.scale == pytest.approx(1.0, abs=0.01)
    np.testing.assert_allclose(m.correct(m.scale * 10.0 + m.bias_m), 10.0)


def test_case_board_scores_ours_and_theirs_on_the_same_epochs(tree):
    data, cases = tree
    case = cases[2].name                                  # NLOS A, tuned on NLOS B
    tune = study.tuning_case(case, [c.name for c in cases])
    assert tune == cases[3].name
    est = [e for e in study.study_estimators(fast=True) if e.name in
           ("raw LS", "LS", "EKF-RF ranges", "NLS residual pruning")] + [study.AuthorsEstimator("LS")]
    board = study.case_board(case, tune, data, fast=True, estimators=est)
    assert board.label == f"hanyang-outdoor-uwb/{case}" and tune in board.calibration.source
    assert board.calibration.dim == 2
    # the tag height is the tuning case's, given to the scored case
    assert board.calibration.tag_height_m["tag"] == pytest.approx(1.0 + 0.0, abs=0.1)
    df = board.table().set_index("method")
    assert (df["coverage"].between(0, 1)).all() and df.loc["authors LS (external)", "n_scored"] > 0
    t0, t1 = study.board_epochs(hd.load_dynamic_case(case, data))
    e = board.entry("raw LS", "tag")
    assert e.estimates.t_s[0] >= t0 and e.estimates.t_s[-1] < min(t1, t0 + study.FAST_SPAN_S)
    repro = study.reproduce_authors(case, data)
    ratios = study.ratio_table({case: board}, repro)
    assert set(ratios["method"]) == {"raw LS", "LS", "EKF-RF ranges", "NLS residual pruning"}
    assert ratios["best"].sum() == 1 and (ratios["ratio"] > 0).all()
    with pytest.raises(ValueError, match="not allowed"):
        study.case_board(case, case, data, fast=True, estimators=est)


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
    sec = sections.scoreboard_section(None, data, fast=True, summary=summary)
    assert sec.absent is None and list(sec.boards) == [cases[0].name]           # FAST: one case
    assert sec.facts["reproduction"]["agree"] and "agree with" in sec.markdown
    assert {r["data"] for r in summary.frame().to_dict("records")} == {f"hanyang-outdoor-uwb/{cases[0].name}"}
    kinds = dict(zip(summary.frame()["quantity"], summary.frame()["kind"]))
    assert kinds["authors LS RMSE_2d, published"] == "input"
    assert kinds["RMSE_2d ratio ours (best on the scored case) / authors LS"] == "reproduced"
    assert sec.facts["tuning"][cases[0].name] != cases[0].name
    prune = sections.pruning_section(None, data, fast=True)
    assert prune.facts["case"].startswith("NLOS/") and {"NLS residual pruning", "NLS robust mean"} <= set(
        prune.tables["ablation"]["method"])
    s2 = uw.metrics.Summary("02_pruning_nls", fast=True)
    prune.record(s2)
    assert len(s2) == len(prune.rows) > 0 and {r["data"] for r in prune.rows} == {f"hanyang-outdoor-uwb/{prune.facts['case']}"}
    motion = sections.motion_section(cases[1].name, data, fast=True)
    assert set(motion.tables["models"]["method"]) == {"EKF-RF", "EKF-RW ranges", "EKF-RF ranges", "EKF-RJ ranges"}
    assert motion.facts["tuned_on"] == cases[0].name


# ------------------------------------------------------------------ notebooks on generated trees

def _hanyang_tree(data_dir, rng):
    fx.write_dataset(data_dir / "hanyang-outdoor-uwb", rng=rng, distances_m=(2, 4, 10, 20))
    return fx.write_dynamic_tree(data_dir / "hanyang-outdoor-uwb", rng=rng, speed_mps=4.0)


@pytest.mark.notebook
def test_pruning_notebook_runs_on_a_generated_dynamic_case(tmp_path):
    """Notebook 02's Hanyang section on a case that is not in ../shared (chosen by HANYANG_CASE)."""
    from tests.fixtures import lias as fx_lias
    from tests.test_notebooks import _run_on

    data_dir = tmp_path / "data"
    rng = np.random.default_rng(21)
    fx_lias.make_tree(data_dir, rng=rng, dynamic={"medium": {"duration_s": 40.0, "clock_offset_s": 0.2}},
                      sessions=[fx_lias.session_814(rng, files=((1, 0), (2, 0), (3, 0), (1, 60)))], static_rows=300)
    cases = _hanyang_tree(data_dir, rng)
    rows = _run_on("02_pruning_nls.ipynb", tmp_path, data_dir, RECORDING="medium", HANYANG_CASE=cases[3].name)
    hy = [r for r in rows if r["data"] == f"hanyang-outdoor-uwb/{cases[3].name}"]
    assert any(r["quantity"] == "RMSE_2d ratio NLS residual pruning / NLS" for r in hy)
    assert {r["kind"] for r in hy} == {"reproduced"} and {r["mode"] for r in hy} == {"FAST"}


@pytest.mark.notebook
def test_motion_models_notebook_runs_on_a_generated_dynamic_case(tmp_path):
    """Notebook 03's Hanyang section on a case that is not in ../shared (chosen by HANYANG_CASE)."""
    from tests.fixtures import iasl as fx_iasl
    from tests.fixtures import lias as fx_lias
    from tests.test_notebooks import _run_on

    data_dir = tmp_path / "data"
    rng = np.random.default_rng(22)
    fx_lias.make_tree(data_dir, rng=rng, dynamic={"medium": {"duration_s": 30.0, "clock_offset_s": 0.2}},
                      sessions=[fx_lias.session_814(rng)])
    fx_iasl.write_dataset(data_dir / "iasl-uwb-imu", rng=rng, duration_s=30.0)
    cases = _hanyang_tree(data_dir, rng)
    rows = _run_on("03_ekf_motion_models.ipynb", tmp_path, data_dir, RECORDING="medium", HANYANG_CASE=cases[1].name)
    hy = [r for r in rows if r["data"].startswith("hanyang-outdoor-uwb/")]
    assert {r["data"] for r in hy} == {f"hanyang-outdoor-uwb/{cases[1].name}"}
    assert any(r["quantity"] == "RMSE_2d ratio EKF-RW ranges / raw LS" for r in hy)


def test_the_fair_pick_is_the_best_method_of_the_tuning_case_board():
    from types import SimpleNamespace

    # two cases tuned on each other: the pick for X is what won on Y, and the reverse
    errs = {"X": {"A": np.full(50, 1.0), "B": np.full(50, 2.0), "authors LS (external)": np.full(50, 1.5)},
            "Y": {"A": np.full(50, 3.0), "B": np.full(50, 1.0), "authors LS (external)": np.full(50, 2.0)}}
    import uwbwb.experiments.hanyang.study as st

    boards = {c: SimpleNamespace(label=f"d/{c}", calibration=SimpleNamespace(source=f"d/{'Y' if c == 'X' else 'X'}"),
                                 table=lambda: pd.DataFrame({"method": ["A", "B", "authors LS (external)"],
                                                             "coverage": [1.0, 1.0, 1.0]}))
              for c in errs}
    orig = st._common_errors
    st._common_errors = lambda b, tag="tag": (None, errs[b.label[2:]])
    try:
        t = st.ratio_table(boards, pd.DataFrame(columns=["data", "method", "metric", "published_m", "reproduced_m"]),
                           tuning={"X": "Y", "Y": "X"})
    finally:
        st._common_errors = orig
    pick = t[t["chosen"]].set_index("case")["method"].to_dict()
    best = t[t["best"]].set_index("case")["method"].to_dict()
    assert pick == {"X": "B", "Y": "A"} and best == {"X": "A", "Y": "B"}
    f = facts.ratio_facts(t, "chosen")
    assert f["pick"] == "chosen" and "tuning case" in facts.ratio_sentence(f)
