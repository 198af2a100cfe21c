"""The template experiment package: its study passes its checks, each check fails on a result doctored
to break it, the verdict follows the numbers across each threshold, and same seed gives same numbers."""

from __future__ import annotations

from dataclasses import replace

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest

from uwbwb import metrics
from uwbwb.experiments import template as tp
from uwbwb.experiments.template import facts as F

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def res():
    return tp.run_study(fast=True, seed=0)


def test_the_fast_study_passes_its_checks(res):
    assert tp.checks(res, True) == []
    f = F.facts(res)
    assert f["n_common"] == f["n_epochs"] == res.t_s.size
    assert f["verdict"] == "better" and f["nis_verdict"] == "consistent"


def test_same_seed_same_numbers_other_seed_other_numbers(res):
    again = F.facts(tp.run_study(fast=True, seed=0))
    assert again == F.facts(res)
    assert F.facts(tp.run_study(fast=True, seed=1))["rmse_m[LS]"] != again["rmse_m[LS]"]


def _doctored(res, what):
    err = dict(res.errors_m)
    if what == "coverage":
        e = err["LS"].copy()
        e[::5] = np.nan                         # LS loses a fifth of its epochs
        err["LS"] = e
    elif what == "LS RMSE":
        err["LS"] = 5 * err["LS"]
    elif what == "NIS":
        return replace(res, nis_per_dof=5 * res.nis_per_dof)
    elif what == "must beat":
        err["EKF-RF"] = 3 * err["EKF-RF"]
    return replace(res, errors_m=err)


@pytest.mark.parametrize("what", ["coverage", "LS RMSE", "NIS", "must beat"])
def test_each_check_fails_on_a_result_doctored_to_break_it(res, what):
    fails = tp.checks(_doctored(res, what), True)
    assert len(fails) == 1 and what in fails[0], fails
    assert tp.checks(_doctored(res, what), False)          # full mode is at least as strict


@pytest.mark.parametrize("lo, hi, verdict", [
    (-0.02, -1e-6, "better"),
    (-0.02, 1e-6, "no significant difference"),
    (-1e-6, 0.02, "no significant difference"),
    (1e-6, 0.02, "worse"),
    (np.nan, np.nan, "no interval"),
])
def test_the_verdict_flips_at_zero(lo, hi, verdict):
    assert F.verdict(lo, hi) == verdict


@pytest.mark.parametrize("nis, inside", [(0.49, False), (0.5, True), (2.0, True), (2.01, False)])
def test_the_nis_verdict_flips_at_the_band_edges(nis, inside):
    assert F.nis_verdict(nis) == ("consistent" if inside else "inconsistent")


def test_the_verdict_follows_the_method_not_just_the_numbers_fed_in():
    # an EKF told a driving σ far too small lags the walk: it loses to LS and its NIS says so — on the full walk;
    # the FAST walk holds too few independent stretches of its slowly varying lag for any interval
    lagging = F.facts(tp.run_study(fast=False, config=replace(tp.FULL, driving_sigma_mps2=0.1)))
    assert lagging["verdict"] == "worse" and lagging["nis_verdict"] == "inconsistent"
    assert F.facts(tp.run_study(fast=True, config=replace(tp.FAST, driving_sigma_mps2=0.1)))["verdict"] == "no interval"


def test_headlines_are_data_with_a_kind_and_are_published(res):
    rows = [h.row(F.facts(res)) for h in tp.HEADLINES]
    assert len(rows) == len(tp.HEADLINES)
    assert {r["kind"] for r in rows} == {"reproduced", "input"}
    assert all(np.isfinite(r["value"]) for r in rows)
    summary = metrics.Summary("template", fast=True)
    for row in rows:
        summary.add(**row)
    frame = summary.publish(None)
    assert len(frame) == len(rows) and set(frame["mode"]) == {"FAST"}
    with pytest.raises(ValueError, match="kind"):
        tp.headlines.Headline("x", "m", "guessed", lambda f: 0.0)


def test_the_figures_draw_headless(res):
    _, axes = plt.subplots(1, 2)
    assert len(tp.figures.paths_figure(res, axes[0]).lines) >= 3          # truth and both methods
    assert "300 common epochs" in tp.figures.cdf_figure(res, axes[1]).get_title()
    plt.close("all")
    with pytest.raises(ValueError, match="sigma_range_m"):
        replace(tp.FAST, sigma_range_m=-0.1)
