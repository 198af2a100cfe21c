"""Notebook 05's ablation read-outs: the ingredient ladder (paired ratios on the epochs both rows
cover), the mismatch table and where eq. 4 fires in the ablation's geometry."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ...models.ranging import predict_ranges
from ...sim import robot
from .ablation import COVERAGE, LADDER, ROWS, ratio_ci

if TYPE_CHECKING:
    from .ablation import AblationConfig, AblationResult

__all__ = ["pair_rmse", "ladder_table", "mismatch_table", "eq4_path", "eq4_thresholds"]


def pair_rmse(res: AblationResult, step: str, metric: str, case: str = "matched", prob: float = 0.95) -> dict:
    """:func:`ratio_ci` of a :data:`LADDER` step (without / with) on ``metric``, both rows scored on
    the epochs both cover (``res.pairs``), with ``both_cov`` (mean share of the scored epochs both
    cover). Without a pairs table, the per-row scores (:meth:`AblationResult.ratio`)."""
    _, a, b = next(x for x in LADDER if x[0] == step)
    p = res.pairs
    if p.empty:
        return {**res.ratio(a, b, metric, case, prob), "both_cov": np.nan}
    p = p[(p["case"] == case) & (p["step"] == step) & (p["metric"] == metric)]
    r = ratio_ci(p["num"].to_numpy(), p["den"].to_numpy(), prob=prob)
    return {**r, "both_cov": float(p["both_cov"].mean()) if len(p) else np.nan}


def ladder_table(res: AblationResult, case: str = "matched",
                 metrics: Sequence[str] = ("static_rmse", "dyn_rmse", "outage_max")) -> pd.DataFrame:
    """Ratio (without / with the ingredient) and its 95 % interval for every step of :data:`LADDER`,
    each scored on the epochs both rows cover (:func:`pair_rmse`), with each row's own coverage
    (``cov without``, ``cov with``: mean over seeds) and the share both cover (``cov both``)."""
    t = res.table(case)
    rows = {}
    for what, a, b in LADDER:
        row = {}
        for m in metrics:
            r = pair_rmse(res, what, m, case)
            row[(m, "ratio")], row[(m, "lo")], row[(m, "hi")] = r["ratio"], r["lo"], r["hi"]
            row[(m, "cov without")], row[(m, "cov with")] = t.loc[a, COVERAGE[m]], t.loc[b, COVERAGE[m]]
            row[(m, "cov both")] = r["both_cov"]
        rows[what] = row
    t = pd.DataFrame(rows).T
    t.columns = pd.MultiIndex.from_tuples(t.columns)
    return t


def eq4_path(cfg: AblationConfig) -> np.ndarray:
    """Tag positions ``(P, 3)`` of the ablation's runs (m): its dynamic path every 0.1 s and the
    static point, at the tag height — where :func:`eq4_thresholds` is evaluated."""
    motion = robot.broken_line(robot.PAPER_WAYPOINTS_M[: cfg.legs + 1])
    path = motion.state(np.arange(0.0, motion.duration_s, 0.1))[0]
    h = cfg.model.tag_height_m
    path = np.column_stack([path[:, :2], np.full(len(path), h)])
    return np.vstack([path, [*robot.PAPER_STATIC_M, h]])


def eq4_thresholds(model: robot.RobotConfig, pos_m: np.ndarray, c_m: float) -> pd.DataFrame:
    """The smallest multipath excess that makes eq. 4 fire, per TDoA pair, over positions ``pos_m``.

    Eq. 4 flags ``|r_j − r_ref| > ‖a_j − a_ref‖ − C``. An excess ``e ≥ 0`` on station ``j`` raises
    ``r_j − r_ref`` and fires once ``e > ‖a_j − a_ref‖ − C − (r_j − r_ref)``; an excess on the
    reference lowers it and fires once ``e > ‖a_j − a_ref‖ − C + (r_j − r_ref)``. Returns per pair
    the baseline and the minimum over the positions of either threshold (m).
    """
    a = np.asarray(model.stations_m, float)
    p = np.atleast_2d(np.asarray(pos_m, float))
    r = predict_ranges(p, a)
    ref = model.reference
    rows = {}
    for j in range(len(a)):
        if j == ref:
            continue
        base = float(np.linalg.norm(a[j] - a[ref]))
        d = r[:, j] - r[:, ref]
        rows[f"BS{j + 1} − BS{ref + 1}"] = {"baseline (m)": base,
                                            "min excess on the station (m)": float(np.min(base - c_m - d)),
                                            "min excess on the reference (m)": float(np.min(base - c_m + d))}
    return pd.DataFrame(rows).T


def mismatch_table(res: "AblationResult", metric: str = "outage_max") -> pd.DataFrame:
    """Mean of ``metric`` over seeds, one row per case, one column per row of the ablation (m)."""
    t = res.scores.groupby(["case", "method"])[metric].mean().unstack("method")
    cols = [r for r in ROWS if r in t.columns and (r == "LS" or r.endswith("+ gate"))]
    return t.loc[[c for c in res.config.cases if c in t.index], cols]
