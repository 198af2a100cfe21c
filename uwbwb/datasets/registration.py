"""Registration: putting recordings made on several clocks and in several frames together.

A recording's ranges, motion-capture truth and IMU samples are stamped by
different clocks, and the motion capture may use its own frame and quaternion
convention. Nothing in the files says how they relate, so the loaders estimate
it from the data and report the estimate (and its method) in
``Recording.meta``. The estimators live here, one per question, so that every
loader answers the same question the same way:

* :func:`fit_clock_offset_and_convention` — clock offset between ranges and a
  rigid body's motion capture, and the frame convention (quaternion order,
  body-frame half turn), by minimising the robust spread of bias-removed range
  residuals (:func:`residual_spread`). Used by the ``lias-planar-uwb`` loader.
* :func:`register_truth` — translation (and optionally a yaw) from the
  motion-capture frame to the anchor frame plus the clock offset, by robust
  nonlinear least squares on every range. Used by the ``iasl-uwb-imu`` loader.
* :func:`align_imu` — IMU clock offset, by correlating the gyro magnitude with
  the rotation rate of the registered truth.

All raise :class:`RegistrationError` (or a :class:`~uwbwb.errors.DataFormatError`
naming the file) when the data cannot support an estimate; none of them
assumes an offset of zero.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.optimize import least_squares

from ..calibration import MAD_TO_SIGMA
from ..errors import DataFormatError
from ..geometry import linear_multilaterate, yaw_rotation
from ..types import Anchors, ImuLog, RangeLog, Trajectory

__all__ = ["BODY_FLIPS", "GRAVITY_MPS2", "QUAT_ORDERS", "ClockFrameFit", "ImuAlignment", "Registration",
           "RegistrationError", "align_imu", "body_points", "fit_clock_offset_and_convention", "frame_rotation",
           "quaternion_to_rot", "register_truth", "residual_spread"]

#: Standard gravity used for the specific-force cross-check, m/s².
GRAVITY_MPS2 = 9.80665
#: Quaternion component orders: scalar first or scalar last.
QUAT_ORDERS = ("wxyz", "xyzw")
#: Candidate half turns of a motion-capture body frame relative to the tag frame (axis -> diagonal).
BODY_FLIPS = {"none": (1.0, 1.0, 1.0), "x": (1.0, -1.0, -1.0),
              "y": (-1.0, 1.0, -1.0), "z": (-1.0, -1.0, 1.0)}

class RegistrationError(ValueError):
    """The data cannot support a clock/frame registration (too little overlap or motion)."""


# --------------------------------------------------------------------------------------------
# Rigid-body motion capture: quaternions, clock offset and frame convention from the ranges
# --------------------------------------------------------------------------------------------

def quaternion_to_rot(quat: np.ndarray, order: str = "wxyz") -> np.ndarray:
    """Body-to-world rotation matrices from unit quaternions.

    Parameters
    ----------
    quat
        Quaternions, shape ``(T, 4)``, components in ``order``; normalised here.
    order
        ``"wxyz"`` (scalar first) or ``"xyzw"`` (scalar last).

    Returns
    -------
    ndarray, shape (T, 3, 3)
    """
    if order not in QUAT_ORDERS:
        raise ValueError(f"order must be one of {QUAT_ORDERS}, got {order!r}")
    q = np.asarray(quat, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q if order == "wxyz" else q[..., [3, 0, 1, 2]], -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def _nanmedian(x: np.ndarray, axis: int) -> np.ndarray:
    """Median ignoring NaN along ``axis``; NaN where nothing is finite (and no warning)."""
    x = np.moveaxis(x, axis, -1)
    n = np.isfinite(x).sum(axis=-1)
    lo, hi = np.maximum((n - 1) // 2, 0), n // 2
    s = np.partition(x, np.unique(np.concatenate([lo.ravel(), hi.ravel()])), axis=-1)  # NaN last
    med = 0.5 * (np.take_along_axis(s, lo[..., None], -1) + np.take_along_axis(s, hi[..., None], -1))
    return np.where(n > 0, med[..., 0], np.nan)


def residual_spread(t_meas_s, meas_m, anchors_m, t_ref_s, points_m, offsets_s,
                     min_overlap: float) -> np.ndarray:
    """Robust spread of bias-removed range residuals for each clock offset.

    For offset ``d`` the reference points (motion capture) are interpolated linearly at
    ``t_meas_s + d``; residual = measured - predicted range; per anchor-point pair the
    median residual (the pair's bias) is removed, and the spread is 1.4826 x the median
    absolute value of what is left (a standard deviation for Gaussian noise). Offsets
    at which fewer than ``min_overlap`` of the measurement epochs fall inside the
    reference span get +inf.

    Shapes: ``t_meas_s (N,)``, ``meas_m (N, n_anchors, n_points)``, ``anchors_m
    (n_anchors, 3)``, ``t_ref_s (K,)`` strictly increasing, ``points_m (K, n_points, 3)``,
    ``offsets_s (M,)``; returns ``(M,)`` metres.
    """
    offsets_s = np.atleast_1d(np.asarray(offsets_s, float))
    n, n_anchors, n_points = meas_m.shape
    k = t_ref_s.size
    ref = points_m.reshape(k, n_points * 3)
    out = np.full(offsets_s.size, np.inf)
    chunk = max(1, int(2e6 // max(1, n * n_anchors * n_points)))
    for c0 in range(0, offsets_s.size, chunk):
        offs = offsets_s[c0:c0 + chunk]
        t = t_meas_s[None, :] + offs[:, None]
        inside = (t >= t_ref_s[0]) & (t <= t_ref_s[-1])
        idx = np.clip(np.searchsorted(t_ref_s, t, side="right") - 1, 0, k - 2)
        w = np.clip((t - t_ref_s[idx]) / (t_ref_s[idx + 1] - t_ref_s[idx]), 0.0, 1.0)[..., None]
        pts = (ref[idx] + w * (ref[idx + 1] - ref[idx])).reshape(offs.size, n, n_points, 3)
        # |a - p|^2 = |a|^2 - 2 a.p + |p|^2, laid out (offset, epoch, anchor, point)
        d2 = (np.einsum("aj,aj->a", anchors_m, anchors_m)[:, None]
              - 2.0 * np.einsum("mnpj,aj->mnap", pts, anchors_m)
              + np.einsum("mnpj,mnpj->mnp", pts, pts)[:, :, None, :])
        res = (meas_m[None] - np.sqrt(np.maximum(d2, 0.0))).reshape(offs.size, n, n_anchors * n_points)
        res[~inside] = np.nan
        dev = np.abs(res - _nanmedian(res, axis=1)[:, None, :]).reshape(offs.size, -1)
        spread = MAD_TO_SIGMA * _nanmedian(dev, axis=1)
        ok = (inside.mean(axis=1) >= min_overlap) & np.isfinite(spread)
        out[c0:c0 + offs.size] = np.where(ok, spread, np.inf)
    return out


def body_points(pos_m, rot, offsets_m) -> np.ndarray:
    """World positions of body-frame points, ``(K, n_tags, 3)``."""
    return pos_m[:, None, :] + np.einsum("kij,nj->kni", rot, offsets_m)


def frame_rotation(quat, order: str, flip: str) -> np.ndarray:
    """Tag-frame-to-world rotations ``R(q) @ F`` for a quaternion order and body-frame turn."""
    return quaternion_to_rot(quat, order) * np.asarray(BODY_FLIPS[flip])[None, None, :]


def _parabola_vertex(x: np.ndarray, y: np.ndarray) -> float:
    """Minimum of the least-squares parabola through ``(x, y)``, kept inside ``x``'s span."""
    ok = np.isfinite(y)
    if ok.sum() < 3:
        return float(x[int(np.argmin(y))])
    a, b, _ = np.polyfit(x[ok] - x[0], y[ok], 2)
    if a <= 0:
        return float(x[int(np.argmin(y))])
    return float(np.clip(x[0] - b / (2 * a), x[0], x[-1]))


@dataclass(frozen=True)
class ClockFrameFit:
    clock_offset_s: float
    order: str
    flip: str
    spreads_m: dict
    centroid_offset_s: float
    stride: int


def fit_clock_offset_and_convention(path: Path, t_uwb, range_m, anchors_m, t_mocap, pos_m, quat, offsets_m, *,
              orders, flips, max_offset_s: float, min_overlap: float,
              max_rows: int) -> ClockFrameFit:
    """Estimate the clock offset and the frame convention (see the module notes).

    1. Convention-free: the mean of the tags' ranges against the centroid, on a 100 ms
       grid over +/-``max_offset_s`` then a 10 ms grid around its minimum.
    2. Every (quaternion order, body-frame turn) candidate predicts all ranges at that
       offset; the smallest residual spread chooses the convention.
    3. For the chosen one: a 10 ms grid over +/-80 ms, then five offsets 5 ms apart on
       all rows and the vertex of a parabola fitted through them. The spreads of all
       candidates are reported at that offset.

    The grids use every ``stride``-th UWB row (at most ``max_rows`` rows; a third of
    that for the coarse centroid grid); step 3's parabola uses all rows.
    """
    stride = max(1, -(-t_uwb.size // max_rows))
    t_sub, r_sub = t_uwb[::stride], range_m[::stride]

    def spread(t, r, pts, offsets):
        return residual_spread(t, r, anchors_m, t_mocap, pts, offsets, min_overlap)

    def argmin_grid(t, r, pts, grid):
        s = spread(t, r, pts, grid)
        if not np.isfinite(s).any():
            raise DataFormatError(
                path, f"cannot align the clocks: for every offset within +/-{max_offset_s:g} s "
                      f"the motion capture ({t_mocap[0]:.1f} s to {t_mocap[-1]:.1f} s after the UWB "
                      f"start) covers fewer than {min_overlap:.0%} of the UWB rows, or no range "
                      f"residual is finite")
        return float(grid[int(np.argmin(s))]), s

    cnt = np.isfinite(r_sub).sum(axis=2)
    mean_r = np.where(cnt > 0, np.nansum(r_sub, axis=2) / np.maximum(cnt, 1), np.nan)[..., None]
    centroid = pos_m[:, None, :]
    t_c, r_c = t_sub[::3], mean_r[::3]
    d, _ = argmin_grid(t_c, r_c, centroid, np.arange(-max_offset_s, max_offset_s + 0.05, 0.1))
    d, _ = argmin_grid(t_sub, mean_r, centroid, d + np.arange(-0.15, 0.1505, 0.01))
    d_centroid = d

    points = {(o, f): body_points(pos_m, frame_rotation(quat, o, f), offsets_m)
              for o, f in itertools.product(orders, flips)}
    rough = {key: float(spread(t_sub, r_sub, pts, [d])[0]) for key, pts in points.items()}
    order, flip = min(rough, key=rough.get)
    pts = points[(order, flip)]
    d, _ = argmin_grid(t_sub, r_sub, pts, d + np.arange(-0.08, 0.0805, 0.01))
    grid = d + np.arange(-0.01, 0.0105, 0.005)
    _, s = argmin_grid(t_uwb, range_m, pts, grid)
    offset = _parabola_vertex(grid, s)
    spreads = {f"{o}/{f}": float(spread(t_sub, r_sub, p, [offset])[0]) for (o, f), p in points.items()}
    return ClockFrameFit(offset, order, flip, spreads, d_centroid, stride)


# --------------------------------------------------------------------------------------------
# Motion capture -> anchor frame and UWB clock, from the ranges (rigid translation, clock offset)
# --------------------------------------------------------------------------------------------

def _track(t_ref: np.ndarray, x_ref: np.ndarray, t: np.ndarray, max_gap_s: float):
    """Piecewise-linear samples of a track.

    Returns
    -------
    x : numpy.ndarray
        ``(len(t), d)``, linear (extrapolated beyond the ends).
    slope : numpy.ndarray
        ``(len(t), d)``, derivative of the segment used.
    valid : numpy.ndarray
        ``(len(t),)`` bool: inside the span and on a segment no longer than ``max_gap_s``.
    """
    k = np.clip(np.searchsorted(t_ref, t, side="right") - 1, 0, t_ref.size - 2)
    dt = t_ref[k + 1] - t_ref[k]
    slope = (x_ref[k + 1] - x_ref[k]) / dt[:, None]
    x = x_ref[k] + slope * (t - t_ref[k])[:, None]
    valid = (t >= t_ref[0]) & (t <= t_ref[-1]) & (dt <= max_gap_s)
    return x, slope, valid


def _max_gap(t: np.ndarray) -> float:
    """Longest step bridged by interpolation: 2.5 median sample intervals."""
    return 2.5 * float(np.median(np.diff(t)))


@dataclass(frozen=True)
class Registration:
    """Mocap → anchor frame and UWB clock: ``p = Rz(yaw) p_mocap(t − time_offset_s) + translation_m``.

    Attributes
    ----------
    time_offset_s
        ``t_uwb = t_mocap + time_offset_s``, s.
    translation_m
        ``T``, shape ``(3,)``, metres.
    yaw_rad
        Rotation about z applied before the translation (0 unless fitted), rad.
    range_bias_m
        Common additive range bias fitted as a nuisance parameter (0 unless
        fitted), metres; the ranges themselves are not corrected.
    rms_m, robust_sigma_m, median_abs_m
        Range residual RMS, 1.4826·MAD and median absolute residual, metres.
    per_anchor_median_m
        Median residual per anchor id, metres (per-anchor systematic errors).
    std
        Formal standard errors of the fitted parameters (from the Jacobian,
        robust σ; optimistic because residuals are correlated in time).
    half_offsets_s
        ``time_offset_s`` refitted on the first and the second half of the
        epochs with the other parameters fixed (their difference is a clock
        drift check).
    coarse_time_offset_s
        The start value from the multilateration scan.
    yaw_check_deg, yaw_check_rms_m
        When yaw is not fitted: the yaw a fit with it gives, and that fit's RMS.
    n_epochs, n_residuals
        UWB epochs and finite ranges used.
    method
        Plain-words description.
    """

    time_offset_s: float
    translation_m: np.ndarray
    yaw_rad: float
    range_bias_m: float
    rms_m: float
    robust_sigma_m: float
    median_abs_m: float
    per_anchor_median_m: dict
    std: dict
    half_offsets_s: tuple[float, float]
    coarse_time_offset_s: float
    yaw_check_deg: float | None
    yaw_check_rms_m: float | None
    n_epochs: int
    n_residuals: int
    method: str = ""

    def apply(self, truth: Trajectory, name: str | None = None) -> Trajectory:
        """``truth`` (mocap clock and frame) moved to the UWB clock and anchor frame."""
        r = yaw_rotation(self.yaw_rad)
        pos = truth.pos_m @ r.T + self.translation_m
        vel = None if truth.vel_mps is None else truth.vel_mps @ r.T
        rot = None if truth.rot is None else np.einsum("ij,tjk->tik", r, truth.rot)
        return Trajectory(truth.t_s + self.time_offset_s, pos, vel, rot, name or truth.name)

    def as_dict(self) -> dict:
        """Plain numbers and lists, for reports and JSON."""
        return {"time_offset_s": self.time_offset_s, "translation_m": [float(v) for v in self.translation_m],
                "yaw_deg": float(np.degrees(self.yaw_rad)), "range_bias_m": self.range_bias_m,
                "rms_m": self.rms_m, "robust_sigma_m": self.robust_sigma_m, "median_abs_m": self.median_abs_m,
                "per_anchor_median_m": dict(self.per_anchor_median_m), "std": dict(self.std),
                "half_offsets_s": list(self.half_offsets_s), "coarse_time_offset_s": self.coarse_time_offset_s,
                "yaw_check_deg": self.yaw_check_deg, "yaw_check_rms_m": self.yaw_check_rms_m,
                "n_epochs": self.n_epochs, "n_residuals": self.n_residuals, "method": self.method}


def _lag_grid(lo: float, hi: float, step: float, max_points: int) -> np.ndarray:
    step = max(step, (hi - lo) / max_points)
    return np.arange(lo, hi + 0.5 * step, step)


def _coarse_time_offset(t_uwb, fix_m, truth, lo, hi, max_gap_s) -> tuple[float, np.ndarray]:
    """Offset (and translation) whose mocap track best matches the multilateration fixes."""
    ok = np.all(np.isfinite(fix_m), axis=1)
    t_uwb, fix_m = t_uwb[ok], fix_m[ok]
    if t_uwb.size < 10:
        raise RegistrationError(f"only {t_uwb.size} UWB epochs give a position fix (need 10)")
    sub = np.linspace(0, t_uwb.size - 1, min(t_uwb.size, 2000)).astype(int)
    t_uwb, fix_m = t_uwb[sub], fix_m[sub]
    min_valid = max(10, t_uwb.size // 4)

    def score(dt):
        pos, _, valid = _track(truth.t_s, truth.pos_m, t_uwb - dt, max_gap_s)
        if valid.sum() < min_valid:
            return np.inf, None
        d = fix_m[valid] - pos[valid]
        shift = np.median(d, axis=0)
        return float(np.median(np.hypot(*(d - shift)[:, :2].T))), shift

    best = (np.inf, None, None)
    for step in (0.2, 0.5 * float(np.median(np.diff(truth.t_s)))):
        for dt in _lag_grid(lo, hi, step, 2000):
            s, shift = score(dt)
            if s < best[0]:
                best = (s, dt, shift)
        if best[1] is None:
            raise RegistrationError("UWB and ground-truth time spans never overlap by a quarter of the UWB "
                                    "epochs")
        lo, hi = best[1] - 2 * step, best[1] + 2 * step
    return float(best[1]), best[2]


@np.errstate(over="ignore", invalid="ignore", divide="ignore")  # implausible values end in RegistrationError
def register_truth(ranges: RangeLog, anchors: Anchors, truth: Trajectory, *, fit_yaw: bool = False,
                   fit_range_bias: bool = True, max_offset_s: float | None = None,
                   loss_scale_m: float = 0.1) -> Registration:
    """Estimate the mocap → anchor-frame translation and mocap → UWB clock offset.

    Method in the module docstring: multilateration scan for start values,
    then robust (soft-L1) least squares on all finite ranges with an analytic
    Jacobian.

    Parameters
    ----------
    ranges
        UWB ranges, shape ``(T, n_anchors)``, on the UWB clock.
    anchors
        Anchor positions (the target frame).
    truth
        Mocap track on its own clock and frame, ``pos_m`` shape ``(N, 3)``.
    fit_yaw
        Also fit a rotation about z.
    fit_range_bias
        Also fit a common additive range bias (recommended: it is clearly
        present in the IASL data and otherwise leaks into ``T_z``).
    max_offset_s
        Only consider ``|time_offset_s| <= max_offset_s`` (default: any offset
        that overlaps the two recordings by half the shorter one).
    loss_scale_m
        Soft-L1 scale: residuals beyond it count linearly, metres.

    Returns
    -------
    Registration

    Raises
    ------
    RegistrationError
        Too few fixes, ranges or overlap.
    """
    if len(truth) < 2 or truth.dim != 3:
        raise RegistrationError("ground truth needs at least two 3-D positions")
    if len(ranges) < 2:
        raise RegistrationError("need at least two UWB epochs")
    a = anchors.pos_m
    t_u, r_u = ranges.t_s, ranges.range_m
    gap = _max_gap(truth.t_s)
    span = min(t_u[-1] - t_u[0], truth.t_s[-1] - truth.t_s[0])
    lo, hi = t_u[0] - truth.t_s[-1] + 0.5 * span, t_u[-1] - truth.t_s[0] - 0.5 * span
    if max_offset_s is not None:
        lo, hi = max(lo, -max_offset_s), min(hi, max_offset_s)
    if not lo <= hi:
        raise RegistrationError("no time offset within the allowed range overlaps the recordings enough")
    dt0, shift0 = _coarse_time_offset(t_u, linear_multilaterate(r_u, a, dim=3), truth, lo, hi, gap)

    # epochs whose mocap time stays on the track while the offset moves up to 1 s from the start value
    margin_s = 1.0
    inside = (_track(truth.t_s, truth.pos_m, t_u - dt0 - margin_s, gap)[2]
              & _track(truth.t_s, truth.pos_m, t_u - dt0 + margin_s, gap)[2])
    model = _RangeModel(truth, t_u[inside], a, r_u[inside], gap)

    def fit(yaw: bool, x0: np.ndarray):
        n_par = x0.size
        if model.n_residuals < n_par + 10:
            raise RegistrationError(f"only {model.n_residuals} ranges overlap the ground truth "
                                    f"(need {n_par + 10})")
        if not (np.all(np.isfinite(x0)) and np.all(np.isfinite(model.residuals(x0, yaw, fit_range_bias)))):
            raise RegistrationError("ranges or positions too large to evaluate (non-finite residuals)")
        sol = least_squares(model.residuals, x0, jac=model.jacobian, args=(yaw, fit_range_bias),
                            loss="soft_l1", f_scale=loss_scale_m, x_scale="jac")
        if not np.all(np.isfinite(sol.x)):
            raise RegistrationError("the fit diverged")
        return sol

    x0 = np.concatenate([shift0, [dt0], [0.0] * (fit_yaw + fit_range_bias)])
    sol = fit(fit_yaw, x0)
    res = sol.fun
    trans, dt, psi, b = _RangeModel.unpack(sol.x, fit_yaw, fit_range_bias)
    rms = float(np.sqrt(np.mean(res ** 2)))
    sigma = float(MAD_TO_SIGMA * np.median(np.abs(res - np.median(res))))
    names = (["tx_m", "ty_m", "tz_m", "time_offset_s"] + (["yaw_rad"] if fit_yaw else [])
             + (["range_bias_m"] if fit_range_bias else []))
    cov = np.linalg.pinv(sol.jac.T @ sol.jac) * sigma ** 2
    std = {n: float(np.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(names)}
    per_anchor = {anchors.ids[k]: float(np.median(res[model.anchor == k]))
                  for k in range(len(anchors)) if np.any(model.anchor == k)}

    # drift check: the clock offset alone, refitted on each half of the epochs
    halves = []
    t_res = model.t_epoch[model.epoch]
    mid = np.median(t_res)
    for rows in (t_res < mid, t_res >= mid):
        if rows.sum() < 20:
            halves.append(float("nan"))
            continue
        x = sol.x.copy()

        def fun_dt(y, rows=rows, x=x):
            x[3] = y[0]
            return model.residuals(x, fit_yaw, fit_range_bias)[rows]

        def jac_dt(y, rows=rows, x=x):
            x[3] = y[0]
            return model.jacobian(x, fit_yaw, fit_range_bias)[rows, 3:4]

        halves.append(float(least_squares(fun_dt, [dt], jac=jac_dt, loss="soft_l1", f_scale=loss_scale_m).x[0]))

    yaw_deg = yaw_rms = None
    if not fit_yaw:  # diagnostic only: would a yaw rotation help?
        try:
            alt = fit(True, np.concatenate([sol.x[:4], [0.0], sol.x[4:]]))
        except RegistrationError:
            alt = None
        if alt is not None:
            yaw_deg = float(np.degrees(alt.x[4]))
            yaw_rms = float(np.sqrt(np.mean(alt.fun ** 2)))

    method = ("mocap track moved by p = Rz(yaw) p_mocap(t - dt) + T; start from a scan of dt comparing "
              "linearised multilateration fixes with the mocap track; refined by soft-L1 least squares "
              f"(scale {loss_scale_m} m) on all finite ranges (range = |p - a_i| + b); "
              f"yaw {'fitted' if fit_yaw else 'fixed at 0'}, "
              f"common range bias {'fitted' if fit_range_bias else 'fixed at 0'}")
    return Registration(float(dt), np.array(trans, float), float(psi), float(b), rms, sigma,
                        float(np.median(np.abs(res))), per_anchor, std, (halves[0], halves[1]), float(dt0),
                        yaw_deg, yaw_rms, int(np.unique(model.epoch).size), model.n_residuals, method)


class _RangeModel:
    """Range residuals ``r = d − |Rz(ψ) p_mocap(t − Δt) + T − a_i| − b`` and their Jacobian.

    Parameter vector ``x = [T_x, T_y, T_z, Δt, (ψ), (b)]``; ψ and b are present
    when the ``yaw`` / ``bias`` flags are set. Residuals are ordered by epoch,
    then anchor, over the finite ranges only.
    """

    def __init__(self, truth: Trajectory, t_epoch: np.ndarray, anchors_pos_m: np.ndarray,
                 range_m: np.ndarray, max_gap_s: float):
        self.truth, self.t_epoch, self.max_gap_s = truth, t_epoch, max_gap_s
        self.epoch, self.anchor = np.nonzero(np.isfinite(range_m))
        self.range_m = range_m[self.epoch, self.anchor]
        self.anchor_pos = anchors_pos_m[self.anchor]
        self.n_residuals = int(self.range_m.size)
        self._cache: tuple = (None, None)

    @staticmethod
    def unpack(x: np.ndarray, yaw: bool, bias: bool):
        psi = x[4] if yaw else 0.0
        b = x[4 + yaw] if bias else 0.0
        return x[:3], x[3], psi, b

    def _evaluate(self, x: np.ndarray, yaw: bool, bias: bool):
        key = (x.tobytes(), yaw, bias)
        if self._cache[0] != key:
            trans, dt, psi, b = self.unpack(x, yaw, bias)
            rz = yaw_rotation(psi)
            g, v, _ = _track(self.truth.t_s, self.truth.pos_m, self.t_epoch - dt, self.max_gap_s)
            g, v = g[self.epoch], v[self.epoch]
            diff = g @ rz.T + trans - self.anchor_pos
            dist = np.linalg.norm(diff, axis=1)
            u = diff / np.maximum(dist, 1e-9)[:, None]
            self._cache = (key, (self.range_m - dist - b, u, g, v, rz))
        return self._cache[1]

    def residuals(self, x: np.ndarray, yaw: bool, bias: bool) -> np.ndarray:
        return self._evaluate(x, yaw, bias)[0]

    def jacobian(self, x: np.ndarray, yaw: bool, bias: bool) -> np.ndarray:
        _, u, g, v, rz = self._evaluate(x, yaw, bias)
        cols = [-u, np.sum(u * (v @ rz.T), axis=1)[:, None]]
        if yaw:
            drz = np.array([[-rz[1, 0], -rz[0, 0], 0.0], [rz[0, 0], -rz[1, 0], 0.0], [0.0, 0.0, 0.0]])
            cols.append(-np.sum(u * (g @ drz.T), axis=1)[:, None])
        if bias:
            cols.append(-np.ones((u.shape[0], 1)))
        return np.hstack(cols)


# --------------------------------------------------------------------------------------------
# IMU clock alignment
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ImuAlignment:
    """IMU clock → truth clock: ``t_truth = t_imu + offset_s``.

    Attributes
    ----------
    offset_s
        From the gyro-magnitude correlation, s.
    peak_corr
        Correlation at ``offset_s``.
    second_peak_corr
        Highest other local maximum of the correlation more than 2 s away from
        ``offset_s`` (ambiguity check; NaN if none).
    acc_offset_s, acc_corr
        The same search on specific-force magnitude (cross-check).
    gyro_axes_corr
        ``(3, 3)`` correlation of the gyro axes (columns) with the body rates
        ``vee(Rᵀ Ṙ)`` of the truth attitude (rows), after alignment; a signed
        permutation with entries near ±1 confirms the attitude convention and
        shows how the IMU is mounted. None when truth has no attitude.
    method
        Plain-words description.
    """

    offset_s: float
    peak_corr: float
    second_peak_corr: float
    acc_offset_s: float
    acc_corr: float
    gyro_axes_corr: np.ndarray | None = None
    method: str = ""

    def as_dict(self) -> dict:
        return {"offset_s": self.offset_s, "peak_corr": self.peak_corr,
                "second_peak_corr": self.second_peak_corr, "acc_offset_s": self.acc_offset_s,
                "acc_corr": self.acc_corr,
                "gyro_axes_corr": None if self.gyro_axes_corr is None else np.round(self.gyro_axes_corr, 3).tolist(),
                "method": self.method}


def _pearson(x: np.ndarray, y: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 20:
        return float("nan")
    x, y = x[ok] - x[ok].mean(), y[ok] - y[ok].mean()
    den = np.sqrt(np.sum(x * x) * np.sum(y * y))
    return float(np.sum(x * y) / den) if den > 0 else float("nan")


def _lagged_corr(t_x, x, t_y, y, lags, max_gap_s, chunk: int = 128) -> np.ndarray:
    """Pearson correlation of ``x(t)`` with ``y(t + lag)`` for each lag, vectorised.

    ``y`` is interpolated linearly (not across gaps longer than ``max_gap_s``);
    a lag whose overlap covers fewer than ``max(20, len(x) // 4)`` samples gives NaN.
    """
    out = np.full(lags.size, np.nan)
    x_ok = np.isfinite(x)
    need = max(20, t_x.size // 4)
    for start in range(0, lags.size, chunk):
        t = t_x[None, :] + lags[start:start + chunk, None]
        k = np.clip(np.searchsorted(t_y, t, side="right") - 1, 0, t_y.size - 2)
        dt = t_y[k + 1] - t_y[k]
        yy = y[k] + (y[k + 1] - y[k]) * (t - t_y[k]) / dt
        ok = (t >= t_y[0]) & (t <= t_y[-1]) & (dt <= max_gap_s) & x_ok & np.isfinite(yy)
        n = ok.sum(axis=1)
        xs, ys = np.where(ok, x, 0.0), np.where(ok, yy, 0.0)
        mx, my = xs.sum(axis=1) / np.maximum(n, 1), ys.sum(axis=1) / np.maximum(n, 1)
        dx, dy = np.where(ok, x - mx[:, None], 0.0), np.where(ok, yy - my[:, None], 0.0)
        den = np.sqrt(np.sum(dx * dx, axis=1) * np.sum(dy * dy, axis=1))
        good = (n >= need) & (den > 0) & np.isfinite(den)
        out[start:start + chunk][good] = np.sum(dx * dy, axis=1)[good] / den[good]
    return out


def _best_lag(t_x, x, t_y, y, lo, hi, coarse_s, max_gap_s):
    """Lag ``L`` maximising corr(x(t), y(t + L)); returns (lag, corr, second-peak corr).

    Coarse grid of ``coarse_s`` over ``[lo, hi]``, then 20 ms and 2 ms grids
    around the best lag.
    """
    lags = _lag_grid(lo, hi, coarse_s, 4000)
    c = _lagged_corr(t_x, x, t_y, y, lags, max_gap_s)
    if not np.any(np.isfinite(c)):
        return float("nan"), float("nan"), float("nan")
    k = int(np.nanargmax(c))
    # the highest other local maximum more than 2 s away (an alternative alignment)
    cc = np.pad(np.where(np.isfinite(c), c, -np.inf), 1, constant_values=-np.inf)
    peak = (cc[1:-1] >= cc[:-2]) & (cc[1:-1] >= cc[2:])
    other = peak & np.isfinite(c) & (np.abs(lags - lags[k]) > 2.0)
    second = float(np.max(c[other])) if other.any() else float("nan")
    best, corr = float(lags[k]), float(c[k])
    for half_width, step in ((2 * coarse_s, 0.02), (0.04, 0.002)):
        fine = best + np.arange(-half_width, half_width + 1e-9, step)
        cf = _lagged_corr(t_x, x, t_y, y, fine, max_gap_s)
        if np.any(np.isfinite(cf)) and np.nanmax(cf) >= corr:
            j = int(np.nanargmax(cf))
            best, corr = float(fine[j]), float(cf[j])
    return best, corr, second


def _rate_magnitude(truth: Trajectory, max_gap_s: float):
    """Mid-interval times and rotation-rate magnitude (rad/s) of the truth attitude."""
    rel = np.einsum("tji,tjk->tik", truth.rot[:-1], truth.rot[1:])
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    dt = np.diff(truth.t_s)
    ok = dt <= max_gap_s
    return (0.5 * (truth.t_s[:-1] + truth.t_s[1:]))[ok], (np.arccos(cos) / dt)[ok]


def _smooth_on_grid(t: np.ndarray, x: np.ndarray, width_s: float, max_points: int = 5000):
    """``x`` box-filtered over ``width_s``, sampled every ``width_s / 2`` (at most ``max_points``)."""
    step = max(width_s / 5.0, (t[-1] - t[0]) / 200_000)
    grid = np.arange(t[0], t[-1], step)
    y = uniform_filter1d(np.interp(grid, t, x), size=max(1, int(round(width_s / step))), mode="nearest")
    keep = max(1, int(round(0.5 * width_s / step)), -(-grid.size // max_points))
    return grid[::keep], y[::keep]


@np.errstate(over="ignore", invalid="ignore", divide="ignore")  # implausible values end in RegistrationError
def align_imu(imu: ImuLog, truth: Trajectory, *, max_lag_s: float | None = None) -> ImuAlignment:
    """Clock offset of an IMU against a truth track with attitude.

    The gyro magnitude, box-filtered over one truth sample interval, is
    correlated with the rotation-rate magnitude of the truth attitude
    (``arccos((tr(R_kᵀ R_{k+1}) − 1)/2) / Δt``) for lags on a 0.1 s grid, then
    on 20 ms and 2 ms grids around the best one. Magnitudes do not depend on how the
    IMU is mounted. The specific-force magnitude (``|a + g ẑ|`` from the truth
    positions, twice differentiated, vs ``|f_imu|``) gives an independent
    cross-check.

    Parameters
    ----------
    imu
        IMU samples on their own clock.
    truth
        Track with ``rot`` (body-to-world), shape ``(N, 3, 3)``.
    max_lag_s
        Only consider ``|offset| <= max_lag_s`` (default: any lag overlapping
        the two by half the shorter one).

    Returns
    -------
    ImuAlignment

    Raises
    ------
    RegistrationError
        No attitude, too few samples or no overlap.
    """
    if truth.rot is None or len(truth) < 3:
        raise RegistrationError("IMU alignment needs a truth track with attitude (at least 3 samples)")
    if len(imu) < 20:
        raise RegistrationError(f"only {len(imu)} IMU samples (need 20)")
    gap = _max_gap(truth.t_s)
    width = float(np.median(np.diff(truth.t_s)))
    span = min(imu.t_s[-1] - imu.t_s[0], truth.t_s[-1] - truth.t_s[0])
    lo, hi = truth.t_s[0] - imu.t_s[-1] + 0.5 * span, truth.t_s[-1] - imu.t_s[0] - 0.5 * span
    if max_lag_s is not None:
        lo, hi = max(lo, -max_lag_s), min(hi, max_lag_s)
    if not lo <= hi:
        raise RegistrationError("IMU and truth time spans do not overlap enough")
    t_w, w = _rate_magnitude(truth, gap)
    if t_w.size < 3:
        raise RegistrationError("too few gap-free truth attitude pairs")
    t_g, g = _smooth_on_grid(imu.t_s, np.linalg.norm(imu.gyro_radps, axis=1), width)
    offset, peak, second = _best_lag(t_g, g, t_w, w, lo, hi, 0.1, gap)
    if not np.isfinite(offset):
        raise RegistrationError("gyro and truth rotation rate never overlap enough to correlate")

    vel = np.gradient(truth.pos_m, truth.t_s, axis=0)
    acc = np.gradient(vel, truth.t_s, axis=0)
    f_truth = np.linalg.norm(acc + [0.0, 0.0, GRAVITY_MPS2], axis=1)
    t_f, f = _smooth_on_grid(imu.t_s, np.linalg.norm(imu.acc_mps2, axis=1), width)
    acc_offset, acc_corr, _ = _best_lag(t_f, f, truth.t_s, f_truth, lo, hi, 0.1, gap)

    rot = truth.rot
    rdot = np.diff(rot, axis=0) / np.diff(truth.t_s)[:, None, None]
    w_mat = np.einsum("tji,tjk->tik", 0.5 * (rot[:-1] + rot[1:]), rdot)
    w_body = 0.5 * np.stack([w_mat[:, 2, 1] - w_mat[:, 1, 2], w_mat[:, 0, 2] - w_mat[:, 2, 0],
                             w_mat[:, 1, 0] - w_mat[:, 0, 1]], axis=1)
    t_mid = 0.5 * (truth.t_s[:-1] + truth.t_s[1:])
    ok = (np.diff(truth.t_s) <= gap) & (t_mid - offset >= imu.t_s[0]) & (t_mid - offset <= imu.t_s[-1])
    axes = None
    if ok.sum() >= 20:
        gyro = np.column_stack([np.interp(t_mid[ok] - offset, imu.t_s, imu.gyro_radps[:, j]) for j in range(3)])
        axes = np.array([[_pearson(w_body[ok, i], gyro[:, j]) for j in range(3)] for i in range(3)])

    method = ("lag maximising the correlation of |gyro| (box-filtered over one truth interval) with the "
              "rotation-rate magnitude of the truth attitude; 0.1 s, 20 ms, 2 ms grids; cross-check with "
              "specific-force magnitude")
    return ImuAlignment(offset, peak, second, acc_offset, acc_corr, axes, method)
