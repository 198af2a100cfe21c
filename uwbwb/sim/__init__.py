"""Simulators, one per scenario, built from the models in :mod:`uwbwb.models`."""

from . import rig

__all__ = ["rig"]
