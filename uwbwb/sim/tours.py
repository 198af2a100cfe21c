"""Synthetic re-creation of the cafeteria experiments of Zupanec et al. (sec. 3).

Setup (as stated in the paper, with our own numbers where it gives none):

* **Anchors.** Six anchors on a ceiling inclined along ``x`` from 3.9 m to 4.5 m,
  antennas facing down. An anchor covers the floor within ``R = H tan 60°`` of the
  point below it (``H`` its height), i.e. 6.8--7.8 m. The layout (our choice, in a
  24 m × 16 m room) leaves the west side and the corners poorly covered, as the
  paper's tours deliberately visited "areas with obstructions, corners and similar".
* **Blind nodes** on an IV pole: ``L`` at 1.3 m and ``H`` at 2 m.
* **Packets.** Each node forms a packet every 130 ms, pinging the anchors
  round-robin: the range to anchor ``j`` is measured in slot ``j`` of the 130 ms
  before the packet is formed, but carries the packet's time stamp (the only time
  the format of Table 1 has). Some ranges fail (status ``ERR`` = missing).
* **Range errors** (:class:`uwbwb.models.ranging.NlosRangeModel`): a small symmetric component (a
  per-pair bias and white noise, :class:`uwbwb.models.ranging.TwrRangeModel`)
  plus, with a probability that depends on coverage, a large positive NLOS excess
  -- the bimodal error of Figs 4--5. A node outside an anchor's coverage disc
  sees that anchor in NLOS (and fails to range) much more often than inside it,
  so NLOS is most likely where few anchors cover the floor.
* **Tours.** Three tours, sequences of straight segments between keypoints, with
  10 s stops at every keypoint, walked at a slow and a fast pace (six experiments).

The same :class:`~uwbwb.models.ranging.NlosRangeModel` object generates the ranges here and
gives the analytic error distribution (its ``error_pdf``, ``error_quantile``) the notebook
draws Figs 4--5 from.

Numbers the paper does not state and we chose (all in :class:`TourConfig`): room
size, anchor plan positions, keypoints, paces (0.5 / 1.0 m/s), LOS noise
(0.5 m, bias 0--0.5 m: the nodes use Nanotron 2.4 GHz chirp ranging, specified to
about a metre indoors, not impulse UWB), NLOS probability inside/outside coverage
(5 % / 30 %), NLOS episodes of 3 s on average, NLOS excess (normal, mean 2.5 m,
s.d. 1 m, clipped at 0) and ERR probability (2 % / 15 %).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..models.ranging import NlosRangeModel, TwrRangeModel
from ..types import Anchors, RangeLog, Recording, Trajectory

__all__ = ["Segment", "T0_MS", "TOURS", "TourConfig", "TourTruth", "cafeteria_anchors",
           "coverage_count", "coverage_radius_m", "draw_range_model", "simulate_tour", "tour_path", "tour_xy"]

#: Keypoints (x, y) in metres of the three tours; each starts and ends with a stop.
TOURS: dict[int, tuple[tuple[float, float], ...]] = {
    1: ((7.0, 6.0), (16.0, 5.0), (17.0, 11.0), (9.0, 11.5), (7.0, 6.0)),          # well covered loop
    2: ((12.0, 8.0), (3.0, 3.0), (2.5, 13.5), (12.0, 11.0), (22.0, 14.5)),         # west side and corners
    3: ((20.0, 2.5), (11.0, 4.0), (4.0, 8.0), (12.0, 14.0), (21.0, 9.0)),          # across the room
}

#: Timestamp of the first packet, ms: the value of Table 1.
T0_MS = 1452967702506


@dataclass(frozen=True)
class TourConfig:
    """Parameters of one experiment (SI units). Change with :func:`dataclasses.replace`.

    Attributes
    ----------
    tour, pace
        Which tour (1, 2, 3) and ``"slow"`` or ``"fast"``.
    speed_mps
        Walking speed per pace.
    stop_s
        Stop at every keypoint, seconds.
    period_s
        Packet period of a node (130 ms).
    node_heights_m
        Blind-node heights on the pole, by tag id.
    node_phase_s
        Offset of each node's packet clock from the first node's.
    room_m
        Room size ``(x, y)``.
    anchor_xy_m
        Plan positions of the anchors ``1..6``.
    ceiling_z_m
        Ceiling height at ``x = 0`` and at ``x = room_m[0]`` (linear in between).
    coverage_half_angle_deg
        Half angle of an anchor's coverage cone (``R = H tan(angle)``).
    sigma_m, bias_range_m, resolution_m
        LOS range noise, per-pair bias range, reported resolution.
    p_nlos_in, p_nlos_out
        NLOS probability inside / outside an anchor's coverage disc.
    nlos_mean_m, nlos_sigma_m
        NLOS excess distribution (normal, clipped at 0).
    nlos_dwell_s
        Mean duration of an NLOS episode on one node--anchor link, seconds (0:
        independent draws per range). See :class:`~uwbwb.models.ranging.NlosRangeModel`.
    p_err_in, p_err_out
        Probability of a failed range (``ERR``) inside / outside coverage.
    edge_m
        Width of the smooth transition at the coverage edge, metres.
    """

    tour: int = 1
    pace: str = "slow"
    speed_mps: tuple = (("slow", 0.5), ("fast", 1.0))
    stop_s: float = 10.0
    period_s: float = 0.130
    node_heights_m: tuple = (("L", 1.3), ("H", 2.0))
    node_phase_s: tuple = (("L", 0.0), ("H", 0.065))
    room_m: tuple = (24.0, 16.0)
    anchor_xy_m: tuple = ((7.0, 3.5), (15.0, 2.5), (21.0, 6.0), (19.0, 13.0), (11.0, 13.5), (10.0, 8.5))
    ceiling_z_m: tuple = (3.9, 4.5)
    coverage_half_angle_deg: float = 60.0
    sigma_m: float = 0.5
    bias_range_m: tuple = (0.0, 0.5)
    resolution_m: float = 0.01
    p_nlos_in: float = 0.05
    p_nlos_out: float = 0.3
    nlos_mean_m: float = 2.5
    nlos_sigma_m: float = 1.0
    nlos_dwell_s: float = 3.0
    p_err_in: float = 0.02
    p_err_out: float = 0.15
    edge_m: float = 0.5

    def __post_init__(self):
        if self.tour not in TOURS:
            raise ValueError(f"tour must be one of {sorted(TOURS)}, got {self.tour!r}")
        if self.pace not in dict(self.speed_mps):
            raise ValueError(f"pace must be one of {list(dict(self.speed_mps))}, got {self.pace!r}")
        if min(v for _, v in self.speed_mps) <= 0 or self.period_s <= 0 or self.stop_s < 0:
            raise ValueError("speeds and period must be positive, stop_s non-negative")
        for p in (self.p_nlos_in, self.p_nlos_out, self.p_err_in, self.p_err_out):
            if not 0 <= p <= 1:
                raise ValueError(f"probabilities must lie in [0, 1], got {p!r}")
        if min(self.sigma_m, self.nlos_sigma_m, self.nlos_mean_m, self.nlos_dwell_s) < 0 or self.edge_m <= 0:
            raise ValueError("sigma_m, nlos_* must be >= 0 and edge_m > 0")
        if set(dict(self.node_phase_s)) != set(dict(self.node_heights_m)):
            raise ValueError("node_phase_s and node_heights_m must name the same nodes")

    @property
    def speed(self) -> float:
        return float(dict(self.speed_mps)[self.pace])

    @property
    def tag_ids(self) -> tuple[str, ...]:
        return tuple(k for k, _ in self.node_heights_m)

    @property
    def heights_m(self) -> dict[str, float]:
        return {k: float(v) for k, v in self.node_heights_m}

    @property
    def name(self) -> str:
        return f"tour{self.tour}-{self.pace}"

    def ceiling_at(self, x_m) -> np.ndarray:
        z0, z1 = self.ceiling_z_m
        return z0 + (z1 - z0) * np.asarray(x_m, float) / self.room_m[0]


def cafeteria_anchors(config: TourConfig = TourConfig()) -> Anchors:
    """Anchors ``"1".."6"`` on the inclined ceiling, metres."""
    xy = np.asarray(config.anchor_xy_m, float)
    return Anchors(tuple(str(i + 1) for i in range(len(xy))),
                   np.column_stack([xy, config.ceiling_at(xy[:, 0])]))


def coverage_radius_m(config: TourConfig, anchors: Anchors) -> np.ndarray:
    """``R = H tan(half angle)`` per anchor, shape ``(n_anchors,)``, metres."""
    return anchors.pos_m[:, 2] * np.tan(np.deg2rad(config.coverage_half_angle_deg))


def coverage_count(xy_m, config: TourConfig = TourConfig(), anchors: Anchors | None = None) -> np.ndarray:
    """Number of anchors whose coverage disc contains each floor point, shape ``xy_m.shape[:-1]``."""
    anchors = cafeteria_anchors(config) if anchors is None else anchors
    d = np.linalg.norm(np.asarray(xy_m, float)[..., None, :] - anchors.pos_m[:, :2], axis=-1)
    return np.sum(d <= coverage_radius_m(config, anchors), axis=-1)


def draw_range_model(config: TourConfig = TourConfig(), *, rng: np.random.Generator) -> NlosRangeModel:
    """A range model with random per-(node, anchor) biases (uniform in ``bias_range_m``), scale 1."""
    anchors = cafeteria_anchors(config)
    shape = (len(config.tag_ids), len(anchors))
    los = TwrRangeModel(bias_m=rng.uniform(*config.bias_range_m, size=shape), scale=np.ones(shape),
                        sigma_m=config.sigma_m, resolution_m=config.resolution_m)
    return NlosRangeModel(los, anchors.pos_m, coverage_radius_m(config, anchors), config.p_nlos_in,
                          config.p_nlos_out, config.nlos_mean_m, config.nlos_sigma_m, config.p_err_in,
                          config.p_err_out, config.edge_m, config.nlos_dwell_s)


# --------------------------------------------------------------------------- tours


@dataclass(frozen=True)
class Segment:
    """A part of a tour: a stop at a keypoint or a straight walk between two.

    Attributes
    ----------
    index
        Position in the tour, 0-based.
    kind
        ``"stop"`` or ``"move"``.
    t_start_s, t_end_s
        Time span on the packet clock, seconds.
    start_xy_m, end_xy_m
        Plan positions at start and end (equal for a stop), metres.
    keypoint
        Keypoint index of a stop, or of the walk's destination.
    """

    index: int
    kind: str
    t_start_s: float
    t_end_s: float
    start_xy_m: tuple
    end_xy_m: tuple
    keypoint: int

    @property
    def vel_xy_mps(self) -> np.ndarray:
        dt = self.t_end_s - self.t_start_s
        return (np.subtract(self.end_xy_m, self.start_xy_m) / dt) if self.kind == "move" else np.zeros(2)

    @property
    def label(self) -> str:
        return f"K{self.keypoint}" if self.kind == "stop" else f"->K{self.keypoint}"


def tour_path(config: TourConfig) -> tuple[Segment, ...]:
    """Stops and walks of a tour, starting at ``t = 0`` with the first stop."""
    kp = np.asarray(TOURS[config.tour], float)
    segs, t = [], 0.0
    for i, p in enumerate(kp):
        if i > 0:
            dur = float(np.linalg.norm(p - kp[i - 1])) / config.speed
            segs.append(Segment(len(segs), "move", t, t + dur, tuple(kp[i - 1]), tuple(p), i))
            t += dur
        segs.append(Segment(len(segs), "stop", t, t + config.stop_s, tuple(p), tuple(p), i))
        t += config.stop_s
    return tuple(segs)


def tour_xy(segs: tuple[Segment, ...], t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plan position ``(N, 2)`` and velocity ``(N, 2)`` along the tour at times ``t_s`` ``(N,)``.

    Times before the first or after the last segment are clamped to the tour's ends.
    """
    starts = np.array([s.t_start_s for s in segs])
    i = np.clip(np.searchsorted(starts, t_s, side="right") - 1, 0, len(segs) - 1)
    a = np.array([s.start_xy_m for s in segs])[i]
    v = np.array([s.vel_xy_mps for s in segs])[i]
    tau = np.clip(t_s - starts[i], 0.0, None)
    ends = np.array([s.t_end_s - s.t_start_s for s in segs])[i]
    return a + v * np.minimum(tau, ends)[:, None], v


@dataclass(frozen=True)
class TourTruth:
    """What the simulator knows and the estimators do not."""

    model: NlosRangeModel
    segments: tuple[Segment, ...]
    keypoints_m: np.ndarray
    nlos: dict = field(repr=False)
    coverage: np.ndarray = field(repr=False)


def simulate_tour(config: TourConfig = TourConfig(), *, rng: np.random.Generator,
                  model: NlosRangeModel | None = None) -> tuple[Recording, TourTruth]:
    """One experiment: both nodes' packets along a tour, and the hidden truth.

    Parameters
    ----------
    config
        Tour, pace and error parameters.
    rng
        Random generator.
    model
        Range-error model; default :func:`draw_range_model` (drawn from ``rng``).

    Returns
    -------
    recording
        ``dataset="synthetic"``, ``name="tour<k>-<pace>"``; ranges per node (anchors
        ``"1".."6"``, ``t_s`` = packet time stamps, ``t0`` = :data:`T0_MS`) and
        truth per node at the packet times (with velocity).
    truth
        The range model, the segments, keypoints, per-node NLOS flags ``(T, n)``
        and the coverage count at each keypoint.
    """
    model = draw_range_model(config, rng=rng) if model is None else model
    anchors = cafeteria_anchors(config)
    n = len(anchors)
    segs = tour_path(config)
    t_end = segs[-1].t_end_s
    heights, phases = config.heights_m, dict(config.node_phase_s)
    slot = config.period_s / n
    tags = config.tag_ids
    # a packet is formed at the end of its round; its anchors were ranged in the slots before it
    n_pkt = int(np.floor((t_end - config.period_s - max(phases.values())) / config.period_s + 1e-9)) + 1
    t_pkt = config.period_s + np.array([phases[g] for g in tags])[None, :] \
        + config.period_s * np.arange(n_pkt)[:, None]                                   # (T, tags)
    t_meas = t_pkt[..., None] - config.period_s + (np.arange(n) + 0.5) * slot          # (T, tags, n)
    xy, _ = tour_xy(segs, t_meas.ravel())
    z = np.broadcast_to(np.array([heights[g] for g in tags])[None, :, None], t_meas.shape)
    pos = np.concatenate([xy.reshape(*t_meas.shape, 2), z[..., None]], axis=-1)        # (T, tags, n, 3)
    r, nl = model.sample(pos, rng=rng, dt_s=config.period_s)
    ranges, truth, nlos_flags = {}, {}, {}
    for k, tag in enumerate(tags):
        ranges[tag] = RangeLog(t_pkt[:, k], r[:, k], anchors.ids, tag, T0_MS)
        nlos_flags[tag] = nl[:, k]
        xy_p, v_p = tour_xy(segs, t_pkt[:, k])
        truth[tag] = Trajectory(t_pkt[:, k], np.column_stack([xy_p, np.full(n_pkt, heights[tag])]),
                                np.column_stack([v_p, np.zeros(n_pkt)]), name="truth")
    kp = np.asarray(TOURS[config.tour], float)
    rec = Recording("synthetic", config.name, anchors, ranges, truth,
                    meta={"source": "uwbwb.sim.tours", "config": config, "segments": segs,
                          "node_heights_m": heights})
    return rec, TourTruth(model, segs, kp, nlos_flags, coverage_count(kp, config, anchors))
