"""Measurement packets of a ranging blind node (Zupanec et al., Table 1).

A blind node pings its anchors round-robin and forms a *measurement packet*
every ~130 ms: a time stamp and one ``ranging``/``status`` pair per anchor.
Stored one row per (packet, anchor), tab-separated, with a header::

    timestamp       anchor ID       ranging status
    1452967702506   1       21.49   OK
    1452967702506   2       12.64   OK
    1452967702506   3       0.00    ERR
    ...

* ``timestamp`` -- integer milliseconds on the node's clock (the time the
  packet was formed); all rows of a packet share it.
* ``anchor ID`` -- the anchor's label (any token without white space).
* ``ranging`` -- the reported distance, metres.
* ``status`` -- ``OK`` or ``ERR``. An ``ERR`` range is *missing* (NaN in the
  :class:`~uwbwb.RangeLog`), whatever number the ranging column holds; the
  loader counts them per anchor.

One file holds one blind node. :func:`read_packets` returns a :class:`PacketLog`
(the ranges as a ``(T, n_anchors)`` :class:`~uwbwb.RangeLog`, ``t_s`` in seconds
from the first packet, plus what was cleaned); :func:`load_recording` combines
the files of several nodes with anchor positions into a
:class:`~uwbwb.Recording`; :func:`write_packets` writes a range log back in this
format (NaN as ``0.00 ERR``).

Cleaning (counted in :attr:`PacketLog.cleaning`, never silent), by the
package's rules (:mod:`uwbwb.datasets.cleaning`): ``ERR`` statuses, anchors
absent from a packet, blank lines, exact duplicate rows, packets out of time
order (sorted), and ``OK`` ranges above ``max_range_m`` (set to NaN). A negative
``OK`` range, and everything else that does not fit the format, is a
:class:`~uwbwb.DataFormatError` naming file and line. UTF-8 with or without a
byte-order mark; ``\n`` or ``\r\n`` line ends.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFormatError
from ..types import Anchors, CleaningStep, RangeLog, Recording, Trajectory, _natural_key
from .cleaning import MAX_RANGE_M, check_ranges, order_rows
from .text import _decode_lines, _numbers, _read_bytes, _split_rows

__all__ = ["HEADER", "PacketLog", "load_recording", "read_packets", "write_packets"]

#: The header row, fields separated by tabs.
HEADER = ("timestamp", "anchor ID", "ranging", "status")
_STATUSES = ("OK", "ERR")
_MAX_MS = 2 ** 62  # keeps time stamps and their differences inside int64
_INT_RE = re.compile(r"[0-9]+")
_ID_RE = re.compile(r"\S+")


@dataclass(frozen=True)
class PacketLog:
    """The packets of one blind node as loaded from one file.

    Attributes
    ----------
    ranges
        Ranges per packet, ``range_m`` of shape ``(T, n_anchors)``, metres, NaN
        where the status was ``ERR`` or the anchor was absent from the packet;
        ``t_s`` in seconds since the first packet; ``t0`` the first packet's
        time stamp in milliseconds (int).
    t0_ms
        Time stamp of the first packet, milliseconds on the node's clock.
    n_err
        Number of ``ERR`` statuses per anchor, keyed by anchor ID.
    n_absent
        Number of packets without a row for the anchor, keyed by anchor ID.
    cleaning
        What the loader removed or changed.
    path
        The file read.
    """

    ranges: RangeLog
    t0_ms: int
    n_err: Mapping[str, int]
    n_absent: Mapping[str, int]
    cleaning: tuple[CleaningStep, ...] = ()
    path: Path | None = None

    @property
    def anchor_ids(self) -> tuple[str, ...]:
        return self.ranges.anchor_ids


def read_packets(path: str | os.PathLike, *, anchor_ids=None, tag_id: str | None = None,
                 max_range_m: float = MAX_RANGE_M) -> PacketLog:
    """Read one blind node's measurement packets.

    Parameters
    ----------
    path
        Tab-separated packet file with the header of :data:`HEADER`.
    anchor_ids
        Expected anchor IDs, in the column order wanted. An ID in the file that
        is not listed is an error; a listed ID that never appears gets a column
        of NaN (counted as absent). Default: the IDs found, in natural order
        (``"2"`` before ``"10"``).
    tag_id
        Label of the node; default the file stem.
    max_range_m
        ``OK`` ranges above this become NaN (counted).

    Returns
    -------
    PacketLog

    Raises
    ------
    uwbwb.DataFormatError
        Wrong header, a row with the wrong number of fields, a time stamp that
        is not integer milliseconds, a range that is not a number, a negative
        ``OK`` range, an unknown status or anchor, conflicting rows for the same
        packet and anchor, or a file without packets.
    uwbwb.DataNotFoundError
        No such file.
    """
    path = Path(path)
    lines = _decode_lines(path, _read_bytes(path))
    if not lines or not lines[0].strip():
        raise DataFormatError(path, f"empty file; expected the header {'<TAB>'.join(HEADER)!r}", line=1)
    head = [h.strip() for h in lines[0].split("\t")]
    if tuple(head) != HEADER:
        raise DataFormatError(path, f"header is {lines[0]!r}; expected the tab-separated fields {list(HEADER)}",
                              line=1)
    if anchor_ids is not None:
        anchor_ids = tuple(str(a) for a in anchor_ids)
        if len(set(anchor_ids)) != len(anchor_ids):
            raise ValueError(f"anchor_ids must be unique, got {anchor_ids}")
        known = set(anchor_ids)

    body = [(i, ln) for i, ln in enumerate(lines[1:], start=2) if ln.strip()]
    if not body:
        raise DataFormatError(path, "the file holds a header but no packets", line=len(lines))
    n_blank = len(lines) - 1 - len(body)
    fields, line_no = _split_rows(path, body, "\t", HEADER, what="packet", header_line=1)
    ts, ids, status = ([f[k].strip() for f in fields] for k in (0, 1, 3))
    for i, (stamp, aid, state) in enumerate(zip(ts, ids, status)):
        line = int(line_no[i])
        if not _INT_RE.fullmatch(stamp):
            raise DataFormatError(path, f"timestamp {stamp!r} is not an integer number of milliseconds",
                                  line=line, column="timestamp")
        if int(stamp) >= _MAX_MS:
            raise DataFormatError(path, f"timestamp {stamp!r} is out of range (milliseconds below {_MAX_MS})",
                                  line=line, column="timestamp")
        if not _ID_RE.fullmatch(aid):
            raise DataFormatError(path, f"anchor ID {aid!r} is empty or contains white space", line=line,
                                  column="anchor ID")
        if anchor_ids is not None and aid not in known:
            raise DataFormatError(path, f"anchor ID {aid!r} is not one of the expected {list(anchor_ids)}",
                                  line=line, column="anchor ID")
        if state not in _STATUSES:
            raise DataFormatError(path, f"status {state!r} is neither 'OK' nor 'ERR'", line=line, column="status")
    range_m = _numbers(path, [f[2] for f in fields], line_no, "ranging")
    ms = np.array([int(v) for v in ts], dtype=np.int64)
    okv = np.array(status) == "OK"
    cleaning: list[CleaningStep] = []
    if n_blank:
        cleaning.append(CleaningStep("blank lines skipped", n_blank, "empty lines between packets"))
    # time order (sorted if need be) and repeats of a (packet, anchor) row (exact ones dropped, others an error)
    range_m, steps = check_ranges(path, range_m, line_no, max_range_m=max_range_m, columns=["ranging"],
                                  ignore=~okv)
    anchor_code, anchor_names = pd.factorize(pd.Series(ids, dtype=object))
    idx, more = order_rows(path, ms, line_no, what="(timestamp, anchor ID)", key=anchor_code,
                           values=np.column_stack([range_m, okv]))
    cleaning += more + steps
    range_m = range_m[idx]
    df = pd.DataFrame({"ms": ms[idx], "anchor": np.asarray(anchor_names, dtype=object)[anchor_code[idx]],
                       "range_m": range_m, "ok": okv[idx]})

    if anchor_ids is None:
        anchor_ids = tuple(sorted(df["anchor"].unique(), key=_natural_key))
    ms_u, inv = np.unique(df["ms"].to_numpy(), return_inverse=True)
    col = pd.Index(anchor_ids).get_indexer(df["anchor"])
    r = np.full((ms_u.size, len(anchor_ids)), np.nan)
    present = np.zeros(r.shape, bool)
    okv = df["ok"].to_numpy()
    present[inv, col] = True
    r[inv[okv], col[okv]] = df["range_m"].to_numpy()[okv]

    n_err = {a: int(np.sum(~okv & (col == j))) for j, a in enumerate(anchor_ids)}
    n_absent = {a: int(np.sum(~present[:, j])) for j, a in enumerate(anchor_ids)}
    if sum(n_err.values()):
        per = ", ".join(f"{a}: {n}" for a, n in n_err.items() if n)
        cleaning.append(CleaningStep("ERR status -> missing", sum(n_err.values()), f"per anchor {per}"))
    if sum(n_absent.values()):
        per = ", ".join(f"{a}: {n}" for a, n in n_absent.items() if n)
        cleaning.append(CleaningStep("anchor absent from packet -> missing", sum(n_absent.values()),
                                     f"per anchor {per}"))
    t0_ms = int(ms_u[0])
    log = RangeLog((ms_u - t0_ms) / 1000.0, r, anchor_ids, tag_id if tag_id is not None else path.stem, t0_ms)
    return PacketLog(log, t0_ms, n_err, n_absent, tuple(cleaning), path)


def write_packets(path: str | os.PathLike, log: RangeLog, *, t0_ms: int | None = None,
                  decimals: int = 2) -> Path:
    """Write a range log as measurement packets (the inverse of :func:`read_packets`).

    Parameters
    ----------
    path
        File to write (tab-separated, header :data:`HEADER`).
    log
        Ranges, one packet per epoch; NaN is written as ``0.00`` with status ``ERR``.
    t0_ms
        Time stamp of ``t_s = 0``, milliseconds; default ``log.t0`` when it is an
        integer (as :func:`read_packets` sets it), else 0.
    decimals
        Decimal places of the ranging column (2, i.e. centimetres, as in Table 1).

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    ValueError
        When two epochs fall into the same millisecond (the format could not
        tell them apart).
    """
    path = Path(path)
    if t0_ms is None:
        t0_ms = int(log.t0) if isinstance(log.t0, (int, np.integer)) else 0
    if isinstance(decimals, bool) or not isinstance(decimals, (int, np.integer)) or decimals < 0:
        raise ValueError(f"decimals must be a non-negative integer, got {decimals!r}")
    ms = np.round(int(t0_ms) + log.t_s * 1000.0).astype(np.int64)
    if ms.size > 1 and np.any(np.diff(ms) <= 0):
        i = int(np.flatnonzero(np.diff(ms) <= 0)[0])
        raise ValueError(f"epochs {i} and {i + 1} (t_s={log.t_s[i]!r}, {log.t_s[i + 1]!r}) fall into the same "
                         f"millisecond; the packet format cannot separate them")
    if np.any(ms < 0):
        raise ValueError("time stamps before 0 ms cannot be written; pass a larger t0_ms")
    T, n = log.range_m.shape
    ok = np.isfinite(log.range_m)
    rng_txt = np.char.mod(f"%.{int(decimals)}f", np.where(ok, log.range_m, 0.0))
    table = pd.DataFrame({
        "timestamp": np.repeat(ms, n),
        "anchor ID": np.tile(np.asarray(log.anchor_ids, dtype=object), T),
        "ranging": rng_txt.ravel(),
        "status": np.where(ok.ravel(), "OK", "ERR"),
    })
    table.to_csv(path, sep="\t", index=False, lineterminator="\n")
    return path


def load_recording(files: Mapping[str, str | os.PathLike], anchors: Anchors, *,
                   truth: Mapping[str, Trajectory] | None = None, dataset: str = "packets",
                   name: str = "") -> Recording:
    """Combine packet files of several blind nodes into a :class:`~uwbwb.Recording`.

    Parameters
    ----------
    files
        Packet file per node, keyed by the node's tag id (e.g. ``{"L": ..., "H": ...}``).
    anchors
        Anchor positions; their IDs must be the packet files' anchor IDs.
    truth
        Optional ground truth per tag, on the packet clock (``t_s`` since each
        file's first packet; use :meth:`~uwbwb.Trajectory.shifted` to align
        files that start at different times -- see ``meta["t0_ms"]``).
    dataset, name
        Labels of the recording.

    Returns
    -------
    Recording
        Cleaning steps prefixed with the tag; ``meta`` holds each file's path
        and first time stamp (``t0_ms``).
    """
    ranges, cleaning, t0, paths = {}, [], {}, {}
    for tag, f in files.items():
        pk = read_packets(f, anchor_ids=anchors.ids, tag_id=tag)
        ranges[tag] = pk.ranges
        cleaning += [CleaningStep(f"{tag}: {s.name}", s.n_affected, s.detail) for s in pk.cleaning]
        t0[tag] = pk.t0_ms
        paths[tag] = str(pk.path)
    return Recording(dataset, name, anchors, ranges, dict(truth or {}), cleaning=tuple(cleaning),
                     meta={"t0_ms": t0, "paths": paths, "source": "uwbwb.datasets.packets"})
