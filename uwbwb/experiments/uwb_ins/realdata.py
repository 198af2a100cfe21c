"""Notebook 05's real-data tables (``iasl-uwb-imu``): horizontal, vertical and 3-D error on common
epochs, and consistency (NEES, NIS), of the methods on a scoreboard (:func:`board_comparison`: the board
runs and tunes them; these tables read its estimates). Which method is more accurate is the scoreboard's
verdict (:func:`uwbwb.scoreboard.verdicts.difference_table`), not this module's.

Every method of a :class:`~uwbwb.filters.alignment.Comparison` is scored on the **common epochs**: those
where the truth exists and every method has an estimate.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from ... import metrics
from ...filters.alignment import Comparison
from ...scoreboard import Board
from ...types import Trajectory

__all__ = ["board_comparison", "summary_rows", "common_epochs", "error_table", "consistency_table"]


def board_comparison(board: Board, tag: str = "tag", methods=None) -> Comparison:
    """The board's estimates of ``methods`` (default: every method that ran) on ``tag`` as a
    :class:`~uwbwb.filters.alignment.Comparison` (the container notebook 05's tables and figures read):
    truth at the board's epochs (``masks["scored"]``: where it exists), and the TDoAs eq. 4 and the tight
    filter's gate rejected (``rejected``, where the board has a ``tight`` row)."""
    ents = [e for e in board.ran(tag) if methods is None or e.method in methods]
    if not ents:
        raise ValueError(f"{board.label}: no method ran on {tag!r}")
    t = ents[0].estimates.t_s
    have = ents[0].scoring
    truth = Trajectory(t, np.where(have[:, None], ents[0].truth_pos_m, 0.0), name="truth")
    est = {e.method: e.estimates for e in ents}
    rejected = {}
    if "tight" in est:
        info = est["tight"].info
        rejected = {"eq4": int(np.sum(info.get("n_outliers", 0))), "gated": int(np.sum(info.get("n_gated", 0)))}
    first = {m: e.t_s[e.has_estimate][0] for m, e in est.items() if e.has_estimate.any()}
    return Comparison(board.data_label, truth, est, {}, {"scored": have}, rejected, 2,
                      {"start_s": float(max(first.values())) if first else np.nan})


def common_epochs(comp: Comparison, methods=None) -> np.ndarray:
    """Epochs scored for every method in ``methods`` (default: all): truth present, estimate present."""
    sel = comp.masks.get("scored", np.ones(len(comp.truth), bool)).copy()
    for m in methods or comp.estimates:
        sel &= np.all(np.isfinite(comp.estimates[m].pos_m), axis=1)
    return sel


def _err(comp: Comparison, m: str) -> np.ndarray:
    est = comp.estimates[m].pos_m
    d = est.shape[1]
    return est - comp.truth.pos_m[:, :d]


def error_table(comp: Comparison, methods=None) -> pd.DataFrame:
    """Horizontal, vertical and 3-D RMSE per method on the common epochs (m), with each method's
    own coverage of the scored epochs and the common-epoch count: :func:`uwbwb.metrics.score_epochs`."""
    methods = list(methods or comp.estimates)
    scored = comp.masks.get("scored", np.ones(len(comp.truth), bool))
    common = common_epochs(comp, methods)
    err = {m: _err(comp, m) for m in methods}
    parts = {"horizontal RMSE (m)": {m: np.linalg.norm(e[:, :2], axis=1) for m, e in err.items()}}
    if comp.truth.pos_m.shape[1] == 3 and all(e.shape[1] == 3 for e in err.values()):
        parts["vertical RMSE (m)"] = {m: np.abs(e[:, 2]) for m, e in err.items()}
        parts["3-D RMSE (m)"] = {m: np.linalg.norm(e, axis=1) for m, e in err.items()}
    cols = [metrics.score_epochs(e, common).table(common={col: metrics.rmse})[col] for col, e in parts.items()]
    own = metrics.score_epochs(parts["horizontal RMSE (m)"], scored)
    return pd.concat(cols + [pd.Series({m.name: m.coverage for m in own}, name="coverage"),
                             pd.Series(int(common.sum()), index=methods, name="common epochs")], axis=1).rename_axis(None)


def consistency_table(comp: Comparison, methods=None, *, prob: float = 0.95) -> pd.DataFrame:
    """Position NEES (3 dof where the estimate is 3-D) and NIS of every method with a covariance.

    NEES ``eᵀP⁻¹e`` of the position error against the method's own position covariance on the
    common epochs: its mean (``dof`` if the covariance is honest) and the share of epochs inside
    the method's own ``prob`` ellipse (``prob`` if honest); and the mean NIS per degree of
    freedom of its updates (1 if honest) where the method keeps one. The inflation that makes
    the mean NEES equal to its dof is ``mean NEES / dof`` (a covariance scale).
    """
    methods = list(methods or comp.estimates)
    sel = common_epochs(comp, methods)
    rows = {}
    for m in methods:
        est = comp.estimates[m]
        if est.pos_cov_m2 is None:
            continue
        e = _err(comp, m)[sel]
        P = est.pos_cov_m2[sel]
        ok = np.all(np.isfinite(P.reshape(len(P), -1)), axis=1)
        if not ok.any():
            continue
        dof = e.shape[1]
        nees = metrics.nees(e, P, ok)[ok]
        row = {"dof": dof, "mean NEES": float(nees.mean()),
               f"inside own {prob:.0%} ellipse": float(np.mean(nees <= stats.chi2.ppf(prob, dof))),
               "covariance inflation for mean NEES = dof": float(nees.mean() / dof)}
        nis, ndof = est.info.get("nis"), est.info.get("dof")
        if nis is not None and ndof is not None:
            row["mean NIS / dof"] = metrics.nis_consistency(nis, ndof, prob)["mean_nis_over_dof"]
        rows[m] = row
    return pd.DataFrame(rows).T


def summary_rows(comp: Comparison, *, cal_label: str) -> list[dict]:
    """Summary rows of one real recording: horizontal / vertical / 3-D RMSE per method on the
    common epochs (``RMSE {method} (calibrated on …)``: the horizontal one, as :func:`error_table` shows it, not
    on each method's own epochs) and each method's mean NEES (the verdicts between methods are the scoreboard's)."""
    data = comp.label
    t = error_table(comp)
    out = [dict(quantity=f"RMSE {m} (calibrated on {cal_label})", value=v, unit="m", data=data, kind="reproduced")
           for m, v in t["horizontal RMSE (m)"].items() if np.isfinite(v)]
    for m in t.index:
        for col in ("horizontal RMSE (m)", "vertical RMSE (m)", "3-D RMSE (m)"):
            if col in t.columns and np.isfinite(t.loc[m, col]):
                out.append(dict(quantity=f"{col.split(' (')[0]} {m}, common epochs (calibrated on {cal_label})",
                                value=t.loc[m, col], unit="m", data=data, kind="reproduced"))
    c = consistency_table(comp)
    for m in c.index:
        out.append(dict(quantity=f"mean position NEES {m} ({int(c.loc[m, 'dof'])} dof)", value=c.loc[m, "mean NEES"],
                        unit="", data=data, kind="reproduced"))
    return out
