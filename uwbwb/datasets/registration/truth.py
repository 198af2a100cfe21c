"""Registration of motion-capture truth to the anchor frame and the range clock (:func:`register_truth`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ...calibration import MAD_TO_SIGMA
from ...geometry import linear_multilaterate, yaw_rotation
from ...types import Anchors, RangeLog, Trajectory
from .clock import RegistrationError


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
