"""Verdicts of a board, computed from intervals into tables (notebook 06's "what the boards say").

Three tables, each the numbers and the verdict by its rule (tests feed values on both sides of each threshold):

* :func:`difference_table` — method A against method B: the
  difference of their RMSEs on the epochs *both* covered, with a 95 % block-bootstrap interval
  (blocks from :func:`block_ids`, so that the correlation of a tracking filter's errors is kept).
  The verdict is "A more accurate" / "B more accurate" when the interval excludes 0, else "no
  significant difference"; with fewer than :data:`MIN_BLOCKS` blocks no interval and no verdict. It reads
  "edge-bound: … at the picks" when either method's tuning pick lies on its grid's edge (the board's
  ``grid_edge``): the difference then holds at those picks, and a wider grid might change it.
* :func:`own_bound_table` — a method below its *own* bound (the interval RMSE / own
  bound ± 2 se lies below 1), and whether it is still below that bound re-evaluated at the noise the scored part's
  truth measures (:meth:`~.interface.BaseEstimator.measured_noise_bound`): not below it, the measured noise accounts
  for the gap; still below it, or not measured, "cause not measured" — the table claims no other reason.
* :func:`placement_table` — a method against the recording's common
  bound (:mod:`.reference`): the interval RMSE / common bound ± 2 block standard errors; "above" or "below" where
  it excludes 1, else "on the bound"; no verdict when the standard error could not be formed (fewer than
  :data:`MIN_BLOCKS` blocks). Its blocks are not a difference's on the same recording: each interval's blocks
  follow the series it is on (one method's squared error on its own epochs here, the paired difference on the
  epochs both covered there), so a method may have a verdict in one table and too few blocks in the other; each
  table shows its count.

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

__all__ = ["DIFFERENCE_RULE", "EDGE_BOUND", "EDGE_BOUND_LABEL", "edge_bound", "N_BOOT", "OWN_BOUND_RULE", "PLACEMENT_RULE", "block_se_ratio", "difference_table",
           "own_bound_table", "pair_rng", "placement_table"]

#: Bootstrap resamples of a difference.
N_BOOT = 2000
#: The rules the tables state beside each verdict.
DIFFERENCE_RULE = "95 % block-bootstrap interval of RMSE(A) − RMSE(B) on common epochs excludes 0"
PLACEMENT_RULE = ("the interval RMSE / common bound ± 2 block standard errors excludes 1 (above or below), else on; "
                  "blocks of the method's squared error on its own epochs (a difference's: of the paired difference "
                  "on the epochs both covered, so their counts differ)")
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


def _side(r: float, se: float) -> str:
    """:func:`~uwbwb.metrics.interval_side` of the interval ``r ± 2 se`` against 1; ``"none"`` where ``r`` is not
    finite (no bound), ``"few blocks"`` where ``se`` is not (fewer than :data:`MIN_BLOCKS` blocks: no verdict)."""
    if not np.isfinite(r):
        return "none"
    side = interval_side(r - 2 * se, r + 2 * se, 1.0)
    return "few blocks" if side == "none" else side


def own_bound_table(boards: Mapping[str, object]) -> pd.DataFrame:
    """Every method with an own bound on each board against it (module docstring): recording, method, RMSE / own
    bound and its standard error, the same at the scored part's measured noise, the bias share (a Cramér–Rao bound
    holds for unbiased estimators), the rule and the verdict."""
    rows = []
    for label, board in boards.items():
        for r in board.table().query("n_scored > 0").itertuples():
            rm = float(getattr(r, "rmse_over_bound_measured", np.nan))
            sm = float(getattr(r, "rmse_over_bound_measured_se", np.nan))
            where, measured = ({"above": "not below", "contains": "not below"}.get(w, w)
                               for w in (_side(float(r.rmse_over_bound), float(r.rmse_over_bound_se)), _side(rm, sm)))
            if where == "none":
                continue
            if where == "few blocks":
                verdict = f"no verdict (fewer than {MIN_BLOCKS} blocks)"
            elif where == "not below":
                verdict = "not below its own bound"
            elif measured == "not below":
                verdict = "below its own bound; not below it at the measured noise"
            elif measured == "below":
                verdict = "below its own bound, also at the measured noise: cause not measured"
            else:
                verdict = "below its own bound; noise not measured: cause not measured"
            rows.append({"recording": label, "method": r.method, "RMSE / own bound": float(r.rmse_over_bound),
                         "standard error": float(r.rmse_over_bound_se), "at measured noise": rm,
                         "its standard error": sm, "bias share": float(r.bias_share), "rule": OWN_BOUND_RULE,
                         "verdict": verdict})
    return pd.DataFrame(rows)


def pair_rng(seed: int, label: str, a: str, b: str) -> np.random.Generator:
    """The bootstrap's generator for ``A − B`` on the board ``label``: from ``seed`` and the three names only, so
    that a pair's interval is the same in every table that holds it (notebooks 05 and 06 on one flight), whatever
    else the table holds and in whatever order."""
    return np.random.default_rng([int(seed), zlib.crc32(f"{label}\x00{a}\x00{b}".encode())])


#: How a :func:`difference_table` verdict starts when either method's tuning pick lies on its grid's edge.
EDGE_BOUND = "edge-bound"
#: What a summary row's quantity adds where its verdict is edge-bound: one wording in every notebook's summary.
EDGE_BOUND_LABEL = f"{EDGE_BOUND} at the tuning picks"


def edge_bound(verdict) -> bool:
    """Whether a :func:`difference_table` verdict is edge-bound (:data:`EDGE_BOUND`): it holds at the picks only."""
    return str(verdict).startswith(EDGE_BOUND)


#: The columns of :func:`difference_table`, also when no pair ran.
DIFFERENCE_COLUMNS = ("recording", "A", "B", "coverage A", "coverage B", "epochs", "blocks", "RMSE A (m)", "RMSE B (m)",
                      "A − B (mm)", "95 % low (mm)", "95 % high (mm)", "A / B", "A / B 95 % low", "A / B 95 % high",
                      "rule", "verdict")


def difference_table(boards: Mapping[str, object], pairs: Sequence[tuple[str, str]], *, seed: int,
                     n_boot: int = N_BOOT) -> pd.DataFrame:
    """Every pair ``(A, B)`` that ran on each board (module docstring), one row each: recording, A, B, each one's
    coverage (share of the scoring epochs with a position, where the board has it), epochs both covered, blocks,
    both RMSEs, A − B and its 95 % interval (mm), A / B and its 95 % interval (the same replicates), the rule and the
    verdict. Each row's bootstrap draws from :func:`pair_rng` (``seed``, the recording, A, B)."""
    rows = []
    for label, board in boards.items():
        tab = board.table().query("n_scored > 0").set_index("method")
        ran = set(tab.index)
        cov = tab["coverage"] if "coverage" in tab else pd.Series(np.nan, tab.index)
        for a, b in pairs:
            if a not in ran or b not in ran:
                continue
            sa, sb = [], []
            for tag in board.tags:
                ea, eb = board.entry(a, tag), board.entry(b, tag)
                both = ea.scored & eb.scored if not (ea.skipped or eb.skipped) else np.zeros(0, bool)
                if both.sum() >= 2:
                    sa.append(ea.error_m[both])
                    sb.append(eb.error_m[both])
            d = block_bootstrap_difference(sa, sb, rng=pair_rng(seed, label, a, b), n_boot=n_boot)
            side = interval_side(d["lo_m"], d["hi_m"])
            verdict = {"below": f"{a} more accurate", "above": f"{b} more accurate"}.get(side, "not significant")
            if d["n"] < 2:
                verdict = "no epochs both covered"
            elif d["n_blocks"] < MIN_BLOCKS:
                verdict = f"no verdict (fewer than {MIN_BLOCKS} blocks)"
            else:
                edge = [f"{m}: {tab.loc[m, 'tuning_pick']}" for m in (a, b) if _on_edge(tab, m)]
                if edge:
                    verdict = f"{EDGE_BOUND}: {verdict} at the picks ({'; '.join(edge)})"
            rows.append({"recording": label, "A": a, "B": b, "coverage A": float(cov[a]), "coverage B": float(cov[b]),
                         "epochs": d["n"], "blocks": d["n_blocks"],
                         "RMSE A (m)": d["rmse_a_m"], "RMSE B (m)": d["rmse_b_m"], "A − B (mm)": 1000 * d["diff_m"],
                         "95 % low (mm)": 1000 * d["lo_m"], "95 % high (mm)": 1000 * d["hi_m"],
                         "A / B": np.divide(d["rmse_a_m"], d["rmse_b_m"]), "A / B 95 % low": d["ratio_lo"],
                         "A / B 95 % high": d["ratio_hi"], "rule": DIFFERENCE_RULE, "verdict": verdict})
    return pd.DataFrame(rows, columns=DIFFERENCE_COLUMNS)   # no pair ran (no data): the header, no rows



def _on_edge(tab: pd.DataFrame, method: str) -> bool:
    """Whether ``method``'s tuning pick on the calibration part lies on its grid's edge (the board's ``grid_edge``)."""
    v = tab.loc[method, "grid_edge"] if "grid_edge" in tab else None
    return isinstance(v, (bool, np.bool_)) and bool(v)


def placement_table(boards: Mapping[str, object]) -> pd.DataFrame:
    """Every method that ran on each board against the recording's common bound (module docstring): recording,
    method, RMSE / common bound, its block standard error and number of blocks, the rule and the verdict."""
    rows = []
    for label, board in boards.items():
        for r in board.table().query("n_scored > 0").itertuples():
            ratio, se = float(r.rmse_over_common), float(r.rmse_over_common_se)
            verdict = {"above": "above the bound", "below": "below the bound", "contains": "on the bound",
                       "none": "no common bound on its epochs"}.get(_side(ratio, se),
                                                                    f"no verdict (fewer than {MIN_BLOCKS} blocks)")
            rows.append({"recording": label, "method": r.method, "RMSE / common bound": ratio, "standard error": se,
                         "blocks": getattr(r, "rmse_over_common_blocks", np.nan), "rule": PLACEMENT_RULE,
                         "verdict": verdict})
    return pd.DataFrame(rows)
