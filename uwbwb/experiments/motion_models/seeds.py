"""Notebook 03's synthetic tables over several test seeds, and a verdict per pair of estimators.

The single-seed Tables 2–5 score one simulated test acquisition per scenario, so a ranking of the motion
models there may be one draw's luck. :func:`seed_study` keeps the filters the study calibrated (its driving σ
per model and range σ per anchor and tag, fitted on the calibration acquisition of the study's seed) and
runs them (:func:`~.study.estimate`, the study's own code path) on the test acquisitions of several seeds;
the first seed is the study's own, so its rows are the single-seed tables. :meth:`SeedStudy.pairs` gives, per
data set and pair ``(A, B)``, the mean over seeds of ``CEP95(A) − CEP95(B)`` (averaged over the data set's
tag-runs within a seed), its Student-t interval over the seeds (seeds are independent replicates; the tag-runs
of one seed share its walk and are not) and the verdict by :func:`uwbwb.metrics.interval_side`: "A better",
"B better" or "not significant". The interval covers test noise given the calibration, not the luck of the
one calibration acquisition.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ...metrics import interval_rows, interval_side, seeds_interval
from .results import MODELS, PAPER_METHODS_CEP95, PAPER_MODELS_CEP95, ekf_name, ranking
from .study import Study, estimate, synthetic_acquisition

__all__ = ["MODEL_PAIRS", "SEED_PAIRS", "SEED_RULE", "SeedStudy", "seed_rows", "seed_study"]

#: Pairs ``(A, B)`` the seeds verdict compares: the motion models among themselves (Tables 3, 5), each EKF
#: against LS and LS against the raw output (Tables 2, 4).
SEED_PAIRS = (("EKF-RW", "EKF-RF"), ("EKF-RW", "EKF-RJ"), ("EKF-RF", "EKF-RJ"), ("EKF-RW", "LS"), ("EKF-RF", "LS"),
              ("EKF-RJ", "LS"), ("LS", "raw"))
#: The motion-model pairs alone (Tables 3 and 5).
MODEL_PAIRS = SEED_PAIRS[:3]
#: The rule the verdict table states beside each verdict.
SEED_RULE = "95 % Student-t interval over test seeds of CEP95(A) − CEP95(B) excludes 0"


def _thesis(key: tuple[str, str], a: str, b: str) -> float:
    """The thesis' ``CEP95(A) − CEP95(B)`` on one of its rows (*input*): both from one table where it has both
    (Tables 3/5 for the models, Tables 2/4 for EKF-RW, LS and raw), else each from the table that has it."""
    models, methods = PAPER_MODELS_CEP95.get(key, {}), PAPER_METHODS_CEP95.get(key, {})
    for table in (models, methods):
        if a in table and b in table:
            return table[a] - table[b]
    va, vb = models.get(a, methods.get(a, np.nan)), models.get(b, methods.get(b, np.nan))
    return va - vb


@dataclass(frozen=True)
class SeedStudy:
    """CEP95 of every estimator on the test acquisitions of several seeds.

    Attributes
    ----------
    cep95
        CEP95 (m) on common epochs, rows ``(seed, run, tag)``, columns the studies' methods (:data:`~.results.METHODS`).
    datasets
        Data-set label → the scenario names (runs) it pools, e.g. ``{"synthetic AGV": ("agv1", "agv2")}``.
    seeds
        The test seeds, the study's own first.
    """

    cep95: pd.DataFrame
    datasets: Mapping[str, tuple[str, ...]]
    seeds: tuple[int, ...]

    def base(self) -> pd.DataFrame:
        """The first seed's rows, indexed ``(run, tag)``: the single-seed tables' numbers."""
        return self.cep95.xs(self.seeds[0], level="seed")

    def table(self, methods: Sequence[str] | None = None) -> pd.DataFrame:
        """Per ``(run, tag)``: the mean CEP95 over the seeds of every method and the half-width of its
        Student-t interval (columns ``(method, "mean")``, ``(method, "± 95 %")``), and the seed count."""
        out = {}
        for key, g in self.cep95.groupby(level=["run", "tag"], sort=False):
            row = {}
            for m in self.cep95.columns if methods is None else methods:
                t = seeds_interval(g[m])
                row[(m, "mean")], row[(m, "± 95 %")] = t["mean"], (t["hi"] - t["lo"]) / 2
            row[("seeds", "")] = len(g)
            out[key] = row
        table = pd.DataFrame.from_dict(out, orient="index")
        table.index.names = ["run", "tag"]
        table.columns = pd.MultiIndex.from_tuples(table.columns)
        return table

    def pairs(self, pairs: Sequence[tuple[str, str]] = SEED_PAIRS, *, by: str = "data") -> pd.DataFrame:
        """Per data set (``by="data"``) or per tag-run (``by="tag-run"``) and pair ``(A, B)``: seeds, the mean over
        seeds of ``CEP95(A) − CEP95(B)`` (with ``by="data"`` each seed's value averaged over the data set's
        tag-runs), its Student-t interval, the thesis' difference on the same rows (*input*), the rule, the verdict
        (:func:`~uwbwb.metrics.interval_side`) and whether a significant order is the thesis'."""
        if by not in ("data", "tag-run"):
            raise ValueError(f"by must be 'data' or 'tag-run', got {by!r}")
        groups = []
        for label, runs in self.datasets.items():
            d = self.cep95[self.cep95.index.get_level_values("run").isin(runs)]
            keys = list(dict.fromkeys((r, t) for _, r, t in d.index))
            if by == "data":
                groups.append((label, d, keys))
            else:
                groups += [(f"{r} {t}", d.xs((r, t), level=("run", "tag"), drop_level=False), [(r, t)])
                           for r, t in keys]
        rows = []
        for label, d, keys in groups:
            for a, b in pairs:
                per_seed = (d[a] - d[b]).groupby(level="seed").mean()
                t = seeds_interval(per_seed.to_numpy())
                side = interval_side(t["lo"], t["hi"])
                verdict = {"below": f"{a} better", "above": f"{b} better", "contains": "not significant"}.get(
                    side, "no interval (one seed)")
                thesis = round(float(np.nanmean([_thesis(k, a, b) for k in keys])), 6) if keys else np.nan
                order = ("thesis: equal" if thesis == 0 else
                         "same order" if (side == "below") == (thesis < 0) else "opposite order") \
                    if side in ("below", "above") and np.isfinite(thesis) else "—"
                rows.append({"data": label, "A": a, "B": b, "seeds": t["n"], "A − B (m)": t["mean"],
                             "95 % low (m)": t["lo"], "95 % high (m)": t["hi"], "thesis A − B (m, input)": thesis,
                             "rule": SEED_RULE, "verdict": verdict, "vs thesis": order})
        return pd.DataFrame(rows)

    def ranking(self, models: Sequence[str] = MODELS) -> pd.Series:
        """Per ``(run, tag)``: the motion models ordered by their mean CEP95 over the seeds, resolved by the pair
        verdicts of :meth:`pairs` (``by="tag-run"``, the same intervals): ``≈`` where they leave an order
        undecided (:func:`~.results.ranking`)."""
        names = [ekf_name(m) for m in models]
        verdicts = self.pairs([(a, b) for i, a in enumerate(names) for b in names[i + 1:]], by="tag-run")
        key = {f"{r} {t}": (r, t) for r, t in self.base().index}
        better: dict = {k: set() for k in key.values()}
        for v in verdicts.to_dict("records"):
            for a, b in ((v["A"], v["B"]), (v["B"], v["A"])):     # "A better", "B better" or not significant
                if v["verdict"] == f"{a} better":
                    better[key[v["data"]]].add((a, b))
        return ranking(self.table(names).xs("mean", axis=1, level=1), models, better=better)


def seed_study(studies: Mapping[str, tuple[Study, Sequence[str]]], seeds: Sequence[int], *, gate_prob: float | None,
               duration_s: float | None = None, rate_hz: float | None = None, ref: int = 0) -> SeedStudy:
    """The study's calibrated filters on the test acquisitions of every seed.

    Parameters
    ----------
    studies
        Data-set label → ``(study, scenario names)``: the study whose calibration is used (:attr:`Study.best`,
        :meth:`~uwbwb.scoreboard.protocol.Calibration.sigma` of its calibration) and the scenarios (:func:`~.study.synthetic_acquisition` names) it tests on.
    seeds
        Test seeds, the study's own first (its rows are then the single-seed tables); each seed's test acquisition is drawn with ``role="test"``, so it
        never shares noise with a calibration acquisition.
    gate_prob, duration_s, rate_hz, ref
        As for the study (the χ² gate is required, as there).
    """
    seeds = tuple(int(s) for s in seeds)
    if not seeds:
        raise ValueError("at least one test seed is needed")
    frames = {}
    for s in seeds:
        for study, names in studies.values():
            for name in names:
                runs, _ = synthetic_acquisition(name, seed=s, duration_s=duration_s, rate_hz=rate_hz, role="test")
                res = [estimate(r, study.calibration.sigma(r.tag), study.best, gate_prob=gate_prob, ref=ref,
                                tuned=study.calibration.tuned) for r in runs]
                frames[(s, name)] = replace(study, results=res).table()
    table = pd.concat({s: pd.concat([frames[(s, n)] for _, names in studies.values() for n in names])
                       for s in seeds}, names=["seed"])
    return SeedStudy(table, {k: tuple(v) for k, (_, v) in studies.items()}, seeds)


def seed_rows(seeds: SeedStudy, pairs: Sequence[tuple[str, str]] = SEED_PAIRS) -> list[dict]:
    """Summary rows of :meth:`SeedStudy.pairs` (all *reproduced*; the thesis' difference as ``paper_value`` of the
    mean): the mean difference and the two ends of its interval, where finite (:func:`~uwbwb.metrics.interval_rows`)."""
    rows = []
    for r in seeds.pairs(pairs).to_dict("records"):
        mean, *ends = interval_rows(f"CEP95 {r['A']} minus {r['B']}, mean over test seeds ({r['data']})",
                                    r["A − B (m)"], r["95 % low (m)"], r["95 % high (m)"], unit="m", data="synthetic",
                                    paper_value=None, kind="reproduced")
        rows += [{**mean, "paper_value": r["thesis A − B (m, input)"]}, *ends]     # NaN: the summary reads None
    return rows
