"""Loader for the Hanyang outdoor UWB dataset, dynamic part (``hanyang-outdoor-uwb``).

Upstream: repository ``cucudasluv/UWB-dataset`` (Apache-2.0). A ground robot
carrying one UWB tag drives two trajectory shapes outdoors, in line of sight
(LOS) and non line of sight (NLOS), around a cluster of four anchors; an RTK
GNSS receiver gives the reference track. Layout (cases found by globbing, never
listed by hand)::

    hanyang-outdoor-uwb/Dynamic_measurements/{LOS,NLOS}/Trajectory_{A,B}/Case_N/
        A3.csv A5.csv A9.csv A12.csv   one file per anchor (ROS topic dumps)
        trajectory.csv                 reference track, anchor frame
        LS.csv ESKF.csv                the dataset authors' own estimates
        RMSD_results.txt               the RMSEs the authors computed from them
        gnss.csv                       raw RTK fixes (not read)

**Case names** are the path below ``Dynamic_measurements``, e.g.
``"NLOS/Trajectory_A/Case_1"`` (:func:`dynamic_cases` lists them); the
recording's label is ``hanyang-outdoor-uwb/NLOS/Trajectory_A/Case_1``. A folder
of this layout anywhere else can be given by its path.

Files and quirks handled (each one tested)
------------------------------------------
* ``A<id>.csv`` (every ``A<number>.csv`` of the folder is an anchor, named by its
  file stem, e.g. ``"A12"``): header ``%time, field.stamp, field.id, field.x,
  field.y, field.z, field.distanceFromTag, field.rssi, field.rssi_fp``. The
  measurement time is ``field.stamp`` (ns, the message stamp; ``%time``, the
  recorder's receive time, is kept in ``meta`` as its median lag).
  ``field.id`` must be the file's number and the anchor position must be the
  same on every row (both errors otherwise, naming the line): a moving anchor
  is not something to average.
* ``field.distanceFromTag`` follows the package's range rule
  (:mod:`uwbwb.datasets.cleaning`): negative is an error, above ``max_range_m``
  becomes NaN (counted). RSSI of ``-inf`` becomes NaN (counted); any other
  non-number is an error.
* ``trajectory.csv``: ``timestamp`` (ns written as a float, e.g.
  ``1.7345014855003267e+18``), ``x, y, z`` (m), ``heading_degrees``.
* ``LS.csv``, ``ESKF.csv``: ``timestamp`` (ns), ``x, y, z``. ``ESKF.csv`` repeats
  some rows exactly (its last rows upstream): dropped and counted.
* In every file: blank lines are removed and counted; rows out of time order are
  sorted (counted); exact repeats dropped (counted); two different rows with one
  time stamp are an error; a wrong field count or a non-number is an error with
  file, line and column.

Epochs
------
The anchors answer one after another within a few milliseconds, about ten
times a second. The measurements of all anchors are merged in time order and
cut into epochs wherever two consecutive measurements are more than
``epoch_gap_s`` apart (default: a quarter of the median interval between one
anchor's measurements), or where an anchor would appear twice. An epoch's time
is the mean of its measurements' stamps; ``meta["epoch_spread_s"]`` gives the
largest spread within an epoch (a few ms: at ~1 m/s a few mm of motion).

Clocks and height, and how they are registered
----------------------------------------------
All stamps are Unix nanoseconds, but the ranges are stamped by the robot's
computer and the reference by the GNSS receiver, so the clocks are checked, not
assumed: :func:`~uwbwb.datasets.registration.register_truth` fits ``range_i =
|p_ref(t − Δt) + T − a_i| + b`` (robust least squares on every range; ``Δt`` the
clock offset, ``t_ranges = t_ref + Δt``; ``T`` a translation; ``b`` a common range
bias) and reports ``Δt`` refitted on each half (drift check). On the four
provided cases ``Δt`` = 0.17–0.20 s (halves within 60 ms), ``T`` ≈ (0.01–0.10,
0.00–0.05, 0.97–1.15) m, robust residual σ 6–9 cm. A registration is refused (an error naming
``trajectory.csv`` and every number that does not fit) when its robust residual σ exceeds
:data:`MAX_REGISTRATION_SIGMA_M`, its horizontal translation :data:`MAX_REFERENCE_SHIFT_M`, its tag height
leaves :data:`TAG_HEIGHT_RANGE_M`, or the two halves' offsets differ by more than
:data:`MAX_HALF_OFFSET_SPREAD_S`: a reference in millimetres, shifted, mirrored or seconds off. What is applied:

* the **clock offset** ``Δt`` (the reference is moved onto the ranges' clock),
  always: without it every reference point is ~0.2 s late, ~0.2 m at the robot's
  ~1 m/s;
* **not** the horizontal translation (the reference is documented to be in the
  anchors' frame; 10 cm is within what the fit can tell from a 4-anchor cluster,
  and fitting the frame on the scored truth would tune the truth to the ranges);
* the **tag height**: the reference is the GNSS antenna's ground track (z ≈ 0,
  the robot drives on the ground) while the tag rides above it. ``T_z`` is the
  tag's height above the reference; it is a calibration, so
  :func:`load_dynamic_case` takes it as ``tag_height_m`` (e.g. fitted on
  *another* case, as the experiment does) and uses this case's own ``T_z`` only
  when none is given (``meta["tag_height_source"]`` says which). The truth's z
  is the reference z plus that height.

The authors' estimates are stamped by the same computer as the ranges (their
scripts stamp each output with the latest IMU message): they are kept on their
own stamps (``t_s`` on the recording's clock, no shift), and
``meta["authors_lag_s"]`` reports the lag (10 ms grid) minimising each one's trimmed mean
squared horizontal distance to the registered reference (their latency; a diagnostic, not applied).

Cleaning report: ``Recording.cleaning`` holds every step of every file read.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFormatError, DataNotFoundError
from ..types import Anchors, CleaningStep, EstimateStatus, Estimates, RangeLog, Recording, Trajectory, _natural_key
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .discovery import find_dataset
from .hanyang import NAME
from .registration import Registration, RegistrationError, register_truth
from .text import _decode_lines, _numbers, _read_bytes, _split_rows

__all__ = ["ANCHOR_COLUMNS", "AUTHORS_FILES", "AnchorFile", "DYNAMIC_DIR", "ESTIMATE_COLUMNS", "MAX_OFFSET_S",
           "TRAJECTORY_COLUMNS", "TRIM", "case_dir", "dynamic_cases", "group_epochs",
           "load_dynamic_case", "read_anchor_file", "read_estimates", "read_trajectory"]

DYNAMIC_DIR = "Dynamic_measurements"
ANCHOR_COLUMNS = ("%time", "field.stamp", "field.id", "field.x", "field.y", "field.z", "field.distanceFromTag",
                  "field.rssi", "field.rssi_fp")
TRAJECTORY_COLUMNS = ("timestamp", "x", "y", "z", "heading_degrees")
ESTIMATE_COLUMNS = ("timestamp", "x", "y", "z")
#: The authors' estimate files, by method name.
AUTHORS_FILES = {"LS": "LS.csv", "ESKF": "ESKF.csv"}
TRAJECTORY_FILE = "trajectory.csv"
#: Largest clock offset between ranges and reference searched, seconds. An assumption: the
#: files share Unix time, so an offset of seconds would mean a misconfigured clock.
MAX_OFFSET_S = 5.0
#: What a registration of the reference to the ranges may show and still be applied (assumptions, each from the
#: four provided cases with a wide margin; a registration outside any of them is an error naming the file): the
#: robust residual σ (provided 6–9 cm), the horizontal translation (the reference is documented to be in the
#: anchors' frame; provided ≤ 0.11 m), the tag height above the reference (a tag on a ground robot; provided
#: 0.97–1.15 m), the clock offsets fitted on the two halves (provided within 60 ms of each other).
MAX_REGISTRATION_SIGMA_M = 0.25
MAX_REFERENCE_SHIFT_M = 0.5
TAG_HEIGHT_RANGE_M = (0.0, 3.0)
MAX_HALF_OFFSET_SPREAD_S = 0.25
#: Share of the smallest squared distances averaged when the authors' lag is estimated (an assumption:
#: up to 20 % of their epochs may be outliers, as NLOS runs show).
TRIM = 0.8

_ANCHOR_FILE = re.compile(r"A(?P<id>\d+)\.csv")
_INT = re.compile(r"\s*\d+\s*")

PathLike = str | os.PathLike


# --------------------------------------------------------------------------------------------
# Reading one file
# --------------------------------------------------------------------------------------------

def _read_table(path: PathLike, header: tuple[str, ...], what: str
                ) -> tuple[dict[str, list[str]], np.ndarray, list[CleaningStep]]:
    """Columns of field texts and 1-based line numbers of a comma-separated file with ``header``."""
    lines = _decode_lines(path, _read_bytes(path))
    name = Path(path).name
    if not lines or not lines[0].strip():
        raise DataFormatError(path, f"empty {what} file: expected the header {','.join(header)!r}", line=1)
    got = tuple(f.strip() for f in lines[0].split(","))
    if got != header:
        raise DataFormatError(path, f"header {lines[0]!r} is not a {what} header; expected {','.join(header)!r}",
                              line=1)
    body = [(i, ln) for i, ln in enumerate(lines[1:], start=2)]
    blank = [i for i, ln in body if not ln.replace(",", "").strip()]
    body = [(i, ln) for i, ln in body if ln.replace(",", "").strip()]
    fields, line_no = _split_rows(path, body, ",", header, what=what, header_line=1)
    steps = [CleaningStep("empty lines", len(blank), f"{name}: lines without a value removed "
                                                     f"(lines {', '.join(map(str, blank[:5]))})")] if blank else []
    return {c: [f[k] for f in fields] for k, c in enumerate(header)}, line_no, steps


def _stamps_ns(path: PathLike, text: list[str], line_no: np.ndarray, column: str) -> np.ndarray:
    """Nanosecond stamps as int64: plain integers exactly, float notation rounded (the reference file)."""
    if all(_INT.fullmatch(s) for s in text):
        return np.array([int(s) for s in text], dtype=np.int64)
    value = _numbers(path, text, line_no, column)
    if np.any(np.abs(value) >= 2.0 ** 63):
        i = int(np.flatnonzero(np.abs(value) >= 2.0 ** 63)[0])
        raise DataFormatError(path, f"{column} {text[i]!r} is too large for a nanosecond stamp",
                              line=int(line_no[i]), column=column)
    return np.round(value).astype(np.int64)


@dataclass(frozen=True)
class AnchorFile:
    """One ``A<id>.csv`` file.

    Attributes
    ----------
    anchor_id
        The file stem, e.g. ``"A12"``.
    pos_m
        Anchor position, shape ``(3,)``, metres (the same on every row).
    stamp_ns
        ``field.stamp`` per measurement, shape ``(N,)``, int64 ns, increasing.
    range_m, rssi_dbm, rssi_fp_dbm
        Per measurement, shape ``(N,)``; NaN where the cleaning removed a value.
    receive_lag_ns
        ``%time − field.stamp`` per measurement, shape ``(N,)`` (recorder latency).
    line
        1-based file line of each measurement, shape ``(N,)``.
    cleaning
        Steps taken, each counted.
    """

    anchor_id: str
    pos_m: np.ndarray
    stamp_ns: np.ndarray
    range_m: np.ndarray
    rssi_dbm: np.ndarray
    rssi_fp_dbm: np.ndarray
    receive_lag_ns: np.ndarray
    line: np.ndarray
    cleaning: tuple[CleaningStep, ...] = ()


def read_anchor_file(path: PathLike, *, max_range_m: float = MAX_RANGE_M) -> AnchorFile:
    """Read one anchor's file ``A<id>.csv`` (format and quirks in the module docstring).

    Raises
    ------
    DataFormatError
        Bad file name or header, wrong field count, a value that is not a number,
        a ``field.id`` other than the file's, an anchor position that changes, a
        negative range, or two different rows with one ``field.stamp``.
    """
    path = Path(path)
    m = _ANCHOR_FILE.fullmatch(path.name)
    if m is None:
        raise DataFormatError(path, "anchor file name must read 'A<number>.csv', e.g. 'A12.csv'")
    cols, line_no, steps = _read_table(path, ANCHOR_COLUMNS, "anchor range")
    stamp = _stamps_ns(path, cols["field.stamp"], line_no, "field.stamp")
    recv = _stamps_ns(path, cols["%time"], line_no, "%time")
    dev = _numbers(path, cols["field.id"], line_no, "field.id")
    wrong = dev != int(m["id"])
    if wrong.any():
        i = int(np.flatnonzero(wrong)[0])
        raise DataFormatError(path, f"field.id {cols['field.id'][i].strip()!r}: this file is anchor {m['id']}",
                              line=int(line_no[i]), column="field.id")
    pos = np.column_stack([_numbers(path, cols[c], line_no, c) for c in ("field.x", "field.y", "field.z")])
    moved = np.any(pos != pos[0], axis=1)
    if moved.any():
        i = int(np.flatnonzero(moved)[0])
        raise DataFormatError(path, f"anchor position {pos[i].tolist()} differs from the first row's "
                                    f"{pos[0].tolist()} (line {line_no[0]}): an anchor must not move",
                              line=int(line_no[i]))
    rng_m = _numbers(path, cols["field.distanceFromTag"], line_no, "field.distanceFromTag")
    rssi = [_numbers(path, cols[c], line_no, c, allow=(-np.inf,)) for c in ("field.rssi", "field.rssi_fp")]
    for c, v in zip(("field.rssi", "field.rssi_fp"), rssi):
        ninf = np.isneginf(v)
        if ninf.any():
            v[ninf] = np.nan
            steps.append(CleaningStep(f"{c} -inf -> NaN", int(ninf.sum()),
                                      f"{path.name}: zero received-power estimate"))
    values = np.column_stack([recv.astype(float), rng_m, *rssi])
    idx, more = order_rows(path, stamp, line_no, what="range", values=values)
    steps += more
    rng_m, line_no = rng_m[idx], line_no[idx]
    rng_m, rsteps = check_ranges(path, rng_m, line_no, max_range_m=max_range_m, columns=["field.distanceFromTag"])
    steps += rsteps
    return AnchorFile(path.stem, pos[0].copy(), stamp[idx], rng_m, rssi[0][idx], rssi[1][idx],
                      recv[idx] - stamp[idx], line_no, tuple(steps))


def read_trajectory(path: PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[CleaningStep]]:
    """The reference track: ``(stamp_ns (K,) int64, pos_m (K, 3), heading_deg (K,), cleaning)``, sorted."""
    cols, line_no, steps = _read_table(path, TRAJECTORY_COLUMNS, "reference trajectory")
    stamp = _stamps_ns(path, cols["timestamp"], line_no, "timestamp")
    pos = np.column_stack([_numbers(path, cols[c], line_no, c) for c in ("x", "y", "z")])
    head = _numbers(path, cols["heading_degrees"], line_no, "heading_degrees")
    idx, more = order_rows(path, stamp, line_no, what="reference", values=np.column_stack([pos, head]))
    return stamp[idx], pos[idx], head[idx], steps + more


def read_estimates(path: PathLike) -> tuple[np.ndarray, np.ndarray, list[CleaningStep]]:
    """An authors' estimate file: ``(stamp_ns (K,) int64, pos_m (K, 3), cleaning)``, sorted, repeats dropped."""
    cols, line_no, steps = _read_table(path, ESTIMATE_COLUMNS, "estimate")
    stamp = _stamps_ns(path, cols["timestamp"], line_no, "timestamp")
    pos = np.column_stack([_numbers(path, cols[c], line_no, c) for c in ("x", "y", "z")])
    idx, more = order_rows(path, stamp, line_no, what="estimate", values=pos)
    return stamp[idx], pos[idx], steps + more


# --------------------------------------------------------------------------------------------
# Epochs
# --------------------------------------------------------------------------------------------

def group_epochs(stamp_ns: list[np.ndarray], t0_ns: int, gap_s: float | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Merge per-anchor measurement stamps into epochs (rule in the module docstring).

    Parameters
    ----------
    stamp_ns
        One int64 array of stamps per anchor (each increasing).
    t0_ns
        Time origin, ns.
    gap_s
        Largest step between consecutive measurements of one epoch, s (default: a
        quarter of the median interval between one anchor's measurements).

    Returns
    -------
    t_s : numpy.ndarray
        Epoch times (mean of their stamps) since ``t0_ns``, shape ``(T,)``, s.
    epoch : numpy.ndarray
        Per anchor concatenated in input order, the epoch of each measurement, ``(N,)``.
    anchor : numpy.ndarray
        The anchor index of each measurement, ``(N,)`` (same order).
    info : dict
        ``gap_s``, ``max_spread_s`` (largest stamp spread within an epoch), ``n_split``
        (epochs cut because an anchor repeated), ``ranges_per_epoch`` (histogram).
    """
    anchor = np.concatenate([np.full(s.size, k) for k, s in enumerate(stamp_ns)])
    stamps = np.concatenate(stamp_ns)
    if stamps.size == 0:
        raise ValueError("no measurements to group")
    if gap_s is None:
        steps = np.concatenate([np.diff(s) for s in stamp_ns if s.size > 1]) / 1e9
        gap_s = 0.25 * float(np.median(steps)) if steps.size else 0.025
    order = np.argsort(stamps, kind="stable")
    t = (stamps[order] - t0_ns) / 1e9
    a = anchor[order]
    start = np.r_[True, np.diff(t) > gap_s]
    # an anchor already in the current epoch starts a new one (rare: only when the gap rule does not cut)
    n_split = 0
    group = np.cumsum(start) - 1
    seen = pd.DataFrame({"g": group, "a": a}).duplicated()
    while seen.any():
        i = int(np.flatnonzero(seen.to_numpy())[0])
        start[i] = True
        n_split += 1
        group = np.cumsum(start) - 1
        seen = pd.DataFrame({"g": group, "a": a}).duplicated()
    n_epochs = int(group[-1]) + 1
    count = np.bincount(group, minlength=n_epochs)
    t_e = np.bincount(group, weights=t, minlength=n_epochs) / count
    lo = np.full(n_epochs, np.inf)
    hi = np.full(n_epochs, -np.inf)
    np.minimum.at(lo, group, t)
    np.maximum.at(hi, group, t)
    epoch = np.empty_like(group)
    epoch[order] = group
    info = {"gap_s": float(gap_s), "max_spread_s": float(np.max(hi - lo)), "n_split": n_split,
            "ranges_per_epoch": {int(k): int(v) for k, v in zip(*np.unique(count, return_counts=True))}}
    return t_e, epoch, anchor, info


# --------------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------------

def _is_case(folder: Path) -> bool:
    return folder.is_dir() and any(_ANCHOR_FILE.fullmatch(p.name) for p in folder.iterdir())


def dynamic_cases(data_dir: PathLike | None = None) -> list[str]:
    """Names of the dynamic cases present, e.g. ``["LOS/Trajectory_A/Case_1", ...]`` (natural order).

    A case is any folder below ``Dynamic_measurements`` holding an ``A<number>.csv``.
    An absent dynamic part gives an empty list; an absent dataset raises
    :class:`~uwbwb.errors.DataNotFoundError`.
    """
    dyn = find_dataset(NAME, data_dir) / DYNAMIC_DIR
    if not dyn.is_dir():
        return []
    names = [p.relative_to(dyn).as_posix() for p in dyn.rglob("*") if _is_case(p)]
    return sorted(names, key=_natural_key)


def case_dir(case: PathLike, data_dir: PathLike | None = None) -> tuple[Path, str]:
    """The folder of ``case`` (a name from :func:`dynamic_cases` or a folder path) and its name."""
    path = Path(case).expanduser()
    if path.is_dir() and _is_case(path):
        parts = path.resolve().parts
        name = "/".join(parts[-3:]) if len(parts) >= 3 and parts[-3] in ("LOS", "NLOS") else path.name
        return path, name
    folder = find_dataset(NAME, data_dir) / DYNAMIC_DIR / str(case)
    if not _is_case(folder):
        raise DataNotFoundError(f"{folder}: no dynamic case there (no A<number>.csv); cases available: "
                                f"{dynamic_cases(data_dir)}")
    return folder, Path(str(case)).as_posix().strip("/")


def _case_fields(name: str) -> dict:
    """Condition, trajectory shape and case number from a name like ``NLOS/Trajectory_A/Case_1``."""
    m = re.fullmatch(r"(?P<c>LOS|NLOS)/Trajectory_(?P<t>[^/]+)/Case_(?P<n>\d+)", name)
    if m is None:
        return {"condition": None, "trajectory": None, "case": None}
    return {"condition": m["c"], "trajectory": m["t"], "case": int(m["n"])}


def _best_lag(est: Estimates, truth: Trajectory, max_lag_s: float = 1.0, step_s: float = 0.01) -> float:
    """Lag ``d`` minimising the trimmed mean squared horizontal distance of ``est(t)`` to ``truth(t + d)``, s
    (the smallest :data:`TRIM` share of the squared distances: robust to the estimates' outliers); NaN when the
    estimates do not overlap the reference (before: the search's first lag, −1.0 s, was reported)."""
    lags = np.arange(-max_lag_s, max_lag_s + 0.5 * step_s, step_s)
    t = est.t_s[None, :] + lags[:, None]
    inside = (t >= truth.t_s[0]) & (t <= truth.t_s[-1])
    x = np.interp(t, truth.t_s, truth.pos_m[:, 0])
    y = np.interp(t, truth.t_s, truth.pos_m[:, 1])
    sq = np.where(inside, (x - est.pos_m[None, :, 0]) ** 2 + (y - est.pos_m[None, :, 1]) ** 2, np.inf)
    n = inside.sum(axis=1)
    keep = max(1, int(TRIM * est.t_s.size))
    ms = np.mean(np.partition(sq, keep - 1, axis=1)[:, :keep], axis=1)     # the smallest TRIM share
    ms[n < 0.8 * est.t_s.size] = np.inf
    if not np.isfinite(ms).any():
        return np.nan                 # no lag within ±max_lag_s puts 80 % of the estimates inside the reference
    return float(lags[int(np.argmin(ms))])


def load_dynamic_case(case: PathLike, data_dir: PathLike | None = None, *, tag_height_m: float | None = None,
                      register: bool = True, epoch_gap_s: float | None = None,
                      max_range_m: float = MAX_RANGE_M) -> Recording:
    """One dynamic case as a :class:`~uwbwb.Recording` on the ranges' clock.

    Parameters
    ----------
    case
        A case name (:func:`dynamic_cases`, e.g. ``"NLOS/Trajectory_A/Case_1"``) or a
        folder of this layout.
    data_dir
        Folder holding ``hanyang-outdoor-uwb/`` (default: the discovery order).
    tag_height_m
        Height of the tag above the reference track, metres — a calibration (e.g. the
        ``meta["tag_height_fit_m"]`` of another case). None: this case's own fit.
    register
        Estimate and apply the clock offset of the reference (module docstring). With
        False the reference keeps its own stamps, and its z is lifted by
        ``tag_height_m`` (0 if None).
    epoch_gap_s
        Passed to :func:`group_epochs`.
    max_range_m
        Ranges above this become NaN (counted).

    Returns
    -------
    Recording
        Dataset ``hanyang-outdoor-uwb``, name = the case name; one tag ``"tag"``;
        anchors ``A3, A5, ...`` (file stems, natural order); ``truth["tag"]`` = the
        reference on the ranges' clock with z + tag height; ``t_s`` = seconds since
        the first range stamp. ``meta``: ``t0_unix_ns``, ``source``, ``condition``,
        ``trajectory``, ``case``, ``epochs`` (grouping info), ``rssi_dbm`` and
        ``rssi_fp_dbm`` (``(T, n_anchors)`` like the ranges), ``receive_lag_s``
        (median ``%time − field.stamp``), ``heading_deg`` (of the reference), ``board_dim`` (2: a
        ground robot; :func:`uwbwb.scoreboard.protocol.fit_calibration` reads it), and when
        registered ``registration`` (:class:`~uwbwb.datasets.registration.Registration`),
        ``reference_time_offset_s`` (``Δt``, ``t_ranges = t_ref + Δt``),
        ``tag_height_fit_m`` (this case's ``T_z``), ``tag_height_m`` and
        ``tag_height_source``; ``authors_estimates`` (``{"LS": Estimates, "ESKF": ...}``,
        on their own stamps) and ``authors_lag_s``.

    Raises
    ------
    DataNotFoundError
        No such case, or no ``trajectory.csv``.
    DataFormatError
        A file breaks the format, or the reference cannot be registered.
    """
    if tag_height_m is not None and not (isinstance(tag_height_m, (int, float, np.integer, np.floating))
                                         and not isinstance(tag_height_m, bool) and np.isfinite(tag_height_m)):
        raise ValueError(f"tag_height_m must be a finite height in metres or None, got {tag_height_m!r}")
    if epoch_gap_s is not None and not (isinstance(epoch_gap_s, (int, float, np.integer, np.floating))
                                        and not isinstance(epoch_gap_s, bool) and np.isfinite(epoch_gap_s)
                                        and epoch_gap_s > 0):
        raise ValueError(f"epoch_gap_s must be a positive number of seconds or None, got {epoch_gap_s!r}")
    folder, name = case_dir(case, data_dir)
    files = sorted((p for p in folder.iterdir() if _ANCHOR_FILE.fullmatch(p.name)), key=lambda p: _natural_key(p.name))
    by_id: dict[int, Path] = {}
    for p in files:                   # A03.csv and A3.csv would be one anchor read twice
        k = int(_ANCHOR_FILE.fullmatch(p.name)["id"])
        if k in by_id:
            raise DataFormatError(p, f"anchor {k} has two files here ({by_id[k].name} and {p.name}): keep one")
        by_id[k] = p
    anchors_read = [read_anchor_file(p, max_range_m=max_range_m) for p in files]
    cleaning = [s for f in anchors_read for s in f.cleaning]
    anchors = Anchors(tuple(f.anchor_id for f in anchors_read), np.array([f.pos_m for f in anchors_read]))
    nonempty = [f.stamp_ns for f in anchors_read if f.stamp_ns.size]
    t0 = int(min(int(s[0]) for s in nonempty))
    t_e, epoch, which, info = group_epochs([f.stamp_ns for f in anchors_read], t0, epoch_gap_s)
    shape = (t_e.size, len(anchors))
    r, rssi, rssi_fp = np.full(shape, np.nan), np.full(shape, np.nan), np.full(shape, np.nan)
    for dst, attr in ((r, "range_m"), (rssi, "rssi_dbm"), (rssi_fp, "rssi_fp_dbm")):
        dst[epoch, which] = np.concatenate([getattr(f, attr) for f in anchors_read])
    ranges = RangeLog(t_e, r, anchors.ids, "tag", pd.Timestamp(t0, unit="ns", tz="UTC"))

    traj_path = folder / TRAJECTORY_FILE
    if not traj_path.is_file():
        raise DataNotFoundError(f"{traj_path} not found: the reference track of {name}")
    ref_ns, ref_pos, heading, steps = read_trajectory(traj_path)
    cleaning += steps
    ref = Trajectory((ref_ns - t0) / 1e9, ref_pos, name="reference")
    meta: dict = {"t0_unix_ns": t0, "source": {"folder": str(folder), "anchors": [str(p) for p in files],
                                               "trajectory": str(traj_path)},
                  **_case_fields(name), "epochs": info, "rssi_dbm": rssi, "rssi_fp_dbm": rssi_fp,
                  "receive_lag_s": float(np.median(np.concatenate([f.receive_lag_ns for f in anchors_read]))) / 1e9,
                  "heading_deg": heading, "registered": bool(register),
                  # a ground robot: every board solves in 2-D at the tag height (the GNSS reference's z wanders by
                  # more than the planar threshold of uwbwb.scoreboard.protocol, which would make the board 3-D)
                  "board_dim": 2}
    if register:
        try:
            reg = register_truth(ranges, anchors, ref, fit_range_bias=True, max_offset_s=MAX_OFFSET_S)
        except RegistrationError as exc:
            raise DataFormatError(traj_path, f"cannot register the reference to the ranges: {exc}") from None
        _check_registration(reg, traj_path)
        ref = ref.shifted(reg.time_offset_s)
        meta.update(registration=reg, reference_time_offset_s=reg.time_offset_s,
                    reference_translation_fit_m=reg.translation_m.copy(), tag_height_fit_m=float(reg.translation_m[2]))
        height = float(reg.translation_m[2]) if tag_height_m is None else float(tag_height_m)
        source = "fitted on this case's ranges" if tag_height_m is None else "given (calibration)"
    else:
        height = 0.0 if tag_height_m is None else float(tag_height_m)
        source = "none (unregistered)" if tag_height_m is None else "given (calibration)"
    meta.update(tag_height_m=height, tag_height_source=source)
    truth = Trajectory(ref.t_s, ref.pos_m + np.array([0.0, 0.0, height]), name="truth")

    authors, lags = {}, {}
    for method, fname in AUTHORS_FILES.items():
        p = folder / fname
        if not p.is_file():
            continue
        stamp, pos, steps = read_estimates(p)
        cleaning += steps
        authors[method] = Estimates((stamp - t0) / 1e9, pos, np.full(stamp.size, int(EstimateStatus.UPDATED), np.int8),
                                    method)
        if register:
            lags[method] = _best_lag(authors[method], ref)
    meta.update(authors_estimates=authors, authors_lag_s=lags)
    meta["source"].update({m: str(folder / f) for m, f in AUTHORS_FILES.items() if m in authors})
    return Recording(NAME, name, anchors, {"tag": ranges}, {"tag": truth}, None, tuple(cleaning), meta)


def _check_registration(reg: Registration, path: Path) -> None:
    """Refuse a registration of the reference ``path`` that does not fit the ranges well enough to be applied."""
    problems = []
    if not reg.robust_sigma_m <= MAX_REGISTRATION_SIGMA_M:
        problems.append(f"robust range residual σ {reg.robust_sigma_m:.3g} m (at most {MAX_REGISTRATION_SIGMA_M:g} m)")
    shift = float(np.hypot(*reg.translation_m[:2]))
    if not shift <= MAX_REFERENCE_SHIFT_M:
        problems.append(f"horizontal translation {shift:.3g} m to the anchors' frame (at most {MAX_REFERENCE_SHIFT_M:g} m: "
                        "the reference should already be in it)")
    lo, hi = TAG_HEIGHT_RANGE_M
    if not lo <= reg.translation_m[2] <= hi:
        problems.append(f"tag height above the reference {reg.translation_m[2]:.3g} m (expected {lo:g}–{hi:g} m)")
    if not abs(reg.time_offset_s) <= MAX_OFFSET_S:
        problems.append(f"clock offset {reg.time_offset_s:+.3f} s (searched within ±{MAX_OFFSET_S:g} s)")
    halves = reg.half_offsets_s
    if not abs(halves[0] - halves[1]) <= MAX_HALF_OFFSET_SPREAD_S:
        problems.append(f"clock offsets of the two halves {halves[0]:+.3f} s and {halves[1]:+.3f} s (at most "
                        f"{MAX_HALF_OFFSET_SPREAD_S:g} s apart)")
    if problems:
        raise DataFormatError(path, "the reference does not fit the ranges — " + "; ".join(problems) + " — check its "
                              "units (metres), axes and time stamps")
