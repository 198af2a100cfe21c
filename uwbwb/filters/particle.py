"""Batched particle-filter building blocks: log-weights, ESS, resampling.

Conventions (``GUIDE.md``): particles have shape ``(..., K, n_x)`` and
log-weights ``(..., K)``; the leading axes are batch axes (Monte Carlo trials,
parameter values, filter variants), so one call serves a whole sweep. Weights
are kept as logs and normalised with log-sum-exp. Resamplers never touch a
global random state: they take ``rng`` (a :class:`numpy.random.Generator`), or
the uniform variates themselves, so the caller decides where randomness comes from.

Functions
---------
normalise_log_weights   log-weights that sum to one (eq. 10 of paper 000), and the log normaliser
coefficient_of_variation   eq. 12 of paper 000, ``CV = (1/K) Σ (K w − 1)²``
effective_sample_size   ``ESS = K / (1 + CV) = 1 / Σ w²``
weighted_mean           ``Σ w x`` (eq. 11 of paper 000)
systematic_counts       copy counts of systematic resampling (O(K), no search)
systematic_indices, multinomial_indices    ancestor indices from given uniforms
resample_indices        the same, drawing the uniforms from ``rng``
resample                resample the rows whose ESS fell below ``threshold · K``
roughen                 jitter resampled particles (Gordon, Salmond & Smith 1993)
tempering_exponent      the largest likelihood exponent ``β ≤ 1`` that keeps a target ESS

The engine
----------
:class:`ParticleFilter` runs a filter from a model's pieces (transition sampler, log-likelihood,
estimate; optional constraint, tempering and roughening) with these blocks, one epoch in
:meth:`~ParticleFilter.step` (kept as an :class:`Epoch`) or a whole recording in
:meth:`~ParticleFilter.run` (a :class:`ParticleRun`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, NamedTuple

import numba
import numpy as np

from ..validate import choice, number, probability

RESAMPLERS = ("systematic", "multinomial")


def _as_float(a) -> np.ndarray:
    a = np.asarray(a)
    return a if a.dtype.kind == "f" else a.astype(float)


def _check_particles(a: np.ndarray, name: str) -> None:
    """At least one particle along the last axis (a filter of zero particles has no estimate)."""
    if a.ndim == 0 or a.shape[-1] == 0:
        raise ValueError(f"{name} must have shape (..., K) with K >= 1 particles, got shape {a.shape}")


def _check_weights(w: np.ndarray) -> None:
    """Resampling weights: at least one particle, finite, non-negative, a positive sum per row."""
    _check_particles(w, "w")
    total = np.sum(w, axis=-1)
    if not (np.all(w >= 0) and np.all(np.isfinite(total)) and np.all(total > 0)):   # NaN fails w >= 0
        raise ValueError("w must hold finite, non-negative weights with a positive sum in every row "
                         "(normalised weights, e.g. exp of normalise_log_weights)")


def normalise_log_weights(logw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalise log-weights over the last axis with log-sum-exp.

    Parameters
    ----------
    logw
        Unnormalised log-weights, shape ``(..., K)``. ``-inf`` is a zero weight;
        a row of only ``-inf`` is an error (the filter has lost track).

    Returns
    -------
    logw_normalised
        Shape ``(..., K)``, ``logsumexp = 0`` along the last axis.
    log_normaliser
        ``log Σ exp(logw)``, shape ``(...)``.
    """
    logw = _as_float(logw)
    _check_particles(logw, "logw")
    m = np.max(logw, axis=-1, keepdims=True)
    if not np.all(np.isfinite(m)):
        raise ValueError("normalise_log_weights: a row has no finite log-weight (all particles have zero weight)")
    lse = m + np.log(np.sum(np.exp(logw - m), axis=-1, keepdims=True))
    return logw - lse, lse[..., 0]


def _normalised_weights(logw: np.ndarray) -> np.ndarray:
    return np.exp(normalise_log_weights(logw)[0])


def coefficient_of_variation(logw: np.ndarray) -> np.ndarray:
    """Coefficient of variation of the weights, eq. 12 of paper 000.

    ``CV = VAR(w) / E[w]² = (1/K) Σ_k (K w_k − 1)²`` with the normalised weights ``w``.

    Parameters
    ----------
    logw
        Log-weights, shape ``(..., K)`` (normalised or not).

    Returns
    -------
    ndarray, shape ``(...)``; 0 for equal weights, ``K − 1`` when one particle holds all weight.
    """
    w = _normalised_weights(logw)
    K = w.shape[-1]
    return np.mean((K * w - 1.0) ** 2, axis=-1)


def effective_sample_size(logw: np.ndarray, *, normalised: bool = False) -> np.ndarray:
    """Effective sample size ``K / (1 + CV) = 1 / Σ w²`` (paper 000, after eq. 12).

    The two forms are algebraically equal: ``1 + CV = K Σ w²`` for normalised ``w``.

    Parameters
    ----------
    logw
        Log-weights, shape ``(..., K)``.
    normalised
        True: ``logw`` is already normalised (as :func:`normalise_log_weights` returns it), so
        ``w = exp(logw)`` is used as is, one log-sum-exp pass fewer. False (default): normalise
        first. The two agree to rounding (a second log-sum-exp moves the last bits).

    Returns
    -------
    ndarray, shape ``(...)``, in ``[1, K]``.
    """
    return _ess(np.exp(_as_float(logw)) if normalised else _normalised_weights(logw))


def _ess(w: np.ndarray) -> np.ndarray:
    """``1 / Σ w²`` of normalised weights ``w`` (..., K)."""
    return 1.0 / np.sum(w * w, axis=-1)


def weighted_mean(particles: np.ndarray, logw: np.ndarray) -> np.ndarray:
    """Posterior mean ``Σ_k w_k X_k`` (eq. 11 of paper 000).

    Parameters
    ----------
    particles, logw
        Particles ``(..., K, n_x)`` and their log-weights ``(..., K)`` (normalised or not).

    Returns
    -------
    ndarray, shape ``(..., n_x)``
    """
    w = _normalised_weights(logw)
    return np.einsum("...k,...kn->...n", w, particles)


def _cdf(w: np.ndarray) -> np.ndarray:
    """Row-wise cumulative weights (float32 stays float32) scaled so the last entry is exactly 1."""
    dtype = np.float32 if w.dtype == np.float32 else np.float64
    c = np.cumsum(w, axis=-1, dtype=dtype)
    c /= c[..., -1:]
    return c


def systematic_counts(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Copy counts of systematic resampling: how many new particles descend from each particle.

    With cumulative weights ``c`` and positions ``(j + u)/K``, ``j = 0 … K−1``, particle ``k``
    is copied ``n_k = N_k − N_{k−1}`` times, ``N_k = #{j : (j + u)/K < c_k} = ⌈K c_k − u⌉``.
    Each ``n_k`` is ``⌊K w_k⌋`` or ``⌈K w_k⌉``; the counts of a row sum to K. O(K), no search.

    Parameters
    ----------
    w
        Normalised weights, shape ``(..., K)`` (float32 is kept in float32).
    u
        One uniform variate in ``[0, 1)`` per row, shape ``(...)``.

    Returns
    -------
    ndarray of intp, shape ``(..., K)``
    """
    w = np.asarray(w)
    _check_weights(w)
    K = w.shape[-1]
    if K >= 2 ** 31 - 1:
        raise ValueError(f"too many particles for int32 counts: {K}")
    dtype = np.float32 if w.dtype == np.float32 else np.float64
    u = np.asarray(u, dtype)
    if u.shape != w.shape[:-1]:
        raise ValueError(f"systematic resampling needs one uniform per row, shape {w.shape[:-1]}, got {u.shape}")
    c = np.cumsum(w, axis=-1, dtype=dtype)
    # ⌈K c − u⌉ = ⌊K c + 1 − u⌋ (except on a null set), and K c + 1 − u > 0, so truncation floors
    c *= K / c[..., -1:]
    c += (1 - u)[..., None]
    # int32 here (converting float32 to int64 is several times slower), intp for the counts
    # (np.repeat is several times slower with int32 repeats)
    n_below = c.astype(np.int32)
    np.minimum(n_below, K, out=n_below)       # guards against rounding of K·c_k only
    n_below[..., -1] = K
    counts = np.empty(n_below.shape, np.intp)
    counts[..., 0] = n_below[..., 0]
    np.subtract(n_below[..., 1:], n_below[..., :-1], out=counts[..., 1:])
    return counts


def systematic_indices(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Ancestor indices by systematic resampling.

    Particle ``j`` of the new set is the ancestor whose cumulative-weight interval
    ``[c_{k−1}, c_k)`` holds ``(j + u) / K`` (see :func:`systematic_counts`).

    Parameters
    ----------
    w
        Normalised weights, shape ``(..., K)``.
    u
        One uniform variate in ``[0, 1)`` per row, shape ``(...)``.

    Returns
    -------
    ndarray of intp, shape ``(..., K)``: ancestor indices, sorted within each row.
    """
    w = np.asarray(w)
    K = w.shape[-1]
    counts = systematic_counts(w, u).reshape(-1)
    rows = counts.size // K
    ancestors = np.repeat(np.arange(rows * K), counts) - np.repeat(K * np.arange(rows), K)
    return ancestors.reshape(w.shape)


def multinomial_indices(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Ancestor indices by multinomial resampling ("select with replacement").

    Each new particle independently picks ancestor ``k`` with probability ``w_k``:
    the ancestor of variate ``u`` is the ``k`` with ``c_{k−1} ≤ u < c_k``. The
    variates are sorted first (the ancestors come out sorted, as in the classic
    select-with-replacement walk; the order of particles carries no meaning).

    Parameters
    ----------
    w
        Normalised weights, shape ``(..., K)``.
    u
        Independent uniform variates in ``[0, 1)``, shape ``(..., K)``.

    Returns
    -------
    ndarray of intp, shape ``(..., K)``
    """
    w = np.asarray(w)
    _check_weights(w)
    u = np.asarray(u, np.float64)
    if u.shape != w.shape:
        raise ValueError(f"multinomial_indices: need K uniforms per row, shape {w.shape}, got {u.shape}")
    K = w.shape[-1]
    c = _cdf(w).astype(np.float64).reshape(-1, K)
    rows = c.shape[0]
    # One search over all rows: offset row r by 2r so the concatenated CDFs stay sorted.
    offset = 2.0 * np.arange(rows)[:, None]
    keys = np.sort(u.reshape(-1, K), axis=-1) + offset
    flat = np.searchsorted((c + offset).ravel(), keys.ravel(), side="right")
    idx = flat.reshape(rows, K) - K * np.arange(rows)[:, None]
    np.clip(idx, 0, K - 1, out=idx)
    return idx.reshape(w.shape)


def resample_indices(logw: np.ndarray, *, rng: np.random.Generator, method: str = "systematic") -> np.ndarray:
    """Ancestor indices for every row, with the uniform variates drawn from ``rng``.

    Parameters
    ----------
    logw
        Log-weights, shape ``(..., K)``.
    method
        ``"systematic"`` (one uniform per row, lowest variance) or ``"multinomial"``
        (K uniforms per row; the "select with replacement" of paper 000's ref. [10]).

    Returns
    -------
    ndarray of intp, shape ``(..., K)``
    """
    choice("method", method, RESAMPLERS)
    return _indices(_normalised_weights(logw), rng, method)


def _indices(w: np.ndarray, rng: np.random.Generator, method: str) -> np.ndarray:
    """:func:`resample_indices` from normalised weights ``w``."""
    if method == "systematic":
        return systematic_indices(w, rng.random(w.shape[:-1]))
    return multinomial_indices(w, rng.random(w.shape))


def resample(particles: np.ndarray, logw: np.ndarray, *, rng: np.random.Generator,
             threshold: float = 0.5, method: str = "systematic"
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Resample the rows whose effective sample size is below ``threshold · K``.

    Parameters
    ----------
    particles, logw
        As for :func:`weighted_mean`.
    threshold
        Fraction of ``K`` (paper 000 uses 0.5). 1 resamples every row at every call, 0 never.
    method
        See :func:`resample_indices`.

    Returns
    -------
    particles, logw
        New arrays; resampled rows get equal weights ``−log K``.
    resampled
        Shape ``(...)``, bool: which rows were resampled.
    """
    threshold = probability("threshold", threshold, open_interval=False)
    choice("method", method, RESAMPLERS)
    particles = np.asarray(particles)
    logw = _as_float(logw)
    if particles.shape[:-1] != logw.shape:
        raise ValueError(f"resample: particles {particles.shape} and logw {logw.shape} do not match")
    w = _normalised_weights(logw)
    need = _ess(w) < threshold * logw.shape[-1]
    return (*_resample_rows(particles, logw, w, need, rng=rng, method=method), need)


def _resample_rows(particles: np.ndarray, logw: np.ndarray, w: np.ndarray, need: np.ndarray, *,
                   rng: np.random.Generator, method: str) -> tuple[np.ndarray, np.ndarray]:
    """New particles and log-weights with the rows ``need`` resampled (``w``: the normalised weights of ``logw``)."""
    particles = np.asarray(particles)
    K, n_x = particles.shape[-2:]
    if not np.any(need):
        return particles.copy(), logw.copy()
    rows = np.flatnonzero(need)
    if method == "systematic":                   # the rows in place in a copy, one compiled pass
        _check_weights(w[need])
        dtype = np.dtype(np.float32 if w.dtype == np.float32 else np.float64)
        u = rng.random(rows.size).astype(dtype)     # as _indices draws them: one uniform per row, in row order
        particles, logw = np.array(particles, order="C"), logw.copy()
        x = particles.reshape(-1, K, n_x)
        _systematic(rows, 1 - u, dtype.type(K), np.ascontiguousarray(w, dtype).reshape(-1, K),
                    tuple(x[..., c] for c in range(n_x)), logw.reshape(-1, K), logw.dtype.type(-np.log(K)))
        return particles, logw
    idx = _indices(w[need], rng, method)                                # (rows, K) ancestors, row by row
    picked = particles.reshape(-1, n_x)[(idx + K * rows[:, None]).ravel()]
    if rows.size == need.size:                                          # every row: no copy of the old cloud
        return picked.reshape(particles.shape), np.full(logw.shape, -np.log(K), logw.dtype)
    particles, logw = particles.copy(), logw.copy()
    particles[need] = picked.reshape(idx.shape + (n_x,))
    logw[need] = -np.log(K)
    return particles, logw


@numba.njit(cache=True, nogil=True)
def _systematic(rows, one_minus_u, Kf, w, state, logw, log_k):
    """Systematic resampling of the flagged rows in place, as :func:`systematic_counts` (float cumulative sum
    ``c``, ``⌊c K / c_K + 1 − u⌋`` descendants below) and ``np.repeat``'s gather: weights ``w`` ``(B, K)``, the
    state as a tuple of ``(B, K)`` arrays (one per component), log-weights ``(B, K)`` set to ``log_k``."""
    K = w.shape[1]
    c, tmp = np.empty(K, w.dtype), np.empty(K, state[0].dtype)
    below, anc = np.empty(K + 1, np.int64), np.empty(K, np.int64)
    for n in range(rows.size):
        r = rows[n]
        c[0] = w[r, 0]
        for i in range(1, K):
            c[i] = c[i - 1] + w[r, i]
        scale = Kf / c[K - 1]
        # particle i has min(⌊c_i K / c_K + 1 − u⌋, K) new particles below its last copy (K for the last):
        # the ancestor of new particle j is the number of particles with at most j below
        below[:] = 0
        for i in range(K - 1):
            below[min(np.int64(c[i] * scale + one_minus_u[n]), K)] += 1
        run = 0
        for i in range(K):
            run += below[i]
            anc[i] = run
        for a in state:
            for i in range(K):
                tmp[i] = a[r, anc[i]]
            for i in range(K):                   # an explicit loop: faster than numba's slice assignment
                a[r, i] = tmp[i]
        logw[r, :] = log_k


def roughen(particles: np.ndarray, *, rng: np.random.Generator, k: float = 0.2,
            rows: np.ndarray | None = None) -> np.ndarray:
    """Roughening (Gordon, Salmond & Smith 1993): jitter resampled particles against impoverishment.

    Each component ``j`` gets independent noise ``N(0, σ_j²)`` with
    ``σ_j = k · E_j · K^(−1/n_x)``, ``E_j`` the spread (max − min) of component ``j``
    over the row's particles.

    Parameters
    ----------
    particles
        Shape ``(..., K, n_x)``.
    k
        Tuning constant (Gordon et al. use 0.2).
    rows
        Optional boolean mask over the batch axes ``(...)``: only these rows are jittered.

    Returns
    -------
    ndarray, same shape: a new array.
    """
    k = number("k", k, minimum=0.0)
    particles = np.asarray(particles, float)
    K, n_x = particles.shape[-2:]
    if K == 0 or n_x == 0:
        raise ValueError(f"particles must have shape (..., K, n_x) with K >= 1 and n_x >= 1, got {particles.shape}")
    batch = particles.shape[:-2]
    # one row per batch element; rows=None is every row, a factor 1.0 (0.0: a row left as it is)
    mask = np.ones(batch) if rows is None else np.broadcast_to(np.asarray(rows, bool), batch).astype(float)
    noise = rng.standard_normal(particles.shape)
    out = np.empty(particles.shape)
    _roughen_rows(np.ascontiguousarray(particles).reshape(-1, K, n_x), noise.reshape(-1, K, n_x), k,
                  K ** (-1.0 / n_x), mask.reshape(-1), rows is not None, out.reshape(-1, K, n_x))
    return out


@numba.njit(cache=True, nogil=True)
def _roughen_rows(x, noise, k, scale, mask, masked, out):
    """:func:`roughen` on rows ``(B, K, n_x)``: ``σ_j = k · (max − min of component j) · scale`` (times the row's
    ``mask`` when ``masked``), ``out = x + σ_j · noise``; the operations of the NumPy definition in its order."""
    B, K, n_x = x.shape
    lo, hi, nan = np.empty(n_x), np.empty(n_x), np.empty(n_x, np.bool_)
    for b in range(B):
        for j in range(n_x):
            lo[j] = hi[j] = x[b, 0, j]
            nan[j] = False
        for i in range(K):                  # max and min are exact: any order gives NumPy's spread
            for j in range(n_x):
                v = x[b, i, j]
                if v < lo[j]:
                    lo[j] = v
                if v > hi[j]:
                    hi[j] = v
                if v != v:
                    nan[j] = True
        for j in range(n_x):
            hi[j] = k * (np.nan if nan[j] else hi[j] - lo[j]) * scale       # σ_j
            if masked:
                hi[j] = hi[j] * mask[b]
        for i in range(K):
            for j in range(n_x):
                out[b, i, j] = x[b, i, j] + hi[j] * noise[b, i, j]


def tempering_exponent(logw: np.ndarray, ll: np.ndarray, min_ess_fraction: float, *,
                       full_ess: np.ndarray | None = None) -> np.ndarray:
    """Per row, the largest ``β ≤ 1`` with ``ESS(logw + β·ll) ≥ min_ess_fraction · K`` (likelihood tempering).

    ``ESS(β)`` falls from the prior's ESS (β = 0) to the full update's (β = 1). Where the full update
    keeps the target, β = 1; elsewhere 16 bisection steps on ``[0, 1]`` keep the lower end (resolution
    2⁻¹⁶), so the update ``likelihood^β`` gives up only the sharpness the cloud cannot resolve.

    Parameters
    ----------
    logw
        Prior log-weights, shape ``(..., K)``; −inf is allowed.
    ll
        Log-likelihood of each particle, shape ``(..., K)``, finite.
    min_ess_fraction
        Target as a fraction of ``K`` in ``[0, 1)``; 0 = off (β = 1 everywhere).
    full_ess
        ``ESS(logw + ll)`` (:func:`effective_sample_size`), shape ``(...)``, when the caller has it already.

    Returns
    -------
    ndarray, shape ``(...)``
    """
    beta = np.ones(np.shape(logw)[:-1])
    if min_ess_fraction <= 0:
        return beta
    target = min_ess_fraction * np.shape(logw)[-1]
    need = (effective_sample_size(logw + ll) if full_ess is None else full_ess) < target
    if need.any():
        lo, hi = np.zeros(int(need.sum())), np.ones(int(need.sum()))
        lw, l = logw[need], ll[need]
        for _ in range(16):
            mid = 0.5 * (lo + hi)
            ok = effective_sample_size(lw + mid[:, None] * l) >= target
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        beta[need] = lo
    return beta


class Epoch(NamedTuple):
    """What :meth:`ParticleFilter.step` keeps of one epoch; arrays of the batch shape ``(...)``.

    ``estimate`` is what the filter's ``estimate`` returned after the update; ``ess`` the effective
    sample size after the update, before resampling; ``resampled`` and ``restarted`` (by the
    constraint) flags; ``beta`` the tempering exponent (1 = the full likelihood).
    """

    estimate: Any
    ess: np.ndarray
    resampled: np.ndarray
    restarted: np.ndarray
    beta: np.ndarray


class ParticleRun(NamedTuple):
    """The epochs of :meth:`ParticleFilter.run`, with the time axis right after the batch axes.

    ``estimate`` has shape ``(..., T, ...)`` (a tuple of such arrays when ``estimate`` returns a
    tuple), ``ess``, ``resampled``, ``restarted``, ``beta`` shape ``(..., T)``; ``particles`` and
    ``logw`` are the cloud after the last epoch.
    """

    estimate: Any
    ess: np.ndarray
    resampled: np.ndarray
    restarted: np.ndarray
    beta: np.ndarray
    particles: np.ndarray
    logw: np.ndarray


def _stack(items: list, axis: int):
    if isinstance(items[0], tuple):
        return tuple(np.stack(column, axis=axis) for column in zip(*items))
    return np.stack(items, axis=axis)


@dataclass(frozen=True)
class ParticleFilter:
    """A bootstrap particle filter assembled from a model's pieces, batched over the leading axes.

    One epoch (:meth:`step`), measurement ``z`` after ``dt_s`` seconds:

    1. predict ``X ← propagate(X, dt_s, rng=rng)`` (skipped when ``dt_s`` is None);
    2. constrain (optional) ``X, log w, restarted ← constrain(X, log w, rng=rng)``: −inf for an
       impossible particle, a fresh cloud for a row that has none left;
    3. weight ``log w ← log w + β log p(z | X)``, normalised by log-sum-exp (eqs. 8–10 of paper 000);
       ``β = 1``, or :func:`tempering_exponent` when ``temper_ess > 0``;
    4. keep ``estimate(X, log w)`` and the ESS (eq. 12);
    5. resample the rows with ``ESS < ess_fraction · K`` as :func:`resample` does (its ESS normalises the
       weights once more; with ``ess_renormalises=False`` the recorded ESS and that one may differ
       in the last bits, so a row exactly at the threshold can be recorded on the other side of it),
       then roughen those rows when ``roughening > 0`` (:func:`roughen`).

    Every random number comes from the one ``rng``, in that order (prediction, constraint,
    resampling, roughening); a batch shares it, one draw per piece for the whole batch.

    Attributes
    ----------
    propagate
        ``propagate(particles (..., K, n_x), dt_s, *, rng) -> particles``: the transition sampler
        (e.g. :meth:`uwbwb.models.motion.VelocityKick.step`).
    log_likelihood
        ``log_likelihood(particles, z) -> (..., K)``: log-density of one epoch's measurement ``z``.
    estimate
        ``estimate(particles, logw)`` with normalised ``logw``: an array or a tuple of arrays of the
        batch shape first (default :func:`weighted_mean`, eq. 11).
    ess_fraction, method
        Resampling rule (:func:`resample`): threshold as a fraction of ``K`` and the resampler.
    roughening
        Roughening constant (:func:`roughen`, ≥ 0; 0 = none).
    temper_ess
        Minimum ESS of an update as a fraction of ``K`` in ``[0, 1)`` (0 = the full likelihood always).
    constrain
        None, or ``constrain(particles, logw, *, rng) -> (particles, logw, restarted (...))``.
    ess_renormalises
        The ESS diagnostic normalises the log-weights once more (True, the :func:`effective_sample_size`
        default) or reads them as normalised (False); the two differ only in the last bits.
    """

    propagate: Callable
    log_likelihood: Callable
    estimate: Callable = weighted_mean
    ess_fraction: float = 0.5
    method: str = "systematic"
    roughening: float = 0.0
    temper_ess: float = 0.0
    constrain: Callable | None = None
    ess_renormalises: bool = True

    def __post_init__(self):
        for name in ("propagate", "log_likelihood", "estimate"):
            if not callable(getattr(self, name)):
                raise ValueError(f"ParticleFilter: {name} must be callable, got {getattr(self, name)!r}")
        if self.constrain is not None and not callable(self.constrain):
            raise ValueError(f"ParticleFilter: constrain must be None or callable, got {self.constrain!r}")
        object.__setattr__(self, "ess_fraction", probability("ess_fraction", self.ess_fraction, open_interval=False))
        choice("method", self.method, RESAMPLERS)
        object.__setattr__(self, "roughening", number("roughening", self.roughening, minimum=0.0))
        t = probability("temper_ess", self.temper_ess, open_interval=False)
        if t >= 1.0:
            raise ValueError(f"temper_ess must be a number in [0, 1), got {self.temper_ess!r}")
        object.__setattr__(self, "temper_ess", t)

    def step(self, particles: np.ndarray, logw: np.ndarray, dt_s, z, *, rng: np.random.Generator
             ) -> tuple[np.ndarray, np.ndarray, Epoch]:
        """One epoch: ``(particles, normalised logw, Epoch)`` after measurement ``z`` (see the class)."""
        if dt_s is not None:
            particles = self.propagate(particles, dt_s, rng=rng)
        restarted = np.zeros(np.shape(logw)[:-1], bool)
        if self.constrain is not None:
            particles, logw, restarted = self.constrain(particles, logw, rng=rng)
        ll = self.log_likelihood(particles, z)
        prior = logw
        logw, _ = normalise_log_weights(prior + ll)                    # the full update (β = 1) ...
        ess = _ess(np.exp(logw))
        beta = tempering_exponent(prior, ll, self.temper_ess, full_ess=ess)
        tempered = beta < 1.0
        if tempered.any():                           # ... or likelihood^β on the rows tempering_exponent chose
            logw = np.where(tempered[..., None], normalise_log_weights(prior + beta[..., None] * ll)[0], logw)
            ess = np.where(tempered, _ess(np.exp(logw)), ess)
        est = self.estimate(particles, logw)
        w = _normalised_weights(logw)                # resample's weights: log-sum-exp once more
        resample_ess = _ess(w)
        if self.ess_renormalises:
            ess = resample_ess
        resampled = resample_ess < self.ess_fraction * logw.shape[-1]
        particles, logw = _resample_rows(particles, logw, w, resampled, rng=rng, method=self.method)
        if self.roughening > 0 and resampled.any():
            particles = roughen(particles, rng=rng, k=self.roughening, rows=resampled)
        return particles, logw, Epoch(est, ess, resampled, restarted, beta)

    def run(self, particles: np.ndarray, logw: np.ndarray, t_s, measurements, *, rng: np.random.Generator,
            t0_s: float | None = None) -> ParticleRun:
        """Filter ``measurements[k]`` at times ``t_s[k]`` (non-decreasing, shape ``(T,)``, seconds).

        ``t0_s`` is the time of the initial cloud: None means ``t_s[0]`` with no prediction before
        the first update; a number means a prediction over ``t_s[0] − t0_s`` first (even 0 s: a
        transition sampler may draw its noise all the same).
        """
        t = np.asarray(t_s, float)
        if t.size == 0:
            raise ValueError("ParticleFilter.run: no epochs to filter (t_s is empty); a run needs at least one "
                             "measurement")
        if t.ndim != 1 or len(measurements) != t.size or np.any(np.diff(t) < 0):
            raise ValueError(f"ParticleFilter.run: non-decreasing t_s (T,) and T measurements expected, "
                             f"got t_s of shape {t.shape} and {len(measurements)} measurements")
        if t0_s is not None and not t0_s <= t[0]:
            raise ValueError(f"ParticleFilter.run: t0_s must not be after t_s[0], got {t0_s!r}")
        epochs = []
        t_prev = t0_s
        for k, z in enumerate(measurements):
            dt = None if t_prev is None else t[k] - t_prev
            t_prev = t[k]
            particles, logw, epoch = self.step(particles, logw, dt, z, rng=rng)
            epochs.append(epoch)
        axis = np.ndim(logw) - 1
        return ParticleRun(*(_stack(list(column), axis) for column in zip(*epochs)), particles, logw)
