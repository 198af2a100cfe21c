"""Exercises of notebook 02 ("change X, predict Y").

Each exercise runs both settings on the same simulated packets (or the same simulator seed) and
returns a :class:`uwbwb.widgets.ExerciseCheck`: the direction to predict, whether this run shows
it, the numbers. The reasoning is the check's ``why``, shown
once the student has predicted; ``TEACHING.md`` gives one run's numbers.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ... import validate
from ...sim import tours as tours_mod
from ...types import Recording
from ...widgets import ExerciseCheck
from .study import SyntheticConfig, run_tour

__all__ = ["no_nlos", "pruning_off"]


def _stop_medians(rec: Recording, truth: tours_mod.TourTruth, config: SyntheticConfig, node: str,
                  heuristics) -> pd.Series:
    """Median horizontal stop error (m) per heuristic on one recording and node (no point-based baseline)."""
    stops, _, _ = run_tour(rec, truth, dataclasses.replace(config, point_baseline=False, kinds=("stop",)),
                           tags=[node], heuristics=list(heuristics))
    return pd.DataFrame(stops).groupby("heuristic")["err_m"].median()


def pruning_off(rec: Recording, truth: tours_mod.TourTruth, config: SyntheticConfig, *, node: str = "H",
                retention: float = 1.0) -> ExerciseCheck:
    """Exercise: residual pruning's retention from the run's value to ``retention`` (1.0: nothing pruned).

    Residual pruning drops the ranges with the largest residuals; under NLOS those are mostly the
    ranges with a positive excess. Keeping every range (retention 1.0) leaves eq. (1) with the
    NLOS ranges, so the stop estimates move away from the truth: the median stop error rises
    (at 1.0 it equals plain NLS's, which the check reports beside). Same packets for both.

    Parameters
    ----------
    rec, truth
        One simulated experiment (:func:`uwbwb.sim.tours.simulate_tour`, or the run's own).
    config
        The run's configuration (its ``pruning.res_retention`` is the first setting).
    node
        Blind node whose stops are scored.
    retention
        The second setting of the retention, in (0, 1].

    Returns
    -------
    ExerciseCheck
        Claim "the median stop error is higher at ``retention``"; numbers: median stop error (m)
        at both retentions and with plain NLS.
    """
    retention = validate.number("retention", retention, minimum=0.0, maximum=1.0, strict_minimum=True)
    base = config.pruning.res_retention
    other = dataclasses.replace(config, pruning=dataclasses.replace(config.pruning, res_retention=retention))
    on = _stop_medians(rec, truth, config, node, ("residual", "none"))
    off = _stop_medians(rec, truth, other, node, ("residual",))
    return ExerciseCheck(
        f"{rec.name}, node {node}: residual pruning at retention {retention:g} has a higher median stop error "
        f"than at {base:g}",
        off["residual"] > on["residual"],
        {f"retention {base:g} (m)": float(on["residual"]), f"retention {retention:g} (m)": float(off["residual"]),
         "plain NLS (m)": float(on["none"])},
        ("up", "not up"),
        "At retention 1 residual pruning drops no range: it is plain NLS (compare the numbers), which the long "
        "NLOS ranges pull away from the stop.")


def no_nlos(config: SyntheticConfig, *, tour: int = 2, pace: str = "fast", node: str = "H",
            seed: int) -> ExerciseCheck:
    """Exercise: remove the NLOS excess from the simulated ranges; predict the 5th percentile against plain NLS.

    The 5th percentile of an anchor's ranges over a stop is the range least lifted by NLOS, so
    with NLOS it beats plain NLS. Without NLOS the errors are symmetric around the per-pair bias
    and the 5th percentile is short by about 1.6 σ on every anchor: it now *loses* to plain NLS.
    Both tours are drawn with the same seed (same route and LOS noise model), one with
    ``p_nlos_in = p_nlos_out = 0``.

    Returns
    -------
    ExerciseCheck
        Claim "the 5th percentile beats plain NLS with NLOS and loses to it without"; numbers:
        median stop error (m) of both, with and without NLOS.
    """
    seed = validate.integer("seed", seed, minimum=0)
    out = {}
    for name, scale in (("with NLOS", None), ("without NLOS", 0.0)):
        tcfg = dataclasses.replace(config.tour, tour=tour, pace=pace)
        if scale is not None:
            tcfg = dataclasses.replace(tcfg, p_nlos_in=scale, p_nlos_out=scale)
        rec, truth = tours_mod.simulate_tour(tcfg, rng=np.random.default_rng(seed))
        out[name] = _stop_medians(rec, truth, config, node, ("none", "percentile"))
    w, wo = out["with NLOS"], out["without NLOS"]
    return ExerciseCheck(
        f"tour {tour}, {pace}, node {node}: the 5th percentile beats plain NLS with NLOS and loses to it without",
        w["percentile"] < w["none"] and wo["percentile"] > wo["none"],
        {"with NLOS, plain NLS (m)": float(w["none"]), "with NLOS, 5th percentile (m)": float(w["percentile"]),
         "without NLOS, plain NLS (m)": float(wo["none"]),
         "without NLOS, 5th percentile (m)": float(wo["percentile"])},
        ("it loses without NLOS", "it does not lose without NLOS"),
        "The 5th percentile keeps the shortest ranges: a correction where NLOS makes ranges long, a bias of its own "
        "where they are not.")
