"""Registration: putting recordings made on several clocks and in several frames together.

A recording's ranges, motion-capture truth and IMU samples are stamped by
different clocks, and the motion capture may use its own frame and quaternion
convention. Nothing in the files says how they relate, so the loaders estimate
it from the data and report the estimate (and its method) in
``Recording.meta``. The estimators live here, one per question, so that every
loader answers the same question the same way:

* :func:`fit_clock_offset_and_convention` — clock offset between ranges and a
  rigid body's motion capture, and the frame convention (quaternion order,
  body-frame half turn), by minimising the robust spread of bias-removed range
  residuals (:func:`residual_spread`). Used by the ``lias-planar-uwb`` loader.
* :func:`register_truth` — translation (and optionally a yaw) from the
  motion-capture frame to the anchor frame plus the clock offset, by robust
  nonlinear least squares on every range. Used by the ``iasl-uwb-imu`` loader.
* :func:`align_imu` — IMU clock offset, by correlating the gyro magnitude with
  the rotation rate of the registered truth.
* :func:`align_imu_to_ranges` — the same offset without motion capture, by
  correlating the specific-force magnitude with that of the tag's own UWB fixes.

All raise :class:`RegistrationError` (or a :class:`~uwbwb.errors.DataFormatError`
naming the file) when the data cannot support an estimate; none of them
assumes an offset of zero.

Modules
-------
:mod:`.clock` (frame conventions, :func:`residual_spread`,
:func:`fit_clock_offset_and_convention`, :class:`RegistrationError`), :mod:`.truth`
(:func:`register_truth`, :class:`Registration`) and :mod:`.imu` (:func:`align_imu`, :func:`align_imu_to_ranges`,
:class:`ImuAlignment`); every name importable from here.
"""

from .clock import (BODY_FLIPS, GRAVITY_MPS2, QUAT_ORDERS, ClockFrameFit, RegistrationError, body_points,
                    fit_clock_offset_and_convention, frame_rotation, residual_spread)
from .imu import ImuAlignment, align_imu, align_imu_to_ranges
from .truth import Registration, register_truth

__all__ = ["BODY_FLIPS", "GRAVITY_MPS2", "QUAT_ORDERS", "ClockFrameFit", "ImuAlignment", "Registration",
           "RegistrationError", "align_imu", "align_imu_to_ranges", "body_points", "fit_clock_offset_and_convention", "frame_rotation",
           "register_truth", "residual_spread"]
