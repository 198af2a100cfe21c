"""uwbwb — a Jupyter workbench for indoor UWB positioning research.

``import uwbwb as uw`` gives the containers and errors at top level and every
sub-module by role, loaded on first use: ``uw.geometry``, ``uw.metrics``, ``uw.bounds``,
``uw.plotting``, ``uw.datasets``, ``uw.calibration``, ``uw.models``, ``uw.filters``,
``uw.sim``, ``uw.experiments``, ``uw.scoreboard``, ``uw.widgets``, ... (every module or
package in this folder; ``docs/ANATOMY.md`` says which layer each belongs to).
"""

from importlib import import_module
from pkgutil import iter_modules

from .errors import DataFormatError, DataNotFoundError, GeometryError
from .types import (Anchors, ChirpFlag, ChirpLog, CleaningStep, EstimateStatus, Estimates, ImuLog, RangeLog,
                    RangeSamples, Recording, SetFixLog, TagRun, TdoaLog, Trajectory)

__version__ = "0.1.0"

__all__ = [
    "Anchors", "ChirpFlag", "ChirpLog", "CleaningStep", "DataFormatError", "DataNotFoundError", "EstimateStatus",
    "Estimates", "GeometryError", "ImuLog", "RangeLog", "RangeSamples", "Recording", "SetFixLog", "TagRun",
    "TdoaLog", "Trajectory", "__version__",
]

#: Every sub-module and sub-package of the package (found on disk, so a new one is reachable too).
_SUBMODULES = frozenset(m.name for m in iter_modules(__path__) if m.name != "__main__")


def __getattr__(name):
    # Sub-modules load on first use so that ``import uwbwb`` stays light
    # (matplotlib and ipywidgets are only imported by the modules that draw).
    if name in _SUBMODULES:
        return import_module(f".{name}", __name__)
    raise AttributeError(f"module 'uwbwb' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | _SUBMODULES)
