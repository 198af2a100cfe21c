"""Noise-model fitting, all in one place.

* Per anchor–tag range calibration from recordings with known positions
  (:class:`RangeCalibration`, :func:`fit_range_calibration`), described below;
* range-noise level per anchor and the empirical TDoA covariance, for the TDoA filters
  (:func:`range_sigma_from_truth`, :func:`fit_range_sigma`, :func:`empirical_tdoa_covariance`);
* where a low percentile of NLOS-affected ranges lands, per static file (:func:`percentile_by_file`);
* the sensor-set noise model of paper 000 (:func:`fit_set_noise`, :func:`fit_set_noise_from_fixes`,
  :func:`location_statistics`).

Range calibration
-----------------

Two-way ranges carry systematic, pair-specific distortions (antenna delays,
body shadowing). We model them as in :mod:`uwbwb.models.ranging`::

    range_meas = scale * range_true + bias + noise

and fit ``(bias, scale)`` for every anchor–tag pair by robust linear regression
of measured on true ranges, where the true range comes from the recording's
ground truth (static poses: pose ⊕ tag offset; dynamic runs: motion capture).
Applying the calibration inverts the model: ``range_true ≈ (range_meas − bias) / scale``.

Fit: Huber M-estimation by iteratively reweighted least squares, vectorised
over all pairs at once. The Huber threshold is ``1.345 × σ̂`` with σ̂ the
normalised median absolute deviation of the current residuals, which keeps
95 % efficiency for Gaussian noise while bounding the pull of NLOS outliers.
A pair whose true ranges span less than ``min_span_m`` cannot separate scale
from bias: it gets a bias-only fit (scale fixed at 1) and is flagged.

Results are plain tables, saved as CSV or JSON (never pickle).

Modules
-------
:mod:`.twr` (two-way range calibration: :class:`RangeCalibration`, :func:`fit_range_calibration`,
:func:`true_ranges`, :func:`pair_samples`, :func:`range_residuals`, :func:`tag_mount_height`,
:data:`MAD_TO_SIGMA`) and :mod:`.noise` (range noise per anchor, the TDoA covariance, NLOS
percentiles per file, the set-noise model of paper 000); every name importable from here.
"""

from .noise import (SET_MIN_COUNT, empirical_tdoa_covariance, fit_range_sigma, fit_set_noise, fit_set_noise_from_fixes,
                    location_statistics, percentile_by_file, range_sigma_from_truth)
from .twr import (MAD_TO_SIGMA, MountHeight, RangeCalibration, fit_range_calibration, pair_samples, range_residuals,
                  tag_mount_height, true_ranges)

__all__ = ["MAD_TO_SIGMA", "MountHeight", "RangeCalibration", "SET_MIN_COUNT", "empirical_tdoa_covariance",
           "fit_range_calibration", "fit_range_sigma", "fit_set_noise", "fit_set_noise_from_fixes",
           "location_statistics", "pair_samples", "percentile_by_file", "range_residuals", "range_sigma_from_truth",
           "tag_mount_height", "true_ranges"]
