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
        if not np.all(np.isfinite(a)):
            raise ValueError(f"update: {name} contains non-finite values; a missing measurement is left out, "
                             f"not passed as NaN")
    if np.any(np.diag(R) <= 0) or not np.allclose(R, R.T):
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
