"""Position errors and their distribution: per-epoch errors, ECDF, CEP, RMSE, the table of accuracy on
common epochs with coverage beside it, and the paired block-bootstrap interval of an RMSE difference.

Missing values
--------------
NaN in an error array means "no estimate" (e.g. an epoch multilateration
could not solve). Every statistic raises ``ValueError`` on NaN so that a
missing epoch is never silently ignored; :func:`error_stats` accepts
``nan="omit"`` and then reports how many values it left out (``n_omitted``).
Infinite values are always an error.

Quantile rule
-------------
``cep(err, p)`` is the empirical quantile that inverts the ECDF returned by
:func:`ecdf`: the smallest observed error ``x`` with ``F(x) >= p``, i.e. the
``ceil(p * n)``-th smallest value (numpy's ``method="inverted_cdf"``). It is
always one of the observed errors, and a CEP marker drawn on the ECDF sits
exactly on the curve.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Sequence

import numba
import numpy as np
import pandas as pd

from ..types import Trajectory
from .scoring import score_epochs



def position_error_m(est_pos_m, true_pos_m, *, horizontal: bool = True) -> np.ndarray:
    """Euclidean position error per epoch.

    Parameters
    ----------
    est_pos_m, true_pos_m
        Estimated and true positions, shape ``(T, 2)`` or ``(T, 3)``, metres.
    horizontal
        If True, use ``x, y`` only (the two arrays may then differ in
        dimension); otherwise both must have the same dimension.

    Returns
    -------
    numpy.ndarray
        Errors, shape ``(T,)``, metres. NaN rows in either input give NaN.
    """
    est = np.asarray(est_pos_m, dtype=float)
    true = np.asarray(true_pos_m, dtype=float)
    for name, a in (("est_pos_m", est), ("true_pos_m", true)):
        if a.ndim != 2 or a.shape[1] not in (2, 3):
            raise ValueError(f"{name} must have shape (T, 2) or (T, 3), got {a.shape}")
    if est.shape[0] != true.shape[0]:
        raise ValueError(f"est_pos_m has {est.shape[0]} epochs, true_pos_m has {true.shape[0]}")
    if horizontal:
        est, true = est[:, :2], true[:, :2]
    elif est.shape[1] != true.shape[1]:
        raise ValueError(f"3-D errors need positions of equal dimension, got {est.shape[1]} and "
                         f"{true.shape[1]} (use horizontal=True for x, y only)")
    return np.linalg.norm(est - true, axis=1)


@dataclass(frozen=True)
class ErrorSeries:
    """Errors of an estimate against interpolated truth (see :func:`errors_vs_truth`).

    Attributes
    ----------
    name
        The estimate's name (legend label).
    t_s
        Times of the compared epochs, shape ``(N,)``, seconds.
    err_m
        Errors at those times, shape ``(N,)``, metres (NaN where the estimate is NaN).
    n_outside
        Estimate epochs left out because they lie outside the truth's time span.
    n_in_gap
        Estimate epochs left out because the bracketing truth samples are more
        than ``max_gap_s`` apart.
    horizontal
        Whether the errors are horizontal (x, y) only.
    """

    name: str
    t_s: np.ndarray
    err_m: np.ndarray
    n_outside: int = 0
    n_in_gap: int = 0
    horizontal: bool = True

    def __post_init__(self):
        t = np.array(self.t_s, dtype=float)
        e = np.array(self.err_m, dtype=float)
        if t.ndim != 1 or e.shape != t.shape:
            raise ValueError(f"t_s and err_m must be 1-D of equal length, got {t.shape} and {e.shape}")
        t.setflags(write=False)
        e.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "err_m", e)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def n_excluded(self) -> int:
        """Estimate epochs without a truth reference (outside the span or in a gap)."""
        return self.n_outside + self.n_in_gap

    def stats(self, *, nan: str = "raise") -> dict:
        """:func:`error_stats` of :attr:`err_m`, plus ``n_excluded``."""
        return {**error_stats(self.err_m, nan=nan), "n_excluded": self.n_excluded}

    def report(self) -> str:
        """One line saying how many epochs were compared and why others were not."""
        parts = [f"{self.name}: {len(self)} epochs compared with truth"]
        if self.n_outside:
            parts.append(f"{self.n_outside} outside the truth time span excluded")
        if self.n_in_gap:
            parts.append(f"{self.n_in_gap} in truth gaps excluded")
        n_nan = int(np.count_nonzero(np.isnan(self.err_m)))
        if n_nan:
            parts.append(f"{n_nan} without an estimate (NaN)")
        return "; ".join(parts)


def errors_vs_truth(estimate: Trajectory, truth: Trajectory, *, horizontal: bool = True,
                    max_gap_s: float | None = None) -> ErrorSeries:
    """Errors of ``estimate`` at its own times against linearly interpolated truth.

    Truth is never extrapolated: estimate epochs before the first or after the
    last truth sample are excluded and counted (``n_outside``). With
    ``max_gap_s``, epochs falling between two truth samples more than
    ``max_gap_s`` apart (e.g. a motion-capture dropout) are excluded and counted
    too (``n_in_gap``); epochs coinciding with a truth sample are always kept.

    Parameters
    ----------
    estimate, truth
        Trajectories on the same clock and frame.
    horizontal
        Horizontal (x, y) errors if True, else 3-D (both must be 3-D).
    max_gap_s
        Largest truth sampling gap to interpolate across, seconds; None = any.

    Returns
    -------
    ErrorSeries
        Compared times and errors, with the exclusion counts.
    """
    if not isinstance(estimate, Trajectory) or not isinstance(truth, Trajectory):
        raise ValueError("estimate and truth must be uwbwb.Trajectory objects")
    if len(truth) < 1:
        raise ValueError("truth is empty")
    if max_gap_s is not None and not (np.isfinite(max_gap_s) and max_gap_s > 0):
        raise ValueError(f"max_gap_s must be positive, got {max_gap_s!r}")
    t = estimate.t_s
    tt = truth.t_s
    inside = (t >= tt[0]) & (t <= tt[-1])
    keep = inside.copy()
    n_in_gap = 0
    if max_gap_s is not None and len(truth) > 1:
        i = np.clip(np.searchsorted(tt, t, side="right"), 1, tt.size - 1)
        exact = tt[np.clip(np.searchsorted(tt, t), 0, tt.size - 1)] == t
        in_gap = inside & ~exact & (tt[i] - tt[i - 1] > max_gap_s)
        n_in_gap = int(np.count_nonzero(in_gap))
        keep &= ~in_gap
    true_pos = truth.interp(t[keep])
    err = position_error_m(estimate.pos_m[keep], true_pos, horizontal=horizontal)
    return ErrorSeries(estimate.name, t[keep], err, int(np.count_nonzero(~inside)), n_in_gap, horizontal)


# --------------------------------------------------------------------------- statistics


def _errors(err, *, nan: str = "raise", nonneg: bool = True) -> tuple[np.ndarray, int]:
    if nan not in ("raise", "omit"):
        raise ValueError(f"nan must be 'raise' or 'omit', got {nan!r}")
    e = np.asarray(getattr(err, "err_m", err), dtype=float)
    if e.ndim != 1:
        raise ValueError(f"errors must be 1-D, got shape {e.shape}")
    if np.any(np.isinf(e)):
        raise ValueError("errors contain infinite values")
    missing = np.isnan(e)
    n_nan = int(np.count_nonzero(missing))
    if n_nan and nan == "raise":
        raise ValueError(f"errors contain {n_nan} NaN value(s) of {e.size}; drop them explicitly or use "
                         f"error_stats(..., nan='omit'), which reports how many were left out")
    e = e[~missing]
    if e.size == 0:
        raise ValueError("no errors to summarise (empty input)")
    if nonneg and np.any(e < 0):
        raise ValueError("position errors must be non-negative (radial errors)")
    return e, n_nan


def ecdf(err) -> tuple[np.ndarray, np.ndarray]:
    """Empirical cumulative distribution function.

    Parameters
    ----------
    err
        Errors, shape ``(N,)`` (signed values allowed), no NaN.

    Returns
    -------
    x : numpy.ndarray
        Sorted errors, shape ``(N,)``.
    F : numpy.ndarray
        ``F[k] = (k + 1) / N``, the fraction of errors ``<= x[k]``, shape ``(N,)``.
    """
    e, _ = _errors(err, nonneg=False)
    return np.sort(e), np.arange(1, e.size + 1) / e.size


def cep(err, p: float) -> float:
    """Circular error probable at level ``p``: the empirical ``p``-quantile of radial errors.

    Uses the ECDF-inverting rule of the module docstring: the ``ceil(p * N)``-th
    smallest error.

    Parameters
    ----------
    err
        Radial errors, shape ``(N,)``, metres, non-negative, no NaN.
    p
        Probability level in ``(0, 1]``.

    Returns
    -------
    float
        The error radius, metres.
    """
    if not (isinstance(p, numbers.Real) and 0 < p <= 1):
        raise ValueError(f"p must be a probability in (0, 1], got {p!r}")
    e, _ = _errors(err)
    k = math.ceil(round(float(p) * e.size, 9))   # rounding guards 0.95 * 100 = 95.00000000000001
    return float(np.partition(e, k - 1)[k - 1])


def cep50(err) -> float:
    """:func:`cep` at 50 %, metres."""
    return cep(err, 0.5)


def cep95(err) -> float:
    """:func:`cep` at 95 %, metres."""
    return cep(err, 0.95)


def rmse(err) -> float:
    """Root mean square of ``err`` (shape ``(N,)``, signed allowed, no NaN)."""
    e, _ = _errors(err, nonneg=False)
    return float(np.sqrt(np.mean(e * e)))


def error_stats(err, *, nan: str = "raise") -> dict:
    """Summary statistics of radial errors.

    Parameters
    ----------
    err
        Radial errors, shape ``(N,)``, metres (an :class:`ErrorSeries` works too).
    nan
        ``"raise"`` (default): NaN is a ValueError. ``"omit"``: NaN values are
        left out and counted in ``n_omitted``.

    Returns
    -------
    dict
        ``n`` (values used), ``n_omitted``, ``mean``, ``median`` (numpy's, the
        average of the middle two for even ``n``), ``rmse``, ``cep50``, ``cep95``
        (rule of :func:`cep`), ``max``; metres.
    """
    e, n_nan = _errors(err, nan=nan)
    return {"n": int(e.size), "n_omitted": n_nan, "mean": float(np.mean(e)), "median": float(np.median(e)),
            "rmse": rmse(e), "cep50": cep50(e), "cep95": cep95(e), "max": float(np.max(e))}


def epoch_summary(epochs: pd.DataFrame, *, by: str = "estimator", order: Sequence[str] = ()) -> pd.DataFrame:
    """Coverage beside accuracy per estimator, from an epoch table scored on common epochs.

    Parameters
    ----------
    epochs
        One row per estimator and scored epoch: ``by`` and ``err_m`` (NaN = the
        estimator produced no position at that epoch), metres.
    by
        The column naming the estimator.
    order
        Estimators listed first, in this order; the others follow in order of appearance.

    Returns
    -------
    pandas.DataFrame
        Indexed by estimator: ``n_epochs``, ``coverage`` (fraction with a position),
        ``median_m`` and ``p90_m`` over the covered epochs, and ``p90_failed_counted_m``
        -- the 90th percentile (inverted CDF) when an epoch without a position counts
        as an unbounded error (``inf`` below 90 % coverage).

    Notes
    -----
    Scored by :func:`uwbwb.metrics.score_epochs` with each estimator on its own rows
    (``compare=False``): the table is expected to hold the same epochs for every estimator already.
    """
    names = list(dict.fromkeys(epochs[by]))
    ordered = [h for h in order if h in names] + [h for h in names if h not in order]
    scores = score_epochs({h: epochs.loc[epochs[by] == h, "err_m"].to_numpy(float) for h in ordered}, compare=False)
    table = scores.table(own={"median_m": np.median, "p90_m": lambda e: np.quantile(e, 0.9)},
                         failed_counted={"p90_failed_counted_m": lambda e: np.quantile(e, 0.9, method="inverted_cdf")},
                         index=by)
    return table[["n_epochs", "coverage", "median_m", "p90_m", "p90_failed_counted_m"]]


#: The block rule: a block is BLOCK_LAG_FACTOR × the first lag at which the autocorrelation of the series falls
#: below ACF_LEVEL (an assumption: beyond it, epochs count as independent).
ACF_LEVEL = 0.05
BLOCK_LAG_FACTOR = 2
#: Fewest blocks for an interval, a standard error or a verdict.
MIN_BLOCKS = 10


def block_length(x: np.ndarray, *, acf_level: float = ACF_LEVEL) -> int:
    """Block length in epochs: :data:`BLOCK_LAG_FACTOR` × the first lag at which the autocorrelation of
    ``x`` (``(n,)``, consecutive epochs) falls below ``acf_level``; at least :data:`BLOCK_LAG_FACTOR`."""
    d = np.asarray(x, float)
    d = d - d.mean() if d.size else d
    var = float(np.dot(d, d))
    if d.size < 3 or var <= 0:
        return BLOCK_LAG_FACTOR
    f = np.fft.rfft(d, 2 * d.size)
    acf = np.fft.irfft(f * np.conj(f))[: d.size] / var
    below = np.flatnonzero(acf < acf_level)
    lag = int(below[0]) if below.size else d.size
    return BLOCK_LAG_FACTOR * max(lag, 1)


def block_ids(series: Sequence[np.ndarray]) -> tuple[np.ndarray, int]:
    """Block of every epoch of the concatenated ``series`` (one array per segment — a tag, a run —, consecutive
    epochs): the package's one block rule.

    Each series is cut into contiguous blocks of :func:`block_length` epochs (its own rule; a trailing piece
    shorter than a block joins the block before it). Returns the block index per epoch ``(sum n,)`` and the
    number of blocks."""
    ids, nb = [], 0
    for x in series:
        n = len(x)
        if n == 0:
            continue
        L = block_length(x)
        k = max(1, n // L)
        ids.append(nb + np.minimum(np.arange(n) // L, k - 1))
        nb += k
    return (np.concatenate(ids) if ids else np.zeros(0, int)), nb


def interval_side(lo: float, hi: float, null: float = 0.0) -> str:
    """Where an interval lies against the value of a null hypothesis: the package's one interval → verdict rule.

    ``"below"`` when ``hi < null``, ``"above"`` when ``lo > null`` (the interval rejects the null), ``"contains"``
    when ``lo ≤ null ≤ hi`` (it does not), ``"none"`` when either end is not finite (no interval, e.g. fewer than
    :data:`MIN_BLOCKS` blocks). Each table names its outcomes from these four; none decides otherwise."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "none"
    return "below" if hi < null else "above" if lo > null else "contains"


def tied_ranks(order: Sequence[str], better) -> dict[str, int]:
    """Ranks of the items of ``order`` (sorted by a point value, lowest first) resolved no further than the
    decided pairs ``better`` (``(a, b)``: ``a`` resolved better than ``b``, e.g. by :func:`interval_side` of their
    difference): the package's one tie-aware ranking rule. An item's rank is 1 + the number ranked above it; it
    is ranked below the items before it only where every one of them is resolved better than it and every item
    after it, else it shares the rank of the one before (a tie). A decided pair inside a tie (an order that is not
    transitive: a ≈ b, a ≈ c, yet b better than c) is not shown by the ranks."""
    order = list(order)
    rank: dict[str, int] = {}
    for i, h in enumerate(order):
        cut = all((a, b) in better for a in order[:i] for b in order[i:])
        rank[h] = i + 1 if cut else rank[order[i - 1]]
    return rank


def seeds_interval(x, *, prob: float = 0.95) -> dict:
    """Mean of ``x`` (one value per independent seed) and its two-sided Student-t interval at ``prob``: the
    package's one interval over seeds (the block bootstrap is its one interval over correlated epochs).

    Non-finite values are left out. Returns ``{"mean", "lo", "hi", "n"}``; with fewer than two values the
    interval is NaN (no verdict by :func:`interval_side`).
    """
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return {"mean": np.nan, "lo": np.nan, "hi": np.nan, "n": 0}
    m = float(x.mean())
    if n < 2:
        return {"mean": m, "lo": np.nan, "hi": np.nan, "n": n}
    from scipy import stats         # imported when used: scipy.stats costs seconds wherever uwbwb.metrics is imported

    h = float(stats.t.ppf(0.5 + prob / 2, n - 1) * x.std(ddof=1) / math.sqrt(n))
    return {"mean": m, "lo": m - h, "hi": m + h, "n": n}


def block_bootstrap_difference(err_a, err_b, *, rng: np.random.Generator, n_boot: int = 2000,
                               level: float = 0.95, statistic: str = "rmse", blocks: str = "acf") -> dict:
    """``RMSE(a) − RMSE(b)`` on paired epochs and its block-bootstrap interval: the package's one interval rule
    for a difference of two methods on the same time series.

    ``statistic="median"`` compares medians instead (``median(a) − median(b)``, for tables that rank by the
    median error): the same blocks, cut over the paired difference ``e_a − e_b``, and the same replicates;
    the keys are then ``median_a_m`` and ``median_b_m`` in place of ``rmse_a_m`` and ``rmse_b_m``.

    ``blocks="segment"`` makes each segment one block (a cluster bootstrap): for segments whose errors share an
    offset the autocorrelation of a short, mean-centred segment cannot see — e.g. stops of one simulated
    experiment, which share its per-pair range biases. The default ``"acf"`` cuts segments by :func:`block_ids`.

    Parameters
    ----------
    err_a, err_b
        Error norms of two methods on the same epochs, m: one ``(n,)`` array in time order, or a list of
        them (one per tag or run, paired segment by segment).

    Returns
    -------
    dict
        ``rmse_a_m``, ``rmse_b_m``, ``diff_m``, ``lo_m``, ``hi_m``, ``n`` (epochs), ``n_blocks``, and the
        interval of the ratio ``RMSE(a) / RMSE(b)`` from the same replicates, ``ratio_lo``, ``ratio_hi``. The blocks
        follow :func:`block_ids` over the paired difference ``e_a² − e_b²`` of each segment (so the correlation
        of a tracking filter's errors is kept); a replicate draws as many blocks as there are, with
        replacement, pairs together. Fewer than :data:`MIN_BLOCKS` blocks: NaN interval (no verdict).
    """
    seg_a = [np.asarray(x, float) for x in err_a] if isinstance(err_a, (list, tuple)) else [np.asarray(err_a, float)]
    seg_b = [np.asarray(x, float) for x in err_b] if isinstance(err_b, (list, tuple)) else [np.asarray(err_b, float)]
    if len(seg_a) != len(seg_b) or any(a.shape != b.shape or a.ndim != 1 for a, b in zip(seg_a, seg_b)):
        raise ValueError(f"paired errors must be 1-D arrays of the same lengths, got {[a.shape for a in seg_a]} "
                         f"and {[b.shape for b in seg_b]}")
    if statistic not in ("rmse", "median"):
        raise ValueError(f"statistic must be 'rmse' or 'median', got {statistic!r}")
    if blocks not in ("acf", "segment"):
        raise ValueError(f"blocks must be 'acf' or 'segment', got {blocks!r}")
    power = 2 if statistic == "rmse" else 1
    if blocks == "segment":
        kept = [k for k, a in enumerate(seg_a) if a.size]
        ids = np.concatenate([np.full(seg_a[k].size, j) for j, k in enumerate(kept)]) if kept else np.zeros(0, int)
        nb = len(kept)
    else:
        ids, nb = block_ids([a ** power - b ** power for a, b in zip(seg_a, seg_b)])
    if statistic == "median":
        return _median_difference(seg_a, seg_b, ids, nb, rng=rng, n_boot=n_boot, level=level)
    sa, sb = [a ** 2 for a in seg_a], [b ** 2 for b in seg_b]
    xa, xb = (np.concatenate(sa), np.concatenate(sb)) if sa else (np.zeros(0), np.zeros(0))
    out = {"n": int(xa.size), "n_blocks": 0, "lo_m": np.nan, "hi_m": np.nan, "ratio_lo": np.nan, "ratio_hi": np.nan}
    if xa.size == 0:
        return {**out, "rmse_a_m": np.nan, "rmse_b_m": np.nan, "diff_m": np.nan}
    rmse_a, rmse_b = float(np.sqrt(xa.mean())), float(np.sqrt(xb.mean()))
    out.update(rmse_a_m=rmse_a, rmse_b_m=rmse_b, diff_m=rmse_a - rmse_b)
    out["n_blocks"] = nb
    if nb < MIN_BLOCKS:
        return out
    ba, bb, bn = np.bincount(ids, xa, nb), np.bincount(ids, xb, nb), np.bincount(ids, minlength=nb)
    pick = rng.integers(0, nb, (n_boot, nb))
    n = bn[pick].sum(axis=1)
    d = np.sqrt(ba[pick].sum(axis=1) / n) - np.sqrt(bb[pick].sum(axis=1) / n)
    alpha = round((1 - level) / 2, 12)
    lo, hi = (float(v) for v in np.quantile(d, [alpha, 1 - alpha]))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.sqrt(ba[pick].sum(axis=1) / bb[pick].sum(axis=1))
    r_lo, r_hi = (float(v) for v in np.quantile(ratio, [alpha, 1 - alpha]))
    return {**out, "lo_m": lo, "hi_m": hi, "ratio_lo": r_lo, "ratio_hi": r_hi}


def _median_difference(seg_a, seg_b, ids, nb, *, rng, n_boot, level) -> dict:
    """:func:`block_bootstrap_difference` with ``statistic="median"``: each replicate takes the epochs of as many
    blocks as there are, drawn with replacement, pairs together, and differences the two medians."""
    xa = np.concatenate(seg_a) if seg_a else np.zeros(0)
    xb = np.concatenate(seg_b) if seg_b else np.zeros(0)
    out = {"n": int(xa.size), "n_blocks": 0, "lo_m": np.nan, "hi_m": np.nan, "ratio_lo": np.nan, "ratio_hi": np.nan}
    if xa.size == 0:
        return {**out, "median_a_m": np.nan, "median_b_m": np.nan, "diff_m": np.nan}
    med_a, med_b = float(np.median(xa)), float(np.median(xb))
    out.update(median_a_m=med_a, median_b_m=med_b, diff_m=med_a - med_b)
    out["n_blocks"] = nb
    if nb < MIN_BLOCKS:
        return out
    order = np.argsort(ids, kind="stable")
    counts = np.bincount(ids, minlength=nb)
    pick = rng.integers(0, nb, (n_boot, nb))
    d, ratio = _median_replicates(xa[order], xb[order], np.cumsum(counts) - counts, counts, pick)
    alpha = round((1 - level) / 2, 12)
    lo, hi = (float(v) for v in np.quantile(d, [alpha, 1 - alpha]))
    r_lo, r_hi = (float(v) for v in np.quantile(ratio, [alpha, 1 - alpha]))
    return {**out, "lo_m": lo, "hi_m": hi, "ratio_lo": r_lo, "ratio_hi": r_hi}

@numba.njit(cache=True, nogil=True)
def _median_replicates(xa, xb, starts, counts, pick):
    """The replicates of :func:`_median_difference`: replicate ``r`` gathers the epochs of blocks ``pick[r]`` (block
    ``k`` holds ``xa[starts[k]:starts[k] + counts[k]]``, pairs together) and returns ``median(a) − median(b)`` and
    ``median(a) / median(b)`` (NaN where the latter is not positive). A compiled loop; its definition, one
    ``np.median`` per replicate, is its declared twin (``metrics._median_replicates``)."""
    n_boot, nb = pick.shape
    d, ratio = np.empty(n_boot), np.empty(n_boot)
    for r in range(n_boot):
        m = 0
        for j in range(nb):
            m += counts[pick[r, j]]
        a, b = np.empty(m), np.empty(m)
        k = 0
        for j in range(nb):
            s = starts[pick[r, j]]
            for i in range(counts[pick[r, j]]):
                a[k], b[k] = xa[s + i], xb[s + i]
                k += 1
        ma, mb = np.median(a), np.median(b)
        d[r] = ma - mb
        ratio[r] = ma / mb if mb > 0 else np.nan
    return d, ratio
