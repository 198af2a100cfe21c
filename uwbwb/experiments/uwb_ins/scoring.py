"""Scoring of one ablation run (:mod:`.ablation`): the epoch masks (scored, outage, recovery), the
RMSE / max / coverage of a row on a mask, and the re-acquisition time after the outage."""

from __future__ import annotations

import math

import numpy as np

from ...sim import robot

__all__ = ["RECOVERY_MAX_M", "HOLD_S", "reacquisition_s"]

#: Error (m) a filter must get below, and stay below, within :data:`~.ablation.RECOVERY_S` of UWB's
#: return after the outage to count as re-acquired (:func:`reacquisition_s`; matched world, every seed).
RECOVERY_MAX_M = 0.5


def _masks(run: robot.RobotRun, k0: int, recovery_s: float) -> dict:
    T = len(run.truth)
    scored = np.arange(T) >= k0
    if not run.outage.any():
        return {"all": scored}
    t = run.truth.t_s
    t_end = t[run.outage][-1]
    rec = (t > t_end) & (t <= t_end + recovery_s)
    return {"all": scored & ~run.outage & ~rec, "outage": scored & run.outage, "recovery": scored & rec}


#: Seconds the error must then stay below the limit for the filter to count as re-acquired.
HOLD_S = 5.0


def reacquisition_s(t_s: np.ndarray, err_m: np.ndarray, t_end_s: float, limit_m: float = RECOVERY_MAX_M,
                    hold_s: float = HOLD_S) -> float:
    """Seconds from UWB's return after an outage until the error gets below ``limit_m`` and holds.

    UWB returns at the first epoch after ``t_end_s`` (the outage's last epoch); the filter has
    re-acquired at the first epoch from which the error stays below ``limit_m`` for ``hold_s``
    seconds, or to the end of the run if that comes first (a missing, non-finite error counts as
    not below). Returns 0 when it holds from the return, ``inf`` when no such stretch starts
    (never re-acquired), NaN when no epoch follows the outage. The drift UWB finds on its return
    is the outage's own score (``outage_max``) and a later excursion the dynamic score's: this is
    the time to re-acquire, neither the error at return nor what happens long after.

    Parameters
    ----------
    t_s, err_m
        Epoch times (s) and errors (m), shape ``(T,)``, scored epochs only.
    """
    t_s, err_m = np.asarray(t_s, float), np.asarray(err_m, float)
    after = t_s > t_end_s
    if not after.any():
        return np.nan
    t, e = t_s[after], err_m[after]
    ok = e < limit_m
    # stretches of consecutive epochs below the limit: [starts[i], ends[i]) in epoch indices
    edge = np.diff(np.r_[0, ok.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1)
    held = (t[ends - 1] - t[starts] >= hold_s) | (ends == t.size)
    if not held.any():
        return math.inf
    return float(t[starts[np.argmax(held)]] - t[0])


def _error_m(pos_m: np.ndarray, truth_m: np.ndarray) -> np.ndarray:
    """Horizontal error per epoch (m); NaN where the row gave no finite position (the scorer's "no estimate")."""
    return np.where(np.isfinite(pos_m).all(axis=1), np.linalg.norm(pos_m - truth_m, axis=1), np.nan)


def _reacq(run: robot.RobotRun, k0: int, pos: np.ndarray, truth_m: np.ndarray) -> float:
    """:func:`reacquisition_s` of one row on one dynamic run (NaN without an outage)."""
    if not run.outage.any():
        return np.nan
    t = run.truth.t_s
    e = np.linalg.norm(pos - truth_m, axis=1)
    return reacquisition_s(t[k0:], e[k0:], float(t[run.outage][-1]))
