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
   a cross-check. With ``imu_clock="ranges"`` the offset comes from the tag's own
   UWB fixes instead (:func:`~uwbwb.datasets.registration.align_imu_to_ranges`:
   specific-force magnitudes, no motion capture): on the two public scenarios it
   lies 2 and 36 ms from the truth-based one.

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

The file readers (:func:`read_uwb`, :func:`read_imu`, :func:`read_gt`) live in
:mod:`uwbwb.datasets.iasl_files` and are importable from here.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from ..errors import DataFormatError, DataNotFoundError
from ..types import Anchors, ImuLog, Recording, _natural_key
from .cleaning import MAX_RANGE_M
from .discovery import find_dataset
from .text import _decode_lines, _read_bytes
from .registration import ImuAlignment, Registration, RegistrationError, align_imu, align_imu_to_ranges, register_truth
from .iasl_files import read_gt, read_imu, read_uwb, spread_whole_seconds

NAME = "iasl-uwb-imu"
UWB_FILE, IMU_FILE, GT_FILE = "uwb.csv", "imu.csv", "gt.csv"
ANCHORS_FILE = "uwb.yaml"

PathLike = str | os.PathLike



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
# Scenario loader
# --------------------------------------------------------------------------------------------

def load_scenario(scenario: str = "scenario1", data_dir: PathLike | None = None, *, register: bool = True,
                  fit_yaw: bool = False, fit_range_bias: bool = True,
                  max_offset_s: float | None = None, max_range_m: float = MAX_RANGE_M,
                  imu_gaps: str = "error", imu_clock: str = "truth") -> Recording:
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
    imu_clock
        How the IMU clock offset is estimated: ``"truth"`` (default, with ``register``): gyro
        magnitude against the registered motion capture's rotation rate (:func:`align_imu`);
        ``"ranges"``: specific-force magnitude against the tag's own UWB fixes
        (:func:`align_imu_to_ranges`) — no motion capture used, so the IMU a filter receives
        owes nothing to the truth it is scored on; works with ``register=False`` too.

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
    if imu_clock not in ("truth", "ranges"):
        raise ValueError(f"imu_clock must be 'truth' or 'ranges', got {imu_clock!r}")
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
    if imu is not None and (register or imu_clock == "ranges"):
        try:
            al = (align_imu(imu.imu, truth["tag"]) if imu_clock == "truth"
                  else align_imu_to_ranges(imu.imu, uwb.ranges, anchors))
        except RegistrationError as exc:
            raise DataFormatError(imu_path, f"cannot align the IMU clock: {exc}") from None
        t_imu = imu.imu.t_s + al.offset_s
        if np.any(np.diff(t_imu) <= 0):
            raise DataFormatError(imu_path, "IMU time stamps too large to shift to the UWB clock")
        imu_log = ImuLog(t_imu, imu.imu.acc_mps2, imu.imu.gyro_radps)
        meta.update(imu_alignment=al, imu_time_offset_s=al.offset_s, imu_clock=imu_clock)
    return Recording(NAME, scenario, anchors, {"tag": uwb.ranges}, truth, imu_log, tuple(cleaning), meta)
