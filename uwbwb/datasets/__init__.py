"""Public datasets: discovery, manifest + fetch, and one loader module per format.

Loader modules: :mod:`.lias` (lias-planar-uwb), :mod:`.iasl` (iasl-uwb-imu),
:mod:`.hanyang` (hanyang-outdoor-uwb static), :mod:`.tidy` (your own data in a
generic tidy CSV), :mod:`.chirps` (ultrasonic chirp logs as tidy CSV).
"""

from .discovery import (EXTERNAL_DIR, PROJECT_ROOT, SHARED_DIR, data_dirs, dataset_available,
                        find_dataset)

__all__ = ["EXTERNAL_DIR", "PROJECT_ROOT", "SHARED_DIR", "data_dirs", "dataset_available",
           "find_dataset"]

from .catalog import overview
from .manifest import DatasetInfo, load_datasets_info, load_manifest, verify

# ``fetch`` stays a sub-module (``uw.datasets.fetch.fetch(name)``), not shadowed by the function.
__all__ += ["DatasetInfo", "load_datasets_info", "load_manifest", "overview", "verify"]
from .standin import RoomData, load_lias_room

__all__ += ["RoomData", "load_lias_room"]
