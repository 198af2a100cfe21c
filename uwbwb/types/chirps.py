"""Ultrasonic chirp detections (paper 003)."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from ._base import ArrayRecord, _check_time, _frozen_array


class ChirpFlag(enum.IntFlag):
    """What the receiver made of one detected chirp (bits of :attr:`ChirpLog.flags`).

    ``LOCK``
        The detection started (or restarted) a beacon's chirp train: it is assigned but
        has no ΔP yet (there is no previous chirp of that beacon to measure from).
    ``GAP``
        The previous chirp(s) of the beacon were missed; ΔP is the mean shift per period
        over the ``k`` periods since the last detection.
    ``AMBIGUOUS``
        The detection fits more than one beacon's train; it was assigned to the closest fit.
    ``UNASSIGNED``
        The detection fits no beacon (a spurious detection, a reflection, or a beacon that
        is not locked yet); ``beacon`` is −1 and ``dp_s`` is NaN.
    """

    LOCK = 1
    GAP = 2
    AMBIGUOUS = 4
    UNASSIGNED = 8


@dataclass(frozen=True)
class ChirpLog(ArrayRecord):
    """Chirps detected by one ultrasonic receiver, one row per detection (paper 003).

    Attributes
    ----------
    t_s
        Arrival times, shape ``(N,)``, seconds, strictly increasing.
    beacon
        Index into ``beacon_ids`` of the beacon each chirp was assigned to, shape ``(N,)``,
        int; −1 where it was not assigned.
    dp_s
        Measured period shift ΔP (observed period minus the beacon's nominal period),
        shape ``(N,)``, seconds; NaN where the row carries no measurement.
    flags
        :class:`ChirpFlag` bits per row, shape ``(N,)``, int8.
    beacon_ids
        Beacon identifiers (the order of the beacon layout).
    """

    t_s: np.ndarray
    beacon: np.ndarray
    dp_s: np.ndarray
    flags: np.ndarray
    beacon_ids: tuple[str, ...]

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "beacon", "dp_s", "flags")

    def __post_init__(self):
        t = _frozen_array("ChirpLog.t_s", self.t_s, ndim=1)
        b = _frozen_array("ChirpLog.beacon", self.beacon, ndim=1, dtype=np.int64)
        dp = _frozen_array("ChirpLog.dp_s", self.dp_s, ndim=1)
        fl = _frozen_array("ChirpLog.flags", self.flags, ndim=1, dtype=np.int8)
        ids = tuple(str(i) for i in self.beacon_ids)
        n = t.size
        for name, a in (("beacon", b), ("dp_s", dp), ("flags", fl)):
            if a.shape != (n,):
                raise ValueError(f"ChirpLog.{name} must have shape ({n},), got {a.shape}")
        _check_time(t, "ChirpLog")
        if len(set(ids)) != len(ids) or not ids:
            raise ValueError(f"ChirpLog.beacon_ids must be unique and non-empty, got {ids}")
        if np.any((b < -1) | (b >= len(ids))):
            raise ValueError(f"ChirpLog.beacon must be -1 or an index below {len(ids)}")
        if np.any(np.isinf(dp)):
            raise ValueError("ChirpLog.dp_s contains infinite values (use NaN for none)")
        if np.any(np.isfinite(dp) & (b < 0)):
            raise ValueError("ChirpLog: a row with a ΔP must be assigned to a beacon")
        def has(flag):
            return (fl & int(flag)) != 0
        # the flags must agree with the fields they describe (the file format's rules, datasets.chirps)
        if np.any(has(ChirpFlag.UNASSIGNED) & ((b >= 0) | (fl != int(ChirpFlag.UNASSIGNED)))):
            raise ValueError("ChirpLog: an 'unassigned' row has no beacon and no other flag")
        if np.any(has(ChirpFlag.LOCK) & ((b < 0) | np.isfinite(dp))):
            raise ValueError("ChirpLog: a 'lock' row has a beacon and no ΔP")
        if np.any(has(ChirpFlag.GAP) & ~np.isfinite(dp)):
            raise ValueError("ChirpLog: a 'gap' row has a ΔP")
        if np.any(has(ChirpFlag.AMBIGUOUS) & (b < 0)):
            raise ValueError("ChirpLog: an 'ambiguous' row has a beacon")
        if np.any(fl & ~np.int8(sum(ChirpFlag))):
            raise ValueError("ChirpLog.flags has unknown bits")
        self._set(t_s=t, beacon=b, dp_s=dp, flags=fl, beacon_ids=ids)

    def has(self, flag: ChirpFlag) -> np.ndarray:
        """Rows with ``flag`` set, bool ``(N,)``."""
        return (self.flags & int(flag)) != 0

    @property
    def measured(self) -> np.ndarray:
        """Rows that carry a ΔP, bool ``(N,)``."""
        return np.isfinite(self.dp_s)

    def counts(self) -> dict[str, int]:
        """Rows in total, with a ΔP, and per flag."""
        out = {"detections": len(self), "with ΔP": int(self.measured.sum())}
        out.update({f.name.lower(): int(self.has(f).sum()) for f in ChirpFlag})
        return out

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, beacon_id, dp_s, flags`` (``beacon_id`` "" if unassigned; flags as names joined by ``+``)."""
        ids = np.array(("",) + self.beacon_ids, dtype=object)[self.beacon + 1]
        names = [f for f in ChirpFlag]
        flags = ["+".join(f.name.lower() for f in names if v & int(f)) for v in self.flags]
        return pd.DataFrame({"t_s": self.t_s, "beacon_id": ids, "dp_s": self.dp_s, "flags": flags})

    @classmethod
    def from_frame(cls, df: pd.DataFrame, beacon_ids) -> "ChirpLog":
        ids = tuple(str(i) for i in beacon_ids)
        lookup = {b: i for i, b in enumerate(ids)}
        lookup[""] = -1
        beacon = [lookup[str(b)] if isinstance(b, str) or not pd.isna(b) else -1 for b in df["beacon_id"]]
        flags = []
        for text in df["flags"].fillna(""):
            v = 0
            for part in filter(None, str(text).split("+")):
                v |= int(ChirpFlag[part.upper()])
            flags.append(v)
        return cls(df["t_s"].to_numpy(float), np.array(beacon, int), df["dp_s"].to_numpy(float),
                   np.array(flags, np.int8), ids)
