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

__all__ = ["ACC_FULL_SCALE_MPS2", "GRADES", "GRAVITY_TOLERANCE_MPS2", "GYRO_FULL_SCALE_RADPS", "HeadingLog",
           "ImuConvention", "ImuErrorModel", "ImuErrors", "ImuEvidence", "MAX_SPIKE_FRACTION", "RATE_SCALE_DEG_LIMIT",
           "UNIT_GRAVITY_TOLERANCE_MPS2", "check_body_imu", "imu_evidence", "unit_problem"]

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

    def to_body(self, imu: ImuLog, *, check: bool = True) -> ImuLog:
        """Body-frame SI samples from a log recorded in this convention.

        With ``check`` (default) the result goes through :func:`check_body_imu` (finite, within
        full scale, |f| ≈ g, z up, gyro in rad/s): a convention that does not fit the log is a
        ``ValueError`` with the evidence, never a silently wrong log. ``check=False`` only
        converts (for unit tests of the arithmetic).
        """
        acc = np.asarray(imu.acc_mps2) * (self.g_mps2 if self.acc_unit == "g" else 1.0) * self.acc_scale
        gyro = np.asarray(imu.gyro_radps) * (_DEG if self.gyro_unit == "deg/s" else 1.0)
        with np.errstate(invalid="ignore"):            # a non-finite sample is reported by the check
            body = ImuLog(imu.t_s, acc @ self.R_body_sensor.T, gyro @ self.R_body_sensor.T)
        if check:
            check_body_imu(body, source=f"ImuConvention.to_body ({self.acc_unit}, {self.gyro_unit})")
        return body


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


# ====================================================================== plausibility of a log
#: Widest full-scale ranges of common MEMS IMUs (data-sheet values, an assumption): ±16 g and ±2000 °/s.
#: A sample beyond them cannot have been measured: it is a transmission or parsing fault.
ACC_FULL_SCALE_MPS2 = 16.0 * GRAVITY_MPS2
GYRO_FULL_SCALE_RADPS = 2000.0 * _DEG
#: |median specific force| of a log that mostly rests or hovers lies within g ± this, m/s²: flight
#: accelerations of a few m/s² average out, and scale errors of a consumer part are a few per cent.
GRAVITY_TOLERANCE_MPS2 = 2.0
#: At a filter's entry (:func:`check_body_imu` with ``gravity_tolerance_mps2`` of this): |median |f| − g| may
#: reach g/2 — wide enough for a deliberately poor sensor (notebook 05's "IMU 10× worse" reads 7.6 m/s²), narrow
#: enough for every unit error (g: 1, cm/s²: 981, mm/s²: 9 807).
UNIT_GRAVITY_TOLERANCE_MPS2 = 0.5 * GRAVITY_MPS2
#: More samples than this fraction beyond full scale is a unit problem (mg, deg/s), not spikes.
MAX_SPIKE_FRACTION = 0.01
#: The gyro is taken to be in deg/s when the rate scale ``k`` (:func:`imu_evidence`) is confidently below
#: this: the geometric mean of 1 (rad/s) and π/180 (deg/s).
RATE_SCALE_DEG_LIMIT = float(np.sqrt(_DEG))


@dataclass(frozen=True)
class ImuEvidence:
    """What a log says about its own units and axes (see :func:`imu_evidence`).

    Attributes
    ----------
    gravity_mps2
        Median specific-force magnitude, in the log's accelerometer unit.
    median_fz
        Median z specific force (positive: gravity reaction along +z, a z-up frame).
    rate_scale, rate_scale_se
        Least-squares ``k`` in ``du/dt ≈ −k ω × u`` (``u`` = specific-force direction) and its
        standard error; ``k ≈ 1`` for rad/s, ≈ π/180 for deg/s; NaN when the log does not tilt
        enough to tell (fewer than 20 samples).
    """

    gravity_mps2: float
    median_fz: float
    rate_scale: float
    rate_scale_se: float

    @property
    def gyro_looks_deg(self) -> bool:
        """``k + 3 σ_k`` below :data:`RATE_SCALE_DEG_LIMIT` and ``k − 3 σ_k`` above 0.

        The second condition asks that the gyro explain the tilt at all: a log at rest (no tilt,
        ``k ≈ 0 ± σ_k`` however long it is) makes no claim either way.
        """
        k, se = self.rate_scale, self.rate_scale_se
        return bool(np.isfinite(k) and k + 3 * se < RATE_SCALE_DEG_LIMIT and k - 3 * se > 0)

    @property
    def gravity_ok(self) -> bool:
        """|median |f| − g| within :data:`GRAVITY_TOLERANCE_MPS2`."""
        return abs(self.gravity_mps2 - GRAVITY_MPS2) <= GRAVITY_TOLERANCE_MPS2

    def unit_guess(self) -> str:
        """What unit the accelerometer magnitude suggests, in words."""
        g = self.gravity_mps2
        if abs(g - 1000.0) < 200.0:
            return "looks like mg"
        if abs(g - 1.0) < 0.2:
            return "looks like g"
        return "unit unknown"


def imu_evidence(t_s, acc, gyro) -> ImuEvidence:
    """Units and axes as the samples themselves show them.

    * gravity: the median of ``|f|``. A log that rests or hovers most of the time reads g there
      (9.81 m/s², 1 g or ~1000 mg).
    * z sign: the median of ``f_z``; a z-up frame reads about +g at rest, a z-down one −g.
    * gyro scale: the accelerometer direction ``u = f/|f|`` is, at low dynamics, gravity seen from
      the body, fixed in the world, so ``du/dt = −ω × u``. The least-squares factor ``k`` between
      the measured ``du/dt`` (central differences) and ``−ω × u`` is ≈ 1 when ω is in rad/s and ≈
      π/180 ≈ 0.017 when it is in deg/s (on the i-ASL flights k = 1.6–2.5 in rad/s, the flight's
      own accelerations inflating it; the same data read as deg/s give 0.028–0.044). Only tilt
      rates enter (a yaw about gravity leaves ``u`` alone).

    Parameters
    ----------
    t_s
        Times, shape ``(T,)``, s, strictly increasing.
    acc, gyro
        Samples, shape ``(T, 3)``, finite, in the log's own units.
    """
    t, a, w = np.asarray(t_s, float), np.asarray(acc, float), np.asarray(gyro, float)
    mag = np.linalg.norm(a, axis=1)
    g = float(np.median(mag)) if mag.size else np.nan
    fz = float(np.median(a[:, 2])) if mag.size else np.nan
    k = se = np.nan
    ok = mag > 0
    if ok.sum() >= 20:
        t, a, w, mag = t[ok], a[ok], w[ok], mag[ok]
        u = a / mag[:, None]
        du = np.gradient(u, t, axis=0)
        p = -np.cross(w, u)
        pp = float((p * p).sum())
        if pp > 0:
            k = float((du * p).sum() / pp)
            r = du - k * p
            se = float(np.sqrt((r * r).sum() / max(r.size - 1, 1) / pp))
    return ImuEvidence(g, fz, k, se)


def unit_problem(t_s, acc, gyro, *, gravity_tolerance_mps2: float = GRAVITY_TOLERANCE_MPS2
                 ) -> tuple[str | None, ImuEvidence, np.ndarray]:
    """The unit rules shared by :func:`check_body_imu` and the loaders' checks.

    * Accelerations not in m/s²: the median ``|f|`` of the samples within full scale lies outside
      g ± ``gravity_tolerance_mps2`` (default :data:`GRAVITY_TOLERANCE_MPS2`).
    * A saturating accelerometer: the median says m/s², but more than :data:`MAX_SPIKE_FRACTION` of the
      samples have a component beyond :data:`ACC_FULL_SCALE_MPS2` (too many to drop as spikes).
    * Gyro rates in deg/s: more than :data:`MAX_SPIKE_FRACTION` of the samples beyond
      :data:`GYRO_FULL_SCALE_RADPS` while the rate scale (on all samples within the accelerometer
      full scale) is not that of rad/s, or :attr:`ImuEvidence.gyro_looks_deg`.

    Returns
    -------
    problem : str or None
        What is wrong, with the evidence, in words (None: nothing).
    evidence : ImuEvidence
        On the samples within both full scales.
    spike : numpy.ndarray
        Samples beyond either full scale, shape ``(T,)``.
    """
    t, a, w = np.asarray(t_s, float), np.asarray(acc, float), np.asarray(gyro, float)
    acc_over = (np.abs(a) > ACC_FULL_SCALE_MPS2).any(axis=1)
    gyro_over = (np.abs(w) > GYRO_FULL_SCALE_RADPS).any(axis=1)
    spike = acc_over | gyro_over
    ev = imu_evidence(t[~spike], a[~spike], w[~spike])
    if t.size == 0:
        return None, ev, spike
    gravity_fits = abs(ev.gravity_mps2 - GRAVITY_MPS2) <= gravity_tolerance_mps2
    if gravity_fits and acc_over.mean() > MAX_SPIKE_FRACTION:
        return (f"{int(acc_over.sum())} of {t.size} samples ({100 * acc_over.mean():.1f} %) have an accelerometer "
                f"component beyond the full scale 16 g, while the others read m/s² (median |f| = "
                f"{ev.gravity_mps2:.4g}): a saturating sensor or corrupt samples, more than the "
                f"{100 * MAX_SPIKE_FRACTION:g} % of spikes that are dropped and counted"), ev, spike
    if not gravity_fits:
        g = imu_evidence(t, a, w)
        return (f"accelerations not in m/s² (mg? g?): median |f| = {g.gravity_mps2:.4g}, expected "
                f"{GRAVITY_MPS2:.2f} ± {gravity_tolerance_mps2:.3g} ({g.unit_guess()}); {int(acc_over.sum())} of "
                f"{t.size} samples beyond the full scale 16 g"), ev, spike
    wide = ev if gyro_over.mean() <= MAX_SPIKE_FRACTION else imu_evidence(t[~acc_over], a[~acc_over], w[~acc_over])
    if wide.gyro_looks_deg or (gyro_over.mean() > MAX_SPIKE_FRACTION and not wide.rate_scale > RATE_SCALE_DEG_LIMIT):
        return (f"gyro rates look like deg/s, not rad/s: the tilt of the specific force follows "
                f"{wide.rate_scale:.3g} ± {wide.rate_scale_se:.2g} × ω (≈ 1 for rad/s, π/180 = 0.0175 for "
                f"deg/s); "
                f"median |ω| = {float(np.median(np.linalg.norm(w, axis=1))):.3g}, {int(gyro_over.sum())} of "
                f"{t.size} samples beyond 2000 °/s"), wide, spike
    if gyro_over.mean() > MAX_SPIKE_FRACTION:
        return (f"{int(gyro_over.sum())} of {t.size} gyro samples beyond 2000 °/s although the rate scale "
                f"({wide.rate_scale:.3g}) says rad/s: not spikes, the gyro scale is wrong"), ev, spike
    return None, ev, spike


def check_body_imu(imu: ImuLog, *, source: str = "IMU log",
                   gravity_tolerance_mps2: float = GRAVITY_TOLERANCE_MPS2) -> ImuEvidence:
    """Refuse a log that cannot be body-frame SI samples (what the INS and the ESKF integrate).

    Raises ``ValueError`` naming ``source``, in this order, for (a sample that is not finite cannot reach it:
    :class:`~uwbwb.types.ImuLog` refuses one): a median ``|f|`` outside g ± ``gravity_tolerance_mps2`` (default
    :data:`GRAVITY_TOLERANCE_MPS2`; the filters' entry uses :data:`UNIT_GRAVITY_TOLERANCE_MPS2`), or more than
    :data:`MAX_SPIKE_FRACTION` of the samples beyond full scale (accelerations not in m/s²); a gyro
    whose rate scale says deg/s (:attr:`ImuEvidence.gyro_looks_deg`); a negative median ``f_z`` (a
    z-down frame: gravity's reaction must point along +z); any remaining sample beyond
    :data:`ACC_FULL_SCALE_MPS2` / :data:`GYRO_FULL_SCALE_RADPS` (a spike a loader should have
    dropped and counted). The unit evidence is taken on the samples within full scale. The rate
    scale is judged only on logs of at least 20 samples. Returns the evidence.
    """
    a, w = np.asarray(imu.acc_mps2, float), np.asarray(imu.gyro_radps, float)
    problem, ev, spike = unit_problem(imu.t_s, a, w, gravity_tolerance_mps2=gravity_tolerance_mps2)
    if a.shape[0] == 0:
        return ev
    if problem is not None:
        raise ValueError(f"{source}: {problem}" + ("; give ImuConvention(gyro_unit='deg/s')" if "deg/s" in problem
                                                   else ""))
    if ev.median_fz < 0:
        raise ValueError(f"{source}: z-down frame: median f_z = {ev.median_fz:.3g} m/s², a z-up body reads +g "
                         "at rest (ImuConvention(R_body_sensor=diag(1, -1, -1)) turns a z-down sensor)")
    if spike.any():
        i = np.flatnonzero(spike)
        raise ValueError(f"{source}: {i.size} sample(s) beyond the full scale (16 g = {ACC_FULL_SCALE_MPS2:.4g} m/s², "
                         f"2000 °/s = {GYRO_FULL_SCALE_RADPS:.4g} rad/s), first at t = {imu.t_s[i[0]]:g} s: spikes; "
                         "drop them (counted) before integrating")
    return ev
