"""Loader for the i-ASL UWB/IMU drone dataset (``iasl-uwb-imu``).

Upstream: repository ``i-ASL/uwb_imu_dataset`` (no licence file: evaluation use
only, never redistribute). A drone carrying one UWB tag (Nooploop LinkTrack
P-B) and an IMU (CH Robotics UM7) flies inside a cuboid of 8 anchors spanning
8.86 × 8.00 × 2.20 m; a Qualisys motion-capture system gives ground truth.

Layout (one folder per scenario, found by globbing, never listed by hand)::

    iasl-uwb-imu/
        uwb.yaml              anchorPositions: [x1..x8, y1..y8, z1..z8], stdV, stdW
        scenarioN/uwb.csv     Local Time (ms), System Time (ms), Position X/Y/Z (the module's
                              own estimate), Distance 1..8 (m)
        scenarioN/imu.csv     Time (whole Unix s), Linear acceleration X/Y/Z (m/s²),
                              Angular velocity X/Y/Z (rad/s)
        scenarioN/gt.csv      Time (s), Position X/Y/Z (m), Rotation[0..8] (3×3, row-major)

A ``uwb.yaml`` inside a scenario folder, if present, overrides the one at the root.

Quirks handled (each one tested)
--------------------------------
* Files are tab-separated; fields may carry spaces (``imu.csv`` has ``"\\t 0.25"``);
  the last line may lack a line terminator; ``\\r\\n`` endings are accepted.
* Blank lines are skipped wherever they are (``scenario2/uwb.csv`` starts with
  one); they hold no data, so nothing is counted.
* The header row is optional (some upstream files lack it): a first line whose
  first field is a number is data. A header, when present, must name the
  expected columns (case, spaces and punctuation ignored).
* ``imu.csv`` stamps are whole Unix seconds with ~20 rows per stamp; they are
  spread over their second (rule in :func:`spread_whole_seconds`) — a counted
  cleaning step.
* ``gt.csv`` rows whose 12 values are all zero are motion-capture dropouts:
  removed and counted.
* Ranges follow the package's range rule (:mod:`uwbwb.datasets.cleaning`): a
  range of exactly 0 in ``uwb.csv`` is the module's "no range" value and becomes
  NaN, counted; a range above ``max_range_m`` (default
  :data:`~uwbwb.datasets.cleaning.MAX_RANGE_M`) becomes NaN, counted; a negative
  range is an error.
* Rows out of time order are sorted (counted); exact duplicate rows are removed
  (counted); two different rows with one time stamp are an error.
* The rotation in ``gt.csv`` read row-major maps mocap-frame vectors into the
  body frame: angular rates derived from it as ``vee(R Ṙᵀ)`` match the gyro
  axis by axis (|corr| ≈ 0.98–1.00 on both scenarios, a proper signed axis
  permutation), while ``vee(Rᵀ Ṙ)`` matches only about z. The loader therefore
  stores its transpose as :attr:`Trajectory.rot` (body-to-world);
  :attr:`ImuAlignment.gyro_axes_corr` repeats this check on every load.

Clocks and frames, and how they are registered
----------------------------------------------
The three files have three clocks (UWB module milliseconds, mocap seconds from
0.1, IMU Unix seconds) and the motion-capture frame is not the anchor frame.
:func:`load_scenario` puts everything on the **UWB clock** (``t_s`` = seconds
since the first UWB row) and in the **anchor frame**:

1. *Truth → anchor frame and UWB clock* (:func:`register_truth`). The model is
   ``p_anchor(t) = Rz(ψ) · p_mocap(t − Δt) + T`` and
   ``range_i = |p_anchor − a_i| + b + noise``, with translation ``T`` (3),
   clock offset ``Δt`` (``t_uwb = t_mocap + Δt``), a common range bias ``b``
   (nuisance; the ranges are *not* corrected) and, optionally, a yaw ``ψ``.
   Start values come from a scan over ``Δt`` comparing linearised
   multilateration fixes with the interpolated mocap track (median offset as
   translation, median horizontal spread as score); then all parameters are
   refined by robust nonlinear least squares (soft-L1 loss, scale 0.1 m) on
   every finite range, with an analytic Jacobian. Reported: residual RMS,
   robust σ (1.4826·MAD), median |r|, per-anchor median residual, formal
   standard errors, ``Δt`` fitted separately on each half (a drift check),
   and, when ``ψ`` is not fitted, the yaw a fit would give and its RMS.
2. *IMU → UWB clock* (:func:`align_imu`). The offset maximises the correlation
   of the gyro magnitude ``|ω_imu|`` (box-filtered to the mocap rate) with the
   rotation rate of the registered mocap attitude; the same search on the
   specific-force magnitude (``|a_mocap + g ẑ|`` vs ``|f_imu|``) is reported as
   a cross-check.

On the two public scenarios the registration gives ``T`` ≈ (4.44–4.47,
4.03, 0.15–0.17) m, ``b`` ≈ −0.13 m, residual RMS ≈ 9 cm (robust σ ≈ 8 cm),
and a yaw fit below 1.3° that lowers the RMS by < 1 mm: no yaw rotation is
needed, so none is applied by default. Without ``b`` the fit pushes ``T_z``
to −0.02…−0.08 m and the RMS rises to 16 cm. The clock offsets fitted on each
half of a recording agree within 12 ms (no drift to speak of). The IMU peak
correlation is 0.99, and the accelerometer cross-check agrees within 0.05 s.
The tag's lever arm from the mocap body origin is not modelled (a fit of one
gave a few centimetres, inconsistent between scenarios): truth is the mocap
body origin.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd
import yaml
from scipy.ndimage import uniform_filter1d
from scipy.optimize import least_squares

from ..errors import DataFormatError, DataNotFoundError
from ..geometry import yaw_rotation
from ..types import Anchors, CleaningStep, ImuLog, RangeLog, Recording, Trajectory, _natural_key
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .discovery import find_dataset
from .tidy import _decode_lines, _numbers, _read_bytes

NAME = "iasl-uwb-imu"
UWB_FILE, IMU_FILE, GT_FILE = "uwb.csv", "imu.csv", "gt.csv"
ANCHORS_FILE = "uwb.yaml"
#: Standard gravity used for the specific-force cross-check, m/s².
GRAVITY_MPS2 = 9.80665

PathLike = str | os.PathLike

#: Upstream column names (headers are compared ignoring case, spaces and punctuation).
UWB_COLUMNS = ("Local Time", "System Time", "Position X", "Position Y", "Position Z")  # + Distance 1..N
IMU_COLUMNS = ("Time", "Linear acceleration X", "Linear acceleration Y", "Linear acceleration Z",
               "Angular velocity X", "Angular velocity Y", "Angular velocity Z")
GT_COLUMNS = ("Time", "Position X", "Position Y", "Position Z") + tuple(f"Rotation[{k}]" for k in range(9))
_NUMBER = re.compile(r"\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*")


class RegistrationError(ValueError):
    """The data cannot support a clock/frame registration (too little overlap or motion)."""


# --------------------------------------------------------------------------------------------
# Listing and anchors
# --------------------------------------------------------------------------------------------

def list_recordings(data_dir: PathLike | None = None) -> pd.DataFrame:
    """Scenario folders of the dataset and which files each holds.

    Every sub-folder of the dataset root that contains ``uwb.csv``,
    ``imu.csv`` or ``gt.csv`` is a scenario, in natural order.

    Returns
    -------
    pandas.DataFrame
        Columns ``name, path, has_uwb, has_imu, has_gt, anchors_path``
        (``anchors_path``: the ``uwb.yaml`` that applies, or None).
    """
    root = find_dataset(NAME, data_dir)
    rows = []
    for folder in sorted((p for p in root.iterdir() if p.is_dir()), key=lambda p: _natural_key(p.name)):
        has = {k: (folder / f).is_file() for k, f in (("uwb", UWB_FILE), ("imu", IMU_FILE), ("gt", GT_FILE))}
        if any(has.values()):
            anchors = _anchors_path(root, folder)
            rows.append({"name": folder.name, "path": folder, "has_uwb": has["uwb"], "has_imu": has["imu"],
                         "has_gt": has["gt"], "anchors_path": anchors})
    return pd.DataFrame(rows, columns=["name", "path", "has_uwb", "has_imu", "has_gt", "anchors_path"])


def _anchors_path(root: Path, folder: Path) -> Path | None:
    for candidate in (folder / ANCHORS_FILE, root / ANCHORS_FILE):
        if candidate.is_file():
            return candidate
    return None


def _read_yaml(path: PathLike) -> tuple[dict, str]:
    """The mapping in a YAML file, and the file's text."""
    text = "\n".join(_decode_lines(path, _read_bytes(path)))
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = None if mark is None else mark.line + 1
        raise DataFormatError(path, f"not valid YAML: {getattr(exc, 'problem', None) or exc}", line=line) from None
    if not isinstance(doc, dict):
        raise DataFormatError(path, "expected a YAML mapping with key 'anchorPositions'")
    return doc, text


def _yaml_line(text: str, key: str, index: int | None = None) -> int | None:
    """1-based line of ``key`` (or of item ``index`` of its list) in YAML ``text``, if found."""
    try:
        node = yaml.compose(text)
    except yaml.YAMLError:
        return None
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            if getattr(k, "value", None) == key:
                if index is None:
                    return k.start_mark.line + 1
                if isinstance(v, yaml.SequenceNode) and index < len(v.value):
                    return v.value[index].start_mark.line + 1
    return None


def read_anchors(yaml_path: PathLike) -> Anchors:
    """Anchor positions from ``uwb.yaml``.

    ``anchorPositions`` is a flat list ``[x1..xN, y1..yN, z1..zN]`` (metres);
    the anchors are named ``a1`` … ``aN`` in that order, matching the
    ``Distance 1`` … ``Distance N`` columns of ``uwb.csv``.

    Returns
    -------
    Anchors
        ``pos_m`` shape ``(N, 3)``, metres.

    Raises
    ------
    DataFormatError
        Invalid YAML, missing key, a length that is not a multiple of 3, or a
        value that is not a finite number (with the line where known).
    """
    doc, text = _read_yaml(yaml_path)
    key = "anchorPositions"
    values = doc.get(key)
    if not isinstance(values, list) or not values:
        raise DataFormatError(yaml_path, f"key {key!r} must be a non-empty list [x1..xN, y1..yN, z1..zN]",
                              line=_yaml_line(text, key))
    if len(values) % 3:
        raise DataFormatError(yaml_path, f"{key!r} has {len(values)} values, not a multiple of 3 "
                                         "([x1..xN, y1..yN, z1..zN])", line=_yaml_line(text, key))
    nums = []
    for k, v in enumerate(values):
        try:
            x = float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else float("nan")
        except OverflowError:
            x = float("nan")
        if not np.isfinite(x):
            raise DataFormatError(yaml_path, f"{key!r} item {k + 1} is not a finite number: {v!r}",
                                  line=_yaml_line(text, key, k))
        nums.append(x)
    pos = np.array(nums).reshape(3, -1).T
    return Anchors(tuple(f"a{i + 1}" for i in range(pos.shape[0])), pos)


# --------------------------------------------------------------------------------------------
# Low-level readers
# --------------------------------------------------------------------------------------------

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
    if not _NUMBER.fullmatch(first_fields[0]):  # a header row
        if tuple(_norm(f) for f in first_fields) != tuple(_norm(n) for n in names):
            raise DataFormatError(path, f"header {first!r} does not name the {what} columns: {expected}",
                                  line=first_line)
        numbered = numbered[1:]
        if not numbered:
            raise DataFormatError(path, f"{what} file has a header but no data rows", line=first_line)
    fields = [ln.split("\t") for _, ln in numbered]
    line_no = np.array([n for n, _ in numbered], dtype=int)
    for n, f in zip(line_no, fields):
        if len(f) != len(names):
            raise DataFormatError(path, f"{len(f)} tab-separated fields, expected {len(names)}", line=int(n))
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
    """

    imu: ImuLog
    unix_time0_s: float
    rate_hz: float
    cleaning: tuple[CleaningStep, ...] = ()


def read_imu(path: PathLike) -> ImuFile:
    """Read ``imu.csv`` (tab-separated; header optional).

    Whole-second stamps that repeat are spread over their second with
    :func:`spread_whole_seconds` (a counted cleaning step); stamps that are
    already strictly increasing are used as they are; repeated stamps that are
    not whole seconds are an error.
    """
    values, line_no = _read_tab(path, "IMU", lambda n: IMU_COLUMNS if n == len(IMU_COLUMNS) else None,
                                "Time, Linear acceleration X/Y/Z, Angular velocity X/Y/Z")
    order, steps = order_rows(path, values[:, 0], line_no, what="IMU", repeats="keep")  # order within a second kept
    values, line_no = values[order], line_no[order]
    stamp = values[:, 0]
    t0 = float(np.floor(stamp[0]))
    rate = np.nan
    if np.any(np.diff(stamp) == 0):
        frac = np.flatnonzero(stamp != np.round(stamp))
        if frac.size:
            i = int(frac[0])
            raise DataFormatError(path, f"time stamps repeat but {float(stamp[i])!r} is not a whole second",
                                  line=int(line_no[i]), column="Time")
        t, rate = spread_whole_seconds(stamp - t0)
        steps.append(CleaningStep("spread whole-second IMU stamps", int(stamp.size),
                                  f"{Path(path).name}: rows of each Unix second spread evenly over it, "
                                  f"nominal {rate:g} rows/s (rule: uwbwb.datasets.iasl.spread_whole_seconds)"))
    else:
        t = stamp - t0
    if np.any(np.diff(t) <= 0):
        raise DataFormatError(path, "IMU time stamps too large to resolve within a second")
    imu = ImuLog(t, values[:, 1:4], values[:, 4:7])
    return ImuFile(imu, t0, rate, tuple(steps))


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


# --------------------------------------------------------------------------------------------
# Registration of the mocap track to the anchor frame and UWB clock
# --------------------------------------------------------------------------------------------

def _track(t_ref: np.ndarray, x_ref: np.ndarray, t: np.ndarray, max_gap_s: float):
    """Piecewise-linear samples of a track.

    Returns
    -------
    x : numpy.ndarray
        ``(len(t), d)``, linear (extrapolated beyond the ends).
    slope : numpy.ndarray
        ``(len(t), d)``, derivative of the segment used.
    valid : numpy.ndarray
        ``(len(t),)`` bool: inside the span and on a segment no longer than ``max_gap_s``.
    """
    k = np.clip(np.searchsorted(t_ref, t, side="right") - 1, 0, t_ref.size - 2)
    dt = t_ref[k + 1] - t_ref[k]
    slope = (x_ref[k + 1] - x_ref[k]) / dt[:, None]
    x = x_ref[k] + slope * (t - t_ref[k])[:, None]
    valid = (t >= t_ref[0]) & (t <= t_ref[-1]) & (dt <= max_gap_s)
    return x, slope, valid


def _max_gap(t: np.ndarray) -> float:
    """Longest step bridged by interpolation: 2.5 median sample intervals."""
    return 2.5 * float(np.median(np.diff(t)))


def multilaterate_linear(anchors_pos_m: np.ndarray, range_m: np.ndarray) -> np.ndarray:
    """Linearised least-squares position fixes, one per epoch.

    Subtracting the squared-range equation of the first available anchor from
    the others gives ``2 (a_i − a_0) · p = |a_i|² − |a_0|² − d_i² + d_0²``,
    solved per epoch. Epochs are grouped by which anchors have a range, so the
    work is vectorised per group.

    Parameters
    ----------
    anchors_pos_m
        ``(n_anchors, 3)``, metres.
    range_m
        ``(T, n_anchors)``, metres, NaN = missing.

    Returns
    -------
    numpy.ndarray
        ``(T, 3)``, metres; NaN where fewer than 4 ranges or anchors that do
        not span 3-D.
    """
    out = np.full((range_m.shape[0], 3), np.nan)
    have = np.isfinite(range_m)
    patterns, inverse = np.unique(have, axis=0, return_inverse=True)
    for g, pattern in enumerate(patterns):
        cols = np.flatnonzero(pattern)
        if cols.size < 4:
            continue
        a = anchors_pos_m[cols]
        h = 2.0 * (a[1:] - a[0])
        if np.linalg.matrix_rank(h) < 3:
            continue
        rows = np.flatnonzero(inverse.ravel() == g)
        d = range_m[np.ix_(rows, cols)]
        b = (np.sum(a[1:] ** 2, axis=1) - np.sum(a[0] ** 2))[None, :] - d[:, 1:] ** 2 + d[:, :1] ** 2
        out[rows] = np.linalg.lstsq(h, b.T, rcond=None)[0].T
    return out


@dataclass(frozen=True)
class Registration:
    """Mocap → anchor frame and UWB clock: ``p = Rz(yaw) p_mocap(t − time_offset_s) + translation_m``.

    Attributes
    ----------
    time_offset_s
        ``t_uwb = t_mocap + time_offset_s``, s.
    translation_m
        ``T``, shape ``(3,)``, metres.
    yaw_rad
        Rotation about z applied before the translation (0 unless fitted), rad.
    range_bias_m
        Common additive range bias fitted as a nuisance parameter (0 unless
        fitted), metres; the ranges themselves are not corrected.
    rms_m, robust_sigma_m, median_abs_m
        Range residual RMS, 1.4826·MAD and median absolute residual, metres.
    per_anchor_median_m
        Median residual per anchor id, metres (per-anchor systematic errors).
    std
        Formal standard errors of the fitted parameters (from the Jacobian,
        robust σ; optimistic because residuals are correlated in time).
    half_offsets_s
        ``time_offset_s`` refitted on the first and the second half of the
        epochs with the other parameters fixed (their difference is a clock
        drift check).
    coarse_time_offset_s
        The start value from the multilateration scan.
    yaw_check_deg, yaw_check_rms_m
        When yaw is not fitted: the yaw a fit with it gives, and that fit's RMS.
    n_epochs, n_residuals
        UWB epochs and finite ranges used.
    method
        Plain-words description.
    """

    time_offset_s: float
    translation_m: np.ndarray
    yaw_rad: float
    range_bias_m: float
    rms_m: float
    robust_sigma_m: float
    median_abs_m: float
    per_anchor_median_m: dict
    std: dict
    half_offsets_s: tuple[float, float]
    coarse_time_offset_s: float
    yaw_check_deg: float | None
    yaw_check_rms_m: float | None
    n_epochs: int
    n_residuals: int
    method: str = ""

    def apply(self, truth: Trajectory, name: str | None = None) -> Trajectory:
        """``truth`` (mocap clock and frame) moved to the UWB clock and anchor frame."""
        r = yaw_rotation(self.yaw_rad)
        pos = truth.pos_m @ r.T + self.translation_m
        vel = None if truth.vel_mps is None else truth.vel_mps @ r.T
        rot = None if truth.rot is None else np.einsum("ij,tjk->tik", r, truth.rot)
        return Trajectory(truth.t_s + self.time_offset_s, pos, vel, rot, name or truth.name)

    def as_dict(self) -> dict:
        """Plain numbers and lists, for reports and JSON."""
        return {"time_offset_s": self.time_offset_s, "translation_m": [float(v) for v in self.translation_m],
                "yaw_deg": float(np.degrees(self.yaw_rad)), "range_bias_m": self.range_bias_m,
                "rms_m": self.rms_m, "robust_sigma_m": self.robust_sigma_m, "median_abs_m": self.median_abs_m,
                "per_anchor_median_m": dict(self.per_anchor_median_m), "std": dict(self.std),
                "half_offsets_s": list(self.half_offsets_s), "coarse_time_offset_s": self.coarse_time_offset_s,
                "yaw_check_deg": self.yaw_check_deg, "yaw_check_rms_m": self.yaw_check_rms_m,
                "n_epochs": self.n_epochs, "n_residuals": self.n_residuals, "method": self.method}


def _lag_grid(lo: float, hi: float, step: float, max_points: int) -> np.ndarray:
    step = max(step, (hi - lo) / max_points)
    return np.arange(lo, hi + 0.5 * step, step)


def _coarse_time_offset(t_uwb, fix_m, truth, lo, hi, max_gap_s) -> tuple[float, np.ndarray]:
    """Offset (and translation) whose mocap track best matches the multilateration fixes."""
    ok = np.all(np.isfinite(fix_m), axis=1)
    t_uwb, fix_m = t_uwb[ok], fix_m[ok]
    if t_uwb.size < 10:
        raise RegistrationError(f"only {t_uwb.size} UWB epochs give a position fix (need 10)")
    sub = np.linspace(0, t_uwb.size - 1, min(t_uwb.size, 2000)).astype(int)
    t_uwb, fix_m = t_uwb[sub], fix_m[sub]
    min_valid = max(10, t_uwb.size // 4)

    def score(dt):
        pos, _, valid = _track(truth.t_s, truth.pos_m, t_uwb - dt, max_gap_s)
        if valid.sum() < min_valid:
            return np.inf, None
        d = fix_m[valid] - pos[valid]
        shift = np.median(d, axis=0)
        return float(np.median(np.hypot(*(d - shift)[:, :2].T))), shift

    best = (np.inf, None, None)
    for step in (0.2, 0.5 * float(np.median(np.diff(truth.t_s)))):
        for dt in _lag_grid(lo, hi, step, 2000):
            s, shift = score(dt)
            if s < best[0]:
                best = (s, dt, shift)
        if best[1] is None:
            raise RegistrationError("UWB and ground-truth time spans never overlap by a quarter of the UWB "
                                    "epochs")
        lo, hi = best[1] - 2 * step, best[1] + 2 * step
    return float(best[1]), best[2]


@np.errstate(over="ignore", invalid="ignore", divide="ignore")  # implausible values end in RegistrationError
def register_truth(ranges: RangeLog, anchors: Anchors, truth: Trajectory, *, fit_yaw: bool = False,
                   fit_range_bias: bool = True, max_offset_s: float | None = None,
                   loss_scale_m: float = 0.1) -> Registration:
    """Estimate the mocap → anchor-frame translation and mocap → UWB clock offset.

    Method in the module docstring: multilateration scan for start values,
    then robust (soft-L1) least squares on all finite ranges with an analytic
    Jacobian.

    Parameters
    ----------
    ranges
        UWB ranges, shape ``(T, n_anchors)``, on the UWB clock.
    anchors
        Anchor positions (the target frame).
    truth
        Mocap track on its own clock and frame, ``pos_m`` shape ``(N, 3)``.
    fit_yaw
        Also fit a rotation about z.
    fit_range_bias
        Also fit a common additive range bias (recommended: it is clearly
        present in the IASL data and otherwise leaks into ``T_z``).
    max_offset_s
        Only consider ``|time_offset_s| <= max_offset_s`` (default: any offset
        that overlaps the two recordings by half the shorter one).
    loss_scale_m
        Soft-L1 scale: residuals beyond it count linearly, metres.

    Returns
    -------
    Registration

    Raises
    ------
    RegistrationError
        Too few fixes, ranges or overlap.
    """
    if len(truth) < 2 or truth.dim != 3:
        raise RegistrationError("ground truth needs at least two 3-D positions")
    if len(ranges) < 2:
        raise RegistrationError("need at least two UWB epochs")
    a = anchors.pos_m
    t_u, r_u = ranges.t_s, ranges.range_m
    gap = _max_gap(truth.t_s)
    span = min(t_u[-1] - t_u[0], truth.t_s[-1] - truth.t_s[0])
    lo, hi = t_u[0] - truth.t_s[-1] + 0.5 * span, t_u[-1] - truth.t_s[0] - 0.5 * span
    if max_offset_s is not None:
        lo, hi = max(lo, -max_offset_s), min(hi, max_offset_s)
    if not lo <= hi:
        raise RegistrationError("no time offset within the allowed range overlaps the recordings enough")
    dt0, shift0 = _coarse_time_offset(t_u, multilaterate_linear(a, r_u), truth, lo, hi, gap)

    # epochs whose mocap time stays on the track while the offset moves up to 1 s from the start value
    margin_s = 1.0
    inside = (_track(truth.t_s, truth.pos_m, t_u - dt0 - margin_s, gap)[2]
              & _track(truth.t_s, truth.pos_m, t_u - dt0 + margin_s, gap)[2])
    model = _RangeModel(truth, t_u[inside], a, r_u[inside], gap)

    def fit(yaw: bool, x0: np.ndarray):
        n_par = x0.size
        if model.n_residuals < n_par + 10:
            raise RegistrationError(f"only {model.n_residuals} ranges overlap the ground truth "
                                    f"(need {n_par + 10})")
        if not (np.all(np.isfinite(x0)) and np.all(np.isfinite(model.residuals(x0, yaw, fit_range_bias)))):
            raise RegistrationError("ranges or positions too large to evaluate (non-finite residuals)")
        sol = least_squares(model.residuals, x0, jac=model.jacobian, args=(yaw, fit_range_bias),
                            loss="soft_l1", f_scale=loss_scale_m, x_scale="jac")
        if not np.all(np.isfinite(sol.x)):
            raise RegistrationError("the fit diverged")
        return sol

    x0 = np.concatenate([shift0, [dt0], [0.0] * (fit_yaw + fit_range_bias)])
    sol = fit(fit_yaw, x0)
    res = sol.fun
    trans, dt, psi, b = _RangeModel.unpack(sol.x, fit_yaw, fit_range_bias)
    rms = float(np.sqrt(np.mean(res ** 2)))
    sigma = float(1.4826 * np.median(np.abs(res - np.median(res))))
    names = (["tx_m", "ty_m", "tz_m", "time_offset_s"] + (["yaw_rad"] if fit_yaw else [])
             + (["range_bias_m"] if fit_range_bias else []))
    cov = np.linalg.pinv(sol.jac.T @ sol.jac) * sigma ** 2
    std = {n: float(np.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(names)}
    per_anchor = {anchors.ids[k]: float(np.median(res[model.anchor == k]))
                  for k in range(len(anchors)) if np.any(model.anchor == k)}

    # drift check: the clock offset alone, refitted on each half of the epochs
    halves = []
    t_res = model.t_epoch[model.epoch]
    mid = np.median(t_res)
    for rows in (t_res < mid, t_res >= mid):
        if rows.sum() < 20:
            halves.append(float("nan"))
            continue
        x = sol.x.copy()

        def fun_dt(y, rows=rows, x=x):
            x[3] = y[0]
            return model.residuals(x, fit_yaw, fit_range_bias)[rows]

        def jac_dt(y, rows=rows, x=x):
            x[3] = y[0]
            return model.jacobian(x, fit_yaw, fit_range_bias)[rows, 3:4]

        halves.append(float(least_squares(fun_dt, [dt], jac=jac_dt, loss="soft_l1", f_scale=loss_scale_m).x[0]))

    yaw_deg = yaw_rms = None
    if not fit_yaw:  # diagnostic only: would a yaw rotation help?
        try:
            alt = fit(True, np.concatenate([sol.x[:4], [0.0], sol.x[4:]]))
        except RegistrationError:
            alt = None
        if alt is not None:
            yaw_deg = float(np.degrees(alt.x[4]))
            yaw_rms = float(np.sqrt(np.mean(alt.fun ** 2)))

    method = ("mocap track moved by p = Rz(yaw) p_mocap(t - dt) + T; start from a scan of dt comparing "
              "linearised multilateration fixes with the mocap track; refined by soft-L1 least squares "
              f"(scale {loss_scale_m} m) on all finite ranges (range = |p - a_i| + b); "
              f"yaw {'fitted' if fit_yaw else 'fixed at 0'}, "
              f"common range bias {'fitted' if fit_range_bias else 'fixed at 0'}")
    return Registration(float(dt), np.array(trans, float), float(psi), float(b), rms, sigma,
                        float(np.median(np.abs(res))), per_anchor, std, (halves[0], halves[1]), float(dt0),
                        yaw_deg, yaw_rms, int(np.unique(model.epoch).size), model.n_residuals, method)


class _RangeModel:
    """Range residuals ``r = d − |Rz(ψ) p_mocap(t − Δt) + T − a_i| − b`` and their Jacobian.

    Parameter vector ``x = [T_x, T_y, T_z, Δt, (ψ), (b)]``; ψ and b are present
    when the ``yaw`` / ``bias`` flags are set. Residuals are ordered by epoch,
    then anchor, over the finite ranges only.
    """

    def __init__(self, truth: Trajectory, t_epoch: np.ndarray, anchors_pos_m: np.ndarray,
                 range_m: np.ndarray, max_gap_s: float):
        self.truth, self.t_epoch, self.max_gap_s = truth, t_epoch, max_gap_s
        self.epoch, self.anchor = np.nonzero(np.isfinite(range_m))
        self.range_m = range_m[self.epoch, self.anchor]
        self.anchor_pos = anchors_pos_m[self.anchor]
        self.n_residuals = int(self.range_m.size)
        self._cache: tuple = (None, None)

    @staticmethod
    def unpack(x: np.ndarray, yaw: bool, bias: bool):
        psi = x[4] if yaw else 0.0
        b = x[4 + yaw] if bias else 0.0
        return x[:3], x[3], psi, b

    def _evaluate(self, x: np.ndarray, yaw: bool, bias: bool):
        key = (x.tobytes(), yaw, bias)
        if self._cache[0] != key:
            trans, dt, psi, b = self.unpack(x, yaw, bias)
            rz = yaw_rotation(psi)
            g, v, _ = _track(self.truth.t_s, self.truth.pos_m, self.t_epoch - dt, self.max_gap_s)
            g, v = g[self.epoch], v[self.epoch]
            diff = g @ rz.T + trans - self.anchor_pos
            dist = np.linalg.norm(diff, axis=1)
            u = diff / np.maximum(dist, 1e-9)[:, None]
            self._cache = (key, (self.range_m - dist - b, u, g, v, rz))
        return self._cache[1]

    def residuals(self, x: np.ndarray, yaw: bool, bias: bool) -> np.ndarray:
        return self._evaluate(x, yaw, bias)[0]

    def jacobian(self, x: np.ndarray, yaw: bool, bias: bool) -> np.ndarray:
        _, u, g, v, rz = self._evaluate(x, yaw, bias)
        cols = [-u, np.sum(u * (v @ rz.T), axis=1)[:, None]]
        if yaw:
            drz = np.array([[-rz[1, 0], -rz[0, 0], 0.0], [rz[0, 0], -rz[1, 0], 0.0], [0.0, 0.0, 0.0]])
            cols.append(-np.sum(u * (g @ drz.T), axis=1)[:, None])
        if bias:
            cols.append(-np.ones((u.shape[0], 1)))
        return np.hstack(cols)


# --------------------------------------------------------------------------------------------
# IMU clock alignment
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ImuAlignment:
    """IMU clock → truth clock: ``t_truth = t_imu + offset_s``.

    Attributes
    ----------
    offset_s
        From the gyro-magnitude correlation, s.
    peak_corr
        Correlation at ``offset_s``.
    second_peak_corr
        Highest other local maximum of the correlation more than 2 s away from
        ``offset_s`` (ambiguity check; NaN if none).
    acc_offset_s, acc_corr
        The same search on specific-force magnitude (cross-check).
    gyro_axes_corr
        ``(3, 3)`` correlation of the gyro axes (columns) with the body rates
        ``vee(Rᵀ Ṙ)`` of the truth attitude (rows), after alignment; a signed
        permutation with entries near ±1 confirms the attitude convention and
        shows how the IMU is mounted. None when truth has no attitude.
    method
        Plain-words description.
    """

    offset_s: float
    peak_corr: float
    second_peak_corr: float
    acc_offset_s: float
    acc_corr: float
    gyro_axes_corr: np.ndarray | None = None
    method: str = ""

    def as_dict(self) -> dict:
        return {"offset_s": self.offset_s, "peak_corr": self.peak_corr,
                "second_peak_corr": self.second_peak_corr, "acc_offset_s": self.acc_offset_s,
                "acc_corr": self.acc_corr,
                "gyro_axes_corr": None if self.gyro_axes_corr is None else np.round(self.gyro_axes_corr, 3).tolist(),
                "method": self.method}


def _pearson(x: np.ndarray, y: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 20:
        return float("nan")
    x, y = x[ok] - x[ok].mean(), y[ok] - y[ok].mean()
    den = np.sqrt(np.sum(x * x) * np.sum(y * y))
    return float(np.sum(x * y) / den) if den > 0 else float("nan")


def _lagged_corr(t_x, x, t_y, y, lags, max_gap_s, chunk: int = 128) -> np.ndarray:
    """Pearson correlation of ``x(t)`` with ``y(t + lag)`` for each lag, vectorised.

    ``y`` is interpolated linearly (not across gaps longer than ``max_gap_s``);
    a lag whose overlap covers fewer than ``max(20, len(x) // 4)`` samples gives NaN.
    """
    out = np.full(lags.size, np.nan)
    x_ok = np.isfinite(x)
    need = max(20, t_x.size // 4)
    for start in range(0, lags.size, chunk):
        t = t_x[None, :] + lags[start:start + chunk, None]
        k = np.clip(np.searchsorted(t_y, t, side="right") - 1, 0, t_y.size - 2)
        dt = t_y[k + 1] - t_y[k]
        yy = y[k] + (y[k + 1] - y[k]) * (t - t_y[k]) / dt
        ok = (t >= t_y[0]) & (t <= t_y[-1]) & (dt <= max_gap_s) & x_ok & np.isfinite(yy)
        n = ok.sum(axis=1)
        xs, ys = np.where(ok, x, 0.0), np.where(ok, yy, 0.0)
        mx, my = xs.sum(axis=1) / np.maximum(n, 1), ys.sum(axis=1) / np.maximum(n, 1)
        dx, dy = np.where(ok, x - mx[:, None], 0.0), np.where(ok, yy - my[:, None], 0.0)
        den = np.sqrt(np.sum(dx * dx, axis=1) * np.sum(dy * dy, axis=1))
        good = (n >= need) & (den > 0) & np.isfinite(den)
        out[start:start + chunk][good] = np.sum(dx * dy, axis=1)[good] / den[good]
    return out


def _best_lag(t_x, x, t_y, y, lo, hi, coarse_s, max_gap_s):
    """Lag ``L`` maximising corr(x(t), y(t + L)); returns (lag, corr, second-peak corr).

    Coarse grid of ``coarse_s`` over ``[lo, hi]``, then 20 ms and 2 ms grids
    around the best lag.
    """
    lags = _lag_grid(lo, hi, coarse_s, 4000)
    c = _lagged_corr(t_x, x, t_y, y, lags, max_gap_s)
    if not np.any(np.isfinite(c)):
        return float("nan"), float("nan"), float("nan")
    k = int(np.nanargmax(c))
    # the highest other local maximum more than 2 s away (an alternative alignment)
    cc = np.pad(np.where(np.isfinite(c), c, -np.inf), 1, constant_values=-np.inf)
    peak = (cc[1:-1] >= cc[:-2]) & (cc[1:-1] >= cc[2:])
    other = peak & np.isfinite(c) & (np.abs(lags - lags[k]) > 2.0)
    second = float(np.max(c[other])) if other.any() else float("nan")
    best, corr = float(lags[k]), float(c[k])
    for half_width, step in ((2 * coarse_s, 0.02), (0.04, 0.002)):
        fine = best + np.arange(-half_width, half_width + 1e-9, step)
        cf = _lagged_corr(t_x, x, t_y, y, fine, max_gap_s)
        if np.any(np.isfinite(cf)) and np.nanmax(cf) >= corr:
            j = int(np.nanargmax(cf))
            best, corr = float(fine[j]), float(cf[j])
    return best, corr, second


def _rate_magnitude(truth: Trajectory, max_gap_s: float):
    """Mid-interval times and rotation-rate magnitude (rad/s) of the truth attitude."""
    rel = np.einsum("tji,tjk->tik", truth.rot[:-1], truth.rot[1:])
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    dt = np.diff(truth.t_s)
    ok = dt <= max_gap_s
    return (0.5 * (truth.t_s[:-1] + truth.t_s[1:]))[ok], (np.arccos(cos) / dt)[ok]


def _smooth_on_grid(t: np.ndarray, x: np.ndarray, width_s: float, max_points: int = 5000):
    """``x`` box-filtered over ``width_s``, sampled every ``width_s / 2`` (at most ``max_points``)."""
    step = max(width_s / 5.0, (t[-1] - t[0]) / 200_000)
    grid = np.arange(t[0], t[-1], step)
    y = uniform_filter1d(np.interp(grid, t, x), size=max(1, int(round(width_s / step))), mode="nearest")
    keep = max(1, int(round(0.5 * width_s / step)), -(-grid.size // max_points))
    return grid[::keep], y[::keep]


@np.errstate(over="ignore", invalid="ignore", divide="ignore")  # implausible values end in RegistrationError
def align_imu(imu: ImuLog, truth: Trajectory, *, max_lag_s: float | None = None) -> ImuAlignment:
    """Clock offset of an IMU against a truth track with attitude.

    The gyro magnitude, box-filtered over one truth sample interval, is
    correlated with the rotation-rate magnitude of the truth attitude
    (``arccos((tr(R_kᵀ R_{k+1}) − 1)/2) / Δt``) for lags on a 0.1 s grid, then
    on 20 ms and 2 ms grids around the best one. Magnitudes do not depend on how the
    IMU is mounted. The specific-force magnitude (``|a + g ẑ|`` from the truth
    positions, twice differentiated, vs ``|f_imu|``) gives an independent
    cross-check.

    Parameters
    ----------
    imu
        IMU samples on their own clock.
    truth
        Track with ``rot`` (body-to-world), shape ``(N, 3, 3)``.
    max_lag_s
        Only consider ``|offset| <= max_lag_s`` (default: any lag overlapping
        the two by half the shorter one).

    Returns
    -------
    ImuAlignment

    Raises
    ------
    RegistrationError
        No attitude, too few samples or no overlap.
    """
    if truth.rot is None or len(truth) < 3:
        raise RegistrationError("IMU alignment needs a truth track with attitude (at least 3 samples)")
    if len(imu) < 20:
        raise RegistrationError(f"only {len(imu)} IMU samples (need 20)")
    gap = _max_gap(truth.t_s)
    width = float(np.median(np.diff(truth.t_s)))
    span = min(imu.t_s[-1] - imu.t_s[0], truth.t_s[-1] - truth.t_s[0])
    lo, hi = truth.t_s[0] - imu.t_s[-1] + 0.5 * span, truth.t_s[-1] - imu.t_s[0] - 0.5 * span
    if max_lag_s is not None:
        lo, hi = max(lo, -max_lag_s), min(hi, max_lag_s)
    if not lo <= hi:
        raise RegistrationError("IMU and truth time spans do not overlap enough")
    t_w, w = _rate_magnitude(truth, gap)
    if t_w.size < 3:
        raise RegistrationError("too few gap-free truth attitude pairs")
    t_g, g = _smooth_on_grid(imu.t_s, np.linalg.norm(imu.gyro_radps, axis=1), width)
    offset, peak, second = _best_lag(t_g, g, t_w, w, lo, hi, 0.1, gap)
    if not np.isfinite(offset):
        raise RegistrationError("gyro and truth rotation rate never overlap enough to correlate")

    vel = np.gradient(truth.pos_m, truth.t_s, axis=0)
    acc = np.gradient(vel, truth.t_s, axis=0)
    f_truth = np.linalg.norm(acc + [0.0, 0.0, GRAVITY_MPS2], axis=1)
    t_f, f = _smooth_on_grid(imu.t_s, np.linalg.norm(imu.acc_mps2, axis=1), width)
    acc_offset, acc_corr, _ = _best_lag(t_f, f, truth.t_s, f_truth, lo, hi, 0.1, gap)

    rot = truth.rot
    rdot = np.diff(rot, axis=0) / np.diff(truth.t_s)[:, None, None]
    w_mat = np.einsum("tji,tjk->tik", 0.5 * (rot[:-1] + rot[1:]), rdot)
    w_body = 0.5 * np.stack([w_mat[:, 2, 1] - w_mat[:, 1, 2], w_mat[:, 0, 2] - w_mat[:, 2, 0],
                             w_mat[:, 1, 0] - w_mat[:, 0, 1]], axis=1)
    t_mid = 0.5 * (truth.t_s[:-1] + truth.t_s[1:])
    ok = (np.diff(truth.t_s) <= gap) & (t_mid - offset >= imu.t_s[0]) & (t_mid - offset <= imu.t_s[-1])
    axes = None
    if ok.sum() >= 20:
        gyro = np.column_stack([np.interp(t_mid[ok] - offset, imu.t_s, imu.gyro_radps[:, j]) for j in range(3)])
        axes = np.array([[_pearson(w_body[ok, i], gyro[:, j]) for j in range(3)] for i in range(3)])

    method = ("lag maximising the correlation of |gyro| (box-filtered over one truth interval) with the "
              "rotation-rate magnitude of the truth attitude; 0.1 s, 20 ms, 2 ms grids; cross-check with "
              "specific-force magnitude")
    return ImuAlignment(offset, peak, second, acc_offset, acc_corr, axes, method)


# --------------------------------------------------------------------------------------------
# Scenario loader
# --------------------------------------------------------------------------------------------

def load_scenario(scenario: str = "scenario1", data_dir: PathLike | None = None, *, register: bool = True,
                  fit_yaw: bool = False, fit_range_bias: bool = True,
                  max_offset_s: float | None = None, max_range_m: float = MAX_RANGE_M) -> Recording:
    """One scenario as a :class:`~uwbwb.Recording` on the UWB clock and in the anchor frame.

    Parameters
    ----------
    scenario
        Folder name, e.g. ``"scenario1"`` (see :func:`list_recordings`).
    data_dir
        Folder holding ``iasl-uwb-imu/`` (default: the discovery order).
    register
        Estimate and apply the mocap → anchor-frame/UWB-clock registration and
        the IMU clock offset (module docstring). With ``False`` the truth stays
        on the mocap clock and frame and the IMU on its own clock (the
        recording's containers are then *not* mutually aligned).
    fit_yaw, fit_range_bias, max_offset_s
        Passed to :func:`register_truth`.
    max_range_m
        Ranges above this become NaN (counted; see :func:`read_uwb`).

    Returns
    -------
    Recording
        One tag ``"tag"``; anchors ``a1..aN`` from ``uwb.yaml``; ``truth["tag"]``
        with position and attitude (body-to-world); ``imu`` (if the file
        exists); ``cleaning`` from all files; ``meta`` with the source paths,
        clock origins, ``device_estimate`` (the module's own X/Y/Z output as a
        :class:`Trajectory`), the IMU noise figures from ``uwb.yaml``
        (``stdV``, ``stdW``, as given upstream), and — when registered —
        ``registration`` (:class:`Registration`), ``imu_alignment``
        (:class:`ImuAlignment`) and the headline numbers
        ``truth_time_offset_s``, ``truth_translation_m``, ``imu_time_offset_s``.

    Raises
    ------
    DataNotFoundError
        No such scenario, no ``uwb.csv``/``uwb.yaml``, or no ``gt.csv`` while
        ``register`` is True.
    DataFormatError
        A file breaks the format, or the data cannot be registered (the message
        names the file that lacks overlap or motion).
    """
    root = find_dataset(NAME, data_dir)
    folder = root / scenario
    if not (folder / UWB_FILE).is_file():
        known = list(list_recordings(root.parent)["name"]) if root.is_dir() else []
        raise DataNotFoundError(f"{folder / UWB_FILE} not found; scenarios with data: {known}")
    yaml_path = _anchors_path(root, folder)
    if yaml_path is None:
        raise DataNotFoundError(f"no {ANCHORS_FILE} in {folder} or {root}")
    anchors = read_anchors(yaml_path)
    uwb = read_uwb(folder / UWB_FILE, anchors.ids, max_range_m=max_range_m)
    imu_path, gt_path = folder / IMU_FILE, folder / GT_FILE
    imu = read_imu(imu_path) if imu_path.is_file() else None
    gt = read_gt(gt_path) if gt_path.is_file() else None
    if register and gt is None:
        raise DataNotFoundError(f"{gt_path} not found: registration needs ground truth "
                                f"(load with register=False)")
    config, _ = _read_yaml(yaml_path)
    meta: dict = {
        "source": {"uwb": str(folder / UWB_FILE), "imu": str(imu_path) if imu else None,
                   "gt": str(gt_path) if gt else None, "anchors": str(yaml_path)},
        "uwb_local_time0_ms": uwb.local_time0_ms,
        "imu_unix_time0_s": None if imu is None else imu.unix_time0_s,
        "imu_noise": {k: config[k] for k in ("stdV", "stdW") if k in config},
        "device_estimate": uwb.device,
        "registered": bool(register),
    }
    cleaning = list(uwb.cleaning) + list(gt.cleaning if gt else ()) + list(imu.cleaning if imu else ())
    truth = {} if gt is None else {"tag": gt.truth}
    imu_log = None if imu is None else imu.imu
    if register:
        try:
            reg = register_truth(uwb.ranges, anchors, gt.truth, fit_yaw=fit_yaw,
                                 fit_range_bias=fit_range_bias, max_offset_s=max_offset_s)
        except RegistrationError as exc:
            raise DataFormatError(gt_path, f"cannot register ground truth to {UWB_FILE}: {exc}") from None
        if np.any(np.diff(gt.truth.t_s + reg.time_offset_s) <= 0):
            raise DataFormatError(gt_path, "ground-truth time stamps too large to shift to the UWB clock")
        truth = {"tag": reg.apply(gt.truth)}
        meta.update(registration=reg, truth_time_offset_s=reg.time_offset_s,
                    truth_translation_m=reg.translation_m.copy())
        if imu is not None:
            try:
                al = align_imu(imu.imu, truth["tag"])
            except RegistrationError as exc:
                raise DataFormatError(imu_path, f"cannot align the IMU clock: {exc}") from None
            t_imu = imu.imu.t_s + al.offset_s
            if np.any(np.diff(t_imu) <= 0):
                raise DataFormatError(imu_path, "IMU time stamps too large to shift to the UWB clock")
            imu_log = ImuLog(t_imu, imu.imu.acc_mps2, imu.imu.gyro_radps)
            meta.update(imu_alignment=al, imu_time_offset_s=al.offset_s)
    return Recording(NAME, scenario, anchors, {"tag": uwb.ranges}, truth, imu_log, tuple(cleaning), meta)
