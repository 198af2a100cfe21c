"""TDoA logs and pseudo-TDoAs formed from two-way ranges."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from ._base import ArrayRecord
from .containers import RangeLog


# ====================================================================== TDoA logs

def pseudo_tdoa(range_m: np.ndarray, ref: int = 0, *, fallback: str = "nearest") -> tuple[np.ndarray, np.ndarray]:
    """Range differences to a reference anchor, per epoch.

    Parameters
    ----------
    range_m
        Ranges, shape ``(T, n_anchors)``, metres; NaN = no measurement.
    ref
        Index of the preferred reference anchor.
    fallback
        Reference for epochs where ``ref`` is missing: ``"nearest"`` (the anchor
        with the smallest measured range, the one most likely in line of sight)
        or ``"first"`` (the lowest-index available anchor).

    Returns
    -------
    tdoa_m : ndarray, shape ``(T, n_anchors)``
        ``range_m[t, j] − range_m[t, ref_t]``; 0 at the reference, NaN where missing.
    ref_idx : ndarray of int, shape ``(T,)``
        Reference anchor per epoch; −1 (and an all-NaN row) where fewer than two
        anchors were measured.
    """
    r = np.asarray(range_m, float)
    if r.ndim != 2:
        raise ValueError(f"pseudo_tdoa: range_m must be (T, n_anchors), got shape {r.shape}")
    n = r.shape[1]
    if not 0 <= ref < n:
        raise ValueError(f"pseudo_tdoa: reference index {ref} outside 0..{n - 1}")
    ok = np.isfinite(r)
    if fallback == "nearest":
        alt = np.argmin(np.where(ok, r, np.inf), axis=1)
    elif fallback == "first":
        alt = np.argmax(ok, axis=1)
    else:
        raise ValueError(f"pseudo_tdoa: fallback must be 'nearest' or 'first', got {fallback!r}")
    ref_idx = np.where(ok[:, ref], ref, alt)
    enough = ok.sum(axis=1) >= 2
    ref_idx = np.where(enough, ref_idx, -1)
    r_ref = np.take_along_axis(r, np.clip(ref_idx, 0, None)[:, None], axis=1)
    tdoa = r - r_ref
    tdoa[~enough] = np.nan
    tdoa[np.flatnonzero(enough), ref_idx[enough]] = 0.0
    return tdoa, ref_idx


@dataclass(frozen=True)
class TdoaLog(ArrayRecord):
    """TDoAs (range differences) of one tag, one row per epoch.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds, strictly increasing.
    tdoa_m
        ``r_j − r_ref``, shape ``(T, n_anchors)``, metres; 0 in the reference
        column, NaN where anchor ``j`` was not measured.
    ref
        Reference anchor index per epoch, shape ``(T,)``; −1 for epochs without
        a TDoA (all-NaN row).
    anchor_ids
        Column labels.
    tag_id
        Tag identifier.
    """

    t_s: np.ndarray
    tdoa_m: np.ndarray
    ref: np.ndarray
    anchor_ids: tuple[str, ...]
    tag_id: str = "tag"

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "tdoa_m", "ref")

    def __post_init__(self):
        t = np.array(self.t_s, float)
        d = np.array(self.tdoa_m, float)
        ref = np.array(self.ref, int)
        ids = tuple(map(str, self.anchor_ids))
        if t.ndim != 1 or d.shape != (t.size, len(ids)) or ref.shape != t.shape:
            raise ValueError(f"TdoaLog: need t_s (T,), tdoa_m (T, {len(ids)}), ref (T,); "
                             f"got {t.shape}, {d.shape}, {ref.shape}")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            raise ValueError("TdoaLog.t_s must be strictly increasing")
        if np.any((ref < -1) | (ref >= len(ids))):
            raise ValueError(f"TdoaLog.ref must be in -1..{len(ids) - 1}")
        has = ref >= 0
        if np.any(np.isfinite(d[~has])):
            raise ValueError("TdoaLog: epochs with ref = -1 must be all NaN")
        at_ref = d[np.flatnonzero(has), ref[has]]
        if np.any(at_ref != 0.0):
            raise ValueError("TdoaLog: tdoa_m must be exactly 0 in each epoch's reference column")
        if np.any(np.isfinite(d[has]).sum(axis=1) < 2):
            raise ValueError("TdoaLog: an epoch with a reference needs at least one other anchor")
        for arr in (t, d, ref):
            arr.setflags(write=False)
        self._set(t_s=t, tdoa_m=d, ref=ref, anchor_ids=ids, tag_id=str(self.tag_id))

    @classmethod
    def from_ranges(cls, log: RangeLog, ref: int | str = 0, *, fallback: str = "nearest") -> "TdoaLog":
        """Pseudo-TDoA from a :class:`RangeLog` (see :func:`pseudo_tdoa`).

        ``ref`` is an anchor index or an anchor id.
        """
        k = list(log.anchor_ids).index(str(ref)) if isinstance(ref, str) else int(ref)
        tdoa, ref_idx = pseudo_tdoa(log.range_m, k, fallback=fallback)
        return cls(log.t_s, tdoa, ref_idx, log.anchor_ids, log.tag_id)

    @property
    def n_anchors(self) -> int:
        return len(self.anchor_ids)

    @property
    def n_tdoa(self) -> np.ndarray:
        """Number of TDoAs per epoch (anchors measured − 1, or 0), shape ``(T,)``."""
        return np.maximum(np.isfinite(self.tdoa_m).sum(axis=1) - 1, 0)

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, anchor_id, ref_id, tdoa_m`` (reference and missing entries omitted)."""
        ti, ai = np.nonzero(np.isfinite(self.tdoa_m))
        keep = ai != self.ref[ti]
        ti, ai = ti[keep], ai[keep]
        ids = np.asarray(self.anchor_ids, dtype=object)
        return pd.DataFrame({"t_s": self.t_s[ti], "anchor_id": ids[ai], "ref_id": ids[self.ref[ti]],
                             "tdoa_m": self.tdoa_m[ti, ai]})


