"""The Hanyang dataset authors' numbers: their RMSE definition reproduced and their LS range front end (their
published LS/ESKF join a board as *external* rows: :func:`uwbwb.scoreboard.sources.external_estimators`).
See :mod:`.study` for the whole study.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ... import metrics
from ...datasets import hanyang_dynamic
from ...errors import DataFormatError, DataNotFoundError
from ...scoreboard.estimators import RawLs
from ...types import Estimates, Trajectory

PathLike = str | os.PathLike

#: *Input* (the authors' script): the reference z is compared with the estimate's z after adding 1 m.
AUTHORS_TAG_HEIGHT_M = 1.0
#: *Input* (the authors' script): reference rows with |z| at or above this are left out.
AUTHORS_Z_LIMIT_M = 0.5
#: *Input* (the authors' script): the window of each trajectory shape, as rules on the reference
#: track (x, y): it starts at the first row meeting ``start`` and ends at the first later row
#: meeting ``end``.
WINDOW_RULES = {"A": {"start": lambda x, y: (x > 49.3) & (y > -5), "end": lambda x, y: (x <= 12) & (y > 3.4)},
                "B": {"start": lambda x, y: (x < 8.6) & (y < -7), "end": lambda x, y: (x > 8.6) & (y < -7)}}
#: Largest difference between our recomputation and the authors' published RMSE called agreement, m.
REPRO_TOL_M = 0.01


# --------------------------------------------------------------------------------------------
# 1. the authors' numbers
# --------------------------------------------------------------------------------------------

def authors_window(reference: Trajectory, shape: str) -> tuple[float, float]:
    """``(t_start, t_end)`` of the authors' evaluation window on ``reference``'s own clock, seconds.

    Raises
    ------
    ValueError
        Unknown shape, or the track never meets the start (or, after it, the end) rule.
    """
    if shape not in WINDOW_RULES:
        raise ValueError(f"shape must be one of {sorted(WINDOW_RULES)}, got {shape!r}")
    x, y = reference.pos_m[:, 0], reference.pos_m[:, 1]
    start = np.flatnonzero(WINDOW_RULES[shape]["start"](x, y))
    if start.size == 0:
        raise ValueError(f"the reference never meets the start rule of trajectory {shape}")
    end = np.flatnonzero(WINDOW_RULES[shape]["end"](x, y) & (np.arange(x.size) > start[0]))
    if end.size == 0:
        raise ValueError(f"the reference never meets the end rule of trajectory {shape} after its start")
    return float(reference.t_s[start[0]]), float(reference.t_s[end[0]])


def authors_errors(reference: Trajectory, est: Estimates, shape: str) -> dict:
    """Errors of ``est`` by the authors' definition (both on the same clock, reference unlifted).

    Window :func:`authors_window`; reference rows in it with ``|z| <`` :data:`AUTHORS_Z_LIMIT_M`;
    the estimate epochs in it (both ends included); the reference interpolated linearly at each
    (held at its first/last row beyond them); 2-D error on x, y; 3-D error with the reference z
    raised by :data:`AUTHORS_TAG_HEIGHT_M`.

    Returns
    -------
    dict
        ``err_2d_m``, ``err_3d_m`` (shape ``(N,)``), ``t_s`` (N,), ``window_s`` (start, end),
        ``n_reference`` (rows used), ``n_z_dropped`` (rows dropped by the |z| rule).
    """
    t0, t1 = authors_window(reference, shape)
    inw = (reference.t_s >= t0) & (reference.t_s <= t1)
    keep = inw & (np.abs(reference.pos_m[:, 2]) < AUTHORS_Z_LIMIT_M)
    ref = reference.select(keep)
    sel = est.has_estimate & (est.t_s >= t0) & (est.t_s <= t1)
    t = est.t_s[sel]
    # hold the ends, as the script does: extend the reference by its end rows at the estimates' extremes
    tt, pp = ref.t_s, ref.pos_m
    if t.size and t[0] < tt[0]:
        tt, pp = np.r_[t[0], tt], np.vstack([pp[:1], pp])
    if t.size and t[-1] > tt[-1]:
        tt, pp = np.r_[tt, t[-1]], np.vstack([pp, pp[-1:]])
    lifted = Trajectory(tt, pp + np.array([0.0, 0.0, AUTHORS_TAG_HEIGHT_M]))
    track = est.select(sel).to_trajectory()
    e2 = metrics.errors_vs_truth(track, lifted, horizontal=True)
    e3 = metrics.errors_vs_truth(track, lifted, horizontal=False)
    return {"err_2d_m": e2.err_m, "err_3d_m": e3.err_m, "t_s": e2.t_s, "window_s": (t0, t1),
            "n_reference": int(keep.sum()), "n_z_dropped": int((inw & ~keep).sum())}


_RMSD = re.compile(r"(?P<method>\w+) (?P<metric>RMSE(?:_2d)?): (?P<value>[-+0-9.eE]+|nan|inf)(?: m)?")


def read_rmsd_results(path: PathLike) -> dict[str, dict[str, float]]:
    """``RMSD_results.txt`` as ``{"LS": {"rmse_m": ..., "rmse_2d_m": ...}, "ESKF": {...}}`` (*input*).

    A line reading ``Insufficient data ...`` gives no value; any other line that is not
    ``<METHOD> RMSE: <v> m`` or ``<METHOD> RMSE_2d: <v>`` is an error naming the line.
    """
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise DataNotFoundError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise DataFormatError(path, "expected the RMSD_results.txt file, found a folder") from None
    except UnicodeDecodeError as exc:
        raise DataFormatError(path, f"expected UTF-8 text, found undecodable bytes at byte {exc.start}") from None
    out: dict[str, dict[str, float]] = {}
    for i, ln in enumerate(lines, start=1):
        if not ln.strip() or ln.startswith("Insufficient data"):
            continue
        m = _RMSD.fullmatch(ln.strip())
        if m is None:
            raise DataFormatError(path, f"expected '<METHOD> RMSE: <value> m' or '<METHOD> RMSE_2d: <value>', "
                                        f"got {ln!r}", line=i)
        key = "rmse_2d_m" if m["metric"].endswith("_2d") else "rmse_m"
        try:
            value = float(m["value"])
        except ValueError:
            value = float("nan")
        if not (np.isfinite(value) and value >= 0):
            raise DataFormatError(path, f"an RMSE must be a non-negative number of metres, got {m['value']!r}", line=i)
        if key in out.get(m["method"], {}):
            raise DataFormatError(path, f"{m['method']} {m['metric']} is given twice (an earlier line holds "
                                        f"{out[m['method']][key]!r})", line=i)
        out.setdefault(m["method"], {})[key] = value
    return out


def reproduce_authors(case: PathLike, data_dir: PathLike | None = None) -> pd.DataFrame:
    """The authors' RMSE and RMSE_2d recomputed by the package's metric code, beside theirs.

    The case is loaded *unregistered* (the script compares raw stamps and the unlifted
    reference). One row per (method, metric): ``reproduced_m`` (*reproduced*), ``published_m``
    (*input*, from ``RMSD_results.txt``; NaN if absent), ``diff_m``, ``n_epochs``, ``window_s``,
    ``n_z_dropped``, and ``verdict``: ``agree`` when ``|diff_m|`` is at most :data:`REPRO_TOL_M`, else
    ``DISAGREE`` (``no published value`` without one).
    """
    rec = hanyang_dynamic.load_dynamic_case(case, data_dir, register=False)
    shape = rec.meta["trajectory"]
    if shape not in WINDOW_RULES:
        raise ValueError(f"{rec.label}: the authors' window needs trajectory shape A or B (case name "
                         f"'<LOS|NLOS>/Trajectory_<A|B>/Case_<n>'), got {shape!r}")
    path = Path(rec.meta["source"]["folder"]) / "RMSD_results.txt"
    published = read_rmsd_results(path) if path.is_file() else {}
    rows = []
    for method, est in rec.meta["authors_estimates"].items():
        e = authors_errors(rec.truth["tag"], est, shape)
        for metric, key, err in (("RMSE 3-D", "rmse_m", e["err_3d_m"]), ("RMSE 2-D", "rmse_2d_m", e["err_2d_m"])):
            mine = metrics.rmse(err) if err.size else float("nan")
            theirs = published.get(method, {}).get(key, float("nan"))
            rows.append({"data": rec.label, "method": method, "metric": metric, "reproduced_m": mine,
                         "published_m": theirs, "diff_m": mine - theirs, "n_epochs": int(err.size),
                         "window_s": float(e["window_s"][1] - e["window_s"][0]), "n_z_dropped": e["n_z_dropped"],
                         "verdict": ("agree" if abs(mine - theirs) <= REPRO_TOL_M else "DISAGREE")
                         if np.isfinite(theirs) else "no published value"})
    return pd.DataFrame(rows)


#: *Input* (the authors' LS front end, ``Technical_validation/``): a range differing from its anchor's
#: previous accepted range by more than this is rejected ...
AUTHORS_JUMP_M = 0.5
#: ... at most this many times in a row (the next one is accepted) ...
AUTHORS_MAX_REJECTS = 4
#: ... and each anchor's latest accepted range is used for up to this long, seconds.
AUTHORS_HOLD_S = 0.3


def authors_front_end(t_s: np.ndarray, range_m: np.ndarray, *, jump_m: float = AUTHORS_JUMP_M,
                      max_rejects: int = AUTHORS_MAX_REJECTS, hold_s: float = AUTHORS_HOLD_S
                      ) -> tuple[np.ndarray, dict]:
    """The authors' LS range front end applied to a range log: per anchor, a jump gate and a hold.

    Per anchor, a measured range whose difference from that anchor's previous accepted range exceeds
    ``jump_m`` is rejected, up to ``max_rejects`` in a row (the next is accepted and becomes the
    reference); at each epoch an anchor without a fresh accepted range uses its latest accepted one if
    it is at most ``hold_s`` old.

    Parameters
    ----------
    t_s
        Epoch times, ``(T,)``, seconds.
    range_m
        Ranges, ``(T, n_anchors)``, metres; NaN = not measured.

    Returns
    -------
    ranges, report
        The ranges the solver sees, ``(T, n_anchors)`` (NaN: none), and per epoch ``(T,)`` the number of
        anchors whose range was rejected (``n_rejected``) and filled by holding (``n_held``).
    """
    t = np.asarray(t_s, float)
    r = np.asarray(range_m, float)
    out = np.full_like(r, np.nan)
    n_rej, n_held = np.zeros(t.size, int), np.zeros(t.size, int)
    for k in range(r.shape[1]):
        prev, rejects, last_t = np.nan, 0, -np.inf
        for i in range(t.size):
            d = r[i, k]
            if np.isfinite(d):
                if np.isfinite(prev) and abs(d - prev) > jump_m:
                    rejects += 1
                    if rejects <= max_rejects:
                        n_rej[i] += 1
                        d = np.nan
                else:
                    rejects = 0
            if np.isfinite(d):
                prev, last_t, out[i, k] = d, t[i], d
            elif np.isfinite(prev) and t[i] - last_t <= hold_s + 1e-9:       # 1 ns: the stamps' resolution
                out[i, k] = prev
                n_held[i] += 1
    return out, {"n_rejected": n_rej, "n_held": n_held}


#: ``raw LS`` (per-epoch unweighted multilateration, no calibration, 2-D at the calibrated height) on the ranges after
#: the authors' LS front end (:func:`authors_front_end`: jump gate and hold), so that outlier handling matches theirs.
#: Their warm-started 3-D solve and 10 Hz output timer are not copied. Bound: the CRLB of the ranges (as ``raw LS``).
AUTHORS_FRONT_END_LS = RawLs("raw LS, authors' front end (jump gate + hold)",
                             lambda t_s, range_m: authors_front_end(t_s, range_m)[0])
