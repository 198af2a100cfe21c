"""Notebook 03's synthetic tables over several test seeds: the interval, the verdict per pair, the summary rows."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from uwbwb import metrics
from uwbwb.experiments import motion_models as mm


def test_the_seeds_interval_is_the_student_t_interval_over_seeds():
    x = np.array([0.1, 0.3, 0.2, 0.6])
    t = metrics.seeds_interval(x)
    h = stats.t.ppf(0.975, 3) * x.std(ddof=1) / 2.0
    assert t["n"] == 4 and t["mean"] == pytest.approx(0.3)
    assert (t["lo"], t["hi"]) == (pytest.approx(0.3 - h), pytest.approx(0.3 + h))
    one = metrics.seeds_interval([0.5, np.nan])                               # one finite seed: a mean, no interval
    assert one["n"] == 1 and one["mean"] == 0.5 and np.isnan(one["lo"]) and np.isnan(one["hi"])


def _study(rw, rf, seeds=(0, 1, 2, 3)):
    """A seeds table of office tag1/tag2 where EKF-RW and EKF-RF have the given CEP95 per seed (other methods 1 m)."""
    rows = []
    for k, s in enumerate(seeds):
        for tag in ("tag1", "tag2"):
            rows.append({"seed": s, "run": "office", "tag": tag, "raw": 1.2, "LS": 1.0, "EKF-RJ": 1.0,
                         "EKF-RW": rw[k], "EKF-RF": rf[k]})
    t = pd.DataFrame(rows).set_index(["seed", "run", "tag"])[list(mm.METHODS)]
    return mm.seeds.SeedStudy(t, {"synthetic office": ("office",)}, tuple(seeds))


@pytest.mark.parametrize("rf, verdict, order", [
    ((0.60, 0.52, 0.58, 0.55), "EKF-RW better", "same order"),         # RF worse on every seed: the thesis' order
    ((0.30, 0.32, 0.28, 0.35), "EKF-RF better", "opposite order"),
    ((0.30, 0.70, 0.25, 0.75), "not significant", "—"),                 # the sign flips with the seed
])
def test_pair_verdict_follows_the_interval_over_seeds(rf, verdict, order):
    rw = (0.41, 0.43, 0.40, 0.42)
    row = _study(rw, rf).pairs([("EKF-RW", "EKF-RF")]).iloc[0]
    d = np.subtract(rw, rf)
    assert row["seeds"] == 4 and row["A − B (m)"] == pytest.approx(d.mean())
    assert row["verdict"] == verdict and row["vs thesis"] == order and row["rule"] == mm.seeds.SEED_RULE
    assert row["thesis A − B (m, input)"] == pytest.approx(np.mean([0.41 - 0.77, 0.48 - 1.13]))   # Table 3


def test_one_seed_gives_no_verdict_and_no_interval_rows():
    s = _study((0.4,), (0.6,), seeds=(0,))
    assert s.pairs([("EKF-RW", "EKF-RF")]).iloc[0]["verdict"] == "no interval (one seed)"
    rows = mm.seeds.seed_rows(s, [("EKF-RW", "EKF-RF")])
    assert [r["quantity"] for r in rows] == ["CEP95 EKF-RW minus EKF-RF, mean over test seeds (synthetic office)"]


def test_table_gives_mean_and_half_width_per_tag_run():
    s = _study((0.40, 0.44, 0.42, 0.46), (0.6,) * 4)
    t = s.table()
    assert t.loc[("office", "tag1"), ("EKF-RW", "mean")] == pytest.approx(0.43)
    half = stats.t.ppf(0.975, 3) * np.std([0.40, 0.44, 0.42, 0.46], ddof=1) / 2.0
    assert t.loc[("office", "tag2"), ("EKF-RW", "± 95 %")] == pytest.approx(half)
    assert t.loc[("office", "tag1"), ("EKF-RF", "± 95 %")] == pytest.approx(0.0)
    assert t.loc[("office", "tag1"), ("seeds", "")] == 4
    assert list(s.base().index) == [("office", "tag1"), ("office", "tag2")]


def test_seed_study_runs_the_study_filters_and_its_first_seed_is_the_study(office_runs):
    cal, test = office_runs                                          # seed 1, 25 s
    study = mm.run_study(cal, test, grids={"RW": [1.0], "RF": [1.0, 3.0], "RJ": [3.0]}, gate_prob=None,
                         progress=False)
    s = mm.seed_study({"synthetic office": (study, ("office",))}, (1, 2), gate_prob=None,
                      duration_s=25.0)
    assert s.seeds == (1, 2) and list(s.cep95.columns) == list(mm.METHODS)
    pd.testing.assert_frame_equal(s.base(), study.table(mm.METHODS))   # the same filters on the same acquisition
    assert not np.allclose(s.cep95.xs(2, level="seed").to_numpy(), study.table(mm.METHODS).to_numpy())
    results = mm.Results(synthetic={"office": study}, seeds=s)
    assert mm.checks(results, fast=True) == []
    rows = mm.headline_rows(results)
    seeds_rows = [r for r in rows if "mean over test seeds" in r["quantity"]]
    assert seeds_rows and {r["kind"] for r in seeds_rows} == {"reproduced"}
    assert {r["data"] for r in seeds_rows} == {"synthetic"}
    rw_rf = next(r for r in seeds_rows if r["quantity"] == "CEP95 EKF-RW minus EKF-RF, mean over test seeds "
                                                          "(synthetic office)")
    assert rw_rf["paper_value"] == pytest.approx(-0.505)
    assert len(rows) == len(mm.headline_rows(mm.Results(synthetic={"office": study}))) + len(seeds_rows)
    moved = replace(s, cep95=s.cep95 + 0.01)                          # a first seed that is not the study's
    assert any("first seed" in p for p in mm.checks(replace(results, seeds=moved), fast=True))


def test_pairs_per_tag_run_split_what_the_data_set_pools():
    rows = []
    for s in range(4):                                   # tag1: RF better on every seed; tag2: RW better by more
        rows.append({"seed": s, "run": "office", "tag": "tag1", "raw": 1.0, "LS": 1.0, "EKF-RJ": 1.0,
                     "EKF-RW": 0.45 + 0.01 * s, "EKF-RF": 0.42 + 0.01 * s})
        rows.append({"seed": s, "run": "office", "tag": "tag2", "raw": 1.0, "LS": 1.0, "EKF-RJ": 1.0,
                     "EKF-RW": 0.37 + 0.005 * s, "EKF-RF": 0.50 - 0.004 * s})
    t = pd.DataFrame(rows).set_index(["seed", "run", "tag"])[list(mm.METHODS)]
    s = mm.seeds.SeedStudy(t, {"synthetic office": ("office",)}, (0, 1, 2, 3))
    pooled = s.pairs(mm.MODEL_PAIRS[:1]).iloc[0]
    per = s.pairs(mm.MODEL_PAIRS[:1], by="tag-run").set_index("data")
    assert pooled["verdict"] == "EKF-RW better" and list(per.index) == ["office tag1", "office tag2"]
    assert per.loc["office tag1", "verdict"] == "EKF-RF better" and per.loc["office tag1", "vs thesis"] == "opposite order"
    assert per.loc["office tag1", "thesis A − B (m, input)"] == pytest.approx(0.41 - 0.77)
    assert per.loc["office tag2", "verdict"] == "EKF-RW better"
    with pytest.raises(ValueError, match="by must be"):
        s.pairs(by="tag")


def _models(rw, rf, rj):
    """A seeds table of agv1 tag1 with the given CEP95 of the three EKFs per seed (raw and LS fixed)."""
    rows = [{"seed": s, "run": "agv1", "tag": "tag1", "raw": 1.2, "LS": 1.0, "EKF-RW": rw[s], "EKF-RF": rf[s],
             "EKF-RJ": rj[s]} for s in range(len(rw))]
    t = pd.DataFrame(rows).set_index(["seed", "run", "tag"])[list(mm.METHODS)]
    return mm.seeds.SeedStudy(t, {"synthetic AGV": ("agv1",)}, tuple(range(len(rw))))


@pytest.mark.parametrize("rw, rf, rj, want", [
    # RW and RF swap with the seed (not significant), both below RJ on every seed
    ((0.40, 0.46, 0.41, 0.45), (0.44, 0.41, 0.45, 0.40), (0.50, 0.52, 0.51, 0.53), "RF ≈ RW < RJ"),
    # only RF < RJ is decided: the chain ties all three and names the decided pair
    ((0.35, 0.48, 0.37, 0.47), (0.40, 0.41, 0.40, 0.41), (0.42, 0.43, 0.425, 0.435), "RF ≈ RW ≈ RJ (RF < RJ)"),
    # every pair decided: a strict order
    ((0.30, 0.31, 0.30, 0.32), (0.40, 0.41, 0.40, 0.42), (0.50, 0.52, 0.51, 0.53), "RW < RF < RJ"),
])
def test_the_ranking_carries_the_resolution_of_the_pair_verdicts(rw, rf, rj, want):
    """The seeds table's ranking is ordered by the means but strict only where the pair verdicts (the same
    intervals as :meth:`SeedStudy.pairs`) decide: a point order over an undecided pair is no ranking."""
    s = _models(rw, rf, rj)
    verdicts = s.pairs(mm.MODEL_PAIRS, by="tag-run").set_index(["A", "B"])["verdict"]
    undecided = {k for k, v in verdicts.items() if v == "not significant"}
    assert s.ranking().loc[("agv1", "tag1")] == want
    assert ("≈" in want) == bool(undecided)
