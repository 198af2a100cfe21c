"""Figures of notebook 05: the paper's Figs 5–9 and the degradation / real-data views.

Every function draws into ``ax`` (or ``axes``) and returns it; colours from
:func:`uwbwb.plotting.color_for`.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ...plotting import color_for
from .study import Comparison

__all__ = ["static_traces", "track", "error_vs_time", "attitude", "bias_estimates"]


def _axes(ax, n=1):
    if ax is None:
        _, ax = plt.subplots(1, n, figsize=(6 * n, 3.5))
    return ax


def _shade(comp: Comparison, ax):
    t = comp.truth.t_s
    for key, colour, label in (("outage", "#fdd0a2", "outage"), ("nlos", "#c6dbef", "BS3 NLOS-biased")):
        m = comp.masks.get(key)
        if m is not None and m.any():
            ax.axvspan(t[m][0], t[m][-1], color=colour, alpha=0.6, label=label, lw=0)


def static_traces(comp: Comparison, names=("UWB-only", "loose", "tight"), axes=None, *, window_m: float = 0.3):
    """Figs 5–6: east and north coordinate against time in the static test (truth dashed)."""
    axes = _axes(axes, 2)
    t = comp.truth.t_s
    for k, (ax, lab) in enumerate(zip(axes, ("east", "north"))):
        for name in names:
            est = comp.estimates[name]
            ax.plot(t, est.pos_m[:, k], color=color_for(name), lw=0.8 if name != "UWB-only" else 0.5,
                    alpha=1.0 if name != "UWB-only" else 0.6, label=name)
        ax.axhline(comp.truth.pos_m[0, k], color="k", ls="--", lw=1, label="truth")
        ax.set_ylim(comp.truth.pos_m[0, k] - window_m, comp.truth.pos_m[0, k] + window_m)
        ax.set_xlabel("t (s)")
        ax.set_ylabel(f"{lab} (m)")
        ax.set_title(f"static test, {lab}ward coordinate")
    axes[0].legend(fontsize=8, loc="upper right")
    return axes


def track(comp: Comparison, names=("UWB-only", "loose", "tight"), ax=None, *, anchors_m=None):
    """Fig. 7: the horizontal track of each method against truth."""
    ax = _axes(ax)
    for name in names:
        p = comp.estimates[name].pos_m
        ax.plot(p[:, 0], p[:, 1], color=color_for(name), lw=0.8 if name != "UWB-only" else 0.4,
                alpha=1.0 if name != "UWB-only" else 0.5, label=name)
    ax.plot(comp.truth.pos_m[:, 0], comp.truth.pos_m[:, 1], "k--", lw=1, label="truth")
    if anchors_m is not None:
        a = np.asarray(anchors_m)
        ax.plot(a[:, 0], a[:, 1], "k^", ms=8, label="stations")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.legend(fontsize=8)
    return ax


def error_vs_time(comp: Comparison, names=("UWB-only", "loose", "tight"), ax=None, *, ylim_m: float | None = 0.5):
    """Fig. 8: horizontal error against time (degradation windows shaded)."""
    ax = _axes(ax)
    _shade(comp, ax)
    t = comp.truth.t_s
    for name in names:
        ax.plot(t, comp.errors(name), color=color_for(name), lw=0.8, label=name)
    if ylim_m:
        ax.set_ylim(0, ylim_m)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.legend(fontsize=8, loc="upper right")
    return ax


def attitude(comp: Comparison, name: str = "tight", ax=None, *, yaw_true_rad=None):
    """Fig. 9: roll, pitch and yaw of ``name`` against time (true yaw dashed where known)."""
    ax = _axes(ax)
    t = comp.truth.t_s
    eul = np.degrees(comp.runs[name].euler_rad)
    for k, (lab, c) in enumerate(zip(("roll", "pitch", "yaw"), ("#2ca02c", "#9467bd", "#d62728"))):
        ax.plot(t, eul[:, k], color=c, lw=1, label=f"{lab} ({name})")
    if yaw_true_rad is not None:
        ax.plot(t, np.degrees(yaw_true_rad), "k--", lw=1, label="true yaw")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("angle (°)")
    ax.legend(fontsize=8)
    return ax


def bias_estimates(comp: Comparison, name: str = "tight", axes=None, *, true_acc=None, true_gyro=None):
    """Estimated accelerometer and gyro biases of ``name`` (true ones dashed where known)."""
    axes = _axes(axes, 2)
    t = comp.truth.t_s
    run = comp.runs[name]
    for k, c in enumerate(("#1f77b4", "#ff7f0e", "#2ca02c")):
        axes[0].plot(t, run.acc_bias_mps2[:, k], color=c, lw=1, label="xyz"[k])
        axes[1].plot(t, np.degrees(run.gyro_bias_radps[:, k]), color=c, lw=1, label="xyz"[k])
        if true_acc is not None:
            axes[0].plot(t, true_acc[:, k], color=c, ls="--", lw=0.8)
        if true_gyro is not None:
            axes[1].plot(t, np.degrees(true_gyro[:, k]), color=c, ls="--", lw=0.8)
    axes[0].set_ylabel("accelerometer bias (m/s²)")
    axes[1].set_ylabel("gyro bias (°/s)")
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.legend(fontsize=8)
    return axes
