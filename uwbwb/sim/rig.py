"""A synthetic planar rig: a trolley carrying several UWB tags among fixed anchors.

It mirrors the *kind* of setup of the ``lias-planar-uwb`` recordings (eight
anchors around a room, three tags on a rigid trolley, ~100 Hz two-way ranges with
1 cm resolution and per-pair biases, motion-capture truth) with its own
geometry, so the workbench has something honest to run on when the real data is
absent. Ranges come from :class:`uwbwb.models.ranging.TwrRangeModel`, the same
model calibration fits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry import yaw_rotation
from ..models import ranging
from ..models.ranging import TwrRangeModel, rigid_points
from ..types import Anchors, RangeLog, Recording, Trajectory


@dataclass(frozen=True)
class RigConfig:
    """Parameters of the synthetic rig (SI units).

    The anchors sit on the walls of a ``room_x_m`` × ``room_y_m`` room centred at
    the origin, at ``anchor_z_m``; the trolley drives a figure-eight at mean speed
    ``speed_mps`` with its x axis along the direction of travel.
    """

    room_x_m: float = 7.0
    room_y_m: float = 6.0
    anchor_z_m: float = 1.05
    tag_offsets_m: tuple = ((-0.10, -0.15, 0.0), (-0.10, 0.15, 0.0), (0.20, 0.0, 0.0))
    centroid_z_m: float = 0.97
    path_half_x_m: float = 2.2
    path_half_y_m: float = 1.4
    speed_mps: float = 0.5
    duration_s: float = 120.0
    rate_hz: float = 100.0
    sigma_m: float = 0.03
    bias_range_m: tuple = (0.05, 0.40)
    scale_sigma: float = 0.005
    outlier_prob: float = 0.01
    outlier_mean_m: float = 0.4
    resolution_m: float = 0.01

    def __post_init__(self):
        if min(self.room_x_m, self.room_y_m, self.speed_mps, self.duration_s, self.rate_hz) <= 0:
            raise ValueError("room size, speed, duration and rate must be positive")
        if self.bias_range_m[0] > self.bias_range_m[1]:
            raise ValueError("bias_range_m must be (low, high)")

    @property
    def anchors(self) -> Anchors:
        hx, hy = self.room_x_m / 2, self.room_y_m / 2
        xy = [(-hx, hy), (0, hy), (hx, hy), (hx, 0), (hx, -hy), (0, -hy), (-hx, -hy), (-hx, 0)]
        pos = np.column_stack([np.array(xy, float), np.full(8, self.anchor_z_m)])
        return Anchors(tuple(f"a{i}" for i in range(8)), pos)

    @property
    def tag_ids(self) -> tuple[str, ...]:
        return tuple(f"t{i}" for i in range(len(self.tag_offsets_m)))


@dataclass(frozen=True)
class RigTruth:
    """What the simulator knows and a real recording would not."""

    range_model: TwrRangeModel
    centroid: Trajectory
    yaw_rad: np.ndarray = field(repr=False)


def draw_range_model(config: RigConfig, *, rng: np.random.Generator) -> TwrRangeModel:
    """Random per-pair biases (uniform in ``bias_range_m``) and scales (1 + N(0, scale_sigma))."""
    shape = (len(config.tag_offsets_m), len(config.anchors))
    return TwrRangeModel(bias_m=rng.uniform(*config.bias_range_m, size=shape),
                         scale=1.0 + config.scale_sigma * rng.standard_normal(shape),
                         sigma_m=config.sigma_m, outlier_prob=config.outlier_prob,
                         outlier_mean_m=config.outlier_mean_m, resolution_m=config.resolution_m)


def figure_eight(config: RigConfig, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centroid position ``(T, 3)``, velocity ``(T, 3)`` and heading ``(T,)`` on a figure-eight.

    ``x = A sin(w t)``, ``y = B sin(2 w t)``, with ``w`` chosen so the mean speed
    over one lap equals ``config.speed_mps``.
    """
    A, B = config.path_half_x_m, config.path_half_y_m
    u = np.linspace(0, 2 * np.pi, 4001)
    lap_length = np.trapezoid(np.hypot(A * np.cos(u), 2 * B * np.cos(2 * u)), u)
    w = 2 * np.pi * config.speed_mps / lap_length
    x, y = A * np.sin(w * t_s), B * np.sin(2 * w * t_s)
    vx, vy = A * w * np.cos(w * t_s), 2 * B * w * np.cos(2 * w * t_s)
    pos = np.column_stack([x, y, np.full_like(x, config.centroid_z_m)])
    vel = np.column_stack([vx, vy, np.zeros_like(vx)])
    return pos, vel, np.unwrap(np.arctan2(vy, vx))


def _recording(config, name, t_s, centroid_m, yaw_rad, model, *, rng, meta) -> Recording:
    anchors = config.anchors
    offsets = np.asarray(config.tag_offsets_m, float)
    tags_m = rigid_points(centroid_m, yaw_rad, offsets)                    # (T, n_tags, 3)
    true_range = ranging.ranges(tags_m, anchors.pos_m)                       # (T, n_tags, n_anchors)
    meas = model.sample(true_range, rng=rng)                                 # (T, n_tags, n_anchors)
    rot = yaw_rotation(yaw_rad)
    ranges, truth = {}, {}
    for k, tag in enumerate(config.tag_ids):
        ranges[tag] = RangeLog(t_s, meas[:, k], anchors.ids, tag)
        truth[tag] = Trajectory(t_s, tags_m[:, k], rot=rot, name="truth")
    return Recording("synthetic", name, anchors, ranges, truth,
                     meta={"source": "uwbwb.sim.rig", "config": config, **meta})


def simulate_dynamic(config: RigConfig = RigConfig(), *, rng: np.random.Generator,
                     range_model: TwrRangeModel | None = None) -> tuple[Recording, RigTruth]:
    """A moving-trolley recording and the simulator's hidden truth.

    Returns
    -------
    recording
        Ranges per tag and per-tag truth, like a loaded real recording
        (``dataset="synthetic"``, ``name="rig-dynamic"``).
    truth
        The range model used (biases, scales) and the centroid trajectory.
    """
    model = range_model if range_model is not None else draw_range_model(config, rng=rng)
    t_s = np.arange(0, config.duration_s, 1 / config.rate_hz)
    pos, vel, yaw = figure_eight(config, t_s)
    rec = _recording(config, "rig-dynamic", t_s, pos, yaw, model, rng=rng, meta={})
    return rec, RigTruth(model, Trajectory(t_s, pos, vel, name="centroid"), yaw)


def simulate_static(config: RigConfig = RigConfig(), poses_xy_yaw=None, *, duration_s: float = 20.0,
                    rng: np.random.Generator, range_model: TwrRangeModel | None = None
                    ) -> tuple[list[Recording], TwrRangeModel]:
    """Static recordings of the trolley at several poses (like a calibration campaign).

    Parameters
    ----------
    poses_xy_yaw
        Array ``(n_poses, 3)`` of centroid x (m), y (m) and yaw (rad); by default
        five sites (four quadrants and the centre) × six headings 60° apart.
    duration_s
        Length of each static recording, seconds.
    """
    model = range_model if range_model is not None else draw_range_model(config, rng=rng)
    if poses_xy_yaw is None:
        sites = np.array([(-1.8, -1.2), (1.8, -1.2), (1.8, 1.2), (-1.8, 1.2), (0.0, 0.0)])
        yaws = np.deg2rad(np.arange(0, 360, 60))
        poses_xy_yaw = np.array([(x, y, a) for x, y in sites for a in yaws])
    poses_xy_yaw = np.asarray(poses_xy_yaw, float)
    t_s = np.arange(0, duration_s, 1 / config.rate_hz)
    recs = []
    for i, (x, y, yaw) in enumerate(poses_xy_yaw):
        centroid = np.tile([x, y, config.centroid_z_m], (t_s.size, 1))
        recs.append(_recording(config, f"rig-static/pose{i}", t_s, centroid, np.full(t_s.size, yaw), model,
                               rng=rng, meta={"pose_xy_yaw": (x, y, yaw)}))
    return recs, model
