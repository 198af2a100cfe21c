"""The Hanyang dynamic runs: the dataset authors' numbers reproduced, then their LS/ESKF on our board.

Three steps, each a function the notebooks call:

1. :func:`reproduce_authors` recomputes the RMSE and RMSE_2d of the authors' ``LS.csv`` and
   ``ESKF.csv`` with :mod:`uwbwb.metrics`, following the definition of their
   ``localization_error_analysis.py`` (time window, epochs, the |z| filter on the reference,
   2-D vs 3-D; :func:`authors_window` and :func:`authors_errors`), beside their
   ``RMSD_results.txt``.
2. :func:`case_board` scores every method of the board on one case with the calibration and
   tuning fitted on *another* case (:func:`tuning_case`: same condition, the other trajectory
   shape), the authors' LS and ESKF as rows marked *external* (:class:`AuthorsEstimator`), all
   on the same epochs (the range epochs inside the authors' window).
3. :func:`compare_cases` runs the boards of several cases and gives, per case and method of ours,
   its RMSE_2d and the authors' LS's on the epochs *that pair* covered (:func:`pair_errors`; both
   coverages beside; not the board's all-method common epochs, which depend on what else is on the
   board), the ratio with a block-bootstrap interval whose block length comes from the data
   (:func:`uwbwb.metrics.block_bootstrap_difference`; no verdict with fewer than
   :data:`uwbwb.metrics.MIN_BLOCKS` blocks), and a full-coverage variant with ours holding its last position (:func:`held_errors`;
   :func:`ratio_table`). The method set against theirs is picked on the tuning case alone
   (:func:`pick_on_tuning_case`); :mod:`.facts` turns them into verdicts.
4. :func:`declared_method_table` runs the one method declared before any case was scored with it
   (:data:`DECLARED_METHOD`) unchanged on every case, against the authors' LS and ESKF.

Front ends differ, so outlier handling is *not* equal between their LS and ours: the authors' LS
(``Technical_validation/``) rejects a per-anchor range that jumps by more than 0.5 m from that
anchor's previous accepted range (up to 4 consecutive rejections, then accepts), holds each anchor's
latest range for up to 0.3 s, solves in 3-D warm-started from its previous solution and outputs on a
10 Hz timer; our LS/NLS solve each epoch's ranges independently (no jump gate, no hold, no warm
start), in 2-D at the calibrated height. The filters and pruned NLS have their own gates. Their
output stamps also lag the reference (``meta["authors_lag_s"]``); that latency is left in.

:func:`static_range_model` fits the static part's bias vs distance and
:class:`StaticModelLs` applies it to the dynamic ranges (does it help? :func:`static_model_effect`).

Height is handled the same way for every method: the tag's height above the reference track is
fitted on the *tuning* case (:func:`~uwbwb.datasets.hanyang_dynamic.load_dynamic_case`'s registration)
and given as a calibration to the scored case; every method then solves in 2-D at that height
(``dim=2``). The authors' LS solved in 3-D (z free); their estimates are used as published.
"""

from __future__ import annotations

import os
import zlib
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ... import metrics
from ...datasets import hanyang_dynamic
from ...errors import DataNotFoundError
from ...scoreboard import Board, score
from ...scoreboard.estimators import EKF_GRIDS, RangeEkfEstimator, default_estimators
from ...scoreboard.setnoise_nls import NLS_WINDOWS_S
from ...scoreboard.protocol import between
from ...types import Recording
from .pairs import _external, ablation, held_errors, pair_errors
from .authors import AuthorsEstimator, AuthorsFrontEndLs, authors_window, reproduce_authors
from .estimators import PrunedNls, StaticModelLs, StaticRangeModel, static_range_model


__all__ = ["CaseComparison", "DECLARED_METHOD", "FAST_SPAN_S", "board_epochs", "case_board", "compare_cases",
           "declared_method", "declared_method_table", "load_pair", "pick_on_tuning_case", "ratio_table",
           "static_model_effect", "tuning_case"]

PathLike = str | os.PathLike

#: FAST mode scores this many seconds of the window (and tunes on as many of the other case).
FAST_SPAN_S = 30.0


# --------------------------------------------------------------------------------------------
# 3. boards
# --------------------------------------------------------------------------------------------

def tuning_case(case: str, cases: Sequence[str]) -> str:
    """The case whose data tunes ``case``'s board: same condition, the other trajectory shape (the
    lowest case number), else another case of the same shape and condition, else any other case.

    Raises
    ------
    ValueError
        ``cases`` holds no case other than ``case``.
    """
    others = [c for c in cases if c != case]
    if not others:
        raise ValueError(f"no other case than {case!r} to tune on: tuning on the scored case is not allowed")
    me = hanyang_dynamic._case_fields(case)

    def key(c):
        f = hanyang_dynamic._case_fields(c)
        return (f["condition"] != me["condition"], f["trajectory"] == me["trajectory"], f["case"] or 0)

    return sorted(others, key=key)[0]


def board_epochs(rec: Recording) -> tuple[float, float]:
    """The authors' window of a registered case on the ranges' clock (their rules on the reference)."""
    ref = rec.truth["tag"]
    return authors_window(ref, rec.meta["trajectory"])


def load_pair(case: str, tune: str, data_dir: PathLike | None = None) -> tuple[Recording, Recording]:
    """``(scored, tuning)`` recordings: the tuning case with its own fitted tag height, the scored case
    with the *tuning case's* height (a calibration)."""
    cal_rec = hanyang_dynamic.load_dynamic_case(tune, data_dir)
    test_rec = hanyang_dynamic.load_dynamic_case(case, data_dir, tag_height_m=cal_rec.meta["tag_height_fit_m"])
    return test_rec, cal_rec


def study_estimators(*, fast: bool = False, static_models: Sequence[StaticRangeModel] = ()) -> list:
    """The board of this study: every method of the package (:func:`~uwbwb.scoreboard.estimators.default_estimators`,
    the EKFs RW/RF/RJ on ranges among them; the methods that do not apply stay on the board, where their rows say
    why: the TDoA methods, whose range differences from a 2 m anchor cluster do not locate a tag tens of metres
    away, and the UWB/INS filters, which need an IMU this dataset does not provide), NLS with residual pruning and
    with the robust mean, LS on ranges corrected by each static model, raw LS behind the authors' front end
    (:class:`AuthorsFrontEndLs`), then the authors' LS and ESKF (*external*)."""
    windows = (1.0,) if fast else NLS_WINDOWS_S
    return [*default_estimators(fast=fast), PrunedNls(windows_s=windows, heuristic="residual"),
            PrunedNls(windows_s=windows, heuristic="robust_mean"),
            *[StaticModelLs(m) for m in static_models], AuthorsFrontEndLs(), AuthorsEstimator("LS"),
            AuthorsEstimator("ESKF")]


def case_board(case: str, tune: str, data_dir: PathLike | None = None, *, fast: bool = False,
               estimators: Sequence | None = None, static_models: Sequence[StaticRangeModel] = (),
               progress: bool = False) -> Board:
    """The board of ``case`` with calibration and tuning on ``tune`` (never the scored case).

    Scored epochs: the range epochs inside the authors' window of ``case`` (FAST: its first
    :data:`FAST_SPAN_S` s, and the tuning case cut to as many seconds of its own window).
    Every method runs in 2-D at the tag height of the tuning case, at the native ~10 Hz. With the
    default estimators a sensitivity row is added: the authors' LS with its output latency removed, the
    lag measured on the tuning case (``authors_lag_s``).
    """
    if case == tune:
        raise ValueError(f"{case}: tuning on the scored case is not allowed; give another case")
    test_rec, cal_rec = load_pair(case, tune, data_dir)
    t0, t1 = board_epochs(test_rec)
    c0, c1 = board_epochs(cal_rec)
    if fast:
        t1, c1 = min(t1, t0 + FAST_SPAN_S), min(c1, c0 + FAST_SPAN_S)
    test = between(test_rec, t0, t1, f"{test_rec.name} [authors' window{' , FAST part' if fast else ''}]")
    cal = between(cal_rec, c0, c1, f"{cal_rec.name} [authors' window]") if fast else cal_rec
    if estimators is None:
        est = study_estimators(fast=fast, static_models=static_models)
        lag = cal_rec.meta.get("authors_lag_s", {}).get("LS")
        if lag is not None and np.isfinite(lag) and lag != 0:  # sensitivity: their latency, measured on the tuning case
            est.append(AuthorsEstimator("LS", shift_s=float(lag)))
    else:
        est = list(estimators)
    return score(test, cal, estimators=est, rate_hz=None, dim=2, fast=fast, progress=progress,
                 label=test_rec.label, other_anchors=True)   # the two trajectories place the same anchors apart



@dataclass(frozen=True)
class CaseComparison:
    """Boards and reproductions of several cases (:func:`compare_cases`)."""

    boards: Mapping[str, Board]
    tuning: Mapping[str, str]
    reproduction: pd.DataFrame
    ratios: pd.DataFrame
    fast: bool
    static_models: tuple = ()
    picks: Mapping[str, str | None] = field(default_factory=dict)

    @property
    def mode(self) -> str:
        return "FAST" if self.fast else "full"


THEIRS = "authors LS (external)"


def _ours(board: Board) -> list[str]:
    return [e.method for e in board.ran("tag") if not _external(e.method)]


def pick_on_tuning_case(tune: str, data_dir: PathLike | None = None, *, fast: bool = False,
                        estimators: Sequence | None = None, static_models: Sequence[StaticRangeModel] = (),
                        progress: bool = False) -> tuple[str | None, Board]:
    """Our ranges-only method to set against the authors' LS, picked on the tuning case alone.

    The authors' window of ``tune`` (FAST: its first :data:`FAST_SPAN_S` s) is split in time: its
    first half calibrates and tunes every method (:func:`~uwbwb.scoreboard.score`), its second half
    scores them beside the authors' LS; the pick is the method with the lowest RMSE_2d ratio to the
    authors' LS on the epochs both covered (:func:`pair_errors`). Nothing of the scored case enters
    (its tag height, ranges and truth are not read). Returns ``(method or None, board)``.
    """
    rec = hanyang_dynamic.load_dynamic_case(tune, data_dir)
    c0, c1 = board_epochs(rec)
    if fast:
        c1 = min(c1, c0 + FAST_SPAN_S)
    mid = 0.5 * (c0 + c1)
    first = between(rec, c0, mid, f"{rec.name} [authors' window, first half]")
    second = between(rec, mid, c1, f"{rec.name} [authors' window, second half]")
    est = study_estimators(fast=fast, static_models=static_models) if estimators is None else list(estimators)
    est = [e for e in est if not isinstance(e, AuthorsEstimator) or e.method == "LS"]
    if not any(isinstance(e, AuthorsEstimator) for e in est):
        est.append(AuthorsEstimator("LS"))
    board = score(second, first, estimators=est, rate_hz=None, dim=2, fast=fast, progress=progress,
                  label=f"{rec.label} [pick: tuned on first half, scored on second]")
    score_of = {}
    for m in _ours(board):
        p = pair_errors(board, m, THEIRS)
        if p is not None and p["err_m"].size:
            score_of[m] = metrics.rmse(p["err_m"]) / metrics.rmse(p["err_ref_m"])
    return (min(score_of, key=score_of.get) if score_of else None), board


def _ratio_cols(prefix: str, p: dict | None, case: str, m: str, seed: int) -> dict:
    if p is None or not p["err_m"].size:
        return {}
    rng = np.random.default_rng([seed, zlib.crc32(f"{case}/{m}/{prefix}".encode())])
    iv = metrics.block_bootstrap_difference(p["err_m"], p["err_ref_m"], rng=rng)
    r_ours, r_theirs = metrics.rmse(p["err_m"]), metrics.rmse(p["err_ref_m"])
    return {f"{prefix}n": int(p["err_m"].size), f"{prefix}rmse_2d_m": r_ours,
            f"{prefix}authors_ls_rmse_2d_m": r_theirs, f"{prefix}ratio": r_ours / r_theirs,
            f"{prefix}ratio_lo": iv["ratio_lo"], f"{prefix}ratio_hi": iv["ratio_hi"],
            f"{prefix}n_blocks": iv["n_blocks"]}


def ratio_table(boards: Mapping[str, Board], reproduction: pd.DataFrame, *, picks: Mapping[str, str | None] | None = None,
                seed: int = 0) -> pd.DataFrame:
    """Per case and our ranges-only method: RMSE_2d of ours and of the authors' LS on the epochs *that
    pair* covered (both have a position; independent of the other methods on the board), the ratio
    ours / theirs and its 95 % block-bootstrap interval (:func:`uwbwb.metrics.block_bootstrap_difference`:
    blocks from the data, ``n_blocks`` beside it), with both coverages (``coverage``: ours, ``coverage_authors_ls``:
    theirs, each over the scoring epochs). Columns ``held_*``: the same on *every* epoch the authors'
    LS covered, ours holding its last position where it has none (full-coverage variant). Columns
    ``nolat_*`` (when the board has it): against the authors' LS with its latency removed (sensitivity).

    Two picks: ``best`` marks the lowest ratio on the scored case itself (optimistic: made after seeing
    the scores); ``chosen`` marks ``picks[case]`` (:func:`pick_on_tuning_case`: made on the tuning case
    alone), the fair one to compare with the authors."""
    rows = []
    for case, board in boards.items():
        pub = reproduction[(reproduction["data"] == board.label) & (reproduction["method"] == "LS")
                           & (reproduction["metric"] == "RMSE 2-D")]
        case_rows = []
        for m in _ours(board):
            p = pair_errors(board, m, THEIRS)
            if p is None or not p["err_m"].size:
                continue
            row = {"data": board.label, "case": case, "tuned_on": board.calibration.source, "method": m,
                   "epochs": f"{m} ∩ authors LS", "coverage": p["coverage"], "coverage_authors_ls": p["coverage_ref"],
                   "n_scoring": p["n_scoring"]}
            row.update(_ratio_cols("", p, case, m, seed))
            nolat = [n for n in (e.method for e in board.ran("tag")) if n.startswith("authors LS, latency removed")]
            if nolat:
                row.update(_ratio_cols("nolat_", pair_errors(board, m, nolat[0]), case, m, seed))
            h = held_errors(board, m, THEIRS)
            row.update(_ratio_cols("held_", h, case, m, seed))
            row["held_n_filled"] = h["n_held"] if h is not None else 0
            row.update(authors_ls_published_2d_m=float(pub["published_m"].iloc[0]) if len(pub) else np.nan,
                       authors_ls_reproduced_2d_m=float(pub["reproduced_m"].iloc[0]) if len(pub) else np.nan)
            case_rows.append(row)
        if case_rows:
            best = min(case_rows, key=lambda r: r["ratio"])["method"]
            for r in case_rows:
                r["best"], r["chosen"] = r["method"] == best, r["method"] == (picks or {}).get(case)
        rows += case_rows
    return pd.DataFrame(rows)


def compare_cases(cases: Sequence[str] | None = None, data_dir: PathLike | None = None, *, fast: bool = False,
                  static: bool = True, seed: int = 0, progress: bool = False) -> CaseComparison:
    """Reproduction and board of every case (default: all present), each tuned on :func:`tuning_case`,
    and per tuning case the pick of :func:`pick_on_tuning_case`."""
    available = hanyang_dynamic.dynamic_cases(data_dir)
    cases = list(available if cases is None else cases)
    if not cases:
        raise DataNotFoundError("no Hanyang dynamic case in the data directories")
    models = []
    if static:
        for cond in ("LOS", "NLOS"):
            try:
                models.append(static_range_model(cond, data_dir))
            except (DataNotFoundError, ValueError):
                pass
    repro = pd.concat([reproduce_authors(c, data_dir) for c in cases], ignore_index=True)
    boards, tuning, pick_of_tune, picks = {}, {}, {}, {}
    for c in cases:
        tuning[c] = tuning_case(c, available)
        boards[c] = case_board(c, tuning[c], data_dir, fast=fast, static_models=models, progress=progress)
        if tuning[c] not in pick_of_tune:
            pick_of_tune[tuning[c]] = pick_on_tuning_case(tuning[c], data_dir, fast=fast, static_models=models,
                                                          progress=progress)[0]
        picks[c] = pick_of_tune[tuning[c]]
    return CaseComparison(boards, tuning, repro, ratio_table(boards, repro, picks=picks, seed=seed), fast,
                          tuple(models), picks)


def static_model_effect(boards: Mapping[str, Board], *, seed: int = 0) -> pd.DataFrame:
    """Per case and static model: RMSE_2d of ``LS static <cond> model`` vs ``raw LS`` (the same solver
    on uncorrected ranges) and vs ``LS`` (per-pair calibration from the tuning case), each pair on the
    epochs both covered, with block-bootstrap intervals of the ratios (``*_n_blocks`` beside them)."""
    rows = []
    for case, board in boards.items():
        for m in [m for m in _ours(board) if m.startswith("LS static")]:
            row = {"data": board.label, "case": case, "method": m}
            for ref in ("raw LS", "LS"):
                p = pair_errors(board, m, ref)
                if p is None or not p["err_m"].size:
                    continue
                rng = np.random.default_rng([seed, zlib.crc32(f"{case}/{m}/{ref}".encode())])
                iv = metrics.block_bootstrap_difference(p["err_m"], p["err_ref_m"], rng=rng)
                key = ref.replace(" ", "_").lower()
                row.setdefault("rmse_2d_m", metrics.rmse(p["err_m"]))
                row.update({f"{key}_rmse_2d_m": metrics.rmse(p["err_ref_m"]),
                            f"ratio_vs_{key}": metrics.rmse(p["err_m"]) / metrics.rmse(p["err_ref_m"]),
                            f"ratio_vs_{key}_lo": iv["ratio_lo"], f"ratio_vs_{key}_hi": iv["ratio_hi"],
                            f"ratio_vs_{key}_n_blocks": iv["n_blocks"]})
            rows.append(row)
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------------------------
# 4. one method, declared before scoring
# --------------------------------------------------------------------------------------------

#: The workbench's ranges-only method against the authors, declared before it was scored on any case (the rule
#: and why: notebook 06, section 4b, and the README): the board's EKF on the ranges with the random-force model and
#: its χ² anchor-dropping gate (``update="gate"``), its driving noise tuned by the board's grid search on
#: :func:`tuning_case` (same condition, the other trajectory shape), the tag height from that case, 2-D, scored on
#: the range epochs inside the authors' window. On generated ranges with 5–20 % NLOS-like outliers, in the
#: square and in the 2 m anchor cluster, that gate was as accurate as or more accurate than the robust updates.
DECLARED_METHOD = RangeEkfEstimator("RF", update="gate")
#: The authors' rows it is set against (names of :class:`AuthorsEstimator` rows).
AUTHORS_ROWS = (AuthorsEstimator("LS").name, AuthorsEstimator("ESKF").name)


def declared_method(*, fast: bool = False) -> RangeEkfEstimator:
    """:data:`DECLARED_METHOD` with the board's tuning grid (FAST: every other value, as
    :func:`~uwbwb.scoreboard.estimators.default_estimators`)."""
    if not fast:
        return DECLARED_METHOD
    return replace(DECLARED_METHOD, grid=tuple(float(g) for g in EKF_GRIDS[DECLARED_METHOD.model][::2]))


def declared_method_table(cases: Sequence[str] | None = None, data_dir: PathLike | None = None, *,
                          tuning: Mapping[str, str] | None = None, fast: bool = False, seed: int = 0,
                          boards: Mapping[str, Board] | None = None) -> pd.DataFrame:
    """:data:`DECLARED_METHOD`, unchanged, on every case against the authors' LS and ESKF.

    ``cases``: names or case folders of the upstream format (default: every case present); ``tuning[case]``
    the case it is tuned on (default :func:`tuning_case` among the cases present). One board per case
    (:func:`case_board`: the method and the authors' two rows; ``boards[case]`` instead where given, e.g. the
    section's boards, which hold the same method tuned alike), then per case and reference one row of
    :func:`~.pairs.ablation`: RMSE_2d of both on the epochs both covered, both coverages, the ratio ours / theirs,
    its 95 % block-bootstrap interval and the verdict (``better`` below 1, ``worse`` above, ``not significant``);
    last, per reference, the mean ratio over the cases (``case`` ``"mean over N cases"``; no interval: its
    ``verdict`` counts the per-case ones).
    """
    available = hanyang_dynamic.dynamic_cases(data_dir)
    cases = list(available if cases is None else cases)
    if not cases:
        raise DataNotFoundError("no Hanyang dynamic case in the data directories")
    method = declared_method(fast=fast)
    parts = []
    for c in cases:
        tune = (tuning or {}).get(c) or tuning_case(c, available)
        board = (boards or {}).get(c) or case_board(c, tune, data_dir, fast=fast,
                                                    estimators=[method, *map(AuthorsEstimator, ("LS", "ESKF"))])
        t = ablation(board, [(method.name, ref) for ref in AUTHORS_ROWS], low="better", high="worse",
                     neither="not significant", seed=seed)
        parts.append(t.assign(case=c, data=board.label, tuned_on=board.calibration.source))
    table = pd.concat(parts, ignore_index=True)
    means = []
    for ref, g in table.groupby("reference", sort=False):
        n = {v: int((g["verdict"] == v).sum()) for v in ("better", "worse", "not significant")}
        rest = len(g) - sum(n.values())
        means.append({"case": f"mean over {len(g)} cases", "method": method.name, "reference": ref,
                      "ratio": float(g["ratio"].mean()),
                      "verdict": ", ".join(f"{v} {k}" for v, k in n.items()) + (f", no verdict {rest}" if rest else "")})
    table = pd.concat([table, pd.DataFrame(means)], ignore_index=True)
    return table[["case", "tuned_on", *[c for c in table if c not in ("case", "tuned_on", "data")], "data"]]
