"""The estimator interface of the board, and the pieces every adapter shares.

A method joins the board by implementing :class:`Estimator` (see :mod:`.estimators` for what each
member means); :class:`BaseEstimator` gives the defaults. The helpers place truth on a tag's
epochs (:func:`truth_at`, one gap rule: :data:`MAX_TRUTH_GAP_S`), apply the shared range
calibration (:func:`calibrated_log`) and evaluate the range and TDoA information the adapters'
bounds are built from.
"""

from __future__ import annotations

from typing import Mapping, Protocol, Sequence, runtime_checkable

import numpy as np

from .. import bounds, metrics
from ..models.tdoa import TdoaModel
from ..types import EstimateStatus, Estimates, MAX_TRUTH_GAP_S, RangeLog, Recording
from .protocol import Calibration

__all__ = ["Estimator", "BaseEstimator", "calibrated_log", "truth_at", "on_grid_edge"]

_UP, _NONE = int(EstimateStatus.UPDATED), int(EstimateStatus.NO_ESTIMATE)


@runtime_checkable
class Estimator(Protocol):
    """What the board needs from a method (module docstring)."""

    name: str

    def applies(self, rec: Recording, tag: str, cal: Calibration) -> str | None: ...

    def tune(self, rec: Recording, tags: Sequence[str], cal: Calibration) -> Mapping: ...

    def estimate(self, rec: Recording, tag: str, cal: Calibration) -> Estimates: ...

    def bound(self, rec: Recording, tag: str, cal: Calibration, est: Estimates) -> bounds.Bound: ...


class BaseEstimator:
    """Defaults: applies everywhere, tunes nothing."""

    name = "estimator"

    def applies(self, rec: Recording, tag: str, cal: Calibration) -> str | None:
        return None

    def tune(self, rec: Recording, tags: Sequence[str], cal: Calibration) -> Mapping:
        return {}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


# ----------------------------------------------------------------------------- shared pieces

def calibrated_log(rec: Recording, tag: str, cal: Calibration) -> RangeLog:
    """``tag``'s ranges with the calibration's per-pair bias/scale removed."""
    return cal.range_calibration.apply(rec.ranges[tag])


def truth_at(rec: Recording, tag: str, t_s: np.ndarray, dim: int) -> np.ndarray:
    """True positions ``(T, dim)`` at ``t_s`` by the one truth rule (:meth:`uwbwb.types.Recording.truth_at`:
    NaN outside the truth or in gaps over :data:`~uwbwb.types.MAX_TRUTH_GAP_S`)."""
    return rec.truth_at(tag, t_s, dim)


def _range_bound(rec, tag, cal, log: RangeLog, kind="CRLB ranges") -> bounds.Bound:
    pos = truth_at(rec, tag, log.t_s, cal.dim)
    have = np.all(np.isfinite(pos), axis=1)
    C = np.full((len(log), cal.dim, cal.dim), np.nan)
    if have.any():
        info = bounds.range_information(pos[have], rec.anchors.pos_m, cal.sigma(tag), z_m=cal.height(tag),
                                        mask=np.isfinite(log.range_m[have]))
        C[have] = bounds.crlb(info)
    return bounds.Bound(log.t_s, C, kind)


def _tdoa_model(rec, tag, cal) -> TdoaModel:
    return TdoaModel(rec.anchors.pos_m, cal.sigma(tag), dim=cal.dim, z_m=cal.height(tag) or 0.0)


def _tdoa_information(rec, tag, cal, log: RangeLog) -> tuple[np.ndarray, np.ndarray]:
    """TDoA information ``(T, dim, dim)`` at the true positions, and where truth exists ``(T,)``."""
    pos = truth_at(rec, tag, log.t_s, cal.dim)
    have = np.all(np.isfinite(pos), axis=1)
    info = np.zeros((len(log), cal.dim, cal.dim))
    if have.any():
        mask = np.isfinite(log.range_m[have])
        info[have] = np.where((mask.sum(axis=1) >= 2)[:, None, None],
                              bounds.tdoa_information(pos[have], _tdoa_model(rec, tag, cal), mask=mask), 0.0)
    return info, have


def _errors_rmse(est: Estimates, rec: Recording, tag: str, dim: int) -> float:
    """RMSE (horizontal) of ``est`` against ``rec``'s truth: what tuning on the calibration part minimises."""
    tr = est.to_trajectory()
    if len(tr) == 0:
        return float("inf")
    e = metrics.errors_vs_truth(tr, rec.truth[tag], horizontal=True, max_gap_s=MAX_TRUTH_GAP_S)
    return metrics.rmse(e.err_m) if len(e) else float("inf")


def on_grid_edge(best: int, n: int) -> bool:
    """Whether a tuning pick (index ``best`` of ``n`` ordered grid values) is on the grid's edge, where a
    wider grid might do better (a one-value grid tunes nothing: always on its edge)."""
    return n < 2 or best in (0, n - 1)
