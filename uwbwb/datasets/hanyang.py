"""Loader for the Hanyang outdoor UWB dataset, static part (``hanyang-outdoor-uwb``).

Upstream: repository ``cucudasluv/UWB-dataset`` (Apache-2.0). One anchor and a
tag at 13 heights and distances 2–60 m, in line of sight (LOS) and non line of
sight (NLOS); ~90 two-way-ranging samples per file. Layout::

    hanyang-outdoor-uwb/Static_measurements/{LOS,NLOS}/height_XXcm/{D}m.csv

The condition is the folder name, the tag height is ``XX`` cm and the true
range is ``D`` metres, both from the path; the column ``Distance`` is the
measured range. Files are found by globbing ``*/height_*cm/*.csv``; a CSV whose
name does not read as ``<number>m.csv`` (or folder as ``height_<number>cm``)
is an error, not skipped.

File format and quirks handled (each one tested)
-------------------------------------------------
* Comma-separated, one header line naming the DW1000 diagnostics
  (``timestamp, Transmission #, Reception #, maxNoise, Distance, Channel,
  FirstPathAmp1..3, Max Growth CIR, Rx Preamble Count, Standard Noise,
  RSSI(dBm), RSSI_fp(dBm), rtd_init, rtd_resp, resp_rx_ts, poll_tx_ts,
  resp_tx_ts, poll_rx_ts, anchor_id``); ``\\n`` or ``\\r\\n`` endings.
  ``timestamp``, ``Distance``, ``RSSI(dBm)`` and ``RSSI_fp(dBm)`` are required;
  other known columns are renamed (:data:`COLUMNS`), unknown ones ignored.
* Most files end with summary lines ``Distance Mean,<v>``, ``Distance Std,<v>``,
  ``RSSI(dBm) Mean``… (sometimes padded with empty fields, values possibly
  empty or ``-inf``). They are not samples: removed and counted, and kept in
  :attr:`StaticFile.summary`; ``list_recordings`` checks the file's
  ``Distance Mean`` against the samples. A sample after a summary line is an
  error.
* Some files hold only the header: they have no samples, which is reported
  (``header_only`` in :func:`list_recordings`, a cleaning step in
  :func:`load_static`), not an error.
* A record whose fields are all empty is removed and counted.
* One file ends in a run of NUL bytes (an interrupted write): trailing NULs
  are removed and counted; a NUL anywhere else is an error.
* Serial-log text sometimes overwrote a diagnostic field (``12anchor_id: 12``,
  ``a Growth CIR: 2598``, an empty ``anchor_id``). A diagnostic field that is
  not a number becomes NaN and is counted; the sample keeps its time, range
  and RSSI. The same damage in a required column is an error.
* ``RSSI(dBm)`` / ``RSSI_fp(dBm)`` of ``-inf`` (zero received power estimate)
  become NaN, counted. Any other non-finite required value is an error.
* ``Distance`` follows the package's range rule
  (:mod:`uwbwb.datasets.cleaning`): a negative range is an error, a range above
  ``max_range_m`` (default :data:`~uwbwb.datasets.cleaning.MAX_RANGE_M`) becomes
  NaN and is counted; 0 is kept (this format has no "no range" value). Large
  errors within that span (NLOS) are measurements and are kept.
* Rows out of time order are sorted, exact duplicate rows removed (both
  counted); two different rows with one ``timestamp`` are an error.

Cleaning report: :func:`load_static` returns a DataFrame whose
``attrs["cleaning"]`` is a tuple of :class:`~uwbwb.CleaningStep` (one per kind
of step, totalled over the files read); :func:`read_static_file` returns it per
file in :attr:`StaticFile.cleaning`.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFormatError, DataNotFoundError
from ..types import CleaningStep, _natural_key
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .discovery import find_dataset
from .text import NUMBER_RE, _decode_lines, _numbers, _read_bytes

NAME = "hanyang-outdoor-uwb"
STATIC_DIR = "Static_measurements"

#: Upstream column → column of the samples table. The first four are required.
COLUMNS = {
    "timestamp": "t_unix_s",
    "Distance": "range_m",
    "RSSI(dBm)": "rssi_dbm",
    "RSSI_fp(dBm)": "rssi_fp_dbm",
    "Transmission #": "tx_seq",
    "Reception #": "rx_seq",
    "maxNoise": "max_noise",
    "Channel": "channel",
    "FirstPathAmp1": "fp_amp1",
    "FirstPathAmp2": "fp_amp2",
    "FirstPathAmp3": "fp_amp3",
    "Max Growth CIR": "max_growth_cir",
    "Rx Preamble Count": "rx_preamble_count",
    "Standard Noise": "std_noise",
    "rtd_init": "rtd_init",
    "rtd_resp": "rtd_resp",
    "resp_rx_ts": "resp_rx_ts",
    "poll_tx_ts": "poll_tx_ts",
    "resp_tx_ts": "resp_tx_ts",
    "poll_rx_ts": "poll_rx_ts",
    "anchor_id": "anchor_id",
}
REQUIRED = ("timestamp", "Distance", "RSSI(dBm)", "RSSI_fp(dBm)")
_RSSI = ("RSSI(dBm)", "RSSI_fp(dBm)")
#: Leading columns of :func:`load_static`; the diagnostics present follow.
SAMPLE_COLUMNS = ("condition", "height_m", "true_range_m", "t_s", "range_m", "range_error_m", "rssi_dbm",
                  "rssi_fp_dbm", "file", "line", "t_unix_s")
LISTING_COLUMNS = ("condition", "height_m", "true_range_m", "file", "path", "n_samples", "header_only",
                   "n_summary_lines", "summary_range_mean_m", "summary_matches")
#: Tolerance of the ``Distance Mean`` check in :func:`list_recordings`, metres.
SUMMARY_TOL_M = 1e-6

_SUMMARY = re.compile(r"(?P<column>.+) (?P<stat>Mean|Std)")
_HEIGHT = re.compile(r"height_(?P<cm>\d+(?:\.\d+)?)cm")
_RANGE = re.compile(r"(?P<m>\d+(?:\.\d+)?)m\.csv")

PathLike = str | os.PathLike


@dataclass(frozen=True)
class StaticFile:
    """One static-measurement file.

    Attributes
    ----------
    samples
        One row per sample: ``line`` (1-based file line), ``t_s`` (seconds
        since the file's first sample), ``t_unix_s``, ``range_m``,
        ``rssi_dbm``, ``rssi_fp_dbm`` and the diagnostics present (names in
        :data:`COLUMNS`), sorted by time. Empty (with these columns) for a
        header-only file.
    summary
        The trailing summary lines, ``{"Distance Mean": 10.08, ...}`` (None
        for an empty value).
    cleaning
        Steps taken, each counted.
    """

    samples: pd.DataFrame
    summary: dict = field(default_factory=dict)
    cleaning: tuple[CleaningStep, ...] = ()

    @property
    def header_only(self) -> bool:
        """True when the file holds no sample (a header, perhaps with empty records)."""
        return self.samples.empty


def read_static_file(path: PathLike, *, max_range_m: float = MAX_RANGE_M) -> StaticFile:
    """Read one ``{D}m.csv`` file (format and quirks in the module docstring).

    Parameters
    ----------
    path
        The file.
    max_range_m
        Measured ranges above this become NaN (counted).

    Returns
    -------
    StaticFile

    Raises
    ------
    DataFormatError
        Empty file, missing required column, wrong field count, a required
        value that is not a finite number, a sample after the summary lines,
        a malformed summary line, a NUL byte inside the text, a negative
        range, or two different rows with the same time stamp.
    """
    name = Path(path).name
    data = _read_bytes(path)
    steps: list[CleaningStep] = []
    stripped = data.rstrip(b"\0")
    if len(stripped) < len(data):
        steps.append(CleaningStep("trailing NUL bytes", len(data) - len(stripped),
                                  f"{name}: padding after an interrupted write removed"))
    lines = _decode_lines(path, stripped)
    for i, ln in enumerate(lines):
        if "\0" in ln:
            raise DataFormatError(path, "NUL byte inside the text", line=i + 1)
    if not lines or not lines[0].strip():
        raise DataFormatError(path, "empty file: expected a header line starting 'timestamp,'", line=1)
    header = [h.strip() for h in lines[0].split(",")]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise DataFormatError(path, f"header lacks required columns {missing}", line=1)
    if len(set(header)) != len(header):
        raise DataFormatError(path, "header repeats a column name", line=1)
    known = [c for c in header if c in COLUMNS]

    rows, line_no, summary, n_summary, blank = [], [], {}, 0, 0
    for i, ln in enumerate(lines[1:], start=2):
        fields = [f.strip() for f in ln.split(",")]
        if not any(fields):
            blank += 1
            continue
        m = _SUMMARY.fullmatch(fields[0])
        if m and m["column"] in header and len(fields) >= 2:
            if any(fields[2:]):
                raise DataFormatError(path, f"summary line {fields[0]!r} has extra values", line=i)
            summary[fields[0]] = _summary_value(path, fields[1], i)
            n_summary += 1
            continue
        if summary:
            raise DataFormatError(path, "sample line after the summary lines", line=i)
        if len(fields) != len(header):
            raise DataFormatError(path, f"{len(fields)} fields, the header has {len(header)}", line=i)
        rows.append(fields)
        line_no.append(i)
    if blank:
        steps.append(CleaningStep("empty records", blank, f"{name}: lines with no value removed"))
    if n_summary:
        steps.append(CleaningStep("summary lines", n_summary, f"{name}: trailing statistics, not samples"))

    line_no = np.array(line_no, dtype=int)
    k_cols = [header.index(c) for c in known]
    values = _plain_numbers([[r[k] for k in k_cols] for r in rows])
    if values is None:  # some field is not a plain finite number: parse column by column
        values = np.column_stack([_column(path, col, [r[k] for r in rows], line_no)
                                  for col, k in zip(known, k_cols)]) if rows else np.empty((0, len(known)))
    aux = np.array([c not in REQUIRED for c in known])
    bad = ~np.isfinite(values) & aux
    if bad.any():
        where = ", ".join(f"line {line_no[i]} {known[j]}" for i, j in np.argwhere(bad)[:5])
        steps.append(CleaningStep("garbled diagnostic fields -> NaN", int(bad.sum()),
                                  f"{name}: not a number ({where}{' ...' if bad.sum() > 5 else ''}); "
                                  f"time, range and RSSI kept"))
        values[bad] = np.nan
    for col in _RSSI:
        v = values[:, known.index(col)]
        ninf = np.isneginf(v)
        if ninf.any():
            v[ninf] = np.nan
            steps.append(CleaningStep(f"{col} -inf -> NaN", int(ninf.sum()),
                                      f"{name}: zero received-power estimate"))
    idx, more = order_rows(path, values[:, known.index("timestamp")], line_no, what="sample", values=values)
    values, line_no = values[idx], line_no[idx]
    j = known.index("Distance")
    values[:, j], ranges = check_ranges(path, values[:, j], line_no, max_range_m=max_range_m, columns=["Distance"])
    steps += more + ranges
    t = values[:, known.index("timestamp")]
    cols = {"line": line_no, "t_s": t - t[0] if t.size else t}
    cols.update({COLUMNS[c]: values[:, j] for j, c in enumerate(known)})
    return StaticFile(pd.DataFrame(cols), summary, tuple(steps))


_NOT_PLAIN = re.compile(r"[^0-9eE+\-.,]")


def _plain_numbers(rows: list[list[str]]) -> np.ndarray | None:
    """Fast path: all fields are plain decimal numbers (no text, nan, inf or empty field) → float matrix."""
    if not rows or any(_NOT_PLAIN.search(",".join(r)) for r in rows):
        return None
    try:
        values = np.array(rows, dtype=float)
    except ValueError:
        return None
    return values if np.all(np.isfinite(values)) else None


def _column(path: PathLike, col: str, text: list[str], line_no: np.ndarray) -> np.ndarray:
    """One column: required ones must be finite numbers (RSSI may be -inf); others NaN where not numbers."""
    if col in REQUIRED:
        return _numbers(path, text, line_no, col, allow=(-np.inf,) if col in _RSSI else ())
    return np.array(pd.to_numeric(pd.Series(text, dtype=object), errors="coerce"), dtype=float)


def _summary_value(path: PathLike, text: str, line: int) -> float | None:
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if np.isnan(value) or not re.fullmatch(rf"{NUMBER_RE}|-inf|inf", text):
        raise DataFormatError(path, f"summary value is not a number: {text!r}", line=line)
    return value


# --------------------------------------------------------------------------------------------
# Listing and loading
# --------------------------------------------------------------------------------------------

def _static_root(data_dir: PathLike | None) -> Path:
    root = find_dataset(NAME, data_dir)
    static = root / STATIC_DIR
    if not static.is_dir():
        raise DataNotFoundError(f"{static} not found (the static part of {NAME})")
    return static


def _scan(static: Path) -> pd.DataFrame:
    """Every static file with condition, height and true range from its path (not read)."""
    rows = []
    for path in static.glob("*/height_*cm/*.csv"):
        h = _HEIGHT.fullmatch(path.parent.name)
        r = _RANGE.fullmatch(path.name)
        if h is None:
            raise DataFormatError(path, "folder name must read 'height_<number>cm'")
        if r is None:
            raise DataFormatError(path, "file name must read '<distance>m.csv', e.g. '12m.csv'")
        rows.append({"condition": path.parent.parent.name, "height_m": float(h["cm"]) / 100.0,
                     "true_range_m": float(r["m"]), "file": path.relative_to(static.parent).as_posix(),
                     "path": path})
    df = pd.DataFrame(rows, columns=["condition", "height_m", "true_range_m", "file", "path"])
    return df.sort_values(["condition", "height_m", "true_range_m"], kind="stable").reset_index(drop=True)


def _select(files: pd.DataFrame, condition: str | None, height_m) -> pd.DataFrame:
    if condition is not None:
        known = sorted(files["condition"].unique())
        if condition not in known:
            raise ValueError(f"condition {condition!r} not in the data; known: {known}")
        files = files[files["condition"] == condition]
    if height_m is not None:
        wanted = np.atleast_1d(np.asarray(height_m, dtype=float))
        known = np.unique(files["height_m"])
        unknown = [h for h in wanted if not np.any(np.isclose(known, h, rtol=0, atol=1e-9))]
        if unknown:
            raise ValueError(f"height_m {unknown} not in the data; known: {known.tolist()}")
        files = files[np.any(np.isclose(files["height_m"].to_numpy()[:, None], wanted[None], rtol=0,
                                        atol=1e-9), axis=1)]
    return files


def list_recordings(data_dir: PathLike | None = None) -> pd.DataFrame:
    """One row per static file, with what it holds.

    Every file is read (about a second for the whole dataset) to count its
    samples and check its summary.

    Returns
    -------
    pandas.DataFrame
        Columns ``condition`` (``"LOS"``/``"NLOS"``), ``height_m``,
        ``true_range_m`` (from the file name), ``file`` (relative to the dataset
        root), ``path``, ``n_samples``, ``header_only``, ``n_summary_lines``,
        ``summary_range_mean_m`` (the file's ``Distance Mean``, NaN if absent)
        and ``summary_matches`` (whether it equals the mean of the samples
        within :data:`SUMMARY_TOL_M`; None without a summary). Sorted by
        condition, height and true range.
    """
    files = _scan(_static_root(data_dir))
    extra = []
    for path in files["path"]:
        sf = read_static_file(path)
        mean = sf.summary.get("Distance Mean")
        matches = None
        if mean is not None and not sf.samples.empty:
            matches = bool(abs(mean - sf.samples["range_m"].mean()) <= SUMMARY_TOL_M)
        extra.append({"n_samples": len(sf.samples), "header_only": sf.header_only,
                      "n_summary_lines": len(sf.summary),
                      "summary_range_mean_m": np.nan if mean is None else mean, "summary_matches": matches})
    return pd.concat([files, pd.DataFrame(extra, columns=list(LISTING_COLUMNS[5:]))], axis=1)


def load_static(data_dir: PathLike | None = None, *, condition: str | None = None,
                height_m: float | list[float] | None = None, max_range_m: float = MAX_RANGE_M) -> pd.DataFrame:
    """Tidy table of all static samples, optionally for one condition / some heights.

    Parameters
    ----------
    data_dir
        Folder holding ``hanyang-outdoor-uwb/`` (default: the discovery order).
    condition
        ``"LOS"`` or ``"NLOS"`` (as the folder names); None for both.
    height_m
        A tag height or a list of them, metres (e.g. ``1.0`` or ``[0.5, 2.0]``);
        None for all.
    max_range_m
        Measured ranges above this become NaN (counted; see :func:`read_static_file`).

    Returns
    -------
    pandas.DataFrame
        One row per sample with columns :data:`SAMPLE_COLUMNS` —
        ``condition, height_m, true_range_m, t_s, range_m, range_error_m
        (= range_m − true_range_m), rssi_dbm, rssi_fp_dbm, file, line,
        t_unix_s`` — followed by the diagnostics (:data:`COLUMNS`). ``t_s`` is
        seconds since the first sample of its file. ``attrs["cleaning"]`` is a
        tuple of :class:`~uwbwb.CleaningStep`, one per kind, totalled over the
        files (header-only files are one of them); ``attrs["n_files"]`` is the
        number of files read.

    Raises
    ------
    ValueError
        ``condition`` or ``height_m`` not in the data.
    DataFormatError
        A file breaks the format (see :func:`read_static_file`).
    """
    files = _select(_scan(_static_root(data_dir)), condition, height_m).reset_index(drop=True)
    parts, counts, steps, header_only = [], [], {}, []
    for row in files.itertuples(index=False):
        sf = read_static_file(row.path, max_range_m=max_range_m)
        if sf.header_only:
            header_only.append(row.file)
        for s in sf.cleaning:
            n, where = steps.get(s.name, (0, []))
            steps[s.name] = (n + s.n_affected, where + [row.file])
        parts.append(sf.samples)
        counts.append(len(sf.samples))
    cleaning = [CleaningStep(name, n, _files_detail(where)) for name, (n, where) in steps.items()]
    if header_only:
        cleaning.append(CleaningStep("header-only files", len(header_only),
                                     "no samples: " + _files_detail(header_only)))
    samples = [p for p in parts if not p.empty]
    out = pd.concat(samples, ignore_index=True) if samples else pd.DataFrame(
        {c: pd.Series(dtype=float) for c in ("line", "t_s", "t_unix_s", "range_m", "rssi_dbm", "rssi_fp_dbm")})
    which = np.repeat(np.arange(len(files)), counts)
    for col in ("condition", "height_m", "true_range_m", "file"):
        out[col] = files[col].to_numpy()[which]
    out["range_error_m"] = out["range_m"] - out["true_range_m"]
    rest = [COLUMNS[c] for c in COLUMNS if COLUMNS[c] in out.columns and COLUMNS[c] not in SAMPLE_COLUMNS]
    out = out[list(SAMPLE_COLUMNS) + rest]
    out.attrs["cleaning"] = tuple(cleaning)
    out.attrs["n_files"] = len(files)
    return out


def _files_detail(files: list[str], limit: int = 6) -> str:
    files = sorted(set(files), key=_natural_key)
    shown = ", ".join(files[:limit])
    return f"{len(files)} file(s): {shown}" + (f" and {len(files) - limit} more" if len(files) > limit else "")
