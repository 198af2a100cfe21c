"""A run whose truth and noise are known exactly: where the filters must reach their bound.

The tag follows the random-force (constant-velocity) model itself
(:meth:`uwbwb.models.motion.MotionModel.sample_path`, PSD ``psd_m2ps3``) at a fixed height,
starting with a velocity drawn from ``N(0, (1 m/s)² I)`` — the prior the TDoA EKF starts from
— and every anchor measures its range with independent Gaussian noise ``sigma_m`` at every
epoch (no bias, no outliers). The board then runs with the *exact* noise (range σ, RF
driving noise, height, no range bias); the other methods' tuning is fitted on an
independent calibration run of the same simulator. With truth and noise known, the EKF
with the true motion model is the near-optimal filter, so its RMSE must meet its
posterior CRLB within Monte Carlo error, and the LS fixes their snapshot CRLB
(:func:`monte_carlo`). This holds while the tag stays inside the anchors' hull (the default
10 s keeps it there): far outside it the geometry is poor, the problem is no longer locally
linear at this noise, and the TDoA LS and EKF come out *below* their bounds (biased estimators
are not bound by the CRLB) — run ``duration_s=20`` to see it.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ..calibration import RangeCalibration
from ..metrics.errors import interval_side, seeds_interval
from ..models.motion import RandomForce
from ..models.ranging import TwrRangeModel, predict_ranges
from ..types import Anchors, RangeLog, Recording, Trajectory
from .board import Board, calibrate, score
from .estimators import CalibratedLs, TdoaEkfEstimator, TdoaLs, default_estimators
from .protocol import Calibration

__all__ = ["SyntheticConfig", "exact_calibration", "monte_carlo", "simulate", "synthetic_board", "own_bound_summary"]


@dataclass(frozen=True)
class SyntheticConfig:
    """The simulated hall, tag and noise (all assumptions, chosen to be unremarkable).

    Attributes
    ----------
    duration_s, rate_hz
        Length and epoch rate of a run. The track is a free random-force walk from the hall's centre
        (no walls): at ``init_vel_sigma_mps`` 1 m/s it may leave the anchors' hull after about 15 s, so
        runs much longer than that score positions outside the hall (poor TDoA geometry).
    sigma_m
        Range noise standard deviation (every anchor), metres.
    psd_m2ps3
        PSD of the tag's white acceleration (random-force model), m²/s³; the model itself is
        :attr:`motion`.
    init_vel_sigma_mps
        Standard deviation of the initial velocity per axis, m/s.
    tag_height_m
        Fixed tag height, metres.
    hall_m
        Side of the square hall; 8 anchors on its corners and edge midpoints, metres.
    """

    duration_s: float = 10.0
    rate_hz: float = 10.0
    sigma_m: float = 0.05
    psd_m2ps3: float = 0.05
    init_vel_sigma_mps: float = 1.0
    tag_height_m: float = 1.0
    hall_m: float = 30.0

    def __post_init__(self):
        if min(self.duration_s, self.rate_hz, self.sigma_m, self.hall_m) <= 0 or self.psd_m2ps3 < 0:
            raise ValueError("duration_s, rate_hz, sigma_m, hall_m must be positive and psd_m2ps3 >= 0")

    @property
    def motion(self) -> RandomForce:
        """The tag's motion model, a 2-D random force with PSD ``psd_m2ps3``."""
        return RandomForce(psd_m2ps3=self.psd_m2ps3, dim=2)

    def anchors(self) -> Anchors:
        h = self.hall_m / 2
        xy = [(-h, -h), (h, -h), (h, h), (-h, h), (0, -h), (h, 0), (0, h), (-h, 0)]
        z = [2.8, 0.5, 2.8, 0.5, 1.8, 2.2, 1.2, 2.5]
        return Anchors(tuple(f"A{i}" for i in range(8)), np.column_stack([np.array(xy, float), z]))


def simulate(config: SyntheticConfig = SyntheticConfig(), *, rng: np.random.Generator,
             name: str = "cv") -> Recording:
    """One run (tag ``"tag"``) with its truth; ``dataset`` is ``"synthetic"``."""
    t = np.arange(0.0, config.duration_s, 1.0 / config.rate_hz)
    motion = config.motion
    x0 = motion.initial_state(np.zeros(2), config.init_vel_sigma_mps * rng.standard_normal(2))
    x = motion.sample_path(x0, t, rng=rng)
    pos = np.column_stack([x[:, :2], np.full(t.size, config.tag_height_m)])
    anchors = config.anchors()
    true_r = predict_ranges(pos, anchors.pos_m)
    unbiased = np.zeros((1, len(anchors)))
    r = TwrRangeModel(unbiased, unbiased + 1.0, sigma_m=config.sigma_m).sample(true_r, rng=rng)
    log = RangeLog(t, r, anchors.ids, "tag")
    truth = Trajectory(t, pos, np.column_stack([x[:, 2:4], np.zeros(t.size)]), name="truth")
    return Recording("synthetic", name, anchors, {"tag": log}, {"tag": truth},
                     meta={"config": config, "truth_state": x})


def exact_calibration(config: SyntheticConfig, cal: Calibration) -> Calibration:
    """``cal`` with the simulator's exact noise: range σ, no range bias, height, RF driving noise."""
    anchors = config.anchors()
    n = len(anchors)
    zeros, ones = np.zeros((1, n)), np.ones((1, n))
    sig = np.full((1, n), config.sigma_m)
    rc = RangeCalibration(anchors.ids, ("tag",), zeros, ones, np.zeros((1, n), bool), np.zeros((1, n), int),
                          zeros, zeros, sig, sig, source=("exact: the simulator's noise",))
    sigma_w = float(np.sqrt(config.psd_m2ps3 * config.rate_hz))      # q = σ_w² dt (uwbwb.models.motion)
    tuned = {**cal.tuned, "EKF-RF": {"sigma_w": sigma_w, "exact": True}}
    return replace(cal, source=f"exact noise (other tuning: {cal.source})", range_calibration=rc,
                   range_sigma_m={"tag": np.full(n, config.sigma_m)}, tag_height_m={"tag": config.tag_height_m},
                   rate_hz=config.rate_hz, tuned=tuned)


def _rng(seed: int, role: str) -> np.random.Generator:
    return np.random.default_rng([int(seed), zlib.crc32(role.encode())])


def synthetic_board(config: SyntheticConfig = SyntheticConfig(), *, seed: int = 0, estimators=None,
                    fast: bool = False) -> Board:
    """Calibrate on one simulated run, put the exact noise in, score another run."""
    estimators = list(default_estimators(fast=fast, seed=seed) if estimators is None else estimators)
    cal_rec = simulate(config, rng=_rng(seed, "calibration"), name=f"cv-{seed}-calibration")
    test_rec = simulate(config, rng=_rng(seed, "test"), name=f"cv-{seed}")
    cal = exact_calibration(config, calibrate(cal_rec, estimators, rate_hz=None, dim=2))
    return score(test_rec, cal_rec, estimators=estimators, rate_hz=None, calibration=cal, fast=fast)


def monte_carlo(n_runs: int, config: SyntheticConfig = SyntheticConfig(), *, seed: int = 0,
                estimators=None) -> pd.DataFrame:
    """Per run and method: mean squared error and mean bound trace over the scored epochs.

    Every run draws a fresh track and fresh noise (the PCRLB is an average over both).
    Default methods: LS, TDoA LS and EKF-RF (the ones whose model is the simulator's).
    """
    if n_runs < 2:
        raise ValueError(f"n_runs must be >= 2 (the error bar needs two runs), got {n_runs}")
    estimators = [CalibratedLs(), TdoaLs(), TdoaEkfEstimator("RF", grid=(1.0,))] if estimators is None else estimators
    rows = []
    cal = None
    for k in range(n_runs):
        rec = simulate(config, rng=_rng(seed + k, "monte-carlo"), name=f"cv-mc-{seed + k}")
        if cal is None:
            cal = exact_calibration(config, calibrate(rec, estimators, rate_hz=None, dim=2))
        board = score(rec, rec, estimators=estimators, rate_hz=None, calibration=cal, check=False)
        for e in board.ran():
            tr = e.trace_m2("bound")
            ok = e.scored & np.isfinite(tr)
            rows.append({"run": k, "method": e.method, "bound_kind": e.bound.kind, "n": int(ok.sum()),
                         "mse_m2": float(np.mean(e.error_m[ok] ** 2)), "bound_m2": float(np.mean(tr[ok]))})
    return pd.DataFrame(rows)


def own_bound_summary(mc: pd.DataFrame, *, prob: float = 0.95) -> pd.DataFrame:
    """Per method: RMSE and own bound over all runs, their ratio, its interval over runs and the verdict.

    ``rmse_over_bound = sqrt(Σ mse / Σ bound)`` over runs — RMSE / own bound (the textbook efficiency is its
    inverse). Its interval is :func:`uwbwb.metrics.seeds_interval` (Student t at
    ``prob``, runs independent) of each run's linearised share of ``R = Σ mse / Σ bound``,
    ``R + (mse_k − R bound_k) / mean(bound)`` (mean ``R``; the linearisation of a ratio of sums, as the board's
    :func:`.verdicts.block_se_ratio` with runs for blocks), its ends square-rooted: ``rmse_over_bound_lo``,
    ``rmse_over_bound_hi``. ``verdict``: :func:`uwbwb.metrics.interval_side` of that interval against 1 —
    ``on its bound`` (it holds 1), ``above its bound``, ``below its bound``.
    """
    rows = []
    for m, g in mc.groupby("method", sort=False):
        mse, bnd = g["mse_m2"].to_numpy(float), g["bound_m2"].to_numpy(float)
        r = mse.sum() / bnd.sum()
        ci = seeds_interval(r + (mse - r * bnd) / bnd.mean(), prob=prob)
        lo, hi = np.sqrt(max(ci["lo"], 0.0)), np.sqrt(ci["hi"])
        rows.append({"method": m, "bound_kind": g["bound_kind"].iloc[0], "runs": len(g),
                     "rmse_m": float(np.sqrt(mse.mean())), "bound_m": float(np.sqrt(bnd.mean())),
                     "rmse_over_bound": float(np.sqrt(r)), "rmse_over_bound_lo": float(lo),
                     "rmse_over_bound_hi": float(hi),
                     "verdict": _SIDES[interval_side(lo, hi, 1.0)]})
    return pd.DataFrame(rows)


_SIDES = {"contains": "on its bound", "above": "above its bound", "below": "below its bound",
          "none": "no interval (fewer than 2 runs)"}
