"""IMU clock offset: from the gyro magnitude against the registered truth's rotation rate
(:func:`align_imu`), or from the tag's own ranges without motion capture (:func:`align_imu_to_ranges`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d

from ...geometry import Status, multilaterate
from ...types import Anchors, ImuLog, RangeLog, Trajectory
from .clock import GRAVITY_MPS2, RegistrationError
from .truth import _lag_grid, _max_gap


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
    half_offsets_s
        The offset found on each half of the recording (within ±1 s of ``offset_s``), a
        consistency check; None where not computed (:func:`align_imu`).
    """

    offset_s: float
    peak_corr: float
    second_peak_corr: float
    acc_offset_s: float
    acc_corr: float
    gyro_axes_corr: np.ndarray | None = None
    method: str = ""
    half_offsets_s: tuple[float, float] | None = None


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
        No attitude, too few samples or no overlap; a correlation peak under :data:`MIN_PEAK_CORR` (an IMU
        from another recording, or one that did not move). A rival peak is reported (``second_peak_corr``), not
        refused: at the right lag the gyro and attitude rates agree sample for sample, so on periodic motion
        the true peak still stands out (1.000 against 0.986 on the test fixtures' sums of sines).
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
    _check_peak("gyro-rate", offset, peak, second, ambiguity=False)

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


#: A rival correlation peak this close to the best one makes an alignment refuse (smooth periodic motion gives
#: several near-equal lags; an assumption, not fitted to a recording).
AMBIGUOUS_PEAK_RATIO = 0.9
#: The weakest correlation peak an IMU clock alignment accepts. An assumption: on i-ASL the gyro-rate peaks are
#: 0.99 and the range-based specific-force ones 0.82–0.89, while another flight's IMU against a flight's truth
#: peaks at 0.27 and a motionless IMU has no peak to speak of.
MIN_PEAK_CORR = 0.6


def _check_peak(what: str, offset: float, peak: float, second: float, *, ambiguity: bool = True) -> None:
    """Refuse a correlation peak too weak (or, with ``ambiguity``, too ambiguous) to fix a clock offset, with the
    numbers."""
    if not peak >= MIN_PEAK_CORR:
        raise RegistrationError(f"the {what} correlation is too weak to fix the IMU clock: its best peak is {peak:.3f} "
                                f"(at {offset:+.3f} s), under {MIN_PEAK_CORR:g} — is this IMU log from this recording, "
                                "and did it move?")
    if ambiguity and second >= AMBIGUOUS_PEAK_RATIO * peak:
        raise RegistrationError(f"the {what} correlation is ambiguous: its peak {peak:.3f} at {offset:+.3f} s "
                                f"has a rival {second:.3f} more than 2 s away (≥ {AMBIGUOUS_PEAK_RATIO:g} × the peak); "
                                "the recording's motion does not pin the IMU clock down")


def _uniform(t: np.ndarray, x: np.ndarray, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    grid = np.arange(t[0], t[-1], step_s)
    return grid, np.column_stack([np.interp(grid, t, x[:, j]) for j in range(x.shape[1])]) if x.ndim == 2 \
        else np.interp(grid, t, x)


@np.errstate(over="ignore", invalid="ignore", divide="ignore")
def align_imu_to_ranges(imu: ImuLog, ranges: RangeLog, anchors: Anchors, *, smooth_s: float = 0.5,
                        max_lag_s: float | None = None, max_gap_s: float = 0.5) -> ImuAlignment:
    """Clock offset of an IMU against the tag's own UWB ranges — no motion capture used.

    The ranges give 3-D multilateration fixes (:func:`~uwbwb.geometry.multilaterate`, epochs
    without a converged fix left out); the fixes, on a uniform grid at the median range
    interval, are smoothed by a Gaussian of σ = ``smooth_s`` and differentiated twice; the
    specific-force magnitude ``|a + g ẑ|`` they imply is correlated with the IMU's ``|f|``
    smoothed by the same Gaussian (magnitudes do not depend on the mounting), over the lags on
    the 0.1 s, 20 ms and 2 ms grids of :func:`align_imu`. ``smooth_s`` is an assumption: range
    noise of ~0.1 m differentiated twice needs ~0.5 s of smoothing; the offset is only as good as
    the motion in the recording (check ``peak_corr`` against ``second_peak_corr``). Precision: a few
    tens of ms (synthetic 60 s flights with 3 cm range noise: −34…+62 ms; the i-ASL scenarios: 2 and
    36 ms from the motion-capture offset of :func:`align_imu`).

    Parameters
    ----------
    imu
        IMU samples on their own clock.
    ranges, anchors
        The tag's ranges (on the clock to align to) and the anchors.
    smooth_s
        σ of the Gaussian applied to both magnitudes, s.
    max_lag_s
        Only consider ``|offset| <= max_lag_s`` (default: any lag overlapping the two by half
        the shorter one).
    max_gap_s
        Fix gaps longer than this are not bridged in the correlation.

    Returns
    -------
    ImuAlignment
        ``offset_s`` (``t_ranges = t_imu + offset_s``) and ``acc_offset_s`` are the same number;
        no gyro-axis table (no attitude to compare with).

    Raises
    ------
    RegistrationError
        Too few fixes or IMU samples, no overlap, or an ambiguous correlation (a rival peak of
        at least :data:`AMBIGUOUS_PEAK_RATIO` × the best one more than 2 s away).
    """
    if smooth_s <= 0 or not np.isfinite(smooth_s):
        raise ValueError(f"smooth_s must be positive, got {smooth_s!r}")
    if len(imu) < 20:
        raise RegistrationError(f"only {len(imu)} IMU samples (need 20)")
    fix = multilaterate(ranges.range_m, anchors.pos_m, dim=3)
    ok = np.isfinite(fix.pos_m).all(axis=1) & (fix.status == Status.OK)
    if ok.sum() < 20:
        raise RegistrationError(f"only {int(ok.sum())} converged 3-D fixes from the ranges (need 20)")
    t_fix, p_fix = ranges.t_s[ok], fix.pos_m[ok]
    step = float(np.median(np.diff(t_fix)))
    t_u, p_u = _uniform(t_fix, p_fix, step)
    if t_u.size < 20:
        raise RegistrationError("the fixes span too short a time to differentiate")
    p_s = gaussian_filter1d(p_u, smooth_s / step, axis=0, mode="nearest")
    acc = np.gradient(np.gradient(p_s, t_u, axis=0), t_u, axis=0)
    f_uwb = np.linalg.norm(acc + [0.0, 0.0, GRAVITY_MPS2], axis=1)
    # grid points farther than max_gap_s from a fix are not used
    near = np.abs(t_u - t_fix[np.clip(np.searchsorted(t_fix, t_u), 0, t_fix.size - 1)]) <= max_gap_s
    t_u, f_uwb = t_u[near], f_uwb[near]
    d_imu = float(np.median(np.diff(imu.t_s)))
    t_i, f_i = _uniform(imu.t_s, np.linalg.norm(imu.acc_mps2, axis=1), d_imu)
    f_i = gaussian_filter1d(f_i, smooth_s / d_imu, mode="nearest")
    span = min(t_i[-1] - t_i[0], t_u[-1] - t_u[0])
    lo, hi = t_u[0] - t_i[-1] + 0.5 * span, t_u[-1] - t_i[0] - 0.5 * span
    if max_lag_s is not None:
        lo, hi = max(lo, -max_lag_s), min(hi, max_lag_s)
    if not lo <= hi:
        raise RegistrationError("IMU and range time spans do not overlap enough")
    offset, peak, second = _best_lag(t_i, f_i, t_u, f_uwb, lo, hi, 0.1, max_gap_s)
    if not np.isfinite(offset):
        raise RegistrationError("IMU and UWB-derived specific force never overlap enough to correlate")
    _check_peak("specific-force", offset, peak, second)
    mid = 0.5 * (t_u[0] + t_u[-1])
    halves = tuple(float(_best_lag(t_i, f_i, t_u[h], f_uwb[h], offset - 1.0, offset + 1.0, 0.1, max_gap_s)[0])
                   for h in (t_u < mid, t_u >= mid))
    method = (f"lag maximising the correlation of |f_imu| with the specific-force magnitude of the 3-D "
              f"multilateration fixes (both Gaussian-smoothed, σ {smooth_s:g} s); 0.1 s, 20 ms, 2 ms grids; "
              f"no motion capture used; each half of the recording searched again within ±1 s")
    return ImuAlignment(offset, peak, second, offset, peak, None, method, halves)
