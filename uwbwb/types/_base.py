"""The base of the array containers and the helpers they share: frozen arrays, the time check,
the time-window rule, the truth-gap constant, natural sort order."""

from __future__ import annotations

import re
from dataclasses import replace
from typing import ClassVar

import numpy as np
import pandas as pd

#: Largest truth sampling gap interpolated across, seconds: truth at a time between two samples
#: further apart than this (and not on a sample) is missing. Also the margin of truth kept beyond
#: each end of a time window, so that interpolation at its first and last epoch works.
MAX_TRUTH_GAP_S = 0.5


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


def _natural_key(s: str):
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s)]


class ArrayRecord:
    """Base of the frozen time-major containers: one row per epoch, ``t_s`` first.

    A subclass is a frozen dataclass that declares, as class attributes,

    ``_rows``
        The per-row array fields (leading axis ``T``; an optional one may be None).
    ``_row_maps``
        Fields that map names to per-row arrays (e.g. ``Estimates.info``).
    ``_columns``
        ``(field, template)`` pairs of the wide :meth:`to_frame`: ``"{a}"`` is replaced by
        the axis letters ``x, y, z`` of a 2-D field, ``"{i}{j}"`` by the indices of a 3-D one.

    Its ``__post_init__`` checks shapes and freezes the arrays (:func:`_frozen_array`, then
    :meth:`_set`). Row selection, the time window, time shifts and the wide table are written
    once here.

    **The time-window rule.** ``between(t_start_s, t_end_s)`` keeps the rows with
    ``t_start_s <= t_s < t_end_s`` (start kept, end left out), so consecutive windows
    ``[t0, t1), [t1, t2)`` share no row and together hold every row of ``[t0, t2)``.
    """

    _rows: ClassVar[tuple[str, ...]] = ("t_s",)
    _row_maps: ClassVar[tuple[str, ...]] = ()
    _columns: ClassVar[tuple[tuple[str, str], ...]] = ()

    def _set(self, **values) -> None:
        """Store checked (frozen) values on the frozen instance."""
        for name, value in values.items():
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return self.t_s.size

    def select(self, mask_or_index):
        """Rows selected by a boolean mask, an index array or a slice (time order kept)."""
        idx = np.arange(len(self))[mask_or_index]
        rows = {f: None if getattr(self, f) is None else getattr(self, f)[idx] for f in self._rows}
        rows.update({f: {k: v[idx] for k, v in getattr(self, f).items()} for f in self._row_maps})
        return replace(self, **rows)

    def between(self, t_start_s: float, t_end_s: float):
        """Rows with ``t_start_s <= t_s < t_end_s`` (the time-window rule, class docstring)."""
        return self.select((self.t_s >= t_start_s) & (self.t_s < t_end_s))

    def shifted(self, dt_s: float):
        """The same rows with ``dt_s`` added to every time stamp."""
        return replace(self, t_s=self.t_s + dt_s)

    def to_frame(self) -> pd.DataFrame:
        """Wide table: ``t_s``, then the columns of ``_columns`` (absent optional fields left out)."""
        return pd.DataFrame(self._wide_columns())

    def _wide_columns(self) -> dict[str, np.ndarray]:
        """The columns of :meth:`to_frame` by name, in order."""
        cols = {"t_s": self.t_s}
        for name, template in self._columns:
            a = getattr(self, name)
            if a is None:
                continue
            if a.ndim == 1:
                cols[template] = a
            elif a.ndim == 2:
                cols.update({template.format(a=axis): a[:, k] for k, axis in enumerate("xyz"[: a.shape[1]])})
            else:
                cols.update({template.format(i=i, j=j): a[:, i, j]
                             for i in range(a.shape[1]) for j in range(a.shape[2])})
        return cols
