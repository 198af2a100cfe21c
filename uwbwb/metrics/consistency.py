"""Filter consistency: NEES per epoch and the χ² test of a filter's NIS (or NEES) over its updates."""

from __future__ import annotations

import numpy as np

from ..validate import probability

# --------------------------------------------------------------------------- consistency
# The one place where a filter's covariances are held to its errors (NEES) and its innovations (NIS):
# every run type (``KalmanRun``, ``FusionRun``, the set-noise ``FilterRun``), the scoreboard and the
# experiments call these two functions.


def nees(err, cov, where=None) -> np.ndarray:
    """Normalised estimation error squared ``eᵀ P⁻¹ e`` per epoch.

    Parameters
    ----------
    err
        Estimation errors, shape ``(T, d)`` (estimate minus truth).
    cov
        The estimator's own covariances of those components, shape ``(T, d, d)``.
    where
        Epochs to evaluate, bool ``(T,)`` (default: all); epochs whose error or covariance is
        not finite are left out as well.

    Returns
    -------
    numpy.ndarray
        Shape ``(T,)``; χ²(d)-distributed when the estimator is consistent; NaN where not evaluated.
    """
    e, P = np.asarray(err, float), np.asarray(cov, float)
    if e.ndim != 2 or P.shape != e.shape + (e.shape[1],):
        raise ValueError(f"nees: err (T, d) and cov (T, d, d) expected, got {e.shape} and {P.shape}")
    T = e.shape[0]
    ok = np.all(np.isfinite(e), axis=1) & np.all(np.isfinite(P), axis=(1, 2))
    if where is not None:
        ok &= np.asarray(where, bool)
    out = np.full(T, np.nan)
    out[ok] = np.einsum("ti,ti->t", e[ok], np.linalg.solve(P[ok], e[ok][..., None])[..., 0])
    return out


def nis_consistency(nis, dof, prob: float = 0.95) -> dict:
    """χ² test of a filter's NIS over its updates (also of NEES values, with ``dof`` the state size).

    Under correct models the sum of the NIS over ``n`` updates is χ²(Σ dof). The verdict
    compares that sum with its central ``prob`` interval: above it the filter is
    *over-confident* (its covariances are too small for its errors), below it
    *under-confident*. Epochs with ``dof == 0`` or a non-finite value (nothing used) are
    left out.

    Returns
    -------
    dict
        ``n`` updates, ``mean_nis_over_dof`` (≈ 1 when consistent), ``fraction_inside``
        (share of single updates inside their own central ``prob`` interval),
        ``sum_nis``, ``sum_dof``, the interval ``sum_lo``/``sum_hi`` and ``verdict``
        (``"consistent"``, ``"over-confident"``, ``"under-confident"`` or ``"no updates"``).
    """
    probability("prob", prob)
    nis, dof = np.asarray(nis, float), np.asarray(dof, int)
    ok = (dof > 0) & np.isfinite(nis)
    if not ok.any():
        return {"n": 0, "mean_nis_over_dof": np.nan, "fraction_inside": np.nan, "sum_nis": np.nan,
                "sum_dof": 0, "sum_lo": np.nan, "sum_hi": np.nan, "verdict": "no updates"}
    from scipy.stats import chi2    # imported when used: scipy.stats costs seconds wherever uwbwb.metrics is imported

    nis, dof = nis[ok], dof[ok]
    a = (1 - prob) / 2
    inside = (nis >= chi2.ppf(a, dof)) & (nis <= chi2.ppf(1 - a, dof))
    total = int(dof.sum())
    lo, hi, s = float(chi2.ppf(a, total)), float(chi2.ppf(1 - a, total)), float(nis.sum())
    verdict = "over-confident" if s > hi else "under-confident" if s < lo else "consistent"
    return {"n": int(ok.sum()), "mean_nis_over_dof": s / total, "fraction_inside": float(inside.mean()),
            "sum_nis": s, "sum_dof": total, "sum_lo": lo, "sum_hi": hi, "verdict": verdict}
