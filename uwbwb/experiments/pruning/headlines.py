"""Notebook 02's summary rows and its checks, from one :class:`Results` record of the run.

:func:`rows` declares the rows (quantity, value, unit, data, kind, paper value): every
value came out of the method on the run's data (*reproduced*); the paper's statements sit beside
them as ``paper_value``, never as a pass bound. :func:`checks` lists what the methods must do
whatever the noise levels (none of them is the paper's number).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...sim.tours import TourConfig
from .scoring import LABELS, PAPER_RANKING, POINT
from .sections import LiasDynamic, LiasStatic
from .study import SyntheticResult
from .verdicts import noise

__all__ = ["Results", "checks", "rows"]


@dataclass(frozen=True)
class Results:
    """What notebook 02's checks and summary read.

    Attributes
    ----------
    synthetic
        The ranked synthetic comparison (:func:`.study.run_synthetic`).
    synthetic_table
        Its :func:`.scoring.heuristic_summary` (stops, walks, packets).
    synthetic_dim
        Its geometry (2: known mount height, 3: no height).
    other_table
        The same packets in the other geometry (None: not run).
    control
        :func:`.scoring.heuristic_summary` of the same tours without NLOS (the outlier-free control).
    lias_static, lias_dynamic
        :func:`.sections.lias_static` / :func:`.sections.lias_dynamic` (None: no LIAS data).
    hanyang
        Per condition (LOS, NLOS) of the Hanyang static files, the median over files of ``median_err_m`` and
        ``pq_err_m`` (:func:`uwbwb.calibration.percentile_by_file`; None: no data).
    hanyang_label
        Its data label.
    tour
        The simulator configuration of the synthetic comparison (its noise is named beside the paper's 4 m).
    """

    synthetic: SyntheticResult = field(repr=False)
    synthetic_table: pd.DataFrame = field(repr=False)
    synthetic_dim: int
    other_table: pd.DataFrame | None = field(repr=False)
    control: pd.DataFrame = field(repr=False)
    lias_static: LiasStatic | None = field(default=None, repr=False)
    lias_dynamic: LiasDynamic | None = field(default=None, repr=False)
    hanyang: pd.DataFrame | None = field(default=None, repr=False)
    hanyang_label: str | None = None
    tour: TourConfig | None = None


def _ranks(table: pd.DataFrame) -> pd.Series:
    """Rank (1 = best) by median stop error of the paper's three heuristics present (plain NLS and the point-based
    baseline are not ranked, as in the paper)."""
    three = [h for h in PAPER_RANKING if h in table.index and np.isfinite(table.loc[h, "stop_median_m"])]
    return table.loc[three, "stop_median_m"].rank()


def rows(results: Results) -> list[dict]:
    """The notebook's headline numbers as :meth:`uwbwb.metrics.Summary.add` keyword dicts, each with its kind.

    Every value came out of the method on the run's data (``kind="reproduced"``); the paper's statements sit
    beside them as ``paper_value`` (the ranking, "90 % under 4 m"), never as a pass bound. Residual pruning's
    90th percentile, set beside the paper's 4 m, names the simulated noise it follows from. The 3-D rows come only
    when the ranked comparison is 2-D (``other_table`` is then 3-D).
    """
    out = []

    def add(quantity, value, unit, data, paper_value=None):
        if value is not None and np.isfinite(value):
            out.append({"quantity": quantity, "value": float(value), "unit": unit, "data": data,
                        "kind": "reproduced", "paper_value": paper_value})

    geo = "known height" if results.synthetic_dim == 2 else "3-D, no height"
    t = results.synthetic_table
    assumed = "; follows from assumed noise: " + (noise(results.tour) if results.tour is not None else
                                                   "our simulator's (uw.sim.tours.TourConfig)")
    for h, r in t.iterrows():
        lab = LABELS[h]
        add(f"median stationary error, {lab} ({geo})", r.get("stop_median_m"), "m", "synthetic")
        add(f"90th-percentile stationary error, {lab} ({geo})", r.get("stop_p90_m"), "m", "synthetic")
        add(f"median walk velocity error, {lab} ({geo})", r.get("vel_err_median_mps"), "m/s", "synthetic")
        add(f"median walk speed ratio (estimated / true), {lab} ({geo})", r.get("speed_ratio_median"), "",
            "synthetic")
        add(f"90 % of all distance errors under, {lab} ({geo}, covered packets{assumed if h == 'residual' else ''})",
            r.get("all_p90_m"), "m", "synthetic", 4.0 if h == "residual" else None)
        add(f"median of all distance errors, {lab} ({geo}, covered packets)", r.get("all_median_m"), "m",
            "synthetic")
        add(f"packet coverage, {lab} ({geo})", r.get("coverage"), "", "synthetic")
    rank = "rank by median stationary error among the three heuristics (1 = best)"
    paper_rank = {"residual": 1, "robust_mean": 2, "percentile": 3}
    for h, v in _ranks(t).items():
        add(f"{rank}, {LABELS[h]} ({geo})", v, "", "synthetic", paper_rank[h])
    if {"residual", POINT} <= set(t.index):
        add(f"90 % of all distance errors, residual pruning minus point-based ({geo})",
            t.loc["residual", "all_p90_m"] - t.loc[POINT, "all_p90_m"], "m", "synthetic")
    if results.synthetic_dim == 2 and results.other_table is not None:
        for h, r in results.other_table.iterrows():
            lab = LABELS[h]
            add(f"median stationary error, {lab} (3-D, no height)", r.get("stop_median_m"), "m", "synthetic")
            add(f"median stationary height error |dz|, {lab} (3-D, no height)", r.get("stop_err_z_median_m"),
                "m", "synthetic")
            add(f"median stationary 3-D error, {lab} (3-D, no height)", r.get("stop_err_3d_median_m"), "m",
                "synthetic")
            add(f"90 % of all distance errors under, {lab} (3-D, no height, covered packets)", r.get("all_p90_m"),
                "m", "synthetic")
    st = results.lias_static
    for k in (st.runs if st is not None else ()):
        hs, es = st.table.loc[k], st.epochs[k]
        for h, r in hs.iterrows():
            add(f"median stationary error, {LABELS[h]}, {k}", r.get("stop_median_m"), "m", st.label)
            add(f"90th-percentile stationary error, {LABELS[h]}, {k}", r.get("stop_p90_m"), "m", st.label)
        for h, v in _ranks(hs).items():
            add(f"{rank}, {LABELS[h]}, {k}", v, "", st.label, paper_rank[h])
        for h, r in es.iterrows():
            add(f"median per-epoch error, {LABELS[h]}, {k}", r.median_m, "m", st.label)
            add(f"epoch coverage, {LABELS[h]}, {k}", r.coverage, "", st.label)
    dy = results.lias_dynamic
    for k in (dy.runs if dy is not None else ()):
        pt, (es, cov) = dy.table.loc[k], dy.epochs[k]
        for h, r in pt.iterrows():
            add(f"median segment position error, {LABELS[h]}, {k}", r.mean_err_m, "m", dy.label)
            add(f"median segment velocity error, {LABELS[h]}, {k}", r.vel_err_mps, "m/s", dy.label)
            add(f"median speed ratio (estimated / true), {LABELS[h]}, {k}", r.speed_ratio, "", dy.label)
        for h, r in es.iterrows():
            add(f"median per-epoch error on the straight pieces, {LABELS[h]}, {k}", r.median_m, "m", dy.label)
            add(f"90th-percentile per-epoch error on the straight pieces, {LABELS[h]}, {k}", r.p90_m, "m",
                dy.label)
        for h, v in cov.items():
            add(f"fraction of the run's epochs with a position, {LABELS[h]}, {k}", v, "", dy.label)
    for cond, r in (results.hanyang.iterrows() if results.hanyang is not None else ()):
        add(f"median per-file 5th-percentile range error, {cond}", r.pq_err_m, "m", results.hanyang_label)
        add(f"median per-file median range error, {cond}", r.median_err_m, "m", results.hanyang_label)
    return out


def checks(results: Results, fast: bool) -> list[str]:
    """What the methods must do whatever the noise levels; returns the failures (empty: all hold).

    None of these is the paper's number. ``fast`` is accepted for the common signature: the
    checks are directions and coverage rules, the same in both modes.
    """
    syn, t, control = results.synthetic, results.synthetic_table, results.control
    fail = []
    if not (syn.stops.converged.mean() > 0.95 and syn.moves.converged.mean() > 0.95):
        fail.append("the resolution routine converges on more than 95 % of stops and walks")
    n_walk = syn.track[syn.track.kind == "move"].groupby("heuristic").size()
    if n_walk.nunique() != 1:
        fail.append(f"every estimator is scored on the same walk packets: {n_walk.to_dict()}")
    three = [h for h in PAPER_RANKING if h in t.index]
    if not t.loc[three, "stop_median_m"].min() < t.loc["none", "stop_median_m"]:
        fail.append("with NLOS outliers in the ranges, some pruning heuristic beats plain NLS")
    for h in ("robust_mean", "residual"):
        if h in control.index and not control.loc[h, "all_median_m"] <= 1.25 * control.loc["none", "all_median_m"]:
            fail.append(f"outlier-free ranges: {LABELS[h]} drops only good ranges and may lose their efficiency, not "
                        f"more ({control.loc[h, 'all_median_m']:.3f} vs {control.loc['none', 'all_median_m']:.3f} m)")
    if "percentile" in control.index and not (control.loc["percentile", "stop_median_m"]
                                              > control.loc["none", "stop_median_m"]):
        fail.append("a 5th percentile of a symmetric error is short by design: on outlier-free ranges it must lose "
                    "to plain NLS")
    if results.lias_static is not None:
        for k, e in results.lias_static.epochs.items():
            if e.n_epochs.nunique() != 1:
                fail.append(f"LIAS static {k}: every estimator scored on the same epochs")
    return fail
