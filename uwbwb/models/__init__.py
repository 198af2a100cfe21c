"""Models shared by simulators and estimators.

:mod:`.ranging` (two-way ranging with per-pair bias/scale, and its coverage-dependent NLOS
mixture), :mod:`.motion` (random walk / random force / random jerk, and the per-step velocity
kick of paper 000), :mod:`.track` (ranges to a straight constant-velocity track, the NLS of
paper 001), :mod:`.tdoa` (TDoA measurements),
:mod:`.setnoise` (sensor-set position noise), :mod:`.imu` (IMU errors and sensor conventions),
:mod:`.ins` (strapdown mechanization and its error-state model), :mod:`.doppler` (Doppler
period shift of ultrasonic beacons, paper 003).
"""

from . import doppler, imu, ins, motion, ranging, setnoise, tdoa, track

__all__ = ["doppler", "imu", "ins", "motion", "ranging", "setnoise", "tdoa", "track"]
