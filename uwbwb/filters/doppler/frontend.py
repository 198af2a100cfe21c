"""The receiver's front end for independent ultrasonic beacons (paper 003, sections 2 and 5).

* :func:`assign_chirps` — assigns detected chirps to beacons by their periodicity
  and measures ΔP per period (section 2).
* :func:`clock_pseudo_ranges` — pseudo-ranges from a model of the beacons'
  transmission clocks (the ranging term proposed in section 5).

The input checks shared by the Doppler filters (:mod:`.pf`, :mod:`.scaat`) live here too.
Part of the :mod:`uwbwb.filters.doppler` package.
"""

from __future__ import annotations

import numpy as np

from ...models.doppler import DopplerModel
from ...types import ChirpFlag, ChirpLog
from ...validate import integer, number

__all__ = ["assign_chirps", "clock_pseudo_ranges"]


def _check(owner: str, name: str, value, cls: type) -> None:
    if not isinstance(value, cls):
        raise ValueError(f"{owner}: {name} must be a {cls.__name__}, got {type(value).__name__}")


def _per_row(name: str, values, n: int) -> np.ndarray:
    """An optional per-row array of ``log`` (pseudo-ranges): shape ``(n,)``, finite or NaN, ≥ 0."""
    a = np.asarray(values, float)
    if a.shape != (n,):
        raise ValueError(f"{name} must have one value per row of the chirp log, shape ({n},), got {a.shape}")
    if np.any(np.isinf(a)) or np.any(a[np.isfinite(a)] < 0):
        raise ValueError(f"{name} must be >= 0 (NaN: none), got an infinite or negative value")
    return a


# ------------------------------------------------------------------------------------ front end

def assign_chirps(t_s, model: DopplerModel, *, window_s: float = 0.004, max_gap: int = 3) -> ChirpLog:
    """Assign detections to beacons by periodicity and measure ΔP (section 2).

    A detection at ``t`` fits beacon ``i`` (whose last assigned chirp arrived at
    ``t_i``) when ``t − t_i`` is close to ``k P_i`` for some ``k = 1 … max_gap``:
    ``ΔP = (t − t_i)/k − P_i`` with ``|ΔP| ≤ window_s`` (``k > 1``: chirps were missed,
    flag ``GAP``). Several fits: the smallest ``|ΔP|`` wins (flag ``AMBIGUOUS``). No
    fit: the detection may start a train — if an earlier unassigned detection lies
    ``P_j ± window_s`` before it for a beacon ``j`` that is not locked, both become
    beacon ``j``'s (flag ``LOCK``, no ΔP); otherwise the detection is ``UNASSIGNED``.
    A beacon unheard for more than ``max_gap + ½`` periods is unlocked.

    Parameters
    ----------
    t_s
        Arrival times, shape ``(N,)``, strictly increasing.
    model
        Supplies the nominal periods (and beacon ids).
    window_s
        Largest period shift accepted (``P v / v_s``: 3 ms at 2 m/s for P ≈ 0.5 s).
    max_gap
        Largest number of periods bridged over missed chirps.
    """
    _check("assign_chirps", "model", model, DopplerModel)
    window_s = number("window_s", window_s, minimum=0.0, strict_minimum=True)
    max_gap = integer("max_gap", max_gap, minimum=1)
    t_s = np.asarray(t_s, float)
    if t_s.ndim != 1 or not np.all(np.isfinite(t_s)) or np.any(np.diff(t_s) <= 0):
        raise ValueError("t_s must be a 1-D array of finite, strictly increasing arrival times")
    P = model.period_s
    n = P.size
    last = np.full(n, np.nan)
    beacon = np.full(t_s.size, -1)
    dp = np.full(t_s.size, np.nan)
    flags = np.zeros(t_s.size, np.int8)
    pending: list[int] = []
    for r, t in enumerate(t_s):
        stale = np.isfinite(last) & (t - last > (max_gap + 0.5) * P)
        last[stale] = np.nan
        gap = t - last
        k = np.rint(gap / P)
        shift = gap / np.where(k > 0, k, np.nan) - P
        fits = np.isfinite(last) & (k >= 1) & (k <= max_gap) & (np.abs(shift) <= window_s)
        if fits.any():
            cand = np.flatnonzero(fits)
            i = int(cand[np.argmin(np.abs(shift[cand]))])
            beacon[r], dp[r], last[i] = i, shift[i], t
            flags[r] |= (ChirpFlag.GAP if k[i] > 1 else 0) | (ChirpFlag.AMBIGUOUS if cand.size > 1 else 0)
            continue
        pending = [p for p in pending if t - t_s[p] <= P.max() + window_s]
        best = None
        for p in pending:
            off = np.abs(t - t_s[p] - P)
            off[np.isfinite(last)] = np.inf
            j = int(np.argmin(off))
            if off[j] <= window_s and (best is None or off[j] < best[2]):
                best = (p, j, off[j])
        if best is None:
            pending.append(r)
            flags[r] |= ChirpFlag.UNASSIGNED
            continue
        p, j, _ = best
        pending.remove(p)
        beacon[p] = beacon[r] = j
        flags[p] = ChirpFlag.LOCK
        flags[r] = ChirpFlag.LOCK
        last[j] = t
    return ChirpLog(t_s, beacon, dp, flags, model.beacons.ids)


def clock_pseudo_ranges(log: ChirpLog, model: DopplerModel, phase_s) -> np.ndarray:
    """Pseudo-ranges ``v_s (t − t_emit)`` from a beacon-clock model (section 5), metres.

    ``t_emit`` is the emission of the assigned beacon that the clock model (phase
    ``phase_s[i]`` and period ``P_i``) places last before the arrival (flights last
    tens of milliseconds, far less than a period). NaN where the row has no beacon.
    """
    _check("clock_pseudo_ranges", "log", log, ChirpLog)
    _check("clock_pseudo_ranges", "model", model, DopplerModel)
    phase = np.asarray(phase_s, float)
    if phase.shape != (model.n_beacons,) or not np.all(np.isfinite(phase)):
        raise ValueError(f"phase_s must hold one finite phase per beacon, shape ({model.n_beacons},), "
                         f"got {phase.shape}")
    out = np.full(len(log), np.nan)
    ok = log.beacon >= 0
    i = log.beacon[ok]
    P = model.period_s[i]
    t_emit = phase[i] + np.floor((log.t_s[ok] - phase[i]) / P) * P
    out[ok] = model.v_s_mps * (log.t_s[ok] - t_emit)
    return out
