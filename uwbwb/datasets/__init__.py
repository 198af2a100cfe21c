"""Public datasets: discovery, one registry of recordings by name, manifest + fetch, and one
loader module per format.

``uw.datasets.open("iasl-uwb-imu/scenario2")`` loads a recording by name (a wrong name is an
error listing the names present); :func:`open_pair` a calibration and a test recording
(:mod:`.registry`); :func:`load_lias_room` uses a caller's stand-in only where the dataset is absent and
says why (:mod:`.standin`). Loader modules: :mod:`.lias` (lias-planar-uwb), :mod:`.iasl`
(iasl-uwb-imu), :mod:`.hanyang` (hanyang-outdoor-uwb static), :mod:`.tidy` (your own data in a
generic tidy CSV), :mod:`.chirps` (ultrasonic chirp logs as tidy CSV).
"""

from importlib import import_module

from .discovery import (EXTERNAL_DIR, PROJECT_ROOT, SHARED_DIR, data_dirs, dataset_available,
                        find_dataset)

__all__ = ["EXTERNAL_DIR", "PROJECT_ROOT", "SHARED_DIR", "data_dirs", "dataset_available",
           "find_dataset"]

from .catalog import overview
from .manifest import DatasetInfo, load_datasets_info, load_manifest, verify

# ``fetch`` stays a sub-module (``uw.datasets.fetch.fetch(name)``), not shadowed by the function.
__all__ += ["DatasetInfo", "load_datasets_info", "load_manifest", "overview", "verify"]
from .registry import Source, names, open, open_pair, register  # noqa: A004

__all__ += ["Source", "names", "open", "open_pair", "register"]
__all__ += ["RoomData", "load_lias_room"]

_LAZY = {"RoomData": "standin", "load_lias_room": "standin"}


def __getattr__(name):
    # The LIAS room loader builds its stand-in with uwbwb.sim; it loads on first use so that
    # ``import uwbwb.datasets`` (the CLI's fetch, the loaders) does not import every simulator.
    if name in _LAZY:
        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
