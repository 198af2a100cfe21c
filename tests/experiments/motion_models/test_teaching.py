"""Notebook 03's exercises, panel back end and headline rows/checks."""

import dataclasses

import matplotlib
import numpy as np
import pytest

from uwbwb.calibration import fit_range_sigma
from uwbwb.experiments import motion_models as mm
from uwbwb.experiments.motion_models import exercises, headlines, panels
from tests.test_teaching import assert_reads_predictions

matplotlib.use("Agg")

SIGMAS = {"RW": 0.83, "RF": 1.0, "RJ": 1.0}


@pytest.fixture(scope="module")
def fitted(office_runs):
    cal, test = office_runs
    return test[0], fit_range_sigma(cal[0])


@pytest.fixture(scope="module")
def small_study(office_runs):
    cal, test = office_runs
    grids = {m: (0.3, 3.0) for m in mm.MODELS}
    return mm.run_study(cal, test, grids=grids, gate_prob=None, progress=False)


# --------------------------------------------------------------------------- exercises

def test_reference_anchor_exercise_correlated_sigma_is_invariant(fitted):
    run, sigma_m = fitted
    check = exercises.reference_anchor(run, sigma_m, SIGMAS, refs=(0, 2), window_s=15.0)
    n = check.numbers
    assert check.holds
    assert n["LS spread, correlated Σ (cm)"] < 1e-6 and n["EKF-RW spread, correlated Σ (cm)"] < 1e-6
    assert n["LS spread, diagonal Σ (cm)"] > 0.1                       # the diagonal shortcut depends on it
    assert check.holds == (n["LS spread, diagonal Σ (cm)"] > exercises.REFERENCE_SPREAD_CM
                           and n["EKF-RW spread, diagonal Σ (cm)"] > exercises.REFERENCE_SPREAD_CM)
    assert_reads_predictions(check)
    with pytest.raises(ValueError, match="refs"):
        exercises.reference_anchor(run, sigma_m, SIGMAS, refs=(1, 1))
    with pytest.raises(ValueError, match="refs"):
        exercises.reference_anchor(run, sigma_m, SIGMAS, refs=(0, 99))


def test_reference_anchor_exercise_fails_on_exact_ranges(fitted):
    # exact ranges (the truth's distances, the run's gaps kept) and 1 cm of assumed noise: every weighting gives
    # the true fixes, so the diagonal Σ's CEP95 no longer depends on the reference either
    run, _ = fitted
    t = run.ranges.t_s
    pos = np.stack([np.interp(t, run.truth.t_s, run.truth.pos_m[:, k]) for k in range(3)], axis=1)
    exact = np.linalg.norm(pos[:, None, :] - run.anchors.pos_m[None], axis=2)
    exact = np.where(np.isfinite(run.ranges.range_m), exact, np.nan)
    clean = dataclasses.replace(run, ranges=dataclasses.replace(run.ranges, range_m=exact))
    check = exercises.reference_anchor(clean, np.full(len(run.anchors.ids), 0.01), SIGMAS, refs=(0, 2), window_s=15.0)
    n = check.numbers
    assert not check.holds, check
    assert n["LS spread, diagonal Σ (cm)"] < 1e-3 and n["EKF-RW spread, diagonal Σ (cm)"] < exercises.REFERENCE_SPREAD_CM
    assert_reads_predictions(check)


def test_overconfident_exercise_raises_cep95_and_nis(fitted):
    run, sigma_m = fitted
    check = exercises.overconfident_driving_noise(run, sigma_m, SIGMAS, factor=0.01, window_s=15.0)
    n = check.numbers
    assert check.holds and n["CEP95 small (m)"] > n["CEP95 calibrated (m)"]
    assert n["mean NIS/dof small"] > n["mean NIS/dof calibrated"]
    assert n["σ_w small"] == pytest.approx(0.01 * SIGMAS["RF"])
    same = exercises.overconfident_driving_noise(run, sigma_m, SIGMAS, factor=1.0, window_s=15.0)
    assert not same.holds                                               # no change: the claim must fail
    for c in (check, same):
        assert_reads_predictions(c)
    with pytest.raises(ValueError, match="factor"):
        exercises.overconfident_driving_noise(run, sigma_m, SIGMAS, factor=0.0)


# --------------------------------------------------------------------------- panel back end

def test_explorer_offers_only_what_the_data_has(small_study):
    ex = panels.Explorer([small_study], window_s=10.0)
    assert ex.choices == ["office/tag1", "office/tag2"]
    assert ex.max_ref == len(small_study.results[0].run.anchors) - 1 == 5
    fig, readout = ex.render("office/tag1", "RF", 1.0, 5, 0.0, True)
    assert set(readout) >= {"CEP95 EKF-RF (m)", "CEP95 LS (m)", "NIS verdict"}
    assert all(ax.get_xlabel() and ax.get_ylabel() and ax.get_title() for ax in fig.axes)
    assert ex.estimate("office/tag1", "RF", 1.0, 5, 0.0, True) is ex.estimate("office/tag1", "RF", 1.0, 5, 0.0, True)
    for bad in ({"key": "office/tag3"}, {"ref": 6}, {"model": "CV"}):
        args = {"key": "office/tag1", "model": "RW", "sigma": 1.0, "ref": 0, "gate": 0.0, "correlated": True, **bad}
        with pytest.raises(ValueError, match=next(iter(bad))):
            ex.estimate(**args)
    with pytest.raises(ValueError, match="studies"):
        panels.Explorer([])


# --------------------------------------------------------------------------- headlines

def test_headline_rows_and_checks(small_study):
    results = mm.Results(synthetic={"office": small_study}, real=[("lias-planar-uwb/x", "raw ranges", small_study)])
    rows = mm.headline_rows(results)
    assert rows[0]["quantity"] == "driving sigma RW (office)" and rows[0]["kind"] == "target"
    assert {r["data"] for r in rows} == {"synthetic", "lias-planar-uwb/x"}
    real = [r for r in rows if r["data"] != "synthetic"]
    assert all(r["paper_value"] is None for r in real)
    assert any(r["quantity"] == "CEP95 tag1 LS (raw ranges, test part office)" for r in real)
    assert {r["kind"] for r in rows} == {"target", "reproduced"}
    assert mm.checks(results, fast=True) == []


def test_checks_report_a_failure(small_study):
    from dataclasses import replace

    res = small_study.results[0]
    before = res.cep95()

    def worse(e):      # every EKF's errors × 10
        if not e.method.startswith("EKF"):
            return e
        pos, truth = e.estimates.pos_m.copy(), e.truth_pos_m[:, :2]
        pos[:, :2] = np.where(np.isfinite(truth), truth + 10 * (pos[:, :2] - truth), pos[:, :2])
        return replace(e, estimates=replace(e.estimates, pos_m=pos))

    bad_board = replace(res.board, entries=tuple(worse(e) for e in res.board.entries))
    bad = replace(small_study, results=[replace(res, board=bad_board)])
    problems = headlines.checks(mm.Results(synthetic={"office": bad}), fast=True)
    assert any("clearly worse than LS" in p for p in problems) and res.cep95() == before


# --------------------------------------------------------------------------- real-data sections

def test_real_sections_without_data_are_skipped_not_replaced(tmp_path):
    lias = mm.real.lias_section(tmp_path, "fast", "8.14", tags=None, rate_hz=10.0, fast=True, grids=None, ref=0,
                                gate_prob=None)
    assert lias.studies == {} and lias.label == "" and lias.banner is not None
    iasl = mm.real.iasl_section(tmp_path, "scenario1", "scenario2", rate_hz=10.0, grids=None, ref=0, gate_prob=None)
    assert iasl.studies == {} and iasl.label == "" and iasl.banner is not None
