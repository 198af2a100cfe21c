"""Office-walking and AGV scenarios of De Angelis' thesis (T4F / DWM1000 system), re-created.

The thesis' raw data are not public; this simulator rebuilds the two settings
from what the text states (an office walk with two tags, AGV runs in a cluttered
hall, DWM1000 ranging within ±10 cm) and, where it states nothing, from
assumptions. The speeds are such assumptions: the thesis gives none, and the
cruise speeds were set equal to its Table 1 random-walk σ (0.83 and 1 m/s), so a
random-walk σ calibrated on these runs is a calibration *target*, not a
reproduction. Rooms, obstacles, their biases and body shadowing are assumptions too:

* **office** — a person walks a curved loop at about 0.8 m/s through a
  cluttered office (walls, desks, cabinets), carrying two tags: tag 1 on the
  head (above the body), tag 2 on the chest (the body blocks anchors behind
  the walker).
* **agv1 / agv2** — an AGV drives straight legs joined by tight turns at about
  1 m/s through an open factory hall with metal machines; tag 1 on a mast,
  tag 2 low on the deck (blocked by machines and pallets more often).

Motion. The target's planar motion is a :class:`~uwbwb.models.motion.RandomForce`
model — the same object the EKF uses — steered along a path: at every fine
step (``sim_rate_hz``) a pursuit command ``u = (v_cmd − v) / tau_s`` (clipped to
``max_acc_mps2``) drives the white-acceleration model
``x_{k+1} = F x_k + G u_k + w_k``, ``w_k ~ N(0, Q)``, where ``v_cmd`` points at a
look-ahead point on the path with the path's speed profile (slower in turns).
A walker's tags also sway sideways at the gait frequency.

Ranging (DWM1000-like two-way ranging at ``rate_hz`` per tag, tags interleaved
in time as in TDMA): line of sight ranges have white noise ``sigma_los_m``
(±10 cm accuracy read as a 2σ bound: σ = 5 cm). A link whose straight line
crosses an obstacle lower edge to upper edge (2-D segment crossing, below the
obstacle's height at the crossing) is NLOS: it gains the obstacle's bias
(positive: the signal travels longer or slower), an exponential excess
(mean ``nlos_excess_mean_m``) and noise ``sigma_nlos_m``; a tag worn on the body
is NLOS towards anchors more than ``body_shadow_angle_deg`` away from the
walking direction, with bias ``body_bias_m``. Ranges drop out with probability
``p_missing_los`` / ``p_missing_nlos``.

"Device output" (the thesis' raw T4F positions). The application's own
positions are not documented in the thesis; :func:`device_output` plays that
role with what such firmware typically does: per epoch, the ``n_nearest``
anchors with the smallest measured ranges, a closed-form unweighted linear
least-squares fix (:func:`uwbwb.geometry.linear_multilaterate`) at the tag's
nominal height, no outlier handling and no tracking.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numba
import numpy as np

from .. import geometry, validate
from ..models.motion import RandomForce
from ..models import ranging
from ..types import Anchors, RangeLog, Recording, Trajectory

__all__ = ["Obstacle", "TagMount", "WalkScenario", "WalkTruth", "office", "agv", "SCENARIOS", "scenario",
           "path_points", "steer", "simulate_walk", "device_output"]


@dataclass(frozen=True)
class Obstacle:
    """A vertical wall segment from ``(x0_m, y0_m)`` to ``(x1_m, y1_m)``, ``height_m`` tall.

    A link crossing it below ``height_m`` gains ``bias_m`` (metres, positive).
    """

    x0_m: float
    y0_m: float
    x1_m: float
    y1_m: float
    height_m: float
    bias_m: float
    label: str = ""


def _box(x0, y0, x1, y1, height_m, bias_m, label) -> tuple[Obstacle, ...]:
    """The four sides of an axis-aligned box, each with half the crossing bias (a link crosses two)."""
    b = bias_m / 2
    return (Obstacle(x0, y0, x1, y0, height_m, b, label), Obstacle(x1, y0, x1, y1, height_m, b, label),
            Obstacle(x1, y1, x0, y1, height_m, b, label), Obstacle(x0, y1, x0, y0, height_m, b, label))


@dataclass(frozen=True)
class TagMount:
    """A tag on the target.

    Attributes
    ----------
    tag_id
        Identifier (``"tag1"``, ``"tag2"``).
    forward_m, left_m
        Offset from the target's reference point in its heading frame, metres.
    height_m
        Height above the floor, metres (also the nominal height of :func:`device_output`).
    body_shadow
        Whether the carrier's body blocks anchors behind the tag.
    """

    tag_id: str
    forward_m: float
    left_m: float
    height_m: float
    body_shadow: bool = False


@dataclass(frozen=True)
class WalkScenario:
    """Everything that defines one simulated acquisition (SI units).

    Attributes
    ----------
    name
        ``"office"``, ``"agv1"``, ``"agv2"`` or your own.
    anchor_pos_m
        Anchor positions, ``((x, y, z), ...)``, metres.
    waypoints_m
        Corners of the closed path ``((x, y), ...)``, metres; the loop is
        driven ``n_laps`` times (fractional allowed) or until ``duration_s``.
    corner_radius_m
        Radius of the circular arcs that round every corner of the path (smaller
        where a leg is too short to hold it).
    speed_mps
        Cruise speed; in turns ``speed / (1 + turn_slowdown_m · curvature)``.
    turn_slowdown_m
        How much curvature slows the target (m).
    duration_s
        Length of the acquisition, seconds.
    rate_hz
        Location rate per tag (TWR rounds to all anchors), Hz.
    tags
        Tag mounts.
    obstacles
        Walls, furniture, machines.
    psd_acc_m2ps3
        PSD of the random acceleration of the target (the RF model's ``q``), m²/s³; the model
        itself is :attr:`motion` (:meth:`with_motion` sets it from a model object).
    tau_s, max_acc_mps2, lookahead_m
        Path-following: velocity time constant, acceleration limit, look-ahead distance.
    sway_m, sway_hz
        Lateral gait sway of the tags (amplitude, frequency); 0 for vehicles.
    sigma_los_m, sigma_nlos_m
        Range noise standard deviation in LOS / NLOS, metres.
    nlos_excess_mean_m
        Mean of the exponential extra delay on an NLOS link, metres.
    body_bias_m, body_shadow_angle_deg
        Bias of a body-blocked link and the angle from the heading beyond which
        the body blocks.
    p_missing_los, p_missing_nlos
        Probability that a range is missing.
    sim_rate_hz
        Rate of the motion simulation (truth), Hz.
    """

    name: str
    anchor_pos_m: tuple
    waypoints_m: tuple
    corner_radius_m: float
    speed_mps: float
    turn_slowdown_m: float
    duration_s: float
    rate_hz: float
    tags: tuple[TagMount, ...]
    obstacles: tuple[Obstacle, ...] = ()
    psd_acc_m2ps3: float = 0.05
    tau_s: float = 0.6
    max_acc_mps2: float = 1.5
    lookahead_m: float = 0.8
    sway_m: float = 0.0
    sway_hz: float = 0.9
    sigma_los_m: float = 0.05
    sigma_nlos_m: float = 0.10
    nlos_excess_mean_m: float = 0.15
    body_bias_m: float = 0.30
    body_shadow_angle_deg: float = 120.0
    p_missing_los: float = 0.02
    p_missing_nlos: float = 0.10
    sim_rate_hz: float = 100.0

    def __post_init__(self):
        validate.points(f"{self.name}: anchor_pos_m", self.anchor_pos_m, minimum=4)
        w = np.asarray(self.waypoints_m, float)
        if w.ndim != 2 or w.shape[1] != 2 or w.shape[0] < 3:
            raise ValueError(f"{self.name}: waypoints_m must be (n >= 3, 2), got {w.shape}")
        if np.any(np.linalg.norm(w - np.roll(w, -1, axis=0), axis=1) < 1e-6):
            raise ValueError(f"{self.name}: consecutive waypoints (last to first included) must differ")
        positive = ("speed_mps", "duration_s", "rate_hz", "tau_s", "max_acc_mps2", "lookahead_m",
                    "sigma_los_m", "sigma_nlos_m", "sim_rate_hz")
        bad = [k for k in positive if not getattr(self, k) > 0]
        if bad:
            raise ValueError(f"{self.name}: {bad} must be positive")
        if min(self.corner_radius_m, self.turn_slowdown_m, self.psd_acc_m2ps3, self.sway_m,
               self.nlos_excess_mean_m, self.body_bias_m) < 0:
            raise ValueError(f"{self.name}: radii, slowdown, PSD, sway, excess and body bias must be >= 0")
        if not (0 <= self.p_missing_los <= 1 and 0 <= self.p_missing_nlos <= 1):
            raise ValueError(f"{self.name}: missing probabilities must be in [0, 1]")
        if not self.tags or len({t.tag_id for t in self.tags}) != len(self.tags):
            raise ValueError(f"{self.name}: needs at least one tag and unique tag ids")

    @property
    def anchors(self) -> Anchors:
        return Anchors(tuple(f"A{i + 1}" for i in range(len(self.anchor_pos_m))), np.asarray(self.anchor_pos_m))

    @property
    def tag_ids(self) -> tuple[str, ...]:
        return tuple(t.tag_id for t in self.tags)

    @property
    def motion(self) -> RandomForce:
        """The motion model that moves the target (shared with the estimators)."""
        return RandomForce(self.psd_acc_m2ps3, dim=2)

    def with_motion(self, motion: RandomForce | None) -> "WalkScenario":
        """This scenario with the target moved by ``motion`` (a 2-D :class:`RandomForce`; None: unchanged).

        The scenario keeps the model's PSD in ``psd_acc_m2ps3``, so ``with_motion(m).motion == m``.
        """
        if motion is None:
            return self
        if not isinstance(motion, RandomForce) or motion.dim != 2:
            raise ValueError(f"{self.name}: motion must be a 2-D RandomForce, got {motion!r}")
        return replace(self, psd_acc_m2ps3=motion.psd)


_OFFICE_ANCHORS = ((0.2, 0.2, 2.6), (6.0, 0.1, 2.4), (11.8, 0.2, 2.6), (11.8, 7.8, 2.4), (6.0, 7.9, 2.6),
                   (0.2, 7.8, 2.4))
_OFFICE_OBSTACLES = (
    Obstacle(4.0, 0.0, 4.0, 2.6, 3.0, 0.35, "partition"),
    Obstacle(8.5, 8.0, 8.5, 5.6, 3.0, 0.35, "partition"),
    *_box(1.5, 3.2, 3.3, 4.6, 0.75, 0.10, "desk"),
    *_box(5.2, 3.0, 7.2, 4.8, 0.75, 0.10, "desk"),
    *_box(9.6, 2.0, 10.6, 3.2, 2.0, 0.30, "cabinet"),
    *_box(0.1, 6.4, 1.1, 7.9, 2.0, 0.30, "shelf"),
)


def office(**changes) -> WalkScenario:
    """The office walk: 12 × 8 m room, 6 ceiling anchors, a curved loop at ~0.8 m/s, two worn tags."""
    base = WalkScenario(
        name="office", anchor_pos_m=_OFFICE_ANCHORS,
        waypoints_m=((1.2, 1.4), (5.0, 1.8), (10.2, 1.2), (11.0, 4.4), (8.4, 5.0), (6.2, 6.4), (2.6, 6.0),
                     (0.9, 4.0)),
        corner_radius_m=1.3, speed_mps=0.9, turn_slowdown_m=0.2, duration_s=120.0, rate_hz=10.0,
        tags=(TagMount("tag1", 0.0, 0.0, 1.80), TagMount("tag2", 0.15, 0.0, 1.30, body_shadow=True)),
        obstacles=_OFFICE_OBSTACLES, psd_acc_m2ps3=0.08, tau_s=0.6, max_acc_mps2=1.5, lookahead_m=0.8,
        sway_m=0.03, sway_hz=0.9)
    return replace(base, **changes)


_AGV_ANCHORS = ((0.0, 0.0, 3.0), (12.0, -0.5, 3.2), (24.0, 0.0, 3.0), (24.5, 8.0, 3.2), (24.0, 16.0, 3.0),
                (12.0, 16.5, 3.2), (0.0, 16.0, 3.0), (-0.5, 8.0, 3.2))
_AGV_OBSTACLES = (
    *_box(5.0, 5.5, 9.0, 10.5, 2.5, 0.50, "machine"),
    *_box(14.5, 5.0, 19.0, 7.0, 2.5, 0.50, "machine"),
    *_box(15.0, 10.0, 17.0, 12.0, 1.2, 0.25, "pallets"),
    *_box(2.0, 13.0, 4.0, 14.5, 1.2, 0.25, "pallets"),
)


def agv(acquisition: int = 1, **changes) -> WalkScenario:
    """An AGV acquisition in a 24 × 16 m hall with 8 anchors: straight legs, tight turns, ~1 m/s.

    ``acquisition=1``: a loop around the first machine and through the aisle;
    ``acquisition=2``: a longer loop around both machines.
    """
    paths = {1: ((2.5, 2.5), (11.5, 2.5), (11.5, 12.5), (2.5, 12.5)),
             2: ((2.5, 2.5), (21.5, 2.5), (21.5, 8.5), (12.0, 8.5), (12.0, 13.5), (2.5, 13.5))}
    if acquisition not in paths:
        raise ValueError(f"agv acquisition must be 1 or 2, got {acquisition!r}")
    base = WalkScenario(
        name=f"agv{acquisition}", anchor_pos_m=_AGV_ANCHORS, waypoints_m=paths[acquisition],
        corner_radius_m=0.6, speed_mps=1.0, turn_slowdown_m=0.6, duration_s=120.0, rate_hz=10.0,
        tags=(TagMount("tag1", 0.3, 0.0, 1.50), TagMount("tag2", -0.4, 0.0, 0.40)),
        obstacles=_AGV_OBSTACLES, psd_acc_m2ps3=0.005, tau_s=0.8, max_acc_mps2=0.6, lookahead_m=1.0,
        sway_m=0.0, p_missing_nlos=0.15)
    return replace(base, **changes)


#: Scenario factories by name.
SCENARIOS = {"office": office, "agv1": lambda **kw: agv(1, **kw), "agv2": lambda **kw: agv(2, **kw)}


def scenario(name: str, **changes) -> WalkScenario:
    """Scenario ``"office" | "agv1" | "agv2"`` with optional field changes."""
    try:
        return SCENARIOS[name](**changes)
    except KeyError:
        raise ValueError(f"unknown scenario {name!r}; choose one of {list(SCENARIOS)}") from None


# --------------------------------------------------------------------------- path


def path_points(waypoints_m, corner_radius_m: float, step_m: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Densely sampled closed path with every corner rounded by a circular arc.

    Returns
    -------
    xy_m : ndarray, shape ``(N, 2)``
        Points ``step_m`` apart along the loop (first point not repeated).
    curvature_1pm : ndarray, shape ``(N,)``
        Unsigned curvature at each point, 1/m.
    """
    W = np.asarray(waypoints_m, float)
    n = len(W)
    pieces = []
    for i in range(n):
        A, B, C = W[i - 1], W[i], W[(i + 1) % n]
        u1, u2 = (A - B) / np.linalg.norm(A - B), (C - B) / np.linalg.norm(C - B)
        half = 0.5 * np.arccos(np.clip(u1 @ u2, -1.0, 1.0))
        if corner_radius_m == 0 or np.isclose(half, np.pi / 2):
            pieces.append(B[None])
            continue
        t = min(corner_radius_m / np.tan(half), 0.45 * np.linalg.norm(A - B), 0.45 * np.linalg.norm(C - B))
        radius = t * np.tan(half)
        T1, T2 = B + u1 * t, B + u2 * t
        bis = (u1 + u2) / np.linalg.norm(u1 + u2)
        centre = B + bis * radius / np.sin(half)
        a1 = np.arctan2(*(T1 - centre)[::-1])
        a2 = np.arctan2(*(T2 - centre)[::-1])
        da = (a2 - a1 + np.pi) % (2 * np.pi) - np.pi
        k = max(int(np.ceil(abs(da) * radius / step_m)), 2)
        ang = a1 + da * np.linspace(0, 1, k)
        pieces.append(centre + radius * np.column_stack([np.cos(ang), np.sin(ang)]))
    poly = np.vstack(pieces + [pieces[0][:1]])
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    s_new = np.arange(0.0, s[-1], step_m)
    xy = np.column_stack([np.interp(s_new, s, poly[:, 0]), np.interp(s_new, s, poly[:, 1])])
    d = np.diff(np.vstack([xy, xy[:1]]), axis=0)
    heading = np.arctan2(d[:, 1], d[:, 0])
    turn = (np.roll(heading, -1) - heading + np.pi) % (2 * np.pi) - np.pi
    curvature = np.abs(turn) / step_m
    return xy, curvature


def steer(config: WalkScenario, *, rng: np.random.Generator,
          motion: RandomForce | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Simulate the target's reference point along the path with the RF motion model.

    ``motion`` (a 2-D :class:`~uwbwb.models.motion.RandomForce`) replaces the scenario's
    model, :attr:`WalkScenario.motion`; the same numbers as ``config.with_motion(motion)``.

    Returns
    -------
    t_s : ndarray, shape ``(T,)``
        Simulation times at ``sim_rate_hz``, seconds.
    x : ndarray, shape ``(T, 4)``
        RF states ``[x, y, vx, vy]`` (m, m/s).
    """
    config = config.with_motion(motion)
    motion = config.motion
    dt = 1.0 / config.sim_rate_hz
    t_s = np.arange(0.0, config.duration_s + 1e-9, dt)
    step = 0.02
    xy, kappa = path_points(config.waypoints_m, config.corner_radius_m, step_m=step)
    N = len(xy)
    # speed profile: slower in turns, looking 1.5 m ahead so the target brakes before a corner
    v_path = config.speed_mps / (1.0 + config.turn_slowdown_m * kappa)
    ahead = int(1.5 / step)
    v_path = np.min(np.stack([np.roll(v_path, -k) for k in range(0, ahead, 5)]), axis=0)
    F, G = motion.F(dt), motion.G(dt)
    noise = np.einsum("ij,tj->ti", motion.Q_sqrt(dt), rng.standard_normal((t_s.size, 4)))
    look = int(round(config.lookahead_m / step))
    window = int(round(2.0 / step))
    x = np.empty((t_s.size, 4))
    heading0 = xy[1] - xy[0]
    x[0] = np.r_[xy[0], 0.2 * config.speed_mps * heading0 / np.linalg.norm(heading0)]
    _steer_loop(x, xy, v_path, noise, F, G, look, window, float(config.tau_s), float(config.max_acc_mps2))
    return t_s, x


@numba.njit(cache=True, nogil=True)
def _steer_loop(x, xy, v_path, noise, F, G, look, window, tau_s, max_acc_mps2):
    """The pursuit loop of :func:`steer`, in place on ``x`` (row 0 given): at each step the nearest path point
    among the ``window`` from the last one, the command towards the point ``look`` further on at the path's speed,
    clipped to ``max_acc_mps2``, then ``x_{k+1} = F x_k + G u + noise_k``. Its definition, the same loop in
    NumPy, is the declared twin (:mod:`uwbwb.filters.twins`)."""
    N = xy.shape[0]
    i = 0
    u = np.empty(2)
    for k in range(x.shape[0] - 1):
        px, py = x[k, 0], x[k, 1]
        best, best_d2 = i, np.inf
        for c in range(window):
            j = (i + c) % N
            ex, ey = xy[j, 0] - px, xy[j, 1] - py
            d2 = ex * ex + ey * ey
            if d2 < best_d2:
                best, best_d2 = j, d2
        i = best
        dx, dy = xy[(i + look) % N, 0] - px, xy[(i + look) % N, 1] - py
        n = max(np.sqrt(dx * dx + dy * dy), 1e-9)
        u[0] = (v_path[i] * dx / n - x[k, 2]) / tau_s
        u[1] = (v_path[i] * dy / n - x[k, 3]) / tau_s
        a = np.sqrt(u[0] * u[0] + u[1] * u[1])
        if a > max_acc_mps2:
            s = max_acc_mps2 / a
            u[0] *= s
            u[1] *= s
        for r in range(4):
            fx = F[r, 0] * x[k, 0]
            for c in range(1, 4):
                fx += F[r, c] * x[k, c]
            x[k + 1, r] = (fx + (G[r, 0] * u[0] + G[r, 1] * u[1])) + noise[k, r]


# --------------------------------------------------------------------------- ranging


def _crossings(tag_m: np.ndarray, anchor_m: np.ndarray, obstacles: tuple[Obstacle, ...]) -> np.ndarray:
    """Bias from obstacles crossed by each tag–anchor link, shape ``(T, n_anchors)``, metres.

    ``tag_m`` (T, 3), ``anchor_m`` (n, 3).
    """
    if not obstacles:
        return np.zeros((tag_m.shape[0], anchor_m.shape[0]))
    O = np.array([[o.x0_m, o.y0_m, o.x1_m, o.y1_m, o.height_m, o.bias_m] for o in obstacles])
    P = tag_m[:, None, None, :2]                             # (T, 1, 1, 2)
    D = anchor_m[None, :, None, :2] - P                      # (T, n, 1, 2)
    Q0 = O[None, None, :, 0:2]
    E = O[None, None, :, 2:4] - Q0                           # (1, 1, m, 2)

    def cross(a, b):
        return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]

    den = cross(D, E)
    parallel = np.abs(den) <= 1e-12
    den = np.where(parallel, 1.0, den)
    lam = np.where(parallel, -1.0, cross(Q0 - P, E) / den)   # along the link (parallel: no crossing)
    mu = cross(Q0 - P, D) / den                              # along the obstacle
    z_at = tag_m[:, None, None, 2] + lam * (anchor_m[None, :, None, 2] - tag_m[:, None, None, 2])
    hit = (lam > 0) & (lam < 1) & (mu >= 0) & (mu <= 1) & (z_at < O[None, None, :, 4])
    return np.sum(np.where(hit, O[None, None, :, 5], 0.0), axis=-1)


@dataclass(frozen=True)
class WalkTruth:
    """What the simulator knows and a real recording would not.

    Attributes
    ----------
    config
        The scenario.
    reference
        The target's reference point (walker's feet / AGV centre), at ``sim_rate_hz``.
    nlos
        Per tag: bool ``(T, n_anchors)`` at that tag's ranging epochs, True where the link was NLOS.
    range_error_m
        Per tag: measured − true range ``(T, n_anchors)`` (NaN where missing), metres.
    true_range_m
        Per tag: true ranges ``(T, n_anchors)`` at the ranging epochs, metres.
    """

    config: WalkScenario
    reference: Trajectory
    nlos: dict = field(repr=False)
    range_error_m: dict = field(repr=False)
    true_range_m: dict = field(repr=False)


def _tag_positions(config, mount, t_s, ref_t, states):
    """Tag positions ``(T, 3)`` at ``t_s`` from the reference states and the mount."""
    x = np.interp(t_s, ref_t, states[:, 0])
    y = np.interp(t_s, ref_t, states[:, 1])
    vx = np.interp(t_s, ref_t, states[:, 2])
    vy = np.interp(t_s, ref_t, states[:, 3])
    psi = np.arctan2(vy, vx)
    c, s = np.cos(psi), np.sin(psi)
    left = mount.left_m + config.sway_m * np.sin(2 * np.pi * config.sway_hz * t_s)
    px = x + c * mount.forward_m - s * left
    py = y + s * mount.forward_m + c * left
    return np.column_stack([px, py, np.full_like(px, mount.height_m)]), psi


def simulate_walk(config: WalkScenario, *, rng: np.random.Generator,
                  motion: RandomForce | None = None) -> tuple[Recording, WalkTruth]:
    """One acquisition: ranges of every tag to every anchor, and truth.

    ``motion`` (a 2-D :class:`~uwbwb.models.motion.RandomForce`) moves the target instead of
    the scenario's own model; the truth's ``config`` then holds it (:meth:`WalkScenario.with_motion`).

    Returns
    -------
    recording
        ``dataset="synthetic"``, ``name=config.name``; one :class:`~uwbwb.types.RangeLog`
        per tag at ``rate_hz`` (tags interleaved), per-tag truth at ``sim_rate_hz``
        (3-D positions at the tag's height, with velocities).
    truth
        The simulator's hidden state (:class:`WalkTruth`).
    """
    config = config.with_motion(motion)
    t_ref, states = steer(config, rng=rng)
    anchors = config.anchors
    A = anchors.pos_m
    n_tags = len(config.tags)
    ranges, truth, nlos_d, err_d, true_d = {}, {}, {}, {}, {}
    cos_shadow = np.cos(np.deg2rad(config.body_shadow_angle_deg))
    for j, mount in enumerate(config.tags):
        t_s = np.arange(j / (n_tags * config.rate_hz), t_ref[-1], 1.0 / config.rate_hz)
        tag_m, psi = _tag_positions(config, mount, t_s, t_ref, states)
        true_r = ranging.ranges(tag_m, A)                                         # (T, n)
        bias = _crossings(tag_m, A, config.obstacles)
        if mount.body_shadow:
            to_anchor = A[None, :, :2] - tag_m[:, None, :2]
            cosang = (np.cos(psi)[:, None] * to_anchor[..., 0] + np.sin(psi)[:, None] * to_anchor[..., 1]) \
                / np.linalg.norm(to_anchor, axis=-1)
            bias = bias + np.where(cosang < cos_shadow, config.body_bias_m, 0.0)
        nlos = bias > 0
        sigma = np.where(nlos, config.sigma_nlos_m, config.sigma_los_m)
        excess = np.where(nlos, rng.exponential(config.nlos_excess_mean_m, true_r.shape), 0.0)
        meas = true_r + bias + excess + sigma * rng.standard_normal(true_r.shape)
        p_miss = np.where(nlos, config.p_missing_nlos, config.p_missing_los)
        meas[rng.random(true_r.shape) < p_miss] = np.nan
        meas = np.maximum(meas, 0.0)
        ranges[mount.tag_id] = RangeLog(t_s, meas, anchors.ids, mount.tag_id)
        tag_fine, _ = _tag_positions(config, mount, t_ref, t_ref, states)
        vel = np.column_stack([np.gradient(tag_fine[:, k], t_ref) for k in range(3)])
        truth[mount.tag_id] = Trajectory(t_ref, tag_fine, vel, name="truth")
        nlos_d[mount.tag_id], err_d[mount.tag_id], true_d[mount.tag_id] = nlos, meas - true_r, true_r
    rec = Recording("synthetic", config.name, anchors, ranges, truth,
                    meta={"source": "uwbwb.sim.walk", "scenario": config.name,
                          "tag_height_m": {m.tag_id: m.height_m for m in config.tags}})
    ref_traj = Trajectory(t_ref, states[:, :2], states[:, 2:], name="reference")
    return rec, WalkTruth(config, ref_traj, nlos_d, err_d, true_d)


def device_output(log: RangeLog, anchors: Anchors, *, z_m: float, n_nearest: int = 4,
                  name: str = "raw") -> Trajectory:
    """Stand-in for the positioning device's own output (the thesis' "raw T4F" positions).

    Per epoch: keep the ``n_nearest`` anchors with the smallest measured ranges,
    solve the closed-form unweighted linear least squares of
    :func:`uwbwb.geometry.linear_multilaterate` in 2-D at the nominal tag height
    ``z_m``; no weighting, no outlier rejection, no tracking. Epochs with fewer
    than three ranges or a collinear anchor subset give no output (left out).

    Parameters
    ----------
    log
        Ranges of one tag.
    anchors
        Anchor positions (same order as ``log.anchor_ids``).
    z_m
        Nominal tag height, metres.
    n_nearest
        Anchors used per epoch (the DWM1001 location engine ranges to four).

    Returns
    -------
    Trajectory
        Horizontal positions ``(T', 2)`` at the epochs with a fix.
    """
    if tuple(log.anchor_ids) != tuple(anchors.ids):
        raise ValueError(f"device_output: log anchors {log.anchor_ids} differ from {anchors.ids}")
    if n_nearest < 3:
        raise ValueError(f"device_output: n_nearest must be >= 3, got {n_nearest}")
    r = np.array(log.range_m, float)
    order = np.argsort(np.where(np.isfinite(r), r, np.inf), axis=1)
    drop = order[:, n_nearest:]
    np.put_along_axis(r, drop, np.nan, axis=1)
    pos = geometry.linear_multilaterate(r, anchors.pos_m, dim=2, z_m=z_m)
    ok = np.all(np.isfinite(pos), axis=1)
    return Trajectory(log.t_s[ok], pos[ok], name=name)
