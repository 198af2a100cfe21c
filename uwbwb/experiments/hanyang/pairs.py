"""Ours vs theirs on the Hanyang boards: errors on the epochs a pair of methods both covered, a
hold-last-position variant. Their intervals are the package's one rule,
:func:`uwbwb.metrics.block_bootstrap_difference` (its ``ratio_lo`` / ``ratio_hi``).
"""

from __future__ import annotations

import zlib
from typing import Sequence

import numpy as np
import pandas as pd

from ... import metrics
from ...scoreboard import Board
from . import facts

def _external(name: str) -> bool:
    return "external" in name


def pair_errors(board: Board, method: str, reference: str, tag: str = "tag") -> dict | None:
    """Errors of ``method`` and ``reference`` on the epochs *both* covered (and the truth reaches).

    Unlike the board's common epochs, these do not depend on which other methods are on the board.
    Returns None if either did not run. Keys: ``t_s`` ``(N,)``, ``err_m``, ``err_ref_m`` ``(N,)``,
    ``coverage`` and ``coverage_ref`` (each one's share of the scoring epochs with a position) and
    ``n_scoring``.
    """
    ran = {e.method: e for e in board.ran(tag)}
    if method not in ran or reference not in ran:
        return None
    a, b = ran[method], ran[reference]
    both = a.scored & b.scored
    n = int(a.scoring.sum())
    return {"t_s": a.estimates.t_s[both], "err_m": a.error_m[both], "err_ref_m": b.error_m[both],
            "coverage": float(a.scored.sum() / n) if n else float("nan"),
            "coverage_ref": float(b.scored.sum() / n) if n else float("nan"), "n_scoring": n}


def held_errors(board: Board, method: str, reference: str, tag: str = "tag") -> dict | None:
    """Errors of ``method`` on every epoch ``reference`` covered, ``method`` *holding its last position*
    where it has none (NaN before its first position); ``reference``'s errors there. None if either
    did not run. Keys as :func:`pair_errors` (``n_held``: epochs filled by holding)."""
    ran = {e.method: e for e in board.ran(tag)}
    if method not in ran or reference not in ran:
        return None
    a, b = ran[method], ran[reference]
    has = a.estimates.has_estimate
    last = np.maximum.accumulate(np.where(has, np.arange(has.size), -1))
    pos = np.where((last >= 0)[:, None], a.estimates.pos_m[np.maximum(last, 0)], np.nan)
    d = pos[:, :2] - a.truth_pos_m[:, :2]
    err = np.sqrt(np.sum(d * d, axis=1))
    keep = b.scored & np.isfinite(err)
    n = int(a.scoring.sum())
    return {"t_s": a.estimates.t_s[keep], "err_m": err[keep], "err_ref_m": b.error_m[keep],
            "coverage": float(keep.sum() / n) if n else float("nan"),
            "coverage_ref": float(b.scored.sum() / n) if n else float("nan"), "n_scoring": n,
            "n_held": int((keep & ~a.scored).sum())}


def ablation(board: Board, pairs: Sequence[tuple[str, str]], *, low: str, high: str, neither: str,
             seed: int = 0) -> pd.DataFrame:
    """RMSE_2d of ``method`` vs ``reference`` on the epochs both covered (:func:`~.pairs.pair_errors`), both
    coverages, the ratio, its block-bootstrap interval (:func:`uwbwb.metrics.block_bootstrap_difference`) and the verdict (``low``
    below 1, ``high`` above, ``neither`` otherwise; none with too few independent blocks)."""
    rows = []
    for m, ref in pairs:
        p = pair_errors(board, m, ref)
        if p is None or not p["err_m"].size:
            continue
        rng = np.random.default_rng([seed, zlib.crc32(f"{board.label}/{m}/{ref}".encode())])
        iv = metrics.block_bootstrap_difference(p["err_m"], p["err_ref_m"], rng=rng)
        r_m, r_ref = metrics.rmse(p["err_m"]), metrics.rmse(p["err_ref_m"])
        rows.append({"method": m, "coverage": p["coverage"], "reference": ref, "reference_coverage": p["coverage_ref"],
                     "n_common": int(p["err_m"].size), "rmse_2d_m": r_m, "reference_rmse_2d_m": r_ref,
                     "ratio": r_m / r_ref, "ratio_lo": iv["ratio_lo"], "ratio_hi": iv["ratio_hi"],
                     "n_blocks": iv["n_blocks"],
                     "verdict": facts.pair_verdict(iv["ratio_lo"], iv["ratio_hi"], iv["n_blocks"], low, high, neither)})
    return pd.DataFrame(rows)
