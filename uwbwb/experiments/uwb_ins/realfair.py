"""Notebook 05's real-data protocol, read from the scoreboard that runs it: every filter's tuning on the
calibration scenario (:func:`tuning_table`: the board's grid, the board's criterion), and the IMU clock
estimated without the scored scenario's motion capture (:func:`imu_clock_sensitivity`).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pandas as pd

from ...datasets import iasl
from ...errors import DataFormatError
from ...filters.alignment import Comparison
from ...metrics import MIN_BLOCKS, block_bootstrap_difference, interval_side, rmse
from ...scoreboard import Board, score
from ...types import Recording
from .realdata import board_comparison

__all__ = ["IMU_FILTERS", "tuning_table", "imu_clock_sensitivity", "clock_verdict", "summary_rows", "difference_rows"]

#: The rows whose inputs include the IMU (the clock's sensitivity is read on them).
IMU_FILTERS = ("tight", "tight (ranges)", "loose", "INS-only")


def tuning_table(board: Board) -> pd.DataFrame:
    """One row per method that tuned a grid on the calibration scenario: its pick (the UWB/INS filters'
    ``Q ×`` and ``R ×``, the EKFs' ``σ_w``), the lowest RMSE on the calibration part, the untuned
    ``(1, 1)`` RMSE where the grid holds it, and whether the pick lies on the grid's edge."""
    rows = {}
    for name in board.methods:
        p = board.calibration.params(name)
        if "grid_rmse_m" not in p:
            continue
        cost = dict(zip(p["grid"], p["grid_rmse_m"]))
        rows[name] = {"Q ×": p.get("q_scale", np.nan), "R ×": p.get("r_scale", np.nan),
                      "σ_w": p.get("sigma_w", np.nan), "RMSE picked (m)": float(min(p["grid_rmse_m"])),
                      "RMSE at Q × 1, R × 1 (m)": float(cost.get((1.0, 1.0), np.nan)),
                      "edge": "on the edge" if p.get("grid_edge") else "—"}
    return pd.DataFrame(rows).T


def _paired(comp_a: Comparison, comp_b: Comparison, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal errors of ``name`` in both comparisons on the epochs (times) both score and cover."""
    def scored(c):
        e = c.errors(name)
        ok = c.masks["scored"] & np.isfinite(e)
        return c.truth.t_s[ok], e[ok]
    ta, ea = scored(comp_a)
    tb, eb = scored(comp_b)
    _, ia, ib = np.intersect1d(ta, tb, return_indices=True)
    return ea[ia], eb[ib]


def imu_clock_sensitivity(board: Board, rec: Recording, cal_rec: Recording, estimators: Sequence, *,
                          rng: np.random.Generator, data_dir=None, rate_hz: float | None = 10.0,
                          fast: bool = False) -> dict:
    """The board again with the IMU clock from the scenario's own ranges instead of its motion capture
    (:func:`uwbwb.datasets.iasl.load_scenario` with ``imu_clock="ranges"``, the loader's other options at their
    defaults), with the board's calibration and tuning unchanged.

    ``board`` is the board of ``estimators`` on ``rec`` (an ``iasl-uwb-imu`` scenario loaded with the IMU clock
    from its motion capture, the default), calibrated on ``cal_rec`` at ``rate_hz``. Per method, on the epochs
    both boards score and cover: horizontal RMSE both ways, the change ``ranges − motion capture`` (mm) with its
    95 % block-bootstrap interval (:func:`uwbwb.metrics.block_bootstrap_difference`) and the epoch count, and
    :func:`clock_verdict` of that interval. Returns ``{"offsets": {"truth_s", "ranges_s", "peak", "rival",
    "halves_s"}, "start_s": (as run, with the ranges clock), "table": DataFrame}``, or ``{"error": message}``
    when the ranges cannot pin the clock down (an ambiguous correlation) — reported, not hidden.
    """
    try:
        rec_r = iasl.load_scenario(rec.name, data_dir, imu_clock="ranges")
    except DataFormatError as exc:
        return {"error": str(exc)}
    # the ranges and the truth are those the board checked: only the IMU clock differs
    board_r = score(rec_r, cal_rec, estimators=estimators, rate_hz=rate_hz, calibration=board.calibration, fast=fast,
                    check=False)
    comp, comp_r = board_comparison(board), board_comparison(board_r)
    rows = {}
    for name in comp.estimates:
        ea, eb = _paired(comp, comp_r, name)
        d = block_bootstrap_difference(eb, ea, rng=rng)
        rows[name] = {"motion-capture clock (m)": rmse(ea) if ea.size else np.nan,
                      "ranges clock (m)": rmse(eb) if eb.size else np.nan,
                      "change (mm)": d["diff_m"] * 1e3, "lo (mm)": d["lo_m"] * 1e3, "hi (mm)": d["hi_m"] * 1e3,
                      "epochs": d["n"], "verdict": clock_verdict(d["lo_m"] * 1e3, d["hi_m"] * 1e3)}
    al = rec_r.meta["imu_alignment"]
    truth_s = rec.meta.get("imu_time_offset_s", np.nan)
    return {"offsets": {"truth_s": float(truth_s), "ranges_s": float(al.offset_s), "peak": float(al.peak_corr),
                        "rival": float(al.second_peak_corr), "halves_s": tuple(al.half_offsets_s or ())},
            "start_s": (float(comp.meta.get("start_s", np.nan)), float(comp_r.meta.get("start_s", np.nan))),
            "table": pd.DataFrame(rows).T.astype({c: float for c in ("motion-capture clock (m)", "ranges clock (m)",
                                                                     "change (mm)", "lo (mm)", "hi (mm)", "epochs")})}


def clock_verdict(lo_mm: float, hi_mm: float) -> str:
    """What the ranges' IMU clock does to a filter's RMSE, from the interval of the change (ranges − motion
    capture): worse / better without the motion capture where it excludes 0, else no detectable change."""
    return {"above": "worse without the motion capture", "below": "better without the motion capture",
            "contains": "no detectable change"}.get(interval_side(lo_mm, hi_mm),
                                                    f"no verdict (fewer than {MIN_BLOCKS} blocks)")


def summary_rows(board: Board, clock: dict | None, *, data: str, cal_label: str, cal_data: str | None = None) -> list[dict]:
    """Summary rows: each UWB/INS filter's tuned multipliers (procedure named in the row; ``data`` the
    calibration recording ``cal_data`` they come from, default ``data``; kind *reproduced* — it came out of the
    board's tuning, not from the paper — and "a tuning output" in the quantity) and the IMU clock's effect on
    ``data`` with its 95 % interval (the columns of ``clock["table"]``)."""
    out = []
    for name in board.methods:
        p = board.calibration.params(name)
        if "q_scale" not in p:
            continue
        for knob, v in (("Q", p["q_scale"]), ("R", p["r_scale"])):
            out.append(dict(quantity=f"{name} {knob} multiplier (lowest horizontal RMSE on {cal_label} over a "
                                     f"{len(p['grid'])}-point grid{', on its edge' if p['grid_edge'] else ''}: "
                                     "a tuning output)", value=float(v), unit="", data=cal_data or data, kind="reproduced"))
    if clock and "error" not in clock:
        o = clock["offsets"]
        out.append(dict(quantity="IMU clock offset from the ranges minus from the motion capture", unit="ms",
                        value=(o["ranges_s"] - o["truth_s"]) * 1e3, data=data, kind="reproduced"))
        for m, r in clock["table"].iterrows():
            if m in IMU_FILTERS and m != "INS-only" and np.isfinite(r["change (mm)"]):
                out += _interval_rows(f"horizontal RMSE change of {m} with the IMU clock from the ranges", r,
                                      ("change (mm)", "lo (mm)", "hi (mm)"), data)
    return out


def _interval_rows(quantity: str, row, columns: tuple[str, str, str], data: str) -> list[dict]:
    """A value (mm) and the ends of its 95 % interval as three summary rows (``quantity``, then ``…, 95 % interval
    low`` / ``high``), read from ``row[columns]`` (value, low, high); a non-finite one is left out."""
    tails = ("", ", 95 % interval low", ", 95 % interval high")
    return [dict(quantity=quantity + tail, value=float(row[col]), unit="mm", data=data, kind="reproduced")
            for tail, col in zip(tails, columns) if np.isfinite(row[col])]


def difference_rows(verdicts: pd.DataFrame, *, rate_hz: float) -> list[dict]:
    """Summary rows of the scoreboard's RMSE differences (:func:`uwbwb.scoreboard.verdicts.difference_table`, as
    the notebook shows it): per pair ``A − B`` (mm) and the ends of its 95 % interval (the verdict is the
    table's, read from that interval)."""
    return [row for _, r in verdicts.iterrows()
            for row in _interval_rows(f"horizontal RMSE difference {r['A']} − {r['B']} (scoreboard, {rate_hz:g} Hz)",
                                      r, ("A − B (mm)", "95 % low (mm)", "95 % high (mm)"), r["recording"])]
