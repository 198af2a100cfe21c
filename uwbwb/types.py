"""Containers shared by loaders, simulators, estimators and notebooks.

All containers are frozen dataclasses holding read-only numpy arrays in SI
units, time-major: ``t_s`` has shape ``(T,)``, per-epoch quantities ``(T, ...)``.
They validate shapes and units in ``__post_init__``; change them with
:func:`dataclasses.replace`. Every container has a tidy ``to_frame`` and a
matching ``from_frame`` so that round trips through pandas are exact.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field, replace
from typing import ClassVar, Mapping

import numpy as np
import pandas as pd


def _frozen_array(name: str, value, ndim: int | None = None, dtype=float) -> np.ndarray:
    arr = np.array(value, dtype=dtype, copy=True)
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


def _check_time(t_s: np.ndarray, owner: str) -> None:
    if not np.all(np.isfinite(t_s)):
        raise ValueError(f"{owner}.t_s contains non-finite values")
    if t_s.size > 1 and np.any(np.diff(t_s) <= 0):
        i = int(np.flatnonzero(np.diff(t_s) <= 0)[0])
        raise ValueError(
            f"{owner}.t_s must be strictly increasing; t_s[{i}]={t_s[i]!r} >= t_s[{i + 1}]={t_s[i + 1]!r}")


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
class RangeLog:
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
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "range_m", r)
        object.__setattr__(self, "anchor_ids", ids)
        object.__setattr__(self, "tag_id", str(self.tag_id))

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def n_anchors(self) -> int:
        return len(self.anchor_ids)

    def select(self, mask_or_index) -> "RangeLog":
        """Rows selected by a boolean mask or an index array (time order kept)."""
        idx = np.arange(len(self))[mask_or_index]
        return RangeLog(self.t_s[idx], self.range_m[idx], self.anchor_ids, self.tag_id, self.t0)

    def between(self, t_start_s: float, t_end_s: float) -> "RangeLog":
        """Rows with ``t_start_s <= t_s < t_end_s``."""
        return self.select((self.t_s >= t_start_s) & (self.t_s < t_end_s))

    def shifted(self, dt_s: float) -> "RangeLog":
        """The same log with ``dt_s`` added to every time stamp."""
        return RangeLog(self.t_s + dt_s, self.range_m, self.anchor_ids, self.tag_id, self.t0)

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


def _natural_key(s: str):
    import re
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s)]


@dataclass(frozen=True)
class Trajectory:
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

    def __post_init__(self):
        t = _frozen_array("Trajectory.t_s", self.t_s, ndim=1)
        p = _frozen_array("Trajectory.pos_m", self.pos_m, ndim=2)
        if p.shape[0] != t.size or p.shape[1] not in (2, 3):
            raise ValueError(f"Trajectory.pos_m must have shape ({t.size}, 2|3), got {p.shape}")
        _check_time(t, "Trajectory")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "pos_m", p)
        if self.vel_mps is not None:
            v = _frozen_array("Trajectory.vel_mps", self.vel_mps, ndim=2)
            if v.shape != p.shape:
                raise ValueError(f"Trajectory.vel_mps must have shape {p.shape}, got {v.shape}")
            object.__setattr__(self, "vel_mps", v)
        if self.rot is not None:
            R = _frozen_array("Trajectory.rot", self.rot, ndim=3)
            if R.shape != (t.size, 3, 3):
                raise ValueError(f"Trajectory.rot must have shape ({t.size}, 3, 3), got {R.shape}")
            object.__setattr__(self, "rot", R)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def dim(self) -> int:
        return self.pos_m.shape[1]

    def select(self, mask_or_index) -> "Trajectory":
        idx = np.arange(len(self))[mask_or_index]
        return Trajectory(self.t_s[idx], self.pos_m[idx],
                          None if self.vel_mps is None else self.vel_mps[idx],
                          None if self.rot is None else self.rot[idx], self.name)

    def between(self, t_start_s: float, t_end_s: float) -> "Trajectory":
        return self.select((self.t_s >= t_start_s) & (self.t_s < t_end_s))

    def shifted(self, dt_s: float) -> "Trajectory":
        return Trajectory(self.t_s + dt_s, self.pos_m, self.vel_mps, self.rot, self.name)

    def interp(self, t_s: np.ndarray) -> np.ndarray:
        """Linearly interpolated positions at ``t_s``, shape ``(len(t_s), dim)``.

        Times outside ``[t_s[0], t_s[-1]]`` give NaN (never extrapolated).
        """
        t_s = np.asarray(t_s, float)
        out = np.column_stack([np.interp(t_s, self.t_s, self.pos_m[:, k]) for k in range(self.dim)])
        out[(t_s < self.t_s[0]) | (t_s > self.t_s[-1])] = np.nan
        return out

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, x_m, y_m[, z_m][, vx_mps, ...][, r00 .. r22]``."""
        axes = "xyz"[: self.dim]
        cols = {"t_s": self.t_s}
        cols.update({f"{a}_m": self.pos_m[:, k] for k, a in enumerate(axes)})
        if self.vel_mps is not None:
            cols.update({f"v{a}_mps": self.vel_mps[:, k] for k, a in enumerate(axes)})
        if self.rot is not None:
            cols.update({f"r{i}{j}": self.rot[:, i, j] for i in range(3) for j in range(3)})
        return pd.DataFrame(cols)

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
class ImuLog:
    """Inertial measurements in the sensor frame.

    Attributes
    ----------
    t_s
        Times, shape ``(T,)``, seconds, strictly increasing.
    acc_mps2
        Specific force, shape ``(T, 3)``, m/s².
    gyro_radps
        Angular rate, shape ``(T, 3)``, rad/s.
    """

    t_s: np.ndarray
    acc_mps2: np.ndarray
    gyro_radps: np.ndarray

    def __post_init__(self):
        t = _frozen_array("ImuLog.t_s", self.t_s, ndim=1)
        a = _frozen_array("ImuLog.acc_mps2", self.acc_mps2, ndim=2)
        g = _frozen_array("ImuLog.gyro_radps", self.gyro_radps, ndim=2)
        for name, x in (("acc_mps2", a), ("gyro_radps", g)):
            if x.shape != (t.size, 3):
                raise ValueError(f"ImuLog.{name} must have shape ({t.size}, 3), got {x.shape}")
        _check_time(t, "ImuLog")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "acc_mps2", a)
        object.__setattr__(self, "gyro_radps", g)

    def __len__(self) -> int:
        return self.t_s.size

    def to_frame(self) -> pd.DataFrame:
        cols = {"t_s": self.t_s}
        cols.update({f"acc_{a}_mps2": self.acc_mps2[:, k] for k, a in enumerate("xyz")})
        cols.update({f"gyro_{a}_radps": self.gyro_radps[:, k] for k, a in enumerate("xyz")})
        return pd.DataFrame(cols)

    @classmethod
    def from_frame(cls, df: pd.DataFrame) -> "ImuLog":
        return cls(df["t_s"].to_numpy(float),
                   df[[f"acc_{a}_mps2" for a in "xyz"]].to_numpy(float),
                   df[[f"gyro_{a}_radps" for a in "xyz"]].to_numpy(float))


@dataclass(frozen=True)
class Recording:
    """Everything loaded from one recording of a dataset.

    Attributes
    ----------
    dataset
        Dataset name, e.g. ``"lias-planar-uwb"``.
    name
        Recording name within the dataset, e.g. ``"fast"`` or ``"8.14/pos1_deg_0"``.
    anchors
        Anchor positions in the frame of ``truth``.
    ranges
        One :class:`RangeLog` per tag, keyed by tag id.
    truth
        Ground-truth :class:`Trajectory` per tag id (may be empty), on the same
        clock as ``ranges`` after the loader's registration.
    imu
        Optional inertial log on the same clock.
    cleaning
        What the loader removed or changed, step by step.
    meta
        Anything else worth reporting (estimated clock offset, source paths, ...).
    """

    dataset: str
    name: str
    anchors: Anchors
    ranges: Mapping[str, RangeLog]
    truth: Mapping[str, Trajectory] = field(default_factory=dict)
    imu: ImuLog | None = None
    cleaning: tuple[CleaningStep, ...] = ()
    meta: Mapping[str, object] = field(default_factory=dict)

    def __post_init__(self):
        for tag, log in self.ranges.items():
            if tuple(log.anchor_ids) != tuple(self.anchors.ids):
                raise ValueError(f"range log of tag {tag!r} has anchors {log.anchor_ids}, "
                                 f"recording anchors are {self.anchors.ids}")
        unknown = set(self.truth) - set(self.ranges)
        if unknown:
            raise ValueError(f"truth given for tags {sorted(unknown)} that have no ranges")
        object.__setattr__(self, "cleaning", tuple(self.cleaning))

    @property
    def tags(self) -> tuple[str, ...]:
        return tuple(self.ranges)

    @property
    def label(self) -> str:
        """``dataset/name``, as used in the ``data`` column of summaries."""
        return f"{self.dataset}/{self.name}"

    def decimate(self, step: int) -> "Recording":
        """Every ``step``-th range epoch of every tag: the one thinning rule of the package.

        Ranges keep epochs ``0, step, 2·step, …`` of each tag. A tag's truth that is
        sampled on that tag's range epochs (same time stamps, e.g. static poses or a
        simulator's truth) is thinned alike; truth on its own clock (e.g. motion
        capture at another rate) is kept whole, since estimates are compared with it
        by interpolation. The IMU log is kept whole. ``meta["decimated"]`` holds the
        total step (steps multiply when decimating twice).

        Parameters
        ----------
        step
            Positive integer; 1 returns the recording unchanged.

        Raises
        ------
        ValueError
            If ``step`` is not a positive integer.
        """
        if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 1:
            raise ValueError(f"{self.label}: decimation step must be a positive integer, got {step!r}")
        step = int(step)
        if step == 1:
            return self
        ranges = {t: log.select(slice(None, None, step)) for t, log in self.ranges.items()}
        truth = {}
        for t, tr in self.truth.items():
            log = self.ranges[t]
            on_ranges = len(tr) == len(log) and np.array_equal(tr.t_s, log.t_s)
            truth[t] = tr.select(slice(None, None, step)) if on_ranges else tr
        meta = {**self.meta, "decimated": step * int(self.meta.get("decimated", 1))}
        return Recording(self.dataset, self.name, self.anchors, ranges, truth, self.imu, self.cleaning, meta)

    def cleaning_report(self) -> str:
        """One line per cleaning step, or a note that nothing was removed."""
        if not self.cleaning:
            return f"{self.label}: no cleaning steps were needed"
        return "\n".join(f"{self.label}: {s}" for s in self.cleaning)


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
class TdoaLog:
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
        for name, arr in (("t_s", t), ("tdoa_m", d), ("ref", ref)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "anchor_ids", ids)
        object.__setattr__(self, "tag_id", str(self.tag_id))

    @classmethod
    def from_ranges(cls, log: RangeLog, ref: int | str = 0, *, fallback: str = "nearest") -> "TdoaLog":
        """Pseudo-TDoA from a :class:`RangeLog` (see :func:`pseudo_tdoa`).

        ``ref`` is an anchor index or an anchor id.
        """
        k = list(log.anchor_ids).index(str(ref)) if isinstance(ref, str) else int(ref)
        tdoa, ref_idx = pseudo_tdoa(log.range_m, k, fallback=fallback)
        return cls(log.t_s, tdoa, ref_idx, log.anchor_ids, log.tag_id)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def n_anchors(self) -> int:
        return len(self.anchor_ids)

    @property
    def n_tdoa(self) -> np.ndarray:
        """Number of TDoAs per epoch (anchors measured − 1, or 0), shape ``(T,)``."""
        return np.maximum(np.isfinite(self.tdoa_m).sum(axis=1) - 1, 0)

    def select(self, mask_or_index) -> "TdoaLog":
        idx = np.arange(len(self))[mask_or_index]
        return TdoaLog(self.t_s[idx], self.tdoa_m[idx], self.ref[idx], self.anchor_ids, self.tag_id)

    def between(self, t_start_s: float, t_end_s: float) -> "TdoaLog":
        """Epochs with ``t_start_s <= t_s < t_end_s``."""
        return self.select((self.t_s >= t_start_s) & (self.t_s < t_end_s))

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, anchor_id, ref_id, tdoa_m`` (reference and missing entries omitted)."""
        ti, ai = np.nonzero(np.isfinite(self.tdoa_m))
        keep = ai != self.ref[ti]
        ti, ai = ti[keep], ai[keep]
        ids = np.asarray(self.anchor_ids, dtype=object)
        return pd.DataFrame({"t_s": self.t_s[ti], "anchor_id": ids[ai], "ref_id": ids[self.ref[ti]],
                             "tdoa_m": self.tdoa_m[ti, ai]})


# ====================================================================== sensor-set fixes (paper 000)

# Sensor sets are integer bit masks (bit ``i`` set <=> sensor ``i`` used), labelled as in the
# paper ('76540': members in descending order).

def set_id_from_mask(used: np.ndarray) -> np.ndarray:
    """Integer set ids from a boolean "sensor used" mask.

    Parameters
    ----------
    used
        Shape ``(..., n_sensors)``, bool; ``n_sensors <= 62``.

    Returns
    -------
    ndarray of int64, shape ``(...)``
        ``sum(2**i for used sensors i)``.
    """
    used = np.asarray(used, bool)
    n = used.shape[-1]
    if n > 62:
        raise ValueError(f"at most 62 sensors can be encoded in a set id, got {n}")
    return used.astype(np.int64) @ (np.int64(1) << np.arange(n, dtype=np.int64))


def set_members(set_id: int, n_sensors: int = 62) -> tuple[int, ...]:
    """Sensor indices in a set, ascending."""
    set_id = int(set_id)
    return tuple(i for i in range(n_sensors) if (set_id >> i) & 1)


def set_mask(set_id, n_sensors: int) -> np.ndarray:
    """Boolean mask ``(..., n_sensors)`` of the sensors in each set id (inverse of :func:`set_id_from_mask`)."""
    set_id = np.asarray(set_id, np.int64)
    return ((set_id[..., None] >> np.arange(n_sensors, dtype=np.int64)) & 1).astype(bool)


def set_label(set_id: int, sensor_ids=None) -> str:
    """The paper's label of a set: members in descending order, e.g. ``'76540'``.

    Parameters
    ----------
    set_id
        Bit mask of the set.
    sensor_ids
        Optional names of the sensors (index → name). Single-character names are
        concatenated as in the paper; longer names are joined with ``'+'``.
    """
    members = set_members(set_id)[::-1]
    if sensor_ids is None:
        names = [str(i) for i in members]
    else:
        names = [str(sensor_ids[i]) for i in members]
    return "".join(names) if all(len(n) == 1 for n in names) else "+".join(names)


def parse_set_label(label: str) -> int:
    """Set id of a paper-style label of single-digit sensors (``'76540'`` → 0b11110001)."""
    if not label.isdigit() or len(set(label)) != len(label):
        raise ValueError(f"a set label is distinct digits such as '76540', got {label!r}")
    return sum(1 << int(c) for c in label)


@dataclass(frozen=True, eq=False)
class SetFixLog:
    """Position fixes, each computed from a sensor set (Banerjee et al., paper 000: the observations ``Z`` of eq. 5).

    Attributes
    ----------
    t_s
        Fix times, shape ``(T,)``, seconds, strictly increasing.
    pos_m
        Fixed positions ``(x̃, ỹ)``, shape ``(T, 2)``, metres.
    set_id
        Sensor set of each fix as a bit mask, shape ``(T,)``, int64.
    sensor_ids
        Names of the sensors, index ``i`` ↔ bit ``i``.
    truth_m
        Optional true positions at ``t_s``, shape ``(T, 2)``, metres.
    name
        Label for legends and tables.
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    set_id: np.ndarray
    sensor_ids: tuple[str, ...]
    truth_m: np.ndarray | None = None
    name: str = "fixes"

    def __post_init__(self):
        t = np.array(self.t_s, float)
        p = np.array(self.pos_m, float)
        s = np.array(self.set_id, np.int64)
        if t.ndim != 1 or p.shape != (t.size, 2) or s.shape != t.shape:
            raise ValueError(f"SetFixLog needs shapes t_s (T,), pos_m (T, 2), set_id (T,); "
                             f"got {t.shape}, {p.shape}, {s.shape}")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            raise ValueError("SetFixLog.t_s must be strictly increasing")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
            raise ValueError("SetFixLog.t_s and pos_m must be finite (drop failed fixes before building the log)")
        ids = tuple(str(i) for i in self.sensor_ids)
        if np.any(s <= 0) or np.any(s >> len(ids)):
            raise ValueError(f"SetFixLog.set_id must be non-empty sets of the {len(ids)} sensors")
        arrays = [("t_s", t), ("pos_m", p), ("set_id", s)]
        if self.truth_m is not None:
            g = np.array(self.truth_m, float)
            if g.shape != p.shape:
                raise ValueError(f"SetFixLog.truth_m must have shape {p.shape}, got {g.shape}")
            arrays.append(("truth_m", g))
        for name, arr in arrays:
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "sensor_ids", ids)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def error_m(self) -> np.ndarray:
        """Fix minus truth, shape ``(T, 2)``, metres (needs ``truth_m``)."""
        if self.truth_m is None:
            raise ValueError(f"{self.name}: no truth to compute errors against")
        return self.pos_m - self.truth_m

    def labels(self) -> np.ndarray:
        """Paper-style set label of every fix, shape ``(T,)``, object."""
        uniq, inv = np.unique(self.set_id, return_inverse=True)
        return np.array([set_label(s, self.sensor_ids) for s in uniq], dtype=object)[inv]

    def set_frequency(self) -> pd.DataFrame:
        """Sets by decreasing frequency: ``set_id, label, count, share, cum_share``."""
        uniq, counts = np.unique(self.set_id, return_counts=True)
        order = np.lexsort((uniq, -counts))
        uniq, counts = uniq[order], counts[order]
        share = counts / counts.sum()
        return pd.DataFrame({"set_id": uniq, "label": [set_label(s, self.sensor_ids) for s in uniq],
                             "count": counts, "share": share, "cum_share": np.cumsum(share)})

    def select(self, mask_or_index) -> "SetFixLog":
        idx = np.arange(len(self))[mask_or_index]
        return SetFixLog(self.t_s[idx], self.pos_m[idx], self.set_id[idx], self.sensor_ids,
                         None if self.truth_m is None else self.truth_m[idx], self.name)

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, x_m, y_m, set_id, set_label[, true_x_m, true_y_m]``."""
        df = pd.DataFrame({"t_s": self.t_s, "x_m": self.pos_m[:, 0], "y_m": self.pos_m[:, 1],
                           "set_id": self.set_id, "set_label": self.labels()})
        if self.truth_m is not None:
            df["true_x_m"], df["true_y_m"] = self.truth_m[:, 0], self.truth_m[:, 1]
        return df


# ====================================================================== unrolled range samples

@dataclass(frozen=True)
class RangeSamples:
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
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "anchor_index", k)
        object.__setattr__(self, "range_m", r)
        object.__setattr__(self, "anchor_ids", ids)

    def __len__(self) -> int:
        return self.t_s.size

    def select(self, mask_or_index) -> "RangeSamples":
        """The samples selected by a boolean mask or an increasing index array."""
        idx = np.arange(len(self))[mask_or_index]
        return RangeSamples(self.t_s[idx], self.anchor_index[idx], self.range_m[idx], self.anchor_ids)

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
        None means raw multilateration is used
        (:func:`uwbwb.experiments.motion_models.raw_multilateration`).
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
    max_truth_gap_s: ClassVar[float] = 0.5

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


class EstimateStatus(enum.IntEnum):
    """What an estimator did at one epoch (stored as ``int8`` in :attr:`Estimates.status`).

    ``UPDATED``
        The epoch's measurements were used: a filter update, or a snapshot fix was computed.
    ``PREDICTED``
        A filter coasted: nothing usable was measured at this epoch (prediction only).
    ``GATED``
        A filter coasted: the epoch's measurements were rejected by its innovation gate.
    ``NO_ESTIMATE``
        Nothing to report: before initialisation, too few measurements, degenerate
        geometry or no convergence. ``pos_m`` is NaN there.
    """

    UPDATED = 0
    PREDICTED = 1
    GATED = 2
    NO_ESTIMATE = 3

    @property
    def label(self) -> str:
        """Lower-case name used in tables, e.g. ``"no_estimate"``."""
        return self.name.lower()


@dataclass(frozen=True)
class Estimates:
    """Per-epoch estimates of one method on one recording — the type every estimator returns.

    Snapshot methods (multilateration, TDoA LS) and tracking filters (EKF, PF, error-state
    filters) all report through this one shape, so metrics, plots and the scoreboard treat
    them alike: accuracy on :attr:`has_estimate` epochs, :attr:`coverage` beside it.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds, strictly increasing.
    pos_m
        Estimated positions, shape ``(T, dim)``, metres; NaN exactly where ``status`` is
        ``NO_ESTIMATE``.
    status
        :class:`EstimateStatus` per epoch, shape ``(T,)``.
    name
        Label in legends and tables (e.g. ``"LS"``, ``"EKF-RF"``).
    pos_cov_m2
        Position covariances, shape ``(T, dim, dim)``, m², or None if the method has none.
    vel_mps
        Velocity estimates, shape ``(T, dim)``, m/s, or None.
    info
        Extra per-epoch columns, each shape ``(T,)`` (e.g. ``nis``, ``dof``, ``n_rejected``).
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    status: np.ndarray
    name: str = "estimate"
    pos_cov_m2: np.ndarray | None = None
    vel_mps: np.ndarray | None = None
    info: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        t = _frozen_array("Estimates.t_s", self.t_s, ndim=1)
        p = _frozen_array("Estimates.pos_m", self.pos_m, ndim=2)
        T = t.size
        if p.shape[0] != T or p.shape[1] not in (2, 3):
            raise ValueError(f"Estimates.pos_m must have shape ({T}, 2|3), got {p.shape}")
        _check_time(t, "Estimates")
        st = np.array(self.status, copy=True)
        if st.shape != (T,) or not np.issubdtype(st.dtype, np.integer):
            raise ValueError(f"Estimates.status must be integer codes of shape ({T},), got {st.dtype} {st.shape}")
        codes = {int(s) for s in EstimateStatus}
        bad = ~np.isin(st, list(codes))
        if bad.any():
            raise ValueError(f"Estimates.status has unknown codes {sorted(set(st[bad].tolist()))}; "
                             f"known: {[s.label for s in EstimateStatus]}")
        st = st.astype(np.int8)
        st.setflags(write=False)
        none = st == EstimateStatus.NO_ESTIMATE
        finite = np.all(np.isfinite(p), axis=1)
        if np.any(finite == none):
            k = int(np.flatnonzero(finite == none)[0])
            raise ValueError(f"Estimates.pos_m must be finite exactly where status is not NO_ESTIMATE; "
                             f"epoch {k} has status {EstimateStatus(st[k]).label} and position {p[k].tolist()}")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "pos_m", p)
        object.__setattr__(self, "status", st)
        object.__setattr__(self, "name", str(self.name))
        d = p.shape[1]
        if self.pos_cov_m2 is not None:
            c = _frozen_array("Estimates.pos_cov_m2", self.pos_cov_m2, ndim=3)
            if c.shape != (T, d, d):
                raise ValueError(f"Estimates.pos_cov_m2 must have shape ({T}, {d}, {d}), got {c.shape}")
            object.__setattr__(self, "pos_cov_m2", c)
        if self.vel_mps is not None:
            v = _frozen_array("Estimates.vel_mps", self.vel_mps, ndim=2)
            if v.shape != p.shape:
                raise ValueError(f"Estimates.vel_mps must have shape {p.shape}, got {v.shape}")
            object.__setattr__(self, "vel_mps", v)
        info = {}
        for key, col in dict(self.info).items():
            a = np.array(col, copy=True)
            if a.shape != (T,):
                raise ValueError(f"Estimates.info[{key!r}] must have shape ({T},), got {a.shape}")
            a.setflags(write=False)
            info[str(key)] = a
        object.__setattr__(self, "info", info)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def dim(self) -> int:
        return self.pos_m.shape[1]

    @property
    def has_estimate(self) -> np.ndarray:
        """Epochs with a position, bool ``(T,)``."""
        return self.status != EstimateStatus.NO_ESTIMATE

    @property
    def coverage(self) -> float:
        """Share of epochs with a position (NaN for an empty series)."""
        return float(self.has_estimate.mean()) if len(self) else float("nan")

    def status_counts(self) -> dict[str, int]:
        """Number of epochs per status label (all labels present, zeros included)."""
        return {s.label: int(np.count_nonzero(self.status == s)) for s in EstimateStatus}

    def select(self, mask_or_index) -> "Estimates":
        """Epochs selected by a boolean mask or an index array (time order kept)."""
        idx = np.arange(len(self))[mask_or_index]
        pick = (lambda a: None if a is None else a[idx])
        return Estimates(self.t_s[idx], self.pos_m[idx], self.status[idx], self.name,
                         pick(self.pos_cov_m2), pick(self.vel_mps), {k: v[idx] for k, v in self.info.items()})

    def to_trajectory(self, name: str | None = None) -> Trajectory:
        """The epochs with a position, as a :class:`Trajectory`."""
        ok = self.has_estimate
        return Trajectory(self.t_s[ok], self.pos_m[ok], None if self.vel_mps is None else self.vel_mps[ok],
                          name=name or self.name)

    def to_frame(self) -> pd.DataFrame:
        """Table ``t_s, x_m, y_m[, z_m][, vx_mps ..][, sd_x_m ..], status`` (label) and the ``info`` columns."""
        axes = "xyz"[: self.dim]
        cols = {"t_s": self.t_s}
        cols.update({f"{a}_m": self.pos_m[:, k] for k, a in enumerate(axes)})
        if self.vel_mps is not None:
            cols.update({f"v{a}_mps": self.vel_mps[:, k] for k, a in enumerate(axes)})
        if self.pos_cov_m2 is not None:
            sd = np.sqrt(np.diagonal(self.pos_cov_m2, axis1=1, axis2=2))
            cols.update({f"sd_{a}_m": sd[:, k] for k, a in enumerate(axes)})
        labels = np.array([s.label for s in EstimateStatus])
        cols["status"] = labels[self.status]
        cols.update(self.info)
        return pd.DataFrame(cols)


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
class ChirpLog:
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
        if np.any(fl & ~np.int8(sum(ChirpFlag))):
            raise ValueError("ChirpLog.flags has unknown bits")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "beacon", b)
        object.__setattr__(self, "dp_s", dp)
        object.__setattr__(self, "flags", fl)
        object.__setattr__(self, "beacon_ids", ids)

    def __len__(self) -> int:
        return self.t_s.size

    def has(self, flag: ChirpFlag) -> np.ndarray:
        """Rows with ``flag`` set, bool ``(N,)``."""
        return (self.flags & int(flag)) != 0

    @property
    def measured(self) -> np.ndarray:
        """Rows that carry a ΔP, bool ``(N,)``."""
        return np.isfinite(self.dp_s)

    def select(self, mask_or_index) -> "ChirpLog":
        idx = np.arange(len(self))[mask_or_index]
        return ChirpLog(self.t_s[idx], self.beacon[idx], self.dp_s[idx], self.flags[idx], self.beacon_ids)

    def between(self, t_start_s: float, t_end_s: float) -> "ChirpLog":
        return self.select((self.t_s >= t_start_s) & (self.t_s <= t_end_s))

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
