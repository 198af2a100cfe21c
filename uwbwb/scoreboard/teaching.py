"""Notebook 06's teaching pieces: the board in class size, the panel and the "what you should see"
notes under the panel and the figures (computed from a :class:`~.board.Board`; nothing quotes a fixed
number). The verdicts are tables: :mod:`.verdicts`.
"""

from __future__ import annotations

from typing import Mapping

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from .. import widgets
from . import figures
from .board import Board

__all__ = ["METHOD_SETS", "PAIRS", "SHORT_COLUMNS", "figure_note", "panel", "panel_note", "short_table"]

#: Columns of the class-size board (:func:`short_table`).
SHORT_COLUMNS = ("method", "coverage", "rmse_m", "cep95_m", "common_bound_m", "rmse_over_common", "bound_m",
                 "rmse_over_bound")
#: The comparisons of notebook 06's verdict table (:func:`.verdicts.difference_table`), where both ran.
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
