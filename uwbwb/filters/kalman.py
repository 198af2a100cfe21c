"""The one edge where uwbwb meets filterpy's Kalman filter.

Everything else in uwbwb passes 1-D states ``x (n,)`` and covariances ``P (n, n)``;
only this module sees filterpy's ``(n, 1)`` column vectors. filterpy's
:class:`~filterpy.kalman.KalmanFilter` performs the textbook steps (its update
uses the Joseph form ``P = (I − KH) P (I − KH)ᵀ + K R Kᵀ``); we add covariance
symmetrisation, the normalised innovation squared (NIS) and a linearised update
for nonlinear measurement models (EKF), where the innovation is ``z − h(x)``
rather than ``z − Hx``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numba
import numpy as np
from filterpy.kalman import KalmanFilter


@dataclass(frozen=True)
class Gaussian:
    """A Gaussian state estimate: mean ``x (n,)`` and covariance ``P (n, n)``."""

    x: np.ndarray
    P: np.ndarray

    def __post_init__(self):
        x = np.array(self.x, float)
        P = np.array(self.P, float)
        if x.ndim != 1 or P.shape != (x.size, x.size):
            raise ValueError(f"Gaussian needs x (n,) and P (n, n); got {x.shape} and {P.shape}")
        x.setflags(write=False)
        P.setflags(write=False)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "P", P)


@dataclass(frozen=True)
class Innovation:
    """Innovation ``y = z − h(x⁻)`` (m,), its covariance ``S`` (m, m) and NIS ``yᵀ S⁻¹ y``."""

    y: np.ndarray
    S: np.ndarray
    nis: float


def _symmetric(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + P.T)


_local = threading.local()


def _filter(state: Gaussian) -> KalmanFilter:
    # One filterpy object per state size and thread, reloaded with (x, P) on every call:
    # predict/update pass F, Q, H, R explicitly, so nothing else carries over between calls,
    # and building a new KalmanFilter each step would cost about a fifth of the step.
    cache = _local.__dict__.setdefault("filters", {})
    kf = cache.get(state.x.size)
    if kf is None:
        kf = cache[state.x.size] = KalmanFilter(dim_x=state.x.size, dim_z=1)
    kf.x = state.x.reshape(-1, 1).copy()
    kf.P = np.array(state.P, copy=True)
    return kf


def predict(state: Gaussian, F: np.ndarray, Q: np.ndarray, u: np.ndarray | None = None,
            B: np.ndarray | None = None) -> Gaussian:
    """Prior ``x⁻ = F x + B u``, ``P⁻ = F P Fᵀ + Q``.

    (The thesis behind notebook 03 prints ``AᵀPA + Q`` in its eq. 6; the
    correct propagation, used here, is ``A P Aᵀ + Q``.)
    """
    kf = _filter(state)
    if u is None:
        kf.predict(F=np.asarray(F, float), Q=np.asarray(Q, float))
    else:
        kf.predict(u=np.asarray(u, float).reshape(-1, 1), B=np.asarray(B, float),
                   F=np.asarray(F, float), Q=np.asarray(Q, float))
    return Gaussian(kf.x[:, 0], _symmetric(kf.P))


def update(state: Gaussian, z: np.ndarray, H: np.ndarray, R: np.ndarray,
           h_x: np.ndarray | None = None) -> tuple[Gaussian, Innovation]:
    """Posterior after measurement ``z (m,)`` with Jacobian ``H (m, n)`` and noise ``R (m, m)``.

    Parameters
    ----------
    h_x
        Predicted measurement ``h(x⁻)`` for a nonlinear model (EKF). If None the
        model is linear and ``h(x⁻) = H x⁻``.

    Returns
    -------
    posterior, innovation
        Joseph-form, symmetrised posterior; innovation with its NIS.
    """
    z = np.asarray(z, float).ravel()
    H = np.atleast_2d(np.asarray(H, float))
    R = np.atleast_2d(np.asarray(R, float))
    if H.shape != (z.size, state.x.size) or R.shape != (z.size, z.size):
        raise ValueError(f"update: z {z.shape}, H {H.shape}, R {R.shape} do not fit state of size {state.x.size}")
    for name, a in (("z", z), ("H", H), ("R", R)) + ((("h_x", np.asarray(h_x, float)),) if h_x is not None else ()):
        if not np.isfinite(a).all():
            raise ValueError(f"update: {name} contains non-finite values; a missing measurement is left out, "
                             f"not passed as NaN")
    # np.allclose(R, R.T)'s test (rtol 1e-5, atol 1e-8), written out: the filters call this per epoch
    if (np.diag(R) <= 0).any() or not (np.abs(R - R.T) <= 1e-8 + 1e-5 * np.abs(R.T)).all():
        raise ValueError(f"update: R must be symmetric with positive variances, got diagonal {np.diag(R).tolist()}")
    S = H @ state.P @ H.T + R
    try:
        np.linalg.cholesky(_symmetric(S))
    except np.linalg.LinAlgError:
        raise ValueError("update: the innovation covariance H P Hᵀ + R is not positive definite "
                         "(check R and the state covariance)") from None
    if h_x is not None:
        # Linearised update: filterpy forms y = z_lin − H x⁻, so z_lin = z − h(x⁻) + H x⁻ gives y = z − h(x⁻).
        z = z - np.asarray(h_x, float).ravel() + H @ state.x
    kf = _filter(state)
    kf.update(z.reshape(-1, 1), R=R, H=H)
    y = kf.y[:, 0].copy()
    S = _symmetric(kf.S)
    nis = float(y @ np.linalg.solve(S, y))
    return Gaussian(kf.x[:, 0], _symmetric(kf.P)), Innovation(y, S, nis)


def update_sequential(state: Gaussian, z: np.ndarray, H: np.ndarray, R: np.ndarray,
                      h_x: np.ndarray | None = None) -> tuple[Gaussian, np.ndarray]:
    """The update of :func:`update`, one scalar measurement at a time (same posterior).

    Correlated noise is decorrelated first: with ``R = L Lᵀ`` (Cholesky), the rows of
    ``L⁻¹ (z − h)`` and ``L⁻¹ H`` have unit, independent noise and are applied one after
    the other, each with a scalar Joseph-form update. With a diagonal ``R`` each row is
    simply one measurement with its own Jacobian. Error-state filters that take every
    TDoA or range as its own update use this; it avoids an ``m × m`` inverse and the
    filterpy round trip per row (plain numpy, 1-D states in and out).

    Returns
    -------
    posterior, nis_parts
        Symmetrised posterior and the NIS of each sequential row, shape ``(m,)``; their
        sum equals the batch NIS ``yᵀ S⁻¹ y``.
    """
    z = np.asarray(z, float).ravel()
    H = np.atleast_2d(np.asarray(H, float))
    R = np.atleast_2d(np.asarray(R, float))
    if H.shape != (z.size, state.x.size) or R.shape != (z.size, z.size):
        raise ValueError(f"update_sequential: z {z.shape}, H {H.shape}, R {R.shape} do not fit state of size "
                         f"{state.x.size}")
    y = z - (H @ state.x if h_x is None else np.asarray(h_x, float).ravel())
    x, P = state.x.copy(), np.array(state.P, copy=True)
    nis = np.empty(z.size)
    code = _sequential(x, P, np.ascontiguousarray(y), np.ascontiguousarray(H), np.ascontiguousarray(R), nis)
    if code == 1:
        raise ValueError("update_sequential: non-finite values; a missing measurement is left out, not passed as NaN")
    if code == 2:
        if np.any(np.abs(R - R.T) > 1e-12 * (np.abs(R) + np.abs(R.T) + 1e-300)):
            raise ValueError("update_sequential: R must be symmetric (to 1e-12 relative; the rows are decorrelated "
                             f"by its Cholesky factor), largest asymmetry {np.max(np.abs(R - R.T)):.3g}")
        raise ValueError("update_sequential: R must be positive definite (the rows are decorrelated by its Cholesky "
                         f"factor; the batch update needs only S positive definite), got diagonal {np.diag(R).tolist()}")
    return Gaussian(x, _symmetric(P)), nis


@numba.njit(cache=True, nogil=True)
def _sequential(x, P, y, H, R, nis):
    """Checks, decorrelation (Cholesky ``R = L Lᵀ``, ``L⁻¹y``, ``L⁻¹H``) and the scalar updates of
    :func:`update_sequential`, in place. Returns 0, or 1 (non-finite input), 2 (R not positive definite)."""
    m, n = y.size, x.size
    for i in range(m):
        if not np.isfinite(y[i]):
            return 1
        for j in range(n):
            if not np.isfinite(H[i, j]):
                return 1
        for j in range(m):
            if not np.isfinite(R[i, j]) or abs(R[i, j] - R[j, i]) > 1e-12 * (abs(R[i, j]) + abs(R[j, i]) + 1e-300):
                return 1 if not np.isfinite(R[i, j]) else 2
    diagonal = True
    for i in range(m):
        for j in range(m):
            if i != j and R[i, j] != 0.0:
                diagonal = False
    r = np.empty(m)
    if diagonal:
        for i in range(m):
            if not R[i, i] > 0:
                return 2
            r[i] = R[i, i]
        yw, Hw = y, H
    else:
        L = np.zeros((m, m))
        for i in range(m):
            for j in range(i + 1):
                acc = R[i, j]
                for k in range(j):
                    acc -= L[i, k] * L[j, k]
                if i == j:
                    if not acc > 0:
                        return 2
                    L[i, i] = np.sqrt(acc)
                else:
                    L[i, j] = acc / L[j, j]
        yw = y.copy()
        Hw = H.copy()
        for i in range(m):                       # forward substitution, L yw = y, L Hw = H
            for k in range(i):
                yw[i] -= L[i, k] * yw[k]
                for j in range(n):
                    Hw[i, j] -= L[i, k] * Hw[k, j]
            yw[i] /= L[i, i]
            for j in range(n):
                Hw[i, j] /= L[i, i]
            r[i] = 1.0
    nis[:] = _scalar_updates(x, P, yw, Hw, r)
    return 0


@numba.njit(cache=True, nogil=True)
def _scalar_updates(x, P, y, H, r):
    """Rows of :func:`update_sequential`, in place on ``x`` and ``P``; returns each row's NIS."""
    n, m = x.size, y.size
    x0 = x.copy()
    nis = np.empty(m)
    Ph = np.empty(n)
    for i in range(m):
        s = r[i]
        innov = y[i]
        for a in range(n):
            acc = 0.0
            for b in range(n):
                acc += P[a, b] * H[i, b]
            Ph[a] = acc
            s += H[i, a] * acc
            innov -= H[i, a] * (x[a] - x0[a])        # rows after the first see the updated mean
        nis[i] = innov * innov / s
        for a in range(n):
            x[a] += Ph[a] / s * innov
        # Joseph form (I − k hᵀ) P (I − k hᵀ)ᵀ + r k kᵀ with k = Ph / s, expanded:
        # P − k Phᵀ − Ph kᵀ + s k kᵀ (valid for any gain k)
        for a in range(n):
            ka = Ph[a] / s
            for b in range(n):
                kb = Ph[b] / s
                P[a, b] += -ka * Ph[b] - Ph[a] * kb + s * ka * kb
    return nis
