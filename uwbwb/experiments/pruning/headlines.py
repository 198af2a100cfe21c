"""Notebook 02's summary rows and its checks, from one dict of the run's results.

:func:`rows` reads the rows declared as data (quantity, column, unit; the kind and paper value beside): every
value came out of the method on the run's data (*reproduced*); the paper's statements sit beside
them as ``paper_value``, never as a pass bound. :func:`checks` lists what the methods must do
whatever the noise levels (none of them is the paper's number).
"""

from __future__ import annotations

import numpy as np

from .scoring import LABELS, PAPER_RANKING, POINT
from .verdicts import noise

__all__ = ["checks", "rows"]


#: The summary rows per estimator, declared as data: (quantity, column of its table, unit); ``{lab}`` is the
#: estimator (or the Hanyang condition), ``{geo}`` the geometry, ``{k}`` the LIAS run, ``{note}`` the assumed noise beside the paper's 4 m.
SYNTHETIC = (("median stationary error, {lab} ({geo})", "stop_median_m", "m"),
             ("90th-percentile stationary error, {lab} ({geo})", "stop_p90_m", "m"),
             ("median walk velocity error, {lab} ({geo})", "vel_err_median_mps", "m/s"),
             ("median walk speed ratio (estimated / true), {lab} ({geo})", "speed_ratio_median", ""),
             ("90 % of all distance errors under, {lab} ({geo}, covered packets{note})", "all_p90_m", "m"),
             ("median of all distance errors, {lab} ({geo}, covered packets)", "all_median_m", "m"),
             ("packet coverage, {lab} ({geo})", "coverage", ""))
THREE_D = (("median stationary error, {lab} (3-D, no height)", "stop_median_m", "m"),
           ("median stationary height error |dz|, {lab} (3-D, no height)", "stop_err_z_median_m", "m"),
           ("median stationary 3-D error, {lab} (3-D, no height)", "stop_err_3d_median_m", "m"),
           ("90 % of all distance errors under, {lab} (3-D, no height, covered packets)", "all_p90_m", "m"),
           ("packet coverage, {lab} (3-D, no height)", "coverage", ""))
LIAS_POSES = (("median stationary error, {lab}, {k}", "stop_median_m", "m"),
              ("90th-percentile stationary error, {lab}, {k}", "stop_p90_m", "m"))
LIAS_EPOCHS = (("median per-epoch error, {lab}, {k}", "median_m", "m"), ("epoch coverage, {lab}, {k}", "coverage", ""))
LIAS_PIECES = (("median segment position error, {lab}, {k}", "mean_err_m", "m"),
               ("median segment velocity error, {lab}, {k}", "vel_err_mps", "m/s"),
               ("median speed ratio (estimated / true), {lab}, {k}", "speed_ratio", ""))
LIAS_PIECE_EPOCHS = (("median per-epoch error on the straight pieces, {lab}, {k}", "median_m", "m"),
                     ("90th-percentile per-epoch error on the straight pieces, {lab}, {k}", "p90_m", "m"))
HANYANG = (("median per-file 5th-percentile range error, {lab}", "pq_err_m", "m"),
           ("median per-file median range error, {lab}", "median_err_m", "m"))
#: The paper's statements beside our rows: its ranking, and "90 % of all distance errors under 4 m" (residual).
PAPER_RANK = {"residual": 1, "robust_mean": 2, "percentile": 3}
PAPER_P90_M = {"residual": 4.0}


def rows(results: dict) -> list[dict]:
    """The notebook's headline numbers as :meth:`uwbwb.metrics.Summary.add` keyword dicts, each with its kind.

    ``results`` holds ``synthetic_table`` (:func:`.scoring.heuristic_summary` of the ranked synthetic comparison),
    ``synthetic_dim`` (its geometry: 2, known mount height; 3, no height), ``rankings``
    (:func:`.verdicts.rankings`: the ranks the verdict table's ranking rows show, ties where an interval does not
    resolve the order) and, where run, ``other_table`` (the same
    packets in the other geometry), ``lias_static`` and ``lias_dynamic`` (:mod:`.sections`), ``hanyang`` (per
    condition, the median over the static files of ``median_err_m`` and ``pq_err_m``) with ``hanyang_label``, and
    ``tour`` (the simulator configuration). Every value came out of the method on the run's data
    (``kind="reproduced"``); the paper's statements sit beside them as ``paper_value`` (the ranking, "90 % under
    4 m"), never as a pass bound. Residual pruning's 90th percentile, set beside the paper's 4 m, names the
    simulated noise it follows from. The 3-D rows come only when the ranked comparison is 2-D (``other_table`` is
    then 3-D).
    """
    out = []

    def add(quantity, value, unit, data, paper_value=None):
        if value is not None and np.isfinite(value):
            out.append({"quantity": quantity, "value": float(value), "unit": unit, "data": data,
                        "kind": "reproduced", "paper_value": paper_value})

    def table(t, decl, data, note="", **fmt):
        for h, r in t.iterrows():
            for q, col, unit in decl:
                add(q.format(lab=LABELS.get(h, h), note=note if h == "residual" else "", **fmt), r.get(col), unit,
                    data, PAPER_P90_M.get(h) if "{note}" in q else None)

    geo = "known height" if results["synthetic_dim"] == 2 else "3-D, no height"
    t, tour = results["synthetic_table"], results.get("tour")
    table(t, SYNTHETIC, "synthetic", geo=geo, note="; follows from assumed noise: " + (
        noise(tour) if tour is not None else "our simulator's (uw.sim.tours.TourConfig)"))
    ranks = results["rankings"]
    rank = "rank by median stationary error among the three heuristics (1 = best; tied where not resolved)"
    for h, v in ranks["synthetic"].rank.items():
        add(f"{rank}, {LABELS[h]} ({geo}){ranks['synthetic'].note()}", v, "", "synthetic", PAPER_RANK[h])
    if {"residual", POINT} <= set(t.index):
        add(f"90 % of all distance errors, residual pruning minus point-based ({geo})",
            t.loc["residual", "all_p90_m"] - t.loc[POINT, "all_p90_m"], "m", "synthetic")
    if results["synthetic_dim"] == 2 and results.get("other_table") is not None:
        table(results["other_table"], THREE_D, "synthetic")
    st = results.get("lias_static")
    for k in (st.runs if st is not None else ()):
        table(st.table.loc[k], LIAS_POSES, st.label, k=k)
        for h, v in ranks[k].rank.items():
            add(f"{rank}, {LABELS[h]}, {k}{ranks[k].note()}", v, "", st.label, PAPER_RANK[h])
        table(st.epochs[k], LIAS_EPOCHS, st.label, k=k)
    dy = results.get("lias_dynamic")
    for k in (dy.runs if dy is not None else ()):
        es, cov = dy.epochs[k]
        table(dy.table.loc[k], LIAS_PIECES, dy.label, k=k)
        table(es, LIAS_PIECE_EPOCHS, dy.label, k=k)
        for h, v in cov.items():
            add(f"fraction of the run's epochs with a position, {LABELS[h]}, {k}", v, "", dy.label)
    if results.get("hanyang") is not None:
        table(results["hanyang"], HANYANG, results["hanyang_label"])
    return out


def checks(results: dict, fast: bool) -> list[str]:
    """What the methods must do whatever the noise levels; returns the failures (empty: all hold).

    ``results`` as in :func:`rows`, with ``synthetic`` (:class:`~.study.SyntheticResult` of the ranked comparison)
    and ``control`` (:func:`.scoring.heuristic_summary` of the same tours without NLOS). None of these is the
    paper's number. ``fast`` is accepted for the common signature: the checks are directions and coverage rules,
    the same in both modes.
    """
    syn, t, control = results["synthetic"], results["synthetic_table"], results["control"]
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
    if results.get("lias_static") is not None:
        for k, e in results["lias_static"].epochs.items():
            if e.n_epochs.nunique() != 1:
                fail.append(f"LIAS static {k}: every estimator scored on the same epochs")
    return fail
