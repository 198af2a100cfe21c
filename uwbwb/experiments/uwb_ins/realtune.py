"""Notebook 05's real-data protocol pieces (``iasl-uwb-imu``): the covariance inflation that makes
the tight filter consistent (fitted on the calibration scenario, applied on the scored one), and
the steps from notebook 05's protocol to the board's (notebook 06) for "tight on the scored
scenario". Every filter's Q/R tuning and the IMU clock without motion capture are in
:mod:`.realfair`.

Nothing here reads the scored scenario's truth except to score; the loader's default IMU clock
offset is estimated against each scenario's own motion-capture attitude (see
:mod:`uwbwb.datasets.registration`) — :func:`.realfair.imu_clock_sensitivity` measures what that changes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
from scipy import stats

from ... import metrics
from ...filters.alignment import FusionSettings, compare_iasl
from ...filters.imu_calibration import RealCalibration
from ...scoreboard.estimators import INS_ALIGN_S, INS_GRID, INS_REST_S, MAX_TRUTH_GAP_S, UwbInsFilter, calibrated_log
from ...scoreboard.protocol import between, fit_calibration
from ...types import Recording
from .realdata import common_epochs

__all__ = ["summary_rows", "nees_inflation", "inflation_sentence", "board_steps", "reconcile_sentence"]

def _nees(comp, method: str) -> np.ndarray:
    sel = common_epochs(comp)
    est = comp.estimates[method]
    return metrics.nees(est.pos_m[sel] - comp.truth.pos_m[sel, : est.dim], est.pos_cov_m2[sel])


def nees_inflation(comp_cal, comp_test, method: str = "tight", *, prob: float = 0.95) -> dict:
    """The scale ``k`` on ``method``'s position covariance that brings its mean NEES to its dof on
    the calibration scenario (``comp_cal``), applied unchanged on the scored one (``comp_test``).

    Returns
    -------
    dict
        ``dof``, ``k`` (= mean NEES / dof on the calibration scenario), ``nees_cal``, ``nees_test``
        (mean, before scaling), ``nees_test_scaled`` (mean of NEES / k), ``inside_test`` and
        ``inside_test_scaled`` (share of scored epochs inside the ``prob`` ellipse), and
        ``nis_dof_cal``, ``nis_dof_test`` (mean NIS per dof of its updates, 1 if honest).
    """
    n_cal, n_test = _nees(comp_cal, method), _nees(comp_test, method)
    dof = comp_test.estimates[method].dim
    k = float(n_cal.mean() / dof)
    lim = stats.chi2.ppf(prob, dof)

    def nis(comp):
        info = comp.estimates[method].info
        return metrics.nis_consistency(info.get("nis", []), info.get("dof", []), prob)["mean_nis_over_dof"]

    return {"dof": dof, "k": k, "nees_cal": float(n_cal.mean()), "nees_test": float(n_test.mean()),
            "nees_test_scaled": float(n_test.mean() / k), "inside_test": float(np.mean(n_test <= lim)),
            "inside_test_scaled": float(np.mean(n_test / k <= lim)), "nis_dof_cal": nis(comp_cal),
            "nis_dof_test": nis(comp_test), "prob": prob}


def inflation_sentence(f: dict, method: str = "tight", *, cal_label: str, test_label: str) -> str:
    """Why ``method`` is over-confident and what inflation makes it consistent, from :func:`nees_inflation`.

    The explanation depends on the numbers: when the mean NIS per dof is far nearer 1 than the
    NEES per dof, the innovations are roughly honest and the over-confidence sits in the
    propagated state covariance (the IMU noise model and correlated range biases that white
    measurement noise treats as independent information); otherwise the measurement model is
    over-confident too.
    """
    d = f["dof"]
    ratio_nees, ratio_nis = f["nees_test"] / d, f["nis_dof_test"]
    where = ("its innovations are much nearer honest (NIS/dof {nis:.2f}) than its position error (NEES/dof {ne:.1f}): "
             "the over-confidence sits in the propagated covariance — the IMU noise densities fitted on the calibration "
             "residuals, and range errors correlated over seconds that a white measurement model counts as independent "
             "information at every epoch" if np.isfinite(ratio_nis) and ratio_nis < 0.5 * ratio_nees else
             "its innovations are over-confident too (NIS/dof {nis:.2f}, NEES/dof {ne:.1f}): the measurement model "
             "understates the range errors as well as the propagated covariance does")
    ok = abs(f["inside_test_scaled"] - f["prob"]) <= 0.1
    return (f"**Consistency of {method}.** On `{test_label}` its mean position NEES is {f['nees_test']:.1f} on {d} dof, "
            f"{f['inside_test']:.0%} of epochs inside its own {f['prob']:.0%} ellipse; "
            + where.format(nis=ratio_nis, ne=ratio_nees)
            + f". Scaling its position covariance by k = {f['k']:.1f} (the mean NEES / dof on `{cal_label}`, "
            f"where NEES was {f['nees_cal']:.1f}) gives on `{test_label}` a mean NEES of {f['nees_test_scaled']:.1f} "
            f"and {f['inside_test_scaled']:.0%} inside the {f['prob']:.0%} ellipse — "
            + ("consistent within 10 points." if ok else "still not consistent within 10 points: the scale does not transfer.")
            + " The scale is applied to the reported covariance after the run: the filter itself, and its χ² gate, "
            "still use the unscaled, over-confident one.")


def _tight_rmse(comp) -> tuple[float, int]:
    sel = comp.masks["scored"] & np.all(np.isfinite(comp.estimates["tight"].pos_m), axis=1)
    e = np.linalg.norm(comp.estimates["tight"].pos_m[sel, :2] - comp.truth.pos_m[sel, :2], axis=1)
    return float(np.sqrt(np.mean(e ** 2))), int(sel.sum())


def board_steps(cal_rec: Recording, test_rec: Recording, real_cal: RealCalibration, comp,
                settings: FusionSettings = FusionSettings(), *, rate_hz: float = 10.0,
                duration_s: float | None = None) -> pd.DataFrame:
    """"Tight on the scored scenario" from notebook 05's protocol (``comp``) to the board's, one change at a time.

    Steps: (1) notebook 05 as run; (2) the ranges thinned to ``rate_hz`` (the board's rate) and the
    board's rest/alignment lengths; (3) the board's per-pair range calibration fitted on ``cal_rec``
    (calibrated ranges, σ per anchor from their residuals, no common bias) instead of the notebook's
    raw ranges and robust σ — steps 1–3 keep the tight filter's ``(q, r)`` of ``comp`` (its
    ``meta["scales"]``, tuned by notebook 05 on ``cal_rec``); (4) the board's own adapter: ``(q, r)``
    tuned on ``cal_rec`` over the board's grid, scored by the board's rule (the estimate's own epochs against interpolated truth,
    gaps over 0.5 s left out). With ``duration_s`` both recordings are cut to the rest, the
    alignment and that many seconds (FAST).
    """
    if duration_s is not None:
        span = INS_REST_S + INS_ALIGN_S + duration_s

        def cut(rec):
            t0 = min(log.t_s[0] for log in rec.ranges.values())
            return between(rec, t0, t0 + span)

        cal_rec, test_rec = cut(cal_rec), cut(test_rec)
    rows = {}
    rmse, n = _tight_rmse(comp)
    scales = {"tight": tuple(comp.meta.get("scales", {}).get("tight", (1.0, 1.0)))}
    q, r = scales["tight"]
    rows[f"1 · notebook 05 (native rate, raw ranges, Q × {q:g}, R × {r:g})"] = (rmse, n)
    cal_t, test_t = cal_rec.decimate(rate_hz=rate_hz), test_rec.decimate(rate_hz=rate_hz)
    c2 = compare_iasl(test_t, real_cal, settings, still_s=INS_REST_S, align_s=INS_ALIGN_S, scales=scales)
    rows[f"2 · + {rate_hz:g} Hz, rest {INS_REST_S:g} s, alignment {INS_ALIGN_S:g} s"] = _tight_rmse(c2)
    bcal = fit_calibration(cal_t, ("tag",), rate_hz=rate_hz, dim=3)
    real = replace(real_cal, range_sigma_m=bcal.sigma("tag"), range_bias_m=0.0)
    one = replace(test_t, ranges={"tag": calibrated_log(test_t, "tag", bcal)})
    c3 = compare_iasl(one, real, settings, still_s=INS_REST_S, align_s=INS_ALIGN_S, scales=scales)
    rows["3 · + the board's range calibration and σ"] = _tight_rmse(c3)
    ins = UwbInsFilter("tight", {}, INS_GRID)
    tuned = ins.tune(cal_t, ("tag",), bcal)
    est = ins.estimate(test_t, "tag", bcal.with_tuned("tight", tuned))
    e = metrics.errors_vs_truth(est.to_trajectory(), test_t.truth["tag"], horizontal=True, max_gap_s=MAX_TRUTH_GAP_S)
    rows[f"4 · + the board's Q × {tuned['q_scale']:g}, R × {tuned['r_scale']:g} (tuned on the calibration scenario) "
         "and scoring rule"] = (metrics.rmse(e.err_m), len(e))
    t = pd.DataFrame(rows, index=["tight horizontal RMSE (m)", "epochs"]).T
    t["epochs"] = t["epochs"].astype(int)
    return t


def reconcile_sentence(steps: pd.DataFrame, *, test_label: str) -> str:
    """The computed sentence that reconciles notebook 05's and the board's "tight on ``test_label``"."""
    v = steps["tight horizontal RMSE (m)"].to_numpy()
    names = [s.split(" · ", 1)[1] for s in steps.index]
    d = np.diff(v)
    big = int(np.argmax(np.abs(d)))
    return (f"**Tight on `{test_label}`: notebook 05 {v[0]:.3f} m, board protocol {v[-1]:.3f} m.** The protocols differ "
            "in rate, range calibration, tuning and scoring epochs; taken one at a time: "
            + "; ".join(f"{n} → {x:.3f} m ({dx * 1e3:+.1f} mm)" for n, x, dx in zip(names[1:], v[1:], d))
            + f". The largest step is \"{names[big + 1]}\".")


def summary_rows(inflation: dict, *, data: str, cal_label: str) -> list[dict]:
    """Summary rows: the tight filter's covariance scale fitted on ``cal_label`` (an output of that
    fit, not of the filter) and its mean NEES on ``data`` after the scale."""
    return [dict(quantity=f"tight covariance scale for mean NEES = dof (fitted on {cal_label}: mean NEES / dof there)",
                 value=inflation["k"], unit="", data=data, kind="reproduced"),
            dict(quantity="mean position NEES tight after that scale", value=inflation["nees_test_scaled"], unit="",
                 data=data, kind="reproduced")]
