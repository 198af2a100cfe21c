"""Ranges to a node on a straight, constant-velocity track (Zupanec et al., eq. 1).

A node that starts at ``P`` (at ``t = 0``) and moves with constant velocity ``v``
is at ``P + v t``; its range to anchor ``k`` at time ``t_m`` is predicted as

.. math::  h_m(P, v) = \\lVert P + v\\, t_m - P_k \\rVert,
           \\qquad \\frac{\\partial h_m}{\\partial P} = u_m,
           \\quad \\frac{\\partial h_m}{\\partial v} = u_m t_m,
           \\quad u_m = \\frac{P + v t_m - P_k}{\\lVert P + v t_m - P_k \\rVert}.

The resolution routine (:func:`uwbwb.filters.nls.fit_trajectory`) minimises the sum of
squared residuals ``h_m − d_{k,m}`` over every range of one straight walk (eq. 1).

Unknowns ``theta``: ``[x, y, z, v_x, v_y, v_z]`` (``dim=3``) or ``[x, y, v_x, v_y]``
(``dim=2``: the node at the known height ``z_m``, ``v_z = 0``), without the velocity
part when ``static`` (``v = 0``: static localisation from all ranges).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from ..types import RangeSamples

__all__ = ["LinearTrackRanges", "anchor_array"]

_TINY_M = 1e-9


def anchor_array(anchors) -> np.ndarray:
    """Anchor positions ``(n_anchors, 3)`` from :class:`~uwbwb.types.Anchors` or an array, checked."""
    A = np.asarray(getattr(anchors, "pos_m", anchors), float)
    if A.ndim != 2 or A.shape[1] != 3 or A.shape[0] == 0:
        raise ValueError(f"anchors must have shape (n_anchors, 3), got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError("anchor positions must be finite")
    return A


@dataclass(frozen=True)
class LinearTrackRanges:
    """The eq. (1) range model of a node moving in a straight line.

    Attributes
    ----------
    anchor_pos_m
        Anchor positions, shape ``(n_anchors, 3)``, metres (an :class:`~uwbwb.types.Anchors` works too).
    dim
        3 (solve ``P, v`` in 3-D) or 2 (horizontal, node at height ``z_m``).
    static
        ``v = 0`` (no velocity unknowns).
    z_m
        Node height for ``dim=2`` (required), metres; not used (stored as None) for ``dim=3``.
    """

    anchor_pos_m: np.ndarray
    dim: int = 3
    static: bool = False
    z_m: float | None = None

    def __post_init__(self):
        A = anchor_array(self.anchor_pos_m)
        A.setflags(write=False)
        object.__setattr__(self, "anchor_pos_m", A)
        if self.dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {self.dim!r}")
        object.__setattr__(self, "static", bool(self.static))
        if self.dim == 2:
            if self.z_m is None or not np.isfinite(self.z_m):
                raise ValueError("dim=2 needs the node height z_m (metres)")
            object.__setattr__(self, "z_m", float(self.z_m))
        else:
            object.__setattr__(self, "z_m", None)

    @property
    def n_params(self) -> int:
        """Number of unknowns in ``theta``."""
        return self.dim * (1 if self.static else 2)

    # ------------------------------------------------------------ parameters
    def unpack(self, theta) -> tuple[np.ndarray, np.ndarray]:
        """``theta`` → ``(P, v)``, 3-vectors each (``z = z_m`` and ``v_z = 0`` for ``dim=2``)."""
        theta = np.asarray(theta, float)
        d = self.dim
        P = np.empty(3)
        v = np.zeros(3)
        P[:d] = theta[:d]
        if d == 2:
            P[2] = self.z_m
        if not self.static:
            v[:d] = theta[d: 2 * d]
        return P, v

    def pack(self, P, v) -> np.ndarray:
        """``(P, v)`` → ``theta`` (the solved coordinates only)."""
        d = self.dim
        return np.asarray(P, float)[:d].copy() if self.static else \
            np.concatenate([np.asarray(P, float)[:d], np.asarray(v, float)[:d]])

    def check_theta(self, theta) -> np.ndarray:
        """``theta`` as a float array, or a ValueError naming the expected shape."""
        theta = np.asarray(theta, float)
        if theta.shape != (self.n_params,):
            raise ValueError(f"theta must have shape ({self.n_params},) for dim={self.dim}, "
                             f"static={self.static}, got {theta.shape}")
        return theta

    # ------------------------------------------------------------ the model
    def residuals_jacobian(self, theta, t_s, anchor_index, range_m, *, jacobian: bool = True,
                           compiled: bool = True):
        """Residuals ``h_m − d_m`` ``(M,)`` and their Jacobian ``(M, n_params)`` (None if not wanted).

        The kernel every solver step calls: no checks, ``t_s`` ``(M,)`` relative to the time of ``P``.
        Row ``m`` of the Jacobian is ``[u_m, u_m t_m]`` restricted to the solved coordinates
        (only ``u_m`` when ``static``). ``compiled`` (default): one compiled loop over the rows
        (:func:`_residuals_jacobian`); False: the NumPy lines below, its declared twin
        (:mod:`uwbwb.filters.twins`).
        """
        P, v = self.unpack(theta)
        if compiled:
            # writeable C arrays: one compiled signature, the one compiled at install (numba types read-only
            # and Fortran-ordered arrays apart and would compile again at first use)
            res, J = _residuals_jacobian(P, v, *(np.require(x, dt, "CW") for x, dt in (
                (t_s, float), (anchor_index, np.intp), (range_m, float), (self.anchor_pos_m, float))),
                self.dim, self.static, jacobian)
            return res, (J if jacobian else None)
        diff = (P if self.static else P + np.multiply.outer(t_s, v)) - self.anchor_pos_m[anchor_index]   # (M, 3)
        dist = np.sqrt(np.einsum("mi,mi->m", diff, diff))
        res = dist - range_m
        if not jacobian:
            return res, None
        u = diff[:, : self.dim] / np.maximum(dist, _TINY_M)[:, None]                  # (M, dim)
        J = u if self.static else np.concatenate([u, u * t_s[:, None]], axis=1)
        return res, J

    def _terms(self, theta, samples: RangeSamples, t0_s, jacobian: bool):
        theta = self.check_theta(theta)
        if len(samples.anchor_ids) != self.anchor_pos_m.shape[0]:
            raise ValueError(f"samples have {len(samples.anchor_ids)} anchors, the model {self.anchor_pos_m.shape[0]}")
        t = samples.t_s
        if len(samples):
            t = t - (samples.t_s[0] if t0_s is None else float(t0_s))
        return self.residuals_jacobian(theta, t, samples.anchor_index, samples.range_m, jacobian=jacobian)

    def residuals(self, theta, samples: RangeSamples, *, t0_s: float | None = None) -> np.ndarray:
        """Residuals of eq. (1), ``||P + v t_m - P_k|| - d_{k,m}``, shape ``(M,)``, metres.

        Parameters
        ----------
        theta
            Unknowns (see the module notes), metres and m/s, ``P`` at time ``t0_s``.
        samples
            The measurements ``D`` (times in seconds).
        t0_s
            Time origin of ``P`` (``t_m = t_s - t0_s``); default the first sample's time, as in
            eq. (1) and :class:`~uwbwb.filters.nls.TrajectoryFit`.
        """
        return self._terms(theta, samples, t0_s, False)[0]

    def jacobian(self, theta, samples: RangeSamples, *, t0_s: float | None = None) -> np.ndarray:
        """Analytic Jacobian of :meth:`residuals`, shape ``(M, n_params)``."""
        return self._terms(theta, samples, t0_s, True)[1]

    def objective(self, theta, samples: RangeSamples, *, t0_s: float | None = None) -> tuple[float, np.ndarray]:
        """The sum of squares of eq. (1), m², and its analytic gradient ``2 Jᵀ r``, shape ``(n_params,)``."""
        r, J = self._terms(theta, samples, t0_s, True)
        return float(r @ r), 2.0 * (J.T @ r)


@numba.njit(cache=True, nogil=True)
def _residuals_jacobian(P, v, t_s, anchor_index, range_m, A, dim, static, jacobian):
    """:meth:`LinearTrackRanges.residuals_jacobian` row by row: the same differences, quotients and products;
    each squared length summed as NumPy's ``einsum`` sums three terms on the machines measured (``x² + z²``,
    then ``+ y²``). Returns the residuals ``(M,)`` and the Jacobian ``(M, n_params)`` (``(M, 0)`` when not
    ``jacobian``)."""
    M = t_s.size
    p = dim if static else 2 * dim
    res = np.empty(M)
    J = np.empty((M, p if jacobian else 0))
    d = np.empty(3)
    for m in range(M):
        a, t = anchor_index[m], t_s[m]
        for i in range(3):
            d[i] = (P[i] - A[a, i]) if static else ((P[i] + t * v[i]) - A[a, i])
        dist = math.sqrt((d[0] * d[0] + d[2] * d[2]) + d[1] * d[1])
        res[m] = dist - range_m[m]
        if jacobian:
            den = _TINY_M if dist < _TINY_M else dist          # np.maximum's: NaN stays NaN
            for i in range(dim):
                J[m, i] = d[i] / den
                if not static:
                    J[m, dim + i] = J[m, i] * t
    return res, J
