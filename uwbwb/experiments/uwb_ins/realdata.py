"""Notebook 05's real-data tables (``iasl-uwb-imu``), read from the scoreboard that tunes, runs and scores the
methods (:func:`uwbwb.scoreboard.score`, the board notebook 06 builds): horizontal, vertical and 3-D error and
consistency (NEES, NIS) on the board's common epochs, the tight filter's covariance scale, and the summary rows.
Which method is more accurate is the board's verdict (:func:`uwbwb.scoreboard.verdicts.difference_table`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from ... import metrics
from ...filters.alignment import Comparison
from ...scoreboard import Board
from ...scoreboard.verdicts import EDGE_BOUND_LABEL, edge_bound
from ...types import Trajectory

__all__ = ["CONSISTENT_POINTS", "board_comparison", "common_table", "nees_inflation", "summary_rows"]

#: The scaled covariance is consistent when its share of epochs inside the ellipse is within this of the level.
CONSISTENT_POINTS = 0.10


def board_comparison(board: Board, tag: str = "tag") -> Comparison:
    """The board's estimates on ``tag`` as the :class:`~uwbwb.filters.alignment.Comparison` notebook 05's figures
    draw: truth where the board scores (``masks["scored"]``), and the TDoAs eq. 4 and the tight filter's gate
    rejected (``rejected``, where the board has a ``tight`` row)."""
    ents = board.ran(tag)
    have = ents[0].scoring
    truth = Trajectory(ents[0].estimates.t_s, np.where(have[:, None], ents[0].truth_pos_m, 0.0), name="truth")
    est = {e.method: e.estimates for e in ents}
    info = est["tight"].info if "tight" in est else {}
    rejected = {k: int(np.sum(info[n])) for k, n in (("eq4", "n_outliers"), ("gated", "n_gated")) if n in info}
    first = [e.t_s[e.has_estimate][0] for e in est.values() if e.has_estimate.any()]
    return Comparison(board.data_label, truth, est, {}, {"scored": have}, rejected, 2,
                      {"start_s": float(max(first)) if first else np.nan})


def common_table(board: Board, tag: str = "tag", *, prob: float = 0.95) -> pd.DataFrame:
    """Per method, on the board's common epochs (truth present, every method has an estimate:
    :meth:`Board.scores`): horizontal, vertical and 3-D RMSE (:func:`uwbwb.metrics.score_epochs`; the horizontal
    one is the board's ``rmse_common_m``), the common-epoch count, and for a method with a covariance its mean
    position NEES (``dof`` if honest: :attr:`~uwbwb.scoreboard.board.Entry.nees`), the share of epochs inside its
    own ``prob`` ellipse, the inflation ``mean NEES / dof`` and the mean NIS per dof of its updates."""
    ents = board.ran(tag)
    common = board.scores(tag).methods[0].common
    err = {e.method: e.estimates.pos_m - e.truth_pos_m for e in ents}
    parts = {"horizontal RMSE (m)": {m: np.linalg.norm(d[:, :2], axis=1) for m, d in err.items()},
             "vertical RMSE (m)": {m: np.abs(d[:, 2]) for m, d in err.items()},
             "3-D RMSE (m)": {m: np.linalg.norm(d, axis=1) for m, d in err.items()}}
    t = pd.concat([metrics.score_epochs(e, common).table(common={c: metrics.rmse})[c] for c, e in parts.items()], axis=1)
    t["common epochs"] = int(common.sum())
    rows = {}
    for e in ents:
        nees = e.nees[common]
        if e.estimates.pos_cov_m2 is None or not np.isfinite(nees).any():
            continue
        dof, nees, info = e.estimates.dim, nees[np.isfinite(nees)], e.estimates.info
        rows[e.method] = {"dof": dof, "mean NEES": nees.mean(), f"inside own {prob:.0%} ellipse":
                          np.mean(nees <= stats.chi2.ppf(prob, dof)), "covariance inflation": nees.mean() / dof,
                          "mean NIS / dof": metrics.nis_consistency(info["nis"], info["dof"], prob)["mean_nis_over_dof"]
                          if "nis" in info else np.nan}
    return t.join(pd.DataFrame(rows, index=["dof", "mean NEES", f"inside own {prob:.0%} ellipse",
                                             "covariance inflation", "mean NIS / dof"]).T).rename_axis(None)


def nees_inflation(cal_board: Board, board: Board, method: str = "tight", tag: str = "tag", *,
                   prob: float = 0.95) -> dict:
    """The scale ``k`` on ``method``'s position covariance that brings its mean NEES to its dof on the calibration
    scenario (``cal_board``: the board's ``method`` run there with the board's calibration), applied unchanged on
    the scored one (``board``, its common epochs): ``k``, the mean NEES before and after the scale, the share inside
    the ``prob`` ellipse before and after, and ``scaled_consistent`` (that share within :data:`CONSISTENT_POINTS` of
    ``prob``: the scale transfers)."""
    cal, test = cal_board.entry(method, tag), board.entry(method, tag)
    n_cal, n_test = cal.nees[cal.scored], test.nees[board.scores(tag).methods[0].common]
    n_cal, n_test = n_cal[np.isfinite(n_cal)], n_test[np.isfinite(n_test)]
    dof, lim = test.estimates.dim, stats.chi2.ppf(prob, test.estimates.dim)
    k = float(n_cal.mean() / dof)
    inside = float(np.mean(n_test / k <= lim))
    return {"dof": dof, "k": k, "nees_cal": float(n_cal.mean()), "nees_test": float(n_test.mean()),
            "nees_test_scaled": float(n_test.mean() / k), "inside_test": float(np.mean(n_test <= lim)),
            "inside_test_scaled": inside, "prob": prob, "scaled_consistent": bool(abs(inside - prob) <= CONSISTENT_POINTS)}


def _interval_rows(quantity: str, row, data: str) -> list[dict]:
    """A difference-table row's ``A − B`` (mm) and the ends of its 95 % interval as three summary rows (``quantity``,
    then ``…, 95 % interval low`` / ``high``); a non-finite one is left out."""
    tails = ("", ", 95 % interval low", ", 95 % interval high")
    return [dict(quantity=quantity + tail, value=float(row[col]), unit="mm", data=data, kind="reproduced")
            for tail, col in zip(tails, ("A − B (mm)", "95 % low (mm)", "95 % high (mm)")) if np.isfinite(row[col])]


def _clock_rows(clock: pd.DataFrame, offset_ms: float, data: str) -> list[dict]:
    """The IMU clock offset from the ranges minus from the motion capture (ms), and each IMU filter's RMSE change
    with the ranges' clock, with its interval ends: the cells of ``clock`` (a difference table of ``m (ranges
    clock)`` against ``m``; INS-only, no UWB, left out), edge-bound where its verdict is (:data:`EDGE_BOUND_LABEL`)."""
    out = [dict(quantity="IMU clock offset from the ranges minus from the motion capture", value=float(offset_ms),
                unit="ms", data=data, kind="reproduced")]
    for _, r in clock[clock["B"] != "INS-only"].iterrows():
        edge = f" ({EDGE_BOUND_LABEL})" if edge_bound(r.get("verdict")) else ""
        out += _interval_rows(f"horizontal RMSE change of {r['B']} with the IMU clock from the ranges{edge}", r, data)
    return out


def summary_rows(board: Board, *, cal_label: str, cal_data: str, rate_hz: float, verdicts=None, clock=None,
                 clock_offset_ms: float = np.nan, inflation: dict | None = None) -> list[dict]:
    """Summary rows of the real-data section, each a cell of a table the notebook shows (kind *reproduced*):
    :func:`common_table`'s RMSEs (labelled *common epochs*: the board's own-epoch RMSEs, shown beside the figures,
    are not rows) and mean NEES, each tuned filter's ``Q ×`` and ``R ×`` (a tuning output on
    ``cal_data``), the covariance scale (:func:`nees_inflation`), the TDoAs the tight filter rejected, the IMU clock
    offset from the ranges and each IMU filter's RMSE change with it (``clock``: a difference table of ``m (ranges
    clock)`` against ``m``), and the board's differences (``verdicts``), each with its 95 % interval ends; a
    difference whose verdict is edge-bound says so in its quantity (:data:`EDGE_BOUND_LABEL`)."""
    data, t = board.data_label, common_table(board)

    def add(quantity, value, unit="m", d=data):
        return dict(quantity=quantity, value=float(value), unit=unit, data=d, kind="reproduced")

    out = [add(f"{c.split(' (')[0]} {m}, common epochs (calibrated on {cal_label})", t.loc[m, c]) for m in t.index
            for c in ("horizontal RMSE (m)", "vertical RMSE (m)", "3-D RMSE (m)") if np.isfinite(t.loc[m, c])]
    out += [add(f"mean position NEES {m} ({int(r['dof'])} dof)", r["mean NEES"], "") for m, r in t.iterrows()
            if np.isfinite(r.get("mean NEES", np.nan))]
    for name in board.methods:
        p = board.calibration.params(name)
        out += [add(f"{name} {knob} multiplier (lowest horizontal RMSE on {cal_label} over a {len(p['grid'])}-point "
                    f"grid{', on its edge' if p['grid_edge'] else ''}: a tuning output)", p[key], "", cal_data)
                for knob, key in (("Q", "q_scale"), ("R", "r_scale")) if key in p]
    if inflation:
        out += [add(f"tight covariance scale for mean NEES = dof (fitted on {cal_label}: mean NEES / dof there)",
                    inflation["k"], ""), add("mean position NEES tight after that scale", inflation["nees_test_scaled"], "")]
    rej = board_comparison(board).rejected
    if rej:
        out.append(add("TDoAs rejected by eq4 + gate", rej["eq4"] + rej["gated"], ""))
    if clock is not None:
        out += _clock_rows(clock, clock_offset_ms, data)
    for _, r in (verdicts.iterrows() if verdicts is not None else ()):
        edge = f"; {EDGE_BOUND_LABEL}" if edge_bound(r.get("verdict")) else ""
        out += _interval_rows(f"horizontal RMSE difference {r['A']} − {r['B']} (scoreboard, {rate_hz:g} Hz{edge})", r,
                              r["recording"])
    return out
