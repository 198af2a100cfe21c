"""What the notebooks show of the Hanyang dynamic runs: one function per notebook section.

Each takes the case(s) by parameter, runs on any tree of the upstream layout, returns a
:class:`Section` (its tables and boards; the text around them is the notebook's) and records the
headline numbers into the notebook's :class:`~uwbwb.metrics.Summary` with
``data = hanyang-outdoor-uwb/<case>``. A dataset or dynamic part that is absent gives a
section with ``absent`` set (the notebook prints it); a case *name* that a present dataset does
not hold is an error.

* :func:`scoreboard_section` (notebook 06): the authors' numbers reproduced, a board per case
  (their LS/ESKF as external rows), the summary ours / theirs across cases, the method declared before scoring
  against their LS and ESKF (:func:`~.study.declared_method_table`), the static range
  model's effect, and each board's methods against the common bound and their own bounds
  (:func:`~uwbwb.scoreboard.verdicts.placement_table`, :func:`~uwbwb.scoreboard.verdicts.own_bound_table`);
* :func:`pruning_section` (notebook 02): NLS with and without the pruning heuristics of paper 001
  on one case (NLOS is the point), each against plain NLS with a bootstrap interval;
* :func:`motion_section` (notebook 03): the RW/RF/RJ motion models on ranges (and the TDoA EKF of
  notebook 03, which does not run where the 4-anchor cluster leaves the TDoAs uninformative), each against raw LS.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ...datasets import dataset_available, hanyang_dynamic
from ...errors import DataNotFoundError
from ...scoreboard import Board
from ...scoreboard.estimators import RawLs, default_estimators
from ...scoreboard.setnoise_nls import NLS_WINDOWS_S, WindowNls
from ...scoreboard.verdicts import own_bound_table, placement_table
from . import authors, estimators, facts, study
from .pairs import ablation

__all__ = ["BOARD_COLUMNS", "Section", "board_table", "motion_section", "pruning_section",
           "scoreboard_section"]

PathLike = str | os.PathLike
NAME = hanyang_dynamic.NAME


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
        The numbers behind the verdict table.
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


class _Rows:
    """Collects summary rows (and adds them to a summary at once when one is given)."""

    def __init__(self, summary=None):
        self.summary, self.rows = summary, []

    def add(self, **row) -> None:
        self.rows.append(row)
        if self.summary is not None:
            self.summary.add(**row)


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


#: The board columns a section shows (:func:`board_table`): errors, the common bound as on every board of notebook
#: 06 (one per recording, :mod:`uwbwb.scoreboard.reference`) and on the common epochs, the own bound with its
#: geometry factor and the check at the measured noise, the tuning pick, the time and the note.
BOARD_COLUMNS = ("method", "coverage", "n_scored", "rmse_m", "cep95_m", "rmse_common_m", "common_bound_m",
                 "rmse_over_common", "rmse_over_common_se", "common_bound_common_m", "rmse_common_over_common",
                 "bound_m", "bound_kind", "rmse_over_bound", "rmse_over_bound_se", "rmse_over_bound_measured",
                 "bound_over_ranges_crlb", "bias_share", "us_per_epoch", "tuning_pick", "note")


def board_table(board: Board) -> pd.DataFrame:
    """The columns of ``board`` a section shows (:data:`BOARD_COLUMNS`; horizontal errors, m; coverage = share of
    scored epochs with a position), one row per method."""
    df = board.table()
    cols = [c for c in BOARD_COLUMNS if c in df]
    return df[cols].set_index("method")


# --------------------------------------------------------------------------------------------
# notebook 06
# --------------------------------------------------------------------------------------------

def scoreboard_section(cases: Sequence[str] | None = None, data_dir: PathLike | None = None, *, fast: bool,
                       summary=None, seed: int = 0, progress: bool = False) -> Section:
    """Notebook 06's Hanyang section: reproduction, boards, ours / theirs across cases, static model.

    ``cases`` None: every case present (FAST: the first only); named cases run as named, FAST
    included. Each board is tuned on
    :func:`~.study.tuning_case`. Checks (raise AssertionError): the recomputed authors' numbers agree
    with ``RMSD_results.txt`` within :data:`~.facts.REPRO_TOL_M` where it exists; every board's
    coverage lies in [0, 1]; the external rows were scored.
    """
    available, chosen, absent = _cases(data_dir, cases)
    if absent:
        return Section(absent=absent)
    if not chosen:                   # none named: every case present (FAST: the first); named cases run as named
        chosen = available[:1] if fast else available
    comp = study.compare_cases(chosen, data_dir, fast=fast, seed=seed, progress=progress)
    repro_f = facts.reproduction_facts(comp.reproduction)
    assert repro_f["n_published"] == 0 or repro_f["agree"], (
        f"the authors' recomputed RMSEs differ from RMSD_results.txt by up to {repro_f['max_abs_diff_m']:.4f} m "
        f"(rule: within {repro_f['tol_m']} m)")
    for case, b in comp.boards.items():
        df = b.table().set_index("method")
        assert df["coverage"].between(0, 1).all(), case
        assert df.loc[authors.AuthorsEstimator("LS").name, "n_scored"] > 0, f"{case}: the authors' LS was not scored"
    ratio_f = facts.ratio_facts(comp.ratios)
    chosen_f = facts.ratio_facts(comp.ratios, "chosen")
    effect = study.static_model_effect(comp.boards, seed=seed)
    static_f = facts.static_facts(effect)
    rows = _Rows(summary)
    facts.summary_rows(comp, rows)
    declared = study.declared_method_table(list(comp.boards), data_dir, fast=fast, seed=seed, boards=comp.boards)
    for r in declared.itertuples(index=False):
        theirs = r.reference.split(" (")[0]
        if r.case.startswith("mean over"):
            rows.add(quantity=f"RMSE_2d ratio ours (declared before scoring: {r.method}) / {theirs}, mean over the "
                     f"cases scored", value=r.ratio, unit="", data=f"{NAME}/{r.case.split()[-2]} cases", kind="reproduced")
        else:
            rows.add(quantity=f"RMSE_2d ratio ours (declared before scoring: {r.method}) / {theirs}", value=r.ratio,
                     unit="", data=r.data, kind="reproduced")
    tables = {"reproduction": comp.reproduction, "ratios": comp.ratios, "declared": declared, "static_effect": effect,
              "static_models": pd.Series([m.describe() for m in comp.static_models], name="static range model",
                                         dtype=object).to_frame(),
              "verdicts": facts.verdict_table(repro_f, {"chosen": chosen_f, "best": ratio_f}, static_f),
              "placement": placement_table(comp.boards), "own_bound": own_bound_table(comp.boards)}
    return Section(None, tables, dict(comp.boards),
                   {"reproduction": repro_f, "ratios": ratio_f, "chosen": chosen_f, "static": static_f,
                    "tuning": dict(comp.tuning)},
                   tuple(rows.rows))


# --------------------------------------------------------------------------------------------
# notebooks 02 and 03: one case
# --------------------------------------------------------------------------------------------

def _one_case(case: str | None, data_dir, prefer: str) -> tuple[str | None, str | None, list[str]]:
    available, chosen, absent = _cases(data_dir, None if case is None else [case])
    if absent:
        return None, absent, available
    if chosen:
        return chosen[0], None, available
    pick = [c for c in available if c.startswith(prefer + "/")]
    return (pick or available)[0], None, available


def pruning_section(case: str | None = None, data_dir: PathLike | None = None, *, fast: bool, summary=None,
                    seed: int = 0) -> Section:
    """Notebook 02's Hanyang section: NLS with the pruning heuristics on one case (default the first NLOS
    case), tuned (window length, range calibration, tag height) on :func:`~.study.tuning_case`.

    Rows: raw LS, NLS (no pruning), NLS with residual pruning, NLS with the robust mean, the authors' LS
    (external); each pruned NLS against plain NLS on the common epochs with a block-bootstrap interval.
    """
    case, absent, available = _one_case(case, data_dir, "NLOS")
    if absent:
        return Section(absent=absent)
    tune = study.tuning_case(case, available)
    windows = (1.0,) if fast else NLS_WINDOWS_S
    est = [RawLs(), WindowNls(windows_s=windows), estimators.PrunedNls(windows_s=windows, heuristic="residual"),
           estimators.PrunedNls(windows_s=windows, heuristic="robust_mean"), authors.AuthorsEstimator("LS")]
    board = study.case_board(case, tune, data_dir, fast=fast, estimators=est)
    pairs = [("NLS residual pruning", "NLS"), ("NLS robust mean", "NLS"), ("NLS", "raw LS"),
             ("NLS residual pruning", "authors LS (external)"), ("NLS robust mean", "authors LS (external)")]
    table = ablation(board, pairs, low="better", high="worse", neither="not significant", seed=seed)
    rows = _Rows(summary)
    for r in table.itertuples(index=False):
        rows.add(quantity=f"RMSE_2d ratio {r.method} / {r.reference}", value=r.ratio, unit="", data=board.label,
                 kind="reproduced")
    for r in board.table().itertuples(index=False):
        if np.isfinite(r.rmse_m):          # the authors' LS is an outside method's number: input, data marked external
            ext = r.method in board.external
            rows.add(quantity=f"RMSE_2d, {r.method}", value=r.rmse_m, unit="m",
                     data=board.label + (facts.EXTERNAL if ext else ""), kind="input" if ext else "reproduced")
    return Section(None, {"ablation": table}, {case: board}, {"case": case, "tuned_on": tune},
                   tuple(rows.rows))


def motion_section(case: str | None = None, data_dir: PathLike | None = None, *, fast: bool, summary=None,
                   seed: int = 0) -> Section:
    """Notebook 03's Hanyang section: the motion models on one case (default the first LOS case), tuned on
    :func:`~.study.tuning_case`: the board's EKF-RW/RF/RJ on the ranges and its TDoA EKF-RF of notebook 03 (which
    does not run where the 4-anchor cluster leaves the TDoAs uninformative: its row's note gives the numbers), raw
    LS and the authors' ESKF (external, IMU-aided); each EKF that ran against raw LS with a block-bootstrap
    interval. The EKFs are the board's (:func:`~uwbwb.scoreboard.estimators.default_estimators`, FAST grids in FAST)."""
    case, absent, available = _one_case(case, data_dir, "LOS")
    if absent:
        return Section(absent=absent)
    tune = study.tuning_case(case, available)
    board_est = {e.name: e for e in default_estimators(fast=fast)}
    names = ["EKF-RF", "EKF-RW ranges", "EKF-RF ranges", "EKF-RJ ranges"]
    est = [board_est["raw LS"], *[board_est[m] for m in names], authors.AuthorsEstimator("ESKF")]
    board = study.case_board(case, tune, data_dir, fast=fast, estimators=est)
    table = ablation(board, [(m, "raw LS") for m in names], low="better", high="worse", neither="not significant",
                     seed=seed)
    sigma = {m: board.calibration.params(m).get("sigma_w", np.nan) for m in names}
    table["sigma_w"] = [sigma.get(m, np.nan) for m in table["method"]]
    rows = _Rows(summary)
    for r in table.itertuples(index=False):
        rows.add(quantity=f"RMSE_2d, {r.method}", value=r.rmse_2d_m, unit="m", data=board.label, kind="reproduced")
        rows.add(quantity=f"RMSE_2d ratio {r.method} / raw LS", value=r.ratio, unit="", data=board.label,
                 kind="reproduced")
    return Section(None, {"models": table}, {case: board}, {"case": case, "tuned_on": tune},
                   tuple(rows.rows))
