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
def test_the_verdict_flips_at_zero(res, lo, hi, verdict):
    assert F.verdict(lo, hi) == verdict
    f = dict(F.facts(res), lo_m=lo, hi_m=hi, verdict=F.verdict(lo, hi))
    assert F.verdict_table(f)["verdict"].iloc[0] == verdict


@pytest.mark.parametrize("nis, inside", [(0.49, False), (0.5, True), (2.0, True), (2.01, False)])
def test_the_nis_verdict_flips_at_the_band_edges(res, nis, inside):
    f = dict(F.facts(res), nis_per_dof=nis, nis_verdict=F.nis_verdict(nis))
    assert (f["nis_verdict"] == "consistent") == inside
    assert F.verdict_table(f)["verdict"].iloc[1] == ("consistent" if inside else "inconsistent")


def test_the_verdict_follows_the_method_not_just_the_numbers_fed_in():
    # an EKF told a driving σ far too small lags the walk: it loses to LS and its NIS says so — on the full walk;
    # the FAST walk holds too few independent stretches of its slowly varying lag for any interval
    lagging = F.facts(tp.panels.run(0.1, 0.10, fast=False))
    assert lagging["verdict"] == "worse" and lagging["nis_verdict"] == "inconsistent"
    assert F.facts(tp.panels.run(0.1, 0.10))["verdict"] == "no interval"
    assert tp.panels.readout(0.1, 0.10, fast=False)["verdict"].iloc[0] == "worse"
    assert tp.panels.readout(0.5, 0.10)["verdict"].iloc[0] == "better"


def test_headlines_are_data_with_a_kind_and_are_published(res):
    rows = tp.rows(F.facts(res))
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


def test_the_panel_is_cached_and_draws_headless():
    assert tp.panels.run(0.5, 0.10) is tp.panels.run(0.5, 0.10)
    axes = tp.panels.draw(0.5, 0.10)
    assert "300 common epochs" in axes[1].get_title()
    plt.close("all")
    with pytest.raises(ValueError, match="sigma_range_m"):
        tp.panels.run(0.5, -0.1)
