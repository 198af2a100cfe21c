"""Helpers shared by the containers: frozen arrays, the time check, natural sort order."""

from __future__ import annotations

import numpy as np


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
    import re
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s)]
