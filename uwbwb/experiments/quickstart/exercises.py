"""Exercises of notebook 00 ("change X, predict Y").

Each exercise function runs both settings on the same epochs and returns a
:class:`uwbwb.widgets.ExerciseCheck`: the direction the student is asked to predict, whether
this run shows it, and the numbers. The reasoning is the check's ``why``, shown
once the student has predicted; ``TEACHING.md`` gives one run's numbers.
"""

from __future__ import annotations

import numpy as np

from ... import geometry, metrics
from ...calibration import RangeCalibration
from ...types import Recording
from ... import validate
from ...widgets import ExerciseCheck


def _errors(rec: Recording, tag: str, range_m: np.ndarray, z_m: float, mask=None) -> metrics.ErrorSeries:
    """Horizontal errors of per-epoch 2-D fixes from ``range_m`` (anchors outside ``mask`` dropped)."""
    r = np.asarray(range_m, float)
    if mask is not None:
        r = np.where(mask, r, np.nan)
    fix = geometry.multilaterate(r, rec.anchors.pos_m, dim=2, z_m=z_m)
    est = fix.to_trajectory(rec.ranges[tag].t_s, name="fix")
    return metrics.errors_vs_truth(est, rec.truth[tag], horizontal=True)


def _ranges(rec: Recording, tag: str, calibration: RangeCalibration | None) -> np.ndarray:
    log = rec.ranges_of(tag, calibration)
    return log.range_m


def fewer_anchors(rec: Recording, tag: str, *, tag_height_m: float, calibration: RangeCalibration | None = None,
                  keep=slice(None, None, 2)) -> ExerciseCheck:
    """Exercise: use only some of the anchors (default every second one); predict HDOP and CEP95.

    Removing anchors removes rows from the geometry matrix $H$, so $H^\\top H$ can only lose
    information and the horizontal DOP along the path can only grow; with the same range errors the
    fixes should scatter more (CEP95 up). The errors are scored on the epochs both settings fixed.

    Parameters
    ----------
    rec, tag
        The recording and the tag to fix.
    tag_height_m
        The tag's mount height, metres (from the static poses).
    calibration
        Range calibration applied to both settings, or None for raw ranges.
    keep
        Index into the anchors (slice, index list or boolean mask of shape ``(n_anchors,)``).

    Returns
    -------
    ExerciseCheck
        Claim "fewer anchors: CEP95 higher" (the HDOP cannot fall, so it is a number, not the claim); numbers: median
        HDOP along the true path and CEP95 (m) with all and with the kept anchors, coverage of each.
    """
    n = len(rec.anchors.pos_m)
    mask = np.zeros(n, bool)
    mask[np.arange(n)[keep]] = True
    if mask.sum() < 3 or mask.all():
        raise ValueError(f"keep: selects {int(mask.sum())} of {n} anchors; need at least 3 and fewer than all")
    r = _ranges(rec, tag, calibration)
    full = _errors(rec, tag, r, tag_height_m)
    part = _errors(rec, tag, r, tag_height_m, mask)
    common = metrics.score_epochs({"all": full.err_m, "part": part.err_m})          # the epochs both fixed
    e_full, e_part = common["all"].common_m, common["part"].common_m
    path = rec.truth[tag].pos_m[:, :2]
    h_full = float(np.median(geometry.gdop(path, rec.anchors.pos_m, z_m=tag_height_m)))
    h_part = float(np.median(geometry.gdop(path, rec.anchors.pos_m, z_m=tag_height_m, mask=mask)))
    c_full, c_part = metrics.cep95(e_full), metrics.cep95(e_part)
    return ExerciseCheck(
        f"with {int(mask.sum())} of {n} anchors CEP95 is higher",
        c_part > c_full,
        {"HDOP, all anchors": h_full, f"HDOP, {int(mask.sum())} anchors": h_part,
         "CEP95 all (m)": c_full, f"CEP95 {int(mask.sum())} anchors (m)": c_part,
         "coverage all (%)": 100 * common["all"].coverage,
         f"coverage {int(mask.sum())} anchors (%)": 100 * common["part"].coverage},
        ("higher", "not higher"),
        "Removing anchors removes rows of H, so the HDOP can only grow (compare the two HDOPs); with the same "
        "range errors the fixes then usually scatter more, but on one short run they need not — so only CEP95 "
        "is a prediction.")


def noisier_ranges(rec: Recording, tag: str, *, tag_height_m: float, calibration: RangeCalibration | None = None,
                   sigma_m: float = 0.10, rng: np.random.Generator) -> ExerciseCheck:
    """Exercise: add independent Gaussian noise of ``sigma_m`` to every range; predict CEP50.

    The fixes' RMS error should grow by about ``sigma_m`` × HDOP (added in quadrature to the
    error already there), so CEP50 goes up. Scored on the epochs both settings fixed.

    Returns
    -------
    ExerciseCheck
        Claim "CEP50 higher with noisier ranges"; numbers: CEP50 (m) before and after, RMSE (m)
        before and after, and the first-order prediction of the RMSE after,
        ``sqrt(rmse_before² + (sigma_m · median HDOP)²)``.
    """
    sigma_m = validate.number("sigma_m", sigma_m, minimum=0.0, strict_minimum=True)
    r = _ranges(rec, tag, calibration)
    noisy = r + rng.normal(0.0, sigma_m, size=r.shape)
    common = metrics.score_epochs({"before": _errors(rec, tag, r, tag_height_m).err_m,
                                   "after": _errors(rec, tag, noisy, tag_height_m).err_m})   # the epochs both fixed
    before, after = common["before"].common_m, common["after"].common_m
    hdop = float(np.median(geometry.gdop(rec.truth[tag].pos_m[:, :2], rec.anchors.pos_m, z_m=tag_height_m)))
    rmse_b, rmse_a = metrics.rmse(before), metrics.rmse(after)
    return ExerciseCheck(
        f"CEP50 is higher with {100 * sigma_m:.0f} cm of extra range noise",
        metrics.cep50(after) > metrics.cep50(before),
        {"CEP50 before (m)": metrics.cep50(before), "CEP50 after (m)": metrics.cep50(after),
         "RMSE before (m)": rmse_b, "RMSE after (m)": rmse_a,
         "RMSE after, predicted (m)": float(np.hypot(rmse_b, sigma_m * hdop))},
        ("higher", "not higher"),
        "Independent errors add in quadrature: the RMSE grows to about √(RMSE² + (σ · HDOP)²), the predicted "
        "value among the numbers.")
