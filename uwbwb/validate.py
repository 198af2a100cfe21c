"""Checks of public parameters where they enter the package.

Every function here returns the value (converted to a plain Python number where
that is the point) or raises a :class:`ValueError` that names the parameter and
says what was expected, so that a wrong value is reported at the call that
passed it, never as a numpy broadcasting error, a ``TypeError`` deep inside a
loop, or a silently wrong result.

Examples
--------
>>> integer("n_particles", 1000, minimum=1)
1000
>>> number("k", -1.0, minimum=0.0)
Traceback (most recent call last):
    ...
ValueError: k must be a finite number >= 0, got -1.0
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Iterable

import numpy as np

__all__ = ["choice", "integer", "number", "points", "probability"]


def integer(name: str, value: Any, *, minimum: int | None = None, maximum: int | None = None) -> int:
    """An integer (not a bool, not a float that happens to be whole) in ``[minimum, maximum]``."""
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool) and type(value).__name__ != "bool_"
    if ok and minimum is not None and value < minimum:
        ok = False
    if ok and maximum is not None and value > maximum:
        ok = False
    if not ok:
        bounds = _bounds(minimum, maximum)
        raise ValueError(f"{name} must be an integer{bounds}, got {value!r}")
    return int(value)


def number(name: str, value: Any, *, minimum: float | None = None, maximum: float | None = None,
           strict_minimum: bool = False, allow_inf: bool = False) -> float:
    """A real, finite number (``inf`` only with ``allow_inf``) in the given range.

    ``strict_minimum`` makes the lower bound exclusive (``> minimum``).
    """
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and type(value).__name__ != "bool_"
    v = float(value) if ok else math.nan
    if ok:
        ok = not math.isnan(v) and (allow_inf or math.isfinite(v))
    if ok and minimum is not None:
        ok = v > minimum if strict_minimum else v >= minimum
    if ok and maximum is not None:
        ok = v <= maximum
    if not ok:
        lo = (f" > {minimum:g}" if strict_minimum else f" >= {minimum:g}") if minimum is not None else ""
        hi = f"{' and' if lo else ''} <= {maximum:g}" if maximum is not None else ""
        raise ValueError(f"{name} must be a {'' if allow_inf else 'finite '}number{lo}{hi}, got {value!r}")
    return v


def probability(name: str, value: Any, *, open_interval: bool = True) -> float:
    """A probability: in ``(0, 1)`` (``open_interval``) or ``[0, 1]``."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and type(value).__name__ != "bool_"
    v = float(value) if ok else math.nan
    ok = ok and (0.0 < v < 1.0 if open_interval else 0.0 <= v <= 1.0)
    if not ok:
        raise ValueError(f"{name} must be a number in {'(0, 1)' if open_interval else '[0, 1]'}, got {value!r}")
    return v


def choice(name: str, value: Any, options: Iterable) -> Any:
    """One of ``options``."""
    options = tuple(options)
    if not any(value == o and type(value) is type(o) for o in options):
        raise ValueError(f"{name} must be one of {', '.join(map(repr, options))}, got {value!r}")
    return value


def points(name: str, value: Any, *, minimum: int = 1) -> np.ndarray:
    """Points in space (anchors, stations): a new float array of shape ``(n, 3)``, ``n >= minimum``, metres."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (n >= {minimum}, 3) array of points, got {value!r}") from None
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] < minimum:
        raise ValueError(f"{name} must be an (n >= {minimum}, 3) array of points, got shape {arr.shape}")
    return arr


def _bounds(minimum, maximum) -> str:
    if minimum is not None and maximum is not None:
        return f" in [{minimum}, {maximum}]"
    if minimum is not None:
        return f" >= {minimum}"
    if maximum is not None:
        return f" <= {maximum}"
    return ""
