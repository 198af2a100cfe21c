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
"""

from __future__ import annotations

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


def effective_sample_size(logw: np.ndarray) -> np.ndarray:
    """Effective sample size ``K / (1 + CV) = 1 / Σ w²`` (paper 000, after eq. 12).

    The two forms are algebraically equal: ``1 + CV = K Σ w²`` for normalised ``w``.

    Parameters
    ----------
    logw
        Log-weights, shape ``(..., K)``.

    Returns
    -------
    ndarray, shape ``(...)``, in ``[1, K]``.
    """
    w = _normalised_weights(logw)
    return 1.0 / np.sum(w * w, axis=-1)


def weighted_mean(particles: np.ndarray, logw: np.ndarray) -> np.ndarray:
    """Posterior mean ``Σ_k w_k X_k`` (eq. 11 of paper 000).

    Parameters
    ----------
    particles
        Shape ``(..., K, n_x)``.
    logw
        Shape ``(..., K)``.

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
    w = _normalised_weights(logw)
    if method == "systematic":
        return systematic_indices(w, rng.random(w.shape[:-1]))
    if method == "multinomial":
        return multinomial_indices(w, rng.random(w.shape))
    raise ValueError(f"unknown resampler {method!r}; choose from {RESAMPLERS}")


def resample(particles: np.ndarray, logw: np.ndarray, *, rng: np.random.Generator,
             threshold: float = 0.5, method: str = "systematic"
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Resample the rows whose effective sample size is below ``threshold · K``.

    Parameters
    ----------
    particles
        Shape ``(..., K, n_x)``.
    logw
        Shape ``(..., K)``.
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
    K = logw.shape[-1]
    need = effective_sample_size(logw) < threshold * K
    particles, logw = particles.copy(), logw.copy()
    if np.any(need):
        idx = resample_indices(logw[need], rng=rng, method=method)
        particles[need] = np.take_along_axis(particles[need], idx[..., None], axis=-2)
        logw[need] = -np.log(K)
    return particles, logw, need


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
    spread = np.ptp(particles, axis=-2, keepdims=True)                 # (..., 1, n_x)
    sigma = k * spread * K ** (-1.0 / n_x)
    if rows is not None:
        sigma = sigma * np.asarray(rows, bool)[..., None, None]
    return particles + sigma * rng.standard_normal(particles.shape)
