"""Two-way-ranging measurement model, shared by simulators and calibration.

A measured range relates to the true anchor–tag distance by a per-pair affine
distortion plus noise::

    range_meas = scale * range_true + bias + noise (+ occasional positive outlier)

so the inverse used by calibration is ``range_true ≈ (range_meas - bias) / scale``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
        for arr in (b, s):
            arr.setflags(write=False)
        object.__setattr__(self, "bias_m", b)
        object.__setattr__(self, "scale", s)

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
