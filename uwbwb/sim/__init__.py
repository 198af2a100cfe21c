"""Simulators, one per scenario, built from the models in :mod:`uwbwb.models`.

:mod:`.rig` (planar trolley with several tags), :mod:`.setnoise` (sensor-set
facility, notebook 01), :mod:`.tours` (ceiling anchors and walking tours,
notebook 02), :mod:`.walk` (office walk and AGV runs, notebook 03), :mod:`.chirps`
(ultrasonic beacon chirps heard by a moving receiver, notebook 04), :mod:`.robot` (mobile
robot with IMU and TDoA tag, notebook 05), :mod:`.mismatch` (worlds that differ from
the filters' noise model, notebook 05).
"""

from . import chirps, mismatch, rig, robot, setnoise, tours, walk

__all__ = ["chirps", "mismatch", "rig", "robot", "setnoise", "tours", "walk"]
