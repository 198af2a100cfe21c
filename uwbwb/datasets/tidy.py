"""Bring your own recording: a generic tidy CSV format.

A recording in this format is two or three small CSV files: the ranges, the
anchor positions and, optionally, the ground truth. They are read by
:func:`load_recording` into a :class:`uwbwb.Recording`, and
:func:`write_recording` (or the three ``write_*_csv`` functions) writes a
recording back so that reading it again gives exactly the same numbers.

General rules (all three files)
-------------------------------
* Plain text, UTF-8 (a leading byte-order mark is accepted), lines ending in
  ``\\n`` or ``\\r\\n``.
* Fields are separated by commas; there is no quoting, so identifiers must not
  contain commas. Spaces around a field are ignored.
* The first line that is neither empty nor a comment is the header, and it must
  be exactly one of the headers listed below (column order included).
* Empty lines and lines whose first character is ``#`` are ignored, so a file
  may carry notes (``# recorded 2024-05-01, anchors surveyed by total station``).
* Numbers are decimal, optionally with an exponent (``1.25``, ``-3e-2``);
  ``nan`` and ``inf`` are not numbers here. Units are SI: seconds, metres.
* Every data line must have as many fields as the header.

Ranges file (required)
----------------------
Header ``t_s,anchor_id,range_m``, optionally followed by ``status`` and/or
``tag_id``, in that order::

    t_s,anchor_id,range_m,status,tag_id
    0.00,A1,3.412,OK,tag
    0.00,A2,5.030,OK,tag
    0.00,A3,,ERR,tag
    0.02,A1,3.418,OK,tag

* ``t_s`` — time of the measurement, seconds, any origin. Rows must be in
  non-decreasing ``t_s`` order over the whole file. The rows of one tag that
  share a ``t_s`` form one epoch (one row of the tag's
  :class:`~uwbwb.RangeLog`).
* ``anchor_id`` — must be listed in the anchors file.
* ``range_m`` — measured range, metres, ``>= 0`` (a negative one is an error); a
  range above ``max_range_m`` (default
  :data:`~uwbwb.datasets.cleaning.MAX_RANGE_M`) is a device failure value: it
  becomes missing (NaN) and is counted in the cleaning report.
* ``status`` (optional, default ``OK``) — ``OK`` keeps the row; ``ERR`` marks a
  failed measurement: its range becomes missing (NaN) and the row is counted in
  the recording's cleaning report; ``range_m`` may then be empty. Any other
  value is an error. An ``ERR`` row still makes its epoch exist, even when no
  anchor of that epoch has a range.
* ``tag_id`` (optional, default ``tag``) — identifier of the tag.
* A repeated ``(t_s, anchor_id, tag_id)`` is an error (never averaged).

Anchors file (required)
-----------------------
Header ``anchor_id,x_m,y_m,z_m``; one line per anchor, unique identifiers, at
least one anchor. Positions in metres, in the frame of the truth file. The
order of the lines fixes the column order of every range log.

Truth file (optional)
---------------------
Header ``t_s,x_m,y_m``, optionally followed by ``z_m`` and/or ``tag_id``, in
that order. Positions (metres) of each tag on the clock of the ranges file.
Rows are in non-decreasing ``t_s`` order over the file, and a repeated
``(t_s, tag_id)`` is an error. Every tag in it must have ranges.

External estimates (optional)
------------------------------
Positions estimated *outside* the workbench (another group's method, a vendor's
RTLS output) may sit beside the three files, one CSV per method in a folder
``external/`` next to the ranges file: ``external/<METHOD>.csv``, in the truth
file's format (header ``t_s,x_m,y_m``, optionally ``z_m`` and/or ``tag_id``;
the same rules), on the clock of the ranges file. :func:`load_recording` reads
them (:func:`read_external_dir`) into ``meta["external_estimates"]``
(method → tag → :class:`~uwbwb.Trajectory`, the method named by the file name
without ``.csv``); ``uwbwb score`` puts each on the board as an *external* row
(:class:`uwbwb.scoreboard.estimators.ExternalEstimates`: scored as given, no
tuning, no bound, its numbers *input*). Every tag of a file must have ranges.

What is and is not stored
-------------------------
The format holds times, anchor identifiers, ranges and tag positions. It does
not hold :attr:`RangeLog.t0` (an absolute time origin), trajectory velocities,
attitudes or names; the writers refuse trajectories that carry velocities or
attitudes rather than drop them silently. Floats are written in Python's
shortest round-trip form, so values read back are bit-for-bit equal.

Errors
------
Any violation raises :class:`uwbwb.DataFormatError` naming the file, the line
(1-based, as an editor shows it) and, where it applies, the column.

Memory
------
Files are parsed into typed columns (floats, and integer codes for the few
distinct identifiers) by pandas' C parser, without a Python object per row, so
reading needs little more than the parsed arrays (``benchmarks/bench_tidy_memory.py``
measures it). A file the fast parser cannot read exactly is read again field by
field, which finds and reports the offending line.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ..errors import DataFormatError
from ..types import Anchors, CleaningStep, RangeLog, Recording, Trajectory, _natural_key
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .text import PathLike, _csv_table, _numbers, _read_bytes

NAME = "tidy"

RANGES_HEADERS = (
    ("t_s", "anchor_id", "range_m"),
    ("t_s", "anchor_id", "range_m", "status"),
    ("t_s", "anchor_id", "range_m", "tag_id"),
    ("t_s", "anchor_id", "range_m", "status", "tag_id"),
)
ANCHORS_HEADER = ("anchor_id", "x_m", "y_m", "z_m")
TRUTH_HEADERS = (
    ("t_s", "x_m", "y_m"),
    ("t_s", "x_m", "y_m", "z_m"),
    ("t_s", "x_m", "y_m", "tag_id"),
    ("t_s", "x_m", "y_m", "z_m", "tag_id"),
)
#: Tag identifier used when a file has no ``tag_id`` column.
DEFAULT_TAG = "tag"
STATUS_OK = "OK"
STATUS_ERR = "ERR"


@dataclass
class _Table:
    """A tidy CSV file as typed columns.

    ``floats``: column → float array (NaN only where empty fields are allowed);
    ``codes``: identifier column → (integer code per row, stripped names);
    ``line_no``: 1-based file line of each row.
    """

    header: tuple[str, ...]
    floats: dict[str, np.ndarray]
    codes: dict[str, tuple[np.ndarray, list[str]]]
    line_no: np.ndarray

    def __len__(self) -> int:
        return self.line_no.size


def _header(path: PathLike, data: bytes, headers: Sequence[tuple[str, ...]], what: str
            ) -> tuple[int, tuple[str, ...], int]:
    """1-based line, fields and end offset (in ``data``) of the header: the first line that is
    neither empty nor a comment."""
    pos, line = 0, 1
    while pos < len(data):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        ln = data[pos:end].removesuffix(b"\r").decode("utf-8")
        if ln.strip() and not ln.startswith("#"):
            header = tuple(f.strip() for f in ln.split(","))
            if header not in headers:
                expected = " or ".join(repr(",".join(h)) for h in headers)
                raise DataFormatError(path, f"header {ln!r} is not a {what} header; expected {expected}", line=line)
            return line, header, end + 1
        pos, line = end + 1, line + 1
    raise DataFormatError(path, f"empty {what} file: expected a header line {','.join(headers[-1])!r} and data lines")


def _body_line_numbers(data: bytes, start: int, first_line: int, n_rows: int) -> np.ndarray | None:
    """File lines of the data rows in ``data[start:]`` (the bytes after the header), skipping empty and
    comment lines as the format says; None if they do not add up to ``n_rows``."""
    size = len(data) - start
    n_lines = data.count(b"\n", start) + (0 if data.endswith(b"\n") or size <= 0 else 1)
    if n_lines == n_rows:   # no empty or comment line: consecutive lines
        return first_line + np.arange(n_rows)
    lines = data[start:].split(b"\n")[:n_lines]
    keep = [i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith(b"#")]
    return first_line + np.asarray(keep, dtype=np.int64) if len(keep) == n_rows else None


def _fast_table(path: PathLike, data: bytes, start: int, header: tuple[str, ...], header_line: int,
                numeric: Sequence[str], empty_ok: Sequence[str]) -> _Table | None:
    """Typed columns of ``data[start:]`` through pandas' C parser, or None when it cannot read the file
    exactly as the format says (then the field-by-field reader runs and reports what is wrong)."""
    n_hash = data.count(b"#", start)
    if n_hash and n_hash != data.count(b"\n#", start - 1 if start else 0) + (start == 0 and data.startswith(b"#")):
        return None   # a '#' inside a line: the C parser would cut the line there
    names = list(header) + ["__extra__"]
    dtype = {c: (float if c in numeric else "category") for c in names}
    try:
        body = io.BytesIO(data)   # shares ``data``: the parser copies only the chunks it reads
        body.seek(start)
        frame = pd.read_csv(body, header=None, names=names, dtype=dtype,
                            engine="c", encoding="utf-8", keep_default_na=False,
                            na_values={c: [""] for c in empty_ok}, skipinitialspace=True, skip_blank_lines=True,
                            comment="#", index_col=False, quoting=csv.QUOTE_NONE)
    except (ValueError, pd.errors.ParserError):
        return None
    if len(frame) == 0 or data.count(b",", start) != len(frame) * (len(header) - 1):
        return None   # no data, or lines with other field counts (or commas in comments): read field by field
    floats = {}
    for c in numeric:
        v = frame[c].to_numpy(float)
        bad = ~np.isfinite(v) if c not in empty_ok else np.isinf(v)
        if bad.any():
            return None
        floats[c] = v
    codes = {}
    for c in header:
        if c in numeric:
            continue
        col = frame[c]
        raw = col.cat.codes.to_numpy()
        if (raw < 0).any():
            return None
        code, names_c = pd.factorize(pd.Index(col.cat.categories.astype(str)).str.strip())
        codes[c] = (code[raw].astype(np.int64), list(names_c))
    line_no = _body_line_numbers(data, start, header_line + 1, len(frame))
    if line_no is None:
        return None
    return _Table(header, floats, codes, line_no)


def _slow_table(path: PathLike, headers: Sequence[tuple[str, ...]], what: str, numeric: Sequence[str],
                empty_ok: Sequence[str]) -> _Table:
    """The same columns, read field by field (finds and reports the first bad field)."""
    header, cols, line_no = _csv_table(path, headers, what)
    floats = {c: _numbers(path, cols[c], line_no, c, allow_empty=c in empty_ok) for c in numeric if c in header}
    codes = {}
    for c in header:
        if c not in numeric:
            code, names = pd.factorize(pd.Series([v.strip() for v in cols[c]], dtype=object))
            codes[c] = (code.astype(np.int64), list(names))
    return _Table(header, floats, codes, line_no)


def _typed_table(path: PathLike, headers: Sequence[tuple[str, ...]], what: str, numeric: Sequence[str],
                 empty_ok: Sequence[str] = ()) -> _Table:
    """A tidy CSV file as typed columns (:class:`_Table`); any format violation raises."""
    data = _read_bytes(path)
    if data.isascii() or _is_utf8(data):
        data = data.removeprefix(b"\xef\xbb\xbf")
        header_line, header, body_start = _header(path, data, headers, what)
        table = _fast_table(path, data, body_start, header, header_line, [c for c in numeric if c in header],
                            empty_ok)
        del data
        if table is not None:
            return table
    return _slow_table(path, headers, what, numeric, empty_ok)


def _is_utf8(data: bytes) -> bool:
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


def _identifier_codes(path: PathLike, table: _Table, column: str) -> tuple[np.ndarray, list[str]]:
    """Codes and names of an identifier column; an empty or non-printable identifier raises."""
    code, names = table.codes[column]
    for k, name in enumerate(names):
        if not name or not name.isprintable():
            i = int(np.flatnonzero(code == k)[0])
            raise DataFormatError(path, f"{column} must be a non-empty printable identifier, got {name!r}",
                                  line=int(table.line_no[i]), column=column)
    return code, names


# --------------------------------------------------------------------------------------------
# Readers
# --------------------------------------------------------------------------------------------

def read_anchors_csv(path: PathLike) -> Anchors:
    """Anchor positions from an anchors file (``anchor_id,x_m,y_m,z_m``).

    Returns
    -------
    Anchors
        In file order; ``pos_m`` shape ``(n_anchors, 3)``, metres.

    Raises
    ------
    DataFormatError
        Bad header, field count, number or identifier, a repeated identifier,
        or no anchors at all.
    """
    table = _typed_table(path, (ANCHORS_HEADER,), "anchors", ANCHORS_HEADER[1:])
    code, names = _identifier_codes(path, table, "anchor_id")
    repeated = np.flatnonzero(pd.Series(code).duplicated().to_numpy())
    if repeated.size:
        i = int(repeated[0])
        raise DataFormatError(path, f"repeated anchor_id {names[code[i]]!r} (first on line "
                                    f"{table.line_no[np.argmax(code == code[i])]})", line=int(table.line_no[i]))
    return Anchors(tuple(names[c] for c in code), np.column_stack([table.floats[c] for c in ANCHORS_HEADER[1:]]))


def read_ranges_csv(path: PathLike, anchors: Anchors | None = None, *, with_cleaning: bool = False,
                    max_range_m: float = MAX_RANGE_M):
    """Range logs, one per tag, from a ranges file.

    Parameters
    ----------
    path
        The ranges CSV (see the module docstring for the format).
    anchors
        If given, every ``anchor_id`` must be one of them and each log's columns
        follow ``anchors.ids``; otherwise the columns are the identifiers found
        in the file, in natural order (``A2`` before ``A10``).
    with_cleaning
        Also return the cleaning steps (``ERR`` rows, ranges above ``max_range_m``).
    max_range_m
        Ranges above this become NaN (counted).

    Returns
    -------
    dict[str, RangeLog] or (dict[str, RangeLog], tuple[CleaningStep, ...])
        Keyed by tag id in order of first appearance. ``range_m`` has shape
        ``(T, n_anchors)`` with NaN where a tag–anchor pair has no range.
    """
    table = _typed_table(path, RANGES_HEADERS, "ranges", ("t_s", "range_m"), empty_ok=("range_m",))
    header, line_no = table.header, table.line_no
    t_s, range_m = table.floats["t_s"], table.floats["range_m"]
    n = t_s.size
    a_code, a_names = _identifier_codes(path, table, "anchor_id")
    if "status" in header:
        s_code, s_names = table.codes["status"]
        for k, name in enumerate(s_names):
            if name not in (STATUS_OK, STATUS_ERR):
                i = int(np.flatnonzero(s_code == k)[0])
                raise DataFormatError(path, f"status must be {STATUS_OK!r} or {STATUS_ERR!r}, got {name!r}",
                                      line=int(line_no[i]), column="status")
        err = s_code == s_names.index(STATUS_ERR) if STATUS_ERR in s_names else np.zeros(n, dtype=bool)
    else:
        err = np.zeros(n, dtype=bool)
    if "tag_id" in header:
        g_code, g_names = _identifier_codes(path, table, "tag_id")
    else:
        g_code, g_names = np.zeros(n, np.int64), [DEFAULT_TAG]
    missing = np.isnan(range_m) & ~err
    if missing.any():
        i = int(np.flatnonzero(missing)[0])
        raise DataFormatError(path, "range_m is empty on an OK row (mark failed measurements "
                                    "with status ERR)", line=int(line_no[i]), column="range_m")
    if anchors is None:
        anchor_ids = tuple(sorted(a_names, key=_natural_key))
    else:
        anchor_ids = tuple(anchors.ids)
        unknown = [k for k, a in enumerate(a_names) if a not in anchor_ids]
        if unknown:
            i = int(np.flatnonzero(np.isin(a_code, unknown))[0])
            raise DataFormatError(path, f"anchor {a_names[a_code[i]]!r} is not in the anchors file "
                                        f"(known: {list(anchor_ids)})", line=int(line_no[i]),
                                  column="anchor_id")
    order, steps = order_rows(path, t_s, line_no, what="ranges (t_s, anchor_id, tag_id)", backwards="error",
                              repeats="error", key=a_code * len(g_names) + g_code)
    del order   # rows are already in time order (a step back is an error)
    range_m, more = check_ranges(path, range_m, line_no, max_range_m=max_range_m, columns=["range_m"], ignore=err)
    col = pd.Index(anchor_ids).get_indexer(a_names)[a_code]
    logs: dict[str, RangeLog] = {}
    for k in np.unique(g_code, return_index=True)[1].argsort():   # tags in order of first appearance
        tag = g_names[k]
        rows = np.flatnonzero(g_code == k)
        epochs, inv = np.unique(t_s[rows], return_inverse=True)
        r = np.full((epochs.size, len(anchor_ids)), np.nan)
        keep = ~err[rows]
        r[inv[keep], col[rows][keep]] = range_m[rows][keep]
        logs[tag] = RangeLog(epochs, r, anchor_ids, tag)
    cleaning = list(steps) + more
    if err.any():
        cleaning.insert(0, CleaningStep("ERR status rows", int(err.sum()),
                                        f"{Path(path).name}: ranges marked ERR are missing (NaN)"))
    return (logs, tuple(cleaning)) if with_cleaning else logs


def read_truth_csv(path: PathLike) -> dict[str, Trajectory]:
    """Ground-truth trajectories, one per tag, from a truth file.

    Returns
    -------
    dict[str, Trajectory]
        Keyed by tag id (``"tag"`` without a ``tag_id`` column), each named
        ``"truth"``, ``pos_m`` shape ``(T, 2)`` or ``(T, 3)``, metres.
    """
    table = _typed_table(path, TRUTH_HEADERS, "truth", ("t_s", "x_m", "y_m", "z_m"))
    header, line_no, t_s = table.header, table.line_no, table.floats["t_s"]
    axes = [c for c in ("x_m", "y_m", "z_m") if c in header]
    pos = np.column_stack([table.floats[c] for c in axes])
    if "tag_id" in header:
        g_code, g_names = _identifier_codes(path, table, "tag_id")
    else:
        g_code, g_names = np.zeros(t_s.size, np.int64), [DEFAULT_TAG]
    order_rows(path, t_s, line_no, what="truth (t_s, tag_id)", backwards="error", repeats="error", key=g_code)
    return {g_names[k]: Trajectory(t_s[g_code == k], pos[g_code == k], name="truth")
            for k in np.unique(g_code, return_index=True)[1].argsort()}


#: Folder beside the ranges file holding outside estimates, one ``<METHOD>.csv`` each (module docstring).
EXTERNAL_DIR = "external"


def read_external_dir(directory: PathLike) -> dict[str, dict[str, Trajectory]]:
    """Outside estimates from ``directory`` (``external/`` of a tidy folder): per ``<METHOD>.csv`` (sorted by
    name), the method's positions per tag, read as a truth file (:func:`read_truth_csv`), each trajectory named
    ``METHOD``. An absent folder gives none."""
    folder = Path(directory)
    if not folder.is_dir():
        return {}
    out = {}
    for path in sorted(folder.glob("*.csv"), key=lambda p: _natural_key(p.stem)):
        out[path.stem] = {tag: Trajectory(tr.t_s, tr.pos_m, name=path.stem)
                          for tag, tr in read_truth_csv(path).items()}
    return out


def load_recording(ranges_csv: PathLike, anchors_csv: PathLike, truth_csv: PathLike | None = None,
                   name: str | None = None, *, max_range_m: float = MAX_RANGE_M) -> Recording:
    """A :class:`~uwbwb.Recording` from tidy CSV files.

    Parameters
    ----------
    ranges_csv, anchors_csv, truth_csv
        The files (format in the module docstring); truth is optional.
    name
        Recording name; defaults to the ranges file name without extension.
    max_range_m
        Ranges above this become NaN (counted).

    Returns
    -------
    Recording
        ``dataset="tidy"``; ``cleaning`` counts the ``ERR`` rows and the ranges
        above ``max_range_m``; ``meta`` holds the source paths and, where a folder
        :data:`EXTERNAL_DIR` sits beside the ranges file, the outside estimates in
        it (``meta["external_estimates"]``, :func:`read_external_dir`; format in the
        module docstring).
    """
    anchors = read_anchors_csv(anchors_csv)
    ranges, cleaning = read_ranges_csv(ranges_csv, anchors, with_cleaning=True, max_range_m=max_range_m)
    truth: dict[str, Trajectory] = {}
    if truth_csv is not None:
        truth = read_truth_csv(truth_csv)
        unknown = [t for t in truth if t not in ranges]
        if unknown:
            raise DataFormatError(truth_csv, f"truth for tags {unknown} that have no ranges in "
                                             f"{Path(ranges_csv).name} (tags there: {list(ranges)})")
    meta = {"source": {"ranges": str(ranges_csv), "anchors": str(anchors_csv),
                       "truth": None if truth_csv is None else str(truth_csv)}}
    external_dir = Path(ranges_csv).parent / EXTERNAL_DIR
    external = read_external_dir(external_dir)
    for method, tracks in external.items():
        unknown = [t for t in tracks if t not in ranges]
        if unknown:
            raise DataFormatError(external_dir / f"{method}.csv", f"estimates for tags {unknown} that have no ranges "
                                                                  f"in {Path(ranges_csv).name} (tags there: {list(ranges)})")
    if external:
        meta.update(external_estimates=external)
        meta["source"]["external"] = {m: str(external_dir / f"{m}.csv") for m in external}
    return Recording(NAME, name or Path(ranges_csv).stem, anchors, ranges, truth,
                     cleaning=cleaning, meta=meta)


# --------------------------------------------------------------------------------------------
# Writers
# --------------------------------------------------------------------------------------------

def _check_identifiers(ids, what: str) -> None:
    for i in ids:
        s = str(i)
        if not s or s != s.strip() or "," in s or not s.isprintable() or s.startswith("#"):
            raise ValueError(f"{what} {s!r} cannot be written: identifiers must be non-empty, printable, "
                             f"without commas or surrounding spaces, and not start with '#'")


def _write(path: PathLike, df: pd.DataFrame) -> Path:
    path = Path(path)
    df.to_csv(path, index=False, lineterminator="\n", na_rep="")
    return path


def write_anchors_csv(path: PathLike, anchors: Anchors) -> Path:
    """Write ``anchors`` as an anchors file; returns the path."""
    _check_identifiers(anchors.ids, "anchor_id")
    return _write(path, anchors.to_frame())


def write_ranges_csv(path: PathLike, ranges: Mapping[str, RangeLog] | RangeLog) -> Path:
    """Write range logs as a ranges file with the full header.

    Rows are ordered by time, then tag, then anchor column. Missing ranges
    (NaN) are not written, except that an epoch with no range at all is kept
    as one ``ERR`` row so that reading the file gives the same epochs back.

    Parameters
    ----------
    ranges
        One :class:`RangeLog` or a mapping tag id → log (the mapping key is the
        tag id written).

    Returns
    -------
    pathlib.Path
    """
    if isinstance(ranges, RangeLog):
        ranges = {ranges.tag_id: ranges}
    _check_identifiers(ranges, "tag_id")
    parts = []
    for order, (tag, log) in enumerate(ranges.items()):
        _check_identifiers(log.anchor_ids, "anchor_id")
        if log.n_anchors == 0:
            raise ValueError(f"range log of tag {tag!r} has no anchors")
        finite = np.isfinite(log.range_m)
        ti, ai = np.nonzero(finite)
        empty = np.flatnonzero(~finite.any(axis=1))
        parts.append(pd.DataFrame({
            "t_s": np.concatenate([log.t_s[ti], log.t_s[empty]]),
            "anchor_id": np.concatenate([np.asarray(log.anchor_ids, dtype=object)[ai],
                                         np.full(empty.size, log.anchor_ids[0], dtype=object)]),
            "range_m": np.concatenate([log.range_m[ti, ai], np.full(empty.size, np.nan)]),
            "status": [STATUS_OK] * ti.size + [STATUS_ERR] * empty.size,
            "tag_id": tag,
            "_tag": order,
            "_col": np.concatenate([ai, np.zeros(empty.size, dtype=int)]),
        }))
    df = (pd.concat(parts, ignore_index=True) if parts else
          pd.DataFrame(columns=["t_s", "anchor_id", "range_m", "status", "tag_id", "_tag", "_col"]))
    df = df.sort_values(["t_s", "_tag", "_col"], kind="stable").drop(columns=["_tag", "_col"])
    return _write(path, df)


def write_truth_csv(path: PathLike, truth: Mapping[str, Trajectory] | Trajectory, *,
                    tag_id: str = DEFAULT_TAG) -> Path:
    """Write ground-truth trajectories as a truth file (``t_s,x_m,y_m[,z_m],tag_id``).

    Parameters
    ----------
    truth
        One trajectory (written for ``tag_id``) or a mapping tag id →
        trajectory. All must have the same dimension (2 or 3).

    Raises
    ------
    ValueError
        A trajectory carries velocities or attitudes (the format holds
        positions only: pass ``dataclasses.replace(traj, vel_mps=None, rot=None)``
        to write positions alone), or dimensions differ.
    """
    if isinstance(truth, Trajectory):
        truth = {tag_id: truth}
    _check_identifiers(truth, "tag_id")
    dims = {traj.dim for traj in truth.values()}
    if len(dims) > 1:
        raise ValueError(f"trajectories of different dimensions {sorted(dims)} cannot share one truth file")
    parts = []
    for order, (tag, traj) in enumerate(truth.items()):
        if traj.vel_mps is not None or traj.rot is not None:
            raise ValueError(f"truth of tag {tag!r} carries velocities or attitudes, which the tidy truth "
                             f"format does not hold; drop them explicitly with dataclasses.replace")
        parts.append(traj.to_frame().assign(tag_id=tag, _tag=order))
    dim = dims.pop() if dims else 3
    cols = ["t_s", "x_m", "y_m", "z_m"][: dim + 1] + ["tag_id"]
    df = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=cols + ["_tag"])
    df = df.sort_values(["t_s", "_tag"], kind="stable")[cols]
    return _write(path, df)


def write_recording(recording: Recording, directory: PathLike) -> dict[str, Path]:
    """Write ``recording`` as ``ranges.csv``, ``anchors.csv`` (and ``truth.csv``) in ``directory``.

    Returns
    -------
    dict[str, pathlib.Path]
        Keys ``ranges``, ``anchors`` and, when the recording has truth,
        ``truth``: ``load_recording(p["ranges"], p["anchors"], p.get("truth"))``
        reads the recording back.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = {"ranges": write_ranges_csv(directory / "ranges.csv", recording.ranges),
             "anchors": write_anchors_csv(directory / "anchors.csv", recording.anchors)}
    if recording.truth:
        paths["truth"] = write_truth_csv(directory / "truth.csv", recording.truth)
    return paths
