"""Notebook 05's real-data protocol made even: every filter with noise knobs tuned on the
calibration scenario by the same procedure on the same grid (:func:`tune_scales`), and the IMU
clock estimated without the scored scenario's motion capture (:func:`imu_clock_sensitivity`).

The tuning procedure, for each filter of :data:`~uwbwb.filters.alignment.TUNABLE` asked for:
one start-up (:func:`~uwbwb.filters.alignment.align_iasl`) on the calibration recording, then
the filter from that start at every ``(q, r)`` of the grid (its process- and measurement-noise
multipliers, :func:`~uwbwb.filters.alignment.run_fusion_filter`), scored by horizontal RMSE on
the epochs with truth; the lowest picks. UWB-only LS has no knob and INS-only is not tuned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...datasets import iasl
from ...errors import DataFormatError
from ...filters.alignment import Comparison, FusionSettings, align_iasl, compare_iasl, run_fusion_filter
from ...filters.imu_calibration import RealCalibration
from ...metrics import MIN_BLOCKS, block_bootstrap_difference, interval_side, nis_consistency, rmse, score_epochs
from ...scoreboard.estimators import INS_GRID
from ...types import Recording

__all__ = ["TUNED", "ScaleTuning", "tune_scales", "tuning_table", "IMU_FILTERS",
           "imu_clock_sensitivity", "clock_verdict", "summary_rows"]

#: The filters notebook 05 tunes on the calibration scenario, each by the same procedure and grid.
TUNED = ("EKF + gate", "loose", "tight", "tight (ranges)")
#: The rows whose inputs include the IMU (the clock's sensitivity is read on them).
IMU_FILTERS = ("tight", "tight (ranges)", "loose", "INS-only")


@dataclass(frozen=True)
class ScaleTuning:
    """One filter's ``(q, r)`` pick on the calibration scenario.

    Attributes
    ----------
    name
        The filter.
    table
        Horizontal RMSE (m) and mean NIS per dof per grid point (index ``q``, ``r``).
    q, r
        The pick: lowest horizontal RMSE.
    q_edge, r_edge
        Whether the pick of that knob lies on the grid's edge (a wider grid might do better).
    """

    name: str
    table: pd.DataFrame
    q: float
    r: float
    q_edge: bool
    r_edge: bool

    @property
    def scales(self) -> tuple[float, float]:
        return self.q, self.r


def tune_scales(rec: Recording, cal: RealCalibration, settings: FusionSettings = FusionSettings(), *,
                names=TUNED, grid=INS_GRID, still_s: float = 2.0, align_s: float = 20.0,
                duration_s: float | None = None) -> dict[str, ScaleTuning]:
    """Tune every filter of ``names`` on ``rec`` (the calibration scenario, with truth) by the
    module's procedure: one alignment, every grid point from the same start, lowest horizontal RMSE.

    Returns filter name → :class:`ScaleTuning`.
    """
    if not grid:
        raise ValueError("grid: at least one (q, r) pair")
    a = align_iasl(rec, cal, settings, still_s=still_s, align_s=align_s, duration_s=duration_s)
    t = a.log.select(a.after).t_s
    truth = rec.truth["tag"].interp(t)[:, :2]
    qs, rs = sorted({float(q) for q, _ in grid}), sorted({float(r) for _, r in grid})
    out = {}
    for name in names:
        rows = {}
        for q, r in grid:
            _, est = run_fusion_filter(name, a, rec, cal, settings, scales=(float(q), float(r)))
            own = score_epochs({name: np.linalg.norm(est.pos_m[:, :2] - truth, axis=1)})[name]
            rows[(float(q), float(r))] = {"horizontal RMSE (m)": rmse(own.own_m)   # a diverged (infinite) error: inf
                                          if own.n_scored and np.isfinite(own.own_m).all() else np.inf,
                                          "mean NIS / dof": nis_consistency(est.info.get("nis", []),
                                                                            est.info.get("dof", []))["mean_nis_over_dof"]}
        table = pd.DataFrame(rows).T
        table.index.names = ["q", "r"]
        q, r = table["horizontal RMSE (m)"].idxmin()
        out[name] = ScaleTuning(name, table, q, r, qs.index(q) in (0, len(qs) - 1), rs.index(r) in (0, len(rs) - 1))
    return out


def tuning_table(tunings: dict[str, ScaleTuning]) -> pd.DataFrame:
    """One row per tuned filter: the pick, its RMSE on the calibration scenario, the untuned
    ``(1, 1)`` RMSE where the grid holds it, and the edge flags."""
    rows = {}
    for name, t in tunings.items():
        rmse = t.table["horizontal RMSE (m)"]
        rows[name] = {"Q ×": t.q, "R ×": t.r, "RMSE picked (m)": float(rmse.min()),
                      "RMSE at Q × 1, R × 1 (m)": float(rmse.get((1.0, 1.0), np.nan)),
                      "edge": ", ".join(k for k, e in (("Q", t.q_edge), ("R", t.r_edge)) if e) or "—"}
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


def imu_clock_sensitivity(comp: Comparison, rec: Recording, cal: RealCalibration,
                          settings: FusionSettings = FusionSettings(), *, rng: np.random.Generator, data_dir=None,
                          **compare_kw) -> dict:
    """The comparison again with the IMU clock from the scenario's own ranges instead of its motion
    capture (:func:`uwbwb.datasets.iasl.load_scenario` with ``imu_clock="ranges"``, the loader's
    other options at their defaults).

    ``comp`` is the comparison as run on ``rec`` (an ``iasl-uwb-imu`` scenario loaded with the IMU
    clock from its motion capture, the default); ``compare_kw`` are the arguments it was run with
    (:func:`~uwbwb.filters.alignment.compare_iasl`: the same tuned scales). Per method, on the
    epochs both runs score and cover: horizontal RMSE both ways, the change ``ranges − motion
    capture`` (mm) with its 95 % block-bootstrap interval (:func:`uwbwb.metrics.block_bootstrap_difference`)
    and the epoch count, and :func:`clock_verdict` of that interval. Returns ``{"offsets": {"truth_s", "ranges_s",
    "peak", "rival", "halves_s"}, "start_s":
    (as run, with the ranges clock), "table": DataFrame}``, or ``{"error": message}`` when the
    ranges cannot pin the clock down (an ambiguous correlation) — reported, not hidden.
    """
    try:
        rec_r = iasl.load_scenario(rec.name, data_dir, imu_clock="ranges")
    except DataFormatError as exc:
        return {"error": str(exc)}
    comp_r = compare_iasl(rec_r, cal, settings, **compare_kw)
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


def summary_rows(tunings: dict[str, ScaleTuning], clock: dict | None, *, data: str, cal_label: str,
                 cal_data: str | None = None) -> list[dict]:
    """Summary rows: each filter's tuned multipliers (procedure named in the row; ``data`` the
    calibration recording ``cal_data`` they come from, default ``data``) and the IMU clock's effect
    on ``data``."""
    out = []
    for name, t in tunings.items():
        for knob, v, edge in (("Q", t.q, t.q_edge), ("R", t.r, t.r_edge)):
            out.append(dict(quantity=f"{name} {knob} multiplier (lowest horizontal RMSE on {cal_label} over a "
                                     f"{len(t.table)}-point grid{', on its edge' if edge else ''}: a tuning output)",
                            value=v, unit="", data=cal_data or data, kind="reproduced"))
    if clock and "error" not in clock:
        o = clock["offsets"]
        out.append(dict(quantity="IMU clock offset from the ranges minus from the motion capture", unit="ms",
                        value=(o["ranges_s"] - o["truth_s"]) * 1e3, data=data, kind="reproduced"))
        for m, v in clock["table"]["change (mm)"].items():
            if m in IMU_FILTERS and m != "INS-only" and np.isfinite(v):
                out.append(dict(quantity=f"horizontal RMSE change of {m} with the IMU clock from the ranges",
                                value=float(v), unit="mm", data=data, kind="reproduced"))
    return out
