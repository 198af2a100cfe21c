"""Figures of the board: error CDFs of every method in one panel, RMSE against the bound,
error over time with the bound's band. Every function takes ``ax=`` and returns the Axes."""

from __future__ import annotations

from typing import Sequence

import matplotlib.pyplot as plt
import numpy as np

from .. import plotting

__all__ = ["board_figure", "error_cdfs", "error_over_time", "rmse_vs_bound"]


def _methods(board, methods):
    ran = {e.method for e in board.ran()}
    return [m for m in (methods or board.methods) if m in ran]


def error_cdfs(board, ax=None, *, methods: Sequence[str] | None = None, tag: str | None = None, unit: str = "m"):
    """Empirical CDFs of the scored horizontal errors of each method (tags pooled, or ``tag``)."""
    errs = board.errors(tag)
    errs = {m: errs[m] for m in _methods(board, methods) if m in errs and errs[m].size}
    ax = plotting.error_cdf(errs, ax=ax, unit=unit)
    ax.set_title(f"{board.label}{'' if tag is None else ' / ' + tag}: error CDF ({board.mode})", fontsize="medium")
    return ax


def rmse_vs_bound(board, ax=None, *, methods: Sequence[str] | None = None, unit: str = "m"):
    """Bars of each method's RMSE with the common bound (grey tick) and its own bound (black tick);
    RMSE / common bound and coverage written above."""
    scale = 100.0 if unit == "cm" else 1.0
    df = board.table().set_index("method")
    names = [m for m in _methods(board, methods) if np.isfinite(df.loc[m, "rmse_m"])]
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 3.5))
    x = np.arange(len(names))
    rmse = df.loc[names, "rmse_m"].to_numpy(float) * scale
    bound = df.loc[names, "bound_m"].to_numpy(float) * scale
    ax.bar(x, rmse, color=[plotting.color_for(m) for m in names])
    ax.bar([], [], color="white", edgecolor="black", label="RMSE (bar, method's colour)")
    common = df.loc[names, "common_bound_m"].to_numpy(float) * scale
    ax.scatter(x, common, marker="_", s=900, color="#9e9e9e", linewidths=4, zorder=3,
               label="common bound (same for all)")
    ax.scatter(x, bound, marker="_", s=900, color="black", zorder=4, label="its own bound")
    for xi, r, e, c in zip(x, rmse, df.loc[names, "rmse_over_common"].to_numpy(float),
                           df.loc[names, "coverage"].to_numpy(float)):
        text = (f"×{e:.2f}\n" if np.isfinite(e) else "") + f"{c:.0%}"
        ax.annotate(text, (xi, r), ha="center", va="bottom", fontsize="x-small", xytext=(0, 2),
                    textcoords="offset points")
    ax.set_xticks(x, names, rotation=30, ha="right")
    ax.set_xlabel("method")
    ax.set_ylabel(f"RMSE ({unit})")
    top = np.nanmax(np.concatenate([rmse, bound, common])) if len(names) else 1.0
    ax.set_ylim(0, 1.3 * top)
    ax.set_title(f"RMSE vs bounds (×: RMSE / common bound; %: coverage) — {board.mode}", fontsize="medium")
    ax.legend(loc="upper right", fontsize="small", framealpha=0.9)
    return ax


def error_over_time(board, method: str, tag: str | None = None, ax=None, *, unit: str = "m"):
    """One method's error against time with its per-epoch RMSE bound as a shaded band."""
    scale = 100.0 if unit == "cm" else 1.0
    tag = tag or board.tags[0]
    e = board.entry(method, tag)
    if e.skipped:
        raise ValueError(f"{method} did not run on tag {tag}: {e.skipped}")
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 3))
    t = e.estimates.t_s
    err = np.where(e.scored, e.error_m, np.nan) * scale
    bnd = np.sqrt(e.trace_m2("bound")) * scale
    if e.bound is not None:
        ax.fill_between(t, 0, bnd, color="#bdbdbd", alpha=0.6, step="mid", label=f"its own bound ({e.bound.kind})")
    if e.common is not None:
        ax.plot(t, np.sqrt(e.trace_m2("common")) * scale, color="black", linewidth=0.8, linestyle="--",
                label=f"common bound ({e.common.kind})")
    ax.plot(t, err, color=plotting.color_for(method), linewidth=0.9, label=f"{method} error")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"error ({unit})")
    ax.set_ylim(bottom=0)
    ax.set_title(f"{board.label} / {tag}: {method}", fontsize="medium")
    ax.legend(loc="upper right", fontsize="small")
    return ax


def board_figure(board, *, methods: Sequence[str] | None = None):
    """The three panels in one figure (what ``python -m uwbwb score`` writes); the error over time is of the first
    of EKF-RF, EKF-RW and LS that ran (else the first method that ran)."""
    fig = plt.figure(figsize=(13, 8.5))
    gs = fig.add_gridspec(2, 2, height_ratios=[1.2, 1.0])
    error_cdfs(board, fig.add_subplot(gs[0, 0]), methods=methods)
    rmse_vs_bound(board, fig.add_subplot(gs[0, 1]), methods=methods)
    ran = _methods(board, methods)
    time_method = next((m for m in ("EKF-RF", "EKF-RW", "LS") if m in ran), ran[0] if ran else None)
    if time_method is not None:
        error_over_time(board, time_method, ax=fig.add_subplot(gs[1, :]))
    fig.tight_layout()
    return fig
