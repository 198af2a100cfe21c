"""IMU calibration from a recording with motion-capture truth: sensor axes, accelerometer scale,
noise densities, range noise and bias — what the UWB/INS filters need on *another* recording.

:func:`calibrate_iasl` is fitted on a calibration recording only; the filters of
:mod:`uwbwb.filters.alignment` then use its :class:`RealCalibration` unchanged on the scored one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..calibration import MAD_TO_SIGMA, range_sigma_from_truth
from ..models.imu import GRADES, ImuConvention, ImuErrorModel
from ..models.ins import GRAVITY_MPS2
from ..types import Recording, Trajectory

__all__ = ["RealCalibration", "truth_specific_force", "calibrate_iasl"]


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


def truth_specific_force(truth: Trajectory, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    f_t, w_t = truth_specific_force(truth, imu.t_s[inside])
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
