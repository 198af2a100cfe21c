"""What notebook 05 runs: UWB-only, INS-only, the paper's loose filter and the tight filter,
on the synthetic robot re-creation and on the ``iasl-uwb-imu`` drone recordings.

Every method of a comparison gets the same information: the same IMU samples, the same
UWB epochs (TDoA from the same ranges, the same eq-4 test), the same initial state, the same
magnetometer headings where there are any, the same known tag height for the ground robot.
They are scored on the same epochs; coverage is reported beside accuracy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from ...filters import eskf
from ...filters.ekf import TdoaEkf
from ...models.motion import RandomForce
from ...filters.tdoa_ls import tdoa_least_squares
from ...models.imu import GRADES, ImuConvention, ImuErrorModel
from ...models.ins import GRAVITY_MPS2, NavState, dcm_from_euler, dcm_to_quat, quat_to_dcm
from ...calibration import MAD_TO_SIGMA, range_sigma_from_truth
from ...models.tdoa import TdoaModel, triangle_outliers
from ...sim import robot
from ...types import EstimateStatus, Estimates, ImuLog, Recording, TdoaLog, Trajectory

__all__ = ["PAPER", "METHODS", "FusionSettings", "Comparison", "simulate_case", "compare_synthetic",
           "error_ranges", "RealCalibration", "calibrate_iasl", "compare_iasl", "screened_tdoa", "level_attitude"]

#: Numbers quoted from paper 004 (kind "input"): error ranges (m) and the summary bounds.
PAPER = {"static_E_m": (-0.04, 0.07), "static_N_m": (-0.07, 0.09), "dynamic_m": (-0.21, 0.16),
         "static_bound_m": 0.1, "dynamic_bound_m": 0.25, "uwb_rate_hz": 50.0, "speed_mps": 0.3}
#: Method names, in display order (one colour each, see :mod:`uwbwb.plotting`).
METHODS = ("UWB-only", "INS-only", "loose", "tight")


@dataclass(frozen=True)
class FusionSettings:
    """Filter settings shared by a comparison (the widget's knobs).

    Attributes
    ----------
    outlier_c_m
        ``C`` of eq. (4), m; None: no eq-4 test.
    gate_prob
        χ²(1) gate probability of the tight filter per TDoA; None: no gate.
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


def _ls_estimates(log: TdoaLog, model: TdoaModel, name: str = "UWB-only") -> Estimates:
    ls = tdoa_least_squares(log, model)
    st = np.where(ls.ok, EstimateStatus.UPDATED, EstimateStatus.NO_ESTIMATE).astype(np.int8)
    pos = np.where(ls.ok[:, None], ls.pos_m, np.nan)
    return Estimates(ls.t_s, pos, st, name, np.where(ls.ok[:, None, None], ls.cov_m2, np.nan))


# ====================================================================== synthetic
#: Where the degradations sit in the dynamic run (s): the outage starts on the second leg, the
#: NLOS-biased station episode covers the third turn and the fourth leg.
OUTAGE_START_S, NLOS_START_S, NLOS_S = 8.0, 18.0, 6.0


def simulate_case(scenario: str, *, seed: int, fast: bool = False, grade: str = "consumer",
                  outlier_rate: float = 0.02, outage_s: float = 0.0, nlos_bias_m: float = 0.0,
                  static_s: float = 60.0, legs: int | None = None) -> robot.RobotRun:
    """One synthetic run: ``"static"`` at (3.5, 2) m or ``"dynamic"`` along the paper's broken line.

    ``outage_s`` > 0 silences every station but BS1 and BS2 from :data:`OUTAGE_START_S` on (one
    TDoA per epoch: no position fix); ``nlos_bias_m`` > 0 adds that excess to station BS3 for
    :data:`NLOS_S` seconds from :data:`NLOS_START_S`. ``fast`` shortens the static run to 20 s;
    ``legs`` drives only the first legs of the broken line (the interactive panel's short runs).
    """
    if scenario not in ("static", "dynamic"):
        raise ValueError(f"scenario must be 'static' or 'dynamic', got {scenario!r}")
    motion = robot.hold(duration_s=min(static_s, 20.0) if fast else static_s) if scenario == "static" \
        else robot.broken_line(robot.PAPER_WAYPOINTS_M[: (legs or 5) + 1])
    if outage_s > 0 and OUTAGE_START_S + outage_s > motion.duration_s:
        raise ValueError(f"outage_s = {outage_s:g} s cannot hold: the outage starts at {OUTAGE_START_S:g} s and "
                         f"this {scenario} run lasts {motion.duration_s:.1f} s")
    cfg = robot.RobotConfig(imu=GRADES[grade], outlier_rate=outlier_rate,
                            outage_start_s=OUTAGE_START_S if outage_s > 0 else None, outage_s=outage_s,
                            nlos_station=2 if nlos_bias_m > 0 else None, nlos_bias_m=nlos_bias_m,
                            nlos_start_s=NLOS_START_S, nlos_s=NLOS_S)
    return robot.simulate(motion, cfg, rng=np.random.default_rng(seed))


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
        """RMSE, max and coverage per method (on ``masks[mask]`` if given), metres."""
        sel = self.masks.get("scored", np.ones(len(self.truth), bool))
        if mask is not None:
            sel = sel & self.masks[mask]
        rows = {}
        for name, est in self.estimates.items():
            e = self.errors(name)[sel]
            ok = np.isfinite(e)
            rows[name] = {"RMSE (m)": float(np.sqrt(np.mean(e[ok] ** 2))) if ok.any() else np.nan,
                          "max (m)": float(e[ok].max()) if ok.any() else np.nan,
                          "coverage": float(ok.mean()) if e.size else np.nan, "epochs": int(e.size)}
        return pd.DataFrame(rows).T


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


def _after(imu: ImuLog, t0: float) -> ImuLog:
    keep = imu.t_s >= t0
    return ImuLog(imu.t_s[keep], imu.acc_mps2[keep], imu.gyro_radps[keep])


def compare_synthetic(run: robot.RobotRun, settings: FusionSettings = FusionSettings(), *,
                      label: str = "synthetic", methods=METHODS) -> Comparison:
    """UWB-only (TDoA LS at the known height), INS-only, loose and tight on one simulated run.

    ``methods`` picks which of :data:`METHODS` to run (UWB-only always runs: the others start
    from its first fix). Filters start at the first UWB fix with zero velocity, level attitude (the robot stands on a
    flat floor) and the magnetometer heading of that epoch; IMU biases start at zero.
    """
    cfg = run.config
    anchors = np.asarray(cfg.stations_m, float)
    screened, n_eq4 = screened_tdoa(run.tdoa, anchors, settings.outlier_c_m)
    m2 = TdoaModel(anchors, cfg.sigma_toa_m, dim=2, z_m=cfg.tag_height_m)
    fixes = _ls_estimates(screened, m2)
    yaw0 = float(run.heading.yaw_rad[int(np.flatnonzero(fixes.has_estimate)[0])])
    x0, k0 = initial_state(fixes, height_m=cfg.tag_height_m, lever_m=cfg.lever_arm_m, yaw_rad=yaw0)
    imu = _after(run.imu, run.truth.t_s[k0])
    tight = eskf.TightEskf(cfg.imu, eskf.TdoaUpdate(cfg.tdoa_model(), settings.outlier_c_m),
                           lever_arm_m=cfg.lever_arm_m, gate_prob=settings.gate_prob, q_scale=settings.q_scale,
                           r_scale=settings.r_scale, feedback=settings.feedback, height_m=cfg.tag_height_m)
    loose = eskf.LooseFilter(height_m=cfg.tag_height_m, lever_arm_m=cfg.lever_arm_m, q_scale=settings.q_scale,
                             r_scale=settings.r_scale, feedback=settings.feedback, vel_window=settings.loose_window,
                             sigma_r_pos_m=2 * cfg.sigma_toa_m)
    unknown = set(methods) - set(METHODS)
    if unknown:
        raise ValueError(f"compare_synthetic: unknown methods {sorted(unknown)}; known: {METHODS}")
    todo = {"tight": lambda: tight.run(imu, run.tdoa, x0, heading=run.heading),
            "loose": lambda: loose.run(imu, fixes, x0, heading=run.heading),
            "INS-only": lambda: eskf.dead_reckon(imu, x0, run.truth.t_s, lever_arm_m=cfg.lever_arm_m)}
    runs = {k: f() for k, f in todo.items() if k in methods}
    est = {"UWB-only": fixes}
    est.update({k: v.to_estimates(dim=2, name=k) for k, v in runs.items()})
    est = {m: est[m] for m in METHODS if m in est}
    ref = run.tdoa.ref
    bad = run.outlier | run.outlier[np.arange(len(ref)), np.clip(ref, 0, None)][:, None]
    bad &= np.isfinite(run.tdoa.tdoa_m)
    bad[np.arange(len(ref)), ref] = False
    scored = np.arange(len(run.truth)) >= k0
    masks = {"scored": scored, "outage": run.outage, "nlos": run.nlos}
    gated = int(runs["tight"].n_gated.sum()) if "tight" in runs else 0
    rejected = {"eq4": int(n_eq4.sum()), "gated": gated, "injected": int(bad.sum()),
                "tdoas": int(run.tdoa.n_tdoa.sum())}
    truth = Trajectory(run.truth.t_s, run.truth.pos_m[:, :2], run.truth.vel_mps[:, :2], run.truth.rot, "truth")
    return Comparison(label, truth, est, runs, masks, rejected, 2, {"yaw_true_rad": run.yaw_true_rad})


def error_ranges(comp: Comparison, name: str = "tight", *, central: float = 0.99) -> dict:
    """East and north error extremes (and the central ``central`` interval) of ``name``, m.

    The paper's "error range (a, b)" is read as the min and max of the signed error over the
    test; its "average residual rate" and "confidence" are not defined and are not reproduced.
    """
    est = comp.estimates[name]
    sel = comp.masks.get("scored", np.ones(len(est), bool)) & est.has_estimate
    e = est.pos_m[sel, :2] - comp.truth.pos_m[sel, :2]
    a = (1 - central) / 2
    out = {}
    for k, ax in enumerate("EN"):
        out[f"{ax}_min"], out[f"{ax}_max"] = float(e[:, k].min()), float(e[:, k].max())
        out[f"{ax}_lo"], out[f"{ax}_hi"] = (float(x) for x in np.quantile(e[:, k], [a, 1 - a]))
    # the dynamic test's single range: the signed error along the direction of travel's normal is
    # not defined in the paper; we take the signed error component of larger magnitude per epoch
    big = np.where(np.abs(e[:, 0]) >= np.abs(e[:, 1]), e[:, 0], e[:, 1])
    out["signed_min"], out["signed_max"] = float(big.min()), float(big.max())
    out["max_abs"] = float(np.linalg.norm(e, axis=1).max())
    return out


# ====================================================================== real data (iasl-uwb-imu)
@dataclass(frozen=True)
class RealCalibration:
    """What the real-data filters take from the calibration scenario (never from the scored one).

    Attributes
    ----------
    source
        Label of the calibration recording.
    convention
        IMU → body (units, the z-down sensor flipped to z-up, accelerometer scale).
    range_sigma_m
        Robust range-noise SD per anchor, m.
    range_bias_m
        Common range bias, m (from the calibration scenario's registration).
    imu_model
        Noise densities from the calibration residuals (biases: consumer-grade assumption).
    notes
        How each value was obtained.
    """

    source: str
    convention: ImuConvention
    range_sigma_m: np.ndarray
    range_bias_m: float
    imu_model: ImuErrorModel
    notes: dict = field(default_factory=dict)


def _truth_specific_force(truth: Trajectory, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|a + g| and |ω| of the truth track at ``t_s`` (differentiated, ~10 Hz mocap)."""
    vel = np.gradient(truth.pos_m, truth.t_s, axis=0)
    acc = np.gradient(vel, truth.t_s, axis=0)
    f = np.linalg.norm(acc + [0, 0, GRAVITY_MPS2], axis=1)
    R = truth.rot
    rel = np.einsum("tji,tjk->tik", R[:-1], R[1:])
    ang = np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1)) / np.diff(truth.t_s)
    tm = 0.5 * (truth.t_s[1:] + truth.t_s[:-1])
    return np.interp(t_s, truth.t_s, f), np.interp(t_s, tm, ang)


def calibrate_iasl(rec: Recording, *, still_s: float = 2.0) -> RealCalibration:
    """Estimate on one recording (with its motion-capture truth) what the filters need elsewhere.

    * sensor axes: the accelerometer reads −g on its z axis at rest, so the UM7 frame is
      z-down; the body frame is that frame turned 180° about x (x forward, y left, z up).
      Checked here, not assumed: the sign of the mean z specific force.
    * accelerometer scale: g over the mean |f| while the platform rests at the start (the log
      reads ≈ 10.3 m/s² at rest: the unit is not exactly m/s²); the least-squares fit of
      |f_truth| on |f_imu| over the flight is reported beside it as a cross-check.
    * noise densities: the spread of the residuals |f| and |ω| against truth, times √(Δt).
    * range noise and bias: robust σ per anchor against truth; the registration's common bias.
    """
    truth, imu = rec.truth["tag"], rec.imu
    if imu is None:
        raise ValueError(f"{rec.label}: no IMU log")
    fz = float(np.median(imu.acc_mps2[:, 2]))
    R = np.diag([1.0, -1.0, -1.0]) if fz < 0 else np.eye(3)
    inside = (imu.t_s > truth.t_s[0] + 0.5) & (imu.t_s < truth.t_s[-1] - 0.5)
    f_t, w_t = _truth_specific_force(truth, imu.t_s[inside])
    f_i = np.linalg.norm(imu.acc_mps2[inside], axis=1)
    flight_scale = float(f_t @ f_i / (f_i @ f_i))
    rest = imu.t_s <= imu.t_s[0] + still_s
    scale = GRAVITY_MPS2 / float(np.linalg.norm(imu.acc_mps2[rest].mean(axis=0)))
    w_i = np.linalg.norm(imu.gyro_radps[inside], axis=1)
    dt = float(np.median(np.diff(imu.t_s)))
    rf, rw = scale * f_i - f_t, w_i - w_t
    mad = lambda x: MAD_TO_SIGMA * float(np.median(np.abs(x - np.median(x))))  # noqa: E731
    acc_nd, gyro_nd = mad(rf) * math.sqrt(dt), mad(rw) * math.sqrt(dt)
    log = rec.ranges["tag"]
    true_r = np.linalg.norm(truth.interp(log.t_s)[:, None, :] - rec.anchors.pos_m, axis=-1)
    reg = rec.meta.get("registration")
    bias = float(getattr(reg, "range_bias_m", 0.0) or 0.0)
    sigma = range_sigma_from_truth(log.range_m - bias, true_r)
    model = replace(GRADES["consumer"], acc_noise_density=acc_nd, gyro_noise_density=gyro_nd,
                    mag_heading_sigma_rad=0.0)
    conv = ImuConvention(R_body_sensor=R, acc_scale=scale)
    notes = {"z specific force at rest (m/s²)": fz, "accelerometer scale (rest)": scale,
             "accelerometer scale (flight fit, cross-check)": flight_scale,
             "acc noise density (m/s²/√Hz)": acc_nd, "gyro noise density (rad/s/√Hz)": gyro_nd,
             "IMU rate (Hz)": 1 / dt, "range bias (m)": bias}
    return RealCalibration(rec.label, conv, sigma, bias, model, notes)


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


#: Random-force spectral density of the IMU-free EKF on the drone recordings, m²/s³: an
#: **assumption** (about 1 m/s² of unmodelled acceleration per second), not tuned on any scenario.
IASL_EKF_PSD_M2PS3 = 1.0


def compare_iasl(rec: Recording, cal: RealCalibration, settings: FusionSettings = FusionSettings(), *,
                 ref_anchor: int = 0, still_s: float = 2.0, align_s: float = 20.0,
                 duration_s: float | None = None, ekf_psd_m2ps3: float = IASL_EKF_PSD_M2PS3) -> Comparison:
    """UWB-only (3-D TDoA LS), the gated IMU-free TDoA EKF of notebook 03 (random force,
    ``ekf_psd_m2ps3``, the same χ² probability as the tight filter's gate), INS-only, loose
    (6 states), tight on TDoA and tight on ranges, on one ``iasl-uwb-imu`` recording, using only
    ``cal`` (from another recording) and this recording's measurements; its truth only scores.

    Start-up, common to every filter (no truth, no magnetometer — this log has none):

    1. *Rest* (the first ``still_s`` s): roll and pitch by levelling, gyro bias by averaging
       (:func:`level_attitude`; if the platform is not at rest, level and zero bias with a 10°
       tilt uncertainty instead).
    2. *In-motion heading alignment* (the next ``align_s`` s): the tight range filter runs from
       the first UWB fix with yaw 0 and a 60° yaw uncertainty; heading is observable once the
       drone accelerates, and the filter's state at the end of the window (position, velocity,
       attitude) starts **every** filter. Scoring starts there, for every method.

    The tag's lever arm from the IMU is unknown and taken as zero (an assumption); so are the
    accelerometer biases (zero at start).
    """
    if rec.imu is None:
        raise ValueError(f"{rec.label}: no IMU log")
    log = rec.ranges["tag"]
    t_start = max(log.t_s[0], rec.imu.t_s[0])
    t_align = t_start + still_s + align_s
    if duration_s is not None:
        log = log.between(log.t_s[0], t_align + duration_s)
    imu = cal.convention.to_body(rec.imu)
    anchors = rec.anchors.pos_m
    tdoa = TdoaLog.from_ranges(log, ref_anchor)
    screened, n_eq4 = screened_tdoa(tdoa, anchors, settings.outlier_c_m)
    m3 = TdoaModel(anchors, cal.range_sigma_m, dim=3)
    fixes = _ls_estimates(screened, m3)
    roll, pitch, bg0, at_rest = level_attitude(imu, t_start, still_s)
    tilt_sigma = (2.0 if at_rest else 10.0) * math.pi / 180
    common = dict(gate_prob=settings.gate_prob, q_scale=settings.q_scale, r_scale=settings.r_scale,
                  feedback=settings.feedback)
    ranges_update = eskf.RangeUpdate(anchors, cal.range_sigma_m, cal.range_bias_m)
    # 2. alignment
    x_a, k_a = initial_state(fixes, height_m=None, lever_m=np.zeros(3), yaw_rad=0.0, roll_rad=roll,
                             pitch_rad=pitch, t0_s=t_start, rest_s=still_s)
    aligner = eskf.TightEskf(cal.imu_model, ranges_update, init_sigma=(0.2, 0.3, tilt_sigma, math.pi / 3),
                             name="alignment", **common)
    win = np.flatnonzero((log.t_s >= log.t_s[k_a]) & (log.t_s <= t_align))
    al = aligner.run(_after(imu, log.t_s[k_a]), log.select(win), x_a, gyro_bias0=bg0)
    k0 = int(win[-1])
    x0 = NavState(al.pos_m[-1], al.vel_mps[-1], al.quat[-1])
    imu_run = _after(imu, log.t_s[k0])
    # 3. the comparison, all from x0 at epoch k0
    tight = eskf.TightEskf(cal.imu_model, eskf.TdoaUpdate(m3, settings.outlier_c_m), **common)
    tight_r = eskf.TightEskf(cal.imu_model, ranges_update, name="tight (ranges)", **common)
    loose = eskf.LooseFilter(dim=3, q_scale=settings.q_scale, r_scale=settings.r_scale, feedback=settings.feedback,
                             vel_window=settings.loose_window, sigma_r_pos_m=2 * float(np.median(cal.range_sigma_m)),
                             sigma_r_vel_mps=0.5, q_vel_mps_rts=0.3)
    after = np.arange(len(log)) >= k0
    sub = log.select(after)
    ekf = TdoaEkf(RandomForce(ekf_psd_m2ps3, dim=3), m3, gate_prob=settings.gate_prob)
    ekf_run = ekf.run(screened.select(after), x0=ekf.init(x0.pos_m, x0.vel_mps))
    runs = {"tight": tight.run(imu_run, tdoa.select(after), x0, gyro_bias0=bg0),
            "tight (ranges)": tight_r.run(imu_run, sub, x0, gyro_bias0=bg0),
            "loose": loose.run(imu_run, fixes.select(after), x0),
            "INS-only": eskf.dead_reckon(imu_run, x0, sub.t_s, gyro_bias=bg0)}
    est = {"UWB-only": fixes.select(after), "EKF + gate": replace(ekf_run.to_estimates(), name="EKF + gate")}
    est.update({k: v.to_estimates(dim=3, name=k) for k, v in runs.items()})
    runs["EKF + gate"] = ekf_run
    pos = rec.truth["tag"].interp(sub.t_s)
    have = np.all(np.isfinite(pos), axis=1)
    pos[~have] = 0.0
    truth = Trajectory(sub.t_s, pos, name="truth")
    rejected = {"eq4": int(n_eq4[after].sum()), "gated": int(runs["tight"].n_gated.sum()),
                "tdoas": int(tdoa.n_tdoa[after].sum())}
    meta = {"at_rest": at_rest, "roll0_deg": math.degrees(roll), "pitch0_deg": math.degrees(pitch),
            "yaw_after_alignment_deg": math.degrees(float(al.euler_rad[-1, 2])), "gyro_bias0_radps": bg0,
            "start_s": float(log.t_s[k0]), "alignment": al}
    return Comparison(rec.label, truth, est, runs, {"scored": have}, rejected, 2, meta)
