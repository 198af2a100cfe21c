"""Figure helpers shared by all notebooks.

Every function draws into ``ax`` (a new figure's Axes when None) and returns
the Axes; nothing here calls ``plt.show()`` or touches ``rcParams``. Each
estimator keeps one colour across all notebooks (:data:`COLORS`,
:func:`color_for`).
"""

from __future__ import annotations

import zlib
from typing import Mapping

import matplotlib.pyplot as plt
import numpy as np

from . import metrics
from .types import Anchors, Trajectory

__all__ = ["COLORS", "color_for", "error_cdf", "floor_plan", "trajectories"]

#: One fixed colour per estimator name, used by every notebook.
COLORS: dict[str, str] = {
    "truth": "#000000",
    "raw": "#9e9e9e",
    "LS": "#1f77b4",
    "raw LS": "#7f7f7f",
    "TDoA LS": "#aec7e8",
    "NLS": "#17becf",
    "EKF": "#d62728",
    "EKF-RW": "#ff7f0e",
    "EKF-RF": "#2ca02c",
    "EKF-RJ": "#9467bd",
    "PF": "#8c564b",
    "baseline PF": "#e377c2",
    "set-noise PF": "#bcbd22",
    "set-noise KF": "#393b79",
    "baseline KF": "#a6761d",
    "set-noise KF (pooled σ)": "#1b9e77",
    "INS": "#e7ba52",
    "ESKF": "#843c39",
    "UWB-only": "#737373",
    "INS-only": "#8c6d31",
    "loose": "#08519c",
    "tight": "#a50f15",
    "tight (ranges)": "#fb6a4a",
    "calibrated": "#31a354",
    "uncalibrated": "#de2d26",
}

# Colours for names not in COLORS: distinct from the fixed ones, chosen by a
# stable hash of the name so a name keeps its colour between runs.
_FALLBACK = ("#5254a3", "#6b6ecf", "#8ca252", "#b5cf6b", "#bd9e39", "#ad494a", "#d6616b",
             "#7b4173", "#a55194", "#ce6dbd", "#3182bd", "#6baed6", "#e6550d", "#fd8d3c",
             "#756bb1", "#636363")

_LOWER = {k.lower(): v for k, v in COLORS.items()}


def color_for(name: str) -> str:
    """Colour of estimator ``name``: from :data:`COLORS` (case-insensitive), else a
    deterministic fallback (CRC-32 of the name) from a palette disjoint from it."""
    name = str(name)
    if name in COLORS:
        return COLORS[name]
    if name.lower() in _LOWER:
        return _LOWER[name.lower()]
    return _FALLBACK[zlib.crc32(name.encode("utf-8")) % len(_FALLBACK)]


def _is_truth(name: str) -> bool:
    return str(name).lower() == "truth"


def _axes(ax):
    if ax is None:
        _, ax = plt.subplots()
    return ax


_UNIT_SCALE = {"m": 1.0, "cm": 100.0}


def _scale(unit: str) -> float:
    if unit not in _UNIT_SCALE:
        raise ValueError(f"unit must be 'm' or 'cm', got {unit!r}")
    return _UNIT_SCALE[unit]


def floor_plan(anchors, ax=None):
    """Anchor positions seen from above, each labelled with its id.

    Parameters
    ----------
    anchors
        :class:`~uwbwb.Anchors`, or an array ``(n_anchors, 2|3)`` in metres
        (labelled by index).
    ax
        Axes to draw into; a new figure if None.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if isinstance(anchors, Anchors):
        ids, pos = anchors.ids, anchors.pos_m
    else:
        pos = np.asarray(anchors, dtype=float)
        if pos.ndim != 2 or pos.shape[1] not in (2, 3):
            raise ValueError(f"anchors must be Anchors or an array (n_anchors, 2|3), got shape {pos.shape}")
        ids = tuple(str(i) for i in range(pos.shape[0]))
    ax = _axes(ax)
    ax.plot(pos[:, 0], pos[:, 1], linestyle="none", marker="^", markersize=9, color="#000000",
            markerfacecolor="#ffffff", label="anchors", zorder=4)
    for i, (x, y) in zip(ids, pos[:, :2]):
        ax.annotate(i, (x, y), xytext=(5, 5), textcoords="offset points", fontsize="small")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return ax


def trajectories(trajs: Mapping[str, "Trajectory | np.ndarray"], ax=None, *, anchors=None):
    """Horizontal tracks of several estimators (and truth) on one floor plan.

    Parameters
    ----------
    trajs
        Name -> :class:`~uwbwb.Trajectory` or array ``(T, 2|3)`` of positions in
        metres (NaN rows leave gaps). ``"raw"`` is drawn as dots, the others as
        lines; ``"truth"`` is drawn on top of everything.
    ax
        Axes to draw into; a new figure if None.
    anchors
        Optional anchors to draw with :func:`floor_plan`.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax)
    if anchors is not None:
        floor_plan(anchors, ax)
    for k, (name, tr) in enumerate(trajs.items()):
        pos = tr.pos_m if isinstance(tr, Trajectory) else np.asarray(tr, dtype=float)
        if pos.ndim != 2 or pos.shape[1] not in (2, 3):
            raise ValueError(f"trajectory {name!r} must have positions (T, 2|3), got shape {pos.shape}")
        style = dict(color=color_for(name), label=str(name))
        if str(name).lower() == "raw":
            style.update(linestyle="none", marker=".", markersize=3, alpha=0.6, zorder=2)
        else:
            style.update(linewidth=2.0 if _is_truth(name) else 1.3, zorder=5 if _is_truth(name) else 3)
        ax.plot(pos[:, 0], pos[:, 1], **style)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize="small")
    return ax


def error_cdf(errors: Mapping[str, object], ax=None, *, cep=(0.5, 0.95), unit: str = "m",
              nan: str = "raise"):
    """Empirical CDF of each estimator's error with its CEP values marked.

    Parameters
    ----------
    errors
        Name -> errors ``(N,)`` in metres (or a :class:`~uwbwb.metrics.ErrorSeries`).
    ax
        Axes to draw into; a new figure if None.
    cep
        Probability levels to mark: a dashed grey line across the plot at each
        level, a marker where each curve crosses it, and the values in the legend.
    unit
        ``"m"`` or ``"cm"`` for the error axis.
    nan
        ``"raise"``: NaN errors are a ValueError. ``"omit"``: left out, and the
        legend says how many of how many epochs have no error.

    Returns
    -------
    matplotlib.axes.Axes
    """
    scale = _scale(unit)
    levels = tuple(float(p) for p in cep)
    ax = _axes(ax)
    for p in levels:
        ax.axhline(p, color="#bdbdbd", linestyle="--", linewidth=0.8, zorder=1)
    for name, err in errors.items():
        e_all = np.asarray(getattr(err, "err_m", err), dtype=float)
        e, n_nan = metrics._errors(e_all, nan=nan)
        x, F = metrics.ecdf(e)
        values = [metrics.cep(e, p) for p in levels]
        label = f"{name} — " + ", ".join(f"CEP{_pct(p)} {v * scale:.3g} {unit}" for p, v in zip(levels, values))
        if n_nan:
            label += f" ({n_nan} of {e_all.size} missing)"
        c = color_for(name)
        ax.plot(np.r_[0.0, x] * scale, np.r_[0.0, F],
                drawstyle="steps-post", color=c, label=label, zorder=3)
        if levels:
            ax.plot(np.asarray(values) * scale, levels, linestyle="none", marker="o", markersize=5,
                    color=c, label="_nolegend_", zorder=4)
    ax.set_xlabel(f"error ({unit})")
    ax.set_ylabel("fraction of epochs")
    ax.set_ylim(0, 1.02)
    ax.set_xlim(left=0)
    ax.legend(loc="lower right", fontsize="small")
    return ax


def _pct(p: float) -> str:
    v = 100 * p
    return f"{v:.0f}" if abs(v - round(v)) < 1e-9 else f"{v:g}"

