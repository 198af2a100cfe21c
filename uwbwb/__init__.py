"""uwbwb — a Jupyter workbench for indoor UWB positioning research.

``import uwbwb as uw`` gives the containers and errors at top level and the
sub-modules by role: ``uw.geometry``, ``uw.metrics``, ``uw.plotting``,
``uw.datasets``, ``uw.calibration``, ``uw.models``, ``uw.filters``, ``uw.sim``,
``uw.experiments``, ``uw.widgets``.
"""

from importlib import import_module

from .errors import DataFormatError, DataNotFoundError, GeometryError
from .types import (Anchors, ChirpFlag, ChirpLog, CleaningStep, EstimateStatus, Estimates, ImuLog, RangeLog,
                    RangeSamples, Recording, SetFixLog, TagRun, TdoaLog, Trajectory)

__version__ = "0.1.0"

__all__ = [
    "Anchors", "ChirpFlag", "ChirpLog", "CleaningStep", "DataFormatError", "DataNotFoundError", "EstimateStatus",
    "Estimates", "GeometryError", "ImuLog", "RangeLog", "RangeSamples", "Recording", "SetFixLog", "TagRun",
    "TdoaLog", "Trajectory", "__version__",
]

_SUBMODULES = {"geometry", "metrics", "plotting", "datasets", "calibration", "models",
               "filters", "sim", "experiments", "widgets", "cli", "parallel"}


def __getattr__(name):
    # Sub-modules load on first use so that ``import uwbwb`` stays light
    # (matplotlib and ipywidgets are only imported by the modules that draw).
    if name in _SUBMODULES:
        return import_module(f".{name}", __name__)
    raise AttributeError(f"module 'uwbwb' has no attribute {name!r}")
