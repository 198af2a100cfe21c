"""Ranges unrolled to one entry per measurement, and one tag's run (ranges, truth, raw output)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np
import pandas as pd

from ._base import MAX_TRUTH_GAP_S, ArrayRecord
from .containers import Anchors, RangeLog, Trajectory
from .tdoa import TdoaLog


# ====================================================================== unrolled range samples

@dataclass(frozen=True)
class RangeSamples(ArrayRecord):
    """Ranges unrolled to one entry per measurement (the ``D`` of Zupanec et al. eq. 1).

    Attributes
    ----------
    t_s
        Measurement times, shape ``(M,)``, seconds (non-decreasing).
    anchor_index
        Index of the anchor of each range, shape ``(M,)``, into ``anchor_ids``.
    range_m
        Measured ranges, shape ``(M,)``, metres, finite.
    anchor_ids
        Labels of the anchors (columns of the range log they came from).
    """

    t_s: np.ndarray
    anchor_index: np.ndarray
    range_m: np.ndarray
    anchor_ids: tuple[str, ...]

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "anchor_index", "range_m")

    def __post_init__(self):
        t = np.array(self.t_s, float)
        k = np.array(self.anchor_index, np.intp)
        r = np.array(self.range_m, float)
        ids = tuple(str(a) for a in self.anchor_ids)
        if t.ndim != 1 or k.shape != t.shape or r.shape != t.shape:
            raise ValueError(f"t_s, anchor_index and range_m must be 1-D of equal length, "
                             f"got {t.shape}, {k.shape}, {r.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(r))):
            raise ValueError("RangeSamples hold finite times and ranges only (drop missing ranges first)")
        if np.any(r < 0):
            raise ValueError("RangeSamples.range_m contains negative ranges")
        if k.size and (k.min() < 0 or k.max() >= len(ids)):
            raise ValueError(f"anchor_index must lie in [0, {len(ids)})")
        if t.size > 1 and np.any(np.diff(t) < 0):
            raise ValueError("RangeSamples.t_s must be non-decreasing")
        for a in (t, k, r):
            a.setflags(write=False)
        self._set(t_s=t, anchor_index=k, range_m=r, anchor_ids=ids)

    def to_matrix(self) -> tuple[np.ndarray, np.ndarray]:
        """Back to epochs: unique times ``(T,)`` and ranges ``(T, n_anchors)`` (NaN = none).

        If an anchor has two samples at one time, the later one is kept.
        """
        t, inv = np.unique(self.t_s, return_inverse=True)
        r = np.full((t.size, len(self.anchor_ids)), np.nan)
        r[inv, self.anchor_index] = self.range_m
        return t, r

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, anchor_id, range_m``."""
        return pd.DataFrame({"t_s": self.t_s,
                             "anchor_id": np.asarray(self.anchor_ids, object)[self.anchor_index],
                             "range_m": self.range_m})

    @classmethod
    def from_ranges(cls, ranges: "RangeLog | np.ndarray", t_s=None, anchor_ids=None) -> "RangeSamples":
        """Unroll a ``(T, n_anchors)`` range table (NaN = missing) to :class:`RangeSamples`.

        Parameters
        ----------
        ranges
            A :class:`RangeLog`, or an array ``(T, n_anchors)`` in metres
            together with ``t_s`` ``(T,)`` (seconds).
        t_s, anchor_ids
            Only for an array input; ``anchor_ids`` defaults to ``"0", "1", ...``.
        """
        if isinstance(ranges, RangeLog):
            if t_s is not None or anchor_ids is not None:
                raise ValueError("t_s and anchor_ids come from the RangeLog")
            t_s, r, anchor_ids = ranges.t_s, ranges.range_m, ranges.anchor_ids
        else:
            r = np.asarray(ranges, float)
            if r.ndim != 2:
                raise ValueError(f"ranges must have shape (T, n_anchors), got {r.shape}")
            if t_s is None:
                raise ValueError("an array of ranges needs t_s")
            t_s = np.asarray(t_s, float)
            if t_s.shape != (r.shape[0],):
                raise ValueError(f"t_s must have shape ({r.shape[0]},), got {t_s.shape}")
            anchor_ids = tuple(str(i) for i in range(r.shape[1])) if anchor_ids is None else anchor_ids
            if len(anchor_ids) != r.shape[1]:
                raise ValueError(f"{len(anchor_ids)} anchor_ids for {r.shape[1]} columns")
        ti, ai = np.nonzero(np.isfinite(r))
        return cls(t_s[ti], ai, r[ti, ai], tuple(anchor_ids))


# ====================================================================== one tag of one recording

@dataclass(frozen=True)
class TagRun:
    """One tag of one recording, ready for the estimators.

    Attributes
    ----------
    data
        Summary label: ``"synthetic"`` or ``"dataset/recording"``.
    name
        Display name of the acquisition (``"office"``, ``"fast"``, ``"scenario2"``...).
    tag
        Tag id.
    ranges
        The tag's ranges.
    truth
        Ground truth of the tag (3-D positions; errors are horizontal).
    anchors
        Anchor positions (columns of ``ranges``).
    dim
        Estimated coordinates: 2 (tag at known height ``z_m``) or 3.
    z_m
        Tag height for ``dim=2`` (known mounting height), metres.
    raw
        The device's own output if the acquisition has one (synthetic: :func:`uwbwb.sim.walk.device_output`);
        None means per-epoch multilateration of the ranges is used (the board's ``RawLs``).
    """

    data: str
    name: str
    tag: str
    ranges: RangeLog
    truth: Trajectory
    anchors: Anchors
    dim: int = 2
    z_m: float = 0.0
    raw: Trajectory | None = field(default=None, repr=False)

    #: Largest truth sampling gap interpolated across when computing errors, seconds.
    max_truth_gap_s: ClassVar[float] = MAX_TRUTH_GAP_S

    def __post_init__(self):
        if self.dim not in (2, 3):
            raise ValueError(f"TagRun.dim must be 2 or 3, got {self.dim!r}")
        if tuple(self.ranges.anchor_ids) != tuple(self.anchors.ids):
            raise ValueError(f"{self.name}/{self.tag}: range columns {self.ranges.anchor_ids} differ from the "
                             f"anchors {self.anchors.ids}")
        if len(self.ranges) < 2:
            raise ValueError(f"{self.name}/{self.tag}: fewer than two epochs")

    @property
    def key(self) -> str:
        """``"name/tag"``."""
        return f"{self.name}/{self.tag}"

    @property
    def dt_s(self) -> float:
        """Nominal epoch period (median step), seconds."""
        return float(np.median(np.diff(self.ranges.t_s)))

    def tdoa(self, ref: int = 0, *, fallback: str = "nearest") -> TdoaLog:
        """Pseudo-TDoA of this run to anchor index ``ref``."""
        return TdoaLog.from_ranges(self.ranges, ref, fallback=fallback)

    def true_range_m(self) -> np.ndarray:
        """Ranges predicted from truth at the range epochs, ``(T, n_anchors)``; NaN outside the truth span."""
        pos = self.truth.interp(self.ranges.t_s)
        if pos.shape[1] != 3:
            raise ValueError(f"{self.key}: true ranges need 3-D truth, got {pos.shape[1]}-D")
        return np.linalg.norm(pos[:, None, :] - self.anchors.pos_m, axis=-1)

    def between(self, t_start_s: float, t_end_s: float, name: str | None = None) -> "TagRun":
        """The epochs in ``[t_start_s, t_end_s)`` (truth and raw output cut alike)."""
        pad = self.max_truth_gap_s
        return replace(self, name=name or self.name, ranges=self.ranges.between(t_start_s, t_end_s),
                       truth=self.truth.between(t_start_s - pad, t_end_s + pad),
                       raw=None if self.raw is None else self.raw.between(t_start_s, t_end_s))

