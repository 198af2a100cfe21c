"""Notebook 06's teaching pieces: the board in class size and the panel (computed from :class:`~.board.Board`
objects; nothing quotes a fixed number). The verdicts are tables: :mod:`.verdicts`.
"""

from __future__ import annotations

from typing import Mapping

import matplotlib.pyplot as plt
import pandas as pd

from .. import widgets
from . import figures
from .board import Board

__all__ = ["METHOD_SETS", "PAIRS", "SHORT_COLUMNS", "panel", "short_table"]

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
