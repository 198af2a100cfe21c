"""Computed sentences of notebook 03: ``*_facts(...) -> dict`` (tested) and a short template each.

:func:`tuning_criterion_facts` explains why notebook 03 and the scoreboard (notebook 06) can report
different driving-noise values σ_w for the same EKF on the same recording: 03 picks the σ_w of its
grid with the lowest mean CEP95 over the tags, the scoreboard the one with the lowest mean RMSE.
Both scores come out of the same calibration sweep (:func:`.study.calibration_curves` keeps both),
so the effect of the criterion alone can be read off 03's own curves.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...models.motion import MOTION_MODELS

__all__ = ["FLAT_REL", "tuning_criterion_facts", "tuning_criterion_sentence"]

#: Two σ_w values count as equally good when their mean scores differ by less than this fraction.
FLAT_REL = 0.02


def tuning_criterion_facts(curves: pd.DataFrame, model: str) -> dict:
    """Best σ_w of ``model`` under each tuning criterion, from one calibration sweep.

    Parameters
    ----------
    curves
        :func:`~.study.calibration_curves` rows (``model, sigma, cep95_m, rmse_m`` per run/tag).
    model
        ``"RW"``, ``"RF"`` or ``"RJ"``.

    Returns
    -------
    dict
        ``model``, ``unit``, ``n_grid`` (grid points), ``by_cep95`` and ``by_rmse`` (σ_w picked by
        the mean CEP95 and by the mean RMSE over the runs/tags), ``same`` (both pick the same),
        ``cep95_m`` and ``rmse_m`` (mean scores at the two picks, ``{σ_w: metres}``), ``adjacent``
        (the picks are neighbours on the grid), ``flat`` (each criterion scores the other's pick within
        :data:`FLAT_REL` of its own).

    Raises
    ------
    ValueError
        No rows for ``model``.
    """
    sub = curves[curves["model"] == model]
    if sub.empty:
        raise ValueError(f"model: no calibration rows for {model!r}; have {sorted(set(curves['model']))}")
    mean = sub.groupby("sigma", sort=True)[["cep95_m", "rmse_m"]].mean()
    grid = mean.index.to_numpy(float)
    by_cep, by_rmse = float(mean["cep95_m"].idxmin()), float(mean["rmse_m"].idxmin())
    picks = (by_cep, by_rmse)
    cep = {s: float(mean.loc[s, "cep95_m"]) for s in picks}
    rmse = {s: float(mean.loc[s, "rmse_m"]) for s in picks}
    i, j = (int(np.flatnonzero(grid == s)[0]) for s in picks)
    flat = cep[by_rmse] <= (1 + FLAT_REL) * cep[by_cep] and rmse[by_cep] <= (1 + FLAT_REL) * rmse[by_rmse]
    return {"model": model, "unit": MOTION_MODELS[model].sigma_unit, "n_grid": int(grid.size), "by_cep95": by_cep,
            "by_rmse": by_rmse, "same": by_cep == by_rmse, "cep95_m": cep, "rmse_m": rmse, "adjacent": abs(i - j) == 1,
            "flat": bool(flat)}


def tuning_criterion_sentence(f: dict, data: str) -> str:
    """Markdown from :func:`tuning_criterion_facts` on the calibration sweep of ``data``."""
    m, u = f["model"], f["unit"]
    head = (f"**Why notebook 06 can report another σ_w for EKF-{m} on {data}.** This notebook keeps the σ_w with the "
            f"lowest mean CEP95 over the tags; the scoreboard (06) keeps the one with the lowest mean RMSE. ")
    if f["same"]:
        return head + (f"On this sweep's {f['n_grid']}-point grid both criteria pick {f['by_cep95']:.3g} {u}: the "
                       "criterion makes no difference here (where the minimum is flat a finer grid can separate them); "
                       "the other settings that differ between the notebooks are the χ² gate and the range calibration.")
    a, b = f["by_cep95"], f["by_rmse"]
    where = "neighbouring points" if f["adjacent"] else "different points"
    verdict = ("the minimum is flat: either value is as good, and the criterion alone moves the pick"
               if f["flat"] else "the two criteria disagree by more than "
               f"{100 * FLAT_REL:g} %: the choice of criterion matters here")
    return head + (f"On this sweep's own curves CEP95 picks {a:.3g} {u} and RMSE picks {b:.3g} {u}, {where} of the "
                   f"same {f['n_grid']}-point grid. CEP95 is {100 * f['cep95_m'][a]:.2f} cm at {a:.3g} and "
                   f"{100 * f['cep95_m'][b]:.2f} cm at {b:.3g}; RMSE {100 * f['rmse_m'][a]:.2f} cm and "
                   f"{100 * f['rmse_m'][b]:.2f} cm: {verdict}.")
