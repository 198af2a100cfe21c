"""Constants, the lever-arm check and the time line (IMU samples, UWB epochs, IMU gaps) of the UWB/INS filters."""

from __future__ import annotations

import math

import numpy as np

from ...models.imu import UNIT_GRAVITY_TOLERANCE_MPS2, check_body_imu
from ...models.ins import NavState
from ...types import ImuLog


_DEG = math.pi / 180.0
_ITER_TOL_M = 1e-4           # an iterated update stops when the position moves less than this, m
HEADING_KNOWN_RAD = 10 * _DEG  # an initial yaw σ at most this is a known heading: the gate is engaged at once
LOST_BUILD_S = 1.0           # lost lock: the time over which the position error is assumed to have built up, s
MAX_IMU_GAP_STEPS = 5        # an IMU step longer than this many median steps is a gap (the loader's rule)
SNAPSHOT_RMS_SIGMAS = 3.0    # a snapshot fix is consistent when its TDoA residual RMS is at most this many TDoA σ


def check_inputs(where: str, imu, x0) -> None:
    """A filter's entry: ``imu`` must be an :class:`~uwbwb.types.ImuLog` (which holds finite samples) and ``x0``
    a :class:`~uwbwb.models.ins.NavState` — a ``TypeError`` naming ``where`` and how to build one otherwise —,
    and the samples must be body-frame SI ones (:func:`~uwbwb.models.imu.check_body_imu`: m/s² not g or mg,
    rad/s not deg/s, z up, no spike beyond full scale) — a ``ValueError`` naming ``where`` otherwise. The
    loaders run the same rules; this is where the Python API meets them, with gravity allowed g/2 either way
    (:data:`~uwbwb.models.imu.UNIT_GRAVITY_TOLERANCE_MPS2`: a unit error, not a poor or mis-simulated sensor)."""
    if not isinstance(imu, ImuLog):
        raise TypeError(f"{where}: imu must be an ImuLog (t_s, acc_mps2, gyro_radps in the body frame, SI), got "
                        f"{type(imu).__name__}; build one with uwbwb.types.ImuLog(t_s, acc_mps2, gyro_radps)")
    if not isinstance(x0, NavState):
        raise TypeError(f"{where}: x0 must be a NavState (position, velocity, attitude at the first IMU sample), "
                        f"got {type(x0).__name__}; build one with uwbwb.models.ins.NavState(...)")
    check_body_imu(imu, source=f"{where}: imu", gravity_tolerance_mps2=UNIT_GRAVITY_TOLERANCE_MPS2)


def _lever(name: str, value) -> np.ndarray:
    """A lever arm: 3 finite numbers, m, body frame."""
    try:
        lever = np.array(value, float)
    except (TypeError, ValueError):
        lever = np.array([np.nan])
    if lever.shape != (3,) or not np.all(np.isfinite(lever)):
        raise ValueError(f"{name} must be 3 finite numbers (m, body frame), got {value!r}")
    return lever


# ====================================================================== inputs
def merge_timeline(imu: ImuLog, t_epoch_s: np.ndarray):
    """IMU samples and UWB epochs on one time line.

    Returns
    -------
    t_s (N,), acc_mps2 (N, 3), gyro_radps (N, 3), epoch_idx (E,)
        The union of the IMU times and the epochs inside the IMU span, the IMU values
        there (linear interpolation at epochs between samples), and each epoch's index
        in ``t_s`` (−1 for epochs outside the IMU span).
    """
    te = np.asarray(t_epoch_s, float)
    inside = (te >= imu.t_s[0]) & (te <= imu.t_s[-1])
    t = np.union1d(imu.t_s, te[inside])
    acc = np.column_stack([np.interp(t, imu.t_s, imu.acc_mps2[:, j]) for j in range(3)])
    gyro = np.column_stack([np.interp(t, imu.t_s, imu.gyro_radps[:, j]) for j in range(3)])
    idx = np.full(te.size, -1)
    idx[inside] = np.searchsorted(t, te[inside])
    return t, acc, gyro, idx


def imu_gaps(imu_t_s: np.ndarray, t_s: np.ndarray, max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The IMU gaps on a merged time line.

    Returns
    -------
    coast (N,), gaps_s (G, 2)
        ``coast[i]``: the step ``t_s[i−1] → t_s[i]`` lies inside an interval between IMU samples
        longer than ``max_gap_s`` (no sample measured the motion there); the ``(start, end)``
        times of those intervals, s.
    """
    ti = np.asarray(imu_t_s, float)
    step = np.diff(ti)
    big = np.flatnonzero(step > max_gap_s)
    gaps = np.column_stack([ti[big], ti[big + 1]]) if big.size else np.zeros((0, 2))
    t = np.asarray(t_s, float)
    coast = np.zeros(t.size, bool)
    for a, b in gaps:
        coast[1:] |= (t[1:] > a) & (t[1:] <= b)
    return coast, gaps


def gap_timeline(imu: ImuLog, t_epoch_s: np.ndarray, max_imu_gap_s: float | None):
    """:func:`merge_timeline` with the IMU gaps marked (the rule every UWB/INS filter and
    :func:`~uwbwb.filters.eskf.dead_reckon` use).

    A step between IMU samples longer than ``max_imu_gap_s`` (None: :data:`MAX_IMU_GAP_STEPS`
    median IMU steps, the loader's rule) is a gap (:func:`imu_gaps`); the IMU values at time-line
    points inside a gap are NaN, not interpolated: nothing measured the motion there.

    Returns
    -------
    t_s (N,), acc_mps2 (N, 3), gyro_radps (N, 3), epoch_idx (E,), coast (N,), gaps_s (G, 2)
        As :func:`merge_timeline` and :func:`imu_gaps`.
    """
    t, acc, gyro, ep_idx = merge_timeline(imu, t_epoch_s)
    max_gap = (MAX_IMU_GAP_STEPS * float(np.median(np.diff(imu.t_s))) if max_imu_gap_s is None
               else max_imu_gap_s) if imu.t_s.size > 1 else math.inf
    coasting, gaps_s = imu_gaps(imu.t_s, t, max_gap)
    inside = coasting & ~np.isin(t, imu.t_s)
    acc[inside], gyro[inside] = np.nan, np.nan
    return t, acc, gyro, ep_idx, coasting, gaps_s
