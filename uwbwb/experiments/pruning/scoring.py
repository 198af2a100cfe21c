"""Notebook 02's scoring: estimator names, the one scorer of a segment, and the per-estimator table.

Every comparison of notebook 02 scores its estimators on one *epoch table* (one row per estimator
and scored epoch, ``err_m`` NaN where the estimator produced nothing), built segment by segment by
:func:`score_segment`; :func:`uwbwb.metrics.epoch_summary`
(``by="heuristic", order=ESTIMATORS``) turns it into coverage beside accuracy, :func:`heuristic_summary`
condenses stops, walks and packets per estimator.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ... import metrics
from ...filters.pruning import HEURISTICS, LABELS as HEURISTIC_LABELS, localize
from ...geometry import line_fit, point_fixes
from ...types import RangeSamples

__all__ = ["ESTIMATORS", "LABELS", "MIN_SEGMENT_RANGES", "PAPER_RANKING", "POINT", "heuristic_summary",
           "score_segment"]

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


def score_segment(log, anchors, heuristics, config, *, still: bool, z_m, true_xy, keys: dict, v_true=None,
                  epoch_xy=None, true_z=None, point: bool = True, fixes=None) -> tuple[list, list[pd.DataFrame]]:
    """Every estimator on one segment's ranges ``log`` (:class:`~uwbwb.types.RangeLog`), scored at each of its epochs.

    The point-based baseline fixes each epoch in ``config.dim`` (``fixes``: fixed already; ``point=False``: not
    run); each heuristic fits the segment (:func:`uwbwb.filters.pruning.localize`, at height ``z_m``), none with
    fewer than :data:`MIN_SEGMENT_RANGES` ranges (its epochs count as not covered). ``true_xy`` is the stop's true
    position (2,) or the walk's at each epoch (n, 2), ``epoch_xy`` the truth the point fixes are scored against
    (default ``true_xy``), ``v_true`` the walk's true velocity (default: the slope of
    :func:`uwbwb.geometry.line_fit` through ``true_xy``), ``true_z`` the true height at each epoch (given: the
    epoch tables hold the height error ``err_z_m``).

    Returns ``(fits, epochs)``: ``(row, result)`` per fitted heuristic (the row: the fit, and the horizontal error
    ``err_m`` and its direction ``bearing_deg`` (degrees, counter-clockwise from +x) of a stop; start, end and mean
    error, velocity error, speed ratio and heading error (degrees, in [-180, 180)) of a walk; ``result`` the
    :class:`~uwbwb.filters.pruning.LocalizationResult`), and the epoch tables: ``keys``, ``heuristic, t_s, err_m``
    (NaN where an estimator has no position).
    """
    t_s, fits, epochs = log.t_s, [], []

    def add(h, err_m, z=np.nan):
        ep = {**keys, "heuristic": h, "t_s": t_s, "err_m": np.broadcast_to(np.asarray(err_m, float), t_s.shape)}
        if true_z is not None:
            ep["err_z_m"] = np.broadcast_to(np.asarray(z - true_z, float), t_s.shape)
        epochs.append(pd.DataFrame(ep))

    if point:
        P = point_fixes(log.range_m, anchors, dim=config.dim, z_m=z_m) if fixes is None else fixes
        add(POINT, np.linalg.norm(P[:, :2] - (true_xy if epoch_xy is None else epoch_xy), axis=1), P[:, 2])
    samples, plain = RangeSamples.from_ranges(log), None
    for h in heuristics:
        if len(samples) < MIN_SEGMENT_RANGES:
            add(h, np.nan)
            continue
        res = localize(samples, anchors, h, config, stationary=still, z_m=z_m, fit=plain)
        plain = res.fit if h == "none" else plain          # plain NLS: residual pruning's first solve
        row = {"heuristic": h, "t0_s": res.t0_s, "t_end_s": res.t_end_s, "x0_m": res.p0_m[0], "y0_m": res.p0_m[1],
               "z0_m": res.p0_m[2], "vx_mps": res.vel_mps[0], "vy_mps": res.vel_mps[1], "vz_mps": res.vel_mps[2],
               "n_used": res.n_used, "converged": bool(res.fit.converged) if res.fit is not None else True}
        if still:
            d = res.p0_m[:2] - np.asarray(true_xy)
            row.update(err_m=float(np.hypot(*d)), bearing_deg=float(np.rad2deg(np.arctan2(d[1], d[0]))))
            fits.append((row, res))
            add(h, row["err_m"], res.p0_m[2])
            continue
        pos = res.position_at(t_s)
        err = np.linalg.norm(pos[:, :2] - true_xy, axis=1)
        v_est = res.vel_mps[:2]
        v = np.asarray(line_fit(t_s, true_xy)[1] if v_true is None else v_true)
        turn = np.rad2deg(np.arctan2(v_est[1], v_est[0]) - np.arctan2(v[1], v[0]))
        row.update(true_vx_mps=v[0], true_vy_mps=v[1], start_err_m=float(err[0]), end_err_m=float(err[-1]),
                   mean_err_m=float(err.mean()), vel_err_mps=float(np.linalg.norm(v_est - v)),
                   speed_ratio=float(np.linalg.norm(v_est) / np.linalg.norm(v)),
                   heading_err_deg=float((turn + 180.0) % 360.0 - 180.0))
        fits.append((row, res))
        add(h, err, pos[:, 2])
    return fits, epochs


def heuristic_summary(stops: pd.DataFrame, moves: pd.DataFrame | None = None,
                      track: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per estimator: stationary error, walk velocity error, and all distance errors with coverage.

    Returns a DataFrame indexed by estimator (:data:`ESTIMATORS` order) with columns
    ``label, n_stops, stop_median_m, stop_p90_m, stop_max_m`` (one estimate per stop;
    ``stop_err_z_median_m`` (median absolute height error), ``stop_err_z_bias_m``
    (median signed, positive = too high) and ``stop_err_3d_median_m`` when the stops
    carry height errors); with ``moves``: ``n_walks, vel_err_median_mps, speed_ratio_median,
    heading_err_median_deg``; with ``track`` (see :func:`uwbwb.metrics.epoch_summary`):
    ``n_epochs, coverage, all_median_m, all_p90_m, all_p90_failed_counted_m`` over
    every packet of stops and walks (stops only for the 5th percentile, which
    ``all_includes_walks`` says).
    """
    parts = []
    if len(stops):
        g, s = stops.groupby("heuristic"), metrics.epoch_summary(stops, by="heuristic")   # a stop: one epoch
        parts.append(pd.DataFrame({"n_stops": s.n_epochs, "stop_median_m": s.median_m, "stop_p90_m": s.p90_m,
                                   "stop_max_m": g["err_m"].max()}))
        if "err_z_m" in stops:
            parts.append(pd.DataFrame({"stop_err_z_median_m": g["err_z_m"].agg(lambda z: z.abs().median()),
                                       "stop_err_z_bias_m": g["err_z_m"].median(),
                                       "stop_err_3d_median_m": g["err_3d_m"].median()}))
    if moves is not None and len(moves):
        m = moves.groupby("heuristic")
        parts.append(pd.DataFrame({"n_walks": m.size(), "vel_err_median_mps": m["vel_err_mps"].median(),
                                   "speed_ratio_median": m["speed_ratio"].median(),
                                   "heading_err_median_deg": m["heading_err_deg"].agg(lambda a: a.abs().median())}))
    if track is not None and len(track):
        s = metrics.epoch_summary(track, by="heuristic")
        parts.append(pd.DataFrame({"n_epochs": s.n_epochs, "coverage": s.coverage, "all_median_m": s.median_m,
                                   "all_p90_m": s.p90_m, "all_p90_failed_counted_m": s.p90_failed_counted_m,
                                   "all_includes_walks": track["kind"].eq("move").groupby(track["heuristic"]).any()}))
    names = (set(stops["heuristic"]) if len(stops) else set()) | (set(track["heuristic"]) if track is not None else set())
    t = pd.concat(parts, axis=1).reindex([h for h in ESTIMATORS if h in names])
    t.insert(0, "label", t.index.map(LABELS))
    t.index.name = "heuristic"
    return t
