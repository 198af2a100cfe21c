"""Chirps of independent ultrasonic beacons heard by a moving receiver (paper 003).

Each beacon of a :class:`~uwbwb.models.doppler.DopplerModel` emits a 250 µs chirp
every ``P_i`` seconds from its own random phase (the beacons are not
synchronised). A chirp emitted at ``t_e`` reaches the receiver at the ``t_a`` that
solves ``t_a = t_e + ‖X(t_a) − T_i‖ / v_s`` — the propagation delay to the
*moving* receiver, solved by fixed-point iteration. The receiver's detections
then suffer:

* timing jitter ``N(0, σ_t²)`` per arrival (``model.sigma_t_s``);
* missed chirps (independently, probability ``p_miss``);
* spurious detections (reflections, noise): a Poisson process of rate
  ``spurious_rate_hz``;
* collisions: a chirp arriving while another is still being received
  (within ``chirp_s``) is not detected separately.

The simulator returns the raw arrival times; the receiver's assignment of chirps
to beacons by periodicity, and hence the measured ΔP, is
:func:`uwbwb.filters.doppler.assign_chirps` — the same code that would process a
real log. Everything the paper averages over (each ΔP spans a whole period, beacons
are asynchronous) is therefore present, not idealised away.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.doppler import DopplerModel
from ..types import Trajectory
from ..validate import number, probability

__all__ = ["LineTrack", "LoopTrack", "rectangle_track", "ChirpRecording", "simulate_chirps"]


@dataclass(frozen=True)
class LineTrack:
    """Straight line at constant velocity: ``X(t) = pos0 + vel t``."""

    pos0_m: tuple[float, float, float]
    vel_mps: tuple[float, float, float]

    def pos_m(self, t_s) -> np.ndarray:
        t = np.asarray(t_s, float)[..., None]
        return np.asarray(self.pos0_m, float) + t * np.asarray(self.vel_mps, float)

    def vel(self, t_s) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.vel_mps, float), np.shape(t_s) + (3,)).copy()


@dataclass(frozen=True)
class LoopTrack:
    """A closed horizontal path walked at constant speed, sampled densely along its length.

    Attributes
    ----------
    points_m
        Dense points of one lap, shape ``(M, 3)`` (the last point connects to the first).
    speed_mps
        Walking speed.
    s0_m
        Distance along the path at ``t = 0``.
    """

    points_m: np.ndarray
    speed_mps: float
    s0_m: float = 0.0

    def __post_init__(self):
        p = np.array(self.points_m, float)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 3:
            raise ValueError(f"points_m must have shape (M >= 3, 3), got {p.shape}")
        if not self.speed_mps > 0:
            raise ValueError(f"speed_mps must be > 0, got {self.speed_mps!r}")
        closed = np.vstack([p, p[:1]])
        seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        object.__setattr__(self, "points_m", closed)
        object.__setattr__(self, "_s", np.concatenate([[0.0], np.cumsum(seg)]))
        tangent = np.diff(closed, axis=0) / seg[:, None]
        object.__setattr__(self, "_tangent", tangent)

    @property
    def length_m(self) -> float:
        return float(self._s[-1])

    def distance_m(self, t_s) -> np.ndarray:
        return np.mod(self.s0_m + self.speed_mps * np.asarray(t_s, float), self.length_m)

    def pos_m(self, t_s) -> np.ndarray:
        s = self.distance_m(t_s)
        return np.stack([np.interp(s, self._s, self.points_m[:, k]) for k in range(3)], axis=-1)

    def vel(self, t_s) -> np.ndarray:
        s = self.distance_m(t_s)
        mid = 0.5 * (self._s[1:] + self._s[:-1])
        v = np.stack([np.interp(s, mid, self._tangent[:, k], period=self.length_m) for k in range(3)], axis=-1)
        return self.speed_mps * v / np.linalg.norm(v, axis=-1, keepdims=True)

    def time_at(self, s_m: float, after_s: float = 0.0) -> float:
        """First time ``>= after_s`` at which the walker is at distance ``s_m`` along the lap."""
        t = (np.mod(s_m - self.s0_m, self.length_m)) / self.speed_mps
        lap = self.length_m / self.speed_mps
        return float(t + lap * max(0.0, np.ceil((after_s - t) / lap)))


def rectangle_track(x_m=(-1.5, 1.5), y_m=(-1.0, 1.0), z_m: float = 0.0, *, corner_radius_m: float = 0.3,
                    speed_mps: float | None = None, corner_interval_s: float = 3.0, start: str = "top-left",
                    step_m: float = 0.002) -> tuple[LoopTrack, dict[str, float]]:
    """A rectangle with rounded corners walked clockwise (seen from above, y up), as in Fig 6.

    Parameters
    ----------
    speed_mps
        Walking speed; None chooses the speed that takes ``corner_interval_s`` from the
        bottom-left to the top-left corner (the two snapshots of Fig 6, 3 s apart).
    start
        Corner the walk starts at.

    Returns
    -------
    track, corners
        The track and the distance along the lap (m) of each corner's apex
        (``"top-left"``, ``"top-right"``, ``"bottom-right"``, ``"bottom-left"``).
    """
    x0, x1 = x_m
    y0, y1 = y_m
    r = corner_radius_m
    if not (x1 - x0 > 2 * r and y1 - y0 > 2 * r and r > 0):
        raise ValueError("rectangle too small for its corner radius")
    # clockwise from the top-left corner: centres of the corner arcs and their start angles
    centres = [(x0 + r, y1 - r, np.pi), (x1 - r, y1 - r, np.pi / 2), (x1 - r, y0 + r, 0.0),
               (x0 + r, y0 + r, -np.pi / 2)]
    pts, apex = [], {}
    names = ["top-left", "top-right", "bottom-right", "bottom-left"]
    s = 0.0
    for k, (cx, cy, a0) in enumerate(centres):
        n_arc = max(8, int(np.ceil(np.pi / 2 * r / step_m)))
        ang = a0 - np.linspace(0.0, np.pi / 2, n_arc, endpoint=False)      # clockwise
        apex[names[k]] = s + np.pi / 4 * r
        pts.append(np.stack([cx + r * np.cos(ang), cy + r * np.sin(ang)], axis=1))
        s += np.pi / 2 * r
        nx_, ny_ = centres[(k + 1) % 4][:2]
        end = np.array([cx + r * np.cos(a0 - np.pi / 2), cy + r * np.sin(a0 - np.pi / 2)])
        nxt_a0 = centres[(k + 1) % 4][2]
        nxt = np.array([nx_ + r * np.cos(nxt_a0), ny_ + r * np.sin(nxt_a0)])
        L = float(np.linalg.norm(nxt - end))
        n_line = max(2, int(np.ceil(L / step_m)))
        f = np.linspace(0.0, 1.0, n_line, endpoint=False)[:, None]
        pts.append(end + f * (nxt - end))
        s += L
    xy = np.vstack(pts)
    points = np.column_stack([xy, np.full(len(xy), z_m)])
    side = (y1 - y0) - 2 * r + np.pi / 2 * r      # bottom-left apex to top-left apex
    speed = side / corner_interval_s if speed_mps is None else speed_mps
    track = LoopTrack(points, speed, apex[start])
    apex = {k: float(v) for k, v in apex.items()}
    return track, apex


@dataclass(frozen=True)
class ChirpRecording:
    """One simulated recording: raw arrival times and the truth behind them.

    Attributes
    ----------
    t_s
        Detected arrival times (jittered), shape ``(N,)``, strictly increasing.
    source
        True beacon of each detection, shape ``(N,)``; −1 for a spurious one.
    emit_s
        True emission time of each detection, shape ``(N,)``; NaN for spurious ones.
    truth
        Receiver position and velocity at the detections (:class:`~uwbwb.types.Trajectory`).
    phase_s
        Emission phase of each beacon (first emission time), shape ``(n,)`` — the
        beacon-clock model of section 5, known exactly in simulation.
    counts
        What happened: emitted, missed, collided, spurious, detected.
    """

    t_s: np.ndarray
    source: np.ndarray
    emit_s: np.ndarray
    truth: Trajectory
    phase_s: np.ndarray
    counts: dict


def _arrival_times(model: DopplerModel, track, beacon: np.ndarray, t_e: np.ndarray, iterations: int = 6):
    T = model.beacons.pos_m[beacon]
    t_a = t_e + np.linalg.norm(track.pos_m(t_e) - T, axis=-1) / model.v_s_mps
    for _ in range(iterations):        # contraction factor |V| / v_s < 0.01
        t_a = t_e + np.linalg.norm(track.pos_m(t_a) - T, axis=-1) / model.v_s_mps
    return t_a


def simulate_chirps(model: DopplerModel, track, duration_s: float, *, rng: np.random.Generator,
                    p_miss: float = 0.05, spurious_rate_hz: float = 0.5, chirp_s: float = 250e-6,
                    jitter: bool = True, phase_s=None) -> ChirpRecording:
    """Simulate the detections of a receiver following ``track`` for ``duration_s`` seconds.

    Parameters
    ----------
    model
        Beacons, periods, speed of sound and timing jitter ``sigma_t_s``.
    track
        Object with ``pos_m(t)`` and ``vel(t)`` (``(..., 3)`` for times ``(...)``).
    p_miss
        Probability that a chirp is not detected.
    spurious_rate_hz
        Rate of spurious detections.
    chirp_s
        Chirp length; a chirp arriving within ``chirp_s`` of the previous detection is lost.
    jitter
        Apply the timing jitter (False: exact arrival times, for tests).
    phase_s
        Emission phases, shape ``(n,)``; default uniform in ``[0, P_i)``.
    """
    if not isinstance(model, DopplerModel):
        raise ValueError(f"model must be a DopplerModel, got {type(model).__name__}")
    duration_s = number("duration_s", duration_s, minimum=0.0, strict_minimum=True)
    p_miss = probability("p_miss", p_miss, open_interval=False)
    if p_miss >= 1.0:
        raise ValueError(f"p_miss must be a number in [0, 1), got {p_miss!r}")
    spurious_rate_hz = number("spurious_rate_hz", spurious_rate_hz, minimum=0.0)
    chirp_s = number("chirp_s", chirp_s, minimum=0.0)
    P = model.period_s
    phase = rng.uniform(0.0, P) if phase_s is None else np.asarray(phase_s, float)
    if phase.shape != P.shape or not np.all(np.isfinite(phase)):
        raise ValueError(f"phase_s must hold one finite phase per beacon, shape {P.shape}, got {phase.shape}")
    beacons, emits = [], []
    for i, (p, ph) in enumerate(zip(P, phase)):
        t_e = ph + p * np.arange(int(np.ceil((duration_s - ph) / p)) + 1)
        beacons.append(np.full(t_e.size, i))
        emits.append(t_e)
    beacon, t_e = np.concatenate(beacons), np.concatenate(emits)
    t_a = _arrival_times(model, track, beacon, t_e)
    if jitter and model.sigma_t_s > 0:
        t_a = t_a + rng.normal(0.0, model.sigma_t_s, t_a.size)
    n_emitted = int(t_a.size)
    keep = (t_a >= 0) & (t_a <= duration_s)
    n_emitted = int(keep.sum())
    missed = rng.random(t_a.size) < p_miss
    keep_det = keep & ~missed
    n_spur = int(rng.poisson(spurious_rate_hz * duration_s))
    t_sp = rng.uniform(0.0, duration_s, n_spur)
    t_all = np.concatenate([t_a[keep_det], t_sp])
    src = np.concatenate([beacon[keep_det], np.full(n_spur, -1)])
    emit = np.concatenate([t_e[keep_det], np.full(n_spur, np.nan)])
    order = np.argsort(t_all, kind="stable")
    t_all, src, emit = t_all[order], src[order], emit[order]
    # collisions: the receiver is busy for chirp_s after each detection
    detected = np.ones(t_all.size, bool)
    last = -np.inf
    for k, t in enumerate(t_all):
        if t - last < chirp_s:
            detected[k] = False
        else:
            last = t
    t_all, src, emit = t_all[detected], src[detected], emit[detected]
    truth = Trajectory(t_all, track.pos_m(t_all), track.vel(t_all), name="truth")
    counts = {"emitted": n_emitted, "missed": int((keep & missed).sum()), "spurious": n_spur,
              "collided": int((~detected).sum()), "detected": int(t_all.size)}
    return ChirpRecording(t_all, src, emit, truth, phase, counts)
