"""A UWB facility with sensor-set switching, re-creating the setup of paper 000.

Banerjee, Suski & Hoover track a tag with a Ubisense system of eight sensors,
some of them behind walls or in a hallway. Each reported position is computed
from a *set* of ≥ 5 sensors that changes from one measurement to the next with
the received signal strengths. Their raw data is not public, so this simulator
builds the mechanism from first principles instead of drawing set noise
directly:

1. **Signal strength** of sensor ``i`` at the tag: log-distance path loss
   ``−10 n log10(d_i)`` minus ``wall_loss_db`` per wall crossed, plus log-normal
   fading ``N(0, fading_db)`` drawn per measurement and sensor.
2. **Sensor set**: the ``set_size`` strongest sensors of that measurement
   (:func:`select_sets`); line-of-sight sensors dominate, hallway sensors join
   when fading favours them.
3. **Ranges** from every sensor in the set: true 3-D distance + the sensor's
   constant bias + an NLOS excess delay for every wall crossed (larger at
   oblique incidence, ``wall_excess_m / cos θ``) + a multipath error that
   varies smoothly with the tag position (a stationary Gaussian random field per
   sensor, standard deviation ``multipath_sigma_m``, correlation length
   ``multipath_corr_m``, drawn once per facility) + white noise ``range_sigma_m``.
4. **Position**: 2-D least squares at the known tag height
   (:func:`uwbwb.geometry.multilaterate`).

So each set's systematic error is computed from its sensors' range errors and
the geometry rather than drawn per set, and it changes (slowly) with position —
which the paper's per-set model, calibrated at six locations, only approximates.
Its size is not a finding of the simulator: the defaults below were chosen to hit
the paper's numbers (see the last paragraph).

Recordings follow paper 000's Table I and section II-D/E: a tag at 0.92 m on a
trolley pulled back and forth seven times along a 2.5 m straight track (17.5 m),
at five speeds, fixes at 9.4 Hz; ground truth moves at constant speed with
instantaneous turns, which is exactly how the paper reconstructs its truth.

The facility layout, losses and error sizes are our choices (the paper gives a
floor plan without dimensions). The selection defaults (losses, fading) make the
set statistics at the paper's Fig. 3 location resemble its Fig. 4 (top set
< 45 %, top five ≈ 86 %); the error defaults make the raw error, averaged over
facility draws, about 21 cm (paper: 18–23 cm, mean 20.6 cm). Individual draws
range over roughly 18–25 cm. These set shares and raw errors are therefore
calibration *targets* of the simulator, not reproductions; the fix counts are
*inputs* (track, speeds and rate taken from the paper).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import multilaterate
from ..models.ranging import ranges
from ..types import RangeLog, SetFixLog, set_id_from_mask

#: Paper 000, Table I: recording number → approximate speed (m/s).
TABLE1_SPEEDS_MPS = (0.11, 0.35, 0.65, 1.00, 1.20)


@dataclass(frozen=True)
class FacilityConfig:
    """Layout and error parameters of the simulated facility (SI units).

    Attributes
    ----------
    sensor_xyz_m
        Sensor positions, 8 × (x, y, z), metres. Sensors 1 and 2 sit in a hallway
        north of the lab, sensor 3 in an office east of it; the others are in the lab.
    walls_m
        Wall segments ``(x1, y1, x2, y2)`` in metres (the lab's north and east walls).
    path_loss_exponent
        ``n`` of the log-distance path loss.
    wall_loss_db
        Attenuation per wall crossed, dB.
    fading_db
        Standard deviation of the per-measurement, per-sensor log-normal fading, dB.
    set_size
        Sensors per position fix (the paper's sets have ≥ 5; Fig. 4's are all 5).
    sensor_bias_sigma_m
        Spread of the constant per-sensor range bias (drawn once per facility), metres.
    wall_excess_m
        Extra range per wall crossed at normal incidence (NLOS delay), metres.
    min_cos_incidence
        Cap of the oblique-incidence factor ``1 / cos θ``.
    multipath_sigma_m
        Standard deviation of the position-dependent multipath range error, metres.
    multipath_corr_m
        Its correlation length (squared-exponential covariance), metres.
    n_multipath_waves
        Random Fourier components used to draw the multipath field.
    range_sigma_m
        White range noise, metres.
    tag_height_m
        Tag height (known to the positioning), metres (paper: 92 cm).
    lab_m
        Lab outline ``(x_min, x_max, y_min, y_max)`` for plots, metres.
    calibration_xy_m
        The calibration locations (paper: 6 × 1000 measurements), metres.
    n_calibration
        Measurements per calibration location.
    fig3_xy_m
        The location of the paper's Figs. 3–5, (450, 590) cm; also a calibration location.
    track_start_xy_m, track_end_xy_m
        Ends of the 2.5 m test track (through the Fig. 3 location, along x).
    n_legs
        Passes along the track per recording (paper: back and forth seven times).
    rate_hz
        Fix rate, Hz. The paper states none; Table I implies fixes ÷ (1750 cm ÷ speed)
        = 9.56, 9.34, 9.29, 9.37 and 9.26 Hz for its five recordings (1521 fixes in
        159 s is 9.56 Hz), 9.36 Hz on average, which 9.4 Hz rounds.
    speeds_mps
        Speeds of the five recordings (Table I).
    """

    sensor_xyz_m: tuple = ((0.3, 0.3, 2.8), (2.0, 9.6, 2.8), (7.0, 9.6, 2.8), (10.6, 2.0, 2.8),
                           (8.7, 0.3, 2.8), (8.7, 7.7, 2.8), (4.5, 7.7, 2.8), (0.3, 7.7, 2.8))
    walls_m: tuple = ((0.0, 8.0, 9.0, 8.0), (9.0, 0.0, 9.0, 8.0))
    path_loss_exponent: float = 2.0
    wall_loss_db: float = 6.0
    fading_db: float = 2.5
    set_size: int = 5
    sensor_bias_sigma_m: float = 0.05
    wall_excess_m: float = 0.30
    min_cos_incidence: float = 0.3
    multipath_sigma_m: float = 0.12
    multipath_corr_m: float = 0.5
    n_multipath_waves: int = 64
    range_sigma_m: float = 0.12
    tag_height_m: float = 0.92
    lab_m: tuple = (0.0, 9.0, 0.0, 8.0)
    calibration_xy_m: tuple = ((1.5, 2.0), (4.5, 2.0), (7.5, 2.0), (1.5, 5.9), (4.5, 5.9), (7.5, 5.9))
    n_calibration: int = 1000
    fig3_xy_m: tuple = (4.5, 5.9)
    track_start_xy_m: tuple = (3.25, 5.9)
    track_end_xy_m: tuple = (5.75, 5.9)
    n_legs: int = 7
    rate_hz: float = 9.4
    speeds_mps: tuple = TABLE1_SPEEDS_MPS

    def __post_init__(self):
        xyz = np.asarray(self.sensor_xyz_m, float)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise ValueError(f"sensor_xyz_m must be (n_sensors, 3), got {xyz.shape}")
        if not 3 <= self.set_size <= xyz.shape[0]:
            raise ValueError(f"set_size must be in [3, {xyz.shape[0]}], got {self.set_size}")
        if np.asarray(self.walls_m, float).reshape(-1, 4).shape[0] != len(self.walls_m):
            raise ValueError("walls_m must be a tuple of (x1, y1, x2, y2) segments")
        for name in ("fading_db", "sensor_bias_sigma_m", "wall_excess_m", "range_sigma_m", "wall_loss_db",
                     "multipath_sigma_m"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0")
        if not 0 < self.min_cos_incidence <= 1:
            raise ValueError("min_cos_incidence must be in (0, 1]")
        if self.rate_hz <= 0 or self.n_legs < 1 or self.n_calibration < 1 or self.n_multipath_waves < 1 \
                or self.multipath_corr_m <= 0:
            raise ValueError("rate_hz, n_legs, n_calibration, n_multipath_waves and multipath_corr_m "
                             "must be positive")
        if any(v <= 0 for v in self.speeds_mps):
            raise ValueError("speeds_mps must be positive")

    @property
    def n_sensors(self) -> int:
        return len(self.sensor_xyz_m)

    @property
    def sensor_ids(self) -> tuple[str, ...]:
        return tuple(str(i) for i in range(self.n_sensors))

    @property
    def track_length_m(self) -> float:
        return float(np.hypot(*np.subtract(self.track_end_xy_m, self.track_start_xy_m)))


@dataclass(frozen=True)
class Facility:
    """One realisation of the facility: the configuration plus its drawn systematic errors.

    Attributes
    ----------
    config
        The layout and error parameters.
    sensor_bias_m
        Constant range bias of every sensor, shape ``(n_sensors,)``, metres.
    wave_k_radpm
        Wave vectors of the multipath field, shape ``(n_sensors, J, 2)``, rad/m.
    wave_phase_rad
        Phases of the multipath field, shape ``(n_sensors, J)``, rad.
    """

    config: FacilityConfig
    sensor_bias_m: np.ndarray
    wave_k_radpm: np.ndarray
    wave_phase_rad: np.ndarray

    def __post_init__(self):
        n = self.config.n_sensors
        b = np.array(self.sensor_bias_m, float)
        k = np.array(self.wave_k_radpm, float)
        ph = np.array(self.wave_phase_rad, float)
        if b.shape != (n,) or k.ndim != 3 or k.shape[::2] != (n, 2) or ph.shape != k.shape[:2]:
            raise ValueError(f"Facility: sensor_bias_m (n,), wave_k_radpm (n, J, 2), wave_phase_rad (n, J) "
                             f"with n = {n}; got {b.shape}, {k.shape}, {ph.shape}")
        for name, arr in (("sensor_bias_m", b), ("wave_k_radpm", k), ("wave_phase_rad", ph)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def sensor_xyz_m(self) -> np.ndarray:
        return np.asarray(self.config.sensor_xyz_m, float)

    @property
    def sensor_ids(self) -> tuple[str, ...]:
        return self.config.sensor_ids

    def _tag_xyz(self, pos_m) -> np.ndarray:
        p = np.asarray(pos_m, float)
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValueError(f"pos_m must be (N, 2), got {p.shape}")
        return np.column_stack([p, np.full(len(p), self.config.tag_height_m)])

    def true_ranges_m(self, pos_m) -> np.ndarray:
        """3-D tag–sensor distances for tag positions ``(N, 2)`` at the tag height: ``(N, n_sensors)``."""
        return ranges(self._tag_xyz(pos_m), self.sensor_xyz_m)

    def wall_crossings(self, pos_m) -> tuple[np.ndarray, np.ndarray]:
        """Walls between tag and each sensor (plan view).

        Returns
        -------
        n_walls
            Number of walls crossed, shape ``(N, n_sensors)``.
        excess_factor
            ``Σ 1 / max(cos θ, min_cos_incidence)`` over the crossed walls, ``(N, n_sensors)``,
            with θ the angle between the ray and the wall normal.
        """
        p = np.asarray(pos_m, float)[:, None, :]                     # (N, 1, 2)
        s = self.sensor_xyz_m[None, :, :2]                            # (1, n, 2)
        d = s - p
        n_walls = np.zeros(d.shape[:2], int)
        factor = np.zeros(d.shape[:2])
        for x1, y1, x2, y2 in self.config.walls_m:
            a, e = np.array([x1, y1]), np.array([x2 - x1, y2 - y1])
            # solve p + t d = a + u e for (t, u); crossing if both in [0, 1]
            den = d[..., 0] * e[1] - d[..., 1] * e[0]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = ((a[0] - p[..., 0]) * e[1] - (a[1] - p[..., 1]) * e[0]) / den
                u = ((a[0] - p[..., 0]) * d[..., 1] - (a[1] - p[..., 1]) * d[..., 0]) / den
            hit = (den != 0) & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
            normal = np.array([-e[1], e[0]]) / np.hypot(*e)
            cos = np.abs(d @ normal) / np.maximum(np.linalg.norm(d, axis=-1), 1e-12)
            n_walls += hit
            factor += np.where(hit, 1.0 / np.maximum(cos, self.config.min_cos_incidence), 0.0)
        return n_walls, factor

    def mean_power_db(self, pos_m) -> np.ndarray:
        """Received power (relative dB, before fading) of every sensor, ``(N, n_sensors)``."""
        n_walls, _ = self.wall_crossings(pos_m)
        return (-10 * self.config.path_loss_exponent * np.log10(self.true_ranges_m(pos_m))
                - self.config.wall_loss_db * n_walls)

    def multipath_m(self, pos_m) -> np.ndarray:
        """Position-dependent multipath range error of every sensor, ``(N, n_sensors)``, metres.

        ``σ √(2/J) Σ_j cos(k_j · p + φ_j)`` with ``k_j ~ N(0, I/ℓ²)``: a stationary
        Gaussian field with covariance ``σ² exp(−|Δp|² / 2ℓ²)`` (random Fourier features).
        """
        p = np.asarray(pos_m, float)
        J = self.wave_phase_rad.shape[1]
        arg = np.einsum("nd,sjd->nsj", p, self.wave_k_radpm) + self.wave_phase_rad
        return self.config.multipath_sigma_m * np.sqrt(2.0 / J) * np.cos(arg).sum(axis=-1)

    def systematic_range_error_m(self, pos_m) -> np.ndarray:
        """Range error every sensor would make at ``pos_m`` apart from white noise, ``(N, n_sensors)``."""
        _, factor = self.wall_crossings(pos_m)
        return self.sensor_bias_m[None] + self.config.wall_excess_m * factor + self.multipath_m(pos_m)

    def measure(self, pos_m, *, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Position fixes of tags at ``pos_m (N, 2)``: the set selection, ranges and 2-D solve.

        Returns
        -------
        fix_m
            Fixed positions, shape ``(N, 2)``, metres.
        set_id
            Set of each fix (bit masks), shape ``(N,)``.
        """
        pos_m = np.asarray(pos_m, float)
        used = select_sets(self.mean_power_db(pos_m), self.config.set_size, self.config.fading_db, rng=rng)
        r = (self.true_ranges_m(pos_m) + self.systematic_range_error_m(pos_m)
             + self.config.range_sigma_m * rng.standard_normal(used.shape))
        res = multilaterate(np.where(used, r, np.nan), self.sensor_xyz_m, dim=2, z_m=self.config.tag_height_m)
        if not np.all(res.ok):
            bad = int(np.flatnonzero(~res.ok)[0])
            raise RuntimeError(f"position fix failed at {pos_m[bad]} ({res.status_labels[bad]}); "
                               "check the facility layout (sensors collinear?)")
        return res.pos_m, set_id_from_mask(used)


def make_facility(config: FacilityConfig = FacilityConfig(), *, rng: np.random.Generator) -> Facility:
    """Draw a facility's systematic errors: per-sensor biases ``N(0, sensor_bias_sigma_m)`` and multipath fields."""
    n, J = config.n_sensors, config.n_multipath_waves
    bias = config.sensor_bias_sigma_m * rng.standard_normal(n)
    k = rng.standard_normal((n, J, 2)) / config.multipath_corr_m
    phase = rng.uniform(0.0, 2 * np.pi, (n, J))
    return Facility(config, bias, k, phase)


def select_sets(power_db: np.ndarray, set_size: int, fading_db: float, *, rng: np.random.Generator) -> np.ndarray:
    """Choose the sensor set of every measurement: the ``set_size`` strongest after fading.

    Parameters
    ----------
    power_db
        Mean received power, shape ``(N, n_sensors)``, dB; NaN = sensor unavailable.
    set_size
        Sensors per set. Rows with fewer available sensors use all of them.
    fading_db
        Standard deviation of the independent log-normal fading added per
        measurement and sensor, dB (0: deterministic, strongest mean power).

    Returns
    -------
    ndarray of bool, shape ``(N, n_sensors)``: sensors used.
    """
    power_db = np.asarray(power_db, float)
    if power_db.ndim != 2:
        raise ValueError(f"power_db must be (N, n_sensors), got {power_db.shape}")
    n = power_db.shape[1]
    if not 1 <= set_size <= n:
        raise ValueError(f"set_size must be in [1, {n}], got {set_size}")
    faded = power_db + fading_db * rng.standard_normal(power_db.shape) if fading_db > 0 else power_db.copy()
    faded = np.where(np.isfinite(faded), faded, -np.inf)
    top = np.argpartition(-faded, set_size - 1, axis=1)[:, :set_size]
    used = np.zeros(power_db.shape, bool)
    np.put_along_axis(used, top, True, axis=1)
    return used & np.isfinite(faded)


@dataclass(frozen=True)
class SetEmulation:
    """How sensor sets are emulated on measured two-way ranges (recordings without sensor sets).

    Per epoch, every anchor with a range gets an emulated received power
    ``−10 n log10(range)`` plus independent fading ``N(0, fading_db)``, and the
    ``set_size`` strongest anchors form the set (:func:`select_sets`, the rule the
    simulator uses). The fix is the 2-D least-squares position from that set's ranges
    at the tag's known height. The fading makes sets switch even for a static tag, as
    in the paper; ``fading_db = 0`` keeps the shortest ranges.

    Attributes
    ----------
    set_size
        Anchors per fix (paper: sets of ≥ 5 of 8 sensors).
    fading_db
        Fading standard deviation, dB.
    path_loss_exponent
        ``n``.
    """

    set_size: int = 5
    fading_db: float = 2.5
    path_loss_exponent: float = 2.0

    def __post_init__(self):
        if self.set_size < 3 or self.fading_db < 0 or self.path_loss_exponent <= 0:
            raise ValueError("set_size >= 3, fading_db >= 0 and path_loss_exponent > 0 are needed")


@dataclass(frozen=True)
class EmulatedFixes:
    """What :func:`emulate_set_fixes` made of a range log.

    Attributes
    ----------
    fixes
        The position fixes (:class:`~uwbwb.types.SetFixLog`).
    row
        Index of every fix's epoch in the range log, shape ``(n_fixes,)``.
    too_few_ranges
        Epochs with fewer than ``set_size`` ranges (no set, no fix).
    fix_failed
        Epochs with a set whose 2-D solve failed.
    """

    fixes: SetFixLog
    row: np.ndarray
    too_few_ranges: int
    fix_failed: int


def emulate_set_fixes(log: RangeLog, anchors_m, z_m: float, emulation: SetEmulation = SetEmulation(), *,
                      rng: np.random.Generator, truth_m: np.ndarray | None = None,
                      name: str = "fixes") -> EmulatedFixes:
    """Position fixes of one tag from sensor sets emulated on its ranges (see :class:`SetEmulation`).

    Parameters
    ----------
    log
        The tag's ranges, ``(T, n_anchors)``, metres.
    anchors_m
        Anchor positions, shape ``(n_anchors, 3)``, metres.
    z_m
        The tag's height, metres (from calibration material, never the scored truth).
    truth_m
        Optional true horizontal positions ``(T, 2)`` attached to the fixes (to fit or
        score the set-noise model); epochs without truth then give no fix. Every
        epoch draws its fading either way, so the random stream does not depend on it.
    name
        Name of the fix log.
    """
    r = log.range_m
    with np.errstate(divide="ignore", invalid="ignore"):
        power = -10 * emulation.path_loss_exponent * np.log10(np.where(r > 0, r, np.nan))
    used = select_sets(power, emulation.set_size, emulation.fading_db, rng=rng)
    enough = used.sum(axis=1) >= emulation.set_size
    too_few = int((~enough).sum())
    if truth_m is not None:
        enough &= np.all(np.isfinite(truth_m), axis=1)
    res = multilaterate(np.where(used, r, np.nan)[enough], anchors_m, dim=2, z_m=float(z_m),
                        min_anchors=emulation.set_size)
    row = np.flatnonzero(enough)[res.ok]
    fixes = SetFixLog(log.t_s[row], res.pos_m[res.ok], set_id_from_mask(used[row]), log.anchor_ids,
                      None if truth_m is None else truth_m[row], name)
    return EmulatedFixes(fixes, row, too_few, int((~res.ok).sum()))


def static_fixes(facility: Facility, xy_m, n: int, *, rng: np.random.Generator, name: str | None = None
                 ) -> SetFixLog:
    """``n`` fixes of a tag standing at ``xy_m`` (one calibration location; paper Fig. 3)."""
    xy = np.asarray(xy_m, float)
    truth = np.tile(xy, (n, 1))
    fix, sets = facility.measure(truth, rng=rng)
    t_s = np.arange(n) / facility.config.rate_hz
    return SetFixLog(t_s, fix, sets, facility.sensor_ids, truth,
                     name or f"static ({100 * xy[0]:.0f}, {100 * xy[1]:.0f}) cm")


def calibration_campaign(facility: Facility, *, rng: np.random.Generator) -> list[SetFixLog]:
    """The paper's calibration step: ``n_calibration`` fixes at each calibration location."""
    cfg = facility.config
    return [static_fixes(facility, xy, cfg.n_calibration, rng=rng, name=f"cal{i}")
            for i, xy in enumerate(cfg.calibration_xy_m)]


def track_truth(config: FacilityConfig, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
    """Fix times and true positions for one recording (constant speed, instantaneous turns).

    Returns
    -------
    t_s
        Fix times ``k / rate_hz`` while the tag is moving, shape ``(T,)``.
    truth_m
        Positions on the track, shape ``(T, 2)``.
    """
    if speed_mps <= 0:
        raise ValueError(f"speed_mps must be positive, got {speed_mps}")
    L = config.track_length_m
    duration_s = config.n_legs * L / speed_mps
    t_s = np.arange(0.0, duration_s + 1e-9, 1.0 / config.rate_hz)
    s = speed_mps * t_s
    leg = np.minimum(np.floor(s / L), config.n_legs - 1)
    along = s - leg * L
    along = np.where(leg % 2 == 0, along, L - along)                 # odd legs come back
    a, b = np.asarray(config.track_start_xy_m, float), np.asarray(config.track_end_xy_m, float)
    return t_s, a + along[:, None] / L * (b - a)


def track_recording(facility: Facility, speed_mps: float, *, rng: np.random.Generator,
                    name: str | None = None) -> SetFixLog:
    """One recording along the test track at ``speed_mps`` (paper section II-D)."""
    t_s, truth = track_truth(facility.config, speed_mps)
    fix, sets = facility.measure(truth, rng=rng)
    return SetFixLog(t_s, fix, sets, facility.sensor_ids, truth, name or f"{100 * speed_mps:.0f} cm/s")


def table1_recordings(facility: Facility, *, rng: np.random.Generator) -> list[SetFixLog]:
    """The five recordings of Table I, named ``"rec1"`` … ``"rec5"``."""
    return [track_recording(facility, v, rng=rng, name=f"rec{i + 1}")
            for i, v in enumerate(facility.config.speeds_mps)]
