"""IMU error model and sensor conventions (paper 004: "true values, a low-frequency noise component and a
white noise term", eq. 3).

Measured specific force and angular rate (body frame, SI)::

    f̃ = f + b_a + n_a,     ω̃ = ω + b_g + n_g
    b(t) = b(0) + ∫ n_b dt           (bias instability as a random walk)

``b(0)`` is a turn-on bias drawn once per run (SD ``*_bias_sigma``); ``n`` is
white noise of spectral density ``*_noise_density`` (so its standard deviation
per sample at rate ``f_s`` is ``density · √f_s``); ``n_b`` drives the bias
random walk with density ``*_bias_rw``. The same object gives the simulator its
errors and the error-state filter its process noise.

:data:`GRADES` states the values used for "consumer", "industrial" and
"tactical" grade IMUs (data-sheet orders of magnitude, an assumption: the paper
names no part).

:class:`ImuConvention` turns a log as recorded into body-frame SI samples:
units (g or m/s², deg/s or rad/s), accelerometer sign and scale, the
sensor-to-body rotation, and the lever arm of the UWB tag from the IMU.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..types import ImuLog
from .ins import GRAVITY_MPS2

__all__ = ["GRADES", "HeadingLog", "ImuConvention", "ImuErrorModel", "ImuErrors"]

_DEG = np.pi / 180.0


@dataclass(frozen=True)
class ImuErrorModel:
    """Bias + bias instability + white noise, per axis (all SI).

    Attributes
    ----------
    acc_noise_density
        Accelerometer white noise, m/s²/√Hz (= velocity random walk, m/s/√s).
    gyro_noise_density
        Gyro white noise, rad/s/√Hz (= angle random walk, rad/√s).
    acc_bias_sigma_mps2, gyro_bias_sigma_radps
        Turn-on bias standard deviations.
    acc_bias_rw, gyro_bias_rw
        Bias random-walk densities, m/s³/√Hz and rad/s²/√Hz.
    mag_heading_sigma_rad
        Standard deviation of a magnetometer heading (0: no magnetometer).
    """

    acc_noise_density: float = 3e-3
    gyro_noise_density: float = 2e-4
    acc_bias_sigma_mps2: float = 0.05
    gyro_bias_sigma_radps: float = 0.1 * _DEG
    acc_bias_rw: float = 1e-4
    gyro_bias_rw: float = 1e-5
    mag_heading_sigma_rad: float = 3.0 * _DEG

    def __post_init__(self):
        for name in ("acc_noise_density", "gyro_noise_density", "acc_bias_sigma_mps2", "gyro_bias_sigma_radps",
                     "acc_bias_rw", "gyro_bias_rw", "mag_heading_sigma_rad"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"ImuErrorModel.{name} must be finite and >= 0, got {v!r}")
        if self.gyro_bias_sigma_radps > 0.5 or self.gyro_noise_density > 0.1:
            raise ValueError("ImuErrorModel: gyro values look like deg/s; give rad/s (multiply by pi/180)")

    def scaled(self, factor: float) -> "ImuErrorModel":
        """Every IMU error (not the magnetometer) multiplied by ``factor``."""
        if not factor > 0:
            raise ValueError(f"scale factor must be positive, got {factor!r}")
        return replace(self, **{k: getattr(self, k) * factor for k in (
            "acc_noise_density", "gyro_noise_density", "acc_bias_sigma_mps2", "gyro_bias_sigma_radps",
            "acc_bias_rw", "gyro_bias_rw")})

    def sample(self, t_s, acc_mps2, gyro_radps, *, rng: np.random.Generator,
               initial_bias: bool = True) -> "ImuErrors":
        """Corrupt ideal samples.

        Parameters
        ----------
        t_s
            Sample times, shape ``(T,)``, s (uniform or not).
        acc_mps2, gyro_radps
            Ideal body-frame specific force and rate, shape ``(T, 3)``.
        rng
            Random generator.
        initial_bias
            Draw the turn-on bias (False: biases start at zero).

        Returns
        -------
        ImuErrors
        """
        t = np.asarray(t_s, float)
        T = t.size
        dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if T > 1 else 1.0))
        rate = 1.0 / np.median(dt)
        ba = np.zeros(3) if not initial_bias else rng.normal(0, self.acc_bias_sigma_mps2, 3)
        bg = np.zeros(3) if not initial_bias else rng.normal(0, self.gyro_bias_sigma_radps, 3)
        steps = np.sqrt(dt)[:, None]
        ba_t = ba + np.cumsum(rng.normal(0, 1, (T, 3)) * self.acc_bias_rw * steps, axis=0)
        bg_t = bg + np.cumsum(rng.normal(0, 1, (T, 3)) * self.gyro_bias_rw * steps, axis=0)
        na = rng.normal(0, self.acc_noise_density * np.sqrt(rate), (T, 3))
        ng = rng.normal(0, self.gyro_noise_density * np.sqrt(rate), (T, 3))
        return ImuErrors(ImuLog(t, np.asarray(acc_mps2) + ba_t + na, np.asarray(gyro_radps) + bg_t + ng), ba_t, bg_t)


@dataclass(frozen=True)
class ImuErrors:
    """A corrupted IMU log and the true bias tracks ``(T, 3)`` behind it."""

    imu: ImuLog
    acc_bias_mps2: np.ndarray
    gyro_bias_radps: np.ndarray


#: IMU grades used in notebook 05 (assumed data-sheet magnitudes; the paper names no part).
GRADES = {
    "consumer": ImuErrorModel(acc_noise_density=3e-3, gyro_noise_density=3e-4, acc_bias_sigma_mps2=0.1,
                              gyro_bias_sigma_radps=0.3 * _DEG, acc_bias_rw=3e-4, gyro_bias_rw=3e-5),
    "industrial": ImuErrorModel(acc_noise_density=6e-4, gyro_noise_density=1e-4, acc_bias_sigma_mps2=0.02,
                                gyro_bias_sigma_radps=0.05 * _DEG, acc_bias_rw=1e-4, gyro_bias_rw=5e-6),
    "tactical": ImuErrorModel(acc_noise_density=3e-4, gyro_noise_density=1e-5, acc_bias_sigma_mps2=0.002,
                              gyro_bias_sigma_radps=1.0 / 3600 * _DEG, acc_bias_rw=1e-5, gyro_bias_rw=1e-7),
}


@dataclass(frozen=True)
class ImuConvention:
    """How a recorded IMU log maps to body-frame SI samples.

    ``f_b = acc_scale · R_body_sensor (acc_unit → m/s²)(acc)``,
    ``ω_b = R_body_sensor (gyro_unit → rad/s)(gyro)``.

    Attributes
    ----------
    acc_unit
        ``"m/s^2"`` or ``"g"`` (multiplied by ``g_mps2``).
    gyro_unit
        ``"rad/s"`` or ``"deg/s"``.
    R_body_sensor
        Proper rotation taking sensor axes to body axes, ``(3, 3)``. A sensor
        whose z axis points down in a z-up body has ``diag(1, -1, -1)``.
    acc_scale
        Multiplicative accelerometer scale applied after unit conversion (1: none).
    lever_arm_m
        UWB tag position relative to the IMU, body frame, ``(3,)``, m.
    g_mps2
        Value of 1 g for ``acc_unit="g"``.
    """

    acc_unit: str = "m/s^2"
    gyro_unit: str = "rad/s"
    R_body_sensor: np.ndarray = None
    acc_scale: float = 1.0
    lever_arm_m: np.ndarray = None
    g_mps2: float = GRAVITY_MPS2

    def __post_init__(self):
        if self.acc_unit not in ("m/s^2", "g"):
            raise ValueError(f"ImuConvention.acc_unit must be 'm/s^2' or 'g', got {self.acc_unit!r}")
        if self.gyro_unit not in ("rad/s", "deg/s"):
            raise ValueError(f"ImuConvention.gyro_unit must be 'rad/s' or 'deg/s', got {self.gyro_unit!r}")
        R = np.eye(3) if self.R_body_sensor is None else np.array(self.R_body_sensor, float)
        if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ValueError("ImuConvention.R_body_sensor must be a proper rotation (orthonormal, det +1); a "
                             "left-handed sensor frame needs its axes fixed before use")
        lever = np.zeros(3) if self.lever_arm_m is None else np.array(self.lever_arm_m, float)
        if lever.shape != (3,) or not np.all(np.isfinite(lever)):
            raise ValueError(f"ImuConvention.lever_arm_m must be 3 finite numbers (m), got {self.lever_arm_m!r}")
        if not 0.5 < self.acc_scale < 2.0:
            raise ValueError(f"ImuConvention.acc_scale must be near 1, got {self.acc_scale!r}")
        for a in (R, lever):
            a.setflags(write=False)
        object.__setattr__(self, "R_body_sensor", R)
        object.__setattr__(self, "lever_arm_m", lever)

    def to_body(self, imu: ImuLog) -> ImuLog:
        """Body-frame SI samples from a log recorded in this convention."""
        acc = np.asarray(imu.acc_mps2) * (self.g_mps2 if self.acc_unit == "g" else 1.0) * self.acc_scale
        gyro = np.asarray(imu.gyro_radps) * (_DEG if self.gyro_unit == "deg/s" else 1.0)
        return ImuLog(imu.t_s, acc @ self.R_body_sensor.T, gyro @ self.R_body_sensor.T)


@dataclass(frozen=True)
class HeadingLog:
    """Magnetometer headings (yaw, rad, navigation frame) at times ``t_s``."""

    t_s: np.ndarray
    yaw_rad: np.ndarray

    def __post_init__(self):
        t, y = np.asarray(self.t_s, float), np.asarray(self.yaw_rad, float)
        if t.ndim != 1 or y.shape != t.shape:
            raise ValueError(f"HeadingLog needs t_s and yaw_rad of equal length, got {t.shape}, {y.shape}")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "yaw_rad", y)

    def at(self, t_s: np.ndarray) -> np.ndarray:
        """Heading at each of ``t_s`` (nearest sample within half a sample interval, else NaN)."""
        t_s = np.asarray(t_s, float)
        if self.t_s.size == 0:
            return np.full(t_s.shape, np.nan)
        k = np.clip(np.searchsorted(self.t_s, t_s), 1, max(self.t_s.size - 1, 1))
        k = np.where(np.abs(self.t_s[k - 1] - t_s) <= np.abs(self.t_s[np.minimum(k, self.t_s.size - 1)] - t_s),
                     k - 1, np.minimum(k, self.t_s.size - 1))
        half = 0.5 * (np.median(np.diff(self.t_s)) if self.t_s.size > 1 else np.inf)
        return np.where(np.abs(self.t_s[k] - t_s) <= half + 1e-9, self.yaw_rad[k], np.nan)
