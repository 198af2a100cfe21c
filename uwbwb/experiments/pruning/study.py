"""Notebook 02 study: trajectory NLS with pruning heuristics (Zupanec et al.), run on every data set.

Everything the notebook computes, grouped by data:

* **Synthetic cafeteria** (:mod:`uwbwb.sim.tours`): :func:`run_synthetic` localises
  every stop and walk of every tour/pace/node with every heuristic *and* with the
  point-based baseline (a multilateration per packet, as the LIPS system reports
  positions), all from the same packets; :func:`run_recordings` re-runs the same
  simulated recordings in another geometry (2-D at the known mount height, or 3-D
  without height information); :func:`heuristic_summary` condenses them.
* **LIAS static poses**: :func:`run_static_poses` treats each pose file as one
  stationary segment; :func:`loso_calibrations` fits range calibrations leaving
  each site out.
* **LIAS dynamic run**: :func:`uwbwb.geometry.straight_segments` cuts the motion-capture track into
  constant-velocity pieces; :func:`run_dynamic_segments` fits ``(P0, v)`` per piece.
* **Hanyang static**: :func:`uwbwb.calibration.percentile_by_file` -- where the 5th percentile of a
  stationary range sample lands relative to the true range, LOS vs NLOS.

Every estimator of one comparison gets the same geometry (node height known, or not
at all) and is scored on the same epochs: each result carries an *epoch table* (one
row per estimator and scored epoch, ``err_m`` NaN where the estimator produced
nothing) that :func:`uwbwb.metrics.epoch_summary` turns into coverage beside accuracy.
"""


from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...calibration import fit_range_calibration
from ...filters.pruning import HEURISTICS, PruningConfig
from ...sim import tours as tours_mod
from ...types import Recording
from .scoring import score_segment

__all__ = ["SyntheticConfig", "SyntheticResult", "loso_calibrations", "run_recordings", "run_synthetic", "run_tour"]

# =========================================================================== synthetic


@dataclass(frozen=True)
class SyntheticConfig:
    """What :func:`run_synthetic` runs.

    Attributes
    ----------
    tours, paces, tags
        Experiments (tour × pace) and blind nodes to evaluate.
    heuristics
        Heuristics to run (:data:`~uwbwb.filters.pruning.HEURISTICS`); the 5th
        percentile is applied to stops only.
    pruning
        Heuristic and solver parameters. ``pruning.dim`` is the geometry of the whole
        comparison: 2 -- every estimator (point-based baseline included) solves the
        horizontal position at the node's mount height from the rig's description;
        3 -- every estimator solves in 3-D without any height information (the
        robust mean cannot: a triplet fix needs the height, so it must be left out).
    tour
        Base simulator configuration (its ``tour``/``pace`` are replaced). A segment's first packet is left
        out: its ranges were measured in the 130 ms *before* its time stamp, partly in the previous segment.
    point_baseline
        Also score the point-based baseline on the same packets.
    kinds
        Segments localised: ``"stop"``, ``"move"`` (the stops alone where only they are read).
    """

    tours: tuple = (1, 2, 3)
    paces: tuple = ("slow", "fast")
    tags: tuple = ("L", "H")
    heuristics: tuple = HEURISTICS
    pruning: PruningConfig = PruningConfig(dim=2)
    tour: tours_mod.TourConfig = tours_mod.TourConfig()
    point_baseline: bool = True
    kinds: tuple = ("stop", "move")

    def __post_init__(self):
        unknown = set(self.heuristics) - set(HEURISTICS)
        if unknown:
            raise ValueError(f"unknown heuristics {sorted(unknown)}; choose from {HEURISTICS}")
        if not set(self.kinds) <= {"stop", "move"}:
            raise ValueError(f"kinds must be 'stop' and/or 'move', got {self.kinds!r}")
        if self.pruning.dim == 3 and "robust_mean" in self.heuristics:
            raise ValueError("the robust mean localises triplets at the node's known height; a 3-D comparison "
                             "without height information must leave it out (heuristics=...)")


@dataclass(frozen=True)
class SyntheticResult:
    """Tidy results of :func:`run_synthetic`.

    Attributes
    ----------
    stops
        One row per (experiment, node, stop, heuristic): estimate, truth, horizontal
        error ``err_m`` and its direction ``bearing_deg``, height error ``err_z_m``,
        3-D error ``err_3d_m``.
    moves
        One row per (experiment, node, walk, heuristic): ``P0``/``v`` estimates,
        start/end/mean horizontal errors, velocity error, speed ratio, heading error.
    track
        The epoch table: the horizontal error of every estimator at every packet of
        every stop and walk -- "all distance errors" (the piecewise estimate: each
        stop's position, each walk's fitted line; the point-based fix of that
        packet): ``experiment, tag, segment, kind ("stop"/"move"), heuristic, t_s,
        err_m, err_z_m`` with NaN where an estimator gave no position (a segment
        with too few ranges, a packet without a fix). The 5th percentile has
        rows on stops only.
    recordings
        ``{experiment name: (Recording, TourTruth)}``.
    dim
        Geometry of the comparison (2 or 3, see :class:`SyntheticConfig`).
    """

    stops: pd.DataFrame
    moves: pd.DataFrame
    track: pd.DataFrame
    recordings: dict = field(repr=False)
    dim: int = 2


def run_tour(rec: Recording, truth: tours_mod.TourTruth, config: SyntheticConfig, *, tags=None,
             heuristics=None) -> tuple[list[dict], list[dict], list[pd.DataFrame]]:
    """Localise every segment of one simulated experiment; rows for :class:`SyntheticResult`.

    With ``config.pruning.dim == 2`` every estimator gets the node's mount height
    from the rig's description (``rec.meta["node_heights_m"]``: the paper's 1.3 m
    and 2 m); with ``dim == 3`` none gets any height.
    """
    tcfg = rec.meta["config"]
    dim = config.pruning.dim
    tags = config.tags if tags is None else tags
    heuristics = config.heuristics if heuristics is None else heuristics
    stops, moves, track = [], [], []
    for tag in tags:
        z_known = float(rec.meta["node_heights_m"][tag]) if dim == 2 else None
        for seg in (s for s in truth.segments if s.kind in config.kinds):
            log = rec.ranges[tag].between(seg.t_start_s + tcfg.period_s, seg.t_end_s)   # see SyntheticConfig
            if len(log) == 0:
                continue
            still = seg.kind == "stop"
            true_xy, _ = tours_mod.tour_xy(truth.segments, log.t_s)
            true_z = rec.truth[tag].interp(log.t_s)[:, 2]
            fits, ep = score_segment(log, rec.anchors, [h for h in heuristics if still or h != "percentile"],
                                     config.pruning, still=still, z_m=z_known, v_true=seg.vel_xy_mps,
                                     true_xy=seg.start_xy_m if still else true_xy, epoch_xy=true_xy, true_z=true_z,
                                     point=config.point_baseline,
                                     keys={"experiment": rec.name, "tag": tag, "segment": seg.index, "kind": seg.kind})
            track += ep
            base = {"experiment": rec.name, "tour": tcfg.tour, "pace": tcfg.pace, "tag": tag,
                    "height_m": float(rec.meta["node_heights_m"][tag]), "segment": seg.index,
                    "keypoint": seg.keypoint, "label": seg.label, "coverage": int(truth.coverage[seg.keypoint]),
                    "dim": dim}
            for row, res in fits:
                if still:
                    d = res.p0_m[:2] - np.asarray(seg.start_xy_m)
                    dz = float(res.p0_m[2] - np.median(true_z))
                    stops.append({**base, **row, "true_x_m": seg.start_xy_m[0], "true_y_m": seg.start_xy_m[1],
                                  "err_z_m": dz, "err_3d_m": float(np.sqrt(d @ d + dz * dz))})
                else:
                    moves.append({**base, **row, "true_x0_m": true_xy[0, 0], "true_y0_m": true_xy[0, 1]})
    return stops, moves, track


_TRACK_COLUMNS = ["experiment", "tag", "segment", "kind", "heuristic", "t_s", "err_m", "err_z_m"]


def run_recordings(recordings: dict, config: SyntheticConfig, *, progress: bool = False) -> SyntheticResult:
    """Localise already simulated experiments (``{name: (Recording, TourTruth)}``) with ``config``.

    Used to compare geometries on the *same* simulated packets.
    """
    items = list(recordings.items())
    if progress:
        from tqdm.auto import tqdm
        items = tqdm(items, desc="tours")
    stops, moves, track = [], [], []
    for _, (rec, truth) in items:
        s, m, tr = run_tour(rec, truth, config)
        stops += s
        moves += m
        track += tr
    track_df = pd.concat(track, ignore_index=True) if track else pd.DataFrame(columns=_TRACK_COLUMNS)
    return SyntheticResult(pd.DataFrame(stops), pd.DataFrame(moves), track_df, dict(recordings),
                           config.pruning.dim)


def run_synthetic(config: SyntheticConfig = SyntheticConfig(), *, rng: np.random.Generator,
                  progress: bool = False) -> SyntheticResult:
    """Simulate every tour × pace and localise every segment with every estimator.

    Parameters
    ----------
    config
        Experiments, nodes, heuristics, geometry and parameters.
    rng
        Random generator (one range model is drawn per experiment).
    progress
        Show a ``tqdm`` progress bar over the experiments.
    """
    recs = {}
    for tour, pace in [(t, p) for t in config.tours for p in config.paces]:
        rec, truth = tours_mod.simulate_tour(dataclasses.replace(config.tour, tour=tour, pace=pace), rng=rng)
        recs[rec.name] = (rec, truth)
    return run_recordings(recs, config, progress=progress)



# =========================================================================== LIAS static poses: calibration


def loso_calibrations(recordings, *, stride: int = 1, **fit_kw) -> dict:
    """Range calibrations fitted leaving each site out (for honest evaluation on that site).

    For every site ``s`` in ``rec.meta["site"]``, :func:`uwbwb.calibration.fit_range_calibration`
    is fitted on the poses of all *other* sites; evaluating site ``s`` with it never
    uses the truth of ``s``. ``stride`` thins the poses first (:meth:`~uwbwb.Recording.decimate`);
    ``fit_kw`` go to the fit. Returns ``{site: RangeCalibration}``.
    """

    recordings = [r.decimate(stride) for r in recordings]
    sites = sorted({r.meta["site"] for r in recordings})
    if len(sites) < 2:
        raise ValueError("leave-one-site-out calibration needs poses from at least two sites")
    return {s: fit_range_calibration([r for r in recordings if r.meta["site"] != s], **fit_kw) for s in sites}
