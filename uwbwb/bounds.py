"""Cramér–Rao bounds of the position, per epoch and along a track.

A bound is "what the measurements allow" only under its stated model: the Gaussian range noise
it is given and, for the posterior bound, the motion model's driving noise as the prior; the
measurement information is evaluated along the one realised true track (not averaged over the
model's random tracks). A posterior bound holds for causal estimators; a smoother, or a method with
other information (an IMU), may go below it.
The scoreboard uses two kinds: each method's *own* bound (its own noise and motion model: a
consistency check of the method against its assumptions) and one *common* bound per recording
(:func:`motion_log_likelihood` picks the motion model that best explains the calibration truth;
the posterior CRLB of that model with all ranges at the measured robust range noise, treated as
Gaussian — an assumption), against which every method is placed.

Three bounds, each computed from the *same* noise model objects the estimators use
(per-anchor range standard deviations, :class:`~uwbwb.models.tdoa.TdoaModel`, the
:mod:`uwbwb.models.motion` models), evaluated at the true positions:

**Snapshot CRLB** (one epoch, no prior). For ranges with independent Gaussian errors
of standard deviation ``σ_i`` the Fisher information of the position is

.. math::  \\mathcal{I}(p) = \\sum_i \\frac{u_i u_i^T}{σ_i^2}, \\qquad
           u_i = \\frac{\\partial r_i}{\\partial p}

(:func:`range_information`; for a 2-D position at a known height ``u_i`` is the
horizontal part of the 3-D unit vector). Pseudo-TDoAs ``r_j − r_ref`` formed from the
same ranges carry the reference-correlated covariance
``Σ = diag(σ_j²) + σ_ref² 1 1ᵀ`` (:meth:`TdoaModel.covariance`), and
``Hᵀ Σ⁻¹ H`` with ``H_j = u_j − u_ref`` works out (Sherman–Morrison) to

.. math::  \\mathcal{I}_{TDoA}(p) = \\sum_i \\frac{u_i u_i^T}{σ_i^2}
           - \\frac{g g^T}{\\sum_i σ_i^{-2}}, \\qquad g = \\sum_i \\frac{u_i}{σ_i^2},

the range information less what the ranges say about their common offset — whatever
the reference (:func:`tdoa_information`). The bound on any unbiased estimator's
position covariance is ``𝓘⁻¹`` (:func:`crlb`); its RMSE bound ``sqrt(tr 𝓘⁻¹)``.

**Posterior CRLB** (a tracking filter). Tichavský, Muravchik & Nehorai, *Posterior
Cramér–Rao bounds for discrete-time nonlinear filtering*, IEEE Trans. Signal
Process. 46(5), 1998, give the information recursion

.. math::  J_{k+1} = D^{22}_k - D^{21}_k (J_k + D^{11}_k)^{-1} D^{12}_k

with, for the linear-Gaussian motion models of :mod:`uwbwb.models.motion`
(``x_{k+1} = F x_k + w``, ``w ~ N(0, Q)``), ``D¹¹ = Fᵀ Q⁻¹ F``, ``D¹² = −Fᵀ Q⁻¹``,
``D²² = Q⁻¹ + E[Hᵀ R⁻¹ H]``. By the matrix inversion lemma this is

.. math::  J_{k+1} = (Q + F J_k^{-1} F^T)^{-1} + \\mathcal{I}_{k+1},

the form :func:`pcrlb` iterates: it needs no ``Q⁻¹`` and so also holds for the
singular ``Q`` of models that drive only the velocity. ``𝓘_{k+1}`` is the measurement
information of epoch ``k+1`` in state coordinates, evaluated along the true track
(the expectation over the state is replaced by the one trajectory at hand, the usual
practice for a recorded run).

**Segment CRLB** (a constant-velocity line fitted to a window of ranges, as the
trajectory NLS of notebook 02 does): the information of ``θ = (p₀, v)`` is
``Σ_k Σ_i a_k a_kᵀ ⊗ u_i u_iᵀ / σ_i²`` with ``a_k = (1, t_k − t₀)``, and the position
at ``t_k`` has bound ``A_k 𝓘_θ⁻¹ A_kᵀ`` with ``A_k = [I, (t_k − t₀) I]``
(:func:`line_crlb`).

All functions are vectorised over epochs; shapes are time-major. Epochs whose
information is singular (too few anchors, degenerate geometry) get NaN bounds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .models.ranging import range_jacobian
from .models.tdoa import TdoaModel

__all__ = ["Bound", "crlb", "embed_information", "line_crlb", "motion_log_likelihood", "pcrlb", "range_information",
           "rmse_bound_m", "tdoa_information", "tracking_bound"]

#: Information matrices whose smallest/largest eigenvalue ratio is at or below this are singular.
RCOND = 1e-10


def _sigma_per_anchor(sigma_m, n: int) -> np.ndarray:
    s = np.asarray(sigma_m, float)
    if s.ndim == 0:
        s = np.full(n, float(s))
    if s.shape != (n,):
        raise ValueError(f"sigma_m must be a scalar or have shape ({n},), got shape {s.shape}")
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ValueError(f"sigma_m must be finite and positive, got {s.tolist()}")
    return s


def _mask(mask, shape: tuple[int, ...]) -> np.ndarray:
    if mask is None:
        return np.ones(shape, bool)
    m = np.asarray(mask)
    if m.dtype != bool:
        raise ValueError("mask must be boolean (True = the anchor was measured)")
    try:
        return np.broadcast_to(m, shape)
    except ValueError:
        raise ValueError(f"mask of shape {m.shape} does not match (..., n_anchors) = {shape}") from None


def range_information(pos_m, anchor_pos_m, sigma_m, *, z_m=None, mask=None) -> np.ndarray:
    """Fisher information of the position from independent range measurements.

    Parameters
    ----------
    pos_m
        True positions, shape ``(..., dim)``, metres (``dim = 2`` with ``z_m``, or 3).
    anchor_pos_m
        Anchor positions, shape ``(n_anchors, 3)``, metres (or an :class:`~uwbwb.Anchors`).
    sigma_m
        Range standard deviation, scalar or ``(n_anchors,)``, metres.
    z_m
        Known tag height for 2-D positions, scalar or broadcastable to ``pos_m.shape[:-1]``.
    mask
        Anchors measured, bool ``(n_anchors,)`` or ``(..., n_anchors)``; default all.

    Returns
    -------
    numpy.ndarray
        ``Σ_i u_i u_iᵀ / σ_i²`` over the measured anchors, shape ``(..., dim, dim)``, m⁻².
    """
    u = range_jacobian(pos_m, anchor_pos_m, z_m=z_m)                     # (..., n, dim)
    w = _mask(mask, u.shape[:-1]) / _sigma_per_anchor(sigma_m, u.shape[-2]) ** 2
    return np.einsum("...n,...ni,...nj->...ij", w, u, u)


def tdoa_information(pos_m, model: TdoaModel, *, mask=None) -> np.ndarray:
    """Fisher information of the position from pseudo-TDoAs (reference-correlated noise).

    Parameters
    ----------
    pos_m
        True positions, shape ``(..., model.dim)``, metres.
    model
        The TDoA measurement model the estimators use: anchors, per-anchor range
        noise ``sigma_m``, ``dim`` and the known height ``z_m``.
    mask
        Anchors measured (reference included), bool ``(..., n_anchors)``; default all.

    Returns
    -------
    numpy.ndarray
        Shape ``(..., dim, dim)``, m⁻² (module docstring). The bound always uses the
        correlated covariance, since that is how pseudo-TDoAs formed from ranges are
        distributed; a model with ``correlated=False`` leaves information unused, which
        shows up as an RMSE / bound above one, not as a different bound.
    """
    u = model.unit_vectors(pos_m)                                       # (..., n, dim)
    w = _mask(mask, u.shape[:-1]) / model.sigma_m ** 2                  # (..., n)
    full = np.einsum("...n,...ni,...nj->...ij", w, u, u)
    g = np.einsum("...n,...ni->...i", w, u)
    total = w.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        common = np.where(total[..., None, None] > 0, g[..., :, None] * g[..., None, :] / total[..., None, None], 0.0)
    return full - common


def crlb(information) -> np.ndarray:
    """Inverse of the information, ``(..., d, d)``; NaN where it is singular."""
    info = np.asarray(information, float)
    if info.ndim < 2 or info.shape[-1] != info.shape[-2]:
        raise ValueError(f"information must have shape (..., d, d), got {info.shape}")
    sym = 0.5 * (info + np.swapaxes(info, -1, -2))
    lam = np.linalg.eigvalsh(sym)
    regular = np.all(np.isfinite(lam), axis=-1) & (lam[..., -1] > 0) & (lam[..., 0] > RCOND * lam[..., -1])
    eye = np.eye(info.shape[-1])
    safe = np.where(regular[..., None, None], sym, eye)
    out = np.linalg.inv(safe)
    return np.where(regular[..., None, None], 0.5 * (out + np.swapaxes(out, -1, -2)), np.nan)


def rmse_bound_m(cov_m2) -> np.ndarray:
    """``sqrt(trace)`` of position covariance bounds ``(..., d, d)``: the RMSE bound, metres."""
    return np.sqrt(np.trace(np.asarray(cov_m2, float), axis1=-2, axis2=-1))


def embed_information(information, n_x: int, index: Sequence[int]) -> np.ndarray:
    """Position information ``(..., d, d)`` placed into state coordinates ``(..., n_x, n_x)``.

    ``Hᵀ 𝓘 H`` with ``H`` selecting the state components ``index`` (the position).
    """
    info = np.asarray(information, float)
    idx = np.asarray(index, int)
    if info.shape[-1] != idx.size:
        raise ValueError(f"information is {info.shape[-1]}-D but index names {idx.size} components")
    out = np.zeros(info.shape[:-2] + (n_x, n_x))
    out[..., idx[:, None], idx] = info
    return out


def pcrlb(P0, F, Q, information) -> np.ndarray:
    """Posterior CRLB of the state along a track (Tichavský recursion, module docstring).

    Parameters
    ----------
    P0
        Prior covariance of the state at epoch 0, shape ``(n, n)`` (positive definite).
    F, Q
        Transition and process noise *into* each epoch, shape ``(T, n, n)`` (entry 0 is
        not used: epoch 0 holds the prior).
    information
        Measurement information per epoch in state coordinates, ``(T, n, n)``
        (zeros where nothing was measured; see :func:`embed_information`).

    Returns
    -------
    numpy.ndarray
        Bound on the posterior state covariance at each epoch, ``J_k⁻¹``, shape ``(T, n, n)``.
    """
    info = np.asarray(information, float)
    F = np.asarray(F, float)
    Q = np.asarray(Q, float)
    P0 = np.asarray(P0, float)
    if info.ndim != 3 or info.shape[1] != info.shape[2]:
        raise ValueError(f"information must have shape (T, n, n), got {info.shape}")
    T, n = info.shape[:2]
    if F.shape != (T, n, n) or Q.shape != (T, n, n) or P0.shape != (n, n):
        raise ValueError(f"pcrlb: P0 {P0.shape}, F {F.shape}, Q {Q.shape} do not fit information {info.shape}")
    if not np.all(np.isfinite(info)):
        raise ValueError("pcrlb: information contains non-finite values")
    try:
        np.linalg.cholesky(P0)
    except np.linalg.LinAlgError:
        raise ValueError("pcrlb: P0 must be symmetric positive definite") from None
    out = np.empty((T, n, n))
    prior = P0
    for k in range(T):
        if k:
            prior = F[k] @ out[k - 1] @ F[k].T + Q[k]
        J = np.linalg.inv(prior) + info[k]
        C = np.linalg.inv(0.5 * (J + J.T))
        out[k] = 0.5 * (C + C.T)
    return out


def tracking_bound(motion, t_s, information_pos, P0) -> np.ndarray:
    """Posterior CRLB of the position for a tracking filter with ``motion`` over epochs ``t_s``.

    Parameters
    ----------
    motion
        A :mod:`uwbwb.models.motion` model (``F(dt)``, ``Q(dt)``, ``n_x``, ``dim``; the
        position is the first ``dim`` state components).
    t_s
        Epoch times, shape ``(T,)``, seconds, strictly increasing.
    information_pos
        Measurement information of the position per epoch, ``(T, dim, dim)``
        (from :func:`range_information` or :func:`tdoa_information`; zeros where nothing
        was measured).
    P0
        Prior state covariance at ``t_s[0]``, ``(n_x, n_x)``.

    Returns
    -------
    numpy.ndarray
        Position covariance bounds, shape ``(T, dim, dim)``.
    """
    t = np.asarray(t_s, float)
    info = np.asarray(information_pos, float)
    if t.ndim != 1 or info.shape != (t.size, motion.dim, motion.dim):
        raise ValueError(f"tracking_bound: t_s {t.shape} and information {info.shape} do not fit a "
                         f"{motion.dim}-D model")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("tracking_bound: t_s must be strictly increasing")
    dt = np.concatenate([[0.0], np.diff(t)])
    pos = np.arange(motion.dim)
    full = pcrlb(P0, motion.F(dt), motion.Q(dt), embed_information(info, motion.n_x, pos))
    return full[:, pos[:, None], pos]


def motion_log_likelihood(models, t_s, pos_m, sigma_obs_m: float, *, skip: int | None = None) -> np.ndarray:
    """Gaussian log-likelihood of an observed track under each of a batch of motion models.

    A Kalman filter per model (:mod:`uwbwb.models.motion`: ``F(dt)``, ``Q(dt)``) observes the
    positions with white noise ``sigma_obs_m`` (the track's own measurement noise, e.g. motion
    capture) and sums ``log N(ν_k; 0, S_k)`` over its innovations — the prediction-error
    decomposition of the likelihood. The prior is centred on the first position (σ 1 m, higher
    derivatives σ 1 unit); the first ``skip`` innovations (default the model order) are left out so
    that the prior does not decide. Models of the same order and dimension are run as one batch.

    Parameters
    ----------
    models
        Sequence of motion models of equal ``n_x`` and ``dim``.
    t_s
        Times, shape ``(T,)``, seconds, strictly increasing.
    pos_m
        Observed positions, shape ``(T, dim)``, metres (finite).
    sigma_obs_m
        Standard deviation of the observation noise per axis, metres (> 0).

    Returns
    -------
    numpy.ndarray
        Log-likelihood per model, shape ``(len(models),)``.
    """
    models = list(models)
    t = np.asarray(t_s, float)
    z = np.asarray(pos_m, float)
    if not models:
        raise ValueError("motion_log_likelihood: no models")
    n, d = models[0].n_x, models[0].dim
    if any(m.n_x != n or m.dim != d for m in models):
        raise ValueError("motion_log_likelihood: the models must share n_x and dim")
    if t.ndim != 1 or z.shape != (t.size, d) or not np.all(np.isfinite(z)):
        raise ValueError(f"motion_log_likelihood: t_s {t.shape} and finite pos_m (T, {d}) expected, got {z.shape}")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("motion_log_likelihood: t_s must be strictly increasing")
    if not sigma_obs_m > 0:
        raise ValueError(f"sigma_obs_m must be positive, got {sigma_obs_m!r}")
    skip = n // d if skip is None else int(skip)
    dt = np.concatenate([[0.0], np.diff(t)])
    F = np.stack([m.F(dt) for m in models], axis=1)                # (T, G, n, n)
    Q = np.stack([m.Q(dt) for m in models], axis=1)
    G = len(models)
    H = np.zeros((d, n))
    H[:, :d] = np.eye(d)
    R = sigma_obs_m ** 2 * np.eye(d)
    x = np.zeros((G, n))
    x[:, :d] = z[0]
    P = np.broadcast_to(np.eye(n), (G, n, n)).copy()
    total = np.zeros(G)
    for k in range(t.size):
        if k:
            x = np.einsum("gij,gj->gi", F[k], x)
            P = F[k] @ P @ np.swapaxes(F[k], -1, -2) + Q[k]
        nu = z[k] - x[:, :d]
        S = P[:, :d, :d] + R
        Sinv = np.linalg.inv(S)
        if k >= skip:
            _, logdet = np.linalg.slogdet(S)
            total -= 0.5 * (np.einsum("gi,gij,gj->g", nu, Sinv, nu) + logdet + d * np.log(2 * np.pi))
        K = P[:, :, :d] @ Sinv                                       # (G, n, d)
        x = x + np.einsum("gij,gj->gi", K, nu)
        IKH = np.eye(n) - K @ H
        P = IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)     # Joseph form
        P = 0.5 * (P + np.swapaxes(P, -1, -2))
    return total


def line_crlb(t_s, pos_m, anchor_pos_m, sigma_m, *, t0_s: float | None = None, z_m=None, mask=None) -> np.ndarray:
    """Bound on the positions of a constant-velocity line fitted to one window of ranges.

    Parameters
    ----------
    t_s
        Epoch times of the window, shape ``(K,)``, seconds.
    pos_m
        True positions at those epochs, shape ``(K, dim)``, metres.
    anchor_pos_m, sigma_m, z_m, mask
        As in :func:`range_information` (``mask`` shape ``(K, n_anchors)``).
    t0_s
        Reference time of ``p₀`` (default ``t_s[0]``); the bound does not depend on it.

    Returns
    -------
    numpy.ndarray
        Position covariance bounds at each epoch of the window, shape ``(K, dim, dim)``;
        NaN if the window's information about ``(p₀, v)`` is singular.
    """
    t = np.asarray(t_s, float)
    info = range_information(pos_m, anchor_pos_m, sigma_m, z_m=z_m, mask=mask)     # (K, d, d)
    d = info.shape[-1]
    tau = t - (t[0] if t0_s is None else float(t0_s))
    a = np.stack([np.ones_like(tau), tau], axis=-1)                                # (K, 2)
    big = np.einsum("ka,kb,kij->aibj", a, a, info).reshape(2 * d, 2 * d)
    C = crlb(big)
    A = np.concatenate([np.broadcast_to(np.eye(d), (t.size, d, d)), tau[:, None, None] * np.eye(d)], axis=-1)
    return np.einsum("kij,jl,kml->kim", A, C, A)


@dataclass(frozen=True)
class Bound:
    """A per-epoch bound on the position covariance of one estimator on one run.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds.
    pos_cov_m2
        Bound on the position covariance, shape ``(T, dim, dim)``, m²; NaN where the
        measurements do not determine the position.
    kind
        What was bounded, e.g. ``"CRLB ranges"``, ``"CRLB TDoA"``, ``"PCRLB RF"``.
    """

    t_s: np.ndarray
    pos_cov_m2: np.ndarray
    kind: str

    def __post_init__(self):
        t = np.array(self.t_s, float)
        c = np.array(self.pos_cov_m2, float)
        if t.ndim != 1 or c.ndim != 3 or c.shape[0] != t.size or c.shape[1] != c.shape[2]:
            raise ValueError(f"Bound: t_s {t.shape} and pos_cov_m2 {c.shape} do not fit (T,), (T, d, d)")
        for name, a in (("t_s", t), ("pos_cov_m2", c)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def rmse_m(self) -> np.ndarray:
        """Per-epoch RMSE bound ``sqrt(tr C_k)``, shape ``(T,)``, metres."""
        return rmse_bound_m(self.pos_cov_m2)

    def aggregate_m(self, mask=None) -> float:
        """RMSE bound over epochs: ``sqrt(mean_k tr C_k)`` (comparable with an RMSE over them).

        NaN epochs are an error, not silently skipped: pass a ``mask`` that leaves them out.
        """
        tr = np.trace(self.pos_cov_m2, axis1=1, axis2=2)
        if mask is not None:
            tr = tr[np.asarray(mask)]
        if tr.size == 0:
            return float("nan")
        if np.any(np.isnan(tr)):
            raise ValueError(f"Bound.aggregate_m: {int(np.isnan(tr).sum())} selected epochs have no bound "
                             f"(singular information); leave them out with mask")
        return float(np.sqrt(np.mean(tr)))
