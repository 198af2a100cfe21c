"""Start-up of the UWB/INS filters on one recording: the eq-4 screen, levelling and gyro bias at
rest, the initial state from the UWB fixes, the in-motion heading alignment (:func:`align_iasl`),
and each fusion filter run from the aligned state (:func:`run_fusion_filter`).

Used by notebook 05 (:mod:`uwbwb.experiments.uwb_ins`, whose result type is :class:`Comparison`)
and by the scoreboard's UWB/INS adapters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..metrics import rmse, score_epochs
from ..models.ins import NavState, dcm_from_euler, dcm_to_quat
from ..models.tdoa import TdoaModel, triangle_outliers
from ..validate import number
from ..types import EstimateStatus, Estimates, ImuLog, Recording, TdoaLog, Trajectory
from . import eskf
from .imu_calibration import RealCalibration
from .tdoa_ls import tdoa_least_squares

__all__ = ["FusionSettings", "screened_tdoa", "ls_estimates", "Comparison", "initial_state", "imu_after",
           "level_attitude", "AlignedStart", "align_iasl", "loose_filter",
           "TUNABLE", "run_fusion_filter", "handover_covariance"]


@dataclass(frozen=True)
class FusionSettings:
    """Filter settings shared by a comparison (the widget's knobs).

    Attributes
    ----------
    outlier_c_m
        ``C`` of eq. (4), m; None: no eq-4 test.
    gate_prob
        χ² gate probability of the tight filter per TDoA (and of the loose filter per fix where it is
        gated); None: no gate.
    q_scale, r_scale
        Multipliers on the process and measurement noise of both filters.
    feedback
        Closed loop (both filters) or open loop.
    loose_window
        Epochs of the backward difference giving the loose filter's UWB velocity.
    """

    outlier_c_m: float | None = 0.1
    gate_prob: float | None = 0.999
    q_scale: float = 1.0
    r_scale: float = 1.0
    feedback: bool = True
    loose_window: int = 5


def screened_tdoa(log: TdoaLog, anchor_pos_m: np.ndarray, c_m: float | None) -> tuple[TdoaLog, np.ndarray]:
    """The eq-4 test applied to a whole log: TDoAs that fail it removed, and the count per epoch.

    Epochs left with fewer than one TDoA become empty (reference −1).
    """
    if c_m is None:
        return log, np.zeros(len(log), int)
    bad = triangle_outliers(log.tdoa_m, log.ref, anchor_pos_m, c_m)
    d = np.where(bad, np.nan, log.tdoa_m)
    ref = log.ref.copy()
    empty = np.isfinite(d).sum(axis=1) < 2
    ref[empty] = -1
    d[empty] = np.nan
    return TdoaLog(log.t_s, d, ref, log.anchor_ids, log.tag_id), bad.sum(axis=1)


def ls_estimates(log: TdoaLog, model: TdoaModel, name: str = "UWB-only") -> Estimates:
    """TDoA least-squares fixes of ``log`` as :class:`~uwbwb.types.Estimates` (NaN and no estimate where LS failed)."""
    ls = tdoa_least_squares(log, model)
    st = np.where(ls.ok, EstimateStatus.UPDATED, EstimateStatus.NO_ESTIMATE).astype(np.int8)
    pos = np.where(ls.ok[:, None], ls.pos_m, np.nan)
    return Estimates(ls.t_s, pos, st, name, np.where(ls.ok[:, None, None], ls.cov_m2, np.nan))


@dataclass(frozen=True)
class Comparison:
    """The four methods on one run, scored on the same epochs.

    Attributes
    ----------
    label
        ``"synthetic static"``, ``"iasl-uwb-imu/scenario2"``, ...
    truth
        Tag truth at the UWB epochs (2-D or 3-D as scored).
    estimates
        Method name → :class:`~uwbwb.types.Estimates` on the UWB epochs.
    runs
        Filter name → :class:`~uwbwb.filters.eskf.FusionRun` (attitude, biases, NIS).
    masks
        Named epoch masks (e.g. ``"outage"``, ``"nlos"``, ``"scored"``).
    rejected
        Counts: ``eq4`` TDoAs removed by the eq-4 test, ``gated`` by the tight filter's χ² gate,
        ``injected`` outliers (synthetic), ``tdoas`` measured.
    dim
        Scored dimensions (2: horizontal).
    """

    label: str
    truth: Trajectory
    estimates: dict
    runs: dict
    masks: dict = field(default_factory=dict)
    rejected: dict = field(default_factory=dict)
    dim: int = 2
    meta: dict = field(default_factory=dict)

    def errors(self, name: str) -> np.ndarray:
        """Horizontal error per epoch of ``name`` (NaN where it has no estimate), m."""
        est = self.estimates[name]
        return np.linalg.norm(est.pos_m[:, :2] - self.truth.pos_m[:, :2], axis=1)

    def table(self, mask: str | None = None) -> pd.DataFrame:
        """RMSE, max and coverage per method on its own epochs (on ``masks[mask]`` if given), metres:
        :func:`uwbwb.metrics.score_epochs`, each method on its own (the ranking across methods on
        common epochs is the scoreboard's)."""
        sel = self.masks.get("scored", np.ones(len(self.truth), bool))
        if mask is not None:
            sel = sel & self.masks[mask]
        scores = score_epochs({name: self.errors(name)[sel] for name in self.estimates}, compare=False)
        t = scores.table(own={"RMSE (m)": rmse, "max (m)": np.max})
        t["epochs"] = t["n_epochs"]
        return t[["RMSE (m)", "max (m)", "coverage", "epochs"]].rename_axis(None)


def initial_state(fixes: Estimates, *, height_m: float | None, lever_m, yaw_rad: float, roll_rad: float = 0.0,
                  pitch_rad: float = 0.0, t0_s: float | None = None, rest_s: float = 0.5) -> tuple[NavState, int]:
    """Initial IMU state while the platform rests: position = median of the UWB fixes over
    ``rest_s`` from ``t0_s`` (default: the first fix; a single fix may be an outlier), minus
    the lever arm; zero velocity; attitude from the given angles. Returns the state and the
    epoch index it holds at (the last fix of that interval)."""
    ok = fixes.has_estimate
    t0 = fixes.t_s[ok][0] if t0_s is None else t0_s
    sel = np.flatnonzero(ok & (fixes.t_s >= t0) & (fixes.t_s <= t0 + rest_s))
    if sel.size == 0:
        raise ValueError(f"initial_state: no UWB fix within {rest_s} s of t = {t0:.2f} s")
    C = dcm_from_euler(roll_rad, pitch_rad, yaw_rad)
    p = np.zeros(3)
    p[:fixes.dim] = np.median(fixes.pos_m[sel], axis=0)
    if fixes.dim == 2:
        p[2] = height_m
    return NavState(p - C @ np.asarray(lever_m, float), np.zeros(3), dcm_to_quat(C)), int(sel[-1])


def imu_after(imu: ImuLog, t0: float) -> ImuLog:
    """The IMU samples at or after ``t0`` (s)."""
    keep = imu.t_s >= t0
    return ImuLog(imu.t_s[keep], imu.acc_mps2[keep], imu.gyro_radps[keep])


def level_attitude(imu: ImuLog, t0: float, still_s: float, *, max_rate_radps: float = 0.05,
                   max_force_spread_mps2: float = 0.5) -> tuple[float, float, np.ndarray, bool]:
    """Roll, pitch (rad) from the mean specific force and the gyro bias (mean rate) over
    ``[t0, t0 + still_s]``, if the platform rests there.

    Rest means every gyro sample below ``max_rate_radps`` and a specific-force magnitude
    spread (max − min) below ``max_force_spread_mps2``. Returns ``(roll, pitch, gyro_bias,
    at_rest)``; when not at rest, ``(0, 0, zeros, False)``: levelling would read motion as
    tilt and the mean rate as bias, so neither is estimated.
    """
    sel = (imu.t_s >= t0) & (imu.t_s <= t0 + still_s)
    if sel.sum() < 5:
        raise ValueError(f"level_attitude: only {int(sel.sum())} IMU samples in the first {still_s} s")
    fn = np.linalg.norm(imu.acc_mps2[sel], axis=1)
    rest = bool(np.linalg.norm(imu.gyro_radps[sel], axis=1).max() < max_rate_radps
                and fn.max() - fn.min() < max_force_spread_mps2)
    if not rest:
        return 0.0, 0.0, np.zeros(3), False
    f = imu.acc_mps2[sel].mean(axis=0)
    roll = math.atan2(f[1], f[2])
    pitch = math.atan2(-f[0], math.hypot(f[1], f[2]))
    return roll, pitch, imu.gyro_radps[sel].mean(axis=0), True


@dataclass(frozen=True)
class AlignedStart:
    """The common start of every UWB/INS filter on one recording (:func:`align_iasl`).

    Attributes
    ----------
    log, tdoa
        The ranges (cut to the run's length) and their TDoAs against the reference anchor.
    model
        The 3-D TDoA model with the calibrated range noise.
    fixes
        UWB-only TDoA least-squares fixes on the screened TDoAs.
    k0, x0
        Epoch index where every filter starts (the end of the alignment window) and the state there.
    imu
        IMU samples in the body frame from the epoch ``k0`` on.
    gyro_bias0_radps
        Gyro bias from the rest interval (zeros when not at rest).
    alignment
        The alignment filter's run.
    """

    log: object
    tdoa: TdoaLog
    model: TdoaModel
    fixes: Estimates
    k0: int
    x0: NavState
    imu: ImuLog
    gyro_bias0_radps: np.ndarray
    alignment: object

    @property
    def after(self) -> np.ndarray:
        """Epochs from the start ``k0`` on (the scored ones), boolean ``(T,)``."""
        return np.arange(len(self.log)) >= self.k0


def align_iasl(rec: Recording, cal: RealCalibration, settings: FusionSettings = FusionSettings(), *,
               ref_anchor: int = 0, still_s: float = 2.0, align_s: float = 20.0,
               duration_s: float | None = None) -> AlignedStart:
    """The start of every UWB/INS filter on one ``iasl-uwb-imu`` recording, from ``cal`` (fitted on
    another recording) and this recording's measurements only (no truth, no magnetometer — this
    log has none): the state and epoch every filter starts from, and the screened TDoAs and
    3-D TDoA least-squares fixes they share.

    1. *Rest* (the first ``still_s`` s): roll and pitch by levelling, gyro bias by averaging
       (:func:`level_attitude`; if the platform is not at rest, level and zero bias with a 10°
       tilt uncertainty instead).
    2. *In-motion heading alignment* (the next ``align_s`` s): the tight range filter runs from
       the first UWB fix with yaw 0 and a 60° yaw uncertainty; heading is observable once the
       drone accelerates, and the filter's state at the end of the window (position, velocity,
       attitude) starts **every** filter (:func:`run_fusion_filter`) — the tight filters with
       the alignment's variances of those states where larger than their own
       (:func:`handover_covariance`). Scoring starts there, for every method.

    The tag's lever arm from the IMU is unknown and taken as zero (an assumption); so are the
    accelerometer biases (zero at start). ``duration_s`` cuts the ranges that long after the
    alignment (None: the whole recording)."""
    if rec.imu is None:
        raise ValueError(f"{rec.label}: no IMU log")
    for name, value in (("still_s", still_s), ("align_s", align_s), ("duration_s", duration_s)):
        if value is not None or name != "duration_s":          # duration_s None: the whole recording
            number(name, value, minimum=0.0, strict_minimum=True)
    log = rec.ranges["tag"]
    t_start = max(log.t_s[0], rec.imu.t_s[0])
    t_align = t_start + still_s + align_s
    if not t_align < log.t_s[-1]:
        raise ValueError(f"{rec.label}: rest ({still_s:g} s) and heading alignment ({align_s:g} s) end at "
                         f"{t_align:.2f} s, but the ranges end at {log.t_s[-1]:.2f} s: nothing is left to run the "
                         "filters on (shorten still_s or align_s)")
    if duration_s is not None:
        log = log.between(log.t_s[0], t_align + duration_s)
    imu = cal.convention.to_body(rec.imu)
    anchors = rec.anchors.pos_m
    tdoa = TdoaLog.from_ranges(log, ref_anchor)
    m3 = TdoaModel(anchors, cal.range_sigma_m, dim=3)
    fixes = ls_estimates(screened_tdoa(tdoa, anchors, settings.outlier_c_m)[0], m3)
    roll, pitch, bg0, at_rest = level_attitude(imu, t_start, still_s)
    tilt_sigma = (2.0 if at_rest else 10.0) * math.pi / 180
    ranges_update = eskf.RangeUpdate(anchors, cal.range_sigma_m, cal.range_bias_m)
    x_a, k_a = initial_state(fixes, height_m=None, lever_m=np.zeros(3), yaw_rad=0.0, roll_rad=roll,
                             pitch_rad=pitch, t0_s=t_start, rest_s=still_s)
    aligner = eskf.TightEskf(cal.imu_model, ranges_update, init_sigma=(0.2, 0.3, tilt_sigma, math.pi / 3),
                             name="alignment", **_common(settings))
    win = np.flatnonzero((log.t_s >= log.t_s[k_a]) & (log.t_s <= t_align))
    al = aligner.run(imu_after(imu, log.t_s[k_a]), log.select(win), x_a, gyro_bias0=bg0)
    k0 = int(win[-1])
    x0 = NavState(al.pos_m[-1], al.vel_mps[-1], al.quat[-1])
    return AlignedStart(log, tdoa, m3, fixes, k0, x0, imu_after(imu, log.t_s[k0]), bg0, al)


def _common(settings: FusionSettings) -> dict:
    return dict(gate_prob=settings.gate_prob, q_scale=settings.q_scale, r_scale=settings.r_scale,
                feedback=settings.feedback)


def loose_filter(cal: RealCalibration, settings: FusionSettings = FusionSettings(), *,
                 loose_scales: tuple[float, float] = (1.0, 1.0)) -> eskf.LooseFilter:
    """The real-data loose filter: position σ twice the median calibrated range σ, velocity σ
    0.5 m/s, velocity random walk 0.3 m/s/√s (the unit of its grid), times ``settings``' scales
    and ``loose_scales`` (its own ``(q, r)`` multipliers, e.g. tuned on the calibration recording)."""
    return eskf.LooseFilter(dim=3, q_scale=settings.q_scale * loose_scales[0],
                            r_scale=settings.r_scale * loose_scales[1], feedback=settings.feedback,
                            vel_window=settings.loose_window, sigma_r_pos_m=2 * float(np.median(cal.range_sigma_m)),
                            sigma_r_vel_mps=0.5, q_vel_mps_rts=0.3)


#: The filters of :func:`run_fusion_filter` that have process/measurement-noise knobs.
TUNABLE = ("loose", "tight", "tight (ranges)")


def handover_covariance(f: eskf.TightEskf, P_align: np.ndarray) -> np.ndarray:
    """Initial covariance of a tight filter started from an alignment's end state: the filter's own
    :meth:`~uwbwb.filters.eskf.TightEskf.initial_covariance`, with the position, velocity and
    attitude variances raised to the alignment's final ones where those are larger.

    The handed-over state is known only as well as the alignment knows it: an alignment that has
    just released its gate ends with a velocity σ of ~0.7 m/s, and a filter that starts from that
    state believing its default 0.1 m/s gates good ranges and drifts (1.2–1.6 m in the first 3 s on
    2 of 8 synthetic flights at 5 Hz before this rule). The bias estimates are not handed over (only
    the gyro bias from rest), so their variances stay the model's.
    """
    d = np.diag(f.initial_covariance()).copy()
    d[:9] = np.maximum(d[:9], np.diag(P_align)[:9])
    return np.diag(d)


def run_fusion_filter(name: str, a: AlignedStart, rec: Recording, cal: RealCalibration,
                      settings: FusionSettings = FusionSettings(), *, scales: tuple[float, float] = (1.0, 1.0)):
    """One filter from the aligned start ``a`` (:func:`align_iasl`), on the epochs from ``a.k0`` on; returns
    ``(run, Estimates)``.

    ``name`` is one of :data:`TUNABLE`, or ``"INS-only"`` (the mechanization alone, nothing to scale).
    ``scales = (q, r)`` multiply that filter's process and measurement noise only (on top of
    ``settings``' common scales): the tight filters' ``q_scale`` and ``r_scale``, the loose filter's
    Q and R (:func:`loose_filter`). ``(1, 1)`` is the untuned filter. Only the tight filters inherit
    the alignment's uncertainty (:func:`handover_covariance`); the loose filter starts from its own
    (velocity σ 0.5 m/s).
    """
    q, r = scales
    after = a.after
    if name in ("tight", "tight (ranges)"):
        common = {**_common(settings), "q_scale": settings.q_scale * q, "r_scale": settings.r_scale * r}
        if name == "tight":
            f = eskf.TightEskf(cal.imu_model, eskf.TdoaUpdate(a.model, settings.outlier_c_m), **common)
            meas = a.tdoa.select(after)
        else:
            f = eskf.TightEskf(cal.imu_model, eskf.RangeUpdate(rec.anchors.pos_m, cal.range_sigma_m, cal.range_bias_m),
                               name=name, **common)
            meas = a.log.select(after)
        run = f.run(a.imu, meas, a.x0, gyro_bias0=a.gyro_bias0_radps, P0=handover_covariance(f, a.alignment.P[-1]))
        return run, run.to_estimates(dim=3, name=name)
    if name == "loose":
        run = loose_filter(cal, settings, loose_scales=scales).run(a.imu, a.fixes.select(after), a.x0)
        return run, run.to_estimates(dim=3, name=name)
    if name == "INS-only":                               # no aiding and no knob: the scales are ignored
        run = eskf.dead_reckon(a.imu, a.x0, a.log.select(after).t_s, gyro_bias=a.gyro_bias0_radps)
        return run, run.to_estimates(dim=3, name=name)
    raise ValueError(f"name must be one of {TUNABLE + ('INS-only',)}, got {name!r}")
