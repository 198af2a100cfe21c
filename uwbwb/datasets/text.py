"""Text helpers shared by the loaders of text formats: bytes and lines, numeric and identifier
columns, delimited fields with line numbers, tidy CSV tables with a header.

Every problem is a :class:`~uwbwb.errors.DataFormatError` naming the file and line (and
column where there is one).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from ..errors import DataFormatError, DataNotFoundError

PathLike = str | os.PathLike


#: Environment variable naming a file to which every data file a loader reads is appended (one absolute path a
#: line): how ``reproduce`` learns which files an executed notebook depends on (:mod:`uwbwb.reproduce.cache`).
READ_LOG_ENV = "UWBWB_READ_LOG"
#: A decimal number as the text formats write one (optional sign and exponent; no ``nan`` or ``inf``), spaces around.
NUMBER_RE = r"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*"


def _read_bytes(path: PathLike) -> bytes:
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise DataNotFoundError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise DataFormatError(path, "is a directory, expected a text file") from None
    log = os.environ.get(READ_LOG_ENV)
    if log:
        with open(log, "a", encoding="utf-8") as fh:
            fh.write(f"{Path(path).resolve()}\n")
    return data


def _decode_lines(path: PathLike, data: bytes) -> list[str]:
    """Lines of UTF-8 ``data`` without their ``\\n`` / ``\\r\\n`` terminators.

    Line ``i`` of the result is line ``i + 1`` of the file. A final line
    terminator does not start an extra (empty) line; a byte-order mark is
    removed.
    """
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise DataFormatError(path, f"not UTF-8 text (byte {data[exc.start]:#04x})", line=line) from None
    if text.startswith("\ufeff"):
        text = text[1:]
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [ln[:-1] if ln.endswith("\r") else ln for ln in lines]


def _numbers(path: PathLike, values: Sequence[str], line_no: np.ndarray, column: str, *,
             allow_empty: bool = False, allow: Sequence[float] = ()) -> np.ndarray:
    """Parse text fields to float, vectorised; the first bad field raises.

    Parameters
    ----------
    values
        Field texts, one per data line (surrounding spaces are ignored).
    line_no
        1-based file line of each value, shape ``(len(values),)``.
    column
        Column name, for the error message.
    allow_empty
        Empty fields give NaN instead of an error.
    allow
        Non-finite values accepted as such (e.g. ``-inf``); all others, and
        ``nan``, are errors.

    Returns
    -------
    numpy.ndarray
        Shape ``(len(values),)``, float.
    """
    text = pd.Series(list(values), dtype=object).str.strip()
    num = pd.to_numeric(text, errors="coerce")
    try:
        out = np.array(num, dtype=float)
    except (TypeError, ValueError, OverflowError):  # huge integers come back as objects
        out = np.array([_to_float(v) for v in num], dtype=float)
    ok = np.isfinite(out)  # "nan", "inf" and overflowing literals are not finite
    for special in allow:
        ok |= out == special
    empty = text.to_numpy(dtype=object) == ""
    if allow_empty:
        ok |= empty
        out[empty] = np.nan
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        what = "is empty" if empty[i] else f"is not a finite number: {values[i]!r}"
        raise DataFormatError(path, f"{column} {what}", line=int(line_no[i]), column=column)
    return out


def _to_float(value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return math.nan


def _split_rows(path: PathLike, numbered: Sequence[tuple[int, str]], sep: str, names: Sequence[str], *,
                what: str, header_line: int) -> tuple[list[list[str]], np.ndarray]:
    """Fields and 1-based line numbers of the data lines ``(line_no, text)`` after a header.

    Raises
    ------
    DataFormatError
        No data line after the header at ``header_line``, or a line whose number of
        ``sep``-separated fields is not ``len(names)``.
    """
    if not numbered:
        raise DataFormatError(path, f"{what} file has a header but no data lines", line=header_line)
    fields = [ln.split(sep) for _, ln in numbered]
    line_no = np.array([n for n, _ in numbered], dtype=int)
    kind = {",": "comma", "\t": "tab"}.get(sep, repr(sep))
    for n, f in zip(line_no, fields):
        if len(f) != len(names):
            raise DataFormatError(path, f"{len(f)} {kind}-separated fields, expected {len(names)} "
                                        f"({', '.join(names)})", line=int(n))
    return fields, line_no


def _csv_table(path: PathLike, headers: Sequence[tuple[str, ...]], what: str
               ) -> tuple[tuple[str, ...], dict[str, list[str]], np.ndarray]:
    """Header, columns of field texts and 1-based line numbers of a tidy CSV file.

    Empty lines and ``#`` comment lines are skipped. The header must be one of
    ``headers``; every data line must have as many fields as the header; a file
    with no data line is an error.
    """
    lines = _decode_lines(path, _read_bytes(path))
    numbered = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")]
    if not numbered:
        raise DataFormatError(path, f"empty {what} file: expected a header line "
                                    f"{','.join(headers[-1])!r} and data lines")
    header_line, header_text = numbered[0]
    header = tuple(f.strip() for f in header_text.split(","))
    if header not in headers:
        expected = " or ".join(repr(",".join(h)) for h in headers)
        raise DataFormatError(path, f"header {header_text!r} is not a {what} header; expected {expected}",
                              line=header_line)
    fields, line_no = _split_rows(path, numbered[1:], ",", header, what=what, header_line=header_line)
    columns = {name: [f[k] for f in fields] for k, name in enumerate(header)}
    return header, columns, line_no
