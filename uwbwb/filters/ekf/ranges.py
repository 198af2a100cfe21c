"""Two-way ranges as :class:`~uwbwb.filters.ekf.Ekf` sees them: the range measurement adapter.

Beside :mod:`.tdoa` (range *differences*, notebook 03): where the anchors sit in a small cluster far from the
tag, range differences hardly locate it while the ranges do, so the same motion models run on the ranges
themselves (:class:`uwbwb.scoreboard.estimators.RangeEkfEstimator`, through :func:`run_ranges`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...models.motion import MotionModel
from ...types import RangeLog
from . import kernels
from .core import Ekf, KalmanRun, Linearisation

__all__ = ["RangeMeasurement", "run_ranges"]


@dataclass(frozen=True)
class RangeMeasurement:
    """Two-way ranges as :class:`~uwbwb.filters.ekf.Ekf` sees them: one epoch's measurement is a row of
    ``RangeLog.range_m`` (NaN = not measured), ``h_i(p) = |(p, z) − a_i|`` at the known tag height ``z_m``
    in 2-D (``|p − a_i|`` in 3-D), ``R = diag(σ_i²)``. It can re-linearise a subset of its anchors, so the
    anchor-dropping gate applies.

    Attributes
    ----------
    anchors_m
        Anchor positions, ``(n_anchors, 3)``, metres.
    sigma_m
        Range-noise standard deviation per anchor, ``(n_anchors,)``, metres.
    motion
        Motion model giving the state layout.
    z_m
        Tag height for a 2-D motion model, metres (ignored in 3-D).
    """

    anchors_m: np.ndarray
    sigma_m: np.ndarray
    motion: MotionModel
    z_m: float | None = None

    def __post_init__(self):
        if self.motion.dim == 2 and self.z_m is None:
            raise ValueError("a 2-D range model needs the tag height z_m")

    @staticmethod
    def epochs(log: RangeLog) -> list[np.ndarray]:
        """The measurements of a log, one row of ranges per epoch."""
        return list(log.range_m)

    def _lin(self, x: np.ndarray, row: np.ndarray, keep: np.ndarray) -> Linearisation:
        p = self.motion.position(x)
        p3 = np.r_[p, self.z_m] if p.size == 2 else p
        d = p3[None, :] - self.anchors_m[keep]
        r = np.linalg.norm(d, axis=1)
        H_pos = d[:, : p.size] / np.maximum(r, 1e-9)[:, None]
        return Linearisation(row[keep], r, H_pos @ self.motion.H_pos, np.diag(self.sigma_m[keep] ** 2))

    def linearise(self, x: np.ndarray, measurement) -> Linearisation | None:
        """Every measured anchor of the epoch, or None if none was measured."""
        row = np.asarray(measurement, float)
        keep = np.flatnonzero(np.isfinite(row))
        return None if keep.size == 0 else self._lin(x, row, keep)

    def components(self, measurement) -> np.ndarray:
        """The measured anchors of the epoch (sorted indices): what an anchor-dropping gate drops."""
        return np.flatnonzero(np.isfinite(np.asarray(measurement, float)))

    def linearise_components(self, x: np.ndarray, measurement, keep: np.ndarray) -> Linearisation:
        """Linearisation from anchors ``keep`` only."""
        return self._lin(x, np.asarray(measurement, float), np.asarray(keep))


def run_ranges(ekf: Ekf, log: RangeLog, x0, *, start: int = 0, name: str = "EKF") -> KalmanRun:
    """``ekf.run(log.t_s, RangeMeasurement.epochs(log), x0, start=start, name=name)`` for an :class:`Ekf` with a
    :class:`RangeMeasurement`: its compiled loop (:mod:`.kernels`, the Python run's decisions, its numbers to
    rounding within the twin's stated tolerance) where that runs the filter's gate, else the Python loop."""
    fast = None
    if type(ekf.measurement) is RangeMeasurement and isinstance(ekf.measurement.motion, MotionModel):
        fast = kernels.run(ekf, log.t_s, log.range_m, None, x0, start, name)
    return fast if fast is not None else ekf.run(log.t_s, RangeMeasurement.epochs(log), x0, start=start, name=name)
