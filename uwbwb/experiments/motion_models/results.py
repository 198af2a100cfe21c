"""Notebook 03's results: its methods (the registry's estimators on pseudo-TDoAs, :func:`estimators`), every
estimator's output for one tag-run, held and scored on common epochs by the board
(:class:`~uwbwb.scoreboard.board.Board`), and the ranking of the motion models, beside the thesis' values.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ... import metrics
from ...scoreboard.board import Board
from ...scoreboard.estimators import default_estimators
from ...types import Estimates, TagRun


__all__ = ["LABELS", "MODELS", "METHODS", "PAPER_SIGMA", "PAPER_METHODS_CEP95", "PAPER_MODELS_CEP95", "TagResults",
           "ekf_name", "estimators", "ranking"]

#: Motion models in the thesis' order.
MODELS = ("RW", "RF", "RJ")

#: The thesis' names of the registry's methods where they differ (the board's name → this notebook's).
LABELS = {"TDoA LS": "LS"}


def estimators(*, gate_prob: float | None, ref: int = 0, correlated: bool = True, grids: Mapping | None = None,
               models: Sequence[str] = MODELS) -> dict:
    """This notebook's methods, name → estimator: every estimator of the one registry
    (:func:`~uwbwb.scoreboard.estimators.default_estimators`) that runs on pseudo-TDoAs (``tdoa = True``), the
    EKFs among them with a motion model in ``models``, named as in the thesis (:data:`LABELS`). Each gets, where it
    has that setting, the reference anchor ``ref``, the TDoA covariance (``correlated``), the χ² gate ``gate_prob``
    (None: none), the CEP95 tuning criterion (thesis Table 1) and the driving-σ grid ``grids[model]`` (None: the
    board's)."""
    out = {}
    for e in default_estimators():
        if getattr(e, "tdoa", False) and getattr(e, "model", models[0]) in models:
            have = {f.name for f in fields(e)}
            grid = None if grids is None or "model" not in have else tuple(map(float, grids[e.model]))
            opts = {"gate_prob": gate_prob, "ref": ref, "correlated": correlated, "criterion": "cep95", "grid": grid}
            e = replace(e, **{k: v for k, v in opts.items() if k in have})
            out[LABELS.get(e.name, e.name)] = e
    return out


#: Every estimator of a :class:`TagResults`, in table order: the raw output, then :func:`estimators`.
METHODS = ("raw", *estimators(gate_prob=None))

#: Thesis Table 1: driving-process standard deviation per model and scenario (m/s, m/s², m/s³).
#: The AGV row prints "1 m/" for RW; read as 1 m/s.
PAPER_SIGMA = {"office": {"RW": 0.83, "RF": 1.0, "RJ": 1.0}, "agv": {"RW": 1.0, "RF": 1.0, "RJ": 1.0}}

#: Thesis Tables 2–5 (inputs), CEP95 in metres, one row per (scenario, tag): Tables 2 (office) and 4
#: (AGV) compare EKF (random walk), LS and the raw T4F output; Tables 3 (office) and 5 (AGV) compare the
#: motion models. Table 5 labels its rows "Acq 1 Tag 1, Acq 1 Tag 2, Acq 1 Tag 1, Acq 1 Tag 2"; we read
#: them in order as acquisitions 1 and 2 (the third label repeats a row name; its values differ from the
#: first row). The two tables print different EKF-RW values for AGV tag 1 (acquisition 1: 0.41 and
#: 0.13; acquisition 2: 0.35 and 0.44); each table's own value is used beside that table's rows.
_THESIS_CEP95_M = {
    # (scenario, tag):  Table 2/4: EKF-RW, LS, raw     Table 3/5: EKF-RW, EKF-RF, EKF-RJ
    ("office", "tag1"): ((0.41, 1.02, 1.23), (0.41, 0.77, 1.03)),
    ("office", "tag2"): ((0.48, 1.02, 2.03), (0.48, 1.13, 1.14)),
    ("agv1", "tag1"): ((0.41, 0.77, 1.03), (0.13, 0.25, 0.33)),
    ("agv1", "tag2"): ((0.44, 0.76, 0.61), (0.44, 0.60, 0.58)),
    ("agv2", "tag1"): ((0.35, 0.37, 0.46), (0.44, 0.60, 0.59)),
    ("agv2", "tag2"): ((0.34, 0.45, 0.60), (0.34, 0.34, 0.28)),
}

#: Thesis Tables 2 and 4: CEP95 (m) of EKF (random walk), LS and the raw T4F output.
PAPER_METHODS_CEP95 = {key: dict(zip(("EKF-RW", "LS", "raw"), methods))
                       for key, (methods, _) in _THESIS_CEP95_M.items()}

#: Thesis Tables 3 and 5: CEP95 (m) per motion model.
PAPER_MODELS_CEP95 = {key: dict(zip(("EKF-RW", "EKF-RF", "EKF-RJ"), models))
                      for key, (_, models) in _THESIS_CEP95_M.items()}


def ekf_name(model: str) -> str:
    """Estimator label of the EKF with ``model`` (``"EKF-RW"`` ...), as in :data:`uwbwb.plotting.COLORS`."""
    return f"EKF-{model}"


@dataclass(frozen=True)
class TagResults:
    """Every estimator's output for one :class:`TagRun`, as the board holds and scores it.

    Attributes
    ----------
    run
        The input.
    board
        The run as a :class:`~uwbwb.scoreboard.board.Board` of its one tag (:func:`~.study.estimate`): one entry per
        estimator (``"raw"``, ``"LS"``, ``"EKF-RW"`` ...) with its :class:`~uwbwb.types.Estimates` on the run's
        epochs (NaN where it has no position: LS with too few anchors or no convergence, an EKF before its
        first LS fix) and the truth there, scored by :meth:`~uwbwb.scoreboard.board.Board.scores`
        (:func:`uwbwb.metrics.score_epochs`); its calibration holds the range σ and what each estimator tuned.

    Notes
    -----
    Scoring. Estimators cover different epochs: LS fails at an epoch with too
    few anchors where the EKF coasts on its prediction. CEP95 over each one's own
    epochs would score LS on the easy epochs only, so the tables score every
    estimator on the *common* epochs (those where all of them have a position
    and truth exists, :meth:`common_errors`) and give each one's coverage
    (:meth:`coverage`) beside it.
    """

    run: TagRun
    board: Board

    @property
    def methods(self) -> tuple[str, ...]:
        return self.board.methods

    def estimates(self, name: str) -> Estimates:
        """Estimator ``name``'s output on the run's epochs."""
        return self.board.entry(name, self.run.tag).estimates

    @property
    def scores(self) -> metrics.EpochScores:
        """Every estimator on the run's epochs (:meth:`~uwbwb.scoreboard.board.Board.scores`)."""
        return self.board.scores(self.run.tag)

    def common_errors(self) -> dict[str, np.ndarray]:
        """Name → horizontal errors (m) on the common epochs, the same epochs for every estimator."""
        scores = self.scores
        if scores.methods[0].n_common == 0:
            cov = {k: f"{100 * v:.0f} %" for k, v in self.coverage().items() if k != "common"}
            raise ValueError(f"{self.run.key}: no epoch where every estimator of {list(self.methods)} has a position "
                             f"and truth exists (coverage {cov}); nothing can be scored on common epochs")
        return {n: scores[n].common_m for n in self.methods}

    def cep95(self) -> dict[str, float]:
        """Name → CEP95 (m) on the common epochs."""
        return {k: metrics.cep95(e) for k, e in self.common_errors().items()}

    def coverage(self) -> dict[str, float]:
        """Name → its coverage as the board scores it (:attr:`uwbwb.metrics.MethodEpochs.coverage`: the share of the
        run's epochs with truth where it has a position), and ``"common"``: the share of those the tables score."""
        scores = self.scores
        first = scores.methods[0]
        return {**{m: scores[m].coverage for m in self.methods},
                "common": first.n_common / first.n_epochs if first.n_epochs else np.nan}

    def nis(self) -> pd.DataFrame:
        """NIS consistency per filter (every method with a NIS) over its updates at its scored epochs (truth and a
        position: the board's NIS, :meth:`~uwbwb.scoreboard.board.Entry.scored`; :func:`uwbwb.metrics.nis_consistency`).

        Under right noise models the NIS summed over the ``n`` updates is χ² with
        ``sum_dof`` degrees of freedom; the verdict compares it with the central
        95 % interval of that χ² (``mean_lo``, ``mean_hi``: the interval divided
        by ``sum_dof``, around a mean NIS per degree of freedom of 1).
        *Over-confident*: errors larger than the filter's covariance says.
        """
        rows = []
        for m in self.methods:
            entry = self.board.entry(m, self.run.tag)
            est = entry.estimates
            if "nis" not in est.info:
                continue
            c = metrics.nis_consistency(est.info["nis"][entry.scored], np.asarray(est.info["dof"])[entry.scored])
            dof = max(c["sum_dof"], 1)
            rows.append({"method": m, "n": c["n"], "mean_nis_over_dof": c["mean_nis_over_dof"],
                         "mean_lo": c["sum_lo"] / dof, "mean_hi": c["sum_hi"] / dof,
                         "fraction_inside": c["fraction_inside"], "verdict": c["verdict"],
                         "n_rejected": int(np.sum(est.info.get("n_rejected", 0)))})
        return pd.DataFrame(rows).set_index("method")


def ranking(table: pd.DataFrame, models: Sequence[str] = MODELS, *, decimals: int = 3,
            better: Mapping | None = None) -> pd.Series:
    """Order of the motion models by CEP95 per row, e.g. ``"RW < RF < RJ"``, resolved no further than its evidence
    (:func:`uwbwb.metrics.tied_ranks`: ``<`` between two ranks, a tie inside one).

    Without ``better`` (one run, or the thesis' numbers: no interval) a model is better than another where its value
    rounded to ``decimals`` (as the table prints it) is lower; values equal there tie (``"RF = RW < RJ"``). With
    ``better`` (row label → the pairs ``(A, B)`` whose verdict says A is better, e.g.
    :meth:`~.seeds.SeedStudy.ranking`) the models are sorted by value and tie as ``≈`` where the verdicts leave the
    order undecided; a decided pair inside a tie is added in brackets (``"RF ≈ RW ≈ RJ (RF < RJ)"``)."""
    cols = [ekf_name(m) for m in models]
    short = dict(zip(cols, models))
    tie = "=" if better is None else "≈"

    def order(row):
        values = np.round(row[cols].to_numpy(float), decimals)
        names = [c for _, c in sorted(zip(values, cols))]
        won = better[row.name] if better is not None else {
            (a, b) for a, va in zip(cols, values) for b, vb in zip(cols, values) if va < vb}
        rank = metrics.tied_ranks(names, won)
        chain = short[names[0]] + "".join(f" {'<' if rank[b] > rank[a] else tie} {short[b]}"
                                          for a, b in zip(names, names[1:]))
        extra = [f"{short[a]} < {short[b]}" for a in names for b in names if (a, b) in won and rank[a] == rank[b]]
        return chain + (f" ({', '.join(extra)})" if extra else "")

    return table.apply(order, axis=1).rename("ranking")
