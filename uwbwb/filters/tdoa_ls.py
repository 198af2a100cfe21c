"""Per-epoch TDoA position by weighted Gauss–Newton least squares (the thesis' LS baseline).

For each epoch independently,

.. math::  \\hat p = \\arg\\min_p\\ (z - h(p))^T Σ^{-1} (z - h(p)),

with ``h`` and its Jacobian ``H`` from :class:`uwbwb.models.tdoa.TdoaModel` and
``Σ`` its (reference-correlated) covariance. Gauss–Newton steps
``δ = (HᵀΣ⁻¹H)⁻¹ HᵀΣ⁻¹ (z − h)`` are halved while they increase the cost
(at most ``max_halvings`` times). All epochs iterate together: arrays are
``(T, n_anchors)`` with zero weight on missing anchors and the reference, and the
weight matrix of each distinct (measured anchors, reference) pattern is
inverted once.

The covariance reported is ``(HᵀΣ⁻¹H)⁻¹`` at the solution (the Cramér–Rao
bound of the linearised problem if ``Σ`` is right).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..models.tdoa import TdoaModel
from ..types import EstimateStatus, Estimates, TdoaLog, Trajectory
from ..validate import integer, number

__all__ = ["TdoaLsResult", "tdoa_least_squares", "STATUS"]

#: Status codes of :attr:`TdoaLsResult.status`.
STATUS = {0: "ok", 1: "too few anchors", 2: "degenerate geometry", 3: "not converged"}

_MAX_COND = 1e10


@dataclass(frozen=True)
class TdoaLsResult:
    """Per-epoch LS fixes.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds.
    pos_m
        Positions, shape ``(T, dim)``, metres; NaN where no fix (see ``status``).
    cov_m2
        Covariances ``(HᵀΣ⁻¹H)⁻¹``, shape ``(T, dim, dim)``, m²; NaN where no fix.
    n_tdoa
        TDoAs used per epoch, shape ``(T,)``.
    n_iter
        Gauss–Newton iterations run, shape ``(T,)``.
    residual_rms_m
        RMS of the TDoA residuals at the solution, shape ``(T,)``, metres.
    status
        Codes per epoch, shape ``(T,)``: 0 ok, 1 too few anchors, 2 degenerate
        geometry, 3 not converged (see :data:`STATUS`).
    name
        Label of the fixes.
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    cov_m2: np.ndarray
    n_tdoa: np.ndarray
    n_iter: np.ndarray
    residual_rms_m: np.ndarray
    status: np.ndarray
    name: str = "LS"

    @property
    def ok(self) -> np.ndarray:
        """Epochs with a valid fix, bool ``(T,)``."""
        return self.status == 0

    def status_counts(self) -> dict[str, int]:
        """Number of epochs per status."""
        return {STATUS[k]: int(np.sum(self.status == k)) for k in STATUS}

    def to_frame(self) -> pd.DataFrame:
        """Table ``t_s, x_m, y_m[, z_m], sd_x_m, ..., n_tdoa, n_iter, residual_rms_m, status``."""
        axes = "xyz"[: self.pos_m.shape[1]]
        cols = {"t_s": self.t_s}
        cols.update({f"{a}_m": self.pos_m[:, k] for k, a in enumerate(axes)})
        sd = np.sqrt(np.diagonal(self.cov_m2, axis1=1, axis2=2))
        cols.update({f"sd_{a}_m": sd[:, k] for k, a in enumerate(axes)})
        cols.update(n_tdoa=self.n_tdoa, n_iter=self.n_iter, residual_rms_m=self.residual_rms_m,
                    status=[STATUS[int(s)] for s in self.status])
        return pd.DataFrame(cols)

    def to_trajectory(self, name: str | None = None) -> Trajectory:
        """The valid fixes as a :class:`~uwbwb.types.Trajectory` (failed epochs left out)."""
        return Trajectory(self.t_s[self.ok], self.pos_m[self.ok], name=name or self.name)

    def to_estimates(self, name: str | None = None) -> Estimates:
        """The common result type: valid fixes ``UPDATED`` (with covariance), failed epochs
        ``NO_ESTIMATE``; ``info`` holds ``n_tdoa``, ``n_iter`` and ``residual_rms_m``. Labelled
        :attr:`name` (``name`` given here, the older call, takes its place)."""
        ok = self.ok
        status = np.where(ok, EstimateStatus.UPDATED, EstimateStatus.NO_ESTIMATE).astype(np.int8)
        return Estimates(self.t_s, np.where(ok[:, None], self.pos_m, np.nan), status, name or self.name,
                         np.where(ok[:, None, None], self.cov_m2, np.nan), None,
                         {"n_tdoa": self.n_tdoa, "n_iter": self.n_iter, "residual_rms_m": self.residual_rms_m})


def _weights(log: TdoaLog, model: TdoaModel, used: np.ndarray) -> np.ndarray:
    """Inverse TDoA covariance per epoch embedded in ``(T, n, n)`` (zero outside the used rows)."""
    T, n = used.shape
    key = np.column_stack([used, log.ref]).astype(np.int64)
    patterns, inverse = np.unique(key, axis=0, return_inverse=True)
    W_pat = np.zeros((patterns.shape[0], n, n))
    for p, row in enumerate(patterns):
        others = np.flatnonzero(row[:n])
        if others.size == 0:
            continue
        Winv = np.linalg.inv(model.covariance(others, int(row[n])))
        W_pat[p][np.ix_(others, others)] = Winv
    return W_pat[inverse.ravel()]


def tdoa_least_squares(log: TdoaLog, model: TdoaModel, *, x0_m: np.ndarray | None = None, max_iter: int = 20,
                       tol_m: float = 1e-4, max_halvings: int = 6, name: str = "LS") -> TdoaLsResult:
    """Gauss–Newton TDoA fix for every epoch of ``log`` (vectorised over epochs).

    Parameters
    ----------
    log
        TDoAs per epoch.
    model
        Measurement model (anchors, noise, ``dim``, tag height).
    x0_m
        Starting point, shape ``(dim,)`` or ``(T, dim)``; default: the centroid
        of the anchors measured in each epoch.
    max_iter
        Maximum Gauss–Newton iterations.
    tol_m
        Convergence threshold on the step length, metres.
    max_halvings
        Step halvings tried when a full step increases the cost.
    name
        Label of the result (its ``to_estimates()`` and ``to_trajectory()``).

    Returns
    -------
    TdoaLsResult
    """
    integer("max_iter", max_iter, minimum=1)
    number("tol_m", tol_m, minimum=0.0, strict_minimum=True)
    integer("max_halvings", max_halvings, minimum=0)
    if log.n_anchors != model.n_anchors:
        raise ValueError(f"tdoa_least_squares: log has {len(log.anchor_ids)} anchors, model {model.n_anchors}")
    T, n = log.tdoa_m.shape
    d = model.dim
    ref = np.clip(log.ref, 0, None)
    measured = np.isfinite(log.tdoa_m)
    used = measured.copy()
    used[np.arange(T), ref] = False
    used &= (log.ref >= 0)[:, None]
    n_tdoa = used.sum(axis=1)
    enough = n_tdoa >= d
    z = np.where(used, log.tdoa_m, 0.0)
    W = _weights(log, model, used)

    if x0_m is None:
        a = model.anchor_pos_m[:, :d]
        cnt = np.maximum(measured.sum(axis=1, keepdims=True), 1)
        p = (measured.astype(float) @ a) / cnt
    else:
        p = np.broadcast_to(np.asarray(x0_m, float), (T, d)).copy()

    r = np.where(used, z - model.h(p, ref), 0.0)
    cost = np.einsum("ti,tij,tj->t", r, W, r)
    active = enough.copy()
    n_iter = np.zeros(T, int)
    converged = np.zeros(T, bool)
    degenerate = np.zeros(T, bool)
    for _ in range(max_iter):
        if not active.any():
            break
        idx = np.flatnonzero(active)
        J = np.where(used[idx, :, None], model.jacobian(p[idx], ref[idx]), 0.0)
        A = np.einsum("tid,tij,tje->tde", J, W[idx], J)
        b = np.einsum("tid,tij,tj->td", J, W[idx], r[idx])
        bad = ~(np.linalg.cond(A) < _MAX_COND)
        degenerate[idx[bad]] = True
        idx, A, b = idx[~bad], A[~bad], b[~bad]
        step = np.linalg.solve(A, b[..., None])[..., 0]
        # Step halving: accept the first of step, step/2, ... that does not increase the cost.
        alpha = np.ones(idx.size)
        accepted = np.zeros(idx.size, bool)
        p_k, c_k = p[idx], cost[idx]
        for _h in range(max_halvings + 1):
            pend = np.flatnonzero(~accepted)
            if pend.size == 0:
                break
            p_try = p_k[pend] + alpha[pend, None] * step[pend]
            r_try = np.where(used[idx[pend]], z[idx[pend]] - model.h(p_try, ref[idx[pend]]), 0.0)
            c_try = np.einsum("ti,tij,tj->t", r_try, W[idx[pend]], r_try)
            good = c_try <= c_k[pend] * (1 + 1e-12) + 1e-15
            g = pend[good]
            p[idx[g]], r[idx[g]], cost[idx[g]] = p_try[good], r_try[good], c_try[good]
            accepted[g] = True
            alpha[pend[~good]] /= 2
        n_iter[idx] += 1
        # Converged: the accepted step is below tol_m, or no step decreases the cost (numerical minimum).
        taken = np.where(accepted, alpha * np.linalg.norm(step, axis=1), 0.0)
        done = taken < tol_m
        converged[idx[done]] = True
        active[idx[done]] = False
        active[degenerate] = False

    pos = np.full((T, d), np.nan)
    cov = np.full((T, d, d), np.nan)
    status = np.full(T, 3, int)
    status[~enough] = 1
    status[degenerate] = 2
    status[converged & ~degenerate] = 0
    ok = status == 0
    if ok.any():
        idx = np.flatnonzero(ok)
        J = np.where(used[idx, :, None], model.jacobian(p[idx], ref[idx]), 0.0)
        cov[idx] = np.linalg.inv(np.einsum("tid,tij,tje->tde", J, W[idx], J))
        pos[idx] = p[idx]
    rms = np.full(T, np.nan)
    rms[ok] = np.sqrt(np.sum(r[ok] ** 2, axis=1) / n_tdoa[ok])
    return TdoaLsResult(log.t_s.copy(), pos, cov, n_tdoa, n_iter, rms, status, name)
