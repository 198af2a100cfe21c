"""What the notebooks show of the Hanyang dynamic runs: one function per notebook section.

Each takes the case(s) by parameter, runs on any tree of the upstream layout, returns a
:class:`Section` (its tables and boards; the text around them is the notebook's) and its headline
rows, which :meth:`Section.record` adds to the notebook's :class:`~uwbwb.metrics.Summary` with
``data = hanyang-outdoor-uwb/<case>``. A dataset or dynamic part that is absent gives a
section with ``absent`` set (the notebook prints it); a case *name* that a present dataset does
not hold is an error.

* :func:`scoreboard_section` (notebook 06): the authors' numbers reproduced, a board per case
  (their LS/ESKF as external rows), ours / theirs per case, the method declared before scoring
  against their LS and ESKF (:func:`~.study.declared_method_table`), the static range
  model's effect, and each board's methods against the common bound and their own bounds
  (:func:`~uwbwb.scoreboard.verdicts.placement_table`, :func:`~uwbwb.scoreboard.verdicts.own_bound_table`).
  Every comparison of two methods is a row of :func:`~uwbwb.scoreboard.verdicts.difference_table`, whose summary
  rows (in every section) say "(epochs both covered)" and, where its verdict is edge-bound, :data:`EDGE_BOUND_LABEL`;
* :func:`pruning_section` (notebook 02): NLS with and without the pruning heuristics of paper 001
  on one case (NLOS is the point), each against plain NLS;
* :func:`motion_section` (notebook 03): the RW/RF/RJ motion models on ranges (and the TDoA EKF of
  notebook 03, which does not run where the 4-anchor cluster leaves the TDoAs uninformative), each against raw LS.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ...datasets import dataset_available, hanyang_dynamic
from ...errors import DataNotFoundError
from ...metrics import interval_rows
from ...scoreboard import Board
from ...scoreboard.estimators import RawLs, default_estimators
from ...scoreboard.setnoise_nls import NLS_WINDOWS_S, WindowNls
from ...scoreboard.verdicts import EDGE_BOUND_LABEL, difference_table, edge_bound, own_bound_table, placement_table
from . import authors, estimators, study

__all__ = ["BOTH", "EXTERNAL", "Section", "motion_section", "pruning_section", "scoreboard_section"]

PathLike = str | os.PathLike
NAME = hanyang_dynamic.NAME
#: Data label suffix of rows that are numbers of the authors' estimates (their LS.csv / ESKF.csv): *external*.
EXTERNAL = " (external: authors' estimates)"
#: The words of every row of a pair (a ratio, or one side's RMSE_2d) on the epochs both methods covered.
BOTH = "epochs both covered"


@dataclass(frozen=True)
class Section:
    """One notebook section's results.

    Attributes
    ----------
    absent
        Why the section did not run (dataset or dynamic part absent), else None.
    tables
        The tables the notebook displays, by name (the text around them is the notebook's).
    boards
        Per case, its board.
    facts
        What the section chose (cases, tuning cases, picks).
    rows
        Headline numbers for the notebook's summary (keyword arguments of
        :meth:`~uwbwb.metrics.Summary.add`); :meth:`record` adds them.
    """

    absent: str | None = None
    tables: Mapping[str, pd.DataFrame] = field(default_factory=dict)
    boards: Mapping[str, Board] = field(default_factory=dict)
    facts: Mapping[str, object] = field(default_factory=dict)
    rows: tuple[dict, ...] = ()

    def record(self, summary) -> None:
        """Add :attr:`rows` to a :class:`~uwbwb.metrics.Summary` (nothing when the section did not run)."""
        for row in self.rows:
            summary.add(**row)


def _cases(data_dir, wanted: Sequence[str] | None) -> tuple[list[str], list[str] | None, str | None]:
    """``(available, chosen, absent_reason)``; a wanted name that is not present raises."""
    if not dataset_available(NAME, data_dir):
        return [], None, f"{NAME} was not found (set DATA_DIR or fetch it): section skipped"
    available = hanyang_dynamic.dynamic_cases(data_dir)
    if not available:
        return [], None, f"{NAME} has no Dynamic_measurements cases here: section skipped"
    if len(available) < 2:
        return available, None, (f"{NAME} holds one dynamic case only ({available[0]}): every board is tuned on "
                                 f"another case, so the section is skipped")
    if wanted is None:
        return available, None, None
    missing = [c for c in wanted if c not in available]
    if missing:
        raise DataNotFoundError(f"{NAME} has no dynamic case {missing}; cases present: {available}")
    return available, list(wanted), None


def scoreboard_section(cases: Sequence[str] | None = None, data_dir: PathLike | None = None, *, fast: bool,
                       seed: int = 0) -> Section:
    """Notebook 06's Hanyang section: reproduction, boards, ours / theirs per case, static model.

    ``cases`` None: every case present (FAST: the first only); named cases run as named, FAST
    included. Each board is tuned on :func:`~.study.tuning_case`, and per tuning case the method set
    against the authors is picked there (:func:`~.study.pick_on_tuning_case`). Checks (raise
    AssertionError): the recomputed authors' numbers agree with ``RMSD_results.txt`` within
    :data:`~.authors.REPRO_TOL_M` where it exists; the authors' LS was scored on every board.
    """
    available, chosen, absent = _cases(data_dir, cases)
    if absent:
        return Section(absent=absent)
    chosen = chosen or (available[:1] if fast else available)     # none named: every case (FAST: the first)
    models = []
    for cond in ("LOS", "NLOS"):
        try:
            models.append(estimators.static_range_model(cond, data_dir))
        except (DataNotFoundError, ValueError):
            pass
    repro = pd.concat([authors.reproduce_authors(c, data_dir) for c in chosen], ignore_index=True)
    assert not (repro["verdict"] == "DISAGREE").any(), (
        f"the authors' recomputed RMSEs differ from RMSD_results.txt by more than {authors.REPRO_TOL_M} m:\n{repro}")
    boards, tuning, picks = {}, {}, {}
    for c in chosen:
        tuning[c] = study.tuning_case(c, available)
        boards[c] = study.case_board(c, tuning[c], data_dir, fast=fast, static_models=models)
        if tuning[c] not in picks:
            picks[tuning[c]] = study.pick_on_tuning_case(tuning[c], data_dir, fast=fast, static_models=models)[0]
        scored = boards[c].table().set_index("method").loc[study.THEIRS, "n_scored"]
        assert scored > 0, f"{c}: the authors' LS was not scored"
    ratios = study.ratio_table(boards, picks={c: picks[t] for c, t in tuning.items()}, seed=seed)
    static = [m.name for m in map(estimators.static_model_ls, models)]
    effect = difference_table({b.label: b for b in boards.values()},
                              [(m, ref) for m in static for ref in ("raw LS", "LS")], seed=seed)
    declared = study.declared_method_table(boards, seed=seed)
    rows = []
    for r in repro[repro["metric"] == "RMSE 2-D"].itertuples(index=False):
        if np.isfinite(r.published_m):
            rows.append(dict(quantity=f"authors {r.method} RMSE_2d, published", value=r.published_m, unit="m",
                             data=r.data + EXTERNAL, kind="input"))
        rows.append(dict(quantity=f"authors {r.method} RMSE_2d, recomputed (their definition)", value=r.reproduced_m,
                         unit="m", data=r.data + EXTERNAL, kind="input",
                         paper_value=r.published_m if np.isfinite(r.published_m) else None))
    theirs_added = set()
    for pick, what in (("best", "best on the scored case"), ("chosen", "picked on the tuning case")):
        for r in (ratios[ratios[pick]] if len(ratios) else ratios).to_dict("records"):
            data = r["recording"]
            rows.append(dict(quantity=f"RMSE_2d, our ranges-only method {what} ({r['A']}; {BOTH} with authors LS)",
                             value=r["RMSE A (m)"], unit="m", data=data, kind="reproduced"))
            if (data, r["A"]) not in theirs_added:
                theirs_added.add((data, r["A"]))
                rows.append(dict(quantity=f"RMSE_2d, authors LS ({BOTH} with {r['A']})", value=r["RMSE B (m)"],
                                 unit="m", data=data + EXTERNAL, kind="input"))
            rows += _ratio_rows(f"RMSE_2d ratio ours ({what}) / authors LS", r, data)
    per_case = declared[~declared["case"].str.startswith("mean over")]
    for r in declared.to_dict("records"):
        theirs, mean = r["B"].split(" (")[0], r["case"].startswith("mean over")
        edge = per_case.loc[per_case["B"] == r["B"], "verdict"].map(edge_bound)   # the cases' verdicts
        rows += _ratio_rows(f"RMSE_2d ratio ours (declared before scoring: {r['A']}) / {theirs}"
                            + (", mean over the cases scored" if mean else ""), r,
                            f"{NAME}/{r['case'].split()[-2]} cases" if mean else r["recording"],
                            edge=f"{EDGE_BOUND_LABEL} of {edge.sum()} of {edge.size} cases"
                            if mean and edge.any() else None)
    tables = {"reproduction": repro, "ratios": ratios, "declared": declared, "static_effect": effect,
              "static_models": pd.DataFrame(map(dataclasses.asdict, models)),
              "placement": placement_table(boards), "own_bound": own_bound_table(boards)}
    return Section(None, tables, boards, {"tuning": tuning, "picks": picks}, tuple(rows))


def _ratio_rows(quantity: str, r: Mapping, data: str, *, edge: str | None = None) -> list[dict]:
    """Summary rows of one difference-table row's ratio A / B with its interval's ends (the table's own), labelled
    with the table's qualifiers: "(epochs both covered)", and :data:`EDGE_BOUND_LABEL` where the row's verdict is
    edge-bound (``edge``: the qualifier of a row without a verdict of its own, e.g. a mean over cases)."""
    edge = edge or (EDGE_BOUND_LABEL if edge_bound(r.get("verdict", "")) else None)
    return interval_rows(f"{quantity} ({BOTH}{'; ' + edge if edge else ''})", r["A / B"],
                         r.get("A / B 95 % low", np.nan), r.get("A / B 95 % high", np.nan), unit="", data=data,
                         kind="reproduced")


def _case_pairs(case: str | None, data_dir, prefer: str, estimators: list, authors: tuple, pairs: list, *,
                fast: bool, seed: int) -> tuple[str | None, str | None, str | None, Board | None, pd.DataFrame | None]:
    """One case (None: the first of condition ``prefer``) on a board of ``estimators`` and the authors' ``authors``
    rows, tuned on :func:`~.study.tuning_case`, and the :func:`~uwbwb.scoreboard.verdicts.difference_table` of
    ``pairs`` on it: ``(absent, case, tuning case, board, table)``, all but ``absent`` None where it is set."""
    available, chosen, absent = _cases(data_dir, None if case is None else [case])
    if absent:
        return absent, None, None, None, None
    case = chosen[0] if chosen else ([c for c in available if c.startswith(prefer + "/")] or available)[0]
    tune = study.tuning_case(case, available)
    board = study.case_board(case, tune, data_dir, fast=fast, estimators=estimators, authors=authors)
    return None, case, tune, board, difference_table({board.label: board}, pairs, seed=seed)


def pruning_section(case: str | None = None, data_dir: PathLike | None = None, *, fast: bool,
                    seed: int = 0) -> Section:
    """Notebook 02's Hanyang section: NLS with the pruning heuristics on one case (default the first NLOS
    case), tuned (window length, range calibration, tag height) on :func:`~.study.tuning_case`.

    Rows: raw LS, NLS (no pruning), NLS with residual pruning, NLS with the robust mean, the authors' LS
    (external); each pruned NLS against plain NLS (and against the authors' LS) on the epochs both covered,
    a row of :func:`~uwbwb.scoreboard.verdicts.difference_table` whose ratio (and its interval's ends) the summary
    row labelled "(epochs both covered)" is (with :data:`EDGE_BOUND_LABEL` where its verdict is edge-bound); each method's
    RMSE_2d row is the board's, on the scored epochs it covered ("(epochs it covered)"), its coverage of the
    scored epochs beside it: where coverages differ, the quotient of two RMSE rows is not the ratio row.
    """
    windows = (1.0,) if fast else NLS_WINDOWS_S
    nls = WindowNls(windows_s=windows)
    est = [RawLs(), nls, estimators.PrunedNls(windows_s=windows, heuristic="residual", fits=nls.fits),
           estimators.PrunedNls(windows_s=windows, heuristic="robust_mean")]
    pairs = [("NLS residual pruning", "NLS"), ("NLS robust mean", "NLS"), ("NLS", "raw LS"),
             ("NLS residual pruning", study.THEIRS), ("NLS robust mean", study.THEIRS)]
    absent, case, tune, board, table = _case_pairs(case, data_dir, "NLOS", est, ("LS",), pairs, fast=fast, seed=seed)
    if absent:
        return Section(absent=absent)
    rows = [x for r in table.to_dict("records") for x in _ratio_rows(f"RMSE_2d ratio {r['A']} / {r['B']}", r,
                                                                      board.label)]
    for r in board.table().itertuples(index=False):
        if np.isfinite(r.rmse_m):          # the authors' LS is an outside method's number: input, data marked external
            ext = r.method in board.external
            row = dict(unit="", data=board.label + (EXTERNAL if ext else ""), kind="input" if ext else "reproduced")
            rows.append(dict(row, quantity=f"RMSE_2d, {r.method} (epochs it covered)", value=r.rmse_m, unit="m"))
            if np.isfinite(r.coverage):
                rows.append(dict(row, quantity=f"epoch coverage, {r.method} (share of the scored epochs)",
                                 value=r.coverage))
    return Section(None, {"ablation": table}, {case: board}, {"case": case, "tuned_on": tune}, tuple(rows))


def motion_section(case: str | None = None, data_dir: PathLike | None = None, *, fast: bool,
                   seed: int = 0) -> Section:
    """Notebook 03's Hanyang section: the motion models on one case (default the first LOS case), tuned on
    :func:`~.study.tuning_case`: the board's EKF-RW/RF/RJ on the ranges and its TDoA EKF-RF of notebook 03 (which
    does not run where the 4-anchor cluster leaves the TDoAs uninformative: its row's note gives the numbers), raw
    LS and the authors' ESKF (external, IMU-aided); each EKF that ran against raw LS, a row of
    :func:`~uwbwb.scoreboard.verdicts.difference_table` with its tuned ``sigma_w``. The EKFs are the board's
    (:func:`~uwbwb.scoreboard.estimators.default_estimators`, FAST grids in FAST)."""
    board_est = {e.name: e for e in default_estimators(fast=fast)}
    names = ["EKF-RF", "EKF-RW ranges", "EKF-RF ranges", "EKF-RJ ranges"]
    absent, case, tune, board, table = _case_pairs(case, data_dir, "LOS", [board_est[m] for m in ("raw LS", *names)],
                                                   ("ESKF",), [(m, "raw LS") for m in names], fast=fast, seed=seed)
    if absent:
        return Section(absent=absent)
    table["sigma_w"] = [board.calibration.params(m).get("sigma_w", np.nan) for m in table["A"]]
    rows = []
    for r in table.to_dict("records"):
        rows.append(dict(quantity=f"RMSE_2d, {r['A']} ({BOTH} with raw LS)", value=r["RMSE A (m)"], unit="m",
                         data=board.label, kind="reproduced"))
        rows += _ratio_rows(f"RMSE_2d ratio {r['A']} / raw LS", r, board.label)
    return Section(None, {"models": table}, {case: board}, {"case": case, "tuned_on": tune}, tuple(rows))
