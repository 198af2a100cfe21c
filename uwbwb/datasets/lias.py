"""Loader for ``lias-planar-uwb`` (Jiang et al., *Efficient Planar Pose Estimation via UWB
Measurements*, ICRA 2023; upstream ``LIAS-CUHKSZ/Efficient-Pose-Estimation-via-UWB-measurements``).

Eight anchors, three tags on a rigid trolley, two-way ranges at ~100 Hz with 1 cm
resolution. The layout below ``Planar_Dataset/`` is kept as published::

    Dynamic/README.md                                anchor and tag-offset tables
    Dynamic/UWB_dynamic_exp_<name>.csv               ranges      (name: fast, medium, ...)
    Dynamic/motion_capture_dynamic_exp_<name>.csv    centroid + quaternion truth
    Static/README.md                                 one section per day ("### 2022/8/14"):
                                                     tag, anchor and pose tables
    Static/<m.d>/UWB_static_exp_<m>_<d>_pos<k>_deg_<yaw>.csv

Recordings are found by globbing this layout (:func:`list_recordings`), never from a
fixed list, so other runs and rooms of the same format load by name.

What the files contain, and what the loader does about it
---------------------------------------------------------
UWB files (headerless): ``YYYY-MM-DD H:MM:SS.fff`` (hour not zero-padded) followed by
the 24 ranges a0-t0, a0-t1, a0-t2, a1-t0, ... a7-t2, in metres.

* **Incomplete rows.** When an anchor does not answer, the logger leaves it out and
  shifts the following anchors left, padding the row with empty fields at the end
  (``...,2.04,1.87,,,``). Comparing such rows with their neighbours shows the missing
  anchor is usually a0 but sometimes another one, so the values cannot be assigned to
  anchors: these rows are dropped and counted (about one row in a thousand).
* **Extra slots.** Some files are 27, 30 or 33 fields wide: the logger had slots for
  anchors that are not in the room. The slots are empty except on a handful of rows
  where they hold ``0`` or garbage such as ``652.8``; the first 24 ranges of those
  rows agree with their neighbours, so they are kept and the extra values ignored
  (counted).
* **Repeated time stamps** (stamps have 1 ms resolution; a few rows per file share
  the previous row's stamp): the later row is dropped and counted. A stamp that goes
  *back* in time never occurs upstream; it is reported as a
  :class:`~uwbwb.errors.DataFormatError` rather than sorted away.
* **Ranges** follow the package's range rule (:mod:`uwbwb.datasets.cleaning`): zero
  ranges (a failed measurement; one occurs upstream) become NaN, counted, and so do
  ranges above ``max_range_m`` (default
  :data:`~uwbwb.datasets.cleaning.MAX_RANGE_M`; the device's failure values such as
  652.8 m appear in the extra slots upstream, never yet in a real one). Negative
  ranges cannot come from two-way ranging and raise
  :class:`~uwbwb.errors.DataFormatError`. Ordinary outliers (NLOS, a metre or two) are
  kept: rejecting them is the estimator's business.

Motion-capture files: header ``time,x,y,z,rotation,,,`` then the time stamp, the trolley
centroid (m) and four quaternion components. About 1 % of rows repeat the previous
stamp (kept: the first). All-zero rows (a tracking dropout) would be dropped and counted.

Motion-capture frame conventions
--------------------------------
The README documents the quaternion as (qw, qx, qy, qz). Read that way the rotation
is a half turn about a *horizontal* axis, not a yaw; read as (qx, qy, qz, qw) it fits
the ranges better, but is not a yaw either. What fits best by far is the documented
order with the motion-capture body frame turned upside down relative to the tag
frame of the README (a half turn about the body x axis): tag-frame rotation
``R(q) @ Rx(pi)``, which is then a pure yaw whose heading follows the direction of
travel. :func:`load_dynamic` decides the order (``quaternion``) and the body-frame
turn (``body_flip``) from the data
(:func:`uwbwb.datasets.registration.fit_clock_offset_and_convention`): for every candidate it predicts all 24 ranges,
removes the per-pair median residual (the ranges carry per-pair biases of 0.1-0.5 m)
and compares the robust spread of what is left; the smallest wins and every
candidate's spread is put in ``Recording.meta``. On the published fast run the spreads
are about 7 cm (wxyz, body flipped about x), 14 cm (xyzw) and 28 cm (wxyz as is); the
per-pair biases of that solution agree with the ones the static recordings give from
the README poses alone to about 2 cm rms.

Clock alignment
---------------
UWB and motion-capture stamps come from two clocks. :func:`load_dynamic` estimates
``clock_offset_s`` = (motion-capture stamp) - (UWB stamp) of the same instant with the
same residual criterion: first without any rotation (the mean of the three tags'
ranges against the centroid; 100 ms grid over +/-5 s, then 10 ms), where the frame
convention is also chosen; then for the chosen convention a 10 ms grid and a parabola
through five offsets 5 ms apart on all rows. Truth is put on the UWB clock and
restricted to the span of the ranges: it is never extrapolated. On the published fast
run the offset comes out at about +3 ms: no offset between the two clocks is
detectable, but nothing in the files guaranteed that beforehand.
"""

from __future__ import annotations

import io
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFormatError, DataNotFoundError
from ..geometry import yaw_rotation
from ..types import Anchors, CleaningStep, RangeLog, Recording, Trajectory
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .registration import (BODY_FLIPS, QUAT_ORDERS, body_points, fit_clock_offset_and_convention,
                           frame_rotation, quaternion_to_rot)
from .discovery import find_dataset
from .tidy import _read_bytes

__all__ = ["NAME", "TROLLEY_CENTROID_Z_M", "LiasTables", "list_recordings", "read_uwb_csv",
           "read_mocap_csv", "read_tables", "quaternion_to_rot", "load_dynamic", "load_static"]

#: Dataset name, as in the manifest and the data folders.
NAME = "lias-planar-uwb"

#: Height of the trolley centroid above the floor, metres: the median motion-capture
#: centroid height of the published dynamic run (0.971 m, peak to peak 3 cm). The
#: static tables give no height; this is a property of the rig, used as the default
#: of :func:`load_static`'s ``centroid_z_m``.
TROLLEY_CENTROID_Z_M = 0.97

_N_ANCHORS = 8
_N_TAGS = 3
_STAMP_RE = r"\d{4}-\d{1,2}-\d{1,2} \d{1,2}:\d{2}:\d{2}(?:\.\d{1,6})?"
_STAMP_FORMAT = "%Y-%m-%d %H:%M:%S.%f"
_DYNAMIC_PREFIX = "UWB_dynamic_exp_"
_MOCAP_PREFIX = "motion_capture_dynamic_exp_"
_STATIC_RE = re.compile(r"UWB_static_exp_(\d+)_(\d+)_pos(\d+)_deg_(\d+)\.csv")
_SESSION_RE = re.compile(r"(\d{1,2})\.(\d{1,2})")
_DATE_HEADING_RE = re.compile(r"(#{1,6})\s*(\d{4})\s*/\s*(\d{1,2})\s*/\s*(\d{1,2})\s*")
_MOCAP_HEADER = "time,x,y,z,rotation,,,"
_NUMBER_RE = r"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*"
_PLAIN_TEXT = re.compile(r"[0-9.,:\-+eE \n]*")


# ----------------------------------------------------------------------------- text files

def _read_lines(path: Path) -> list[str]:
    """Lines of a text file without line ends; trailing blank lines removed.

    Raises DataFormatError for an empty file, undecodable bytes or a blank line
    between data lines.
    """
    raw = _read_bytes(path)
    if not raw.strip():
        raise DataFormatError(path, "file is empty (expected CSV rows)", line=1)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise DataFormatError(path, f"bytes that are not UTF-8 text ({exc.reason})", line=line) from None
    lines = text.split("\n")
    lines = [ln[:-1] if ln.endswith("\r") else ln for ln in lines]
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
    ok = tokens.str.fullmatch(_NUMBER_RE).to_numpy(bool)
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


def _pair_labels(n_anchors: int, n_tags: int) -> list[str]:
    return [f"a{a}-t{t}" for a in range(n_anchors) for t in range(n_tags)]


def _ordinal_lines(mask: np.ndarray, first_line: int, limit: int = 5) -> str:
    idx = np.flatnonzero(mask)[:limit] + first_line
    more = ", ..." if mask.sum() > limit else ""
    return ", ".join(str(int(i)) for i in idx) + more


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
    names = _pair_labels(n_anchors, n_tags)
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
            f"dropped (lines {_ordinal_lines(~complete, 1)})"))
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
            f"(lines {_ordinal_lines(extra, 1)})"))
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
                                     f"(lines {_ordinal_lines(dropout, 2)})"))
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


# ----------------------------------------------------------------------------- README tables

@dataclass(frozen=True)
class LiasTables:
    """The settings tables of one README section.

    Attributes
    ----------
    readme
        The README they were read from.
    session
        Static session (``"8.14"``) or None for a README without date sections.
    line
        First line of the section.
    anchors
        Anchors ``a0`` ... in the global frame, metres.
    tag_ids
        ``("t0", "t1", ...)``.
    tag_offsets_m
        Tag positions in the trolley (body) frame, shape ``(n_tags, 3)``, metres.
    poses
        Static pose table (columns ``site, yaw_deg, x_m, y_m, line``), or None when the
        section has none.
    """

    readme: Path
    session: str | None
    line: int
    anchors: Anchors
    tag_ids: tuple[str, ...]
    tag_offsets_m: np.ndarray
    poses: pd.DataFrame | None = None


@dataclass(frozen=True)
class _MdTable:
    first_line: int
    header: list[str]
    rows: list[tuple[int, list[str]]]


def _md_cells(line: str) -> list[str]:
    s = line.strip()
    s = s[1:] if s.startswith("|") else s
    s = s[:-1] if s.endswith("|") else s
    return [c.strip() for c in s.split("|")]


def _is_rule(cells: list[str]) -> bool:
    """The ``| --- | :-: |`` line under a markdown table header."""
    return any(cells) and all(re.fullmatch(r":?-+:?", c) for c in cells if c)


def _md_tables(lines: list[str], start: int, stop: int) -> list[_MdTable]:
    """Markdown tables among ``lines[start:stop]`` (0-based), with 1-based line numbers."""
    tables, i = [], start
    while i < stop:
        if not lines[i].lstrip().startswith("|"):
            i += 1
            continue
        j = i
        while j < stop and lines[j].lstrip().startswith("|"):
            j += 1
        block = [(k + 1, _md_cells(lines[k])) for k in range(i, j)]
        body = [row for row in block[1:] if not _is_rule(row[1])]
        tables.append(_MdTable(i + 1, block[0][1], body))
        i = j
    return tables


def _sections(readme: Path, lines: list[str]) -> dict[str, tuple[int, int]]:
    """Date sections ``### YYYY/M/D`` -> ``{"M.D": (start, stop)}`` (0-based line range)."""
    heads = []
    for i, ln in enumerate(lines):
        m = re.match(r"(#{1,6})\s", ln)
        if m:
            heads.append((i, len(m.group(1)), _DATE_HEADING_RE.fullmatch(ln.strip())))
    out: dict[str, tuple[int, int]] = {}
    for k, (i, level, date) in enumerate(heads):
        if date is None:
            continue
        stop = next((j for j, lv, _ in heads[k + 1:] if lv <= level), len(lines))
        session = f"{int(date.group(3))}.{int(date.group(4))}"
        if session in out:
            raise DataFormatError(readme, f"two sections for session {session}", line=i + 1)
        out[session] = (i, stop)
    return out


def _numbers(readme: Path, line: int, cells: list[str], names: list[str]) -> list[float]:
    out = []
    for c, name in zip(cells, names):
        v = float(c) if re.fullmatch(_NUMBER_RE, c) else np.nan
        if not np.isfinite(v):
            raise DataFormatError(readme, f"{c!r} is not a number", line=line, column=name)
        out.append(v)
    return out


def _axes_ok(header: list[str], axes: str) -> bool:
    found = ["".join(ch for ch in cell if ch in "XYZ") for cell in header[1:1 + len(axes)]]
    return found == list(axes)


def _labelled_table(readme: Path, tables: list[_MdTable], label: str, what: str,
                    where: str, section_line: int) -> tuple[list[str], np.ndarray]:
    """Rows ``'<label> k' | x | y | z`` of the one table whose rows carry ``label``."""
    pat = re.compile(rf"{label}\s*(\d+)", re.IGNORECASE)
    hits = [t for t in tables if any(pat.fullmatch(r[1][0]) for r in t.rows if r[1])]
    if not hits:
        raise DataFormatError(readme, f"{where} has no {what} table (rows '{label} 0', "
                                      f"'{label} 1', ...)", line=section_line)
    if len(hits) > 1:
        raise DataFormatError(readme, f"{where} has more than one {what} table", line=hits[1].first_line)
    table = hits[0]
    if len(table.header) != 4 or not _axes_ok(table.header, "XYZ"):
        raise DataFormatError(readme, f"{what} table header {table.header}; expected a label "
                                      f"column then X, Y, Z (m)", line=table.first_line)
    index, pos = [], []
    for line, cells in table.rows:
        m = pat.fullmatch(cells[0]) if cells else None
        if m is None or len(cells) != 4:
            raise DataFormatError(readme, f"{what} table row {cells}; expected '{label} k | x | y | z'",
                                  line=line)
        index.append(int(m.group(1)))
        pos.append(_numbers(readme, line, cells[1:], ["X", "Y", "Z"]))
    if sorted(index) != list(range(len(index))):
        raise DataFormatError(readme, f"{what} numbers {index}; expected 0 ... {len(index) - 1}, "
                                      f"each once", line=table.first_line)
    order = np.argsort(index)
    return [str(index[k]) for k in order], np.asarray(pos, float)[order]


def _pose_table(readme: Path, tables: list[_MdTable], where: str) -> pd.DataFrame | None:
    hits = [t for t in tables if t.header and re.fullmatch(r"poses?", t.header[0], re.IGNORECASE)]
    if not hits:
        return None
    if len(hits) > 1:
        raise DataFormatError(readme, f"{where} has more than one pose table", line=hits[1].first_line)
    table = hits[0]
    if len(table.header) != 4 or "yaw" not in table.header[1].lower() or not _axes_ok(
            [""] + table.header[2:], "XY"):
        raise DataFormatError(readme, f"pose table header {table.header}; expected "
                                      f"'Poses | Yaw(deg) | X (m) | Y (m)'", line=table.first_line)
    rows, site = [], None
    for line, cells in table.rows:
        if len(cells) != 4:
            raise DataFormatError(readme, f"pose table row has {len(cells)} cells, expected 4", line=line)
        if cells[0]:
            m = re.fullmatch(r"pose\s*(\d+)", cells[0], re.IGNORECASE)
            if m is None:
                raise DataFormatError(readme, f"pose label {cells[0]!r}; expected 'Pose k' or empty",
                                      line=line)
            site = int(m.group(1))
            if not any(cells[1:]):
                continue  # "Pose k" on a row of its own; its poses follow
        if site is None:
            raise DataFormatError(readme, "pose values before any 'Pose k' label", line=line)
        yaw, x, y = _numbers(readme, line, cells[1:], ["Yaw", "X", "Y"])
        rows.append((site, yaw, x, y, line))
    if not rows:
        raise DataFormatError(readme, "pose table has no poses", line=table.first_line)
    return pd.DataFrame(rows, columns=["site", "yaw_deg", "x_m", "y_m", "line"])


def _parse_session(session: str) -> str:
    m = _SESSION_RE.fullmatch(str(session).strip())
    if m is None:
        raise ValueError(f"session must look like '8.14' (month.day), got {session!r}")
    return f"{int(m.group(1))}.{int(m.group(2))}"


def read_tables(readme_path: str | os.PathLike, session: str | None = None) -> LiasTables:
    """Parse the anchor, tag-offset and (static) pose tables of an upstream README.

    ``Static/README.md`` has one section per day (``### 2022/8/14`` is session
    ``"8.14"``), each with its own tag, anchor and pose tables; ``Dynamic/README.md`` has
    a single set of tag and anchor tables and no sections. The pose table lists
    ``Pose k`` on the row of its first yaw (site 1) or on an empty row of its own (later
    sites), the following rows belonging to that site.

    Parameters
    ----------
    readme_path
        The README.md file.
    session
        ``"M.D"`` section to read: required for a README with date sections (Static),
        None for one without (Dynamic).

    Returns
    -------
    LiasTables

    Raises
    ------
    DataNotFoundError
        No such file.
    DataFormatError
        A missing section or table, or a garbled row, naming the README and line.
    ValueError
        ``session`` missing although the README has sections, or malformed.
    """
    readme = Path(readme_path)
    if not readme.is_file():
        raise DataNotFoundError(f"{readme} not found (it holds the anchor and tag tables)")
    text = readme.read_text(encoding="utf-8", errors="replace")
    if not text.strip():
        raise DataFormatError(readme, "README is empty (expected the settings tables)", line=1)
    lines = text.splitlines()
    sections = _sections(readme, lines)
    if session is None:
        if sections:
            raise ValueError(f"{readme} has one section per session ({', '.join(sections)}); "
                             f"pass session=")
        start, stop, where = 0, len(lines), "the README"
    else:
        session = _parse_session(session)
        if session not in sections:
            raise DataFormatError(readme, f"no section '### YYYY/{session.replace('.', '/')}' for "
                                          f"session {session}; sections found: "
                                          f"{', '.join(sections) or 'none'}")
        start, stop = sections[session]
        where = f"section '{lines[start].strip()}'"
    tables = _md_tables(lines, start, stop)
    tag_idx, offsets = _labelled_table(readme, tables, "Tag", "tag", where, start + 1)
    anchor_idx, anchor_pos = _labelled_table(readme, tables, "Anchor", "anchor", where, start + 1)
    poses = _pose_table(readme, tables, where)
    offsets.setflags(write=False)
    return LiasTables(readme, session, start + 1,
                      Anchors(tuple(f"a{i}" for i in anchor_idx), anchor_pos),
                      tuple(f"t{i}" for i in tag_idx), offsets, poses)


# ----------------------------------------------------------------------------- discovery

def _planar_dir(data_dir) -> Path:
    return find_dataset(NAME, data_dir) / "Planar_Dataset"


def _session_key(name: str):
    m = _SESSION_RE.fullmatch(name)
    return (0, int(m.group(1)), int(m.group(2)), name) if m else (1, 0, 0, name)


def list_recordings(data_dir: str | os.PathLike | None = None) -> pd.DataFrame:
    """Every recording of the dataset found on disk.

    Globs ``Dynamic/UWB_dynamic_exp_*.csv`` and ``Static/*/UWB_static_exp_*_pos*_deg_*.csv``.

    Returns
    -------
    pandas.DataFrame
        One row per recording: ``kind`` (``"dynamic"``/``"static"``), ``name``
        (``"fast"``, ``"8.14/pos1_deg_0"``), ``session`` (static folder, else None),
        ``site`` and ``yaw_deg`` (static: from the file name, else None), ``path`` (the
        UWB file) and ``truth_path`` (motion-capture file, or the README with the pose
        table; None when a dynamic run has no motion-capture file).
    """
    planar = _planar_dir(data_dir)
    rows = []
    for uwb in sorted((planar / "Dynamic").glob(f"{_DYNAMIC_PREFIX}*.csv")):
        name = uwb.name[len(_DYNAMIC_PREFIX):-len(".csv")]
        mocap = uwb.with_name(f"{_MOCAP_PREFIX}{name}.csv")
        rows.append(("dynamic", name, None, None, None, uwb, mocap if mocap.is_file() else None))
    static = []
    for uwb in (planar / "Static").glob("*/UWB_static_exp_*.csv"):
        m = _STATIC_RE.fullmatch(uwb.name)
        if m is None:
            continue
        site, yaw = int(m.group(3)), int(m.group(4))
        session = uwb.parent.name
        static.append((_session_key(session), site, yaw, session, uwb))
    for _, site, yaw, session, uwb in sorted(static, key=lambda r: r[:3]):
        readme = uwb.parent.parent / "README.md"
        rows.append(("static", f"{session}/pos{site}_deg_{yaw}", session, site, yaw, uwb,
                     readme if readme.is_file() else None))
    cols = ["kind", "name", "session", "site", "yaw_deg", "path", "truth_path"]
    frame = pd.DataFrame({c: pd.Series([r[i] for r in rows], dtype=object) for i, c in enumerate(cols)})
    for c in ("site", "yaw_deg"):
        frame[c] = frame[c].astype("Int64")
    return frame


# ----------------------------------------------------------------------------- loaders

def _choices(value: str, allowed, what: str) -> tuple[str, ...]:
    if value == "auto":
        return tuple(allowed)
    if value not in allowed:
        raise ValueError(f"{what} must be 'auto' or one of {tuple(allowed)}, got {value!r}")
    return (value,)


def load_dynamic(recording: str = "fast", data_dir: str | os.PathLike | None = None, *,
                 quaternion: str = "auto", body_flip: str = "auto",
                 max_clock_offset_s: float = 5.0, min_overlap: float = 0.5,
                 search_rows: int = 3000) -> Recording:
    """Load a dynamic run: ranges of three tags plus motion-capture truth on the UWB clock.

    Parameters
    ----------
    recording
        Run name, the ``<name>`` of ``UWB_dynamic_exp_<name>.csv`` (``"fast"``, ``"medium"``, ...).
    data_dir
        Folder holding ``lias-planar-uwb/`` (see :mod:`uwbwb.datasets.discovery`).
    quaternion
        Order of the four quaternion columns: ``"wxyz"`` (as upstream documents),
        ``"xyzw"``, or ``"auto"`` to decide from the ranges.
    body_flip
        Half turn of the motion-capture body frame relative to the README's tag frame:
        ``"none"``, ``"x"``, ``"y"``, ``"z"`` (axis of the turn), or ``"auto"``. Tag
        positions are ``centroid + R(q) @ F @ offset``.
    max_clock_offset_s
        Half width of the clock-offset search, seconds.
    min_overlap
        Fraction of UWB rows the shifted motion capture must cover for an offset to count.
    search_rows
        At most this many (evenly strided) UWB rows are used in the grid searches; the
        final comparison and refinement use all rows.

    Returns
    -------
    Recording
        ``anchors`` a0..a7 (README), ``ranges`` per tag (t_s since the UWB file's first
        stamp, ``t0`` that stamp), ``truth`` per tag: a 3-D :class:`~uwbwb.types.Trajectory`
        with ``rot`` (tag-frame-to-world), sampled at the motion-capture epochs moved onto
        the UWB clock and restricted to the span of the ranges. ``meta`` holds
        ``clock_offset_s`` (motion-capture minus UWB clock), the method, the chosen
        ``quaternion`` and ``body_flip``, the residual spread of every candidate
        (``convention_spreads_m``, and ``quaternion_spreads_m`` for the two orders at
        their best body-frame turn), paths and a registration note.

    Raises
    ------
    DataNotFoundError
        No such run (the message lists those found) or no motion-capture file.
    DataFormatError
        Any file problem, or motion capture that cannot be aligned with the ranges.
    """
    orders = _choices(quaternion, QUAT_ORDERS, "quaternion")
    flips = _choices(body_flip, tuple(BODY_FLIPS), "body_flip")
    dyn = _planar_dir(data_dir) / "Dynamic"
    uwb_path = dyn / f"{_DYNAMIC_PREFIX}{recording}.csv"
    mocap_path = dyn / f"{_MOCAP_PREFIX}{recording}.csv"
    if not uwb_path.is_file():
        found = [p.name[len(_DYNAMIC_PREFIX):-4] for p in sorted(dyn.glob(f"{_DYNAMIC_PREFIX}*.csv"))]
        raise DataNotFoundError(f"no dynamic run {recording!r} ({uwb_path} missing); "
                                f"runs found: {found or 'none'}")
    if not mocap_path.is_file():
        raise DataNotFoundError(f"dynamic run {recording!r} has no motion-capture file {mocap_path}")
    tables = read_tables(dyn / "README.md")
    n_anchors, n_tags = len(tables.anchors), len(tables.tag_ids)
    t_s, range_m, t0, cleaning = read_uwb_csv(uwb_path, n_anchors=n_anchors, n_tags=n_tags,
                                              return_cleaning=True)
    tm_s, pos_m, quat, tm0, mocap_cleaning = read_mocap_csv(mocap_path, return_cleaning=True)
    cleaning = cleaning + mocap_cleaning
    if t_s.size < 2 or tm_s.size < 2:
        raise DataFormatError(uwb_path if t_s.size < 2 else mocap_path,
                              "fewer than two usable rows; cannot align the clocks")
    tm_s = tm_s + (tm0 - t0).total_seconds()  # motion-capture stamps, seconds since UWB t0

    reg = fit_clock_offset_and_convention(mocap_path, t_s, range_m, tables.anchors.pos_m, tm_s, pos_m, quat,
                                          tables.tag_offsets_m, orders=orders, flips=flips,
                                          max_offset_s=max_clock_offset_s, min_overlap=min_overlap,
                                          max_rows=search_rows)

    t_truth = tm_s - reg.clock_offset_s
    inside = (t_truth >= t_s[0]) & (t_truth <= t_s[-1])
    if (~inside).any():
        cleaning.append(CleaningStep(
            "truth outside the UWB span", int((~inside).sum()),
            f"motion-capture samples before {t_s[0]:.3f} s or after {t_s[-1]:.3f} s on the UWB "
            f"clock; dropped (truth is never extrapolated)"))
    rot = frame_rotation(quat[inside], reg.order, reg.flip)
    pts = body_points(pos_m[inside], rot, tables.tag_offsets_m)
    ranges, truth = {}, {}
    for j, tag in enumerate(tables.tag_ids):
        ranges[tag] = RangeLog(t_s, range_m[:, :, j], tables.anchors.ids, tag, t0)
        truth[tag] = Trajectory(t_truth[inside], pts[:, j], rot=rot, name="truth")

    per_order = {o: min(v for k, v in reg.spreads_m.items() if k.startswith(o + "/"))
                 for o in orders}
    method = ("minimise 1.4826 x median |r - median_pair(r)| of range residuals r = measured - "
              "predicted (motion capture interpolated at UWB time + offset): tags' mean range vs "
              f"centroid on a 100 ms grid over +/-{max_clock_offset_s:g} s then 10 ms; frame "
              "convention chosen there; for it a 10 ms grid, then a parabola through 5 offsets "
              f"5 ms apart on all rows (grids and reported spreads on every {reg.stride}-th row)")
    note = (f"motion capture moved onto the UWB clock by subtracting {reg.clock_offset_s:+.4f} s; "
            f"quaternion read as {reg.order}, body-frame half turn about {reg.flip} "
            f"(residual spread {reg.spreads_m[f'{reg.order}/{reg.flip}'] * 100:.1f} cm); "
            f"truth kept for {int(inside.sum())} of {inside.size} samples inside the UWB span")
    meta = {
        "kind": "dynamic", "uwb_path": str(uwb_path), "mocap_path": str(mocap_path),
        "readme_path": str(tables.readme), "t0": t0, "mocap_t0": tm0,
        "clock_offset_s": reg.clock_offset_s, "clock_offset_method": method,
        "clock_offset_centroid_s": reg.centroid_offset_s,
        "quaternion": reg.order, "body_flip": reg.flip,
        "quaternion_spreads_m": per_order, "convention_spreads_m": reg.spreads_m,
        "residual_spread_m": reg.spreads_m[f"{reg.order}/{reg.flip}"],
        "tag_offsets_m": tables.tag_offsets_m, "registration": note,
    }
    return Recording(NAME, recording, tables.anchors, ranges, truth, cleaning=tuple(cleaning),
                     meta=meta)


def load_static(session: str = "8.14", data_dir: str | os.PathLike | None = None, *,
                site: int | None = None, yaw_deg: int | None = None,
                centroid_z_m: float = TROLLEY_CENTROID_Z_M,
                max_yaw_mismatch_deg: float = 20.0) -> list[Recording]:
    """Load the static recordings of one session (one folder ``Static/<session>/``).

    Each file ``UWB_static_exp_<m>_<d>_pos<k>_deg_<yaw>.csv`` becomes a Recording named
    ``"<session>/pos<k>_deg_<yaw>"``. Its pose is the row of site ``k`` in the session's
    pose table (README) whose yaw is circularly nearest to the nominal ``<yaw>`` of the
    file name. Truth per tag is constant on the ranges' time stamps: the tag's body
    offset rotated by the table yaw, plus the table (x, y); its height is
    ``centroid_z_m`` plus the offset's z.

    Parameters
    ----------
    session
        Folder / README section, ``"M.D"`` (``"8.14"``, ``"8.20"``).
    data_dir
        Folder holding ``lias-planar-uwb/``.
    site, yaw_deg
        Load only this site and/or this nominal yaw (as in the file names).
    centroid_z_m
        Height of the trolley centroid, metres. The static tables give none; the
        default is the rig's centroid height seen by the motion capture in the dynamic
        run (:data:`TROLLEY_CENTROID_Z_M`). A height error dz changes a true range by
        about dz x (anchor height above the tag) / range: with the 8.14 anchors 7 cm
        above the tags and 2-7 m away, 3 cm cost at most a millimetre; with the 8.20
        anchors about 0.3 m above, a few millimetres. The 8.20 tables list larger tag
        offsets, so that rig may sit at another height: pass it if known.
    max_yaw_mismatch_deg
        A file whose nominal yaw is farther than this from every table yaw of its site is
        an error.

    Returns
    -------
    list of Recording
        Sorted by site then yaw. ``meta``: ``session, site, yaw_deg`` (table),
        ``nominal_yaw_deg`` (file name), ``x_m, y_m, centroid_z_m``, ``pose_line``
        (README line), paths and ``t0``.

    Raises
    ------
    DataNotFoundError
        No such session folder, or no file matching the selection.
    DataFormatError
        File or README problems, or a file with no matching pose.
    """
    session_name = _parse_session(session)
    static = _planar_dir(data_dir) / "Static"
    folder = static / str(session)
    if not folder.is_dir():
        folder = static / session_name
    files = []
    for p in folder.glob("UWB_static_exp_*.csv") if folder.is_dir() else ():
        m = _STATIC_RE.fullmatch(p.name)
        if m is not None:
            files.append((int(m.group(3)), int(m.group(4)), p))
    if not files:
        sessions = sorted({d.name for d in static.glob("*") if d.is_dir()}, key=_session_key)
        raise DataNotFoundError(f"no static recordings in {folder}; sessions found: {sessions or 'none'}")
    files.sort(key=lambda f: f[:2])
    chosen = [f for f in files if (site is None or f[0] == site) and (yaw_deg is None or f[1] == yaw_deg)]
    if not chosen:
        raise DataNotFoundError(f"no static recording of session {session} with site={site}, "
                                f"yaw_deg={yaw_deg}; files found: {[f[2].name for f in files]}")
    tables = read_tables(static / "README.md", session_name)
    if tables.poses is None:
        raise DataFormatError(tables.readme, f"section for session {session_name} has no pose "
                                             f"table ('| Poses | Yaw ...')", line=tables.line)
    n_anchors, n_tags = len(tables.anchors), len(tables.tag_ids)
    out = []
    for k, nominal, path in chosen:
        rows = tables.poses[tables.poses["site"] == k]
        if rows.empty:
            raise DataFormatError(tables.readme, f"pose table has no site {k} (needed by "
                                                 f"{path.name})", line=tables.line)
        diff = np.abs((rows["yaw_deg"].to_numpy() - nominal + 180.0) % 360.0 - 180.0)
        i = int(np.argmin(diff))
        if diff[i] > max_yaw_mismatch_deg:
            raise DataFormatError(tables.readme, f"no pose of site {k} within "
                                                 f"{max_yaw_mismatch_deg:g} deg of {path.name}'s "
                                                 f"yaw {nominal} deg", line=int(rows["line"].iloc[0]))
        pose = rows.iloc[i]
        t_s, range_m, t0, cleaning = read_uwb_csv(path, n_anchors=n_anchors, n_tags=n_tags,
                                                  return_cleaning=True)
        yaw_rad = np.deg2rad(float(pose["yaw_deg"]))
        centre = np.array([pose["x_m"], pose["y_m"], centroid_z_m], float)
        tag_pos = centre + tables.tag_offsets_m @ yaw_rotation(yaw_rad).T
        ranges, truth = {}, {}
        for j, tag in enumerate(tables.tag_ids):
            ranges[tag] = RangeLog(t_s, range_m[:, :, j], tables.anchors.ids, tag, t0)
            truth[tag] = Trajectory(t_s, np.broadcast_to(tag_pos[j], (t_s.size, 3)), name="truth")
        meta = {
            "kind": "static", "session": session_name, "site": k, "yaw_deg": float(pose["yaw_deg"]),
            "nominal_yaw_deg": nominal, "x_m": float(pose["x_m"]), "y_m": float(pose["y_m"]),
            "centroid_z_m": float(centroid_z_m), "pose_line": int(pose["line"]),
            "uwb_path": str(path), "readme_path": str(tables.readme), "t0": t0,
            "tag_offsets_m": tables.tag_offsets_m,
        }
        out.append(Recording(NAME, f"{path.parent.name}/pos{k}_deg_{nominal}", tables.anchors,
                             ranges, truth, cleaning=tuple(cleaning), meta=meta))
    return out
