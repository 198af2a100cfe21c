"""Why a method beats its own bound: what the scoring part's truth says about the noise and the motion.

:func:`diagnostics` measures, per tag, the scoring part's range noise against the calibration's and
the driving noise its true track implies for each motion model; :func:`beats_bound_note` turns them
into the note the board shows beside a method whose RMSE is below its own bound.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..calibration import range_sigma_from_truth
from ..types import Recording
from .interface import calibrated_log, truth_at
from .protocol import Calibration

__all__ = ["beats_bound_note", "diagnostics"]


def beats_bound_note(row, diagnostics: Mapping[str, Mapping], calibration: Calibration) -> str:
    """Why a method's RMSE is below its own bound (empty when it is not, beyond sampling error).

    ``row`` is a row of :meth:`.board.Board.table` (``rmse_over_bound``, ``rmse_over_bound_se``,
    ``bound_kind``, ``nees_mean``, ``nees_dof``); ``diagnostics`` the board's per-tag
    :func:`diagnostics`; ``calibration`` the board's (for the tuned driving noise).
    """
    eff, se = row.rmse_over_bound, row.rmse_over_bound_se
    if not np.isfinite(eff) or eff >= 1:
        return ""
    if np.isfinite(se) and eff > 1 - 2 * se:
        return f"below its own bound by {1 - eff:.0%}, within 2 standard errors ({se:.2f}): sampling error"
    reasons = []
    diag = [d for d in diagnostics.values()]
    ratio = np.nanmedian([d["sigma_ratio"] for d in diag]) if diag else np.nan
    if np.isfinite(ratio) and ratio < 0.9:
        reasons.append(f"the ranges of the scoring part are less noisy than calibrated "
                       f"(robust σ {ratio:.2f}× the calibration's): the bound's noise model is pessimistic here")
    kind = str(row.bound_kind)
    if "INS" in kind:
        reasons.append("the UWB/INS bound is driven by the accelerometer noise density fitted on the calibration "
                       "recording; if that over-states the noise of the scored flight, the bound is too wide")
    elif kind.startswith("PCRLB") and "set-noise" not in kind:
        model = kind.split()[-1]
        vals = np.array([d.get(f"sigma_w_{model}", np.nan) for d in diag], float)
        implied = float(np.nanmedian(vals)) if np.isfinite(vals).any() else np.nan
        tuned = calibration.params(f"EKF-{model}").get("sigma_w", np.nan)
        if np.isfinite(implied) and implied < tuned:
            reasons.append(f"the true track is smoother than the {model} prior: driving-noise σ from the "
                           f"truth {implied:.3g} vs tuned {tuned:.3g}, so the PCRLB (its prior's driving "
                           f"noise, evaluated along this track) over-states what this track allows")
        else:
            reasons.append(f"the {model} prior (tuned σ_w {tuned:.3g}) misdescribes this track; the PCRLB "
                           f"holds for tracks drawn from that prior")
    if "set-noise" in kind:
        reasons.append("the per-set noise was fitted on the calibration part; where the scoring part's fixes "
                       "are less spread than that, the bound given the fixes is pessimistic")
    if row.nees_mean is not None and np.isfinite(row.nees_mean) and row.nees_mean < 0.8 * row.nees_dof:
        reasons.append(f"its own covariance is also larger than its errors (NEES {row.nees_mean:.2f} < "
                       f"{row.nees_dof:.0f}): the noise model over-states the noise")
    if not reasons:
        reasons.append("no diagnostic explains it: check the noise model")
    return f"BEATS its own bound (RMSE/bound {eff:.2f} ± {se:.2f}): " + "; ".join(reasons)


def diagnostics(rec: Recording, tag: str, cal: Calibration) -> dict:
    """What the scoring part's truth says: range noise vs the calibration's, driving noise per model."""
    log = calibrated_log(rec, tag, cal)
    pos = truth_at(rec, tag, log.t_s, 3 if rec.truth[tag].dim == 3 else 2)
    out = {"sigma_ratio": np.nan}
    if pos.shape[1] == 3:
        true_r = np.linalg.norm(pos[:, None, :] - rec.anchors.pos_m[None], axis=-1)
        ok = np.isfinite(log.range_m - true_r).sum(axis=0) >= 2      # anchors with a spread to measure
        if ok.any():
            robust = range_sigma_from_truth(log.range_m[:, ok], true_r[:, ok])
            out["sigma_ratio"] = float(np.median(robust / cal.sigma(tag)[ok]))
    have = np.all(np.isfinite(pos), axis=1)
    if have.sum() > 5:
        t, p = log.t_s[have], pos[have][:, :cal.dim]
        dt = float(np.median(np.diff(t)))
        d = p
        for order, m in enumerate(("RW", "RF", "RJ"), start=1):
            d = np.diff(d, axis=0) / dt
            out[f"sigma_w_{m}"] = float(np.sqrt(np.mean(np.sum(d * d, axis=1)) / cal.dim))
    return out
