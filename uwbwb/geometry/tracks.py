"""Frames and tracks: the yaw rotation, point fixes along a recording, straight-line segments of a truth track."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..types import Trajectory
from .multilateration import Status, linear_multilaterate, multilaterate


def yaw_rotation(yaw_rad) -> np.ndarray:
    """Rotation about +z by ``yaw_rad`` (body to world), shape ``(..., 3, 3)`` for ``yaw_rad`` of shape ``(...)``.

    ``[[cos, -sin, 0], [sin, cos, 0], [0, 0, 1]]``: a body-frame vector ``v`` is ``R @ v`` in the world.
    """
    yaw = np.asarray(yaw_rad, dtype=float)
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros(yaw.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


# --------------------------------------------------------------------------- fixes and tracks


def point_fixes(range_m, anchors, *, dim: int, z_m: float | None = None) -> np.ndarray:
    """One position per epoch by nonlinear least squares (a point-based system's output).

    Parameters
    ----------
    range_m
        Ranges of the epochs to fix, shape ``(T, n_anchors)``, metres (NaN = missing).
    anchors
        :class:`~uwbwb.types.Anchors` or positions ``(n_anchors, 3)``, metres.
    dim
        2: horizontal fix at the node height ``z_m``; 3: free 3-D fix without height
        information, started from the horizontal linear fix at the height hint
        :func:`uwbwb.filters.nls.initial_guess` uses (1 m below the lowest anchor, the
        side of the anchor plane where nodes are).

    Returns
    -------
    numpy.ndarray
        Positions ``(T, 3)``, metres; NaN rows where no fix exists (too few
        ranges, degenerate geometry, no convergence).
    """
    A = np.asarray(getattr(anchors, "pos_m", anchors), float)
    R = np.asarray(range_m, float)
    if dim == 2:
        if z_m is None:
            raise ValueError("a 2-D point fix needs the node height z_m")
        res = multilaterate(R, A, dim=2, z_m=z_m)
        P = np.column_stack([res.pos_m, np.full(len(R), float(z_m))])
    elif dim == 3:
        z_hint = float(A[:, 2].min() - 1.0)
        xy = linear_multilaterate(R, A, dim=2, z_m=z_hint)
        x0 = np.column_stack([xy, np.full(len(R), z_hint)])
        bad = ~np.isfinite(x0).all(axis=1)
        x0[bad] = np.r_[A[:, :2].mean(axis=0), z_hint]
        res = multilaterate(R, A, dim=3, x0=x0)
        P = np.array(res.pos_m, float)
    else:
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    P[res.status != Status.OK] = np.nan
    return P


def line_fit(t_s: np.ndarray, pos_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares constant-velocity line ``c + v (t - t_0)`` through positions.

    Parameters
    ----------
    t_s
        Times, shape ``(T,)``, seconds (``t_0 = t_s[0]``).
    pos_m
        Positions, shape ``(T, d)``, metres.

    Returns
    -------
    c, v, max_dev_m
        Start point ``(d,)``, velocity ``(d,)`` (m/s) and the largest distance of a
        position from the line, metres.
    """
    G = np.column_stack([np.ones_like(t_s), t_s - t_s[0]])
    coef, *_ = np.linalg.lstsq(G, pos_m, rcond=None)
    dev = np.linalg.norm(pos_m - G @ coef, axis=1).max()
    return coef[0], coef[1], float(dev)


def straight_segments(truth: Trajectory, *, tol_m: float = 0.10, min_duration_s: float = 2.0,
                      min_length_m: float = 0.5, rate_hz: float = 10.0) -> pd.DataFrame:
    """Cut a track into constant-velocity pieces (the motion model of eq. 1 of paper 001).

    Rule: resample the horizontal track at ``rate_hz``; starting at the first
    sample, grow a piece for as long as a straight line at constant velocity,
    ``c + v (t - t_start)`` fitted by least squares (:func:`line_fit`), stays within
    ``tol_m`` of every sample in it (maximum deviation); then start the next piece at
    the first sample it could not take. Pieces shorter than ``min_duration_s`` or
    covering less than ``min_length_m`` (standing, turning on the spot, or a tight
    curve) are dropped. Greedy growth by doubling, then bisection (the deviation
    grows with the piece in practice).

    Returns
    -------
    pandas.DataFrame
        ``segment, t_start_s, t_end_s, duration_s, length_m, speed_mps,
        heading_deg, max_dev_m, x0_m, y0_m, vx_mps, vy_mps`` (line fit).
    """
    if tol_m <= 0 or rate_hz <= 0:
        raise ValueError("tol_m and rate_hz must be positive")
    t = np.arange(truth.t_s[0], truth.t_s[-1], 1.0 / rate_hz)
    P = truth.interp(t)[:, :2]
    n = t.size
    rows, i = [], 0

    def ok(i, j):          # samples i..j-1
        return line_fit(t[i:j], P[i:j])[2] <= tol_m

    while i < n - 2:
        j, step = i + 3, 4
        if not ok(i, j):
            i += 1
            continue
        while j + step <= n and ok(i, j + step):
            j += step
            step *= 2
        lo, hi = j, min(j + step, n + 1)           # ok(i, lo) holds, ok(i, hi) fails (or hi past end)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if mid <= n and ok(i, mid):
                lo = mid
            else:
                hi = mid
        j = lo
        c, v, dev = line_fit(t[i:j], P[i:j])
        dur = t[j - 1] - t[i]
        length = float(np.linalg.norm(v) * dur)
        if dur >= min_duration_s and length >= min_length_m:
            rows.append({"t_start_s": t[i], "t_end_s": t[j - 1], "duration_s": dur, "length_m": length,
                         "speed_mps": float(np.linalg.norm(v)),
                         "heading_deg": float(np.rad2deg(np.arctan2(v[1], v[0]))), "max_dev_m": dev,
                         "x0_m": c[0], "y0_m": c[1], "vx_mps": v[0], "vy_mps": v[1]})
        i = j
    df = pd.DataFrame(rows, columns=["t_start_s", "t_end_s", "duration_s", "length_m", "speed_mps", "heading_deg",
                                     "max_dev_m", "x0_m", "y0_m", "vx_mps", "vy_mps"])
    df.insert(0, "segment", np.arange(len(df)))
    return df
