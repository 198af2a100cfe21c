"""Ours vs theirs on the Hanyang boards: errors on the epochs a pair of methods both covered, a
hold-last-position variant, a clock-offset sensitivity, and block-bootstrap intervals of RMSE ratios.

Split from :mod:`.study` (which re-exports every name).
"""

from __future__ import annotations

import numpy as np

from ... import metrics
from ...scoreboard import Board

#: Block bootstrap: a block is BLOCK_LAG_FACTOR × the lag (s) at which the autocorrelation of the paired
#: difference e_ours² − e_theirs² first falls below ACF_LEVEL (an assumption: below it, epochs count as
#: independent); with fewer than MIN_BLOCKS blocks no interval and no verdict is given.
ACF_LEVEL = 0.05
BLOCK_LAG_FACTOR = 2.0
MIN_BLOCKS = 10


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


def offset_ratio(board: Board, method: str, reference: str, delta_s: float, tag: str = "tag") -> float:
    """RMSE_2d ratio ``method`` / ``reference`` on the epochs both covered, with the reference track's clock
    offset changed by ``delta_s`` (truth'(t) = truth(t − delta_s), interpolated linearly between the board's
    epochs; epochs it does not reach are left out). A sensitivity check of the registration."""
    ran = {e.method: e for e in board.ran(tag)}
    if method not in ran or reference not in ran:
        return float("nan")
    a, b = ran[method], ran[reference]
    t = a.estimates.t_s
    have = a.scoring
    if have.sum() < 2:
        return float("nan")
    tq = t - delta_s
    inside = (tq >= t[have][0]) & (tq <= t[have][-1])
    truth = np.column_stack([np.interp(tq, t[have], a.truth_pos_m[have, k]) for k in range(2)])
    both = a.scored & b.scored & inside
    if not both.any():
        return float("nan")
    ea = np.hypot(*(a.estimates.pos_m[both, :2] - truth[both]).T)
    eb = np.hypot(*(b.estimates.pos_m[both, :2] - truth[both]).T)
    return metrics.rmse(ea) / metrics.rmse(eb)


def block_length_s(err_a: np.ndarray, err_b: np.ndarray, t_s: np.ndarray, *, acf_level: float = ACF_LEVEL) -> float:
    """Block length of the bootstrap, seconds: :data:`BLOCK_LAG_FACTOR` × the first lag at which the
    autocorrelation of the paired difference ``err_a² − err_b²`` falls below ``acf_level``.

    The autocorrelation is taken over the sequence of paired epochs (gaps ignored) and the lag turned
    into seconds with their median spacing; at least two spacings. NaN with fewer than 3 epochs.
    """
    t = np.asarray(t_s, float)
    if t.size < 3:
        return float("nan")
    d = np.asarray(err_a, float) ** 2 - np.asarray(err_b, float) ** 2
    d = d - d.mean()
    dt = float(np.median(np.diff(t)))
    var = float(np.dot(d, d))
    if var <= 0:
        return BLOCK_LAG_FACTOR * dt
    f = np.fft.rfft(d, 2 * d.size)
    acf = np.fft.irfft(f * np.conj(f))[: d.size] / var
    below = np.flatnonzero(acf < acf_level)
    lag = int(below[0]) if below.size else d.size
    return BLOCK_LAG_FACTOR * max(lag, 1) * dt


def ratio_interval(err_a: np.ndarray, err_b: np.ndarray, t_s: np.ndarray, *, rng: np.random.Generator,
                   n_boot: int = 2000, level: float = 0.95, block_s: float | None = None,
                   min_blocks: int = MIN_BLOCKS) -> dict:
    """Interval of ``RMSE(err_a) / RMSE(err_b)`` on paired epochs by a block bootstrap.

    The epochs at ``t_s`` (seconds, ``(N,)``) are cut into contiguous blocks of ``block_s`` seconds
    (default :func:`block_length_s`, derived from the data); the blocks are resampled with replacement.
    With fewer than ``min_blocks`` non-empty blocks there are too few independent pieces for an
    interval: ``lo``/``hi`` are NaN and the verdict is refused.

    Returns
    -------
    dict
        ``lo``, ``hi``, ``block_s``, ``n_blocks``.
    """
    err_a, err_b, t = np.asarray(err_a, float), np.asarray(err_b, float), np.asarray(t_s, float)
    if not (err_a.size == err_b.size == t.size):
        raise ValueError(f"paired errors and times must have the same length, got {err_a.size}, {err_b.size}, {t.size}")
    bl = block_length_s(err_a, err_b, t) if block_s is None else float(block_s)
    if not np.isfinite(bl) or t.size == 0:
        return {"lo": float("nan"), "hi": float("nan"), "block_s": bl, "n_blocks": 0}
    ids = np.floor((t - t[0]) / bl).astype(int)
    _, ids = np.unique(ids, return_inverse=True)
    nb = int(ids.max()) + 1
    if nb < min_blocks:
        return {"lo": float("nan"), "hi": float("nan"), "block_s": bl, "n_blocks": nb}
    sa = np.bincount(ids, err_a ** 2, nb)
    sb = np.bincount(ids, err_b ** 2, nb)
    pick = rng.integers(0, nb, (n_boot, nb))
    ratio = np.sqrt(sa[pick].sum(axis=1) / sb[pick].sum(axis=1))
    lo, hi = np.quantile(ratio, [(1 - level) / 2, (1 + level) / 2])
    return {"lo": float(lo), "hi": float(hi), "block_s": bl, "n_blocks": nb}


def block_bootstrap_ratio(err_a: np.ndarray, err_b: np.ndarray, *, rng: np.random.Generator, t_s=None,
                          n_boot: int = 2000, level: float = 0.95) -> tuple[float, float]:
    """``(lo, hi)`` of :func:`ratio_interval` (``t_s`` None: one epoch per 0.1 s, the runs' rate)."""
    t = 0.1 * np.arange(np.asarray(err_a).size) if t_s is None else t_s
    r = ratio_interval(err_a, err_b, t, rng=rng, n_boot=n_boot, level=level)
    return r["lo"], r["hi"]
