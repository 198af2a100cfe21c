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
* ``imu.csv`` samples are checked (:mod:`uwbwb.datasets.imu_checks`): a median
  ``|f|`` outside 9.81 ± 2 m/s² (mg? g?) or a gyro whose rates do not follow the
  tilt of the specific force in rad/s (deg/s?) is an error with the measured
  evidence; a sample beyond the MEMS full scale (16 g, 2000 °/s) is dropped and
  counted; a gap longer than 5 nominal intervals is an error (``imu_gaps="warn"``
  keeps it, warns and lists it in ``meta["imu_gaps_s"]``). The UM7 axes are z-down
  (f_z ≈ −10.3 at rest): measured in ``meta["imu_evidence"]``, not a defect.
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

The estimators live in :mod:`uwbwb.datasets.registration` (shared with the
other loaders); this loader applies them:

1. *Truth → anchor frame and UWB clock* (:func:`~uwbwb.datasets.registration.register_truth`). The model is
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
2. *IMU → UWB clock* (:func:`~uwbwb.datasets.registration.align_imu`). The offset maximises the correlation
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
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd
import yaml

from ..errors import DataFormatError, DataNotFoundError
from ..types import Anchors, CleaningStep, ImuLog, RangeLog, Recording, Trajectory, _natural_key
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .discovery import find_dataset
from .imu_checks import ImuChecks, check_imu_samples, check_second_counts
from .registration import ImuAlignment, Registration, RegistrationError, align_imu, register_truth
from .tidy import _decode_lines, _numbers, _read_bytes, _split_rows

NAME = "iasl-uwb-imu"
UWB_FILE, IMU_FILE, GT_FILE = "uwb.csv", "imu.csv", "gt.csv"
ANCHORS_FILE = "uwb.yaml"

PathLike = str | os.PathLike

#: Upstream column names (headers are compared ignoring case, spaces and punctuation).
UWB_COLUMNS = ("Local Time", "System Time", "Position X", "Position Y", "Position Z")  # + Distance 1..N
IMU_COLUMNS = ("Time", "Linear acceleration X", "Linear acceleration Y", "Linear acceleration Z",
               "Angular velocity X", "Angular velocity Y", "Angular velocity Z")
GT_COLUMNS = ("Time", "Position X", "Position Y", "Position Z") + tuple(f"Rotation[{k}]" for k in range(9))
_NUMBER = re.compile(r"\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*")


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


# --------------------------------------------------------------------------------------------
# Scenario loader
# --------------------------------------------------------------------------------------------

def load_scenario(scenario: str = "scenario1", data_dir: PathLike | None = None, *, register: bool = True,
                  fit_yaw: bool = False, fit_range_bias: bool = True,
                  max_offset_s: float | None = None, max_range_m: float = MAX_RANGE_M,
                  imu_gaps: str = "error") -> Recording:
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
    imu_gaps
        ``"error"`` (default) or ``"warn"``: what a gap in ``imu.csv`` longer than
        5 nominal intervals is (see :func:`read_imu`); kept gaps are listed in
        ``meta["imu_gaps_s"]`` on the IMU's own clock.

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
    imu = read_imu(imu_path, gaps=imu_gaps) if imu_path.is_file() else None
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
        "imu_evidence": None if imu is None else imu.checks.evidence,
        "imu_gaps_s": None if imu is None else imu.checks.gaps_s,
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
