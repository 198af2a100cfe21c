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
  each site out; :func:`range_error_stats` describes the ranges (bias, long outliers).
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

from ...calibration import MAD_TO_SIGMA, fit_range_calibration, pair_samples
from ...filters.pruning import HEURISTICS, PruningConfig, localize
from ...geometry import point_fixes
from ...sim import tours as tours_mod
from ...types import RangeLog, RangeSamples, Recording
from .scoring import MIN_SEGMENT_RANGES, POINT, bearing_deg, heading_err_deg

__all__ = ["EXCESS_FACTORS", "SyntheticConfig", "SyntheticResult", "loso_calibrations", "nlos_excess_sensitivity",
           "range_error_stats", "run_recordings", "run_synthetic", "run_tour", "sensitivity"]

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
        Base simulator configuration (its ``tour``/``pace`` are replaced).
    skip_first_packet
        Leave out a segment's first packet: its ranges were measured in the
        130 ms *before* its time stamp, i.e. partly in the previous segment.
    point_baseline
        Also score the point-based baseline on the same packets.
    """

    tours: tuple = (1, 2, 3)
    paces: tuple = ("slow", "fast")
    tags: tuple = ("L", "H")
    heuristics: tuple = HEURISTICS
    pruning: PruningConfig = PruningConfig(dim=2)
    tour: tours_mod.TourConfig = tours_mod.TourConfig()
    skip_first_packet: bool = True
    point_baseline: bool = True

    def __post_init__(self):
        unknown = set(self.heuristics) - set(HEURISTICS)
        if unknown:
            raise ValueError(f"unknown heuristics {sorted(unknown)}; choose from {HEURISTICS}")
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


def _track_rows(rec, tag, seg, kind, h, t_s, err_m, err_z_m) -> pd.DataFrame:
    n = len(t_s)
    return pd.DataFrame({"experiment": rec.name, "tag": tag, "segment": seg.index, "kind": kind, "heuristic": h,
                         "t_s": t_s, "err_m": np.broadcast_to(np.asarray(err_m, float), (n,)),
                         "err_z_m": np.broadcast_to(np.asarray(err_z_m, float), (n,))})


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
    if dim == 3 and "robust_mean" in heuristics:
        raise ValueError("the robust mean needs the node height: leave it out of a 3-D comparison")
    stops, moves, track = [], [], []
    for tag in tags:
        z_known = float(rec.meta["node_heights_m"][tag]) if dim == 2 else None
        for seg in truth.segments:
            log = rec.ranges[tag].between(seg.t_start_s + (tcfg.period_s if config.skip_first_packet else 0.0),
                                          seg.t_end_s)
            if len(log) == 0:
                continue
            still = seg.kind == "stop"
            t_pk = log.t_s
            true_xy, true_v = tours_mod.tour_xy(truth.segments, t_pk)
            true_z = rec.truth[tag].interp(t_pk)[:, 2]
            if config.point_baseline:
                P = point_fixes(log.range_m, rec.anchors, dim=dim, z_m=z_known)
                track.append(_track_rows(rec, tag, seg, seg.kind, POINT, t_pk,
                                         np.linalg.norm(P[:, :2] - true_xy, axis=1), P[:, 2] - true_z))
            samples = RangeSamples.from_ranges(log)
            run = [h for h in heuristics if still or h != "percentile"]
            if len(samples) < MIN_SEGMENT_RANGES:
                for h in run:                       # no fit: these packets count as not covered
                    track.append(_track_rows(rec, tag, seg, seg.kind, h, t_pk, np.nan, np.nan))
                continue
            base = {"experiment": rec.name, "tour": tcfg.tour, "pace": tcfg.pace, "tag": tag,
                    "height_m": float(rec.meta["node_heights_m"][tag]), "segment": seg.index,
                    "keypoint": seg.keypoint, "label": seg.label, "coverage": int(truth.coverage[seg.keypoint]),
                    "dim": dim}
            for h in run:
                res = localize(samples, rec.anchors, h, config.pruning, stationary=still, z_m=z_known)
                conv = bool(res.fit.converged) if res.fit is not None else True
                common = {**base, "heuristic": h, "t0_s": res.t0_s, "t_end_s": res.t_end_s,
                          "x0_m": res.p0_m[0], "y0_m": res.p0_m[1], "z0_m": res.p0_m[2],
                          "vx_mps": res.vel_mps[0], "vy_mps": res.vel_mps[1], "vz_mps": res.vel_mps[2],
                          "n_used": res.n_used, "converged": conv}
                if still:
                    d = res.p0_m[:2] - np.asarray(seg.start_xy_m)
                    dz = float(res.p0_m[2] - np.median(true_z))
                    stops.append({**common, "true_x_m": seg.start_xy_m[0], "true_y_m": seg.start_xy_m[1],
                                  "err_m": float(np.hypot(*d)), "bearing_deg": float(bearing_deg(d)),
                                  "err_z_m": dz, "err_3d_m": float(np.sqrt(d @ d + dz * dz))})
                    track.append(_track_rows(rec, tag, seg, "stop", h, t_pk, np.hypot(*d), res.p0_m[2] - true_z))
                    continue
                est = res.position_at(t_pk)
                err = np.linalg.norm(est[:, :2] - true_xy, axis=1)
                v_true = np.asarray(seg.vel_xy_mps)
                v_est = res.vel_mps[:2]
                moves.append({**common, "true_x0_m": true_xy[0, 0], "true_y0_m": true_xy[0, 1],
                              "true_vx_mps": v_true[0], "true_vy_mps": v_true[1],
                              "start_err_m": float(err[0]), "end_err_m": float(err[-1]),
                              "mean_err_m": float(err.mean()),
                              "vel_err_mps": float(np.linalg.norm(v_est - v_true)),
                              "speed_ratio": float(np.linalg.norm(v_est) / np.linalg.norm(v_true)),
                              "heading_err_deg": heading_err_deg(v_est, v_true)})
                track.append(_track_rows(rec, tag, seg, "move", h, t_pk, err, est[:, 2] - true_z))
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



def sensitivity(config: SyntheticConfig, dwell_s=(0.0, 3.0, 30.0), *, seed: int) -> pd.DataFrame:
    """The stops (:attr:`SyntheticResult.stops`, column ``nlos_dwell_s`` added) per mean NLOS episode length.

    Each length simulates the configured tours afresh with ``nlos_dwell_s`` replaced (same seed for every
    length); the geometry is ``config.pruning.dim``.
    """
    out = []
    for d in dwell_s:
        c = dataclasses.replace(config, point_baseline=False,
                                tour=dataclasses.replace(config.tour, nlos_dwell_s=float(d)))
        out.append(run_synthetic(c, rng=np.random.default_rng(seed)).stops.assign(nlos_dwell_s=float(d)))
    return pd.concat(out, ignore_index=True)


#: Factors on the simulated NLOS excess (``TourConfig.nlos_mean_m``) of :func:`nlos_excess_sensitivity`: half,
#: the configured value, double.
EXCESS_FACTORS = (0.5, 1.0, 2.0)


def nlos_excess_sensitivity(config: SyntheticConfig, factors=EXCESS_FACTORS, *, seed: int,
                            heuristic: str = "residual") -> pd.DataFrame:
    """All distance errors of one heuristic as the simulated NLOS excess is scaled.

    The mean NLOS excess of the range-error model (``config.tour.nlos_mean_m``, an assumption of the
    simulator, not a number of the paper) is multiplied by each factor; every factor simulates the configured
    tours afresh from ``seed`` (the same draws whatever the factor), so factor 1 gives the comparison's own
    packets when ``seed`` is the comparison's. Returns the epoch tables (:attr:`SyntheticResult.track`) of
    ``heuristic``, one after the other, with columns ``factor`` and ``nlos_mean_m`` added.
    """
    out = []
    for k in factors:
        if not k > 0:
            raise ValueError(f"excess factors must be positive, got {k!r}")
        tour = dataclasses.replace(config.tour, nlos_mean_m=float(k) * config.tour.nlos_mean_m)
        c = dataclasses.replace(config, tour=tour, heuristics=(heuristic,), point_baseline=False)
        r = run_synthetic(c, rng=np.random.default_rng(seed))
        out.append(r.track.assign(factor=float(k), nlos_mean_m=tour.nlos_mean_m))
    return pd.concat(out, ignore_index=True)


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


def range_error_stats(recordings, *, tags=None, stride: int = 10, long_m: float = 0.5) -> pd.DataFrame:
    """What the static poses' ranges look like: per anchor--tag pair bias and long outliers.

    Range error = measured range minus the range from the pose's true tag position
    (:func:`uwbwb.calibration.pair_samples`, pooled over the poses, every ``stride``-th
    epoch). Per pair: ``bias_m`` (median error), ``spread_m`` (1.4826 × median absolute
    deviation), ``frac_long`` (fraction of errors more than ``long_m`` above the pair's
    median: the positive excess NLOS would add).

    Returns
    -------
    pandas.DataFrame
        One row per ``(anchor, tag)`` with samples: ``n, bias_m, spread_m, frac_long``.
    """

    anchor_ids, tag_ids, true_m, meas_m = pair_samples([r.decimate(int(stride)) for r in recordings])
    err = meas_m - true_m                                                    # (N, n_tags, n_anchors)
    rows = []
    for k, tag in enumerate(tag_ids):
        if tags is not None and tag not in tags:
            continue
        for j, a in enumerate(anchor_ids):
            e = err[:, k, j][np.isfinite(err[:, k, j])]
            if not e.size:
                continue
            med = np.median(e)
            rows.append({"anchor": a, "tag": tag, "n": e.size, "bias_m": med,
                         "spread_m": MAD_TO_SIGMA * np.median(np.abs(e - med)),
                         "frac_long": float(np.mean(e > med + long_m))})
    return pd.DataFrame(rows)
