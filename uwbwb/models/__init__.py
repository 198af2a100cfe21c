"""Models shared by simulators and estimators.

:mod:`.ranging` (two-way ranging with per-pair bias/scale), :mod:`.motion`
(random walk / random force / random jerk), :mod:`.tdoa` (TDoA measurements),
:mod:`.setnoise` (sensor-set position noise).
"""

from . import motion, ranging, setnoise, tdoa

__all__ = ["motion", "ranging", "setnoise", "tdoa"]
