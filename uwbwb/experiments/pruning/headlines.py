"""Notebook 02's summary rows and its checks, from one :class:`Results` record of the run.

:func:`headline_rows` declares the rows (quantity, value, unit, data, kind, paper value): every
value came out of the method on the run's data (*reproduced*); the paper's statements sit beside
them as ``paper_value``, never as a pass bound. :func:`checks` lists what the methods must do
whatever the noise levels (none of them is the paper's number); :func:`add_rows` fills a
:class:`uwbwb.metrics.Summary`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .scoring import LABELS, PAPER_RANKING, POINT, rank_heuristics
from .sections import LiasDynamic, LiasStatic
from .study import SyntheticResult

__all__ = ["Results", "add_rows", "checks", "headline_rows", "rows"]


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
        :func:`.study.outlier_free_control` of the same configuration.
    lias_static, lias_dynamic
        :func:`.sections.lias_static` / :func:`.sections.lias_dynamic` (None: no LIAS data).
    hanyang
        :func:`.scoring.hanyang_table` of the Hanyang static files (None: no data).
    hanyang_label
        Its data label.
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


def _fin(x) -> bool:
    return x is not None and np.isfinite(x)


def headline_rows(*, synthetic: pd.DataFrame, synthetic_dim: int, synthetic_3d: pd.DataFrame | None = None,
                  lias_static: dict | None = None, static_label: str | None = None,
                  lias_dynamic: dict | None = None, dyn_label: str | None = None,
                  hanyang: pd.DataFrame | None = None, hy_label: str | None = None) -> list[dict]:
    """The notebook's headline numbers as ``Summary.add`` keyword dicts, each with its ``kind``.

    Every value here came out of the method on the run's data (``kind="reproduced"``);
    the paper's statements sit beside them as ``paper_value`` (the ranking, "90 %
    under 4 m"), never as a pass bound.

    Parameters
    ----------
    synthetic
        :func:`heuristic_summary` of the fair synthetic comparison (stops, walks, track).
    synthetic_dim
        Its geometry (2: known mount height, 3: no height).
    synthetic_3d
        Optionally the other geometry's summary (3-D rows: horizontal and height errors).
    lias_static
        ``{"raw": (heuristic_summary, epoch_summary), "LOSO calibrated": (...)}``.
    lias_dynamic
        ``{ranges: (pieces median table, epoch_summary, run_coverage)}``.
    hanyang
        :func:`hanyang_table`.
    """
    rows = []

    def add(quantity, value, unit, data, paper_value=None):
        if _fin(value):
            rows.append({"quantity": quantity, "value": float(value), "unit": unit, "data": data,
                         "kind": "reproduced", "paper_value": paper_value})

    geo = "known height" if synthetic_dim == 2 else "3-D, no height"
    t = synthetic
    for h, r in t.iterrows():
        lab = LABELS[h]
        add(f"median stationary error, {lab} ({geo})", r.get("stop_median_m"), "m", "synthetic")
        add(f"90th-percentile stationary error, {lab} ({geo})", r.get("stop_p90_m"), "m", "synthetic")
        add(f"median walk velocity error, {lab} ({geo})", r.get("vel_err_median_mps"), "m/s", "synthetic")
        add(f"median walk speed ratio (estimated / true), {lab} ({geo})", r.get("speed_ratio_median"), "",
            "synthetic")
        add(f"90 % of all distance errors under, {lab} ({geo}, covered packets)", r.get("all_p90_m"), "m",
            "synthetic", 4.0 if h == "residual" else None)
        add(f"median of all distance errors, {lab} ({geo}, covered packets)", r.get("all_median_m"), "m",
            "synthetic")
        add(f"packet coverage, {lab} ({geo})", r.get("coverage"), "", "synthetic")
    for h, v in rank_heuristics(t).items():
        add(f"rank by median stationary error among the three heuristics (1 = best), {LABELS[h]} ({geo})", v, "",
            "synthetic", {"residual": 1, "robust_mean": 2, "percentile": 3}[h])
    if {"residual", POINT} <= set(t.index):
        add(f"90 % of all distance errors, residual pruning minus point-based ({geo})",
            t.loc["residual", "all_p90_m"] - t.loc[POINT, "all_p90_m"], "m", "synthetic")
    if synthetic_3d is not None:
        for h, r in synthetic_3d.iterrows():
            lab = LABELS[h]
            add(f"median stationary error, {lab} (3-D, no height)", r.get("stop_median_m"), "m", "synthetic")
            add(f"median stationary height error |dz|, {lab} (3-D, no height)", r.get("stop_err_z_median_m"),
                "m", "synthetic")
            add(f"median stationary 3-D error, {lab} (3-D, no height)", r.get("stop_err_3d_median_m"), "m",
                "synthetic")
            add(f"90 % of all distance errors under, {lab} (3-D, no height, covered packets)", r.get("all_p90_m"),
                "m", "synthetic")
    if lias_static is not None:
        for k, (hs, es) in lias_static.items():
            for h, r in hs.iterrows():
                add(f"median stationary error, {LABELS[h]}, {k}", r.get("stop_median_m"), "m", static_label)
                add(f"90th-percentile stationary error, {LABELS[h]}, {k}", r.get("stop_p90_m"), "m", static_label)
            for h, v in rank_heuristics(hs).items():
                add(f"rank by median stationary error among the three heuristics (1 = best), {LABELS[h]}, {k}",
                    v, "", static_label, {"residual": 1, "robust_mean": 2, "percentile": 3}[h])
            for h, r in es.iterrows():
                add(f"median per-epoch error, {LABELS[h]}, {k}", r.median_m, "m", static_label)
                add(f"epoch coverage, {LABELS[h]}, {k}", r.coverage, "", static_label)
    if lias_dynamic is not None:
        for k, (pt, es, cov) in lias_dynamic.items():
            for h, r in pt.iterrows():
                add(f"median segment position error, {LABELS[h]}, {k}", r.mean_err_m, "m", dyn_label)
                add(f"median segment velocity error, {LABELS[h]}, {k}", r.vel_err_mps, "m/s", dyn_label)
                add(f"median speed ratio (estimated / true), {LABELS[h]}, {k}", r.speed_ratio, "", dyn_label)
            for h, r in es.iterrows():
                add(f"median per-epoch error on the straight pieces, {LABELS[h]}, {k}", r.median_m, "m", dyn_label)
                add(f"90th-percentile per-epoch error on the straight pieces, {LABELS[h]}, {k}", r.p90_m, "m",
                    dyn_label)
            for h, v in cov.items():
                add(f"fraction of the run's epochs with a position, {LABELS[h]}, {k}", v, "", dyn_label)
    if hanyang is not None:
        for cond, r in hanyang.iterrows():
            add(f"median per-file 5th-percentile range error, {cond}", r.pq_err_m, "m", hy_label)
            add(f"median per-file median range error, {cond}", r.median_err_m, "m", hy_label)
    return rows


def rows(results: Results) -> list[dict]:
    """:func:`headline_rows` of a :class:`Results` (the 3-D rows only when the ranked comparison is 2-D)."""
    st, dy = results.lias_static, results.lias_dynamic
    dy_runs = dy.runs if dy is not None else {}
    return headline_rows(
        synthetic=results.synthetic_table, synthetic_dim=results.synthetic_dim,
        synthetic_3d=results.other_table if results.synthetic_dim == 2 else None,
        lias_static={k: (st.table.loc[k], st.epochs[k]) for k in st.runs} if st is not None else None,
        static_label=st.label if st is not None else None,
        lias_dynamic={k: (dy.table.loc[k], *dy.epochs[k]) for k in dy_runs} if dy_runs else None,
        dyn_label=dy.label if dy_runs else None,
        hanyang=results.hanyang, hy_label=results.hanyang_label)


def add_rows(results: Results, summary) -> None:
    """Add every headline row of ``results`` to ``summary`` (:class:`uwbwb.metrics.Summary`)."""
    for row in rows(results):
        summary.add(**row)


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
