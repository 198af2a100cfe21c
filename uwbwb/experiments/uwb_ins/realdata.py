"""Notebook 05's real-data table (``iasl-uwb-imu``): horizontal, vertical and 3-D error on common
epochs, block-bootstrap intervals on the differences between methods, and consistency (NEES, NIS).

Every method of a :class:`~uwbwb.filters.alignment.Comparison` from :func:`~uwbwb.filters.alignment.compare_iasl` is scored on the
**common epochs**: those where the truth exists and every method has an estimate. The errors of
one method are correlated in time, so an interval on a difference resamples contiguous blocks
of epochs (a block bootstrap over non-overlapping blocks), never single epochs.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from ... import metrics
from ...metrics import MIN_BLOCKS, block_bootstrap_difference, interval_side
from ...filters.alignment import Comparison

__all__ = ["PAIRS", "summary_rows", "common_epochs", "error_table", "difference_table",
           "difference_verdict", "consistency_table"]


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
    own coverage of the scored epochs and the common-epoch count."""
    methods = list(methods or comp.estimates)
    sel = common_epochs(comp, methods)
    scored = comp.masks.get("scored", np.ones(len(comp.truth), bool))
    rows = {}
    for m in methods:
        e = _err(comp, m)[sel]
        row = {"horizontal RMSE (m)": float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, axis=1))))}
        if e.shape[1] == 3 and comp.truth.pos_m.shape[1] == 3:
            row["vertical RMSE (m)"] = float(np.sqrt(np.mean(e[:, 2] ** 2)))
            row["3-D RMSE (m)"] = float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))
        own = np.all(np.isfinite(comp.estimates[m].pos_m[scored]), axis=1)
        row["coverage"] = float(own.mean()) if own.size else np.nan
        row["common epochs"] = int(sel.sum())
        rows[m] = row
    return pd.DataFrame(rows).T


def difference_verdict(a: str, b: str, r: dict) -> str:
    """Which of ``a`` and ``b`` is more accurate by the interval of ``RMSE(a) − RMSE(b)``
    (:func:`uwbwb.metrics.block_bootstrap_difference`), "not significant", or no verdict with too few blocks."""
    return {"below": f"{a} more accurate", "above": f"{b} more accurate", "contains": "not significant"}.get(
        interval_side(r["lo_m"], r["hi_m"]), f"no verdict (fewer than {MIN_BLOCKS} blocks)")


def difference_table(comp: Comparison, pairs, *, rng: np.random.Generator, horizontal: bool = True) -> pd.DataFrame:
    """:func:`uwbwb.metrics.block_bootstrap_difference` (the package's one interval rule) for each ``(a, b)`` of
    ``pairs`` on the common epochs of every method in the pairs, with its blocks and :func:`difference_verdict`."""
    names = sorted({m for p in pairs for m in p})
    sel = common_epochs(comp, names)
    k = 2 if horizontal else None
    rows = {}
    for a, b in pairs:
        ea = np.linalg.norm(_err(comp, a)[sel][:, :k], axis=1)
        eb = np.linalg.norm(_err(comp, b)[sel][:, :k], axis=1)
        r = block_bootstrap_difference(ea, eb, rng=rng)
        rows[f"{a} − {b}"] = {"difference (mm)": r["diff_m"] * 1e3, "lo (mm)": r["lo_m"] * 1e3,
                              "hi (mm)": r["hi_m"] * 1e3, "epochs": r["n"], "blocks": r["n_blocks"],
                              "verdict": difference_verdict(a, b, r)}
    t = pd.DataFrame(rows).T
    num = ["difference (mm)", "lo (mm)", "hi (mm)"]
    t[num] = t[num].astype(float)
    t[["epochs", "blocks"]] = t[["epochs", "blocks"]].astype(int)
    return t


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


#: The differences notebook 05 reports (a − b): tight vs loose, each fusion filter vs the gated IMU-free EKF.
PAIRS = (("tight", "loose"), ("tight", "EKF + gate"), ("loose", "EKF + gate"), ("EKF + gate", "UWB-only"))


def summary_rows(comp: Comparison, *, cal_label: str, seed: int = 0) -> list[dict]:
    """Summary rows of one real recording: horizontal / vertical / 3-D RMSE per method on the
    common epochs, the :data:`PAIRS` differences (mm) and each method's mean NEES."""
    data = comp.label
    out = []
    t = error_table(comp)
    for m in t.index:
        for col in ("horizontal RMSE (m)", "vertical RMSE (m)", "3-D RMSE (m)"):
            if col in t.columns and np.isfinite(t.loc[m, col]):
                out.append(dict(quantity=f"{col.split(' (')[0]} {m}, common epochs (calibrated on {cal_label})",
                                value=t.loc[m, col], unit="m", data=data, kind="reproduced"))
    pairs = [p for p in PAIRS if all(x in comp.estimates for x in p)]
    d = difference_table(comp, pairs, rng=np.random.default_rng(seed))
    for name in d.index:
        out.append(dict(quantity=f"horizontal RMSE difference {name} (block bootstrap on common epochs)",
                        value=d.loc[name, "difference (mm)"], unit="mm", data=data, kind="reproduced"))
    c = consistency_table(comp)
    for m in c.index:
        out.append(dict(quantity=f"mean position NEES {m} ({int(c.loc[m, 'dof'])} dof)", value=c.loc[m, "mean NEES"],
                        unit="", data=data, kind="reproduced"))
    return out
