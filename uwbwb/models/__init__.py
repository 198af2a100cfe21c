"""Models shared by simulators and estimators.

:mod:`.ranging` (two-way ranging with per-pair bias/scale), :mod:`.motion`
(random walk / random force / random jerk), :mod:`.tdoa` (TDoA measurements),
:mod:`.setnoise` (sensor-set position noise), :mod:`.imu` (IMU errors and sensor conventions),
:mod:`.ins` (strapdown mechanization and its error-state model), :mod:`.doppler` (Doppler
period shift of ultrasonic beacons, paper 003).
"""

from . import doppler, imu, ins, motion, ranging, setnoise, tdoa

__all__ = ["doppler", "imu", "ins", "motion", "ranging", "setnoise", "tdoa"]
