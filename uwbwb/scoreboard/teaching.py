"""Notebook 06's teaching pieces: the board in class size, the verdicts as text, the panel and the
notes under it, and why the board's tuned driving noise differs from notebook 03's.

Every sentence here is computed from a :class:`~.board.Board`; nothing quotes a fixed number.
"""

from __future__ import annotations

from typing import Mapping

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from .. import widgets
from . import figures, verdicts
from .board import Board

__all__ = ["METHOD_SETS", "PAIRS", "SHORT_COLUMNS", "figure_note", "findings", "findings_markdown", "panel", "panel_note",
           "short_table", "sigma_w_note"]

#: Columns of the class-size board (:func:`short_table`).
SHORT_COLUMNS = ("method", "coverage", "rmse_m", "cep95_m", "common_bound_m", "rmse_over_common", "bound_m",
                 "rmse_over_bound")
#: The comparisons whose difference the verdicts state (method, against), where both ran.
PAIRS = (("LS", "raw LS"), ("EKF-RF", "LS"), ("EKF-RF", "EKF-RW"), ("NLS", "EKF-RF"), ("tight", "loose"),
         ("tight", "EKF-RF"))
#: Method sets offered by the panel (None: every method on the board).
METHOD_SETS: dict[str, list[str] | None] = {
    "all methods": None,
    "per-epoch fixes (LS family)": ["raw LS", "LS", "TDoA LS"],
    "tracking filters": ["EKF-RW", "EKF-RF", "EKF-RJ", "set-noise KF", "set-noise PF"],
    "best of each family": ["LS", "EKF-RW", "EKF-RF", "set-noise KF", "NLS"],
}


def short_table(board: Board) -> pd.DataFrame:
    """The board's main columns (:data:`SHORT_COLUMNS`), one row per method that ran, rounded for display."""
    df = board.table()
    return df.loc[df["n_scored"] > 0, list(SHORT_COLUMNS)].set_index("method").round(3)


def findings(label: str, board: Board, rng: np.random.Generator) -> str:
    """What one board says: the lowest RMSE, each method placed against the common bound, the
    differences of :data:`PAIRS` with their bootstrap intervals (:mod:`.verdicts`), the notes and the
    methods whose NEES is outside its interval."""
    df = board.table().set_index("method")
    ran = df[df["n_scored"] > 0]
    best = ran["rmse_m"].idxmin()
    lines = [f"**{label}** ({board.mode}): lowest RMSE {best} ({ran.loc[best, 'rmse_m']:.3f} m, common bound "
             f"{ran.loc[best, 'common_bound_m']:.3f} m)."]
    lines += [verdicts.placement_sentence(verdicts.placement_facts(r)) for r in ran.reset_index().itertuples()]
    for a, c in PAIRS:
        if a in ran.index and c in ran.index:
            lines.append(verdicts.difference_sentence(verdicts.difference_facts(board, a, c, rng=rng)))
    for m, r in ran.iterrows():
        if r.note:
            lines.append(f"{m}: {r.note}.")
    inconsistent = [m for m, r in ran.iterrows() if r.nees_ok is False]
    if inconsistent:
        lines.append("Position NEES outside its 95 % interval (the method's covariance does not describe its errors): "
                     + ", ".join(inconsistent) + ".")
    for m, r in df[df["n_scored"] == 0].iterrows():
        lines.append(f"{m}: {r.note}.")
    return "\n\n".join(lines)


def findings_markdown(boards: Mapping[str, Board], *, rng: np.random.Generator, short: bool = False) -> str:
    """:func:`findings` of every board, separated by rules; ``short`` (class mode): the first sentence of
    each board and the differences whose interval excludes 0, at most three per board."""
    if not short:
        return "\n\n---\n\n".join(findings(label, b, rng) for label, b in boards.items())
    out = []
    for label, b in boards.items():
        df = b.table().set_index("method")
        ran = df[df["n_scored"] > 0]
        best = ran["rmse_m"].idxmin()
        text = [f"**{label}** ({b.mode}): lowest RMSE {best} ({ran.loc[best, 'rmse_m']:.3f} m)."]
        for a, c in PAIRS:
            if a in ran.index and c in ran.index and len(text) < 4:
                facts = verdicts.difference_facts(b, a, c, rng=rng)
                if facts.get("verdict") in ("a", "b"):
                    text.append(verdicts.difference_sentence(facts))
        out.append(" ".join(text))
    return "\n\n".join(out)


def panel_note(board: Board) -> str:
    """The "what you should see" under the panel (three lines at most), from ``board``'s numbers."""
    df = board.table().set_index("method")
    ran = df[df["n_scored"] > 0]
    best = ran["rmse_m"].idxmin()
    above = [m for m, r in ran.iterrows() if np.isfinite(r.rmse_over_common) and r.rmse_over_common > 1]
    sets = []
    for label in ("per-epoch fixes (LS family)", "tracking filters"):
        names = [m for m in METHOD_SETS[label] if m in ran.index]
        if names:
            m = ran.loc[names, "rmse_m"].idxmin()
            sets.append(f"*{label}*: best {m}, {ran.loc[m, 'rmse_m']:.3f} m")
    return (f"On {board.label} the CDF furthest left is the most accurate: {best}, RMSE "
            f"{ran.loc[best, 'rmse_m']:.3f} m ({ran.loc[best, 'rmse_over_common']:.2f}× the common bound).\n"
            f"The grey tick (common bound) is the same for every method; {len(above)} of {len(ran)} methods "
            f"stand above it.\n" + ("Method sets — " + "; ".join(sets) + "." if sets else ""))


def panel(boards: Mapping[str, Board]) -> widgets.Panel:
    """Method set, recording and tag → error CDFs and RMSE vs bounds, redrawn from ``boards`` (nothing re-run)."""
    tags = max((len(b.tags) for b in boards.values()), default=1)

    def render(methods, recording, tag_index):
        b = boards[recording]
        tag = b.tags[min(tag_index, len(b.tags) - 1)]
        chosen = METHOD_SETS[methods]
        fig, axes = plt.subplots(1, 2, figsize=(12, 4))
        figures.error_cdfs(b, axes[0], methods=chosen, tag=tag)
        figures.rmse_vs_bound(b, axes[1], methods=chosen)
        fig.tight_layout()
        df = b.table().set_index("method")
        names = [m for m in (chosen or b.methods) if m in df.index and df.loc[m, "n_scored"] > 0]
        best = df.loc[names, "rmse_m"].idxmin() if names else "—"
        return fig, {"tag": tag, "methods shown": len(names), "lowest RMSE": best,
                     "its RMSE (m)": float(df.loc[best, "rmse_m"]) if names else float("nan"),
                     "its RMSE / common bound": float(df.loc[best, "rmse_over_common"]) if names else float("nan")}

    labels = ("first tag", "second tag", "third tag")
    return widgets.Panel("Scoreboard: methods, recording, tag", {
        "methods": widgets.dropdown("method set", list(METHOD_SETS), "all methods"),
        "recording": widgets.dropdown("recording", list(boards), list(boards)[-1]),
        "tag_index": widgets.dropdown("tag", {labels[i] if i < 3 else f"tag {i + 1}": i for i in range(tags)}, 0),
    }, render)


def sigma_w_note(board: Board, model: str = "RJ", *, within: float = 0.05) -> str:
    """Why the board's tuned driving noise of ``EKF-<model>`` need not equal notebook 03's on the same run.

    Computed from the board's tuning record: the pick, its place on the grid, and how flat the
    calibration-part RMSE is around it (the grid values whose RMSE is within ``within`` of the best);
    then what differs from notebook 03's tuning (data part, range calibration, criterion, thinning,
    tags). Empty when the board has no tuning of that EKF.
    """
    p = board.calibration.params(f"EKF-{model}")
    if "sigma_w" not in p or "grid" not in p:
        return ""
    grid, cost = np.asarray(p["grid"], float), np.asarray(p["grid_rmse_m"], float)
    k = int(np.argmin(cost))
    near = grid[cost <= (1 + within) * cost[k]]
    unit = {"RW": "m/s", "RF": "m/s²", "RJ": "m/s³"}.get(model, "")
    flat = (f"{near.size} of the {grid.size} values ({near.min():.3g} to {near.max():.3g} {unit}) are within "
            f"{within:.0%} of the best calibration RMSE ({cost[k]:.3f} m)" if near.size > 1 else
            f"no other grid value is within {within:.0%} of the best calibration RMSE ({cost[k]:.3f} m)")
    step = grid[1] / grid[0] if grid.size > 1 else float("nan")
    return (f"The board tunes EKF-{model}'s σ_w to {grid[k]:.3g} {unit} (value {k + 1} of {grid.size} on a "
            f"log grid {grid[0]:.3g}–{grid[-1]:.3g}, ×{step:.2g} per step); {flat}. Notebook 03 tunes the same "
            f"filter differently: it minimises CEP95 (the board: RMSE), on ranges calibrated on a static session "
            f"of the room (the board: on {board.calibration.source} itself, with per-anchor noise from its "
            f"residuals), decimating the run with one step for all tags (the board: each tag thinned to "
            f"{board.calibration.rate_hz:.3g} Hz), over all tags of the run's first half (the board: tags "
            f"{', '.join(board.tags)}). Where the curve is this flat, those choices move the pick by a grid "
            f"step or more without changing the error much — the two values are different tunings, not a "
            f"contradiction.")


def figure_note(board: Board, mc_eff: pd.DataFrame, method: str = "EKF-RF") -> str:
    """The "what you should see" under the synthetic run's figures: the Monte Carlo RMSE / own bound of
    the methods whose model is the simulator's (``mc_eff``: :func:`.synthetic.efficiency_summary`) and how
    often ``method``'s error lies under its bound's band in the error-over-time panel."""
    eff = mc_eff.set_index("method")
    parts = [f"{m} {r.efficiency:.2f} ± {r.efficiency_se:.2f}" for m, r in eff.iterrows()]
    lines = [f"Monte Carlo RMSE / own bound over {int(eff['runs'].max())} runs: {', '.join(parts)} "
             f"(1: the method reaches its bound)."]
    e = board.entry(method, board.tags[0])
    band = np.sqrt(e.bound_trace_m2)
    ok = e.scored & np.isfinite(band)
    if ok.any():
        share = float(np.mean(e.error_m[ok] <= band[ok]))
        lines.append(f"Lower panel: {method}'s error lies under its bound's band at {share:.0%} of the epochs "
                     f"(about 63 % for a round Gaussian error that just meets its bound).")
    return "\n".join(lines)
