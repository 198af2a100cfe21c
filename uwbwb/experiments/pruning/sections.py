"""Notebook 02's real-data sections as one call each: the LIAS static poses and the LIAS dynamic run.

:func:`lias_static` localises every static pose (raw ranges, and with a leave-one-site-out range
calibration when the session has two sites or more) at the tags' mount height from the same
poses; :func:`lias_dynamic` cuts the dynamic run into straight pieces and fits each (raw ranges,
and calibrated from the static poses of the same room when the anchors match). Each returns a
frozen record of everything the notebook's tables, figures, checks and verdict table read.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ... import metrics, validate
from ...calibration import fit_range_calibration, range_residuals, tag_mount_height
from ...filters.pruning import PruningConfig
from ...geometry import straight_segments
from ...types import Recording
from .real import DynamicResult, run_dynamic_segments, run_static_poses
from .scoring import ESTIMATORS, heuristic_summary
from .study import loso_calibrations

__all__ = ["LiasDynamic", "LiasStatic", "lias_dynamic", "lias_static"]


@dataclass(frozen=True)
class LiasStatic:
    """Notebook 02's LIAS static section (see :func:`lias_static`).

    Attributes
    ----------
    label
        ``"lias-planar-uwb/<session>"``.
    recordings
        The static poses (one stationary segment each).
    mount
        :class:`uwbwb.calibration.MountHeight` of the tags, from these poses.
    range_stats
        :func:`uwbwb.calibration.range_residuals` of every pose (every 10th epoch), the tags localised only.
    runs
        ``{"raw": StaticResult, "calibrated (LOSO)": StaticResult}`` (the second only with two sites or more).
    table
        :func:`.scoring.heuristic_summary` per run, concatenated (outer index: the run's name).
    epochs
        ``{run name: epoch_summary}``: every estimator on the same epochs, coverage beside accuracy.
    """

    label: str
    recordings: list = field(repr=False)
    mount: object
    range_stats: pd.DataFrame = field(repr=False)
    runs: dict = field(repr=False)
    table: pd.DataFrame = field(repr=False)
    epochs: dict = field(repr=False)


def lias_static(recordings, *, label: str, tags, config: PruningConfig, stride: int, loso: bool = True,
                progress: bool = False) -> LiasStatic:
    """Localise every LIAS static pose, raw and with a leave-one-site-out range calibration.

    Parameters
    ----------
    recordings
        Static poses of one session (:func:`uwbwb.datasets.load_lias_room`'s ``static``).
    label
        Data label of the rows, e.g. ``"lias-planar-uwb/8.14"``.
    tags
        Tags to localise.
    config
        Solver/heuristic parameters (2-D: every estimator at the mount height from the same poses,
        :func:`uwbwb.calibration.tag_mount_height`).
    stride
        Every ``stride``-th range epoch of a pose.
    loso
        Also run with the leave-one-site-out calibration (needs two sites or more; False: raw only).
    progress
        ``tqdm`` bars over the poses.
    """
    recs = list(recordings)
    if not recs:
        raise ValueError("recordings: lias_static needs at least one static pose")
    stride = validate.integer("stride", stride, minimum=1)
    tags = tuple(tags)
    mount = tag_mount_height(recs, tags=tags)
    kw = dict(heights_m=mount.per_tag_m, tags=tags, config=config, stride=stride, progress=progress)
    runs = {"raw": run_static_poses(recs, **kw)}
    if loso and len({r.meta.get("site") for r in recs}) >= 2:
        runs["calibrated (LOSO)"] = run_static_poses(recs, calibrations=loso_calibrations(recs, stride=10), **kw)
    stats = pd.concat([range_residuals(r.decimate(10)) for r in recs], ignore_index=True)
    return LiasStatic(label, recs, mount, stats[stats["tag_id"].isin(tags)], runs,
                      pd.concat({k: heuristic_summary(v.poses) for k, v in runs.items()}),
                      {k: metrics.epoch_summary(v.epochs, by="heuristic", order=ESTIMATORS) for k, v in runs.items()})


@dataclass(frozen=True)
class LiasDynamic:
    """Notebook 02's LIAS dynamic section (see :func:`lias_dynamic`).

    Attributes
    ----------
    recording
        The dynamic run.
    segments
        Its straight pieces (:func:`uwbwb.geometry.straight_segments` of the first tag's truth).
    calibration
        Range calibration fitted on the static poses of the same room (None: anchors differ).
    runs
        ``{"raw": DynamicResult, "calibrated": DynamicResult}``, runs with at least one fitted piece only.
    table
        Per run and heuristic, the median over pieces of ``start_err_m, mean_err_m, vel_err_mps,
        speed_ratio`` (None without a run).
    epochs
        ``{run name: (epoch_summary, run_coverage)}``.
    """

    recording: Recording = field(repr=False)
    segments: pd.DataFrame = field(repr=False)
    calibration: object = field(repr=False)
    runs: dict = field(repr=False)
    table: pd.DataFrame | None = field(repr=False)
    epochs: dict = field(repr=False)

    @property
    def label(self) -> str:
        return self.recording.label


def lias_dynamic(recording: Recording, static: LiasStatic, *, tags, config: PruningConfig, stride: int,
                 calibrated: bool = True) -> LiasDynamic:
    """Fit every straight piece of a LIAS dynamic run, raw and calibrated from the static poses.

    Parameters
    ----------
    recording
        The dynamic run (truth used for the pieces and the scoring only).
    static
        :func:`lias_static` of the same room: the mount heights, and the poses a range calibration
        is fitted on when their anchors are the run's (a different recording, so not circular).
    tags, config, stride
        As in :func:`.real.run_dynamic_segments`; the pieces are cut from the first tag's truth.
    calibrated
        Also run with the static poses' calibration (when the anchors match; False: raw only).
    """
    tags = tuple(tags)
    stride = validate.integer("stride", stride, minimum=1)
    segs = straight_segments(recording.truth[tags[0]])
    first = static.recordings[0].anchors
    same_room = recording.anchors.ids == first.ids and np.allclose(recording.anchors.pos_m, first.pos_m)
    cal = fit_range_calibration([r.decimate(10) for r in static.recordings]) if same_room and calibrated else None
    runs: dict[str, DynamicResult] = {}
    if len(segs):
        kw = dict(heights_m=static.mount.per_tag_m, tags=tags, config=config, stride=stride)
        runs["raw"] = run_dynamic_segments(recording, segs, **kw)
        if cal is not None:
            runs["calibrated"] = run_dynamic_segments(recording, segs, calibration=cal, **kw)
    runs = {k: v for k, v in runs.items() if len(v.pieces)}
    cols = ["start_err_m", "mean_err_m", "vel_err_mps", "speed_ratio"]
    table = pd.concat({k: v.pieces.groupby("heuristic")[cols].median() for k, v in runs.items()}) if runs else None
    epochs = {k: (metrics.epoch_summary(v.epochs, by="heuristic", order=ESTIMATORS), v.run_coverage)
              for k, v in runs.items()}
    return LiasDynamic(recording, segs, cal, runs, table, epochs)

