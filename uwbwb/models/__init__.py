"""Models shared by simulators and estimators.

:mod:`.ranging` (two-way ranging with per-pair bias/scale), :mod:`.motion`
(random walk / random force / random jerk), :mod:`.tdoa` (TDoA measurements),
:mod:`.setnoise` (sensor-set position noise), :mod:`.imu` (IMU errors and sensor conventions),
:mod:`.ins` (strapdown mechanization and its error-state model).
"""

from . import imu, ins, motion, ranging, setnoise, tdoa

__all__ = ["imu", "ins", "motion", "ranging", "setnoise", "tdoa"]
