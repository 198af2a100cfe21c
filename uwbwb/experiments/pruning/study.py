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
nothing) that :func:`epoch_summary` turns into coverage beside accuracy.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...filters.pruning import HEURISTICS, LABELS as HEURISTIC_LABELS, PruningConfig, localize
from ... import metrics
from ...geometry import line_fit, point_fixes
from ...sim import tours as tours_mod
from ...types import RangeLog, RangeSamples, Recording

__all__ = [
    "ESTIMATORS", "LABELS", "MIN_SEGMENT_RANGES", "POINT", "PAPER_RANKING", "DynamicResult", "StaticResult",
    "SyntheticConfig",
    "SyntheticResult", "TourExplorer", "PieceExplorer", "epoch_summary", "hanyang_table",
    "headline_rows", "heuristic_summary", "loso_calibrations", "outlier_free_control",
    "range_error_stats", "rank_heuristics", "run_dynamic_segments", "run_recordings", "run_static_poses",
    "run_synthetic", "run_tour", "segment_ranges", "sensitivity", "wins_table",
]

#: The point-based baseline's name in the tables: one multilateration per packet/epoch.
POINT = "point"
#: Estimators in table order: the four pipelines of Fig. 7, then the point-based baseline.
ESTIMATORS = (*HEURISTICS, POINT)
#: Display names.
LABELS = {**HEURISTIC_LABELS, POINT: "point-based (per packet)"}
#: The three heuristics (plain NLS excluded) in the paper's order, best first.
PAPER_RANKING = ("residual", "robust_mean", "percentile")
#: Fewer ranges than this in a segment: no NLS fit (the segment's epochs count as not covered).
MIN_SEGMENT_RANGES = 12


# =========================================================================== point-based baseline


# =========================================================================== scoring on common epochs


def epoch_summary(epochs: pd.DataFrame) -> pd.DataFrame:
    """Coverage beside accuracy per estimator (:func:`uwbwb.metrics.epoch_summary`, :data:`ESTIMATORS` order).

    ``epochs`` has one row per estimator (column ``heuristic``) and scored epoch, with
    ``err_m`` NaN where the estimator produced no position.
    """
    return metrics.epoch_summary(epochs, by="heuristic", order=ESTIMATORS)


def _bearing_deg(dxy: np.ndarray) -> np.ndarray:
    return np.rad2deg(np.arctan2(dxy[..., 1], dxy[..., 0]))


def _heading_err_deg(v_est, v_true) -> float:
    ang = np.rad2deg(np.arctan2(v_est[1], v_est[0]) - np.arctan2(v_true[1], v_true[0]))
    return float((ang + 180.0) % 360.0 - 180.0)


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


def segment_ranges(log: RangeLog, seg: tours_mod.Segment, *, period_s: float, skip_first_packet: bool = True
                   ) -> RangeLog:
    """The packets stamped inside a segment (optionally without the first one)."""
    start = seg.t_start_s + (period_s if skip_first_packet else 0.0)
    return log.between(start, seg.t_end_s)


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
            log = segment_ranges(rec.ranges[tag], seg, period_s=tcfg.period_s,
                                 skip_first_packet=config.skip_first_packet)
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
                                  "err_m": float(np.hypot(*d)), "bearing_deg": float(_bearing_deg(d)),
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
                              "heading_err_deg": _heading_err_deg(v_est, v_true)})
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


def heuristic_summary(stops: pd.DataFrame, moves: pd.DataFrame | None = None,
                      track: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per estimator: stationary error, walk velocity error, and all distance errors with coverage.

    Returns a DataFrame indexed by estimator (:data:`ESTIMATORS` order) with columns
    ``label, n_stops, stop_median_m, stop_p90_m, stop_max_m`` (one estimate per stop;
    ``stop_err_z_median_m`` (median absolute height error), ``stop_err_z_bias_m``
    (median signed, positive = too high) and ``stop_err_3d_median_m`` when the stops
    carry height errors); with ``moves``: ``n_walks, vel_err_median_mps, speed_ratio_median,
    heading_err_median_deg``; with ``track`` (see :func:`epoch_summary`):
    ``n_epochs, coverage, all_median_m, all_p90_m, all_p90_failed_counted_m`` over
    every packet of stops and walks (stops only for the 5th percentile, which
    ``all_includes_walks`` says), ``walk_median_m, walk_p90_m`` and
    ``stop_packet_median_m`` (the per-packet error on stops).
    """
    names = set(stops["heuristic"]) if len(stops) else set()
    if track is not None and len(track):
        names |= set(track["heuristic"])
    rows = []
    for h in [h for h in ESTIMATORS if h in names]:
        row = {"heuristic": h, "label": LABELS[h]}
        e = stops.loc[stops.heuristic == h, "err_m"].to_numpy() if len(stops) else np.array([])
        if e.size:
            row.update(n_stops=e.size, stop_median_m=np.median(e), stop_p90_m=np.quantile(e, 0.9), stop_max_m=e.max())
            if "err_z_m" in stops:
                s = stops[stops.heuristic == h]
                row.update(stop_err_z_median_m=s.err_z_m.abs().median(), stop_err_z_bias_m=s.err_z_m.median(),
                           stop_err_3d_median_m=s.err_3d_m.median())
        if moves is not None and len(moves) and h in set(moves["heuristic"]):
            m = moves[moves.heuristic == h]
            row.update(n_walks=len(m), vel_err_median_mps=m.vel_err_mps.median(),
                       speed_ratio_median=m.speed_ratio.median(),
                       heading_err_median_deg=m.heading_err_deg.abs().median())
        if track is not None and len(track) and h in set(track["heuristic"]):
            tr = track[track.heuristic == h]
            s = epoch_summary(tr).iloc[0]
            row.update(n_epochs=int(s.n_epochs), coverage=s.coverage, all_median_m=s.median_m, all_p90_m=s.p90_m,
                       all_p90_failed_counted_m=s.p90_failed_counted_m,
                       all_includes_walks=bool((tr["kind"] == "move").any()))
            w = tr.loc[tr["kind"] == "move", "err_m"].dropna().to_numpy()
            if w.size:
                row.update(walk_median_m=np.median(w), walk_p90_m=np.quantile(w, 0.9))
            sp = tr.loc[tr["kind"] == "stop", "err_m"].dropna().to_numpy()
            if sp.size:
                row.update(stop_packet_median_m=np.median(sp))
        rows.append(row)
    return pd.DataFrame(rows).set_index("heuristic")


def rank_heuristics(table: pd.DataFrame, column: str = "stop_median_m") -> pd.Series:
    """Rank (1 = best) of the three heuristics present in ``table`` by ``column`` (plain NLS and the
    point-based baseline excluded, as in the paper's ranking)."""
    three = [h for h in PAPER_RANKING if h in table.index and np.isfinite(table.loc[h, column])]
    return table.loc[three, column].rank()


def sensitivity(config: SyntheticConfig, dwell_s=(0.0, 3.0, 30.0), *, seed: int) -> pd.DataFrame:
    """Median stationary error per mean NLOS episode length (rows, seconds) and heuristic (columns).

    Each row simulates the configured tours afresh with ``nlos_dwell_s`` replaced
    (same seed for every row); the geometry is ``config.pruning.dim``.
    """
    out = {}
    for d in dwell_s:
        c = dataclasses.replace(config, point_baseline=False,
                                tour=dataclasses.replace(config.tour, nlos_dwell_s=float(d)))
        r = run_synthetic(c, rng=np.random.default_rng(seed))
        out[float(d)] = heuristic_summary(r.stops)["stop_median_m"]
    table = pd.DataFrame(out).T
    table.index.name = "nlos_dwell_s"
    return table


def outlier_free_control(config: SyntheticConfig, *, seed: int) -> pd.DataFrame:
    """The same tours without NLOS (LOS noise, biases and failed ranges kept): what pruning costs
    when there is nothing to prune.

    Returns :func:`heuristic_summary` (stops, walks, packets) of a fresh simulation
    with ``p_nlos_in = p_nlos_out = 0``, same geometry, no point-based baseline.
    """
    tour = dataclasses.replace(config.tour, p_nlos_in=0.0, p_nlos_out=0.0)
    r = run_synthetic(dataclasses.replace(config, tour=tour, point_baseline=False), rng=np.random.default_rng(seed))
    return heuristic_summary(r.stops, r.moves, r.track)


# =========================================================================== LIAS static poses


@dataclass(frozen=True)
class StaticResult:
    """Output of :func:`run_static_poses`.

    Attributes
    ----------
    poses
        One row per (pose, tag, heuristic): ``recording, site, yaw_deg, tag, heuristic,
        true_x_m, true_y_m, x_m, y_m, err_m, bearing_deg, n_used, n_epochs, calibrated``.
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


def run_static_poses(recordings, *, heights_m: dict, tags=None, heuristics=HEURISTICS,
                     config: PruningConfig = PruningConfig(dim=2), stride: int = 10,
                     calibrations: dict | None = None, point_baseline: bool = True,
                     progress: bool = False) -> StaticResult:
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
    heuristics
        Heuristics to run.
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
    point_baseline
        Also fix every epoch by multilateration at the same height.
    progress
        ``tqdm`` bar over the poses.
    """
    if stride < 1 or int(stride) != stride:
        raise ValueError(f"stride must be a positive integer, got {stride!r}")
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
            log = rec.ranges[tag] if cal is None else cal.apply(rec.ranges[tag])
            log = log.select(slice(None, None, int(stride)))
            z = heights[tag]
            true = rec.truth[tag].pos_m[0]
            ep = {"recording": rec.name, "site": site, "tag": tag, "t_s": log.t_s}
            if point_baseline:
                P = point_fixes(log.range_m, rec.anchors, dim=2, z_m=z)
                epochs.append(pd.DataFrame({**ep, "heuristic": POINT,
                                            "err_m": np.linalg.norm(P[:, :2] - true[:2], axis=1)}))
            samples = RangeSamples.from_ranges(log)
            for h in heuristics:
                res = localize(samples, rec.anchors, h, config, stationary=True, z_m=z)
                d = res.p0_m[:2] - true[:2]
                rows.append({"recording": rec.name, "site": site, "yaw_deg": rec.meta.get("yaw_deg"),
                             "tag": tag, "heuristic": h, "true_x_m": true[0], "true_y_m": true[1],
                             "x_m": res.p0_m[0], "y_m": res.p0_m[1], "err_m": float(np.hypot(*d)),
                             "bearing_deg": float(_bearing_deg(d)), "n_used": res.n_used,
                             "n_epochs": len(log), "calibrated": cal is not None})
                epochs.append(pd.DataFrame({**ep, "heuristic": h, "err_m": float(np.hypot(*d))}))
    ep_df = pd.concat(epochs, ignore_index=True) if epochs else pd.DataFrame(
        columns=["recording", "site", "tag", "t_s", "heuristic", "err_m"])
    return StaticResult(pd.DataFrame(rows), ep_df)


def loso_calibrations(recordings, *, stride: int = 1, **fit_kw) -> dict:
    """Range calibrations fitted leaving each site out (for honest evaluation on that site).

    For every site ``s`` in ``rec.meta["site"]``, :func:`uwbwb.calibration.fit_range_calibration`
    is fitted on the poses of all *other* sites; evaluating site ``s`` with it never
    uses the truth of ``s``. ``stride`` thins the poses first (:meth:`~uwbwb.Recording.decimate`);
    ``fit_kw`` go to the fit. Returns ``{site: RangeCalibration}``.
    """
    from ...calibration import fit_range_calibration

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
    from ...calibration import MAD_TO_SIGMA, pair_samples

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
    rows, epochs, cover = [], [], {}
    use = rec.tags if tags is None else tags
    heights = _check_heights(heights_m, use)
    for tag in use:
        full = rec.ranges[tag] if calibration is None else calibration.apply(rec.ranges[tag])
        full = full.select(slice(None, None, int(stride)))
        tr = rec.truth[tag]
        full = full.between(tr.t_s[0], tr.t_s[-1])              # epochs with truth
        z = heights[tag]
        n_run = len(full)
        n_fit = 0
        if point_baseline and n_run:
            P_all = point_fixes(full.range_m, rec.anchors, dim=2, z_m=z)
            cover.setdefault(POINT, [0, 0])
            cover[POINT][0] += int(np.isfinite(P_all[:, 0]).sum())
            cover[POINT][1] += n_run
        for seg in segments.itertuples(index=False):
            sel = (full.t_s >= seg.t_start_s) & (full.t_s <= seg.t_end_s)
            log = full.select(sel)
            if len(log) == 0:
                continue
            true = tr.interp(log.t_s)[:, :2]
            ep = {"segment": seg.segment, "tag": tag, "t_s": log.t_s}
            if point_baseline:
                epochs.append(pd.DataFrame({**ep, "heuristic": POINT,
                                            "err_m": np.linalg.norm(P_all[sel, :2] - true, axis=1)}))
            samples = RangeSamples.from_ranges(log)
            if len(samples) < MIN_SEGMENT_RANGES:
                for h in heuristics:
                    epochs.append(pd.DataFrame({**ep, "heuristic": h, "err_m": np.nan}))
                continue
            n_fit += len(log)
            _, v_true, _ = line_fit(log.t_s, true)
            for h in heuristics:
                res = localize(samples, rec.anchors, h, config, stationary=False, z_m=z)
                est = res.position_at(log.t_s)[:, :2]
                err = np.linalg.norm(est - true, axis=1)
                v_est = res.vel_mps[:2]
                rows.append({"segment": seg.segment, "tag": tag, "heuristic": h, "t0_s": res.t0_s,
                             "t_end_s": res.t_end_s, "duration_s": res.t_end_s - res.t0_s,
                             "x0_m": res.p0_m[0], "y0_m": res.p0_m[1], "vx_mps": v_est[0], "vy_mps": v_est[1],
                             "true_vx_mps": v_true[0], "true_vy_mps": v_true[1],
                             "start_err_m": float(err[0]), "mean_err_m": float(err.mean()),
                             "vel_err_mps": float(np.linalg.norm(v_est - v_true)),
                             "speed_ratio": float(np.linalg.norm(v_est) / np.linalg.norm(v_true)),
                             "heading_err_deg": _heading_err_deg(v_est, v_true),
                             "n_used": res.n_used, "calibrated": calibration is not None})
                epochs.append(pd.DataFrame({**ep, "heuristic": h, "err_m": err}))
        for h in heuristics:
            cover.setdefault(h, [0, 0])
            cover[h][0] += n_fit
            cover[h][1] += n_run
    ep_df = pd.concat(epochs, ignore_index=True) if epochs else pd.DataFrame(
        columns=["segment", "tag", "t_s", "heuristic", "err_m"])
    run_cov = pd.Series({h: c[0] / c[1] if c[1] else np.nan for h, c in cover.items()}, name="run_coverage")
    return DynamicResult(pd.DataFrame(rows), ep_df, run_cov)


# =========================================================================== Hanyang


def hanyang_table(pct: pd.DataFrame) -> pd.DataFrame:
    """Per condition present (LOS, NLOS): number of files and the median over files of
    ``median_err_m, pq_err_m, frac_over_1m`` (empty when no file had enough samples)."""
    cols = ["median_err_m", "pq_err_m", "frac_over_1m"]
    if pct.empty:
        return pd.DataFrame(columns=["n_files", *cols])
    t = pct.groupby("condition")[cols].median()
    t.insert(0, "n_files", pct.groupby("condition").size())
    return t


# =========================================================================== tables for the notebook


def wins_table(entries: dict) -> pd.DataFrame:
    """Which estimator wins where: ``entries`` maps a row name to a Series of errors per estimator.

    Adds ``best of all`` (every estimator present) and ``best heuristic`` (among the
    three heuristics) columns, by label.
    """
    t = pd.DataFrame(entries).T
    t = t.reindex(columns=[h for h in ESTIMATORS if h in t.columns])
    t["best of all"] = t[[h for h in ESTIMATORS if h in t.columns]].idxmin(axis=1).map(LABELS)
    three = [h for h in PAPER_RANKING if h in t.columns]
    t["best heuristic"] = t[three].idxmin(axis=1).map(LABELS)
    return t


def _fin(x) -> bool:
    return x is not None and np.isfinite(x)


def headline_rows(*, synthetic: pd.DataFrame, synthetic_dim: int, synthetic_3d: pd.DataFrame | None = None,
                  lias_static: dict | None = None, static_label: str | None = None,
                  lias_dynamic: dict | None = None, dyn_label: str | None = None,
                  hanyang: pd.DataFrame | None = None, hy_label: str | None = None) -> list[dict]:
    """The notebook's headline numbers as ``Summary.add`` keyword dicts, each with its ``kind``.

    Every value here came out of the method on the run's data (``kind="reproduced"``);
    the paper's statements sit beside them as ``paper_value`` (the ranking, "90 %
    under 4 m"), never as a pass bound.

    Parameters
    ----------
    synthetic
        :func:`heuristic_summary` of the fair synthetic comparison (stops, walks, track).
    synthetic_dim
        Its geometry (2: known mount height, 3: no height).
    synthetic_3d
        Optionally the other geometry's summary (3-D rows: horizontal and height errors).
    lias_static
        ``{"raw": (heuristic_summary, epoch_summary), "LOSO calibrated": (...)}``.
    lias_dynamic
        ``{ranges: (pieces median table, epoch_summary, run_coverage)}``.
    hanyang
        :func:`hanyang_table`.
    """
    rows = []

    def add(quantity, value, unit, data, paper_value=None):
        if _fin(value):
            rows.append({"quantity": quantity, "value": float(value), "unit": unit, "data": data,
                         "kind": "reproduced", "paper_value": paper_value})

    geo = "known height" if synthetic_dim == 2 else "3-D, no height"
    t = synthetic
    for h, r in t.iterrows():
        lab = LABELS[h]
        add(f"median stationary error, {lab} ({geo})", r.get("stop_median_m"), "m", "synthetic")
        add(f"90th-percentile stationary error, {lab} ({geo})", r.get("stop_p90_m"), "m", "synthetic")
        add(f"median walk velocity error, {lab} ({geo})", r.get("vel_err_median_mps"), "m/s", "synthetic")
        add(f"median walk speed ratio (estimated / true), {lab} ({geo})", r.get("speed_ratio_median"), "",
            "synthetic")
        add(f"90 % of all distance errors under, {lab} ({geo}, covered packets)", r.get("all_p90_m"), "m",
            "synthetic", 4.0 if h == "residual" else None)
        add(f"median of all distance errors, {lab} ({geo}, covered packets)", r.get("all_median_m"), "m",
            "synthetic")
        add(f"packet coverage, {lab} ({geo})", r.get("coverage"), "", "synthetic")
    for h, v in rank_heuristics(t).items():
        add(f"rank by median stationary error among the three heuristics (1 = best), {LABELS[h]} ({geo})", v, "",
            "synthetic", {"residual": 1, "robust_mean": 2, "percentile": 3}[h])
    if {"residual", POINT} <= set(t.index):
        add(f"90 % of all distance errors, residual pruning minus point-based ({geo})",
            t.loc["residual", "all_p90_m"] - t.loc[POINT, "all_p90_m"], "m", "synthetic")
    if synthetic_3d is not None:
        for h, r in synthetic_3d.iterrows():
            lab = LABELS[h]
            add(f"median stationary error, {lab} (3-D, no height)", r.get("stop_median_m"), "m", "synthetic")
            add(f"median stationary height error |dz|, {lab} (3-D, no height)", r.get("stop_err_z_median_m"),
                "m", "synthetic")
            add(f"median stationary 3-D error, {lab} (3-D, no height)", r.get("stop_err_3d_median_m"), "m",
                "synthetic")
            add(f"90 % of all distance errors under, {lab} (3-D, no height, covered packets)", r.get("all_p90_m"),
                "m", "synthetic")
    if lias_static is not None:
        for k, (hs, es) in lias_static.items():
            for h, r in hs.iterrows():
                add(f"median stationary error, {LABELS[h]}, {k}", r.get("stop_median_m"), "m", static_label)
                add(f"90th-percentile stationary error, {LABELS[h]}, {k}", r.get("stop_p90_m"), "m", static_label)
            for h, v in rank_heuristics(hs).items():
                add(f"rank by median stationary error among the three heuristics (1 = best), {LABELS[h]}, {k}",
                    v, "", static_label, {"residual": 1, "robust_mean": 2, "percentile": 3}[h])
            for h, r in es.iterrows():
                add(f"median per-epoch error, {LABELS[h]}, {k}", r.median_m, "m", static_label)
                add(f"epoch coverage, {LABELS[h]}, {k}", r.coverage, "", static_label)
    if lias_dynamic is not None:
        for k, (pt, es, cov) in lias_dynamic.items():
            for h, r in pt.iterrows():
                add(f"median segment position error, {LABELS[h]}, {k}", r.mean_err_m, "m", dyn_label)
                add(f"median segment velocity error, {LABELS[h]}, {k}", r.vel_err_mps, "m/s", dyn_label)
                add(f"median speed ratio (estimated / true), {LABELS[h]}, {k}", r.speed_ratio, "", dyn_label)
            for h, r in es.iterrows():
                add(f"median per-epoch error on the straight pieces, {LABELS[h]}, {k}", r.median_m, "m", dyn_label)
                add(f"90th-percentile per-epoch error on the straight pieces, {LABELS[h]}, {k}", r.p90_m, "m",
                    dyn_label)
            for h, v in cov.items():
                add(f"fraction of the run's epochs with a position, {LABELS[h]}, {k}", v, "", dyn_label)
    if hanyang is not None:
        for cond, r in hanyang.iterrows():
            add(f"median per-file 5th-percentile range error, {cond}", r.pq_err_m, "m", hy_label)
            add(f"median per-file median range error, {cond}", r.median_err_m, "m", hy_label)
    return rows


# =========================================================================== widget back ends


class TourExplorer:
    """Back end of the synthetic-tour panel: cached recomputation from frozen configs.

    The run's own settings are served from its results (no recomputation); other
    retention/dropout values re-solve one tour for one node and heuristic, cached.

    Parameters
    ----------
    result, config
        The notebook's synthetic run and its configuration.
    seed
        Seeds tours the run did not simulate (one generator per tour/pace).
    """

    def __init__(self, result: SyntheticResult, config: SyntheticConfig, *, seed: int):
        self.result, self.config, self.seed = result, config, int(seed)
        self.experiment = functools.lru_cache(maxsize=8)(self._experiment)
        self.rows = functools.lru_cache(maxsize=64)(self._rows)
        self.n_solved = 0            # tours re-solved (not served from the run)

    def _experiment(self, tour: int, pace: str):
        name = f"tour{tour}-{pace}"
        if name in self.result.recordings:
            return self.result.recordings[name]
        paces = tuple(dict(self.config.tour.speed_mps))
        return tours_mod.simulate_tour(dataclasses.replace(self.config.tour, tour=tour, pace=pace),
                                       rng=np.random.default_rng((self.seed, tour, paces.index(pace))))

    def _rows(self, tour, pace, node, heuristic, res_retention, res_dropout_pct, rm_retention, rm_dropout_pct):
        base = self.config.pruning
        cfg = dataclasses.replace(base, res_retention=res_retention, res_dropout=res_dropout_pct / 100,
                                  rm_retention=rm_retention, rm_dropout=rm_dropout_pct / 100)
        name = f"tour{tour}-{pace}"
        same = {"residual": ("res_retention", "res_dropout"),
                "robust_mean": ("rm_retention", "rm_dropout")}.get(heuristic, ())
        if (all(np.isclose(getattr(cfg, k), getattr(base, k)) for k in same) and name in self.result.recordings
                and node in self.config.tags and heuristic in self.config.heuristics):
            def pick(d):
                return d[(d.experiment == name) & (d.tag == node) & (d.heuristic == heuristic)]
            return pick(self.result.stops), pick(self.result.moves)
        rec, truth = self.experiment(tour, pace)
        self.n_solved += 1
        c = dataclasses.replace(self.config, pruning=cfg, point_baseline=False)
        s, m, _ = run_tour(rec, truth, c, tags=[node], heuristics=[heuristic])
        return pd.DataFrame(s), pd.DataFrame(m)

    def render(self, heuristic, res_retention, res_dropout_pct, rm_retention, rm_dropout_pct, tour, pace, node):
        """Figure (Fig 9 style) and readout for the panel's values."""
        import matplotlib.pyplot as plt

        from .figures import plot_segment_fits

        st, mv = self.rows(tour, pace, node, heuristic, res_retention, res_dropout_pct, rm_retention,
                           rm_dropout_pct)
        rec, _ = self.experiment(tour, pace)
        fig, ax = plt.subplots(figsize=(7.5, 4.8))
        empty = self.result.moves.iloc[:0] if len(self.result.moves) else pd.DataFrame(columns=["heuristic", "t0_s"])
        plot_segment_fits(mv if len(mv) else empty, st, ax=ax, truth_xy=rec.truth[node].pos_m, anchors=rec.anchors,
                          heuristic=heuristic)
        ax.set_title(f"tour {tour}, {pace}, node {node} ({rec.meta['node_heights_m'][node]} m): {LABELS[heuristic]}")
        out = {"median stop error (m)": st.err_m.median(), "90th pct stop error (m)": st.err_m.quantile(0.9)}
        if len(mv):
            out.update({"median walk velocity error (m/s)": mv.vel_err_mps.median(),
                        "median speed ratio": mv.speed_ratio.median()})
        return fig, out


class PieceExplorer:
    """Back end of the LIAS dynamic panel: one straight piece, cached fits, point fixes for comparison.

    Parameters
    ----------
    rec, segments
        The dynamic recording and its straight pieces.
    heights_m
        Tag mount heights (as in :func:`run_dynamic_segments`).
    config, stride
        Base solver configuration and epoch thinning.
    calibration
        Range calibration for ``ranges="calibrated"`` (None: raw only).
    """

    def __init__(self, rec: Recording, segments: pd.DataFrame, *, heights_m: dict, config: PruningConfig,
                 stride: int, calibration=None):
        self.rec, self.segments, self.heights_m = rec, segments, dict(heights_m)
        self.config, self.stride, self.calibration = config, int(stride), calibration
        self.piece = functools.lru_cache(maxsize=64)(self._piece)

    @property
    def range_options(self) -> list[str]:
        return ["raw", "calibrated"] if self.calibration is not None else ["raw"]

    def _piece(self, segment, tag, heuristic, res_retention, rm_retention, dropout_pct, ranges):
        if ranges == "calibrated" and self.calibration is None:
            raise ValueError("no calibration for this run")
        cfg = dataclasses.replace(self.config, res_retention=res_retention, res_dropout=dropout_pct / 100,
                                  rm_retention=rm_retention, rm_dropout=dropout_pct / 100)
        cal = self.calibration if ranges == "calibrated" else None
        return run_dynamic_segments(self.rec, self.segments.iloc[[segment]], heights_m=self.heights_m, tags=[tag],
                                    heuristics=(heuristic,), config=cfg, stride=self.stride, calibration=cal,
                                    point_baseline=False).pieces

    def render(self, segment, tag, heuristic, res_retention, rm_retention, dropout_pct, ranges):
        """Figure (fit over the per-epoch point fixes and the truth) and readout."""
        import matplotlib.pyplot as plt

        from .figures import plot_segment_fits

        row = self.piece(segment, tag, heuristic, res_retention, rm_retention, dropout_pct, ranges)
        s = self.segments.iloc[segment]
        log = self.rec.ranges[tag] if ranges == "raw" else self.calibration.apply(self.rec.ranges[tag])
        log = log.between(s.t_start_s, s.t_end_s)
        fixes = point_fixes(log.range_m, self.rec.anchors, dim=2, z_m=self.heights_m[tag])
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        ax.plot(fixes[:, 0], fixes[:, 1], ".", ms=2, color="#9e9e9e", label="per-epoch point fixes")
        truth_piece = self.rec.truth[tag].between(s.t_start_s, s.t_end_s)
        plot_segment_fits(row, ax=ax, truth_xy=truth_piece.pos_m, heuristic=heuristic)
        ax.set_title(f"{self.rec.label}, piece {segment} ({s.duration_s:.1f} s), tag {tag}, {ranges}")
        if row.empty:
            return fig, {"fit": "too few ranges in this piece"}
        r = row.iloc[0]
        return fig, {"start error (m)": r.start_err_m, "mean error (m)": r.mean_err_m,
                     "velocity error (m/s)": r.vel_err_mps, "speed ratio": r.speed_ratio,
                     "true speed (m/s)": float(np.hypot(r.true_vx_mps, r.true_vy_mps))}
