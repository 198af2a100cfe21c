"""Figures of notebook 05: the paper's Figs 5–9 and the degradation / real-data views.

Every function draws into ``ax`` (or ``axes``) and returns it; colours from
:func:`uwbwb.plotting.color_for`.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ...plotting import color_for
from ...filters.alignment import Comparison

__all__ = ["static_traces", "track", "error_vs_time", "attitude", "bias_estimates"]


#: The UWB-only fixes (notebook 05's name, the board's): drawn thin and beneath the filters, spikes counted.
FIXES = ("UWB-only", "LS")


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
            ax.plot(t, est.pos_m[:, k], color=color_for(name), lw=0.8 if name not in FIXES else 0.5,
                    alpha=1.0 if name not in FIXES else 0.6, label=name)
        ax.axhline(comp.truth.pos_m[0, k], color="k", ls="--", lw=1, label="truth")
        ax.set_ylim(comp.truth.pos_m[0, k] - window_m, comp.truth.pos_m[0, k] + window_m)
        ax.set_xlabel("t (s)")
        ax.set_ylabel(f"{lab} (m)")
        ax.set_title(f"static test, {lab}ward coordinate")
    axes[0].legend(fontsize=8, loc="upper right")
    return axes


def _truth_xy(comp: Comparison) -> np.ndarray:
    """Truth positions with NaN where the epoch is not scored (e.g. no motion-capture sample)."""
    p = comp.truth.pos_m[:, :2].astype(float)
    return np.where(comp.masks.get("scored", np.ones(len(p), bool))[:, None], p, np.nan)


def track(comp: Comparison, names=("UWB-only", "loose", "tight"), ax=None, *, anchors_m=None, margin_m: float = 0.5):
    """Fig. 7: the horizontal track of each method against truth (drawn only where it exists).

    The axes hold the truth, the anchors and every method but UWB-only; UWB-only fixes
    outside them (multipath spikes) are counted in a note instead of stretching the axes.
    """
    ax = _axes(ax)
    truth = _truth_xy(comp)
    keep = [truth]
    for name in names:
        p = comp.estimates[name].pos_m
        ax.plot(p[:, 0], p[:, 1], color=color_for(name), lw=0.8 if name not in FIXES else 0.4,
                alpha=1.0 if name not in FIXES else 0.5, label=name, zorder=1 if name in FIXES else 2)
        if name not in FIXES:
            keep.append(p[:, :2])
    ax.plot(truth[:, 0], truth[:, 1], "k--", lw=1, label="truth", zorder=3)
    if anchors_m is not None:
        a = np.asarray(anchors_m)
        ax.plot(a[:, 0], a[:, 1], "k^", ms=8, label="anchors")
        keep.append(a[:, :2])
    pts = np.vstack(keep)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts):
        lo, hi = pts.min(axis=0) - margin_m, pts.max(axis=0) + margin_m
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        for fix in (n for n in names if n in FIXES):
            u = comp.estimates[fix].pos_m[:, :2]
            out = int(np.sum(np.any((u < lo) | (u > hi), axis=1) & np.all(np.isfinite(u), axis=1)))
            if out:
                ax.text(0.01, 0.01, f"{out} {fix} fixes outside the axes", transform=ax.transAxes, fontsize=8)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(f"{comp.label}: horizontal track")
    ax.legend(fontsize=8)
    return ax


def error_vs_time(comp: Comparison, names=("UWB-only", "loose", "tight"), ax=None):
    """Fig. 8: horizontal error against time (degradation windows shaded).

    UWB-only is drawn thin and beneath the filters so that its multipath spikes do not hide
    them; the y axis stops at 1.2 × the largest error of the other methods and the UWB-only
    epochs above it are counted in a note.
    """
    ax = _axes(ax)
    _shade(comp, ax)
    t = comp.truth.t_s
    scored = comp.masks.get("scored", np.ones(len(t), bool))
    finite = [e[np.isfinite(e)] for e in (comp.errors(n)[scored] for n in names if n not in FIXES)]
    top = 1.2 * max((float(e.max()) for e in finite if e.size), default=1.0)
    for name in names:
        e = np.where(scored, comp.errors(name), np.nan)
        uwb = name in FIXES
        ax.plot(t, e, color=color_for(name), lw=0.5 if uwb else 0.9, alpha=0.5 if uwb else 1.0, label=name,
                zorder=1 if uwb else 2)
        if uwb:
            above = int(np.sum(e > top))
            if above:
                ax.text(0.01, 0.97, f"{name}: {above} epochs above {top:.2g} m (max {np.nanmax(e):.2g} m)",
                        transform=ax.transAxes, fontsize=8, va="top")
    ax.set_ylim(0, top)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.set_title(f"{comp.label}: horizontal error")
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
    ax.set_title(f"{comp.label}: attitude of {name}")
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
    axes[0].set_title(f"{comp.label}: accelerometer bias of {name}")
    axes[1].set_title(f"{comp.label}: gyro bias of {name}")
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.legend(fontsize=8)
    return axes
