"""The cleaning rules every loader applies: one rule per kind of bad value.

Loaders parse their format and then hand the rows to these functions, so a
given defect gets the same treatment whatever file it is found in. Each
function returns what it kept and a :class:`~uwbwb.types.CleaningStep` for
everything it removed or changed; nothing is dropped silently, and whatever
cannot be repaired without guessing is a :class:`~uwbwb.errors.DataFormatError`
naming the file, the line and the column.

The rules
---------
Missing values (NaN)
    NaN means "no measurement" and nothing else. A loader turns a format's own
    "no value" marker (an ``ERR`` status, an empty slot, a 0 that the format
    documents as "no range") into NaN and counts it; a time stamp must never be
    NaN (an error). When two rows are compared, NaN equals NaN.
Time order (:func:`order_rows`)
    Rows are returned in strictly increasing time (or, for formats with one row
    per anchor, strictly increasing ``(time, key)``). A format whose documentation
    guarantees time order treats a step back as an error; the others are sorted
    (stably) and the rows that moved are counted.
Repeated time stamps
    Rows that repeat an earlier row's time (and key) exactly are dropped and
    counted. Different rows with one time are an error, except in formats whose
    stamps are coarser than their rate (LIAS: 1 ms stamps), where the later row
    is dropped and counted.
Ranges (:func:`check_ranges`)
    A negative range cannot come from two-way ranging: an error. A range above
    ``max_range_m`` (default :data:`MAX_RANGE_M`) is a device failure value: set
    to NaN and counted. A range of exactly 0 becomes NaN (counted) in formats that
    document 0 as "no range"; elsewhere it is kept. Outliers within that span (NLOS,
    a few metres) are measurements: rejecting them is an estimator's business.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..errors import DataFormatError
from ..types import CleaningStep

__all__ = ["MAX_RANGE_M", "check_ranges", "lines_text", "order_rows"]

#: Largest plausible two-way range, metres. An assumption: UWB links reported in
#: the literature reach a few hundred metres at most (the public datasets here stay
#: below 60 m), while device failure values such as 652.8 m or 1e9 m lie beyond it.
MAX_RANGE_M = 300.0

_BACKWARDS = ("sort", "error")
_REPEATS = ("drop_identical", "drop_later", "error", "keep")


def lines_text(line_no: np.ndarray, limit: int = 5) -> str:
    """``"3, 7, 12, ..."``: the first ``limit`` of some 1-based file lines."""
    line_no = np.asarray(line_no).ravel()
    shown = ", ".join(str(int(v)) for v in line_no[:limit])
    return shown + (", ..." if line_no.size > limit else "")


def _same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise equality with NaN equal to NaN; rows of 2-D arrays, or elements of 1-D ones."""
    eq = (a == b) | (_isnan(a) & _isnan(b))
    return eq.all(axis=tuple(range(1, eq.ndim))) if eq.ndim > 1 else eq


def _show(value) -> str:
    """A value for a message: numpy scalars shown as the Python number they hold."""
    return repr(value.item() if isinstance(value, np.generic) else value)


def _isnan(x: np.ndarray) -> np.ndarray:
    return np.isnan(x) if x.dtype.kind == "f" else np.zeros(x.shape, bool)


def order_rows(path: str | os.PathLike, t: np.ndarray, line_no: np.ndarray, *, what: str,
               backwards: str = "sort", repeats: str = "drop_identical", key: np.ndarray | None = None,
               values: np.ndarray | None = None) -> tuple[np.ndarray, list[CleaningStep]]:
    """Put rows in time order and remove repeats, by the package's one rule (module notes).

    Parameters
    ----------
    path
        The file, for messages.
    t
        Time of each row, shape ``(N,)``, any unit (compared exactly).
    line_no
        1-based file line of each row, shape ``(N,)``.
    what
        What a row is, for messages (``"UWB"``, ``"ground-truth"``...).
    backwards
        ``"sort"``: sort stably by time and count the rows that moved;
        ``"error"``: a time smaller than the previous row's is an error.
    repeats
        What to do with rows whose ``(t, key)`` equals an earlier row's:
        ``"drop_identical"`` drops exact repeats (counted) and raises on different
        rows; ``"drop_later"`` drops the later row whatever it holds (counted; for
        stamps coarser than the rate); ``"error"`` raises on any repeat;
        ``"keep"`` keeps them (for stamps that repeat by design and are resolved
        by the loader, e.g. whole-second IMU stamps).
    key
        Integer code per row, shape ``(N,)``, for formats with several rows per
        time (one per anchor): repeats are rows with the same time *and* key.
    values
        What must be equal for a repeat to be exact, shape ``(N, ...)``; default
        ``t`` and ``key`` only (every repeat is then exact).

    Returns
    -------
    index : numpy.ndarray
        Indices into the input rows, in output order, shape ``(M,)``.
    steps : list of CleaningStep
        ``"rows sorted by time"`` and ``"repeated rows dropped"`` when they did anything.

    Raises
    ------
    DataFormatError
        A time that is not finite, a step back under ``backwards="error"``, a repeat
        that is not allowed.
    ValueError
        An unknown policy or arrays of different lengths.
    """
    if backwards not in _BACKWARDS:
        raise ValueError(f"backwards must be one of {_BACKWARDS}, got {backwards!r}")
    if repeats not in _REPEATS:
        raise ValueError(f"repeats must be one of {_REPEATS}, got {repeats!r}")
    t = np.asarray(t)
    line_no = np.asarray(line_no)
    n = t.shape[0]
    for name, arr in (("line_no", line_no), ("key", key), ("values", values)):
        if arr is not None and np.shape(arr)[0] != n:
            raise ValueError(f"{name} has {np.shape(arr)[0]} rows, t has {n}")
    name = Path(path).name
    if t.dtype.kind == "f":
        bad = ~np.isfinite(t)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DataFormatError(path, f"{what} time {_show(t[i])} is not a finite number", line=int(line_no[i]))
    steps: list[CleaningStep] = []
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size and backwards == "error":
        i = int(back[0]) + 1
        raise DataFormatError(path, f"{what} time goes back from {_show(t[i - 1])} (line {line_no[i - 1]}) to {_show(t[i])}; "
                                    f"files of this format are written in time order, so it looks spliced or corrupt",
                              line=int(line_no[i]))
    if back.size:
        order = np.argsort(t, kind="stable")
        moved = order != np.arange(n)
        steps.append(CleaningStep("rows sorted by time", int(moved.sum()),
                                  f"{name}: {what} rows out of time order, sorted (first lines "
                                  f"{lines_text(np.sort(line_no[moved]))})"))
        del moved
        ts = t[order]
    else:
        order, ts = np.arange(n), t            # already in order: no copies
    if repeats == "keep":
        return order, steps
    # repeats: rows with equal (t, key). Time is sorted, so they lie within runs of equal time; with a key
    # the rows are grouped by (run, key) with a stable sort so that the first occurrence is kept.
    if key is None:
        group = None
        rep = np.flatnonzero(ts[1:] == ts[:-1]) + 1
    else:
        ks = np.asarray(key, np.int64)
        ks = ks[order] if back.size else ks
        run = np.zeros(n, np.int64)
        np.cumsum(ts[1:] != ts[:-1], out=run[1:])
        combined = run * (int(ks.max()) + 1 if n else 1) + (ks - int(ks.min()) if n else ks)
        del run
        group = np.argsort(combined, kind="stable")
        combined = combined[group]
        rep = np.flatnonzero(combined[1:] == combined[:-1]) + 1
        del combined
    if rep.size:
        pos_later, pos_earlier = (rep, rep - 1) if group is None else (group[rep], group[rep - 1])
        later, earlier = order[pos_later], order[pos_earlier]   # indices into the input rows
        if repeats == "error":
            raise DataFormatError(path, f"repeated {what} time {_show(t[later[0]])} (first on line {line_no[earlier[0]]})",
                                  line=int(line_no[later[0]]))
        if repeats == "drop_identical" and values is not None:
            v = np.asarray(values)
            identical = _same(v[later], v[earlier])
            if not identical.all():
                k = int(np.flatnonzero(~identical)[0])
                raise DataFormatError(path, f"two different {what} rows share time {_show(t[later[k]])} (other one on "
                                            f"line {line_no[earlier[k]]})", line=int(line_no[later[k]]))
        detail = ("exact repeats of an earlier row" if repeats == "drop_identical"
                  else "same time stamp as the previous row (stamps coarser than the rate); later row")
        steps.append(CleaningStep("repeated rows dropped", int(rep.size),
                                  f"{name}: {what} {detail} dropped (lines {lines_text(np.sort(line_no[later]))})"))
        drop = np.zeros(n, bool)
        drop[pos_later] = True
        order = order[~drop]
    return order, steps


def check_ranges(path: str | os.PathLike, range_m: np.ndarray, line_no: np.ndarray, *,
                 max_range_m: float = MAX_RANGE_M, zero_is_missing: bool = False,
                 columns: list[str] | tuple[str, ...] | None = None,
                 ignore: np.ndarray | None = None) -> tuple[np.ndarray, list[CleaningStep]]:
    """Apply the range rule (module notes) to measured ranges.

    Parameters
    ----------
    path
        The file, for messages.
    range_m
        Ranges, metres, shape ``(N,)`` or ``(N, ...)`` (row = file line); NaN is
        already missing and left alone.
    line_no
        1-based file line of each row, shape ``(N,)``.
    max_range_m
        Ranges above this become NaN (counted). Must be positive.
    zero_is_missing
        The format documents a range of 0 as "no range": zeros become NaN (counted).
    columns
        Column name of each range of a row (flattened), for messages.
    ignore
        Same shape as ``range_m``: entries not subject to the rule (e.g. rows
        marked ``ERR``, whose number means nothing); they are returned unchanged.

    Returns
    -------
    range_m : numpy.ndarray
        A copy with NaN where values were removed.
    steps : list of CleaningStep
        ``"zero ranges -> missing"``, ``"implausible ranges -> missing"`` when they did anything.

    Raises
    ------
    DataFormatError
        A negative range (naming line and column).
    ValueError
        ``max_range_m`` not a positive number.
    """
    if isinstance(max_range_m, bool) or not isinstance(max_range_m, (int, float, np.floating, np.integer)) \
            or not max_range_m > 0 or math.isnan(max_range_m):
        raise ValueError(f"max_range_m must be a positive number of metres, got {max_range_m!r}")
    r = np.array(range_m, dtype=float, copy=True)
    line_no = np.asarray(line_no)
    check = np.ones(r.shape, bool) if ignore is None else ~np.asarray(ignore, bool)
    name = Path(path).name
    flat = r.reshape(r.shape[0], int(np.prod(r.shape[1:])))
    check_flat = check.reshape(flat.shape)

    def where(mask):
        i, j = (int(k[0]) for k in np.nonzero(mask))
        col = columns[j] if columns is not None else None
        return i, j, col

    negative = check_flat & (flat < 0)
    if negative.any():
        i, j, col = where(negative)
        raise DataFormatError(path, f"negative range {flat[i, j]:g} m: two-way ranging cannot give one",
                              line=int(line_no[i]), column=col)
    steps: list[CleaningStep] = []

    def to_missing(mask, step: str, what: str):
        """Set the masked ranges to NaN and record the step naming the lines."""
        if mask.any():
            rows = np.flatnonzero(mask.any(axis=1))
            steps.append(CleaningStep(step, int(mask.sum()),
                                      f"{name}: {what} set to NaN (lines {lines_text(line_no[rows])})"))
            flat[mask] = np.nan

    if zero_is_missing:
        to_missing(check_flat & (flat == 0), "zero ranges -> missing", "the format's 'no range' value 0")
    to_missing(check_flat & (flat > max_range_m), "implausible ranges -> missing",
               f"ranges above {max_range_m:g} m (device failure values)")
    return flat.reshape(r.shape), steps
