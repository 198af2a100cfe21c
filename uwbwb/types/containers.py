"""Anchors, range logs, trajectories, IMU logs and the cleaning steps of a loader."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from ._base import ArrayRecord, _check_time, _frozen_array, _natural_key


def _optional_rows(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """A frozen copy of an optional per-row field, checked against ``shape``."""
    a = _frozen_array(name, value, ndim=len(shape))
    if a.shape != tuple(shape):
        raise ValueError(f"{name} must have shape {tuple(shape)}, got {a.shape}")
    return a


@dataclass(frozen=True)
class CleaningStep:
    """One cleaning action a loader took, with what it removed or changed.

    Attributes
    ----------
    name
        Short name of the step, e.g. ``"drop zero rows"``.
    n_affected
        Number of rows / samples removed or changed.
    detail
        Human-readable description (what, why, where).
    """

    name: str
    n_affected: int
    detail: str = ""

    def __str__(self) -> str:
        return f"{self.name}: {self.n_affected} ({self.detail})" if self.detail else f"{self.name}: {self.n_affected}"


@dataclass(frozen=True)
class Anchors:
    """Fixed anchor (sensor, beacon) positions.

    Attributes
    ----------
    ids
        Anchor identifiers, length ``n_anchors``.
    pos_m
        Positions, shape ``(n_anchors, 3)``, metres.
    """

    ids: tuple[str, ...]
    pos_m: np.ndarray

    def __post_init__(self):
        ids = tuple(str(i) for i in self.ids)
        pos = _frozen_array("Anchors.pos_m", self.pos_m, ndim=2)
        if pos.shape != (len(ids), 3):
            raise ValueError(f"Anchors.pos_m must have shape ({len(ids)}, 3), got {pos.shape}")
        if len(set(ids)) != len(ids):
            raise ValueError(f"Anchors.ids must be unique, got {ids}")
        if not np.all(np.isfinite(pos)):
            raise ValueError("Anchors.pos_m contains non-finite values")
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "pos_m", pos)

    def __len__(self) -> int:
        return len(self.ids)

    def index(self, anchor_id: str) -> int:
        """Position of ``anchor_id`` in :attr:`ids`."""
        try:
            return self.ids.index(str(anchor_id))
        except ValueError:
            raise KeyError(f"unknown anchor {anchor_id!r}; known: {list(self.ids)}") from None

    def subset(self, ids) -> "Anchors":
        """Anchors restricted to ``ids`` (in that order)."""
        idx = [self.index(i) for i in ids]
        return Anchors(tuple(self.ids[i] for i in idx), self.pos_m[idx])

    def to_frame(self) -> pd.DataFrame:
        """Tidy table with columns ``anchor_id, x_m, y_m, z_m``."""
        return pd.DataFrame({"anchor_id": list(self.ids), "x_m": self.pos_m[:, 0],
                             "y_m": self.pos_m[:, 1], "z_m": self.pos_m[:, 2]})

    @classmethod
    def from_frame(cls, df: pd.DataFrame) -> "Anchors":
        return cls(tuple(df["anchor_id"].astype(str)), df[["x_m", "y_m", "z_m"]].to_numpy(float))


@dataclass(frozen=True)
class RangeLog(ArrayRecord):
    """Ranges from one tag to a set of anchors, one row per epoch.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds, strictly increasing.
    range_m
        Measured ranges, shape ``(T, n_anchors)``, metres; NaN = no measurement.
    anchor_ids
        Column labels of ``range_m``, length ``n_anchors``.
    tag_id
        Identifier of the tag.
    t0
        Absolute time origin of ``t_s`` (metadata, e.g. a ``pandas.Timestamp``), or None.
    """

    t_s: np.ndarray
    range_m: np.ndarray
    anchor_ids: tuple[str, ...]
    tag_id: str = "tag"
    t0: object = None

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "range_m")

    def __post_init__(self):
        t = _frozen_array("RangeLog.t_s", self.t_s, ndim=1)
        r = _frozen_array("RangeLog.range_m", self.range_m, ndim=2)
        ids = tuple(str(i) for i in self.anchor_ids)
        if r.shape != (t.size, len(ids)):
            raise ValueError(f"RangeLog.range_m must have shape ({t.size}, {len(ids)}), got {r.shape}")
        _check_time(t, "RangeLog")
        if np.any(np.isinf(r)):
            raise ValueError("RangeLog.range_m contains infinite values (use NaN for missing)")
        if np.any(r < 0):
            raise ValueError("RangeLog.range_m contains negative ranges")
        self._set(t_s=t, range_m=r, anchor_ids=ids, tag_id=str(self.tag_id))

    @property
    def n_anchors(self) -> int:
        return len(self.anchor_ids)

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, anchor_id, range_m`` (missing ranges omitted), sorted by time."""
        ti, ai = np.nonzero(np.isfinite(self.range_m))
        return pd.DataFrame({"t_s": self.t_s[ti],
                             "anchor_id": np.asarray(self.anchor_ids, dtype=object)[ai],
                             "range_m": self.range_m[ti, ai]})

    @classmethod
    def from_frame(cls, df: pd.DataFrame, anchor_ids=None, tag_id: str = "tag", t0=None) -> "RangeLog":
        """Inverse of :meth:`to_frame`: pivot a tidy table to ``(T, n_anchors)``.

        Rows sharing ``t_s`` form one epoch. ``anchor_ids`` fixes the column order
        (and may include anchors that never appear); a (t_s, anchor_id) pair that
        occurs twice is an error, not silently averaged.
        """
        missing = {"t_s", "anchor_id", "range_m"} - set(df.columns)
        if missing:
            raise ValueError(f"range table lacks columns {sorted(missing)}")
        ids = df["anchor_id"].astype(str)
        if anchor_ids is None:
            anchor_ids = tuple(dict.fromkeys(sorted(ids.unique(), key=_natural_key)))
        anchor_ids = tuple(str(a) for a in anchor_ids)
        unknown = set(ids) - set(anchor_ids)
        if unknown:
            raise ValueError(f"range table has anchors {sorted(unknown)} not in anchor_ids {list(anchor_ids)}")
        dup = df.assign(anchor_id=ids).duplicated(["t_s", "anchor_id"])
        if dup.any():
            row = int(np.flatnonzero(dup.to_numpy())[0])
            raise ValueError(f"range table has a repeated (t_s, anchor_id) pair at row {row}")
        t_s, inv = np.unique(df["t_s"].to_numpy(float), return_inverse=True)
        col = pd.Index(anchor_ids).get_indexer(ids)
        r = np.full((t_s.size, len(anchor_ids)), np.nan)
        r[inv, col] = df["range_m"].to_numpy(float)
        return cls(t_s, r, anchor_ids, tag_id, t0)


@dataclass(frozen=True)
class Trajectory(ArrayRecord):
    """A sampled trajectory: ground truth or an estimate.

    Attributes
    ----------
    t_s
        Times, shape ``(T,)``, seconds, strictly increasing.
    pos_m
        Positions, shape ``(T, 2)`` or ``(T, 3)``, metres.
    vel_mps
        Optional velocities, same shape as ``pos_m``, m/s.
    rot
        Optional attitude as body-to-world rotation matrices, shape ``(T, 3, 3)``.
    name
        Label used in legends and tables (e.g. ``"truth"``, ``"EKF-RW"``).
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    vel_mps: np.ndarray | None = None
    rot: np.ndarray | None = None
    name: str = "trajectory"

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "pos_m", "vel_mps", "rot")
    _columns: ClassVar[tuple[tuple[str, str], ...]] = (("pos_m", "{a}_m"), ("vel_mps", "v{a}_mps"), ("rot", "r{i}{j}"))

    def __post_init__(self):
        t = _frozen_array("Trajectory.t_s", self.t_s, ndim=1)
        p = _frozen_array("Trajectory.pos_m", self.pos_m, ndim=2)
        if p.shape[0] != t.size or p.shape[1] not in (2, 3):
            raise ValueError(f"Trajectory.pos_m must have shape ({t.size}, 2|3), got {p.shape}")
        _check_time(t, "Trajectory")
        self._set(t_s=t, pos_m=p)
        if self.vel_mps is not None:
            self._set(vel_mps=_optional_rows("Trajectory.vel_mps", self.vel_mps, p.shape))
        if self.rot is not None:
            self._set(rot=_optional_rows("Trajectory.rot", self.rot, (t.size, 3, 3)))

    @property
    def dim(self) -> int:
        return self.pos_m.shape[1]

    def interp(self, t_s: np.ndarray) -> np.ndarray:
        """Linearly interpolated positions at ``t_s``, shape ``(len(t_s), dim)``.

        Times outside ``[t_s[0], t_s[-1]]`` give NaN (never extrapolated).
        """
        t_s = np.asarray(t_s, float)
        out = np.column_stack([np.interp(t_s, self.t_s, self.pos_m[:, k]) for k in range(self.dim)])
        out[(t_s < self.t_s[0]) | (t_s > self.t_s[-1])] = np.nan
        return out

    @classmethod
    def from_frame(cls, df: pd.DataFrame, name: str = "trajectory") -> "Trajectory":
        axes = "xyz" if "z_m" in df.columns else "xy"
        pos = df[[f"{a}_m" for a in axes]].to_numpy(float)
        vel = df[[f"v{a}_mps" for a in axes]].to_numpy(float) if f"v{axes[0]}_mps" in df.columns else None
        rot = None
        if "r00" in df.columns:
            rot = df[[f"r{i}{j}" for i in range(3) for j in range(3)]].to_numpy(float).reshape(-1, 3, 3)
        return cls(df["t_s"].to_numpy(float), pos, vel, rot, name)


@dataclass(frozen=True)
class ImuLog(ArrayRecord):
    """Inertial measurements in the sensor frame.

    Attributes
    ----------
    t_s
        Times, shape ``(T,)``, seconds, strictly increasing.
    acc_mps2
        Specific force, shape ``(T, 3)``, m/s², finite.
    gyro_radps
        Angular rate, shape ``(T, 3)``, rad/s, finite.
    """

    t_s: np.ndarray
    acc_mps2: np.ndarray
    gyro_radps: np.ndarray

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "acc_mps2", "gyro_radps")
    _columns: ClassVar[tuple[tuple[str, str], ...]] = (("acc_mps2", "acc_{a}_mps2"), ("gyro_radps", "gyro_{a}_radps"))

    def __post_init__(self):
        t = _frozen_array("ImuLog.t_s", self.t_s, ndim=1)
        a = _frozen_array("ImuLog.acc_mps2", self.acc_mps2, ndim=2)
        g = _frozen_array("ImuLog.gyro_radps", self.gyro_radps, ndim=2)
        for name, x in (("acc_mps2", a), ("gyro_radps", g)):
            if x.shape != (t.size, 3):
                raise ValueError(f"ImuLog.{name} must have shape ({t.size}, 3), got {x.shape}")
            bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
            if bad.size:     # a filter would read it as an IMU sample and blame the next UWB measurement
                raise ValueError(f"ImuLog.{name} must be finite: {bad.size} sample(s) hold NaN or inf, the first at "
                                 f"index {bad[0]} (t = {t[bad[0]]:.3f} s); drop or interpolate them when loading")
        _check_time(t, "ImuLog")
        self._set(t_s=t, acc_mps2=a, gyro_radps=g)

    @classmethod
    def from_frame(cls, df: pd.DataFrame) -> "ImuLog":
        return cls(df["t_s"].to_numpy(float),
                   df[[f"acc_{a}_mps2" for a in "xyz"]].to_numpy(float),
                   df[[f"gyro_{a}_radps" for a in "xyz"]].to_numpy(float))


