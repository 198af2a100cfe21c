"""Why a method may beat its own bound, measured: what the scoring part's truth says about the noise and the
motion.

:func:`diagnostics` measures, per tag, the scoring part's range noise against the calibration's and the driving
noise its true track implies for each motion model; :func:`diagnostics_table` lays them beside what the methods
were told (calibrated noise, tuned σ_w). :func:`beats_bound_note` is the board's note for a method whose RMSE is
below its own bound: how far, in standard errors, and whether it is still below the same bound re-evaluated at the
scored part's measured noise (a measurement; where it is, the note says "cause not measured", no reason is
written by code). :func:`geometry_note` gives the factor by which a method's own bound exceeds the ranges' CRLB.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Mapping

import numpy as np
import pandas as pd

from ..calibration import range_sigma_from_truth
from ..types import Recording
from .interface import calibrated_log, truth_at
from .protocol import Calibration
from .verdicts import own_bound_facts

__all__ = ["GEOMETRY_FACTOR", "beats_bound_note", "bound_note", "diagnostics", "diagnostics_table", "geometry_note"]


#: A method's own bound more than this many times the ranges' snapshot CRLB gets a geometry note
#: (:func:`geometry_note`): its measurement model carries far less information than the ranges.
GEOMETRY_FACTOR = 10.0


def _num(row, name: str) -> float:
    v = getattr(row, name, float("nan"))
    return float(v) if v is not None and np.isfinite(v) else float("nan")


def beats_bound_note(row) -> str:
    """The note of a board row (:meth:`.board.Board.table`) whose RMSE is below its own bound; empty when it is not.

    Below by less than 2 standard errors: sampling error; by more: "BEATS its own bound" with the ratio and its
    standard error, then the measurement beside it: RMSE over the own bound re-evaluated at the scored part's
    measured noise (``rmse_over_bound_measured`` ± its standard error; a row without it: "cause not measured").
    Not below that one (ratio + 2 se ≥ 1): the measured noise accounts for it; also below it: "cause not
    measured" (the bound's motion model, a bias or information the bound leaves out remain; nothing here measures
    which). Without a standard error only that it is below."""
    eff, se = row.rmse_over_bound, row.rmse_over_bound_se
    if not np.isfinite(eff) or eff >= 1:
        return ""
    if not np.isfinite(se):
        return f"below its own bound (RMSE/bound {eff:.2f}; no standard error: too few blocks to say more)"
    if eff > 1 - 2 * se:
        return f"below its own bound by {1 - eff:.0%}, within 2 standard errors ({se:.2f}): sampling error"
    head = f"BEATS its own bound (RMSE/bound {eff:.2f} ± {se:.2f})"
    f = own_bound_facts(SimpleNamespace(method="", rmse_over_bound=eff, rmse_over_bound_se=se,
                                        rmse_over_bound_measured=_num(row, "rmse_over_bound_measured"),
                                        rmse_over_bound_measured_se=_num(row, "rmse_over_bound_measured_se")))
    if f["measured"] in ("none", "few blocks"):
        return head + "; cause not measured"
    at = f"at the scored part's measured noise {f['ratio_measured']:.2f} ± {f['se_measured']:.2f}"
    if f["measured"] == "not below":
        return f"{head}; not below it {at}"
    return f"{head}; below it also {at}: cause not measured"


def geometry_note(row) -> str:
    """"own bound N× the ranges' CRLB (x m)" for a row whose own bound exceeds the ranges' snapshot CRLB on the
    same epochs by more than :data:`GEOMETRY_FACTOR`; empty otherwise."""
    g, rc = _num(row, "bound_over_ranges_crlb"), _num(row, "ranges_crlb_m")
    if not np.isfinite(g) or g <= GEOMETRY_FACTOR:
        return ""
    return f"own bound {g:.0f}× the ranges' CRLB ({rc:.3g} m)"


def bound_note(row) -> str:
    """The board's note of a row that ran: :func:`geometry_note` and :func:`beats_bound_note`, either or both."""
    return "; ".join(n for n in (geometry_note(row), beats_bound_note(row)) if n)


def diagnostics_table(diag: Mapping[str, Mapping], calibration: Calibration) -> pd.DataFrame:
    """Per tag: the scoring part's robust range σ over the calibrated σ (median over anchors; < 1: the bound's
    noise is pessimistic here), and per motion model the driving-noise σ its true track implies beside the tuned
    σ_w of that EKF (implied < tuned: the track is smoother than the prior the PCRLB assumes)."""
    rows = []
    for tag, d in diag.items():
        row = {"tag": tag, "range σ scoring / calibrated": d.get("sigma_ratio", np.nan)}
        for m in ("RW", "RF", "RJ"):
            row[f"σ_w {m} from truth"] = d.get(f"sigma_w_{m}", np.nan)
            row[f"σ_w {m} tuned"] = calibration.params(f"EKF-{m}").get("sigma_w", np.nan)
        rows.append(row)
    return pd.DataFrame(rows).set_index("tag") if rows else pd.DataFrame()


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
