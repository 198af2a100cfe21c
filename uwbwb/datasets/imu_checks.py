"""Checks of an IMU file's samples: units, spikes and gaps, each reported.

Loaders call :func:`check_imu_samples` after parsing and time-ordering an IMU file. The rules:

* **Units** (an error naming the file; rules in :func:`~uwbwb.models.imu.unit_problem`): the
  median specific-force magnitude must lie within g ± 2 m/s² (a log in mg or g fails, with the
  measured magnitude); the gyro rate scale fitted from the tilt of the specific force
  (:func:`~uwbwb.models.imu.imu_evidence`) must not say deg/s. More than
  :data:`~uwbwb.models.imu.MAX_SPIKE_FRACTION` (1 %) of the samples beyond full scale is a unit
  error too, not spikes.
* **Spikes** (dropped, counted with their lines): a sample with a component beyond the MEMS
  full scale (:data:`~uwbwb.models.imu.ACC_FULL_SCALE_MPS2`, 16 g;
  :data:`~uwbwb.models.imu.GYRO_FULL_SCALE_RADPS`, 2000 °/s) cannot have been measured.
* **Gaps**: a time step longer than :data:`MAX_GAP_SAMPLES` nominal intervals (median step).
  No filter interpolates across such a gap: the UWB/INS filters and INS alone
  (:class:`~uwbwb.filters.eskf.TightEskf`, :class:`~uwbwb.filters.eskf.LooseFilter`,
  :func:`~uwbwb.filters.eskf.dead_reckon`, same rule) coast across it with velocity and attitude
  held and list it in their result's ``meta["imu_gaps_s"]``, but nothing measured the motion
  there, so by default this is an error listing the gaps; ``gaps="warn"`` keeps the log and warns
  with the same list.
  Whole-second stamps hide gaps inside a second; :func:`check_second_counts` finds seconds
  with rows missing, under the same policy.
* Non-finite numbers never get this far: the parsers refuse them, naming line and column.

The axis sign (z up or down at rest) is a property of the format, not a defect: it is measured
(:attr:`ImuChecks.evidence`) and left to the convention (:class:`~uwbwb.models.imu.ImuConvention`),
whose :meth:`~uwbwb.models.imu.ImuConvention.to_body` refuses a z-down *body* frame.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataFormatError
from ..models.imu import ACC_FULL_SCALE_MPS2, GYRO_FULL_SCALE_RADPS, ImuEvidence, unit_problem
from ..types import CleaningStep
from .cleaning import lines_text

__all__ = ["GAP_POLICIES", "ImuChecks", "ImuGapWarning", "MAX_GAP_SAMPLES", "check_imu_samples",
           "check_second_counts"]

#: Longest step between IMU samples, in nominal intervals, that is not a gap: the filters
#: interpolate linearly within such a step and coast across a longer one (an assumption: a few
#: samples at 20–200 Hz is well below the time over which a consumer IMU's attitude and velocity
#: change appreciably while flying).
MAX_GAP_SAMPLES = 5
GAP_POLICIES = ("error", "warn")


class ImuGapWarning(UserWarning):
    """An IMU log kept although it has gaps longer than a filter should bridge."""


@dataclass(frozen=True)
class ImuChecks:
    """Outcome of :func:`check_imu_samples`.

    Attributes
    ----------
    keep
        Boolean mask of the samples kept, shape ``(T,)``.
    steps
        Cleaning steps (``"IMU spikes dropped"`` when any).
    gaps_s
        ``(start, end)`` times of each gap longer than the limit, shape ``(G, 2)``, s, on the kept samples.
    max_gap_s
        The limit used, s.
    evidence
        Units and axes as measured (:class:`~uwbwb.models.imu.ImuEvidence`), on the kept samples.
    """

    keep: np.ndarray
    steps: tuple[CleaningStep, ...]
    gaps_s: np.ndarray
    max_gap_s: float
    evidence: ImuEvidence


def check_imu_samples(path: str | os.PathLike, t_s, acc, gyro, line_no, *, gaps: str = "error",
                      max_gap_s: float | None = None) -> ImuChecks:
    """Apply the module's rules to one IMU file's samples (time-ordered, finite).

    Parameters
    ----------
    path
        The file, for messages.
    t_s
        Sample times, shape ``(T,)``, s, strictly increasing.
    acc, gyro
        Accelerometer (m/s² expected) and gyro (rad/s expected) samples, shape ``(T, 3)``.
    line_no
        1-based file line of each sample, shape ``(T,)``.
    gaps
        ``"error"`` (default) or ``"warn"`` for gaps longer than ``max_gap_s``.
    max_gap_s
        Longest allowed step, s; default :data:`MAX_GAP_SAMPLES` × the median step.

    Returns
    -------
    ImuChecks

    Raises
    ------
    DataFormatError
        Accelerations not in m/s², gyro rates in deg/s, too many samples beyond full scale,
        or (``gaps="error"``) a gap longer than the limit; the message gives the evidence.
    ValueError
        An unknown ``gaps`` policy or a non-positive ``max_gap_s``.
    """
    if gaps not in GAP_POLICIES:
        raise ValueError(f"gaps must be one of {GAP_POLICIES}, got {gaps!r}")
    if max_gap_s is not None and not (isinstance(max_gap_s, (int, float)) and max_gap_s > 0):
        raise ValueError(f"max_gap_s must be a positive number of seconds, got {max_gap_s!r}")
    name = Path(path).name
    t, a, w = np.asarray(t_s, float), np.asarray(acc, float), np.asarray(gyro, float)
    line_no = np.asarray(line_no)
    problem, ev, spike = unit_problem(t, a, w)
    if problem is not None:
        raise DataFormatError(path, problem, column="Angular velocity" if "gyro" in problem else "Linear acceleration")
    steps: list[CleaningStep] = []
    if spike.any():
        mag = np.maximum(np.abs(a[spike]).max(axis=1) / ACC_FULL_SCALE_MPS2, np.abs(w[spike]).max(axis=1)
                         / GYRO_FULL_SCALE_RADPS)
        steps.append(CleaningStep("IMU spikes dropped", int(spike.sum()),
                                  f"{name}: samples beyond the MEMS full scale "
                                  f"(16 g = {ACC_FULL_SCALE_MPS2:.4g} m/s², "
                                  f"2000 °/s = {GYRO_FULL_SCALE_RADPS:.4g} rad/s; up to {mag.max():.3g}× it) dropped "
                                  f"(lines {lines_text(line_no[spike])})"))
    keep = ~spike
    tk = t[keep]
    dt = np.diff(tk)
    if max_gap_s is not None:
        limit = float(max_gap_s)
    else:
        limit = MAX_GAP_SAMPLES * float(np.median(dt)) if dt.size else np.inf
    big = np.flatnonzero(dt > limit)
    gaps_s = np.column_stack([tk[big], tk[big + 1]]) if big.size else np.zeros((0, 2))
    if big.size:
        lk = line_no[keep]
        shown = ", ".join(f"{s:.3f}–{e:.3f} s (line {int(lk[i + 1])})" for (s, e), i in zip(gaps_s[:5], big[:5]))
        more = ", ..." if big.size > 5 else ""
        text = (f"{big.size} gap(s) between IMU samples longer than {limit:.3g} s ({MAX_GAP_SAMPLES} nominal "
                f"intervals unless given), longest {float(dt[big].max()):.3g} s: {shown}{more}; the filters "
                f"coast across them (velocity and attitude held, nothing measured there)")
        if gaps == "error":
            raise DataFormatError(path, text + " (load with imu_gaps='warn' to keep the log)", line=int(lk[big[0] + 1]))
        warnings.warn(f"{path}: {text}", ImuGapWarning, stacklevel=3)
    return ImuChecks(keep, tuple(steps), gaps_s, limit, ev)


def check_second_counts(path: str | os.PathLike, stamp_s, line_no, rate_hz: float, *, t0_s: float = 0.0,
                        gaps: str = "error") -> np.ndarray:
    """Gaps hidden inside whole-second stamps: interior seconds with rows missing.

    Rows that share a whole-second stamp are spread evenly over it
    (:func:`uwbwb.datasets.iasl.spread_whole_seconds`), so rows missing inside a second leave
    no time gap: the survivors are stretched over the second. An interior second (not the
    first or last) holding fewer than ``rate_hz − MAX_GAP_SAMPLES`` rows has lost more samples
    than a filter should bridge; where in the second they were lost is unknown.

    Parameters
    ----------
    path
        The file, for messages.
    stamp_s
        Whole-second stamps, non-decreasing, shape ``(T,)``, s.
    line_no
        1-based file line of each row, shape ``(T,)``.
    rate_hz
        Nominal rows per second (median over interior seconds).
    t0_s
        Subtracted from the stamps for the returned times.
    gaps
        ``"error"`` or ``"warn"`` (:data:`GAP_POLICIES`).

    Returns
    -------
    numpy.ndarray
        ``(start, end)`` of each short second, shape ``(G, 2)``, s after ``t0_s``.

    Raises
    ------
    DataFormatError
        With ``gaps="error"``, when any second is short (the first one's line named).
    """
    if gaps not in GAP_POLICIES:
        raise ValueError(f"gaps must be one of {GAP_POLICIES}, got {gaps!r}")
    stamp_s = np.asarray(stamp_s, float)
    sec, start, count = np.unique(stamp_s, return_index=True, return_counts=True)
    if sec.size < 3 or not np.isfinite(rate_hz):
        return np.zeros((0, 2))
    short = np.flatnonzero(count[1:-1] < rate_hz - MAX_GAP_SAMPLES) + 1
    if not short.size:
        return np.zeros((0, 2))
    lines = np.asarray(line_no)[start[short]]
    shown = ", ".join(f"{sec[k] - t0_s:g} s: {int(count[k])} rows" for k in short[:5]) + (", ..." if short.size > 5
                                                                                          else "")
    text = (f"{short.size} whole second(s) hold fewer than {rate_hz - MAX_GAP_SAMPLES:g} rows (nominal "
            f"{rate_hz:g}/s; {shown}; first lines {lines_text(lines)}): samples lost inside a second, where "
            f"unknown; spreading the rest over it would stretch time")
    if gaps == "error":
        raise DataFormatError(path, text + " (load with imu_gaps='warn' to keep the log)", line=int(lines[0]))
    warnings.warn(f"{path}: {text}", ImuGapWarning, stacklevel=3)
    return np.column_stack([sec[short] - t0_s, sec[short] + 1 - t0_s])
