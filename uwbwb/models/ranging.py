"""Two-way-ranging measurement models, shared by simulators, calibration, bounds and estimators.

The one definition of the two-way range and its Jacobian: :func:`ranges` (``r_i = ‖p − a_i‖``)
and :func:`range_jacobian` (``∂r_i/∂p = (p − a_i)ᵀ / r_i``, the unit vector from anchor ``i`` to
the tag). :mod:`uwbwb.geometry` re-exports both; :mod:`uwbwb.bounds`, the simulators,
:func:`uwbwb.calibration.true_ranges` and :class:`~uwbwb.models.tdoa.TdoaModel` call them.

:class:`TwrRangeModel`: a measured range relates to the true anchor–tag distance by a
per-pair affine distortion plus noise::

    range_meas = scale * range_true + bias + noise (+ occasional positive outlier)

so the inverse used by calibration is ``range_true ≈ (range_meas - bias) / scale``.

:class:`NlosRangeModel`: that LOS part plus a coverage-dependent, persistent NLOS excess
(the bimodal error of Zupanec et al.), with its analytic error distribution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.stats import norm

from .. import validate


#: Floor on a range in the Jacobian's denominator (a tag exactly on an anchor), metres.
TINY_RANGE_M = 1e-12


def anchor_positions(anchor_pos_m) -> np.ndarray:
    """Anchor positions as a checked float array ``(n_anchors, 2 | 3)``; an :class:`~uwbwb.Anchors` works too."""
    A = np.asarray(getattr(anchor_pos_m, "pos_m", anchor_pos_m), dtype=float)
    if A.ndim != 2 or A.shape[1] not in (2, 3) or A.shape[0] == 0:
        raise ValueError(f"anchor_pos_m must have shape (n_anchors, 3) or (n_anchors, 2), got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError("anchor_pos_m contains non-finite values")
    return A


def tag_positions(pos_m, A: np.ndarray, z_m) -> np.ndarray:
    """Tag positions with the same number of coordinates as the anchors ``A`` (``z_m`` appended to 2-D ones)."""
    pos = np.asarray(pos_m, dtype=float)
    if pos.ndim == 0 or pos.shape[-1] not in (2, 3):
        raise ValueError(f"pos_m must have shape (..., 2) or (..., 3), got {pos.shape}")
    k, ka = pos.shape[-1], A.shape[1]
    if k == ka:
        if z_m is not None:
            raise ValueError("z_m is only used with 2-D positions and 3-D anchors")
        return pos
    if k == 2 and ka == 3:
        if z_m is None:
            raise ValueError("2-D positions with 3-D anchors need the tag height z_m")
        z = np.asarray(z_m, dtype=float)
        try:
            z = np.broadcast_to(z, pos.shape[:-1])
        except ValueError:
            raise ValueError(f"z_m of shape {z.shape} does not match positions of shape {pos.shape}") from None
        return np.concatenate([pos, z[..., None]], axis=-1)
    raise ValueError(f"3-D positions need 3-D anchors, got anchors of shape {A.shape}")


def predict_ranges(p: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Two-way ranges ``‖p − a_i‖`` without input checks (the kernel of :func:`ranges`).

    ``p`` has shape ``(..., d)`` and ``A`` ``(n_anchors, d)`` with the same ``d``; returns ``(..., n_anchors)``.
    """
    return np.linalg.norm(p[..., None, :] - A, axis=-1)


def predict_jacobian(p: np.ndarray, A: np.ndarray, k: int) -> np.ndarray:
    """``∂r_i/∂p`` over the first ``k`` coordinates without input checks (the kernel of :func:`range_jacobian`).

    ``p`` ``(..., d)``, ``A`` ``(n_anchors, d)``; returns ``(..., n_anchors, k)``, zero rows for a tag on an anchor.
    """
    diff = p[..., None, :] - A
    r = np.maximum(np.linalg.norm(diff, axis=-1), TINY_RANGE_M)
    return diff[..., :k] / r[..., None]


def ranges(pos_m, anchor_pos_m, *, z_m=None) -> np.ndarray:
    """Euclidean tag--anchor distances: the noise-free two-way range.

    Parameters
    ----------
    pos_m
        Tag positions, shape ``(..., 3)``, or ``(..., 2)`` together with ``z_m``, metres.
    anchor_pos_m
        Anchor positions, shape ``(n_anchors, 3)`` (or ``(n_anchors, 2)`` with
        2-D positions and no ``z_m``), metres; an :class:`~uwbwb.Anchors` works too.
    z_m
        Tag height for 2-D positions, scalar or broadcastable to ``pos_m.shape[:-1]``, metres.

    Returns
    -------
    numpy.ndarray
        Ranges, shape ``(..., n_anchors)``, metres.
    """
    A = anchor_positions(anchor_pos_m)
    return predict_ranges(tag_positions(pos_m, A, z_m), A)


def range_jacobian(pos_m, anchor_pos_m, *, z_m=None) -> np.ndarray:
    """Derivative of :func:`ranges` with respect to the given position coordinates.

    Row ``i`` is the unit vector from anchor ``i`` to the tag, restricted to the
    coordinates in ``pos_m`` (for 2-D positions with a known height it is the
    horizontal part of the 3-D unit vector, so its norm is below one).

    Parameters
    ----------
    pos_m, anchor_pos_m, z_m
        As in :func:`ranges`.

    Returns
    -------
    numpy.ndarray
        ``d r_i / d p_k``, shape ``(..., n_anchors, k)`` with ``k = pos_m.shape[-1]``.
        Rows for a tag exactly on an anchor are zero.
    """
    A = anchor_positions(anchor_pos_m)
    return predict_jacobian(tag_positions(pos_m, A, z_m), A, np.shape(pos_m)[-1])


def rigid_points(centroid_m: np.ndarray, yaw_rad: np.ndarray, offsets_m: np.ndarray) -> np.ndarray:
    """World positions of body-fixed points on a planar rigid body.

    Parameters
    ----------
    centroid_m
        Body origin, shape ``(T, 3)``, metres.
    yaw_rad
        Heading about +z, shape ``(T,)``, radians.
    offsets_m
        Body-frame point offsets, shape ``(n_points, 3)``, metres.

    Returns
    -------
    ndarray, shape ``(T, n_points, 3)``
    """
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    ox, oy, oz = offsets_m[:, 0], offsets_m[:, 1], offsets_m[:, 2]
    x = centroid_m[:, None, 0] + c[:, None] * ox - s[:, None] * oy
    y = centroid_m[:, None, 1] + s[:, None] * ox + c[:, None] * oy
    z = centroid_m[:, None, 2] + np.broadcast_to(oz, x.shape)
    return np.stack([x, y, z], axis=-1)


def _set_frozen(model, **arrays: np.ndarray) -> None:
    """Store checked arrays on a frozen model, read-only (they are its parameters, shared by reference)."""
    for name, arr in arrays.items():
        arr.setflags(write=False)
        object.__setattr__(model, name, arr)


@dataclass(frozen=True)
class TwrRangeModel:
    """Per anchor–tag affine range distortion with Gaussian noise and outliers.

    Attributes
    ----------
    bias_m
        Additive bias per pair, shape ``(n_tags, n_anchors)``, metres.
    scale
        Multiplicative scale per pair, shape ``(n_tags, n_anchors)``, dimensionless.
    sigma_m
        Standard deviation of the white range noise, metres.
    outlier_prob
        Probability that a range carries an extra positive (NLOS-like) error.
    outlier_mean_m
        Mean of that exponentially distributed extra error, metres.
    resolution_m
        Quantisation step of reported ranges (0 for none), metres.
    """

    bias_m: np.ndarray
    scale: np.ndarray
    sigma_m: float = 0.03
    outlier_prob: float = 0.0
    outlier_mean_m: float = 0.5
    resolution_m: float = 0.0

    def __post_init__(self):
        b = np.array(self.bias_m, float)
        s = np.array(self.scale, float)
        if b.ndim != 2 or s.shape != b.shape:
            raise ValueError(f"bias_m and scale must be equal 2-D (n_tags, n_anchors) arrays, got {b.shape}, {s.shape}")
        if np.any(s <= 0):
            raise ValueError("scale must be positive")
        if self.sigma_m < 0 or not 0 <= self.outlier_prob <= 1 or self.resolution_m < 0:
            raise ValueError("sigma_m, resolution_m must be >= 0 and outlier_prob in [0, 1]")
        _set_frozen(self, bias_m=b, scale=s)

    def distort(self, range_true_m: np.ndarray) -> np.ndarray:
        """Noise-free distorted ranges, ``scale * true + bias``; input ``(T, n_tags, n_anchors)``."""
        return self.scale * range_true_m + self.bias_m

    def sample(self, range_true_m: np.ndarray, *, rng: np.random.Generator) -> np.ndarray:
        """Measured ranges for true distances of shape ``(T, n_tags, n_anchors)``."""
        r = self.distort(range_true_m) + self.sigma_m * rng.standard_normal(range_true_m.shape)
        if self.outlier_prob > 0:
            hit = rng.random(range_true_m.shape) < self.outlier_prob
            r = r + hit * rng.exponential(self.outlier_mean_m, range_true_m.shape)
        r = np.maximum(r, 0.0)
        if self.resolution_m > 0:
            r = np.round(r / self.resolution_m) * self.resolution_m
        return r


@dataclass(frozen=True)
class NlosRangeModel:
    """Bimodal two-way-ranging error: LOS distortion + coverage-dependent NLOS excess (Zupanec et al., Figs 4–5).

    ``range = scale·d + bias + N(0, sigma²) + [NLOS]·max(N(mu, s²), 0)``, with
    ``P(NLOS)`` = ``p_nlos_in`` inside the anchor's coverage disc and
    ``p_nlos_out`` outside (logistic transition of width ``edge_m``), and a range
    failing (``ERR``, NaN) with ``p_err_in`` / ``p_err_out`` likewise.

    NLOS is a *state* of a node--anchor link, not a coin flip per range: a
    two-state Markov chain per link whose NLOS episodes last ``nlos_dwell_s`` on
    average and whose stationary NLOS probability is ``P(NLOS)`` at the node's
    current position (obstructions persist while the node stands still). With
    ``nlos_dwell_s = 0`` every range draws its state independently. The marginal
    error distribution at a point is the bimodal mixture either way.

    Attributes
    ----------
    los
        LOS part (per node and anchor bias/scale, noise, resolution).
    anchor_pos_m
        Anchors, shape ``(n_anchors, 3)``.
    coverage_m
        Coverage radius per anchor, shape ``(n_anchors,)``.
    p_nlos_in, p_nlos_out
        NLOS probability inside / outside the coverage disc.
    nlos_mean_m, nlos_sigma_m
        Mean and standard deviation of the NLOS excess (normal, clipped at 0), metres.
    p_err_in, p_err_out
        Probability of a failed range (NaN) inside / outside the disc.
    edge_m
        Width of the logistic transition at the disc's edge, metres.
    nlos_dwell_s
        Mean NLOS episode of a link, seconds (0: independent draws per range).
    """

    los: TwrRangeModel
    anchor_pos_m: np.ndarray
    coverage_m: np.ndarray
    p_nlos_in: float = 0.05
    p_nlos_out: float = 0.3
    nlos_mean_m: float = 2.5
    nlos_sigma_m: float = 1.0
    p_err_in: float = 0.02
    p_err_out: float = 0.15
    edge_m: float = 0.5
    nlos_dwell_s: float = 3.0

    def __post_init__(self):
        A = validate.points("anchor_pos_m", self.anchor_pos_m)
        R = np.array(self.coverage_m, float)
        if R.shape != (A.shape[0],):
            raise ValueError(f"coverage_m must have one radius per anchor, shape ({A.shape[0]},), got {R.shape}")
        if self.los.bias_m.shape[1] != A.shape[0]:
            raise ValueError("the LOS model must have one column per anchor")
        _set_frozen(self, anchor_pos_m=A, coverage_m=R)

    def _outside_dist(self, d_xy_m: np.ndarray) -> np.ndarray:
        return 1.0 / (1.0 + np.exp(-(d_xy_m - self.coverage_m) / (self.edge_m / 4)))

    def outside(self, pos_m) -> np.ndarray:
        """Degree of being outside each anchor's disc in [0, 1], shape ``(..., n_anchors)``."""
        d = np.linalg.norm(np.asarray(pos_m, float)[..., None, :2] - self.anchor_pos_m[:, :2], axis=-1)
        return self._outside_dist(d)

    def p_nlos(self, pos_m) -> np.ndarray:
        """NLOS probability per anchor at node positions ``(..., 3)``; shape ``(..., n_anchors)``."""
        w = self.outside(pos_m)
        return self.p_nlos_in + (self.p_nlos_out - self.p_nlos_in) * w

    def p_err(self, pos_m) -> np.ndarray:
        """Probability of a failed range per anchor; shape ``(..., n_anchors)``."""
        w = self.outside(pos_m)
        return self.p_err_in + (self.p_err_out - self.p_err_in) * w

    # ------------------------------------------------------------ the error distribution (Figs 4-5)
    def error_pdf(self, err_m, p_nlos: float, *, bias_m: float = 0.0) -> np.ndarray:
        """Density of ``range - true range`` for a given NLOS probability (1/m).

        A two-component normal mixture (the NLOS clip at 0 is ignored; it
        removes ``Phi(-mu/s)`` of the NLOS mass). Quantisation is ignored.
        """
        e = np.asarray(err_m, float) - bias_m
        s1 = max(self.los.sigma_m, 1e-9)
        s2 = np.hypot(s1, self.nlos_sigma_m)
        return (1 - p_nlos) * norm.pdf(e, 0, s1) + p_nlos * norm.pdf(e, self.nlos_mean_m, s2)

    def error_cdf(self, err_m, p_nlos: float, *, bias_m: float = 0.0) -> np.ndarray:
        """Cumulative distribution matching :meth:`error_pdf`."""
        e = np.asarray(err_m, float) - bias_m
        s1 = max(self.los.sigma_m, 1e-9)
        s2 = np.hypot(s1, self.nlos_sigma_m)
        return (1 - p_nlos) * norm.cdf(e, 0, s1) + p_nlos * norm.cdf(e, self.nlos_mean_m, s2)

    def error_quantile(self, q: float, p_nlos: float, *, bias_m: float = 0.0) -> float:
        """The ``q``-quantile (``0 < q < 1``) of :meth:`error_cdf`, metres."""
        if not 0 < q < 1:
            raise ValueError(f"q must lie in (0, 1), got {q!r}")
        span = 10 * (self.los.sigma_m + self.nlos_sigma_m + self.nlos_mean_m) + 1
        return float(brentq(lambda e: self.error_cdf(e, p_nlos) - q, -span, span)) + bias_m

    # ------------------------------------------------------------ sampling
    def sample(self, pos_m, *, rng: np.random.Generator, dt_s: float | None = None):
        """Measured ranges for node positions.

        Parameters
        ----------
        pos_m
            Node positions at the measurement instants, shape ``(T, n_tags, n_anchors, 3)``
            (each range may be taken at its own instant), metres.
        rng
            Random generator.
        dt_s
            Time between consecutive rows (the packet period), seconds: needed for
            NLOS episodes (``nlos_dwell_s > 0``); without it states are independent.

        Returns
        -------
        range_m : numpy.ndarray
            Shape ``(T, n_tags, n_anchors)``, metres, NaN for failed ranges.
        nlos : numpy.ndarray
            Bool, same shape: the range carries an NLOS excess.
        """
        pos = np.asarray(pos_m, float)
        n = self.anchor_pos_m.shape[0]
        if pos.ndim != 4 or pos.shape[2:] != (n, 3):
            raise ValueError(f"pos_m must have shape (T, n_tags, {n}, 3), got {pos.shape}")
        d = np.linalg.norm(pos - self.anchor_pos_m, axis=-1)
        w = self._outside_dist(np.linalg.norm(pos[..., :2] - self.anchor_pos_m[:, :2], axis=-1))
        r = self.los.sample(d, rng=rng)
        p_n = self.p_nlos_in + (self.p_nlos_out - self.p_nlos_in) * w
        p_e = self.p_err_in + (self.p_err_out - self.p_err_in) * w
        u = rng.random(d.shape)
        if self.nlos_dwell_s > 0 and dt_s is not None and d.shape[0] > 1:
            nlos = self._markov_states(p_n, u, dt_s)
        else:
            nlos = u < p_n
        excess = np.maximum(rng.normal(self.nlos_mean_m, self.nlos_sigma_m, d.shape), 0.0)
        if self.los.resolution_m > 0:
            excess = np.round(excess / self.los.resolution_m) * self.los.resolution_m
        r = r + nlos * excess
        r[rng.random(d.shape) < p_e] = np.nan
        return r, nlos

    def _markov_states(self, p_n: np.ndarray, u: np.ndarray, dt_s: float) -> np.ndarray:
        """NLOS states along axis 0 with stationary probability ``p_n`` (per row) and mean
        NLOS episode ``nlos_dwell_s``: P(N->L) = a, P(L->N) = a p / (1 - p)."""
        a = min(1.0, dt_s / self.nlos_dwell_s)
        p = np.clip(p_n, 0.0, 0.999)
        b = np.minimum(1.0, a * p / (1.0 - p))
        state = np.empty(p.shape, bool)
        state[0] = u[0] < p[0]
        for i in range(1, p.shape[0]):
            state[i] = np.where(state[i - 1], u[i] >= a, u[i] < b[i])
        return state
