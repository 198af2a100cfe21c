"""Notebook 03's figures: scenario floor plans, TDoA covariance, calibration curves, paths and CDFs.

Every function draws into ``ax=`` (or makes its own figure) and returns it; colours are
the package's fixed estimator colours (:data:`uwbwb.plotting.COLORS`).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from ... import plotting
from ...models.motion import MOTION_MODELS
from ...sim import walk
from ...types import Trajectory
from .results import MODELS, TagResults, ekf_name

__all__ = ["scenario_figure", "covariance_figure", "calibration_figure", "paths_figure", "cdf_figure"]


def scenario_figure(config: walk.WalkScenario, *, ax=None, truth: Trajectory | None = None):
    """Floor plan of a simulated scenario: anchors, obstacles (grey: low, black: full height) and the path."""
    ax = plotting.floor_plan(config.anchors, ax=ax)
    for o in config.obstacles:
        tall = o.height_m >= 1.9
        ax.plot([o.x0_m, o.x1_m], [o.y0_m, o.y1_m], color="#000000" if tall else "#9e9e9e",
                linewidth=2.5 if tall else 1.5, solid_capstyle="butt")
    xy, _ = walk.path_points(config.waypoints_m, config.corner_radius_m)
    ax.plot(np.r_[xy[:, 0], xy[0, 0]], np.r_[xy[:, 1], xy[0, 1]], color="#bdbdbd", linestyle=":", label="path")
    if truth is not None:
        ax.plot(truth.pos_m[:, 0], truth.pos_m[:, 1], color=plotting.color_for("truth"), linewidth=1, label="truth")
    ax.set_title(f"{config.name}: {len(config.anchors)} anchors, obstacles (black ≥ 1.9 m tall, grey lower)")
    ax.legend(loc="best", fontsize="small")
    return ax



def covariance_figure(empirical: np.ndarray, model: np.ndarray, labels: Sequence[str], *, title: str = ""):
    """Empirical TDoA error covariance beside the reference-correlated model, in cm², same colour scale."""
    fig, axes = plt.subplots(1, 2, figsize=(8.4, 3.8))
    vmax = 1e4 * max(np.abs(empirical).max(), np.abs(model).max())
    for ax, M, name in zip(axes, (empirical, model), ("empirical (truth)", "model diag(σ²) + σ_ref² 11ᵀ")):
        im = ax.imshow(1e4 * M, cmap="RdBu_r", vmin=-vmax, vmax=vmax)
        ax.set_xticks(range(len(labels)), labels)
        ax.set_yticks(range(len(labels)), labels)
        ax.set_title(name, fontsize="medium")
        ax.set_xlabel("anchor of the TDoA")
        ax.set_ylabel("anchor of the TDoA")
    fig.colorbar(im, ax=axes, label="cm²", shrink=0.85)
    if title:
        fig.suptitle(title)
    return fig


def calibration_figure(curves: pd.DataFrame, *, best: Mapping[str, float] | None = None,
                       paper: Mapping[str, float] | None = None, models: Sequence[str] = MODELS,
                       title: str | None = None):
    """CEP95 against driving standard deviation, one panel per motion model (thesis Table 1 procedure).

    Each run/tag is a thin line; the mean over them (what the tuning minimises)
    is thick; ``best`` is marked and ``paper`` drawn as a dashed vertical line.
    Returns the Figure.
    """
    fig, axes = plt.subplots(1, len(models), figsize=(4.2 * len(models), 3.4), sharey=True, squeeze=False)
    for ax, m in zip(axes[0], models):
        sub = curves[curves.model == m]
        color = plotting.color_for(ekf_name(m))
        for (run, tag), g in sub.groupby(["run", "tag"]):
            ax.plot(g.sigma, g.cep95_m, color=color, alpha=0.35, linewidth=1, marker=".")
        mean = sub.groupby("sigma")["cep95_m"].mean()
        ax.plot(mean.index, mean.values, color=color, linewidth=2.2, label=f"{ekf_name(m)} mean")
        if best is not None and m in best:
            ax.plot([best[m]], [mean.loc[best[m]]], marker="*", markersize=13, color="#000000", linestyle="none",
                    label=f"best {best[m]:.3g} {MOTION_MODELS[m].sigma_unit}")
        if paper is not None and m in paper:
            ax.axvline(paper[m], color="#555555", linestyle="--", linewidth=1,
                       label=f"thesis {paper[m]:g} {MOTION_MODELS[m].sigma_unit}")
        ax.set_xscale("log")
        ax.set_xlabel(f"driving σ of {MOTION_MODELS[m].driven} ({MOTION_MODELS[m].sigma_unit})")
        ax.set_title(f"{m}: white {MOTION_MODELS[m].driven}")
        ax.legend(fontsize="small")
    axes[0, 0].set_ylabel("CEP95 (m)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def paths_figure(res: TagResults, names: Sequence[str] = ("EKF-RW", "LS", "raw"), *, ax=None,
                 t_range_s: tuple[float, float] | None = None):
    """Paths of the chosen estimators against truth on the floor plan (thesis Figs 5, 7, 9 / 6, 8, 10)."""
    trajs = {"truth": res.run.truth, **{n: res.estimates(n).to_trajectory(n) for n in names}}
    if t_range_s is not None:
        trajs = {k: v.between(*t_range_s) for k, v in trajs.items()}
    ax = plotting.trajectories(trajs, ax=ax, anchors=res.run.anchors)
    ax.set_title(f"{res.run.name}, {res.run.tag}")
    return ax


def cdf_figure(res: TagResults, names: Sequence[str] = ("EKF-RW", "EKF-RF", "EKF-RJ", "LS", "raw"), *, ax=None):
    """Empirical CDFs of the horizontal error with CEP50/CEP95 marked, on the epochs the tables score.

    Every estimator's errors are taken at the run's common epochs (:meth:`TagResults.common_errors`),
    so the curves match the CEP95 tables.
    """
    common = res.common_errors()
    ax = plotting.error_cdf({n: common[n] for n in names}, ax=ax)
    ax.set_title(f"{res.run.name}, {res.run.tag} ({100 * res.coverage()['common']:.0f} % of epochs with truth, "
                 "common to all)")
    return ax
