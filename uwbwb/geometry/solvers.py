"""The batched multilateration problem and its solvers (Gauss--Newton with step halving, trust region).

Private to :mod:`uwbwb.geometry`: :mod:`.multilateration` builds a :class:`_Problem` from ranges
and anchors and runs one of the solvers on the epochs still to be solved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..models.ranging import TINY_RANGE_M as _TINY_RANGE_M
from ..models.ranging import anchor_positions as _as_anchors

#: A symmetric geometry matrix with smallest/largest eigenvalue ratio at or
#: below this is treated as singular (collinear / coplanar anchors, tag in the
#: anchors' line or plane). Nearly degenerate but solvable geometry is *not*
#: flagged: it shows up as a large covariance and GDOP instead.
RCOND = 1e-10

_MAX_HALVINGS = 30


# --------------------------------------------------------------------------- problem set-up


@dataclass(frozen=True)
class _Problem:
    """Validated multilateration inputs in coordinates centred on the anchors."""

    r: np.ndarray        # (T, n) ranges, 0 where missing
    mask: np.ndarray     # (T, n) bool, range present
    A: np.ndarray        # (n, dim) anchors (solved coordinates), centred
    dz2: np.ndarray      # (T, n) squared height difference (zeros for dim=3 / planar)
    w: np.ndarray        # (T, n) weights mask / sigma^2 (mask when sigma is None)
    centre: np.ndarray   # (dim,) subtracted from the anchors
    dim: int
    sigma: np.ndarray | None  # (n,) or None

    @property
    def n_used(self) -> np.ndarray:
        return self.mask.sum(axis=1)

    @classmethod
    def build(cls, range_m, anchor_pos_m, dim, z_m, sigma_m) -> "_Problem":
        A = _as_anchors(anchor_pos_m)
        if dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {dim!r}")
        r = np.asarray(range_m, dtype=float)
        if r.ndim != 2 or r.shape[1] != A.shape[0]:
            raise ValueError(f"range_m must have shape (T, {A.shape[0]}) to match the anchors, got {r.shape}")
        if np.any(np.isinf(r)):
            raise ValueError("range_m contains infinite values (use NaN for missing ranges)")
        mask = np.isfinite(r)
        if np.any(r[mask] < 0):
            raise ValueError("range_m contains negative ranges")
        T, n = r.shape
        if dim == 3:
            if A.shape[1] != 3:
                raise ValueError("dim=3 needs 3-D anchors")
            if z_m is not None:
                raise ValueError("z_m is only used with dim=2 (the height is solved for with dim=3)")
            dz2 = np.zeros((T, n))
        elif A.shape[1] == 3:
            if z_m is None:
                raise ValueError("dim=2 with 3-D anchors needs the tag height z_m (scalar or (T,)); "
                                 "use dim=3 to solve for the height")
            z = np.asarray(z_m, dtype=float)
            if z.ndim > 1 or (z.ndim == 1 and z.shape != (T,)):
                raise ValueError(f"z_m must be a scalar or have shape ({T},), got {z.shape}")
            if not np.all(np.isfinite(z)):
                raise ValueError("z_m contains non-finite values")
            dz2 = (A[None, :, 2] - np.broadcast_to(z, (T,))[:, None]) ** 2
        else:
            if z_m is not None:
                raise ValueError("z_m is only used with 3-D anchors")
            dz2 = np.zeros((T, n))
        if sigma_m is None:
            sigma = None
            w = mask.astype(float)
        else:
            s = np.asarray(sigma_m, dtype=float)
            if s.ndim == 0:
                s = np.full(n, float(s))
            if s.shape != (n,):
                raise ValueError(f"sigma_m must be a scalar or have shape ({n},), got {s.shape}")
            if not np.all(np.isfinite(s)) or np.any(s <= 0):
                raise ValueError("sigma_m must be finite and positive")
            sigma = s
            w = mask / s**2
        Ad = A[:, :dim]
        centre = Ad.mean(axis=0)
        return cls(np.where(mask, r, 0.0), mask, Ad - centre, dz2, w, centre, dim, sigma)

    def predict(self, idx: np.ndarray, x: np.ndarray):
        """Differences ``x - a_i`` (m, n, dim) and predicted ranges (m, n) for epochs ``idx``."""
        diff = x[:, None, :] - self.A
        rh = np.sqrt(np.einsum("tni,tni->tn", diff, diff) + self.dz2[idx])
        return diff, np.maximum(rh, _TINY_RANGE_M)

    def cost(self, idx, x):
        diff, rh = self.predict(idx, x)
        e = self.r[idx] - rh
        return np.einsum("tn,tn->t", self.w[idx], e * e), diff, rh


def _solve_psd(H: np.ndarray, g: np.ndarray | None = None):
    """Batched solve / inverse of symmetric PSD matrices via eigen-decomposition.

    Returns ``(x or H^-1, regular)``; rows that are numerically singular
    (``lambda_min <= RCOND * lambda_max``) get zeros and ``regular=False``.
    """
    lam, V = np.linalg.eigh(H)
    regular = (lam[:, -1] > 0) & (lam[:, 0] > RCOND * lam[:, -1])
    inv_lam = np.where(regular[:, None], 1.0 / np.where(regular[:, None], lam, 1.0), 0.0)
    if g is None:
        return np.einsum("tik,tk,tjk->tij", V, inv_lam, V), regular
    return np.einsum("tik,tk->ti", V, inv_lam * np.einsum("tki,tk->ti", V, g)), regular


def _anchor_span_ok(A: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """True where the anchors with a range span ``dim`` dimensions (affinely)."""
    w = mask.astype(float)
    nw = np.maximum(w.sum(axis=1), 1.0)
    abar = (w @ A) / nw[:, None]
    dA = A[None, :, :] - abar[:, None, :]
    M = np.einsum("tn,tni,tnj->tij", w, dA, dA)
    lam = np.linalg.eigvalsh(M)
    return (lam[:, -1] > 0) & (lam[:, 0] > RCOND * lam[:, -1])


def _linear(p: _Problem) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form LS in centred coordinates; returns (x (T, dim), regular (T,))."""
    # |x|^2 - 2 a_i.x + |a_i|^2 = r_i^2 - dz_i^2 is linear in (x, R=|x|^2); fitting
    # R as a free intercept is the same as centring the equations on the
    # (weighted) mean over the anchors with a range, which eliminates R.
    w = p.mask.astype(float)
    nw = np.maximum(w.sum(axis=1), 1.0)
    b = p.r**2 - p.dz2 - np.sum(p.A**2, axis=1)
    abar = (w @ p.A) / nw[:, None]
    bbar = np.sum(w * b, axis=1) / nw
    dA = p.A[None, :, :] - abar[:, None, :]
    M = np.einsum("tn,tni,tnj->tij", w, dA, dA)
    g = np.einsum("tn,tni,tn->ti", w, dA, b - bbar[:, None])
    x, regular = _solve_psd(M, g)
    return -0.5 * x, regular


# --------------------------------------------------------------------------- solvers


def _gauss_newton(p: _Problem, x: np.ndarray, run: np.ndarray, max_iter: int, tol_m: float):
    """Batched Gauss--Newton with backtracking over the epochs in ``run``.

    Returns (x (T, dim), converged (T,)). Every iteration works on the epochs
    still active only; an epoch stops when its step is below ``tol_m``, when
    its normal matrix is singular or when no step along the Gauss--Newton
    direction decreases the cost.
    """
    x = x.copy()
    converged = np.zeros(x.shape[0], dtype=bool)
    idx = np.flatnonzero(run)
    xa = x[idx]
    cost, diff, rh = p.cost(idx, xa)
    for _ in range(max_iter):
        if idx.size == 0:
            break
        J = diff / rh[..., None]
        wa = p.w[idx]
        e = p.r[idx] - rh
        H = np.einsum("tn,tni,tnj->tij", wa, J, J)
        g = np.einsum("tn,tni,tn->ti", wa, J, e)
        step, regular = _solve_psd(H, g)
        # Second-order term of the range model, d2r/dx2 = (I - J J^T) / r: with it
        # the step is Newton's, which converges quadratically where large residuals
        # and a weak direction (typically the height) make plain Gauss-Newton crawl.
        # Used only where the full Hessian is positive definite.
        S = np.einsum("tn,tnij->tij", wa * e / rh, np.eye(p.dim) - J[..., :, None] * J[..., None, :])
        step_n, newton_ok = _solve_psd(H - S, g)
        step = np.where(newton_ok[:, None], step_n, step)
        step_norm = np.linalg.norm(step, axis=1)
        small = regular & (step_norm < tol_m)
        xa[small] += step[small]

        # Backtracking on the weighted sum of squares for the remaining epochs.
        pending = regular & ~small
        accepted = np.zeros(idx.size, dtype=bool)
        alpha = np.ones(idx.size)
        for _ in range(_MAX_HALVINGS):
            k = np.flatnonzero(pending)
            if k.size == 0:
                break
            x_try = xa[k] + alpha[k, None] * step[k]
            c_try, d_try, r_try = p.cost(idx[k], x_try)
            better = c_try <= cost[k] * (1.0 + 1e-12)
            kk = k[better]
            xa[kk], cost[kk], diff[kk], rh[kk] = x_try[better], c_try[better], d_try[better], r_try[better]
            accepted[kk] = True
            pending[kk] = False
            alpha[k[~better]] *= 0.5

        done = small | (accepted & (alpha * step_norm < tol_m))
        x[idx] = xa
        converged[idx[done]] = True
        keep = accepted & ~done
        idx, xa, cost, diff, rh = idx[keep], xa[keep], cost[keep], diff[keep], rh[keep]
    return x, converged


def _least_squares(p: _Problem, x: np.ndarray, run: np.ndarray, max_iter: int, tol_m: float,
                   loss: str, f_scale: float):
    """Per-epoch ``scipy.optimize.least_squares`` with the analytic Jacobian."""
    x = x.copy()
    converged = np.zeros(x.shape[0], dtype=bool)
    scale = np.ones(p.A.shape[0]) if p.sigma is None else 1.0 / p.sigma
    for t in np.flatnonzero(run):
        m = p.mask[t]
        a, r, dz2, s = p.A[m], p.r[t, m], p.dz2[t, m], scale[m]

        def fun(xt, a=a, r=r, dz2=dz2, s=s):
            return (r - np.sqrt(np.sum((xt - a) ** 2, axis=1) + dz2)) * s

        def jac(xt, a=a, dz2=dz2, s=s):
            d = xt - a
            rh = np.maximum(np.sqrt(np.sum(d * d, axis=1) + dz2), _TINY_RANGE_M)
            return -d / rh[:, None] * s[:, None]

        sol = least_squares(fun, x[t], jac=jac, method="trf", loss=loss, f_scale=f_scale,
                            xtol=tol_m * 1e-3, ftol=1e-15, gtol=1e-15, max_nfev=max_iter)
        x[t] = sol.x
        converged[t] = sol.status > 0
    return x, converged
