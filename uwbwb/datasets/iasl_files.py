"""Readers of the i-ASL UWB/IMU text files: ``uwb.csv``, ``imu.csv`` and ``gt.csv`` (tab-separated).

The format is described in :mod:`uwbwb.datasets.iasl` (module notes), whose loader calls these
readers; every name is importable from there too. Every problem is a
:class:`~uwbwb.errors.DataFormatError` naming file and line; every cleaning step is reported.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..errors import DataFormatError
from ..types import CleaningStep, ImuLog, RangeLog, Trajectory
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .imu_checks import ImuChecks, check_imu_samples, check_second_counts
from .text import NUMBER_RE, _decode_lines, _numbers, _read_bytes, _split_rows

PathLike = str | os.PathLike

#: Upstream column names (headers are compared ignoring case, spaces and punctuation).
UWB_COLUMNS = ("Local Time", "System Time", "Position X", "Position Y", "Position Z")  # + Distance 1..N
IMU_COLUMNS = ("Time", "Linear acceleration X", "Linear acceleration Y", "Linear acceleration Z",
               "Angular velocity X", "Angular velocity Y", "Angular velocity Z")
GT_COLUMNS = ("Time", "Position X", "Position Y", "Position Z") + tuple(f"Rotation[{k}]" for k in range(9))


def _norm(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def _read_tab(path: PathLike, what: str, columns: Callable[[int], tuple[str, ...] | None], expected: str
              ) -> tuple[np.ndarray, np.ndarray]:
    """Numbers of a tab-separated file with an optional header row.

    Parameters
    ----------
    columns
        Column names for a given number of fields, or None when that number
        is not valid; a header must match them (case, spaces and punctuation
        ignored), and error messages use them.
    expected
        The columns in words, for error messages.

    Returns
    -------
    values : numpy.ndarray
        Shape ``(n_rows, n_columns)``, all finite.
    line_no : numpy.ndarray
        1-based file line of each row, shape ``(n_rows,)``.
    """
    lines = _decode_lines(path, _read_bytes(path))
    numbered = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip()]
    if not numbered:
        raise DataFormatError(path, f"empty {what} file")
    first_line, first = numbered[0]
    first_fields = first.split("\t")
    names = columns(len(first_fields))
    if names is None:
        raise DataFormatError(path, f"{len(first_fields)} tab-separated fields; {what} columns are: {expected}",
                              line=first_line)
    if not re.fullmatch(NUMBER_RE, first_fields[0]):  # a header row
        if tuple(_norm(f) for f in first_fields) != tuple(_norm(n) for n in names):
            raise DataFormatError(path, f"header {first!r} does not name the {what} columns: {expected}",
                                  line=first_line)
        numbered = numbered[1:]
    fields, line_no = _split_rows(path, numbered, "\t", names, what=what, header_line=first_line)
    values = np.column_stack([_numbers(path, [f[k] for f in fields], line_no, name)
                              for k, name in enumerate(names)])
    return values, line_no


@dataclass(frozen=True)
class UwbFile:
    """Contents of one ``uwb.csv``.

    Attributes
    ----------
    ranges
        Ranges on the UWB clock: ``t_s`` = (Local Time − first Local Time) / 1000,
        shape ``(T, n_anchors)``, NaN where the module reported 0.
    device
        The module's own position estimate (Position X/Y/Z) on the same clock,
        as reported (raw; its frame and quality are the device's), named ``"device"``.
    local_time0_ms
        Local Time of the first row (the origin of ``t_s``), ms.
    system_time_ms
        The System Time column, shape ``(T,)``, ms.
    cleaning
        Steps taken while reading.
    """

    ranges: RangeLog
    device: Trajectory
    local_time0_ms: float
    system_time_ms: np.ndarray
    cleaning: tuple[CleaningStep, ...] = ()


def read_uwb(path: PathLike, anchor_ids: Sequence[str] | None = None, *,
             max_range_m: float = MAX_RANGE_M) -> UwbFile:
    """Read ``uwb.csv`` (tab-separated; header optional; blank lines skipped).

    Parameters
    ----------
    path
        The file.
    anchor_ids
        Names of the ``Distance 1..N`` columns (default ``a1..aN``); their
        number must match the file.
    max_range_m
        Ranges above this become NaN (counted).

    Returns
    -------
    UwbFile
    """
    def columns(n):
        k = n - len(UWB_COLUMNS)
        return UWB_COLUMNS + tuple(f"Distance {i + 1}" for i in range(k)) if k >= 1 else None

    values, line_no = _read_tab(path, "UWB", columns, "Local Time, System Time, Position X/Y/Z, Distance 1..N")
    n_anchors = values.shape[1] - len(UWB_COLUMNS)
    if anchor_ids is None:
        anchor_ids = tuple(f"a{k + 1}" for k in range(n_anchors))
    elif len(anchor_ids) != n_anchors:
        raise DataFormatError(path, f"{n_anchors} distance columns but {len(anchor_ids)} anchors "
                                    f"({list(anchor_ids)})")
    idx, steps = order_rows(path, values[:, 0], line_no, what="UWB", values=values)
    values, line_no = values[idx], line_no[idx]
    r, more = check_ranges(path, values[:, len(UWB_COLUMNS):], line_no, max_range_m=max_range_m,
                           zero_is_missing=True, columns=[f"Distance {k + 1}" for k in range(n_anchors)])
    steps += more
    t_s = (values[:, 0] - values[0, 0]) / 1000.0
    if np.any(np.diff(t_s) <= 0):  # distinct ms stamps that collapse in floating point
        raise DataFormatError(path, "Local Time stamps too large to resolve in milliseconds")
    ranges = RangeLog(t_s, r, tuple(anchor_ids), "tag")
    device = Trajectory(t_s, values[:, 2:5], name="device")
    return UwbFile(ranges, device, float(values[0, 0]), values[:, 1].copy(), tuple(steps))


def spread_whole_seconds(stamp_s: np.ndarray) -> tuple[np.ndarray, float]:
    """Spread rows that share a whole-second stamp evenly over that second.

    Let second ``k`` hold ``n_k`` rows (file order ``i = 0..n_k-1``) and let
    ``f`` be the median of ``n_k`` over the interior seconds (all but the first
    and the last; all seconds when there are fewer than three). Stamps are
    taken to be truncated times, so row ``i`` of second ``k`` is placed at

    * interior seconds: ``t = k + (i + 0.5) / n_k``;
    * the first second, which the recording entered part-way and whose rows
      therefore sit at its end: ``t = k + 1 - (n_k - i - 0.5) / max(f, n_k)``;
    * the last second, left part-way, whose rows sit at its start:
      ``t = k + (i + 0.5) / max(f, n_k)``.

    A single second is treated as interior. Any constant error of this rule
    (e.g. stamps rounded rather than truncated) is absorbed by the estimated
    IMU clock offset; the rule's jitter is at most ``1 / (2 f)``.

    Parameters
    ----------
    stamp_s
        Whole-second stamps, non-decreasing, shape ``(n,)``.

    Returns
    -------
    t_s : numpy.ndarray
        Shape ``(n,)``, strictly increasing where the input allows it.
    rate_hz : float
        ``f``, the nominal number of rows per second.
    """
    stamp_s = np.asarray(stamp_s, float)
    sec, start, count = np.unique(stamp_s, return_index=True, return_counts=True)
    i = np.arange(stamp_s.size) - np.repeat(start, count)
    n = np.repeat(count, count).astype(float)
    rate = float(np.median(count[1:-1] if count.size >= 3 else count))
    t = stamp_s + (i + 0.5) / n
    if sec.size >= 2:
        first, last = stamp_s == sec[0], stamp_s == sec[-1]
        t[first] = sec[0] + 1 - (n[first] - i[first] - 0.5) / max(rate, count[0])
        t[last] = sec[-1] + (i[last] + 0.5) / max(rate, count[-1])
    return t, rate


@dataclass(frozen=True)
class ImuFile:
    """Contents of one ``imu.csv``.

    Attributes
    ----------
    imu
        Samples on the IMU's own clock: ``t_s`` = Unix time − ``unix_time0_s``.
    unix_time0_s
        The first whole Unix second, s.
    rate_hz
        Nominal rows per second (see :func:`spread_whole_seconds`); NaN when the
        stamps were already distinct.
    cleaning
        Steps taken while reading.
    checks
        Units, spikes and gaps as checked (:func:`~uwbwb.datasets.imu_checks.check_imu_samples`):
        the measured gravity magnitude, z sign and gyro rate scale, and any gaps kept.
    """

    imu: ImuLog
    unix_time0_s: float
    rate_hz: float
    cleaning: tuple[CleaningStep, ...] = ()
    checks: ImuChecks | None = None


def read_imu(path: PathLike, *, gaps: str = "error", max_gap_s: float | None = None) -> ImuFile:
    """Read ``imu.csv`` (tab-separated; header optional).

    Whole-second stamps that repeat are spread over their second with
    :func:`spread_whole_seconds` (a counted cleaning step); stamps that are
    already strictly increasing are used as they are; repeated stamps that are
    not whole seconds are an error. Then the samples are checked
    (:func:`~uwbwb.datasets.imu_checks.check_imu_samples`): accelerations not in
    m/s² or gyro rates in deg/s are errors with the evidence; samples beyond the
    MEMS full scale (16 g, 2000 °/s) are dropped and counted; gaps longer than
    ``max_gap_s`` (default 5 nominal intervals), and interior whole seconds
    holding more than 5 rows fewer than the nominal rate
    (:func:`~uwbwb.datasets.imu_checks.check_second_counts`), are an error, or
    with ``gaps="warn"`` a warning listing them (kept in :attr:`ImuFile.checks`).
    Non-finite values are parse errors naming line and column.
    """
    values, line_no = _read_tab(path, "IMU", lambda n: IMU_COLUMNS if n == len(IMU_COLUMNS) else None,
                                "Time, Linear acceleration X/Y/Z, Angular velocity X/Y/Z")
    order, steps = order_rows(path, values[:, 0], line_no, what="IMU", repeats="keep")  # order within a second kept
    values, line_no = values[order], line_no[order]
    stamp = values[:, 0]
    t0 = float(np.floor(stamp[0]))
    rate = np.nan
    hidden = np.zeros((0, 2))
    if np.any(np.diff(stamp) == 0):
        frac = np.flatnonzero(stamp != np.round(stamp))
        if frac.size:
            i = int(frac[0])
            raise DataFormatError(path, f"time stamps repeat but {float(stamp[i])!r} is not a whole second",
                                  line=int(line_no[i]), column="Time")
        t, rate = spread_whole_seconds(stamp - t0)
        hidden = check_second_counts(path, stamp, line_no, rate, t0_s=t0, gaps=gaps)
        steps.append(CleaningStep("spread whole-second IMU stamps", int(stamp.size),
                                  f"{Path(path).name}: rows of each Unix second spread evenly over it, "
                                  f"nominal {rate:g} rows/s (rule: uwbwb.datasets.iasl.spread_whole_seconds)"))
    else:
        t = stamp - t0
    if np.any(np.diff(t) <= 0):
        raise DataFormatError(path, "IMU time stamps too large to resolve within a second")
    checks = check_imu_samples(path, t, values[:, 1:4], values[:, 4:7], line_no, gaps=gaps, max_gap_s=max_gap_s)
    steps += checks.steps
    if hidden.size:
        gaps_s = np.concatenate([checks.gaps_s, hidden])
        checks = replace(checks, gaps_s=gaps_s[np.argsort(gaps_s[:, 0], kind="stable")])
    keep = checks.keep
    imu = ImuLog(t[keep], values[keep, 1:4], values[keep, 4:7])
    return ImuFile(imu, t0, rate, tuple(steps), checks)


@dataclass(frozen=True)
class GtFile:
    """Contents of one ``gt.csv``.

    Attributes
    ----------
    truth
        Motion-capture track on the mocap clock and in the mocap frame, named
        ``"truth"``; ``rot`` is body-to-world (the transpose of the file's
        row-major matrix, see the module docstring).
    cleaning
        Steps taken while reading.
    """

    truth: Trajectory
    cleaning: tuple[CleaningStep, ...] = ()


def read_gt(path: PathLike) -> GtFile:
    """Read ``gt.csv`` (tab-separated; header optional); drop all-zero dropout rows."""
    values, line_no = _read_tab(path, "ground-truth", lambda n: GT_COLUMNS if n == len(GT_COLUMNS) else None,
                                "Time, Position X/Y/Z, Rotation[0..8]")
    steps: list[CleaningStep] = []
    dropout = np.all(values[:, 1:] == 0, axis=1)
    if dropout.any():
        steps.append(CleaningStep("drop mocap dropouts", int(dropout.sum()),
                                  f"{Path(path).name}: rows whose position and rotation are all zero"))
        values, line_no = values[~dropout], line_no[~dropout]
    if values.shape[0] == 0:
        raise DataFormatError(path, "no ground-truth rows left after removing all-zero dropout rows")
    idx, more = order_rows(path, values[:, 0], line_no, what="ground-truth", values=values)
    steps += more
    values = values[idx]
    rot = values[:, 4:13].reshape(-1, 3, 3).transpose(0, 2, 1)
    return GtFile(Trajectory(values[:, 0], values[:, 1:4], rot=rot, name="truth"), tuple(steps))
