"""Chirp logs of an ultrasonic beacon receiver as tidy CSV (paper 003, notebook 04).

A chirp log is one CSV file, read into a :class:`uwbwb.types.ChirpLog` by
:func:`read_chirps_csv` and written by :func:`write_chirps_csv`; the beacon
positions go in an anchors file of :mod:`uwbwb.datasets.tidy` (header
``anchor_id,x_m,y_m,z_m``). General rules as in :mod:`.tidy` (UTF-8, commas, no
quoting, ``#`` comment lines, SI units, ``nan``/``inf`` are not numbers).

Header ``t_s,beacon_id,dp_s,flags``::

    t_s,beacon_id,dp_s,flags
    0.0311,b3,,lock
    0.1874,,,unassigned
    0.5412,b3,0.00091,
    1.6060,b3,-0.00042,gap

* ``t_s`` — arrival time of the detected chirp, seconds, strictly increasing.
* ``beacon_id`` — the beacon the receiver assigned the chirp to (one of the layout's
  ids), or empty if it was not assigned.
* ``dp_s`` — measured period shift ΔP in seconds, or empty if the row has none
  (a lock row, an unassigned detection). A ΔP needs a beacon.
* ``flags`` — empty, or names of :class:`~uwbwb.types.ChirpFlag` joined by ``+``
  (``lock``, ``gap``, ``ambiguous``, ``unassigned``).

**Plausibility.** A ΔP must satisfy ``|dp_s| <=`` :data:`MAX_ABS_DP_S` (0.1 s). With
``ΔP/(P + ΔP) = u·V / v_s`` (eq 1), a shift of 0.1 s on a 0.5 s period needs a radial
speed of about 57 m/s (a sixth of the speed of sound), far beyond any receiver carried
or driven indoors; a larger value is a corrupt row or a unit error (milliseconds
written as seconds), not a measurement. Such a row is an error naming file, line and
column (not dropped: a unit error would otherwise empty the whole log silently).

**Consistency.** Each row's flags must agree with its fields, else the row is an error
naming file, line and column (the counts of :meth:`~uwbwb.types.ChirpLog.counts` rely
on it):

* ``unassigned`` — no ``beacon_id`` and no ``dp_s`` (it fits no beacon); not combined
  with another flag;
* ``lock`` — a ``beacon_id`` and no ``dp_s`` (the first chirp of a train has nothing to
  measure from);
* ``gap`` — a ``beacon_id`` and a ``dp_s`` (the mean shift over the missed periods);
* ``ambiguous`` — a ``beacon_id`` (it was assigned to the closest fit);
* a ``dp_s`` needs a ``beacon_id``.

A log holding only arrival times (``beacon_id``, ``dp_s`` and ``flags`` empty) is
valid: :func:`uwbwb.filters.doppler.assign_chirps` assigns its chirps to beacons
by periodicity.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataFormatError
from ..types import ChirpFlag, ChirpLog
from .text import PathLike, _csv_table, _numbers
from .tidy import _check_identifiers, _write

__all__ = ["CHIRPS_HEADER", "MAX_ABS_DP_S", "read_chirps_csv", "write_chirps_csv"]

CHIRPS_HEADER = ("t_s", "beacon_id", "dp_s", "flags")
#: Largest plausible |ΔP| in seconds (see the module docstring): beyond it a row is an error.
MAX_ABS_DP_S = 0.1


def _contradiction(flags: int, has_beacon: bool, has_dp: bool) -> str | None:
    """Why a row's flags contradict its beacon and ΔP fields (None when they agree)."""
    if flags & ChirpFlag.UNASSIGNED:
        if flags & ~int(ChirpFlag.UNASSIGNED):
            return "flag 'unassigned' cannot be combined with another flag"
        if has_beacon:
            return "flag 'unassigned' on a row with a beacon_id"
        return None
    if flags & ChirpFlag.LOCK:
        if not has_beacon:
            return "flag 'lock' needs a beacon_id"
        if has_dp:
            return "flag 'lock' on a row with a dp_s (the first chirp of a train has no ΔP)"
    if flags & ChirpFlag.GAP and not (has_beacon and has_dp):
        return "flag 'gap' needs a beacon_id and a dp_s (the mean shift over the missed periods)"
    if flags & ChirpFlag.AMBIGUOUS and not has_beacon:
        return "flag 'ambiguous' needs a beacon_id (the beacon it was assigned to)"
    return None


def read_chirps_csv(path: PathLike, beacon_ids) -> ChirpLog:
    """Read a chirp log; ``beacon_ids`` are the layout's beacon identifiers (in order).

    Raises
    ------
    DataFormatError
        Naming the file, line and column of the first problem: a malformed field, a
        ΔP beyond :data:`MAX_ABS_DP_S`, or flags that contradict the row (module docstring).
    DataNotFoundError
        If the file does not exist.
    """
    if isinstance(beacon_ids, (str, bytes)) or not hasattr(beacon_ids, "__iter__"):
        raise TypeError(f"beacon_ids must be the layout's beacon identifiers in order (a sequence), "
                        f"got {beacon_ids!r}")
    ids = tuple(str(i) for i in beacon_ids)
    if not ids:
        raise ValueError("beacon_ids: the layout has no beacon identifiers")
    _, cols, line_no = _csv_table(path, [CHIRPS_HEADER], "chirp log")
    t = _numbers(path, cols["t_s"], line_no, "t_s")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise DataFormatError(path, f"t_s must be strictly increasing ({t[i]!r} after {t[i - 1]!r})",
                              line=int(line_no[i]), column="t_s")
    dp = _numbers(path, cols["dp_s"], line_no, "dp_s", allow_empty=True)
    implausible = np.flatnonzero(np.abs(dp) > MAX_ABS_DP_S)
    if implausible.size:
        k = int(implausible[0])
        raise DataFormatError(path, f"dp_s {dp[k]!r} s is not a plausible period shift: |ΔP| must be at most "
                                    f"{MAX_ABS_DP_S} s (a corrupt row, or milliseconds written as seconds?); "
                                    f"{implausible.size} row(s) of the file exceed it",
                              line=int(line_no[k]), column="dp_s")
    lookup = {b: k for k, b in enumerate(ids)}
    beacon = np.empty(t.size, int)
    for k, text in enumerate(cols["beacon_id"]):
        b = text.strip()
        if not b:
            beacon[k] = -1
        elif b in lookup:
            beacon[k] = lookup[b]
        else:
            raise DataFormatError(path, f"beacon_id {b!r} is not a beacon of the layout {list(ids)}",
                                  line=int(line_no[k]), column="beacon_id")
        if beacon[k] < 0 and np.isfinite(dp[k]):
            raise DataFormatError(path, "a dp_s needs a beacon_id", line=int(line_no[k]), column="dp_s")
    flags = np.zeros(t.size, np.int8)
    names = {f.name.lower(): int(f) for f in ChirpFlag}
    for k, text in enumerate(cols["flags"]):
        for part in filter(None, (p.strip() for p in text.split("+"))):
            if part not in names:
                raise DataFormatError(path, f"unknown flag {part!r}; expected names from {sorted(names)} "
                                            "joined by '+'", line=int(line_no[k]), column="flags")
            flags[k] |= names[part]
        problem = _contradiction(int(flags[k]), beacon[k] >= 0, bool(np.isfinite(dp[k])))
        if problem is not None:
            raise DataFormatError(path, problem, line=int(line_no[k]), column="flags")
    return ChirpLog(t, beacon, dp, flags, ids)


def write_chirps_csv(path: PathLike, log: ChirpLog) -> Path:
    """Write ``log`` so that :func:`read_chirps_csv` gives exactly the same numbers back."""
    _check_identifiers(log.beacon_ids, "beacon_id")
    df = log.to_frame()
    for c in ("t_s", "dp_s"):
        df[c] = [repr(float(v)) if np.isfinite(v) else "" for v in df[c]]
    return _write(path, df)
