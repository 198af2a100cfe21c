"""Readers of the LIAS planar UWB text files: UWB range CSVs and motion-capture CSVs.

The formats are described in :mod:`uwbwb.datasets.lias` (module notes); the loaders there
call these readers. Every problem is a :class:`~uwbwb.errors.DataFormatError` naming file
and line; every cleaning step is reported.
"""

from __future__ import annotations

import io
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFormatError
from ..types import CleaningStep
from .cleaning import MAX_RANGE_M, check_ranges, lines_text, order_rows
from .text import NUMBER_RE, _decode_lines, _read_bytes

__all__ = ["read_mocap_csv", "read_uwb_csv"]

_N_ANCHORS = 8
_N_TAGS = 3
_STAMP_RE = r"\d{4}-\d{1,2}-\d{1,2} \d{1,2}:\d{2}:\d{2}(?:\.\d{1,6})?"
_STAMP_FORMAT = "%Y-%m-%d %H:%M:%S.%f"
_MOCAP_HEADER = "time,x,y,z,rotation,,,"
_PLAIN_TEXT = re.compile(r"[0-9.,:\-+eE \n]*")


def _read_lines(path: Path) -> list[str]:
    """Lines of a text file without line ends; trailing blank lines removed.

    Raises DataFormatError for an empty file, undecodable bytes or a blank line
    between data lines.
    """
    raw = _read_bytes(path)
    if not raw.strip():
        raise DataFormatError(path, "file is empty (expected CSV rows)", line=1)
    lines = _decode_lines(path, raw)
    while lines and not lines[-1].strip():
        lines.pop()
    for i, ln in enumerate(lines):
        if not ln.strip():
            raise DataFormatError(path, "blank line between data rows", line=i + 1)
    return lines


def _read_table(path: Path, lines: list[str], first_line: int, width: int, col_names,
                col_offset: int):
    """Time stamps and numbers of CSV lines that must all have ``width`` fields.

    Returns ``stamps`` (N,) str, ``values`` (N, width - 1) float with NaN for empty
    fields, and ``filled`` (N, width - 1) bool. Files made only of digits, signs,
    separators and exponents go through pandas' C parser; anything else, or a parser
    failure, through a field-by-field check that names the offending line and column.
    """
    counts = np.fromiter((ln.count(",") + 1 for ln in lines), dtype=int, count=len(lines))
    bad = np.flatnonzero(counts != width)
    if bad.size:
        i = int(bad[0])
        raise DataFormatError(path, f"{counts[i]} comma-separated fields, expected {width} "
                                    f"like the rest of the file", line=first_line + i)
    text = "\n".join(lines)
    if _PLAIN_TEXT.fullmatch(text):
        try:
            frame = pd.read_csv(io.StringIO(text), header=None, names=range(width), engine="c",
                                dtype={0: str, **{c: float for c in range(1, width)}},
                                keep_default_na=False, na_values={c: [""] for c in range(1, width)},
                                skip_blank_lines=False)
        except ValueError:
            pass
        else:
            values = frame.iloc[:, 1:].to_numpy(float)
            if values.shape == (len(lines), width - 1):
                return frame[0].to_numpy(str), values, ~np.isnan(values)
    cells = np.array([ln.split(",") for ln in lines], dtype=object)
    fields = cells[:, 1:]
    filled = fields != ""
    tokens = pd.Series(fields[filled], dtype=object)
    ok = tokens.str.fullmatch(NUMBER_RE).to_numpy(bool)
    if not ok.all():
        i, j = (int(k[np.flatnonzero(~ok)[0]]) for k in np.nonzero(filled))
        raise DataFormatError(path, f"{fields[i, j]!r} is not a number", line=first_line + i,
                              column=_column_label(col_names, j, col_offset))
    values = np.full(fields.shape, np.nan)
    values[filled] = tokens.astype(float).to_numpy()
    return cells[:, 0].astype(str), values, filled


def _parse_stamps(path: Path, stamps: np.ndarray, first_line: int) -> pd.Series:
    """Parse ``YYYY-MM-DD H:MM:SS.fff`` wall-clock stamps; errors name the line."""
    s = pd.Series(stamps, dtype=object)
    ok = s.str.fullmatch(_STAMP_RE).to_numpy(bool)
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        raise DataFormatError(path, f"time stamp {str(stamps[i])!r} is not 'YYYY-MM-DD H:MM:SS.fff'",
                              line=first_line + i, column="time")
    no_frac = ~s.str.contains(".", regex=False).to_numpy(bool)
    if no_frac.any():
        s = s.where(~no_frac, s + ".0")
    t = pd.to_datetime(s, format=_STAMP_FORMAT, errors="coerce")
    bad = t.isna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataFormatError(path, f"time stamp {str(stamps[i])!r} is not a valid date and time",
                              line=first_line + i, column="time")
    return t


def _seconds_since(t: pd.Series, t0: pd.Timestamp) -> np.ndarray:
    return (t - t0).dt.total_seconds().to_numpy(float)


def _column_label(names, j: int, offset: int) -> str:
    name = names[j] if j < len(names) else "extra slot"
    return f"{j + offset} ({name})"


# ----------------------------------------------------------------------------- UWB files

def read_uwb_csv(path: str | os.PathLike, *, n_anchors: int = _N_ANCHORS, n_tags: int = _N_TAGS,
                 max_range_m: float = MAX_RANGE_M, return_cleaning: bool = False):
    """Read one UWB range file (dynamic or static; the format is the same).

    Parameters
    ----------
    path
        A headerless CSV: time stamp ``YYYY-MM-DD H:MM:SS.fff`` then ``n_anchors * n_tags``
        ranges ordered a0-t0, a0-t1, ..., a1-t0, ..., possibly followed by empty extra
        slots in groups of ``n_tags`` (see the module notes).
    n_anchors, n_tags
        Expected numbers of anchors and tags (8 and 3 in the published set).
    max_range_m
        Ranges above this are device failure values and become NaN (counted); default
        :data:`~uwbwb.datasets.cleaning.MAX_RANGE_M`.
    return_cleaning
        Also return the list of :class:`~uwbwb.types.CleaningStep` taken.

    Returns
    -------
    t_s : ndarray, shape (T,)
        Seconds since ``t0``, strictly increasing.
    range_m : ndarray, shape (T, n_anchors, n_tags)
        Ranges in metres; NaN where the file holds a zero or a value above
        ``max_range_m`` (failed measurement).
    t0 : pandas.Timestamp
        The stamp on the file's first line (wall clock of the logging PC).
    cleaning : list of CleaningStep
        Only with ``return_cleaning=True``: incomplete rows dropped, extra slots
        ignored, repeated stamps dropped, zero and implausible ranges set to NaN (steps
        that affected nothing are left out).

    Raises
    ------
    DataFormatError
        Naming the file, line and column: wrong field count, an empty field between
        values, a partial anchor group, a non-numeric or negative range, a malformed or
        backwards time stamp, an empty file, no complete row at all, or values in the extra
        slots on most rows (the file has more anchors or tags than expected).
    """
    for name, n in (("n_anchors", n_anchors), ("n_tags", n_tags)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"{name} must be a positive integer, got {n!r}")
    path = Path(path)
    n_pairs = n_anchors * n_tags
    names = [f"a{a}-t{t}" for a in range(n_anchors) for t in range(n_tags)]
    lines = _read_lines(path)
    n_fields = lines[0].count(",") + 1
    if n_fields - 1 < n_pairs or (n_fields - 1) % n_tags:
        raise DataFormatError(path, f"{n_fields} fields; expected a time stamp and {n_pairs} ranges "
                                    f"(a0-t0 ... a{n_anchors - 1}-t{n_tags - 1}), possibly followed by "
                                    f"empty extra slots in groups of {n_tags}", line=1)
    stamps, values, filled = _read_table(path, lines, 1, n_fields, names, 2)
    n_rows, n_slots = values.shape
    n_val = filled.sum(axis=1)
    holes = filled != (np.arange(n_slots) < n_val[:, None])
    if holes.any():
        i, j = (int(k[0]) for k in np.nonzero(holes))
        raise DataFormatError(path, "empty range field followed by more values (the logger only "
                                    "leaves fields empty at the end of a row)",
                              line=i + 1, column=_column_label(names, j, 2))
    partial = n_val % n_tags != 0
    if partial.any():
        i = int(np.flatnonzero(partial)[0])
        raise DataFormatError(path, f"{n_val[i]} range values, not a whole number of anchors "
                                    f"({n_tags} tags each)", line=i + 1)

    t_abs = _parse_stamps(path, stamps, 1)
    t0 = t_abs.iloc[0]
    t_all = _seconds_since(t_abs, t0)
    line_no = np.arange(1, n_rows + 1)
    order_rows(path, t_all, line_no, what="UWB", backwards="error", repeats="keep")

    cleaning: list[CleaningStep] = []
    complete = n_val >= n_pairs
    if not complete.all():
        cleaning.append(CleaningStep(
            "incomplete UWB rows", int((~complete).sum()),
            f"rows with fewer than {n_pairs} ranges: the logger leaves out anchors that did not "
            f"answer and shifts the rest left, so the values cannot be assigned to anchors; "
            f"dropped (lines {lines_text(np.flatnonzero(~complete) + 1)})"))
    extra = complete & (n_val > n_pairs)
    if extra.sum() > 0.5 * complete.sum():
        i = int(np.flatnonzero(extra)[0])
        raise DataFormatError(path, f"{extra.sum()} of {complete.sum()} complete rows hold more than "
                                    f"{n_pairs} ranges: the file has more anchors or tags than the "
                                    f"{n_anchors} x {n_tags} expected", line=i + 1)
    if extra.any():
        cleaning.append(CleaningStep(
            "extra range slots ignored", int(extra.sum()),
            f"rows with values in the slots after the {n_pairs} ranges (anchors not in the "
            f"tables); the {n_pairs} ranges kept, the extra values ignored "
            f"(lines {lines_text(np.flatnonzero(extra) + 1)})"))
    keep = np.flatnonzero(complete)
    if keep.size == 0:
        raise DataFormatError(path, f"no row holds all {n_pairs} ranges", line=1)
    t_s, rng, kept_lines = t_all[keep], values[keep, :n_pairs], line_no[keep]
    idx, steps = order_rows(path, t_s, kept_lines, what="UWB", backwards="error", repeats="drop_later")
    t_s, rng, kept_lines = t_s[idx], rng[idx], kept_lines[idx]
    rng, more = check_ranges(path, rng, kept_lines, max_range_m=max_range_m, zero_is_missing=True,
                             columns=[_column_label(names, j, 2) for j in range(n_pairs)])
    cleaning += steps + more
    out = (t_s, rng.reshape(-1, n_anchors, n_tags), t0)
    return out + (cleaning,) if return_cleaning else out


# ----------------------------------------------------------------------------- motion capture

def read_mocap_csv(path: str | os.PathLike, *, return_cleaning: bool = False):
    """Read one motion-capture file.

    Parameters
    ----------
    path
        CSV with header ``time,x,y,z,rotation,,,`` and rows: time stamp, centroid x, y, z
        (m), four quaternion components.
    return_cleaning
        As in :func:`read_uwb_csv`.

    Returns
    -------
    t_s : ndarray, shape (T,)
        As in :func:`read_uwb_csv`.
    pos_m : ndarray, shape (T, 3)
        Trolley centroid in the anchor frame, metres.
    quat : ndarray, shape (T, 4)
        The four quaternion columns exactly as in the file (their order is decided by
        :func:`load_dynamic`; upstream documents (qw, qx, qy, qz)).
    t0 : pandas.Timestamp
        Stamp of the first data row (motion-capture PC clock).
    cleaning : list of CleaningStep
        Only with ``return_cleaning=True``: repeated stamps and all-zero (dropout) rows dropped.

    Raises
    ------
    DataFormatError
        Naming file, line and column: missing or wrong header, wrong field count,
        non-numeric value, a coordinate beyond 1 km, a quaternion whose norm is not 1, a
        malformed or backwards time stamp, no data rows.
    """
    path = Path(path)
    lines = _read_lines(path)
    head = [c.strip().lower() for c in lines[0].split(",")]
    if len(head) != 8 or head[:4] != ["time", "x", "y", "z"]:
        raise DataFormatError(path, f"header {lines[0]!r}; expected {_MOCAP_HEADER!r} "
                                    f"(time, centroid x, y, z, four quaternion columns)", line=1)
    if len(lines) < 2:
        raise DataFormatError(path, "header only, no motion-capture samples", line=1)
    names = ["x", "y", "z", "q1", "q2", "q3", "q4"]
    stamps, values, filled = _read_table(path, lines[1:], 2, 8, names, 2)
    if not filled.all():
        i, j = (int(k[0]) for k in np.nonzero(~filled))
        raise DataFormatError(path, "empty value", line=i + 2, column=_column_label(names, j, 2))
    t_abs = _parse_stamps(path, stamps, 2)
    t0 = t_abs.iloc[0]
    t_s = _seconds_since(t_abs, t0)
    line_no = np.arange(2, len(lines) + 1)
    order_rows(path, t_s, line_no, what="motion-capture", backwards="error", repeats="keep")

    cleaning: list[CleaningStep] = []
    dropout = np.all(values == 0, axis=1)
    if dropout.any():
        cleaning.append(CleaningStep("motion-capture dropouts", int(dropout.sum()),
                                     "rows of all zeros (tracking lost); dropped "
                                     f"(lines {lines_text(np.flatnonzero(dropout) + 2)})"))
    far = ~dropout[:, None] & (np.abs(values[:, :3]) > 1e3)
    if far.any():
        i, j = (int(k[0]) for k in np.nonzero(far))
        raise DataFormatError(path, f"coordinate {values[i, j]:g} m is implausible for an indoor "
                                    f"motion-capture volume", line=i + 2, column=_column_label(names, j, 2))
    norm = np.linalg.norm(values[:, 3:], axis=1)
    bad = ~dropout & (np.abs(norm - 1) > 1e-2)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataFormatError(path, f"quaternion norm {norm[i]:.4f}, expected 1", line=i + 2,
                              column="5-8 (rotation)")
    keep = np.flatnonzero(~dropout)
    if keep.size == 0:
        raise DataFormatError(path, "every motion-capture row is a dropout (all zeros)", line=2)
    t_s, values, kept_lines = t_s[keep], values[keep], line_no[keep]
    idx, steps = order_rows(path, t_s, kept_lines, what="motion-capture", backwards="error", repeats="drop_later")
    cleaning += steps
    t_s, values = t_s[idx], values[idx]
    out = (t_s, values[:, :3], values[:, 3:], t0)
    return out + (cleaning,) if return_cleaning else out
