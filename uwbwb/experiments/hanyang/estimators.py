"""Estimators of the Hanyang study beside the board's defaults (which hold the EKFs on the ranges,
:class:`uwbwb.scoreboard.estimators.RangeEkfEstimator`): NLS with pruning, and LS on ranges corrected by
the static part's range model (:func:`static_range_model`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ...datasets import hanyang
from ...filters.pruning import LABELS as PRUNING_LABELS, PruningConfig, localize
from ...scoreboard.estimators import RawLs
from ...scoreboard.setnoise_nls import WindowNls
from ...types import RangeSamples

PathLike = str | os.PathLike


@dataclass(frozen=True)
class PrunedNls(WindowNls):
    """The windowed NLS of the board with one pruning heuristic of paper 001 (Zupanec et al., sec. 2.5)
    inside each window: ``"residual"`` (drop the largest residuals, re-solve) or ``"robust_mean"``
    (triplet fixes, pruned centroid line). Same windows and window tuning as ``NLS``; solved in
    2-D at the calibrated height (:func:`uwbwb.filters.pruning.localize`, ``stationary=False``); residual
    pruning starts from the window's plain NLS line, kept in ``fits`` (pass the ``NLS`` row's to share its lines).
    Bound: the line-fit CRLB of all the window's ranges (a lower bound for a fit that uses fewer).
    """

    heuristic: str = "residual"
    name: str = ""
    _covariance = False

    def __post_init__(self):
        if self.heuristic not in ("residual", "robust_mean"):
            raise ValueError(f"heuristic must be 'residual' or 'robust_mean' (moving windows), got {self.heuristic!r}")
        if not self.name:
            object.__setattr__(self, "name", f"NLS {PRUNING_LABELS[self.heuristic]}")

    def _fit(self, part, rec, tag, cal):
        samples = RangeSamples.from_ranges(part)
        if len(samples) < 2 * cal.dim + 2:
            return None
        plain = self._line(samples, rec, tag, cal) if self.heuristic == "residual" else None   # its first solve
        if self.heuristic == "residual" and plain is None:
            return None
        try:
            res = localize(samples, rec.anchors, self.heuristic, PruningConfig(dim=cal.dim), stationary=False,
                           z_m=cal.height(tag), fit=plain)
        except ValueError:
            return None
        if res.fit is not None and not res.fit.converged:
            return None
        return res.position_at(part.t_s)[:, :cal.dim], None


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


def static_model_ls(model: StaticRangeModel) -> RawLs:
    """``raw LS`` on the ranges corrected by a static range model instead of the board's per-pair calibration:
    does the static part's bias-vs-distance help the dynamic runs?"""
    return RawLs(f"LS static {model.condition} model", lambda t_s, range_m: np.maximum(model.correct(range_m), 0.0))
