"""Verdicts of a board, computed from intervals into tables (notebook 06's "what the boards say").

Two kinds of statement, each a ``facts`` function returning the numbers and the verdict by its rule,
and a table over many of them (tests feed values on both sides of each threshold):

* :func:`difference_facts` / :func:`difference_table` — method A against method B: the
  difference of their RMSEs on the epochs *both* covered, with a 95 % block-bootstrap interval
  (blocks from :func:`block_ids`, so that the correlation of a tracking filter's errors is kept).
  The verdict is "A more accurate" / "B more accurate" when the interval excludes 0, else "no
  significant difference"; with fewer than :data:`MIN_BLOCKS` blocks no interval and no verdict.
* :func:`own_bound_facts` / :func:`own_bound_table` — a method below its *own* bound (the interval RMSE / own
  bound ± 2 se lies below 1), and whether it is still below that bound re-evaluated at the noise the scored part's
  truth measures (:meth:`~.interface.BaseEstimator.measured_noise_bound`): not below it, the measured noise accounts
  for the gap; still below it, or not measured, "cause not measured" — the table claims no other reason.
* :func:`placement_facts` / :func:`placement_table` — a method against the recording's common
  bound (:mod:`.reference`): the interval RMSE / common bound ± 2 block standard errors; "above" or "below" where
  it excludes 1, else "on the bound"; no verdict when the standard error could not be formed (fewer than
  :data:`MIN_BLOCKS` blocks).

Every verdict is :func:`uwbwb.metrics.interval_side` of an interval (the bootstrap's, or ratio ± 2 se) against its
null (0 for a difference, 1 for a ratio to a bound): the package's one interval → verdict rule.

The package's one block rule serves both (and :meth:`uwbwb.scoreboard.Board.table`'s standard errors):
:func:`uwbwb.metrics.block_ids` over the paired difference ``e_a² − e_b²`` (in
:func:`uwbwb.metrics.block_bootstrap_difference`, the one interval rule of a difference) or over the squared
error for a placement, cut per tag.
"""

from __future__ import annotations

import zlib
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ..metrics.errors import MIN_BLOCKS, block_bootstrap_difference, block_ids, interval_side

__all__ = ["DIFFERENCE_RULE", "N_BOOT", "OWN_BOUND_RULE", "PLACEMENT_RULE", "block_se_ratio", "difference_facts",
           "difference_table", "own_bound_facts", "own_bound_table", "pair_rng", "placement_facts", "placement_table"]

#: Bootstrap resamples of a difference.
N_BOOT = 2000
#: The rules the tables state beside each verdict.
DIFFERENCE_RULE = "95 % block-bootstrap interval of RMSE(A) − RMSE(B) on common epochs excludes 0"
PLACEMENT_RULE = "the interval RMSE / common bound ± 2 block standard errors excludes 1 (above or below), else on"
OWN_BOUND_RULE = ("below: the interval RMSE / own bound ± 2 block standard errors lies below 1; then the same against "
                  "the own bound at the scored part's measured noise")


def block_se_ratio(sq_err: list[np.ndarray], trace: list[np.ndarray]) -> tuple[float, int]:
    """Standard error of ``sqrt(mean sq_err / mean trace)`` (per tag ``(n,)`` arrays) from the blocks of
    :func:`block_ids` over the squared errors; NaN with fewer than :data:`MIN_BLOCKS` blocks.

    Returns ``(se, n_blocks)``."""
    ids, nb = block_ids(sq_err)
    if nb < MIN_BLOCKS:
        return float("nan"), nb
    e, t = np.concatenate(sq_err), np.concatenate(trace)
    se_b, tr_b = np.bincount(ids, e, nb), np.bincount(ids, t, nb)
    r2 = e.sum() / t.sum()
    # linearised ratio of sums: var(r²) from the block residuals, then d sqrt(r²) = d r² / (2 r)
    resid = (se_b - r2 * tr_b) / t.sum()
    var_r2 = nb / (nb - 1) * np.sum(resid ** 2)
    return (float(np.sqrt(var_r2) / (2 * np.sqrt(r2))) if r2 > 0 else float("nan")), nb


def difference_facts(board, a: str, b: str, *, n_boot: int = N_BOOT, rng: np.random.Generator) -> dict:
    """RMSE of ``a`` minus RMSE of ``b`` on the epochs both covered, with its 95 % block-bootstrap interval.

    Returns
    -------
    dict
        ``a, b, n_epochs, n_blocks, rmse_a_m, rmse_b_m, diff_m, lo_m, hi_m, verdict`` (``"a"``,
        ``"b"`` or ``"none"``: which is more accurate, by the rule that the interval excludes 0; no
        interval and ``"none"`` with fewer than :data:`MIN_BLOCKS` blocks), ``mode``, and the interval of
        ``RMSE(a) / RMSE(b)`` from the same replicates, ``ratio_lo``, ``ratio_hi``.
    """
    sa, sb = [], []
    for tag in board.tags:
        ea, eb = board.entry(a, tag), board.entry(b, tag)
        if ea.skipped or eb.skipped:
            continue
        both = ea.scored & eb.scored
        if both.sum() < 2:
            continue
        sa.append(ea.error_m[both])
        sb.append(eb.error_m[both])
    d = block_bootstrap_difference(sa, sb, rng=rng, n_boot=n_boot)
    verdict = {"below": "a", "above": "b"}.get(interval_side(d["lo_m"], d["hi_m"]), "none")
    return {"a": a, "b": b, "mode": board.mode, "n_epochs": d["n"], "n_blocks": d["n_blocks"], "rmse_a_m": d["rmse_a_m"],
            "rmse_b_m": d["rmse_b_m"], "diff_m": d["diff_m"], "lo_m": d["lo_m"], "hi_m": d["hi_m"], "verdict": verdict,
            "ratio_lo": d["ratio_lo"], "ratio_hi": d["ratio_hi"]}


def placement_facts(row) -> dict:
    """Where one board row (:meth:`Board.table`) sits against the common bound: ``above``, ``on``, ``below`` or ``none``."""
    r, se = float(row.rmse_over_common), float(row.rmse_over_common_se)
    where = _side(r, se)
    return {"method": row.method, "ratio": r, "se": se, "where": "on" if where == "contains" else where}


def _side(r: float, se: float) -> str:
    """:func:`~uwbwb.metrics.interval_side` of the interval ``r ± 2 se`` against 1; ``"none"`` where ``r`` is not
    finite (no bound), ``"few blocks"`` where ``se`` is not (fewer than :data:`MIN_BLOCKS` blocks: no verdict)."""
    if not np.isfinite(r):
        return "none"
    side = interval_side(r - 2 * se, r + 2 * se, 1.0)
    return "few blocks" if side == "none" else side


def own_bound_facts(row) -> dict:
    """One board row (:meth:`Board.table`) against its own bound (``where``: ``below``, ``not below``, ``few blocks``,
    ``none``) and, where below, against the own bound at the measured noise (``measured``: the same sides;
    ``none`` where not measured). ``verdict``: the table's words (module docstring)."""
    r, se = float(row.rmse_over_bound), float(row.rmse_over_bound_se)
    rm = float(getattr(row, "rmse_over_bound_measured", np.nan))
    sm = float(getattr(row, "rmse_over_bound_measured_se", np.nan))
    where, measured = ({"above": "not below", "contains": "not below"}.get(w, w) for w in (_side(r, se), _side(rm, sm)))
    if where == "none":
        verdict = "no own bound"
    elif where == "few blocks":
        verdict = f"no verdict (fewer than {MIN_BLOCKS} blocks)"
    elif where == "not below":
        verdict = "not below its own bound"
    elif measured == "not below":
        verdict = "below its own bound; not below it at the measured noise"
    elif measured == "below":
        verdict = "below its own bound, also at the measured noise: cause not measured"
    else:
        verdict = "below its own bound; noise not measured: cause not measured"
    return {"method": row.method, "ratio": r, "se": se, "ratio_measured": rm, "se_measured": sm, "where": where,
            "measured": measured, "verdict": verdict}


def own_bound_table(boards: Mapping[str, object]) -> pd.DataFrame:
    """:func:`own_bound_facts` of every method with an own bound on each board: recording, method, RMSE / own bound
    and its standard error, the same at the scored part's measured noise, the bias share (a Cramér–Rao bound holds
    for unbiased estimators), the rule and the verdict."""
    rows = []
    for label, board in boards.items():
        for r in board.table().query("n_scored > 0").itertuples():
            f = own_bound_facts(r)
            if f["where"] == "none":
                continue
            rows.append({"recording": label, "method": f["method"], "RMSE / own bound": f["ratio"],
                         "standard error": f["se"], "at measured noise": f["ratio_measured"],
                         "its standard error": f["se_measured"], "bias share": float(r.bias_share),
                         "rule": OWN_BOUND_RULE, "verdict": f["verdict"]})
    return pd.DataFrame(rows)


def pair_rng(seed: int, label: str, a: str, b: str) -> np.random.Generator:
    """The bootstrap's generator for ``A − B`` on the board ``label``: from ``seed`` and the three names only, so
    that a pair's interval is the same in every table that holds it (notebooks 05 and 06 on one flight), whatever
    else the table holds and in whatever order."""
    return np.random.default_rng([int(seed), zlib.crc32(f"{label}\x00{a}\x00{b}".encode())])


def difference_table(boards: Mapping[str, object], pairs: Sequence[tuple[str, str]], *,
                     seed: int) -> pd.DataFrame:
    """:func:`difference_facts` of every pair ``(A, B)`` that ran on each board, one row each: recording, A, B,
    each one's coverage (share of the scoring epochs with a position, where the board has it), epochs both covered,
    blocks, both RMSEs, A − B and its 95 % interval (mm), A / B and its 95 % interval (the same replicates), the rule
    and the verdict. Each row's bootstrap draws from
    :func:`pair_rng` (``seed``, the recording, A, B)."""
    rows = []
    for label, board in boards.items():
        tab = board.table().query("n_scored > 0").set_index("method")
        ran = set(tab.index)
        cov = tab["coverage"] if "coverage" in tab else pd.Series(np.nan, tab.index)
        for a, b in pairs:
            if a not in ran or b not in ran:
                continue
            f = difference_facts(board, a, b, rng=pair_rng(seed, label, a, b))
            verdict = {"a": f"{a} more accurate", "b": f"{b} more accurate"}.get(f["verdict"], "not significant")
            if f["n_epochs"] < 2:
                verdict = "no epochs both covered"
            elif f["n_blocks"] < MIN_BLOCKS:
                verdict = f"no verdict (fewer than {MIN_BLOCKS} blocks)"
            rows.append({"recording": label, "A": a, "B": b, "coverage A": float(cov[a]), "coverage B": float(cov[b]),
                         "epochs": f["n_epochs"], "blocks": f["n_blocks"],
                         "RMSE A (m)": f["rmse_a_m"], "RMSE B (m)": f["rmse_b_m"], "A − B (mm)": 1000 * f["diff_m"],
                         "95 % low (mm)": 1000 * f["lo_m"], "95 % high (mm)": 1000 * f["hi_m"],
                         "A / B": np.divide(f["rmse_a_m"], f["rmse_b_m"]), "A / B 95 % low": f["ratio_lo"],
                         "A / B 95 % high": f["ratio_hi"], "rule": DIFFERENCE_RULE, "verdict": verdict})
    return pd.DataFrame(rows)


def placement_table(boards: Mapping[str, object]) -> pd.DataFrame:
    """:func:`placement_facts` of every method that ran on each board: recording, method, RMSE / common bound,
    its block standard error, the rule and the verdict (above / on / below the bound, or none)."""
    rows = []
    for label, board in boards.items():
        for r in board.table().query("n_scored > 0").itertuples():
            f = placement_facts(r)
            verdict = {"above": "above the bound", "below": "below the bound", "on": "on the bound",
                       "none": "no common bound on its epochs"}.get(f["where"], f"no verdict (fewer than {MIN_BLOCKS} blocks)")
            rows.append({"recording": label, "method": f["method"], "RMSE / common bound": f["ratio"],
                         "standard error": f["se"], "rule": PLACEMENT_RULE, "verdict": verdict})
    return pd.DataFrame(rows)
