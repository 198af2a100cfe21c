"""Figures of notebook 01 (paper 000); every builder takes ``ax=`` and returns the Axes."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ... import plotting
from ...calibration import location_statistics
from ...types import SetFixLog
from ...sim import setnoise as sim
from .study import BAND_MPS, BASE_KF, BASE_PF, FILTERS, RAW, SET_KF, SET_KF_POOLED, SET_PF, set_shares


def _set_colours(n: int):
    import matplotlib

    return [matplotlib.colormaps["tab10"](i) for i in range(n)]


def plot_facility(facility: sim.Facility, ax=None, *, off_track_xy_m=None):
    """Floor plan: sensors, walls, calibration locations and the test track (cf. paper Figs. 2, 7).

    ``off_track_xy_m`` (two ends, metres) adds the track away from the calibration locations,
    and circles of one multipath correlation length show how far a calibration location reaches.
    """
    from matplotlib.patches import Circle

    ax = plotting._axes(ax)
    cfg = facility.config
    x0, x1, y0, y1 = cfg.lab_m
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="#bdbdbd", linewidth=1, label="lab")
    for i, (wx1, wy1, wx2, wy2) in enumerate(cfg.walls_m):
        ax.plot([wx1, wx2], [wy1, wy2], color="#636363", linewidth=4, solid_capstyle="butt",
                label="walls (NLOS)" if i == 0 else "_nolegend_")
    plotting.floor_plan(facility.sensor_xyz_m, ax)
    cal = np.asarray(cfg.calibration_xy_m)
    ax.plot(cal[:, 0], cal[:, 1], "s", color="#31a354", markersize=6, label="calibration locations")
    for i, c in enumerate(cal):
        ax.add_patch(Circle(c, cfg.multipath_corr_m, fill=False, color="#31a354", linestyle=":",
                            label=f"multipath correlation length ({100 * cfg.multipath_corr_m:.0f} cm)"
                            if i == 0 else "_nolegend_"))
    a, b = np.asarray(cfg.track_start_xy_m), np.asarray(cfg.track_end_xy_m)
    ax.plot([a[0], b[0]], [a[1], b[1]], color="#000000", linewidth=2.5, label="test track")
    if off_track_xy_m is not None:
        a, b = np.asarray(off_track_xy_m, float)
        ax.plot([a[0], b[0]], [a[1], b[1]], color="#000000", linewidth=2.5, linestyle="--",
                label="track away from calibration")
    ax.plot(*cfg.fig3_xy_m, "+", color="#d62728", markersize=12, mew=2, label="Fig. 3 location")
    ax.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize="small")
    ax.set_title("simulated facility")
    return ax


def plot_fixes(log: SetFixLog, ax=None, *, n_sets: int = 5, unit: str = "cm"):
    """Fig. 3: fixes of a static tag, coloured by their (most frequent) sets; truth as '+'."""
    ax = plotting._axes(ax)
    s = plotting._scale(unit)
    fr = log.set_frequency()
    top = fr["set_id"].iloc[:n_sets].tolist()
    other = ~np.isin(log.set_id, top)
    ax.plot(log.pos_m[other, 0] * s, log.pos_m[other, 1] * s, ".", color="#bdbdbd", markersize=3,
            label=f"other sets ({other.sum()})")
    for c, (sid, lab, n) in zip(_set_colours(n_sets), fr[["set_id", "label", "count"]].iloc[:n_sets].itertuples(index=False)):
        m = log.set_id == sid
        ax.plot(log.pos_m[m, 0] * s, log.pos_m[m, 1] * s, ".", color=c, markersize=3, label=f"'{lab}' ({n})")
    tx, ty = log.truth_m[0] * s
    ax.plot(tx, ty, "+", color="#000000", markersize=14, mew=2, label="truth")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.legend(fontsize="x-small", loc="best")
    return ax


def plot_set_frequency(log: SetFixLog, ax=None, *, n_bars: int = 12):
    """Fig. 4: how often each set occurs, most frequent first, with the top-five share."""
    ax = plotting._axes(ax)
    fr = log.set_frequency().iloc[:n_bars]
    colours = _set_colours(5) + ["#bdbdbd"] * max(0, len(fr) - 5)
    ax.bar(range(len(fr)), fr["count"], color=colours[:len(fr)])
    ax.set_xticks(range(len(fr)))
    ax.set_xticklabels(fr["label"], rotation=60, fontsize="small")
    ax.set_xlabel("sensor set (sensors in descending order)")
    ax.set_ylabel("number of fixes")
    sh = set_shares(log)
    ax.set_title(f"top set {100 * sh['top1_share']:.1f} %, top five {100 * sh['top5_share']:.1f} % "
                 f"of {len(log)} ({sh['n_sets']} sets)")
    return ax


def plot_set_ellipses(log: SetFixLog, ax=None, *, n_sets: int = 4, n_sigma: float = 3.0, unit: str = "cm"):
    """Fig. 5: the noise models ``(μ, σ)`` of the most frequent sets at one location as n-σ ellipses.

    The per-axis model has no correlation, so the ellipses are axis-aligned, centred on
    truth + μ with semi-axes ``n_sigma · σ``.
    """
    from matplotlib.patches import Ellipse

    ax = plotting._axes(ax)
    s = plotting._scale(unit)
    st = location_statistics(log.error_m, log.set_id, np.zeros(len(log))).iloc[:n_sets]
    truth = log.truth_m[0]
    ax.plot(log.pos_m[:, 0] * s, log.pos_m[:, 1] * s, ".", color="#d9d9d9", markersize=2, label="fixes")
    for c, row in zip(_set_colours(n_sets), st.itertuples(index=False)):
        centre = (truth + [row.mu_x_m, row.mu_y_m]) * s
        lab = log.set_frequency().set_index("set_id").loc[row.set_id, "label"]
        ax.add_patch(Ellipse(centre, 2 * n_sigma * row.sigma_x_m * s, 2 * n_sigma * row.sigma_y_m * s,
                             fill=False, color=c, linewidth=1.8, label=f"'{lab}' (n = {row.n})"))
        ax.plot(*centre, "o", color=c, markersize=4)
    ax.plot(*(truth * s), "+", color="#000000", markersize=14, mew=2, label="truth")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_title(f"{n_sigma:g}σ ellipses of the {n_sets} most frequent sets")
    ax.legend(fontsize="x-small", loc="best")
    return ax


def plot_trace(estimates: dict, ax=None, *, index=None, axis: int = 0, unit: str = "cm",
               names=(RAW, BASE_PF, SET_PF)):
    """Fig. 8: one coordinate (default X) against measurement index for truth, raw and filters."""
    ax = plotting._axes(ax)
    s = plotting._scale(unit)
    n = len(estimates["truth"])
    idx = np.arange(n) if index is None else np.arange(n)[index]
    ax.plot(idx, estimates["truth"][idx, axis] * s, color=plotting.color_for("truth"), linewidth=1.5, label="truth")
    for name in names:
        est = estimates[name]
        style = dict(linestyle="none", marker=".", markersize=4) if name == RAW else dict(linewidth=1.3)
        ax.plot(idx, est[idx, axis] * s, color=plotting.color_for(name), label=name, **style)
    ax.set_xlabel("measurement index")
    ax.set_ylabel(f"{'XY'[axis]} ({unit})")
    ax.legend(fontsize="small", loc="best")
    return ax


def plot_sweep(df: pd.DataFrame, recording: str, ax=None, *, names=FILTERS, unit: str = "cm", band=BAND_MPS,
               y_max=None):
    """Fig. 9 (one recording): mean error against σ_d; PF curves with ±2 standard errors.

    ``y_max`` (in ``unit``) fixes the top of the axes; points above it are not dropped but drawn
    as ▲ on the top edge, and a box in the upper right says, per curve, how high they go and at
    which σ_d, so a breakdown (the PF at small σ_d) stays visible.
    """
    ax = plotting._axes(ax)
    s = plotting._scale(unit)
    d = df[df["recording"] == recording]
    off = []                                     # curves with points above y_max: what the box says
    for name in names:
        g = d[d["filter"] == name].sort_values("sigma_d_mps")
        if g.empty:
            continue
        x = g["sigma_d_mps"].to_numpy() * 100
        y = g["mean_error_m"].to_numpy() * s
        colour, dash = plotting.color_for(name), {BASE_KF: "--", SET_KF: "--", SET_KF_POOLED: ":"}.get(name, "-")
        ax.plot(x, y, color=colour, label=name, linestyle=dash, marker="" if name == RAW else ".")
        e = 2 * g["sem_error_m"].to_numpy() * s
        if np.any(e > 0):
            ax.fill_between(x, y - e, y + e, color=colour, alpha=0.2, linewidth=0)
        if y_max is not None and np.any(y > y_max):
            ax.plot(x[y > y_max], np.full(np.count_nonzero(y > y_max), 0.97 * y_max), "^", color=colour,
                    markersize=8, clip_on=False, label="_nolegend_", zorder=5)
            off.append(f"▲ {name}: up to {y[y > y_max].max():.0f} {unit} (σ_d ≤ {x[y > y_max].max():g} cm/s)")
    if band is not None:
        ax.axvspan(100 * band[0], 100 * band[1], color="#f0f0f0", zorder=0)
    if y_max is not None:
        ax.set_ylim(0, y_max)
    if off:
        ax.text(0.98, 0.95, "off the axes:\n" + "\n".join(off), transform=ax.transAxes, ha="right", va="top",
                fontsize="x-small", bbox=dict(facecolor="white", edgecolor="#bdbdbd", alpha=0.9))
    ax.set_xlabel("σ_d (cm/s)")
    ax.set_ylabel(f"mean error ({unit})")
    ax.set_title(recording)
    return ax


def plot_pf_kf_gap(df: pd.DataFrame, ax=None, *, unit: str = "cm"):
    """RMS distance between the set-noise PF and the exact KF against K, with a 1/√K guide."""
    ax = plotting._axes(ax)
    s = plotting._scale(unit)
    K = df["n_particles"].to_numpy(float)
    g = df["rms_gap_m"].to_numpy() * s
    ax.loglog(K, g, "o-", color="#bcbd22", label="set-noise PF − set-noise KF (RMS)")
    ax.loglog(K, g[0] * np.sqrt(K[0] / K), ":", color="#636363", label="∝ 1/√K")
    ax.set_xlabel("number of particles K")
    ax.set_ylabel(f"RMS gap ({unit})")
    ax.legend(fontsize="small")
    return ax
