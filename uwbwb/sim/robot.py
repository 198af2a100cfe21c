"""Mobile robot with a MEMS IMU and a TDoA UWB tag in a four-station room: paper 004 re-created.

The paper states: a mobile robot, four synchronised UWB base stations, one reference
station, a 50 Hz tag, an INS module with gyro, accelerometer and magnetometer; a static
test at (3.5, 2) m and a dynamic test at 0.3 m/s along the broken line
(2, 1) → (3, 1) → (3, 2) → (4, 2) → (4, 3) → (5, 3) with four yaw turns. Everything else
here is an **assumption**, named as a parameter of :class:`RobotConfig`: the room
(7 × 5 m, stations in its corners at 2.2–2.4 m), the IMU rate (100 Hz) and grade, the
TDoA noise (independent arrival-time noise of σ = 3 cm per station, so TDoAs that share
the reference are correlated), multipath outliers (positive excess, more likely near a
station), dropouts, the magnetometer heading noise, the tag 15 cm above the IMU, and
how the robot moves between the waypoints: it drives each leg with smooth speed ramps
(``ramp_s``), stops, turns on the spot in ``turn_s``, and drives on.

Motion is closed form (:class:`RobotMotion`), so the ideal IMU (specific force
``f_b = Cᵀ(a − g_n)``, rate ``ω_b = [0, 0, ψ̇]``) is exact; the IMU errors come from the
same :class:`~uwbwb.models.imu.ImuErrorModel` the tight filter uses for its process
noise, the TDoAs from the same :class:`~uwbwb.models.tdoa.TdoaModel` its updates use.

Degradations for the tight-vs-loose comparison: an **outage** during which only
``outage_keep`` stations are heard (one TDoA: no position fix possible), an
**NLOS-biased station** (a constant excess on one station for a while) and a
**time-correlated range bias** per station (first-order Gauss–Markov, ``range_bias_sigma_m``,
``range_bias_tau_s``; off by default), which no filter of notebook 05 models.
The mismatch cases of notebook 05 (simulator ≠ filter model) are in :mod:`uwbwb.sim.mismatch`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import validate
from ..models.imu import GRADES, HeadingLog, ImuErrorModel
from ..models.ins import Mechanization, NavState, dcm_from_euler, dcm_to_quat
from ..models.tdoa import TdoaModel
from ..types import Anchors, ImuLog, RangeLog, TdoaLog, Trajectory

__all__ = ["PAPER_WAYPOINTS_M", "PAPER_STATIC_M", "RobotConfig", "RobotMotion", "RobotRun", "broken_line",
           "gauss_markov", "hold", "simulate"]

#: The dynamic test's broken line (paper 004, Sec. 4.2), m.
PAPER_WAYPOINTS_M = ((2.0, 1.0), (3.0, 1.0), (3.0, 2.0), (4.0, 2.0), (4.0, 3.0), (5.0, 3.0))
#: The static test position, m.
PAPER_STATIC_M = (3.5, 2.0)
_TWO_PI = 2 * math.pi


def _S(u):
    """Smooth step 0 → 1 on u ∈ [0, 1] with zero slope-rate at both ends: ``u − sin(2πu)/2π``."""
    return u - np.sin(_TWO_PI * u) / _TWO_PI


def _dS(u):
    return 1 - np.cos(_TWO_PI * u)


def _I(u):
    """∫₀ᵘ S."""
    return u * u / 2 + (np.cos(_TWO_PI * u) - 1) / _TWO_PI ** 2


@dataclass(frozen=True)
class RobotMotion:
    """Piecewise closed-form planar motion: segments ``(kind, t0_s, duration_s, params)``.

    Kinds: ``"hold"`` (params: position, yaw), ``"drive"`` (start, unit direction, length,
    speed, ramp time, yaw), ``"turn"`` (position, yaw0, yaw change).
    """

    segments: tuple
    height_m: float

    @property
    def duration_s(self) -> float:
        kind, t0, dur, _ = self.segments[-1]
        return t0 + dur

    def state(self, t_s):
        """Position (T, 3), velocity (T, 3), acceleration (T, 3), yaw (T,), yaw rate (T,) at ``t_s``."""
        t = np.asarray(t_s, float)
        pos, vel, acc = np.zeros((t.size, 3)), np.zeros((t.size, 3)), np.zeros((t.size, 3))
        yaw, rate = np.zeros(t.size), np.zeros(t.size)
        pos[:, 2] = self.height_m
        for n, (kind, t0, dur, prm) in enumerate(self.segments):
            last = n == len(self.segments) - 1
            m = (t >= t0) & ((t < t0 + dur) | (last & (t <= t0 + dur + 1e-9)))
            if not m.any():
                continue
            tau = np.clip(t[m] - t0, 0, dur)
            if kind == "hold":
                pos[m, :2], yaw[m] = prm["pos"], prm["yaw"]
            elif kind == "turn":
                u = tau / dur
                pos[m, :2] = prm["pos"]
                yaw[m] = prm["yaw0"] + prm["dyaw"] * _S(u)
                rate[m] = prm["dyaw"] / dur * _dS(u)
            else:  # drive: ramp up, cruise, ramp down
                V, r, L, d = prm["speed"], prm["ramp"], prm["length"], np.asarray(prm["dir"])
                s, sd, sdd = np.zeros(tau.size), np.zeros(tau.size), np.zeros(tau.size)
                up, down = tau < r, tau > dur - r
                mid = ~up & ~down
                u = tau[up] / r
                s[up], sd[up], sdd[up] = V * r * _I(u), V * _S(u), V / r * _dS(u)
                s[mid], sd[mid] = V * r / 2 + V * (tau[mid] - r), V
                u = (tau[down] - (dur - r)) / r
                s[down] = L - V * r / 2 + V * r * (u - _I(u))
                sd[down], sdd[down] = V * (1 - _S(u)), -V / r * _dS(u)
                pos[m, :2] = np.asarray(prm["start"]) + s[:, None] * d
                vel[m, :2], acc[m, :2] = sd[:, None] * d, sdd[:, None] * d
                yaw[m] = prm["yaw"]
        return pos, vel, acc, yaw, rate


def hold(pos_m=PAPER_STATIC_M, duration_s: float = 60.0, *, yaw_rad: float = 0.0, height_m: float = 0.3):
    """A robot standing still (the static test)."""
    return RobotMotion((("hold", 0.0, float(duration_s), {"pos": tuple(pos_m), "yaw": yaw_rad}),), height_m)


def broken_line(waypoints_m=PAPER_WAYPOINTS_M, *, speed_mps: float = 0.3, ramp_s: float = 1.0,
                turn_s: float = 2.0, pause_s: float = 1.0, height_m: float = 0.3) -> RobotMotion:
    """Drive the waypoints (the dynamic test): hold, then per leg drive / stop / turn on the spot."""
    w = np.asarray(waypoints_m, float)
    if w.ndim != 2 or w.shape[1] != 2 or len(w) < 2:
        raise ValueError(f"broken_line: need at least two (x, y) waypoints, got shape {w.shape}")
    segs, t = [], 0.0
    yaw = math.atan2(*(w[1] - w[0])[::-1])
    segs.append(("hold", t, pause_s, {"pos": tuple(w[0]), "yaw": yaw}))
    t += pause_s
    for k in range(len(w) - 1):
        d = w[k + 1] - w[k]
        L = float(np.linalg.norm(d))
        if L <= speed_mps * ramp_s:
            raise ValueError(f"broken_line: leg {k} ({L:.2f} m) is too short for the speed ramps")
        heading = math.atan2(d[1], d[0])
        if k > 0:
            dyaw = (heading - yaw + math.pi) % (2 * math.pi) - math.pi
            if abs(dyaw) > 1e-9:
                segs.append(("turn", t, turn_s, {"pos": tuple(w[k]), "yaw0": yaw, "dyaw": dyaw}))
                t += turn_s
            yaw = heading
        dur = L / speed_mps + ramp_s
        segs.append(("drive", t, dur, {"start": tuple(w[k]), "dir": tuple(d / L), "length": L, "speed": speed_mps,
                                       "ramp": ramp_s, "yaw": yaw}))
        t += dur
    segs.append(("hold", t, pause_s, {"pos": tuple(w[-1]), "yaw": yaw}))
    return RobotMotion(tuple(segs), height_m)


@dataclass(frozen=True)
class RobotConfig:
    """Everything the simulation assumes (module docstring); SI units."""

    stations_m: tuple = ((0.0, 0.0, 2.4), (7.0, 0.0, 2.2), (7.0, 5.0, 2.4), (0.0, 5.0, 2.2))
    reference: int = 0
    uwb_rate_hz: float = 50.0
    imu_rate_hz: float = 100.0
    sigma_toa_m: float = 0.03
    outlier_rate: float = 0.02
    outlier_near_gain: float = 3.0
    outlier_near_scale_m: float = 1.5
    outlier_excess_m: tuple = (0.3, 4.0)
    p_missing: float = 0.01
    imu: ImuErrorModel = field(default_factory=lambda: GRADES["consumer"])
    lever_arm_m: tuple = (0.0, 0.0, 0.15)
    tag_height_m: float = 0.30
    outage_start_s: float | None = None
    outage_s: float = 0.0
    outage_keep: tuple = (0, 1)
    nlos_station: int | None = None
    nlos_bias_m: float = 0.4
    nlos_start_s: float = 0.0
    nlos_s: float = 0.0
    range_bias_sigma_m: float = 0.0
    range_bias_tau_s: float = 30.0

    def __post_init__(self):
        a = validate.points("RobotConfig.stations_m", self.stations_m, minimum=3)
        if not 0 <= self.reference < a.shape[0]:
            raise ValueError("RobotConfig.reference must index a station")
        if not (self.imu_rate_hz >= self.uwb_rate_hz > 0):
            raise ValueError("RobotConfig: need imu_rate_hz >= uwb_rate_hz > 0")
        for name in ("sigma_toa_m", "outlier_rate", "p_missing", "outage_s", "nlos_s", "range_bias_sigma_m"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"RobotConfig.{name} must be >= 0")
        if not self.range_bias_tau_s > 0:
            raise ValueError(f"RobotConfig.range_bias_tau_s must be > 0, got {self.range_bias_tau_s!r}")
        lo, hi = self.outlier_excess_m
        if not 0 <= lo <= hi:
            raise ValueError(f"RobotConfig.outlier_excess_m must be (low, high) with 0 <= low <= high, "
                             f"got {self.outlier_excess_m!r}")

    @property
    def anchors(self) -> Anchors:
        a = np.asarray(self.stations_m, float)
        return Anchors(tuple(f"BS{i + 1}" for i in range(len(a))), a)

    def tdoa_model(self, sigma_m: float | None = None) -> TdoaModel:
        """The 3-D TDoA model of this room (per-station arrival-time noise ``sigma_toa_m``)."""
        return TdoaModel(np.asarray(self.stations_m, float), self.sigma_toa_m if sigma_m is None else sigma_m, dim=3)


@dataclass(frozen=True)
class RobotRun:
    """One simulated run.

    ``truth`` is the tag at the UWB epochs (with the IMU's velocity and attitude ``rot``; the
    motion is the IMU's, the tag sits at ``IMU + C · lever_arm_m``);
    ``nav_truth`` the IMU state at the IMU samples; ``outlier`` (T, n) marks injected
    multipath excesses, ``outage`` (T,) the outage epochs, ``nlos`` (T,) the biased-station
    epochs.
    """

    config: RobotConfig
    motion: RobotMotion
    truth: Trajectory
    tdoa: TdoaLog
    ranges: RangeLog
    imu: ImuLog
    acc_bias_mps2: np.ndarray
    gyro_bias_radps: np.ndarray
    heading: HeadingLog
    nav_truth: tuple
    outlier: np.ndarray
    outage: np.ndarray
    nlos: np.ndarray

    @property
    def x0(self) -> NavState:
        """True IMU state at the first IMU sample."""
        p, v, q = self.nav_truth
        return NavState(p[0], v[0], q[0])

    @property
    def yaw_true_rad(self) -> np.ndarray:
        R = self.truth.rot
        return np.arctan2(R[:, 1, 0], R[:, 0, 0])


def ideal_imu(motion: RobotMotion, t_s, mechanization: Mechanization = Mechanization()):
    """Exact body-frame specific force and rate of ``motion`` at ``t_s``, and the IMU states."""
    pos, vel, acc, yaw, rate = motion.state(t_s)
    C = dcm_from_euler(np.zeros_like(yaw), np.zeros_like(yaw), yaw)
    f_b = np.einsum("tji,tj->ti", C, acc - mechanization.g_n)
    w_b = np.zeros_like(f_b)
    w_b[:, 2] = rate
    return f_b, w_b, (pos, vel, dcm_to_quat(C)), C


def gauss_markov(n_steps: int, n_series: int, *, sigma: float, tau_s: float, dt_s: float,
                 rng: np.random.Generator) -> np.ndarray:
    """Stationary first-order Gauss–Markov sequences, shape ``(n_steps, n_series)``.

    ``b[k+1] = a b[k] + √(1 − a²) σ w[k]``, ``a = exp(−dt/τ)``, ``b[0] ~ N(0, σ²)``: every
    sample has SD ``sigma``, the correlation between samples ``Δt`` apart is ``exp(−Δt/τ)``.
    """
    a = math.exp(-dt_s / tau_s)
    w = rng.normal(0.0, sigma, (n_steps, n_series))
    w[1:] *= math.sqrt(1 - a * a)
    b = np.empty_like(w)
    b[0] = w[0]
    for k in range(1, n_steps):            # n_steps ~ 10³: a plain recursion is fast enough
        b[k] = a * b[k - 1] + w[k]
    return b


def simulate(motion: RobotMotion, config: RobotConfig = RobotConfig(), *, rng: np.random.Generator,
             mechanization: Mechanization = Mechanization()) -> RobotRun:
    """Simulate IMU, magnetometer and TDoA logs for ``motion`` (module docstring)."""
    cfg = config
    lever = np.asarray(cfg.lever_arm_m, float)
    T_end = motion.duration_s
    t_imu = np.arange(0.0, T_end + 1e-9, 1.0 / cfg.imu_rate_hz)
    f_b, w_b, (p_i, v_i, q_i), _ = ideal_imu(motion, t_imu, mechanization)
    # the motion is the IMU's; the tag sits at IMU + C·lever, at height motion.height_m
    p_i[:, 2] = motion.height_m - lever[2]
    errs = cfg.imu.sample(t_imu, f_b, w_b, rng=rng)

    t_uwb = np.arange(0.0, T_end + 1e-9, 1.0 / cfg.uwb_rate_hz)
    pos, vel, _, yaw, _ = motion.state(t_uwb)
    C = dcm_from_euler(np.zeros_like(yaw), np.zeros_like(yaw), yaw)
    pos[:, 2] = motion.height_m - lever[2]
    tag = pos + C @ lever
    model = cfg.tdoa_model(sigma_m=max(cfg.sigma_toa_m, 1e-3))       # geometry only; noise drawn below
    n = model.n_anchors
    true_r = model.ranges(tag)
    r = true_r + rng.normal(0.0, cfg.sigma_toa_m, true_r.shape)
    p_out = np.minimum(1.0, cfg.outlier_rate * (1 + cfg.outlier_near_gain * np.exp(-true_r / cfg.outlier_near_scale_m)))
    outlier = rng.random(r.shape) < p_out
    r = r + np.where(outlier, rng.uniform(*cfg.outlier_excess_m, r.shape), 0.0)
    nlos = np.zeros(t_uwb.size, bool)
    if cfg.nlos_station is not None and cfg.nlos_s > 0:
        nlos = (t_uwb >= cfg.nlos_start_s) & (t_uwb < cfg.nlos_start_s + cfg.nlos_s)
        r[nlos, cfg.nlos_station] += cfg.nlos_bias_m
    missing = rng.random(r.shape) < cfg.p_missing
    missing[:, cfg.reference] = False
    if cfg.range_bias_sigma_m > 0:         # drawn only when asked: the other draws keep their order
        r = r + gauss_markov(t_uwb.size, n, sigma=cfg.range_bias_sigma_m, tau_s=cfg.range_bias_tau_s,
                             dt_s=1.0 / cfg.uwb_rate_hz, rng=rng)
    outage = np.zeros(t_uwb.size, bool)
    if cfg.outage_start_s is not None and cfg.outage_s > 0:
        outage = (t_uwb >= cfg.outage_start_s) & (t_uwb < cfg.outage_start_s + cfg.outage_s)
        drop = np.setdiff1d(np.arange(n), cfg.outage_keep)
        missing[np.ix_(outage, drop)] = True
    r[missing] = np.nan
    outlier &= ~missing
    ranges = RangeLog(t_uwb, r, cfg.anchors.ids, "tag")
    tdoa = TdoaLog.from_ranges(ranges, cfg.reference)
    heading = HeadingLog(t_uwb, (yaw + rng.normal(0.0, cfg.imu.mag_heading_sigma_rad, yaw.size)
                                 + np.pi) % (2 * np.pi) - np.pi)
    truth = Trajectory(t_uwb, tag, vel, C, name="truth")
    return RobotRun(cfg, motion, truth, tdoa, ranges, errs.imu, errs.acc_bias_mps2, errs.gyro_bias_radps, heading,
                    (p_i, v_i, q_i), outlier, outage, nlos)
