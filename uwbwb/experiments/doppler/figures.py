"""Figure builders of notebook 04 (paper 003, Figs 3–6). Each takes ``ax=`` and returns its Axes."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ... import sampling as smp
from ...models import doppler as dm
from ...metrics import interval_text
from ...plotting import color_for
from .study import distinct_counts

__all__ = ["ghost_panel", "space_figure", "cuts_figure", "tracks_figure", "clouds_figure", "NEAR_REFERENCE",
           "far_positions", "lap", "plan", "no_samples"]

_GHOST = "#3182bd"
#: Share of a panel's half-width within which a sample counts as *at* the reference: a panel whose samples all
#: lie that close gets an inset zoom (at the panel's scale they would sit inside the reference marker), and a
#: position farther than this (25 cm on the ±5 m position panels) is counted apart, away from the reference.
NEAR_REFERENCE = 0.05
#: Half-width of the position panels (m) and of the velocity panels (m/s).
LIMITS = {"position": 5.0, "velocity": 3.0}
#: Lower-left corners (axes fraction) an inset zoom may take, in order of preference.
_CORNERS = ((0.73, 0.72), (0.09, 0.09), (0.73, 0.09), (0.09, 0.72))


def far_positions(samples: smp.GhostSamples, *, radius_m: float = NEAR_REFERENCE * LIMITS["position"]) -> int:
    """Distinct sample positions farther than ``radius_m`` from the reference position (the reference is no sample)."""
    if len(samples) == 0:
        return 0
    pos = np.unique(samples.pos_m, axis=0)
    return int(np.count_nonzero(np.linalg.norm(pos - dm.REFERENCE_POS_M, axis=1) > radius_m))


def _ax(ax):
    return plt.subplots(figsize=(4, 4))[1] if ax is None else ax


def lap(ax, study, label=None, *, beacons: bool = False):
    """One lap of the study's track in the truth colour (the base of Fig 6 a and b, and of the filter panel), and
    the beacons as stars when ``beacons``."""
    t = np.linspace(0, study.track.length_m / study.track.speed_mps, 400)
    lap = study.track.pos_m(t)
    ax.plot(lap[:, 0], lap[:, 1], color="#000000", linewidth=1.0, label=label)
    if beacons:
        b = study.model.beacons.pos_m
        ax.plot(b[:, 0], b[:, 1], "*", color="#000000", markersize=9, label="beacons")
    return ax


def plan(ax, title: str):
    """Finish a Fig 6 plan view: equal axes in metres, the title, the legend."""
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    return ax


def ghost_panel(samples: smp.GhostSamples, what: str, *, beacons=None, weak_dir=None, ax=None, title: str = "",
                lim: float | None = None):
    """X–Y projection of ghost samples: ``what`` is ``"position"`` or ``"velocity"``.

    The reference pair (the truth, not a sample) is the open circle, drawn beneath the samples; when every
    sample lies within :data:`NEAR_REFERENCE` of the panel's half-width of it (at the panel's scale they
    would sit inside the circle), an inset zooms in: the samples' offsets from the reference in cm (cm/s),
    drawn above a small ``+`` for the reference, its title saying how close they all are. Beacons are
    stars (position panels); ``weak_dir`` (3,) draws a line through the reference (the weakest direction of
    the information matrix, or ``V_ref`` on velocity panels).
    """
    ax = _ax(ax)
    pts = samples.pos_m if what == "position" else samples.vel_mps
    ref = dm.REFERENCE_POS_M if what == "position" else dm.REFERENCE_VEL_MPS
    lim = lim if lim is not None else LIMITS[what]
    ax.plot(pts[:, 0], pts[:, 1], ".", color=_GHOST, markersize=1.5, alpha=0.5, rasterized=True, zorder=3)
    if beacons is not None:
        ax.plot(beacons[:, 0], beacons[:, 1], "*", color="#000000", markersize=10, label="beacons")
    line = None
    if weak_dir is not None:
        d = np.asarray(weak_dir, float)[:2]
        if np.linalg.norm(d) > 0:
            line = d / np.linalg.norm(d)
            d = line * 2 * lim
            ax.plot([ref[0] - d[0], ref[0] + d[0]], [ref[1] - d[1], ref[1] + d[1]], "--", color="#d62728",
                    linewidth=1.0)
    # the reference as an open circle beneath the samples, so that samples near it stay visible
    ax.plot(ref[0], ref[1], "o", markerfacecolor="none", markeredgecolor="#000000", markersize=12, zorder=2)
    if len(pts):
        reach = float(np.max(np.linalg.norm(pts[:, :2] - np.asarray(ref)[:2], axis=1)))
        if reach < NEAR_REFERENCE * lim:      # every sample inside the circle at this scale: zoom in
            _zoom(ax, 100 * (pts[:, :2] - np.asarray(ref)[:2]), 100 * reach, what, lim, ref, beacons, line)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    unit = "m" if what == "position" else "m/s"
    ax.set_xlabel(f"{'x' if what == 'position' else 'vx'} ({unit})")
    ax.set_ylabel(f"{'y' if what == 'position' else 'vy'} ({unit})")
    ax.set_title(title, fontsize=9)
    return ax


def _zoom(ax, offsets_cm, reach_cm, what, lim, ref, beacons, line):
    """Inset of ``ax``: the samples' offsets from the reference (cm or cm/s) above a small ``+`` at the reference.

    Placed in the corner of the panel (a 25 % square, room left for its labels) that covers the fewest beacons, not the reference, and
    preferably not the dashed line.
    """
    size, unit = 0.25, ("cm" if what == "position" else "cm/s")
    marks = np.empty((0, 2)) if beacons is None else np.asarray(beacons, float)[:, :2]
    ref2 = np.asarray(ref, float)[:2]
    costs = []
    for corner in _CORNERS:
        lo = -lim + 2 * lim * np.asarray(corner)
        hi = lo + 2 * lim * size
        n_marks = np.count_nonzero(np.all((marks >= lo) & (marks <= hi), axis=1))
        covers_ref = bool(np.all((ref2 >= lo) & (ref2 <= hi)))
        c = (lo + hi) / 2 - ref2
        crossed = line is not None and abs(c[0] * line[1] - c[1] * line[0]) < 0.75 * (hi - lo)[0]
        costs.append(10 * covers_ref + 3 * n_marks + int(crossed))
    corner = _CORNERS[int(np.argmin(costs))]
    ins = ax.inset_axes([*corner, size, size])
    ins.plot(0.0, 0.0, "+", color="#000000", markersize=7, zorder=2)
    ins.plot(offsets_cm[:, 0], offsets_cm[:, 1], ".", color=_GHOST, markersize=3, alpha=0.7, zorder=3)
    half = max(1.25 * reach_cm, 0.5)
    ins.set_xlim(-half, half)
    ins.set_ylim(-half, half)
    ins.set_aspect("equal")
    ins.tick_params(labelsize=5, length=2, pad=1)
    axis = ("x", "y") if what == "position" else ("vx", "vy")
    ins.set_xlabel(f"Δ{axis[0]} ({unit})", fontsize=5, labelpad=0)
    ins.set_ylabel(f"Δ{axis[1]} ({unit})", fontsize=5, labelpad=0)
    ins.set_title(f"zoom: all within {reach_cm:.1f} {unit}", fontsize=6, pad=2)
    return ins


def space_figure(runs_by_threshold: dict[float, smp.SamplerResult], model: dm.DopplerModel, *, pos_dir=None,
                 vel_dir=None, suptitle: str = ""):
    """Figs 3 / 4: one column per threshold, positions on top, velocities below. Returns the Figure.

    ``runs_by_threshold`` maps each threshold to the conditional-sampler run made for it
    (:func:`~.study.figure_samples`). Every kept draw under the threshold is drawn once
    (nothing is resampled); under each panel: the number of distinct samples, of distinct
    positions (draws of one position share it), of those positions away from the reference
    (:func:`far_positions`; the reference itself is no sample) and the fraction with its 95 %
    interval. A panel without samples says so.
    """
    n = len(runs_by_threshold)
    fig, axes = plt.subplots(2, n, figsize=(3.3 * n, 7.2), squeeze=False)
    for j, (tau, res) in enumerate(runs_by_threshold.items()):
        s = res.samples.below(tau)
        n_s, n_p = distinct_counts(s)
        e = res.estimate(tau)
        ghost_panel(s, "position", beacons=model.beacons.pos_m, weak_dir=pos_dir, ax=axes[0, j],
                    title=f"({'abcd'[j]}) δ < {100 * tau:g} cm")
        ghost_panel(s, "velocity", weak_dir=vel_dir, ax=axes[1, j])
        iv = " " + interval_text(100 * e.ci_low, 100 * e.ci_high, ".2g", none="(no interval)")
        far = f"{far_positions(s)} of them > {100 * NEAR_REFERENCE * LIMITS['position']:g} cm from the reference"
        axes[1, j].set_title(f"{n_s} distinct samples, {n_p} positions,\n{far}\nfraction {100 * e.fraction:.2g} %{iv}",
                             fontsize=8)
        if n_s == 0:
            no_samples(axes[:, j])
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    fig.tight_layout()
    return fig


def no_samples(axes):
    """Write "no sample under this threshold" across each of ``axes``."""
    for ax in axes:
        ax.text(0.5, 0.5, "no sample under\nthis threshold", transform=ax.transAxes, ha="center", va="center",
                fontsize=9, color="#d62728")


def cuts_figure(df, *, threshold_cm: float = 6.0, ax=None):
    """Fig 5: δ (cm) along the line, one curve per fixed velocity, and the threshold line."""
    ax = _ax(ax)
    s = df["s (m)"]
    for col in df.columns[1:]:
        ax.plot(s, df[col], label=col, linewidth=1.2)
    ax.axhline(threshold_cm, color="#9e9e9e", linestyle="--", linewidth=1.0, label=f"{threshold_cm:g} cm")
    ax.set_xlabel("distance along the line from the reference point (m)")
    ax.set_ylabel("δ (cm)")
    ax.set_ylim(0, max(4 * threshold_cm, 1.0))
    ax.legend(fontsize=8)
    return ax


def tracks_figure(study, variant: str = "Doppler", *, kept=None, n_runs: int = 5, ax=None):
    """Fig 6(a): the rectangle (clockwise), five PF runs between the two corners, and the MH-EKF.

    ``kept`` (``{"PF keeps track": words, "MH-EKF keeps track": words}``, this recording's row of
    :func:`~.facts.track_cells`: each cell in the words of its verdict, the PF's withheld while its particle count is
    not shown to converge) puts each cell into its filter's legend entry, and into the title which one did not keep
    track."""
    kept = {} if kept is None else dict(kept)
    said = {m: f" ({kept[f'{m} keeps track']} on this recording)" if f"{m} keeps track" in kept else ""
            for m in ("PF", "MH-EKF")}
    ax = lap(_ax(ax), study, label="truth (clockwise)", beacons=True)
    runs = study.pf[variant]
    t0, t1 = study.snapshots_s
    sel = (runs.t_s >= t0 - 1.5) & (runs.t_s <= t1 + 0.5)
    for r in range(min(n_runs, runs.n_runs)):
        ax.plot(runs.pos_m[r, sel, 0], runs.pos_m[r, sel, 1], color=color_for("PF"), linewidth=0.8, alpha=0.8,
                label=f"PF runs{said['PF']}" if r == 0 else "_nolegend_")
    kf = study.kf[variant]
    selk = (kf.t_s >= t0 - 1.5) & (kf.t_s <= t1 + 0.5)
    ax.plot(kf.pos_m[selk, 0], kf.pos_m[selk, 1], color=color_for("MH-EKF"), linewidth=1.0,
            label=f"MH-EKF{said['MH-EKF']}")
    for k, tk in enumerate(study.snapshots_s):
        p = study.track.pos_m(tk)
        ax.plot(p[0], p[1], "o", markerfacecolor="none", markeredgecolor="#000000", markersize=10)
    lost = [m for m, v in said.items() if "does not keep track" in v]
    return plan(ax, f"{variant}: tracks between the two corners" + (f"; {' and '.join(lost)} lost track" if lost else ""))


def clouds_figure(study, variant: str = "Doppler", *, ax=None):
    """Fig 6(b): every run's position at the two snapshots (3 s apart), with the truth."""
    ax = lap(_ax(ax), study)
    colors = ("#3182bd", "#31a354")
    for k, tk in enumerate(study.snapshots_s):
        c = study.cloud(variant, k)
        p = study.track.pos_m(tk)
        ax.plot(c[:, 0], c[:, 1], ".", color=colors[k], markersize=2, alpha=0.6,
                label=f"t = {tk:.1f} s ({c.shape[0]} runs)")
        ax.plot(p[0], p[1], "x", color="#000000", markersize=10, markeredgewidth=2)
    return plan(ax, f"{variant}: PF positions at two corners")
