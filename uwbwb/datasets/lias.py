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

Modules
-------
This module discovers and loads recordings; the file readers live in
:mod:`uwbwb.datasets.lias_files` (:func:`read_uwb_csv`, :func:`read_mocap_csv`) and the README
tables in :mod:`uwbwb.datasets.lias_tables` (:func:`read_tables`); all are importable from here.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFormatError, DataNotFoundError
from ..geometry import yaw_rotation
from ..types import CleaningStep, RangeLog, Recording, Trajectory
from .registration import BODY_FLIPS, QUAT_ORDERS, body_points, fit_clock_offset_and_convention, frame_rotation
from .discovery import find_dataset
from .lias_tables import _SESSION_RE, _parse_session, read_tables
from .lias_files import read_mocap_csv, read_uwb_csv

__all__ = ["NAME", "TROLLEY_CENTROID_Z_M", "list_recordings", "load_dynamic", "load_static"]

#: Dataset name, as in the manifest and the data folders.
NAME = "lias-planar-uwb"

#: Height of the trolley centroid above the floor, metres: the median motion-capture
#: centroid height of the published dynamic run (0.971 m, peak to peak 3 cm). The
#: static tables give no height; this is a property of the rig, used as the default
#: of :func:`load_static`'s ``centroid_z_m``.
TROLLEY_CENTROID_Z_M = 0.97

_DYNAMIC_PREFIX = "UWB_dynamic_exp_"
_MOCAP_PREFIX = "motion_capture_dynamic_exp_"
_STATIC_RE = re.compile(r"UWB_static_exp_(\d+)_(\d+)_pos(\d+)_deg_(\d+)\.csv")


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
