"""Estimators of the Hanyang study beside the board's defaults: an EKF on the ranges with the
RW/RF/RJ motion models, NLS with pruning, and LS on ranges corrected by the static part's
range model (:func:`static_range_model`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ... import bounds, geometry
from ...datasets import hanyang
from ...filters.ekf import Ekf, Linearisation
from ...filters.gating import AnchorDropping
from ...filters.kalman import Gaussian
from ...filters.pruning import LABELS as PRUNING_LABELS, PruningConfig, localize
from ...models.motion import MotionModel, make_motion_model
from ...scoreboard.estimators import EKF_GRIDS
from ...scoreboard.interface import BaseEstimator, _errors_rmse, _range_bound, calibrated_log, on_grid_edge, truth_at
from ...scoreboard.setnoise_nls import WindowNls
from ...types import EstimateStatus, Estimates

PathLike = str | os.PathLike


_UP, _NONE = int(EstimateStatus.UPDATED), int(EstimateStatus.NO_ESTIMATE)


@dataclass(frozen=True)
class RangeMeasurement:
    """Two-way ranges as :class:`~uwbwb.filters.ekf.Ekf` sees them: one epoch's measurement is a row of
    ``RangeLog.range_m`` (NaN = not measured), ``h_i(p) = |(p, z) − a_i|`` at the known tag height ``z_m``
    in 2-D (``|p − a_i|`` in 3-D), ``R = diag(σ_i²)``. It can re-linearise a subset of its anchors, so the
    anchor-dropping gate applies.
    """

    anchors_m: np.ndarray
    sigma_m: np.ndarray
    motion: MotionModel
    z_m: float | None = None

    def __post_init__(self):
        if self.motion.dim == 2 and self.z_m is None:
            raise ValueError("a 2-D range model needs the tag height z_m")

    def _lin(self, x: np.ndarray, row: np.ndarray, keep: np.ndarray) -> Linearisation:
        p = self.motion.position(x)
        p3 = np.r_[p, self.z_m] if p.size == 2 else p
        d = p3[None, :] - self.anchors_m[keep]
        r = np.linalg.norm(d, axis=1)
        H_pos = d[:, : p.size] / np.maximum(r, 1e-9)[:, None]
        return Linearisation(row[keep], r, H_pos @ self.motion.H_pos, np.diag(self.sigma_m[keep] ** 2))

    def linearise(self, x, measurement):
        row = np.asarray(measurement, float)
        keep = np.flatnonzero(np.isfinite(row))
        return None if keep.size == 0 else self._lin(x, row, keep)

    def components(self, measurement) -> np.ndarray:
        return np.flatnonzero(np.isfinite(np.asarray(measurement, float)))

    def linearise_components(self, x, measurement, keep):
        return self._lin(x, np.asarray(measurement, float), np.asarray(keep))


@dataclass(frozen=True)
class RangeEkfEstimator(BaseEstimator):
    """An EKF on the ranges themselves (no TDoA: with four anchors in a 2 m cluster and the tag up to
    50 m away, range differences carry almost no information, while the ranges do), motion model
    ``model`` (RW, RF, RJ of notebook 03), calibrated ranges and range noise of the board, the
    anchor-dropping χ² gate (``gate_prob``) of the TDoA EKF. ``tune`` picks the driving noise on the
    calibration part over :data:`~uwbwb.scoreboard.estimators.EKF_GRIDS` as the board's EKFs do; the
    filter starts at the first epoch with a multilateration fix. Bound: the posterior CRLB with the
    same motion model and the range information of every epoch.
    """

    model: str = "RF"
    gate_prob: float = 0.9999
    grid: tuple[float, ...] | None = None
    init_sigma: float = 1.0

    @property
    def name(self) -> str:
        return f"EKF-{self.model} ranges"

    def _filter(self, rec, tag, cal, sigma_w) -> Ekf:
        motion = make_motion_model(self.model, sigma=sigma_w, dt_s=1.0 / cal.rate_hz, dim=cal.dim)
        meas = RangeMeasurement(rec.anchors.pos_m, cal.sigma(tag), motion, cal.height(tag))
        return Ekf(motion, meas, vel_index=motion.layout.vel_index,
                   gate=AnchorDropping(prob=self.gate_prob, max_gated=10, min_rows=2))

    def _run(self, rec, tag, cal, sigma_w) -> Estimates:
        log = calibrated_log(rec, tag, cal)
        ekf = self._filter(rec, tag, cal, sigma_w)
        fix = geometry.multilaterate(log.range_m, rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag))
        ok = np.flatnonzero(np.all(np.isfinite(fix.pos_m), axis=1))
        if ok.size == 0:
            T = len(log)
            return Estimates(log.t_s, np.full((T, cal.dim), np.nan), np.full(T, _NONE, np.int8), self.name)
        m = ekf.transition
        s = self.init_sigma
        x0 = Gaussian(m.initial_state(fix.pos_m[ok[0], : cal.dim]), m.initial_covariance(s, s, s))
        return ekf.run(log.t_s, list(log.range_m), x0, start=int(ok[0]), name=self.name).to_estimates()

    def tune(self, rec, tags, cal):
        grid = EKF_GRIDS[self.model] if self.grid is None else np.asarray(self.grid, float)
        cost = [np.mean([_errors_rmse(self._run(rec, t, cal, g), rec, t, cal.dim) for t in tags]) for g in grid]
        best = int(np.argmin(cost))
        return {"sigma_w": float(grid[best]), "grid": tuple(float(g) for g in grid),
                "grid_rmse_m": tuple(float(c) for c in cost), "grid_edge": on_grid_edge(best, len(grid))}

    def estimate(self, rec, tag, cal):
        return self._run(rec, tag, cal, cal.params(self.name)["sigma_w"])

    def bound(self, rec, tag, cal, est):
        log = calibrated_log(rec, tag, cal)
        pos = truth_at(rec, tag, log.t_s, cal.dim)
        have = np.all(np.isfinite(pos), axis=1)
        info = np.zeros((len(log), cal.dim, cal.dim))
        if have.any():
            info[have] = bounds.range_information(pos[have], rec.anchors.pos_m, cal.sigma(tag), z_m=cal.height(tag),
                                                  mask=np.isfinite(log.range_m[have]))
        C = np.full((len(log), cal.dim, cal.dim), np.nan)
        start = np.flatnonzero(est.has_estimate)
        kind = f"PCRLB {self.model} ranges"
        if start.size:
            k0 = int(start[0])
            m = self._filter(rec, tag, cal, cal.params(self.name)["sigma_w"]).transition
            s = self.init_sigma
            C[k0:] = bounds.tracking_bound(m, log.t_s[k0:], info[k0:], m.initial_covariance(s, s, s))
            C[~have] = np.nan
        return bounds.Bound(log.t_s, C, kind)


@dataclass(frozen=True)
class PrunedNls(WindowNls):
    """The windowed NLS of the board with one pruning heuristic of paper 001 (Zupanec et al., sec. 2.5)
    inside each window: ``"residual"`` (drop the largest residuals, re-solve) or ``"robust_mean"``
    (triplet fixes, pruned centroid line). Same windows and window tuning as ``NLS``; solved in
    2-D at the calibrated height (:func:`uwbwb.filters.pruning.localize`, ``stationary=False``).
    Bound: the line-fit CRLB of all the window's ranges (a lower bound for a fit that uses fewer).
    """

    heuristic: str = "residual"
    name: str = ""

    def __post_init__(self):
        if self.heuristic not in ("residual", "robust_mean"):
            raise ValueError(f"heuristic must be 'residual' or 'robust_mean' (moving windows), got {self.heuristic!r}")
        if not self.name:
            object.__setattr__(self, "name", f"NLS {PRUNING_LABELS[self.heuristic]}")

    def _run(self, rec, tag, cal, w) -> Estimates:
        log = calibrated_log(rec, tag, cal)
        T, d = len(log), cal.dim
        pos = np.full((T, d), np.nan)
        status = np.full(T, _NONE, np.int8)
        win = self._windows(log, w)
        config = PruningConfig(dim=d)
        for k in np.unique(win):
            idx = np.flatnonzero(win == k)
            part = log.select(idx)
            if idx.size < 3 or np.isfinite(part.range_m).sum() < 2 * d + 2:
                continue
            try:
                res = localize(part, rec.anchors, self.heuristic, config, stationary=False, z_m=cal.height(tag))
            except ValueError:
                continue
            if res.fit is not None and not res.fit.converged:
                continue
            pos[idx] = res.position_at(part.t_s)[:, :d]
            status[idx] = _UP
        return Estimates(log.t_s, pos, status, self.name, None, None, {"window": win})


@dataclass(frozen=True)
class StaticRangeModel:
    """Range error vs distance from the static files: ``range_meas ≈ scale · d + bias_m``.

    Fitted by least squares on the per-file medians of the measured range against the file's
    true range (one point per file: the ~90 samples of a file are one geometry), per condition.
    """

    condition: str
    scale: float
    bias_m: float
    n_files: int
    n_samples: int
    span_m: tuple[float, float]
    resid_sigma_m: float

    def correct(self, range_m: np.ndarray) -> np.ndarray:
        """Ranges with the static bias removed: ``(r − bias) / scale``."""
        return (np.asarray(range_m, float) - self.bias_m) / self.scale

    def describe(self) -> str:
        return (f"static {self.condition} model: range = {self.scale:.4f}·d {self.bias_m:+.3f} m "
                f"({self.n_files} files, {self.n_samples} samples, d {self.span_m[0]:g}–{self.span_m[1]:g} m, "
                f"file-median residual σ {self.resid_sigma_m:.3f} m)")


def static_range_model(condition: str = "LOS", data_dir: PathLike | None = None,
                       min_samples: int = 10) -> StaticRangeModel:
    """Fit :class:`StaticRangeModel` on the static files of ``condition`` (all heights).

    Files with fewer than ``min_samples`` samples are left out (header-only files have none).
    """
    df = hanyang.load_static(data_dir, condition=condition)
    med = df.groupby("file").agg(d=("true_range_m", "first"), r=("range_m", "median"), n=("range_m", "count"))
    med = med[med["n"] >= min_samples]
    if len(med) < 3 or med["d"].nunique() < 2:
        raise ValueError(f"static {condition} files: {len(med)} with at least {min_samples} samples "
                         f"at {med['d'].nunique()} distances; need 3 files at 2 distances for a line")
    A = np.column_stack([med["d"], np.ones(len(med))])
    (scale, bias), *_ = np.linalg.lstsq(A, med["r"].to_numpy(float), rcond=None)
    resid = med["r"].to_numpy(float) - A @ [scale, bias]
    return StaticRangeModel(condition, float(scale), float(bias), int(len(med)), int(med["n"].sum()),
                            (float(med["d"].min()), float(med["d"].max())), float(np.std(resid, ddof=2)))


@dataclass(frozen=True)
class StaticModelLs(BaseEstimator):
    """Unweighted multilateration (as ``raw LS``) of the ranges corrected by a static range model
    (:class:`StaticRangeModel`) instead of the board's per-pair calibration: does the static part's
    bias-vs-distance help the dynamic runs? Bound: the CRLB of the ranges (as ``raw LS``)."""

    model: StaticRangeModel | None = None
    name: str = ""

    def __post_init__(self):
        if self.model is None:
            raise ValueError("StaticModelLs needs a StaticRangeModel (static_range_model(...))")
        if not self.name:
            object.__setattr__(self, "name", f"LS static {self.model.condition} model")

    def estimate(self, rec, tag, cal):
        log = rec.ranges[tag]
        r = self.model.correct(log.range_m)
        res = geometry.multilaterate(np.maximum(r, 0.0), rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag),
                                     t_s=log.t_s, name=self.name)
        return res.to_estimates()

    def bound(self, rec, tag, cal, est):
        return _range_bound(rec, tag, cal, rec.ranges[tag])
