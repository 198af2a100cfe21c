"""The set-noise Kalman filter (paper 000): the same model in closed form per axis.

See :mod:`uwbwb.filters.setnoise` for the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...models.setnoise import SetNoiseModel
from ...types import EstimateStatus, EstimatesBatch, SetFixLog
from .pf import FilterRun, _noise_arrays, _times, model_noise


@dataclass(frozen=True)
class KFSweep:
    """Set-noise Kalman filter for several σ_d values (and noise-model variants).

    Attributes
    ----------
    t_s
        Shape ``(T,)``.
    sigma_d_mps
        Shape ``(S,)``.
    state
        Posterior means ``(..., S, T, 4)``.
    cov
        Posterior covariances ``(..., S, T, 4, 4)`` (x and y blocks; cross terms are zero).
    nis
        Normalised innovation squared per fix, ``(..., S, T)`` (χ² with 2 dof if the model holds).
    """

    t_s: np.ndarray
    sigma_d_mps: np.ndarray
    state: np.ndarray
    cov: np.ndarray
    nis: np.ndarray

    @property
    def pos_m(self) -> np.ndarray:
        return self.state[..., :2]

    def to_estimates(self) -> EstimatesBatch:
        """Every run as :class:`~uwbwb.types.Estimates` fields batched over ``(..., S)``: every fix
        ``UPDATED``, with velocities, position covariances and ``nis``/``dof`` (2 per fix) in ``info``
        (``batch[i]`` is run ``i`` as the :class:`FilterRun` of :func:`run_set_noise_kf` reports it)."""
        lead = self.nis.shape
        return EstimatesBatch(self.t_s, self.pos_m, np.full(lead, EstimateStatus.UPDATED, np.int8), "set-noise KF",
                              self.cov[..., :2, :2], self.state[..., 2:], {"nis": self.nis, "dof": np.full(lead, 2)})

    def mean_error_m(self, truth_m) -> np.ndarray:
        """Mean Euclidean error against ``truth_m (T, 2)``, shape ``(..., S)``."""
        return np.linalg.norm(self.pos_m - np.asarray(truth_m, float), axis=-1).mean(axis=-1)


def kf_sweep(t_s, z_m, mu_m, sigma_m, x0_m, sigma_d_mps) -> KFSweep:
    """Exact set-noise Kalman filter, vectorised over σ_d values (and leading model axes).

    Per axis the state ``(p, v)`` evolves by eq. 3 and the fix observes ``p + μ``
    with variance ``σ²``; the x and y axes decouple (diagonal noise), so each is a
    2-state filter run in closed form with the Joseph-form update
    ``P⁺ = (I − KH) P (I − KH)ᵀ + K R Kᵀ``. It is checked against
    :mod:`uwbwb.filters.kalman` (the filterpy edge) in the tests.

    Parameters
    ----------
    t_s, z_m, x0_m
        As for :func:`reference_pf`.
    mu_m, sigma_m
        Shape ``(..., T, 2)``.
    sigma_d_mps
        Scalar or ``(S,)``, m/s.

    Returns
    -------
    KFSweep
    """
    t, dt = _times(t_s)
    T = t.size
    z, mu, sd = _noise_arrays(z_m, mu_m, sigma_m, T)
    sig_d = np.atleast_1d(np.asarray(sigma_d_mps, float))
    if sig_d.ndim != 1 or not np.all(np.isfinite(sig_d) & (sig_d >= 0)):
        raise ValueError(f"sigma_d_mps must be a finite non-negative scalar or 1-D array, got {sigma_d_mps!r}")
    lead = mu.shape[:-2]
    S = sig_d.size
    bshape = lead + (S, 2)                                  # batch: models..., σ_d, axis
    q = np.broadcast_to(sig_d[:, None] ** 2, bshape)
    zc = np.broadcast_to((z - mu)[..., None, :, :], lead + (S, T, 2))   # bias-corrected fixes
    r = np.broadcast_to((sd ** 2)[..., None, :, :], lead + (S, T, 2))
    p = np.broadcast_to(np.asarray(x0_m, float), bshape).copy()
    v = np.zeros(bshape)
    P00, P01, P11 = np.zeros(bshape), np.zeros(bshape), np.zeros(bshape)
    state = np.empty(lead + (S, T, 4))
    cov = np.zeros(lead + (S, T, 4, 4))
    nis = np.zeros(lead + (S, T))
    for k in range(T):
        if k:
            h = dt[k]
            p = p + h * v
            P00, P01, P11 = P00 + 2 * h * P01 + h * h * P11, P01 + h * P11, P11 + q
        rk = r[..., k, :]
        innov = zc[..., k, :] - p
        Sk = P00 + rk
        K0, K1 = P00 / Sk, P01 / Sk
        p, v = p + K0 * innov, v + K1 * innov
        a = 1.0 - K0
        P00, P01, P11 = (a * a * P00 + K0 * K0 * rk,
                         a * (P01 - K1 * P00) + K0 * K1 * rk,
                         P11 - 2 * K1 * P01 + K1 * K1 * P00 + K1 * K1 * rk)
        nis[..., k] = np.sum(innov * innov / Sk, axis=-1)
        state[..., k, :2], state[..., k, 2:] = p, v
        for ax in (0, 1):
            i, j = ax, ax + 2                               # position and velocity of this axis
            cov[..., k, i, i], cov[..., k, i, j] = P00[..., ax], P01[..., ax]
            cov[..., k, j, i], cov[..., k, j, j] = P01[..., ax], P11[..., ax]
    return KFSweep(t, sig_d, state, cov, nis)


def run_set_noise_kf(fixes: SetFixLog, model: SetNoiseModel, x0_m, sigma_d_mps: float,
                     name: str = "set-noise KF") -> FilterRun:
    """The set-noise Kalman filter on one recording (see :func:`kf_sweep`)."""
    mu, sd = model_noise(fixes, model)
    res = kf_sweep(fixes.t_s, fixes.pos_m, mu, sd, x0_m, sigma_d_mps)
    n = len(fixes)
    return FilterRun(res.t_s, res.state[0], np.full(n, np.nan), np.zeros(n, bool), name,
                     {"sigma_d_mps": sigma_d_mps}, cov=res.cov[0], nis=res.nis[0])
