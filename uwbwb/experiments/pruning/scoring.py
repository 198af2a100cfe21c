"""Notebook 02's scoring: estimator names and the per-estimator table.

Every comparison of notebook 02 scores its estimators on one *epoch table* (one row per estimator
and scored epoch, ``err_m`` NaN where the estimator produced nothing); :func:`uwbwb.metrics.epoch_summary`
(``by="heuristic", order=ESTIMATORS``) turns it into coverage beside accuracy, :func:`heuristic_summary`
condenses stops, walks and packets per estimator.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ... import metrics
from ...filters.pruning import HEURISTICS, LABELS as HEURISTIC_LABELS

__all__ = ["ESTIMATORS", "LABELS", "MIN_SEGMENT_RANGES", "PAPER_RANKING", "POINT", "bearing_deg", "heading_err_deg",
           "heuristic_summary"]

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


def bearing_deg(dxy: np.ndarray) -> np.ndarray:
    """Direction of ``dxy`` (..., 2) in degrees, counter-clockwise from +x (the polar charts' convention)."""
    return np.rad2deg(np.arctan2(dxy[..., 1], dxy[..., 0]))


def heading_err_deg(v_est, v_true) -> float:
    """Signed angle (degrees, in [-180, 180)) from the true heading ``v_true`` to the estimated ``v_est``."""
    ang = np.rad2deg(np.arctan2(v_est[1], v_est[0]) - np.arctan2(v_true[1], v_true[0]))
    return float((ang + 180.0) % 360.0 - 180.0)


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
            s = metrics.epoch_summary(tr, by="heuristic").iloc[0]
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
