"""Where datasets are looked for.

Search order, first hit wins:

1. the ``data_dir`` argument (a notebook's ``DATA_DIR`` parameter), if given;
2. the directory in the ``UWBWB_DATA`` environment variable;
3. ``data/external/`` in the project (where ``python -m uwbwb fetch`` writes);
4. ``../shared/datasets/`` next to the project.

Each of these is a directory that holds one folder per dataset, named as in the
manifest (``lias-planar-uwb``, ``iasl-uwb-imu``, ``hanyang-outdoor-uwb``).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import DataNotFoundError

#: The project root (the folder holding ``uwbwb/``, ``notebooks/``, ``data/``).
PROJECT_ROOT = Path(__file__).resolve().parents[2]
#: Where ``fetch`` puts datasets by default.
EXTERNAL_DIR = PROJECT_ROOT / "data" / "external"
#: The shared copy of the public datasets, beside the project.
SHARED_DIR = PROJECT_ROOT.parent / "shared" / "datasets"


def data_dirs(data_dir: str | os.PathLike | None = None) -> list[tuple[str, Path]]:
    """Candidate data directories in search order, as ``(origin, path)`` pairs."""
    dirs: list[tuple[str, Path]] = []
    if data_dir is not None:
        dirs.append(("DATA_DIR argument", Path(data_dir).expanduser()))
    env = os.environ.get("UWBWB_DATA")
    if env:
        dirs.append(("UWBWB_DATA", Path(env).expanduser()))
    dirs.append(("data/external", EXTERNAL_DIR))
    dirs.append(("../shared/datasets", SHARED_DIR))
    return dirs


def find_dataset(name: str, data_dir: str | os.PathLike | None = None) -> Path:
    """Root folder of dataset ``name``.

    If ``data_dir`` is given it is the only place searched: a notebook told to
    use a folder must not quietly fall back to another copy.

    Raises
    ------
    DataNotFoundError
        Listing every place searched and how to fetch the data.
    """
    candidates = data_dirs(data_dir)
    if data_dir is not None:
        candidates = candidates[:1]
    for _, base in candidates:
        root = base / name
        if root.is_dir():
            return root
    searched = "\n".join(f"  - {base / name}  ({origin})" for origin, base in candidates)
    raise DataNotFoundError(
        f"dataset {name!r} not found. Searched:\n{searched}\n"
        f"Get it with:  python -m uwbwb fetch {name}   (writes to {EXTERNAL_DIR / name}),\n"
        f"or point UWBWB_DATA (or the notebook's DATA_DIR) at a folder that contains {name}/.")


def dataset_available(name: str, data_dir: str | os.PathLike | None = None) -> bool:
    """True when :func:`find_dataset` would succeed."""
    try:
        find_dataset(name, data_dir)
    except DataNotFoundError:
        return False
    return True
