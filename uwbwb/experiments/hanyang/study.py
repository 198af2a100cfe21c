"""The Hanyang dynamic runs: the dataset authors' numbers reproduced, then their LS/ESKF on our board.

Three steps, each a function the notebooks call:

1. :func:`reproduce_authors` recomputes the RMSE and RMSE_2d of the authors' ``LS.csv`` and
   ``ESKF.csv`` with :mod:`uwbwb.metrics`, following the definition of their
   ``localization_error_analysis.py`` (time window, epochs, the |z| filter on the reference,
   2-D vs 3-D; :func:`authors_window` and :func:`authors_errors`), beside their
   ``RMSD_results.txt``.
2. :func:`case_board` scores every method of the board on one case with the calibration and
   tuning fitted on *another* case (:func:`tuning_case`: same condition, the other trajectory
   shape), the authors' LS and ESKF as rows marked *external*
   (:class:`~uwbwb.scoreboard.estimators.ExternalEstimates`), all
   on the same epochs (the range epochs inside the authors' window).
3. :func:`ratio_table` sets each method of ours against the authors' LS with the board's one difference rule
   (:func:`uwbwb.scoreboard.verdicts.difference_table`: the epochs *that pair* covered, both coverages beside,
   not the board's all-method common epochs, which depend on what else is on the board; RMSE difference and
   ratio with 95 % block-bootstrap intervals whose blocks come from the data; no verdict with fewer than
   :data:`uwbwb.metrics.MIN_BLOCKS` blocks), with a full-coverage variant, ours holding its last position
   (:func:`held_ratio`). The method set against theirs is picked on the tuning case alone
   (:func:`pick_on_tuning_case`).
4. :func:`declared_method_table` runs the one method declared before any case was scored with it
   (:data:`DECLARED_METHOD`) unchanged on every case, against the authors' LS and ESKF.

:func:`static_range_model` fits the static part's bias vs distance and
:func:`static_model_ls` applies it to the dynamic ranges (does it help? against raw LS on the board). Outlier
handling differs between the authors' LS and ours (:data:`AUTHORS_FRONT_END_LS`); every method of ours solves in
2-D at the tag height of the tuning case (:func:`case_board`).

"""

from __future__ import annotations

import os
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ... import metrics
from ...datasets import hanyang_dynamic
from ...errors import DataNotFoundError
from ...scoreboard import Board, score
from ...scoreboard.protocol import Calibration
from ...types import Trajectory
from ...scoreboard.estimators import ExternalEstimates, RangeEkfEstimator, default_estimators
from ...scoreboard.setnoise_nls import NLS_WINDOWS_S, WindowNls
from ...scoreboard.sources import external_estimators
from ...scoreboard.verdicts import difference_table, pair_rng
from .authors import AUTHORS_FRONT_END_LS, authors_window
from .estimators import PrunedNls, StaticRangeModel, static_model_ls


__all__ = ["DECLARED_METHOD", "FAST_SPAN_S", "case_board", "declared_method_table", "held_ratio", "pick_on_tuning_case",
           "ratio_table", "tuning_case"]

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


def study_estimators(*, fast: bool = False, static_models: Sequence[StaticRangeModel] = ()) -> list:
    """The board of this study: every method of the package (:func:`~uwbwb.scoreboard.estimators.default_estimators`,
    the EKFs RW/RF/RJ on ranges among them; the methods that do not apply stay on the board, where their rows say
    why: the TDoA methods, whose range differences from a 2 m anchor cluster do not locate a tag tens of metres
    away, and the UWB/INS filters, which need an IMU this dataset does not provide), NLS with residual pruning and
    with the robust mean, LS on ranges corrected by each static model and raw LS behind the authors' front end
    (:data:`AUTHORS_FRONT_END_LS`); :func:`case_board` adds the authors' LS and ESKF (*external*)."""
    windows = (1.0,) if fast else NLS_WINDOWS_S
    base = default_estimators(fast=fast)
    fits = next(e.fits for e in base if isinstance(e, WindowNls))    # NLS's window lines: residual pruning's start
    return [*base, PrunedNls(windows_s=windows, heuristic="residual", fits=fits),
            PrunedNls(windows_s=windows, heuristic="robust_mean"),
            *map(static_model_ls, static_models), AUTHORS_FRONT_END_LS]


def case_board(case: str, tune: str, data_dir: PathLike | None = None, *, fast: bool = False,
               estimators: Sequence | None = None, static_models: Sequence[StaticRangeModel] = (),
               authors: tuple[str, ...] = ("LS", "ESKF"), calibration: Calibration | None = None) -> Board:
    """The board of ``case`` with calibration and tuning on ``tune`` (never the scored case): ``estimators``
    (default :func:`study_estimators`), then the authors' ``authors`` rows of ``case`` (*external*).
    ``calibration``: an earlier board's of the same two cases (:attr:`~uwbwb.scoreboard.Board.calibration`), whose
    fits and tunings are kept (only what it lacks is fitted: :func:`~uwbwb.scoreboard.score`).

    Scored epochs: the range epochs inside the authors' window of ``case`` (FAST: its first
    :data:`FAST_SPAN_S` s, and the tuning case cut to as many seconds of its own window).
    Every method runs in 2-D at the tag height of the tuning case, at the native ~10 Hz. With the
    default estimators a sensitivity row is added: the authors' LS with its output latency removed, the
    lag measured on the tuning case (``authors_lag_s``).
    """
    if case == tune:
        raise ValueError(f"{case}: tuning on the scored case is not allowed; give another case")
    cal_rec = hanyang_dynamic.load_dynamic_case(tune, data_dir)   # its tag height calibrates the scored case
    test_rec = hanyang_dynamic.load_dynamic_case(case, data_dir, tag_height_m=cal_rec.meta["tag_height_fit_m"])
    t0, t1 = authors_window(test_rec.truth["tag"], test_rec.meta["trajectory"])
    c0, c1 = authors_window(cal_rec.truth["tag"], cal_rec.meta["trajectory"])
    if fast:
        t1, c1 = min(t1, t0 + FAST_SPAN_S), min(c1, c0 + FAST_SPAN_S)
    test = test_rec.between(t0, t1, f"{test_rec.name} [authors' window{' , FAST part' if fast else ''}]")
    cal = cal_rec.between(c0, c1, f"{cal_rec.name} [authors' window]") if fast else cal_rec
    est = [*(study_estimators(fast=fast, static_models=static_models) if estimators is None else estimators),
           *external_estimators(test_rec, authors)]
    lag = cal_rec.meta.get("authors_lag_s", {}).get("LS")
    theirs = test_rec.meta.get("authors_estimates", {}).get("LS")
    if estimators is None and theirs is not None and lag is not None and np.isfinite(lag) and lag != 0:
        tr = theirs.to_trajectory()      # sensitivity: their latency, measured on the tuning case, removed
        est.append(ExternalEstimates(f"authors LS, latency removed ({lag:+.2f} s, tuning case) (external)",
                                     {"tag": Trajectory(tr.t_s + float(lag), tr.pos_m)}))
    return score(test, cal, estimators=est, rate_hz=None, dim=2, fast=fast, label=test_rec.label,
                 other_anchors=True, calibration=calibration)   # the two trajectories place the same anchors apart



THEIRS = "authors LS (external)"


def pick_on_tuning_case(tune: str, data_dir: PathLike | None = None, *, fast: bool = False,
                        estimators: Sequence | None = None,
                        static_models: Sequence[StaticRangeModel] = ()) -> tuple[str | None, Board]:
    """Our ranges-only method to set against the authors' LS, picked on the tuning case alone.

    The authors' window of ``tune`` (FAST: its first :data:`FAST_SPAN_S` s) is split in time: its
    first half calibrates and tunes every method (:func:`~uwbwb.scoreboard.score`), its second half
    scores them beside the authors' LS; the pick is the method with the lowest RMSE_2d ratio to the
    authors' LS on the epochs both covered (``best`` of :func:`ratio_table`). Nothing of the
    scored case enters (its tag height, ranges and truth are not read). Returns ``(method or None, board)``.
    """
    rec = hanyang_dynamic.load_dynamic_case(tune, data_dir)
    c0, c1 = authors_window(rec.truth["tag"], rec.meta["trajectory"])
    if fast:
        c1 = min(c1, c0 + FAST_SPAN_S)
    mid = 0.5 * (c0 + c1)
    first = rec.between(c0, mid, f"{rec.name} [authors' window, first half]")
    second = rec.between(mid, c1, f"{rec.name} [authors' window, second half]")
    est = study_estimators(fast=fast, static_models=static_models) if estimators is None else estimators
    est = [*(e for e in est if not getattr(e, "external", False)), *external_estimators(rec, ("LS",))]
    board = score(second, first, estimators=est, rate_hz=None, dim=2, fast=fast,
                  label=f"{rec.label} [pick: tuned on first half, scored on second]")
    t = ratio_table({tune: board})
    return (t.loc[t["best"], "A"].iloc[0] if len(t) else None), board


def held_ratio(board: Board, method: str, *, seed: int) -> dict:
    """``method`` against the authors' LS on *every* epoch theirs covered, ``method`` holding its last position
    where it has none (none before its first): RMSE_2d ratio and its interval by the one rule
    (:func:`uwbwb.metrics.block_bootstrap_difference`), epochs, blocks and the epochs filled by holding."""
    a, b = board.entry(method, "tag"), board.entry(THEIRS, "tag")
    has = a.estimates.has_estimate
    last = np.maximum.accumulate(np.where(has, np.arange(has.size), -1))
    pos = np.where((last >= 0)[:, None], a.estimates.pos_m[np.maximum(last, 0)], np.nan)
    err = metrics.position_error_m(pos, a.truth_pos_m)
    keep = b.scored & np.isfinite(err)
    iv = metrics.block_bootstrap_difference(err[keep], b.error_m[keep],
                                            rng=pair_rng(seed, board.label, f"{method}, held", THEIRS))
    return {"held A / B": np.divide(iv["rmse_a_m"], iv["rmse_b_m"]), "held 95 % low": iv["ratio_lo"],
            "held 95 % high": iv["ratio_hi"], "held epochs": iv["n"], "held blocks": iv["n_blocks"],
            "held filled": int((keep & ~a.scored).sum())}


def ratio_table(boards: Mapping[str, Board], *, picks: Mapping[str, str | None] | None = None,
                seed: int = 0) -> pd.DataFrame:
    """Per case, each of our methods against the authors' LS (and against their LS with its latency removed, where
    the board has that row): the board's :func:`~uwbwb.scoreboard.verdicts.difference_table` (the epochs *that
    pair* covered, independent of the other methods on the board; both coverages; RMSE_2d of both, their
    difference and ratio with 95 % block-bootstrap intervals; the verdict), with ``case`` and ``tuned_on``.
    Against their LS also :func:`held_ratio` (``held *``: the full-coverage variant) and two picks: ``best`` marks
    the lowest ratio on the scored case itself (optimistic: made after seeing the scores); ``chosen`` marks
    ``picks[case]`` (:func:`pick_on_tuning_case`: made on the tuning case alone), the fair one."""
    parts = []
    for case, board in boards.items():
        ours = [e.method for e in board.ran("tag") if e.method not in board.external]
        nolat = [m for m in board.external if m.startswith("authors LS, latency removed")]
        t = difference_table({board.label: board}, [(m, ref) for ref in (THEIRS, *nolat) for m in ours], seed=seed)
        t = t[t["epochs"] > 0] if len(t) else t
        if not len(t):
            continue
        vs = t["B"] == THEIRS
        held = pd.DataFrame([held_ratio(board, m, seed=seed) for m in t.loc[vs, "A"]], index=t.index[vs])
        t = t.join(held).assign(case=case, tuned_on=board.calibration.source)
        t["best"] = vs & (t.index == t.loc[vs, "A / B"].idxmin())
        t["chosen"] = vs & (t["A"] == (picks or {}).get(case))
        parts.append(t)
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


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
#: The authors' rows it is set against.
AUTHORS_ROWS = (THEIRS, "authors ESKF (external, +IMU)")


def declared_method_table(boards: Mapping[str, Board], *, seed: int = 0) -> pd.DataFrame:
    """:data:`DECLARED_METHOD`, unchanged, on every case against the authors' LS and ESKF.

    ``boards``: per case, its :func:`case_board` holding the method (FAST: with the board's FAST grid, as in
    :func:`~uwbwb.scoreboard.estimators.default_estimators`) and the authors' two rows; per case and reference one
    row of the board's :func:`~uwbwb.scoreboard.verdicts.difference_table`: RMSE_2d of both on the epochs both
    covered, both coverages, the difference and the ratio ours / theirs with their 95 % block-bootstrap intervals
    and the verdict; last, per reference, the mean ratio over the cases (``case`` ``"mean over N cases"``; no
    interval: its ``verdict`` counts the per-case ones).
    """
    if not boards:
        raise DataNotFoundError("no Hanyang dynamic case board to set the declared method on")
    name = DECLARED_METHOD.name
    table = pd.concat([difference_table({b.label: b}, [(name, ref) for ref in AUTHORS_ROWS], seed=seed)
                       .assign(case=c, tuned_on=b.calibration.source) for c, b in boards.items()], ignore_index=True)
    means = [{"case": f"mean over {len(g)} cases", "A": name, "B": ref, "A / B": float(g["A / B"].mean()),
              "verdict": ", ".join(f"{v}: {k}" for v, k in g["verdict"].value_counts().items())}
             for ref, g in table.groupby("B", sort=False)]
    table = pd.concat([table, pd.DataFrame(means)], ignore_index=True)
    return table[["case", "tuned_on", *[c for c in table if c not in ("case", "tuned_on")]]]
