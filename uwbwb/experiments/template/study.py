"""What the notebook runs: a toy study on a short simulated walk (the template's example method).

The example compares two estimators **on equal terms** — the same ranges of the same walk, the same
range noise σ told to both, scored on the epochs both cover, coverage beside accuracy:

* ``"LS"`` — per-epoch range multilateration (:func:`uwbwb.geometry.multilaterate`, tag at its
  known height);
* ``"EKF-RF"`` — the TDoA EKF of the package (:class:`uwbwb.filters.ekf.TdoaEkf`) with a
  random-force motion model, on the pseudo-TDoAs of those ranges (reference anchor 0).

The walk is an ellipse at walking speed; the ranges come from the TWR model of
:mod:`uwbwb.models.ranging`. The EKF's driving σ is a setting of the study (:class:`Config`), not
fitted to this walk; a copied package tunes it on other data (see ``experiments/motion_models/study.py``).

To add a method: copy this package, replace :func:`simulate` by the paper's scenario (``sim/``) or a
recording, :func:`run_estimators` by the paper's estimators (built in ``filters/``, returning
:class:`~uwbwb.types.Estimates`), and keep :class:`Results` the one object the other modules read.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ... import geometry, metrics, validate
from ...filters.ekf import TdoaEkf
from ...models.motion import make_motion_model
from ...models.ranging import TwrRangeModel, ranges
from ...models.tdoa import TdoaModel
from ...types import Anchors, Estimates, TdoaLog, pseudo_tdoa

__all__ = ["Config", "Results", "METHODS", "simulate", "run_estimators", "run_study"]

#: The compared estimators, in table order.
METHODS = ("LS", "EKF-RF")


@dataclass(frozen=True)
class Config:
    """The toy study's settings (SI units; frozen: change it with :func:`dataclasses.replace`).

    Attributes
    ----------
    duration_s, rate_hz
        Length of the walk and ranging rate.
    room_m
        Floor size ``(x, y)``; one anchor in each corner at ``anchor_height_m``.
    tag_height_m
        Known tag height (both estimators solve for ``x, y``).
    sigma_range_m
        Range noise σ of the simulator, told to both estimators.
    driving_sigma_mps2
        Driving σ of the EKF's random-force model.
    speed_mps
        Walking speed.
    """

    duration_s: float = 60.0
    rate_hz: float = 10.0
    room_m: tuple[float, float] = (8.0, 6.0)
    anchor_height_m: float = 2.5
    tag_height_m: float = 1.0
    sigma_range_m: float = 0.10
    driving_sigma_mps2: float = 0.5
    speed_mps: float = 0.8

    def __post_init__(self):
        validate.number("duration_s", self.duration_s, minimum=1.0)
        validate.number("rate_hz", self.rate_hz, minimum=0.0, strict_minimum=True)
        validate.number("sigma_range_m", self.sigma_range_m, minimum=0.0, strict_minimum=True)
        validate.number("driving_sigma_mps2", self.driving_sigma_mps2, minimum=0.0, strict_minimum=True)

    @property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def anchors(self) -> Anchors:
        x, y = self.room_m
        h = self.anchor_height_m
        return Anchors(("a0", "a1", "a2", "a3"), np.array([[0, 0, h], [x, 0, h], [x, y, h], [0, y, h]], float))


#: The FAST (CI) and full settings.
FAST = Config(duration_s=30.0)
FULL = Config(duration_s=120.0)


@dataclass(frozen=True)
class Results:
    """Everything the study computed that headlines, facts and panels read.

    Attributes
    ----------
    config, fast, seed
        What ran.
    t_s
        Epochs, shape ``(T,)``, s.
    truth_m
        True horizontal positions, shape ``(T, 2)``, m.
    estimates
        ``{method: Estimates}`` (:data:`METHODS`).
    errors_m
        ``{method: (T,)}`` horizontal error, m; NaN where the method has no estimate.
    nis_per_dof
        The EKF's NIS / dof per epoch, shape ``(T,)`` (NaN where it did not update).
    """

    config: Config
    fast: bool
    seed: int
    t_s: np.ndarray
    truth_m: np.ndarray
    estimates: dict = field(repr=False)
    errors_m: dict = field(repr=False)
    nis_per_dof: np.ndarray = field(repr=False)


def simulate(cfg: Config, *, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A walk around the room and its ranges: ``(t_s (T,), truth_m (T, 2), range_m (T, 4))``.

    The walk is an ellipse about the room's centre (semi-axes 35 % of the room) at ``speed_mps``
    from a random starting angle; the ranges are the TWR model's (:class:`~uwbwb.models.ranging.TwrRangeModel`,
    no bias, Gaussian noise ``sigma_range_m``) to the corner anchors.
    """
    t = np.arange(0.0, cfg.duration_s, cfg.dt_s)
    a, b = 0.35 * np.asarray(cfg.room_m, float)
    omega = cfg.speed_mps / np.sqrt(0.5 * (a * a + b * b))          # rad/s, about the mean radius
    phase = rng.uniform(0.0, 2 * np.pi) + omega * t
    truth = 0.5 * np.asarray(cfg.room_m, float) + np.column_stack([a * np.cos(phase), b * np.sin(phase)])
    twr = TwrRangeModel(np.zeros((1, 4)), np.ones((1, 4)), sigma_m=cfg.sigma_range_m)
    r = twr.sample(ranges(truth, cfg.anchors.pos_m, z_m=cfg.tag_height_m)[:, None, :], rng=rng)[:, 0]
    return t, truth, r


def run_estimators(cfg: Config, t_s, range_m) -> dict[str, Estimates]:
    """Both estimators on the same ranges, each told the same range σ (:data:`METHODS` order)."""
    anchors = cfg.anchors
    ls = geometry.multilaterate(range_m, anchors.pos_m, dim=2, z_m=cfg.tag_height_m, sigma_m=cfg.sigma_range_m)
    tdoa, ref = pseudo_tdoa(range_m, 0)
    log = TdoaLog(t_s, tdoa, ref, anchors.ids)
    model = TdoaModel(anchors.pos_m, cfg.sigma_range_m, dim=2, z_m=cfg.tag_height_m)
    motion = make_motion_model("RF", sigma=cfg.driving_sigma_mps2, dt_s=cfg.dt_s, dim=2)      # random force
    ekf = TdoaEkf(motion, model, gate_prob=None).run(log, name="EKF-RF")
    return {"LS": ls.to_estimates(t_s, name="LS"), "EKF-RF": ekf.to_estimates()}


def run_study(*, fast: bool, seed: int = 0, config: Config | None = None) -> Results:
    """Simulate, estimate and score (the one call of the notebook).

    Parameters
    ----------
    fast
        The notebook's FAST flag: :data:`FAST` (a 30 s walk) unless ``config`` is given, else :data:`FULL`.
    seed
        Seed of the walk, the ranges and (in :mod:`.facts`) the bootstrap. Same seed, same numbers.
    config
        Settings instead of the mode's default.
    """
    cfg = config if config is not None else (FAST if fast else FULL)
    rng = np.random.default_rng(seed)
    t, truth, r = simulate(cfg, rng=rng)
    est = run_estimators(cfg, t, r)
    errors = {m: metrics.position_error_m(e.pos_m, truth) for m, e in est.items()}
    info = est["EKF-RF"].info
    with np.errstate(invalid="ignore", divide="ignore"):
        nis = np.where(info["dof"] > 0, info["nis"] / np.maximum(info["dof"], 1), np.nan)
    return Results(cfg, bool(fast), int(seed), t, truth, est, errors, nis)
