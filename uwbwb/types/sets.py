"""Sensor-set fixes of paper 000: set ids, labels, masks and the fix log."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from ._base import ArrayRecord


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
class SetFixLog(ArrayRecord):
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

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "pos_m", "set_id", "truth_m")

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
        for _, arr in arrays:
            arr.setflags(write=False)
        self._set(**dict(arrays), sensor_ids=ids)

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

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, x_m, y_m, set_id, set_label[, true_x_m, true_y_m]``."""
        df = pd.DataFrame({"t_s": self.t_s, "x_m": self.pos_m[:, 0], "y_m": self.pos_m[:, 1],
                           "set_id": self.set_id, "set_label": self.labels()})
        if self.truth_m is not None:
            df["true_x_m"], df["true_y_m"] = self.truth_m[:, 0], self.truth_m[:, 1]
        return df


