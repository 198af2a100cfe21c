"""Figures of notebook 02 (Zupanec et al.): builders take ``ax=`` and return Axes, or return a Figure
for multi-panel ones."""

from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.ticker import MaxNLocator
import numpy as np
import pandas as pd

from ...models.ranging import NlosRangeModel
from ...plotting import color_for, floor_plan
from ...sim import tours as tours_mod
from .scoring import ESTIMATORS, LABELS, POINT

__all__ = ["HEURISTIC_MARKERS", "heuristic_color", "plot_coverage",
           "plot_error_cdf_percentile", "plot_error_histogram", "plot_hanyang", "plot_polar_errors",
           "plot_robust_mean_cloud", "plot_segment_fits"]

#: Marker per estimator in the polar charts (the paper draws residual pruning as an asterisk).
HEURISTIC_MARKERS = {"none": "o", "percentile": "s", "robust_mean": "^", "residual": "*", POINT: "."}


def heuristic_color(h: str) -> str:
    """Fixed colour of an estimator (plain NLS uses the workbench's ``"NLS"`` colour, the
    point-based baseline the per-epoch ``"LS"`` colour)."""
    return color_for({"none": "NLS", POINT: "LS"}.get(h, LABELS[h]))


def plot_coverage(config: tours_mod.TourConfig = tours_mod.TourConfig(), ax=None, *, tour: int | None = None):
    """Floor plan of the cafeteria: anchors, coverage discs ``R = H tan 60°``, coverage count map, a tour."""
    ax = ax if ax is not None else plt.subplots(figsize=(7, 5))[1]
    anchors = tours_mod.cafeteria_anchors(config)
    X, Y = np.meshgrid(np.linspace(0, config.room_m[0], 121), np.linspace(0, config.room_m[1], 81))
    cnt = tours_mod.coverage_count(np.stack([X, Y], -1), config, anchors)
    im = ax.pcolormesh(X, Y, cnt, cmap="Greys", vmin=0, vmax=len(anchors) + 2, shading="auto", alpha=0.6)
    plt.colorbar(im, ax=ax, label="anchors covering")
    R = tours_mod.coverage_radius_m(config, anchors)
    for p, r in zip(anchors.pos_m, R):
        ax.add_patch(plt.Circle(p[:2], r, fill=False, color="#6b6ecf", lw=0.8, ls="--"))
    floor_plan(anchors, ax)
    ax.set_aspect("equal", adjustable="box")      # the room's extent fixes the limits
    if tour is not None:
        kp = np.asarray(tours_mod.TOURS[tour])
        ax.plot(kp[:, 0], kp[:, 1], "-", color="#000000", lw=1.2)
        for i, (x, y) in enumerate(kp):
            ax.annotate(f"K{i}", (x, y), xytext=(4, -10), textcoords="offset points", fontsize="small")
    ax.set_xlim(0, config.room_m[0])
    ax.set_ylim(0, config.room_m[1])
    return ax


def plot_error_histogram(errors_m, model: NlosRangeModel | None = None, p_nlos: float | None = None,
                         ax=None, *, bias_m: float = 0.0, label: str = "simulated", bins: int = 60):
    """Fig. 4: range-error histogram with the bimodal model density (if given)."""
    ax = ax if ax is not None else plt.subplots()[1]
    e = np.asarray(errors_m, float)
    e = e[np.isfinite(e)]
    ax.hist(e, bins=bins, density=True, color="#bdbdbd", label=f"{label} (n={e.size})")
    if model is not None:
        x = np.linspace(e.min() - 0.5, e.max() + 0.5, 400)
        ax.plot(x, model.error_pdf(x, p_nlos, bias_m=bias_m), color="#000000",
                label=f"model, P(NLOS) = {p_nlos:.2f}")
    ax.set_xlabel("range error (m)")
    ax.set_ylabel("density (1/m)")
    ax.legend(fontsize="small")
    return ax


def plot_error_cdf_percentile(errors_m, ax=None, *, q: float = 5.0, label: str = "errors", color=None,
                              model: NlosRangeModel | None = None, p_nlos: float | None = None,
                              bias_m: float = 0.0):
    """Fig. 5: empirical CDF of range errors with the ``q``-th percentile marked."""
    ax = ax if ax is not None else plt.subplots()[1]
    e = np.sort(np.asarray(errors_m, float)[np.isfinite(errors_m)])
    F = np.arange(1, e.size + 1) / e.size
    c = color or "#636363"
    pq = float(np.percentile(e, q))
    ax.step(e, F, where="post", color=c, label=f"{label}: P{q:g} = {pq:+.2f} m")
    ax.axvline(pq, color=c, ls=":", lw=1)
    if model is not None:
        x = np.linspace(e[0] - 0.5, e[-1] + 0.5, 400)
        ax.plot(x, model.error_cdf(x, p_nlos, bias_m=bias_m), color="#000000", lw=0.8, label="model")
    ax.axhline(q / 100.0, color="#bdbdbd", ls="--", lw=0.8)
    ax.axvline(0.0, color="#000000", lw=0.5)
    ax.set_xlabel("range error (m)")
    ax.set_ylabel("CDF (fraction of ranges)")
    ax.legend(fontsize="small", loc="lower right")
    return ax


def plot_robust_mean_cloud(result, truth_xy=None, ax=None, *, anchors=None):
    """Fig. 6: the pooled k-tuple cloud, the retained cluster and the centroid's path.

    ``result`` is a :class:`~uwbwb.filters.pruning.LocalizationResult` of the robust mean;
    ``anchors`` (optional) are drawn with :func:`uwbwb.plotting.floor_plan`.
    """
    cloud, rm = result.detail
    ax = ax if ax is not None else plt.subplots()[1]
    if anchors is not None:
        floor_plan(anchors, ax)
    P = cloud.pos_m
    ax.plot(P[~rm.kept, 0], P[~rm.kept, 1], ".", ms=2, color="#bdbdbd")
    ax.plot(P[rm.kept, 0], P[rm.kept, 1], ".", ms=2, color="#31a354")
    # legend proxies with readable markers (the cloud itself is drawn with tiny dots)
    ax.plot([], [], "o", ms=5, color="#bdbdbd", label=f"dropped ({(~rm.kept).sum()})")
    ax.plot([], [], "o", ms=5, color="#31a354", label=f"retained ({rm.kept.sum()})")
    ax.plot(rm.history_m[:, 0], rm.history_m[:, 1], "-", color="#d62728", lw=1, label="centroid path")
    ax.plot(*rm.center_m, "o", color="#d62728", mfc="none", ms=9, label="robust mean")
    if truth_xy is not None:
        ax.plot(*np.asarray(truth_xy)[:2], "x", color="#000000", ms=10, mew=2, label="truth")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize="small")
    return ax


def plot_polar_errors(stops: pd.DataFrame, *, by: str = "label", ncols: int = 5, rmax_m: float | None = None,
                      title=None) -> plt.Figure:
    """Fig. 8: one polar chart per stationary point, error direction and size per heuristic.

    The radius is the horizontal error (m, the tick labels carry the unit); the angle is the
    direction of the error vector estimate − truth, 0° along +x, counter-clockwise (as
    :func:`.scoring.score_segment`). Both are written under the charts.

    Parameters
    ----------
    stops
        Rows with ``heuristic, err_m, bearing_deg`` and the grouping column ``by``.
    by
        Column naming the stationary point (``"label"`` for tours, ``"site"`` for LIAS).
    rmax_m
        Common radial limit (default: the largest error).
    """
    groups = list(dict.fromkeys(stops[by]))
    nrows = int(np.ceil(len(groups) / ncols))
    fig = plt.figure(figsize=(3.2 * min(ncols, len(groups)), 3.2 * nrows + 1.2))
    rmax = rmax_m or float(stops["err_m"].max()) * 1.05
    for k, g in enumerate(groups):
        ax = fig.add_subplot(nrows, min(ncols, len(groups)), k + 1, projection="polar")
        sub = stops[stops[by] == g]
        for h in [h for h in ESTIMATORS if h in set(sub.heuristic)]:
            s = sub[sub.heuristic == h]
            ax.plot(np.deg2rad(s.bearing_deg), s.err_m, linestyle="none", marker=HEURISTIC_MARKERS[h],
                    ms=9 if h == "residual" else 6, color=heuristic_color(h), label=LABELS[h], alpha=0.8)
        ax.set_theta_zero_location("E")
        ax.set_theta_direction(1)
        ax.set_rlim(0, rmax)
        ax.yaxis.set_major_locator(MaxNLocator(3))
        ax.yaxis.set_major_formatter(lambda r, _: f"{r:g} m")
        ax.set_title(f"{by} {g}" if by != "label" else str(g), fontsize="small")
        ax.set_xlabel("error direction (°)", fontsize="x-small")
        ax.set_ylabel("horizontal error (m)", fontsize="x-small", labelpad=24)
        ax.tick_params(labelsize="x-small")
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize="small")
    h_in = fig.get_figheight()
    fig.text(0.5, 0.45 / h_in, "radius: horizontal error (m); angle: direction of estimate − truth, 0° = +x, "
             "counter-clockwise", ha="center", fontsize="small")
    if title:
        fig.suptitle(title)
    # fixed margins in inches (a tight layout of polar axes costs a full extra draw)
    fig.subplots_adjust(left=0.6 / fig.get_figwidth(), right=1 - 0.35 / fig.get_figwidth(), bottom=1.05 / h_in,
                        top=1 - 0.75 / h_in, wspace=0.55, hspace=0.55)
    return fig


def plot_segment_fits(moves: pd.DataFrame, stops: pd.DataFrame | None = None, ax=None, *,
                      truth_xy=None, anchors=None, heuristic: str = "residual"):
    """Fig. 9: each walk's fitted line ``P0 -> P0 + v T`` (fading with time) over the true path.

    Parameters
    ----------
    moves, stops
        Rows of one experiment and node (:class:`SyntheticResult` tables or
        :func:`run_dynamic_segments` output); ``stops`` adds the stop estimates.
    truth_xy
        True path ``(N, 2)`` drawn in black.
    anchors
        Drawn with :func:`uwbwb.plotting.floor_plan`.
    heuristic
        Which heuristic's fits to draw.
    """
    ax = ax if ax is not None else plt.subplots(figsize=(7, 5))[1]
    if anchors is not None:
        floor_plan(anchors, ax)
    if truth_xy is not None:
        ax.plot(*np.asarray(truth_xy)[:, :2].T, "-", color="#000000", lw=1.5, label="truth")
    m = moves[moves.heuristic == heuristic].sort_values("t0_s")
    c = heuristic_color(heuristic)
    n = len(m)
    for k, r in enumerate(m.itertuples(index=False)):
        alpha = 0.25 + 0.75 * (k + 1) / max(n, 1)          # later segments drawn stronger
        T = r.t_end_s - r.t0_s
        x1, y1 = r.x0_m + r.vx_mps * T, r.y0_m + r.vy_mps * T
        ax.annotate("", xy=(x1, y1), xytext=(r.x0_m, r.y0_m),
                    arrowprops=dict(arrowstyle="-|>", color=c, alpha=alpha, lw=2))
    ax.plot([], [], color=c, lw=2, label=f"{LABELS[heuristic]} walks")
    if stops is not None and len(stops):
        s = stops[stops.heuristic == heuristic]
        ax.plot(s.x0_m, s.y0_m, linestyle="none", marker=HEURISTIC_MARKERS[heuristic], color=c, ms=9,
                label=f"{LABELS[heuristic]} stops")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize="small", loc="best")
    return ax


def plot_hanyang(samples: pd.DataFrame, pct: pd.DataFrame, axes=None, *, q: float = 5.0) -> np.ndarray:
    """Hanyang static files: error histograms (Fig 4 analogue), CDFs with the ``q``-th percentile (Fig 5
    analogue), and the per-file median and percentile errors against the true range.

    Parameters
    ----------
    samples
        Tidy samples with ``condition, range_error_m`` (:func:`uwbwb.datasets.hanyang.load_static`).
    pct
        :func:`uwbwb.calibration.percentile_by_file` of the same samples (may be empty).
    axes
        Three Axes (default: a new 1 × 3 figure).

    Returns
    -------
    numpy.ndarray
        The three Axes.
    """
    if axes is None:
        _, axes = plt.subplots(1, 3, figsize=(15, 4))
    axes = np.asarray(axes).ravel()
    err = samples["range_error_m"].dropna()
    lo, hi = (np.percentile(err, [0.5, 99.5]) if len(err) else (-1.0, 1.0))
    pad = 0.1 * max(hi - lo, 0.1)
    lim = (lo - pad, hi + pad)                         # the data's range (0.5-99.5 %), not a fixed span
    for cond, color in (("LOS", "#2ca02c"), ("NLOS", "#d62728")):
        e = samples.loc[samples.condition == cond, "range_error_m"].dropna()
        if e.empty:
            continue
        axes[0].hist(e.clip(*lim), bins=np.linspace(*lim, 121), density=True, alpha=0.5, color=color,
                     label=f"{cond} (n={len(e)})")
        plot_error_cdf_percentile(e, ax=axes[1], label=cond, color=color, q=q)
        p = pct[pct.condition == cond].groupby("true_range_m")[["median_err_m", "pq_err_m"]].median() \
            if len(pct) else pd.DataFrame()
        if len(p):
            axes[2].plot(p.index, p.median_err_m, "-", color=color, label=f"{cond} median")
            axes[2].plot(p.index, p.pq_err_m, "--", color=color, label=f"{cond} {q:g}th percentile")
    axes[0].set_xlim(*lim)
    axes[0].set_xlabel("range error (m), outer 1 % piled at the edges")
    axes[0].set_ylabel("density (1/m)")
    axes[0].set_title("Fig 4 analogue: range error")
    axes[1].set_xlim(*lim)
    axes[1].set_title(f"Fig 5 analogue: CDF and {q:g}th percentile")
    axes[2].axhline(0, color="#000000", lw=0.5)
    axes[2].set_xlabel("true range (m)")
    axes[2].set_ylabel("error (m)")
    axes[2].set_title("error vs distance (median over heights)")
    for ax in (axes[0], axes[2]):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize="small")
    return axes

