"""Notebook 02 on real poses and runs: every LIAS static pose as a stationary segment, every straight
piece of a LIAS dynamic run as a walk.

:func:`run_static_poses` localises every tag of every pose with every heuristic and the point-based
baseline at the tag's mount height; :func:`run_dynamic_segments` fits ``(P0, v)`` to each straight
piece (:func:`uwbwb.geometry.straight_segments`). Both return an epoch table for
:func:`uwbwb.metrics.epoch_summary`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...filters.pruning import HEURISTICS, PruningConfig
from ...geometry import point_fixes
from ...types import Recording
from .scoring import POINT, score_segment

__all__ = ["DynamicResult", "StaticResult", "run_dynamic_segments", "run_static_poses"]


@dataclass(frozen=True)
class StaticResult:
    """Output of :func:`run_static_poses`.

    Attributes
    ----------
    poses
        One row per (pose, tag, heuristic): ``recording, site, yaw_deg, tag``, the row of
        :func:`.scoring.score_segment` (``x0_m, y0_m, err_m, bearing_deg, n_used``...), ``true_x_m, true_y_m,
        n_epochs, calibrated``.
    epochs
        The epoch table: every estimator's horizontal error at every (thinned) range
        epoch of every pose -- a heuristic's one position per pose scored at each of
        its epochs, the point-based fix of each epoch (NaN where none):
        ``recording, site, tag, heuristic, t_s, err_m``.
    """

    poses: pd.DataFrame
    epochs: pd.DataFrame


def _check_heights(heights_m, tags) -> dict:
    if heights_m is None:
        raise ValueError("pass heights_m={tag: mount height in metres} (from calibration data or the "
                         "dataset's description, not from the evaluated recording's truth)")
    missing = [t for t in tags if t not in heights_m]
    if missing:
        raise ValueError(f"heights_m lacks tags {missing}")
    return {t: float(heights_m[t]) for t in tags}


def run_static_poses(recordings, *, heights_m: dict, tags=None, config: PruningConfig = PruningConfig(dim=2),
                     stride: int = 10, calibrations: dict | None = None, progress: bool = False) -> StaticResult:
    """Each static pose file is a stationary segment: localise every tag with every heuristic.

    Parameters
    ----------
    recordings
        Static recordings with constant per-tag truth (:func:`uwbwb.datasets.lias.load_static`).
    heights_m
        ``{tag: mount height}``, metres: the height every 2-D estimator (and the
        robust mean's triplets) solves at. It must come from calibration data or
        the dataset's description, never from the evaluated recording's truth.
    tags
        Tags to use (default all).
    config
        Heuristic/solver parameters. Default ``dim=2``: the LIAS anchors and tags
        all sit close to one horizontal plane, so the height is not observable
        from ranges; the tag is held at its mount height.
    stride
        Use every ``stride``-th range epoch (10 gives ~10 Hz from the ~100 Hz
        logs, close to the paper's 7.7 packets/s, and keeps the 56-triplet clouds small).
    calibrations
        Optional ``{site: RangeCalibration}`` applied to the poses of that site
        (see :func:`loso_calibrations`); None for raw ranges.
    progress
        ``tqdm`` bar over the poses.
    """
    it = recordings
    if progress:
        from tqdm.auto import tqdm
        it = tqdm(recordings, desc="poses")
    rows, epochs = [], []
    for rec in it:
        site = rec.meta.get("site")
        cal = None if calibrations is None else calibrations.get(site)
        if calibrations is not None and cal is None:
            raise ValueError(f"{rec.label}: no calibration for site {site!r}")
        use = rec.tags if tags is None else tags
        heights = _check_heights(heights_m, use)
        for tag in use:
            log = rec.ranges_of(tag, cal).select(slice(None, None, int(stride)))
            true = rec.truth[tag].pos_m[0]
            fits, ep = score_segment(log, rec.anchors, HEURISTICS, config, still=True, z_m=heights[tag],
                                     true_xy=true[:2], keys={"recording": rec.name, "site": site, "tag": tag})
            epochs += ep
            rows += [{"recording": rec.name, "site": site, "yaw_deg": rec.meta.get("yaw_deg"), "tag": tag, **row,
                      "true_x_m": true[0], "true_y_m": true[1], "n_epochs": len(log), "calibrated": cal is not None}
                     for row, _ in fits]
    ep_df = pd.concat(epochs, ignore_index=True) if epochs else pd.DataFrame(
        columns=["recording", "site", "tag", "t_s", "heuristic", "err_m"])
    return StaticResult(pd.DataFrame(rows), ep_df)



# =========================================================================== LIAS dynamic


@dataclass(frozen=True)
class DynamicResult:
    """Output of :func:`run_dynamic_segments`.

    Attributes
    ----------
    pieces
        One row per (segment, tag, heuristic): ``start_err_m`` (at ``t0``),
        ``mean_err_m`` (line vs truth at every range epoch), ``vel_err_mps``,
        ``speed_ratio``, ``heading_err_deg``, estimate and truth velocity.
    epochs
        The epoch table over the pieces' (thinned) range epochs with truth: every
        heuristic's line and the point-based fixes, ``segment, tag, heuristic, t_s,
        err_m`` (NaN = no position).
    run_coverage
        Per estimator, the fraction of the whole run's (thinned) range epochs with
        truth that got a position: the trajectory fits cover the straight pieces
        only, the point-based fixes every epoch they can solve.
    """

    pieces: pd.DataFrame
    epochs: pd.DataFrame
    run_coverage: pd.Series


def run_dynamic_segments(rec: Recording, segments: pd.DataFrame, *, heights_m: dict, tags=None,
                         heuristics=("none", "robust_mean", "residual"),
                         config: PruningConfig = PruningConfig(dim=2), stride: int = 1,
                         calibration=None, point_baseline: bool = True) -> DynamicResult:
    """Fit ``(P0, v)`` to each straight piece of a dynamic run and compare with the truth.

    Parameters
    ----------
    rec
        Dynamic recording with per-tag truth on the range clock.
    segments
        Pieces from :func:`uwbwb.geometry.straight_segments` (the centroid or one tag's truth).
    heights_m, tags, heuristics, config
        As in :func:`run_static_poses` (the 5th percentile does not apply to motion).
    stride
        Use every ``stride``-th range epoch.
    calibration
        Optional :class:`~uwbwb.calibration.RangeCalibration` applied to the ranges.
    point_baseline
        Also fix every epoch by multilateration at the same height.
    """
    if "percentile" in heuristics:
        raise ValueError("the percentile heuristic applies to stationary segments only")
    rows, epochs, n_run = [], [], 0
    n_pos = dict.fromkeys([POINT] * point_baseline + list(heuristics), 0)    # the run's epochs with a position
    use = rec.tags if tags is None else tags
    heights = _check_heights(heights_m, use)
    for tag in use:
        full = rec.ranges_of(tag, calibration)
        full = full.select(slice(None, None, int(stride)))
        tr = rec.truth[tag]
        full = full.between(tr.t_s[0], tr.t_s[-1])              # epochs with truth
        z = heights[tag]
        n_run += len(full)
        if point_baseline and len(full):
            P_all = point_fixes(full.range_m, rec.anchors, dim=2, z_m=z)
            n_pos[POINT] += int(np.isfinite(P_all[:, 0]).sum())
        for seg in segments.itertuples(index=False):
            sel = (full.t_s >= seg.t_start_s) & (full.t_s <= seg.t_end_s)
            log = full.select(sel)
            if len(log) == 0:
                continue
            fits, ep = score_segment(log, rec.anchors, heuristics, config, still=False, z_m=z,
                                     true_xy=tr.interp(log.t_s)[:, :2], keys={"segment": seg.segment, "tag": tag},
                                     point=point_baseline, fixes=P_all[sel] if point_baseline else None)
            epochs += ep
            for row, _ in fits:
                n_pos[row["heuristic"]] += len(log)
                rows.append({"segment": seg.segment, "tag": tag, **row, "calibrated": calibration is not None})
    ep_df = pd.concat(epochs, ignore_index=True) if epochs else pd.DataFrame(
        columns=["segment", "tag", "t_s", "heuristic", "err_m"])
    run_cov = pd.Series({h: n / n_run if n_run else np.nan for h, n in n_pos.items()}, name="run_coverage")
    return DynamicResult(pd.DataFrame(rows), ep_df, run_cov)
