"""Notebook 05's real-data covariance check (``iasl-uwb-imu``): the covariance inflation that makes
the tight filter consistent, fitted on the calibration scenario and applied on the scored one. The
tuning table and the IMU clock without motion capture are in :mod:`.realfair`.

Nothing here reads the scored scenario's truth except to score; the loader's default IMU clock
offset is estimated against each scenario's own motion-capture attitude (see
:mod:`uwbwb.datasets.registration`) — :func:`.realfair.imu_clock_sensitivity` measures what that changes.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ... import metrics
from .realdata import common_epochs

__all__ = ["CONSISTENT_POINTS", "summary_rows", "nees_inflation"]

#: The scaled covariance is consistent when its share of epochs inside the ellipse is within this of the level.
CONSISTENT_POINTS = 0.10

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
        ``inside_test_scaled`` (share of scored epochs inside the ``prob`` ellipse),
        ``nis_dof_cal``, ``nis_dof_test`` (mean NIS per dof of its updates, 1 if honest), and
        ``scaled_consistent`` (``inside_test_scaled`` within :data:`CONSISTENT_POINTS` of ``prob``: the scale
        transfers to the scored scenario).
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
            "nis_dof_test": nis(comp_test), "prob": prob,
            "scaled_consistent": bool(abs(np.mean(n_test / k <= lim) - prob) <= CONSISTENT_POINTS)}


def summary_rows(inflation: dict, *, data: str, cal_label: str) -> list[dict]:
    """Summary rows: the tight filter's covariance scale fitted on ``cal_label`` (an output of that
    fit, not of the filter) and its mean NEES on ``data`` after the scale."""
    return [dict(quantity=f"tight covariance scale for mean NEES = dof (fitted on {cal_label}: mean NEES / dof there)",
                 value=inflation["k"], unit="", data=data, kind="reproduced"),
            dict(quantity="mean position NEES tight after that scale", value=inflation["nees_test_scaled"], unit="",
                 data=data, kind="reproduced")]
