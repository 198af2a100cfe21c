"""TDoA measurement model: pseudo-TDoA from ranges, analytic Jacobian, reference-correlated noise.

A TDoA (expressed as a range difference, metres) between anchor ``j`` and the
reference anchor ``k`` for a tag at ``p`` is

.. math::  h_j(p) = \\lVert p - a_j \\rVert - \\lVert p - a_k \\rVert,
           \\qquad \\frac{\\partial h_j}{\\partial p} = u_j(p) - u_k(p),
           \\quad u_i = \\frac{p - a_i}{\\lVert p - a_i \\rVert}.

The thesis (De Angelis, Sec. 6) forms TDoAs from the T4F system's two-way
ranges ("TOA converted to TDoA"). If range ``j`` carries independent noise of
variance ``σ_j²``, every difference with the same reference shares the
reference's noise, so

.. math::  Σ_{jl} = σ_j^2 δ_{jl} + σ_k^2, \\qquad Σ = σ^2 (I + 1 1^T)\\ \\text{for equal } σ.

With that covariance the TDoA vector carries exactly the information of the
ranges up to their common offset, so LS and EKF estimates do not depend on the
choice of reference. Ignoring the correlation (``correlated=False``,
``Σ = diag(σ_j² + σ_k²)``) is the common shortcut; then the reference matters.

2-D problems (``dim=2``) estimate the horizontal position of a tag at a known
height ``z_m``; the ranges still include the vertical anchor–tag offset.

Storage convention (:class:`uwbwb.types.TdoaLog`, built by :func:`uwbwb.types.pseudo_tdoa`):
``tdoa_m[t, j] = r_j − r_ref(t)``, exactly 0 in the reference column and NaN where anchor
``j`` has no measurement. Any other anchor of the epoch can serve as reference:
``tdoa_m[t] − tdoa_m[t, k]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validate
from ..types import TagRun
from .ranging import predict_jacobian, predict_ranges

__all__ = ["TdoaModel", "triangle_outliers"]


@dataclass(frozen=True)
class TdoaModel:
    """TDoA measurement model for a fixed set of anchors.

    Attributes
    ----------
    anchor_pos_m
        Anchor positions, shape ``(n_anchors, 3)``, metres.
    sigma_m
        Standard deviation of each anchor's range noise, scalar or shape
        ``(n_anchors,)``, metres.
    dim
        Estimated coordinates: 2 (x, y at known height ``z_m``) or 3.
    z_m
        Tag height for ``dim=2``, metres (ignored in 3-D).
    correlated
        Use the reference-correlated covariance (default) or only its diagonal.
    """

    anchor_pos_m: np.ndarray
    sigma_m: np.ndarray | float = 0.1
    dim: int = 2
    z_m: float = 0.0
    correlated: bool = True

    def __post_init__(self):
        a = validate.points("TdoaModel.anchor_pos_m", self.anchor_pos_m, minimum=3)
        if self.dim not in (2, 3):
            raise ValueError(f"TdoaModel.dim must be 2 or 3, got {self.dim!r}")
        s = np.broadcast_to(np.array(self.sigma_m, float), (a.shape[0],)).copy()
        with np.errstate(over="ignore", under="ignore"):
            var = s * s
        if np.any(~np.isfinite(s)) or np.any(s <= 0) or np.any(~np.isfinite(var)) or np.any(var == 0):
            raise ValueError(f"TdoaModel.sigma_m must be finite and positive with a representable variance "
                             f"(sigma_m**2 neither 0 nor inf), got {s.tolist()}")
        a.setflags(write=False)
        s.setflags(write=False)
        object.__setattr__(self, "anchor_pos_m", a)
        object.__setattr__(self, "sigma_m", s)
        object.__setattr__(self, "z_m", float(self.z_m))

    @classmethod
    def for_tag(cls, run: TagRun, sigma_m, *, correlated: bool = True) -> "TdoaModel":
        """The model of one :class:`~uwbwb.types.TagRun` (its anchors, dimension and tag height)."""
        return cls(run.anchors.pos_m, sigma_m, dim=run.dim, z_m=run.z_m, correlated=correlated)

    @property
    def n_anchors(self) -> int:
        return self.anchor_pos_m.shape[0]

    # ------------------------------------------------------------ geometry
    def _position(self, pos_m) -> np.ndarray:
        """Positions with the fixed height appended in 2-D, shape ``(..., 3)``."""
        p = np.asarray(pos_m, float)
        if p.shape[-1] != self.dim:
            raise ValueError(f"TdoaModel: positions must have {self.dim} coordinates, got shape {p.shape}")
        if self.dim == 2:
            p = np.concatenate([p, np.full(p.shape[:-1] + (1,), self.z_m)], axis=-1)
        return p

    def _offsets(self, pos_m) -> np.ndarray:
        """``p − a_i`` with the fixed height appended in 2-D, shape ``(..., n_anchors, 3)``."""
        return self._position(pos_m)[..., None, :] - self.anchor_pos_m

    def ranges(self, pos_m) -> np.ndarray:
        """True ranges to every anchor, shape ``(..., n_anchors)``, metres (:func:`~uwbwb.models.ranging.ranges`)."""
        return predict_ranges(self._position(pos_m), self.anchor_pos_m)

    def unit_vectors(self, pos_m) -> np.ndarray:
        """``∂r_i/∂p``, shape ``(..., n_anchors, dim)`` (the estimated coordinates only; :func:`~uwbwb.models.ranging.range_jacobian`)."""
        return predict_jacobian(self._position(pos_m), self.anchor_pos_m, self.dim)

    def h(self, pos_m, ref) -> np.ndarray:
        """Predicted TDoAs ``r_j − r_ref`` for every anchor, shape ``(..., n_anchors)`` (0 at ``ref``).

        ``ref`` is an int or an int array broadcastable to ``pos_m.shape[:-1]``.
        """
        r = self.ranges(pos_m)
        ref = np.broadcast_to(np.asarray(ref, int), r.shape[:-1])
        return r - np.take_along_axis(r, ref[..., None], axis=-1)

    def jacobian(self, pos_m, ref) -> np.ndarray:
        """Analytic ``∂h/∂p``, shape ``(..., n_anchors, dim)`` (zero row at ``ref``)."""
        u = self.unit_vectors(pos_m)
        ref = np.broadcast_to(np.asarray(ref, int), u.shape[:-2])
        return u - np.take_along_axis(u, ref[..., None, None], axis=-2)

    # ------------------------------------------------------------ noise
    def covariance(self, used, ref: int) -> np.ndarray:
        """Covariance of the TDoAs of anchors ``used`` (excluding ``ref``) w.r.t. ``ref``, ``(m, m)``.

        ``Σ = diag(σ_used²) + σ_ref² 1 1ᵀ`` (or ``diag(σ_used² + σ_ref²)`` if
        ``correlated`` is False).
        """
        used = np.asarray(used, int)
        if np.any(used == ref):
            raise ValueError("TdoaModel.covariance: the reference anchor cannot be among the differences")
        var = self.sigma_m[used] ** 2
        var_ref = self.sigma_m[ref] ** 2
        if self.correlated:
            return np.diag(var) + var_ref
        return np.diag(var + var_ref)

    def epoch(self, tdoa_row_m: np.ndarray, pos_m: np.ndarray, ref: int, anchors=None):
        """Everything one EKF/LS update needs from one epoch.

        Parameters
        ----------
        tdoa_row_m
            One row of :attr:`uwbwb.types.TdoaLog.tdoa_m`, shape ``(n_anchors,)``: range
            differences to that epoch's reference (0 there), NaN where missing.
        pos_m
            Linearisation point, shape ``(dim,)``.
        ref
            Reference anchor to use; any measured anchor works, because
            ``r_j − r_k = row[j] − row[k]`` whatever the row's own reference.
        anchors
            Anchor indices to use, ``ref`` included (default: all measured ones).

        Returns
        -------
        z, h, H, R, others
            Measured TDoAs ``(m,)``, predicted ``(m,)``, Jacobian ``(m, dim)``,
            covariance ``(m, m)`` and the anchor index of each row ``(m,)``.
        """
        row = np.asarray(tdoa_row_m, float)
        anchors = np.flatnonzero(np.isfinite(row)) if anchors is None else np.asarray(anchors, int)
        if ref not in anchors or not np.isfinite(row[ref]):
            raise ValueError(f"TdoaModel.epoch: reference {ref} is not among the measured anchors {anchors.tolist()}")
        others = anchors[anchors != ref]
        d = self._offsets(pos_m)                       # (n, 3): one pass for ranges and unit vectors
        r = np.sqrt(np.einsum("ij,ij->i", d, d))
        u = d[:, : self.dim] / np.maximum(r, 1e-12)[:, None]
        z = row[others] - row[ref]
        h = r[others] - r[ref]
        H = u[others] - u[ref]
        return z, h, H, self.covariance(others, ref), others


def triangle_outliers(tdoa_m: np.ndarray, ref, anchor_pos_m: np.ndarray, c_m: float) -> np.ndarray:
    """The TDoA plausibility test of paper 004, eq. (4): flag ``|L_{1,2}| > ‖P1 − P2‖ − C``.

    By the triangle inequality a range difference can never exceed the distance
    between its two stations; a TDoA within ``C`` of that bound (or beyond it) is
    taken as a multipath/NLOS outlier. The test sees only the measurement, so an
    NLOS excess that keeps the TDoA inside the bound passes it.

    Parameters
    ----------
    tdoa_m
        TDoAs ``r_j − r_ref`` as stored in :attr:`uwbwb.types.TdoaLog.tdoa_m`, shape
        ``(..., n_anchors)`` (0 at the reference, NaN where missing), metres.
    ref
        Reference anchor per row, int or int array of shape ``tdoa_m.shape[:-1]`` (−1: none).
    anchor_pos_m
        Anchor positions ``(n_anchors, 3)``, metres.
    c_m
        The margin ``C`` of eq. (4), metres (0: the plain triangle inequality; may be negative
        to tolerate measurements slightly beyond the bound).

    Returns
    -------
    ndarray of bool, shape ``tdoa_m.shape``
        True where a measured TDoA fails the test (never at the reference or where missing).
    """
    d = np.asarray(tdoa_m, float)
    a = np.asarray(anchor_pos_m, float)
    if a.ndim != 2 or a.shape != (d.shape[-1], 3):
        raise ValueError(f"triangle_outliers: anchor_pos_m must be ({d.shape[-1]}, 3), got {a.shape}")
    if not np.isfinite(c_m):
        raise ValueError(f"triangle_outliers: C must be finite, got {c_m!r}")
    ref = np.broadcast_to(np.asarray(ref, int), d.shape[:-1])
    baseline = np.linalg.norm(a[:, None, :] - a[None, :, :], axis=-1)          # (n, n)
    bound = baseline[np.clip(ref, 0, None)] - c_m                              # (..., n)
    out = np.isfinite(d) & (np.abs(d) > bound) & (ref >= 0)[..., None]
    idx = np.arange(d.shape[-1])
    return out & (idx != ref[..., None])
