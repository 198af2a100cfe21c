"""One registry of the recordings the package can load by name.

A recording is named ``"<dataset>/<name>"``, e.g. ``"iasl-uwb-imu/scenario2"``,
``"lias-planar-uwb/fast"``, ``"lias-planar-uwb/8.14/pos1_deg_0"`` or
``"hanyang-outdoor-uwb/NLOS/Trajectory_A/Case_1"``; a folder holding ``ranges.csv`` and
``anchors.csv`` (:mod:`uwbwb.datasets.tidy`) is opened by its path.

* :func:`open` loads one recording. A dataset that is not on this machine raises
  :class:`~uwbwb.errors.DataNotFoundError` saying where it was looked for; a name that a
  *present* dataset does not hold raises it too, listing the names that it does hold.
  Nothing is ever replaced by synthetic data here.
* :func:`open_pair` loads a calibration and a test recording and refuses to calibrate on
  the recording it scores.

Registering a loader
--------------------
A loader module joins with :func:`register` (at import of this module for the built-in
formats; any other code may register more)::

    register(Source("my-dataset", names=my_names, load=my_load, what="a run folder"))

``names(data_dir)`` lists the names found on disk (``data_dir`` as in
:mod:`uwbwb.datasets.discovery`, raising :class:`~uwbwb.errors.DataNotFoundError` when the
dataset is absent); ``load(name, data_dir, **options)`` loads one. Several sources may
serve one dataset (its static and dynamic parts); a name belongs to the source that lists
it. The built-in loader modules are imported on first use.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib import import_module
from pathlib import Path
from typing import Any, Callable

from ..errors import DataNotFoundError
from .discovery import find_dataset

__all__ = ["Source", "datasets", "names", "open", "open_pair", "register"]

PathLike = str | os.PathLike


@dataclass(frozen=True)
class Source:
    """Recordings of one dataset (or one part of it) that can be loaded by name.

    Attributes
    ----------
    dataset
        Dataset folder name, as in the manifest.
    names
        ``names(data_dir) -> list[str]``: the names present (without the dataset prefix).
    load
        ``load(name, data_dir, **options)``: one recording.
    what
        What a name means, for messages (``"a dynamic run: fast, medium, ..."``).
    """

    dataset: str
    names: Callable[[PathLike | None], list[str]]
    load: Callable[..., Any]
    what: str

    def __post_init__(self):
        if not isinstance(self.dataset, str) or not self.dataset or "/" in self.dataset:
            raise ValueError(f"Source.dataset must be a folder name without '/', got {self.dataset!r}")
        if not (callable(self.names) and callable(self.load)):
            raise ValueError(f"Source {self.dataset!r}: names and load must be callables")


_SOURCES: list[Source] = []


def register(source: Source) -> Source:
    """Add a source of recordings; returns it. A dataset may have several sources."""
    if not isinstance(source, Source):
        raise ValueError(f"register: expected a Source, got {type(source).__name__}")
    _SOURCES.append(source)
    return source


def datasets() -> list[str]:
    """Names of the datasets that have a registered loader."""
    return list(dict.fromkeys(s.dataset for s in _SOURCES))


def _sources_of(dataset: str) -> list[Source]:
    found = [s for s in _SOURCES if s.dataset == dataset]
    if not found:
        raise ValueError(f"no loader for a dataset called {dataset!r}; known datasets: {datasets()} "
                         f"(or give a folder holding ranges.csv and anchors.csv)")
    return found


def names(dataset: str, data_dir: PathLike | None = None) -> list[str]:
    """Every name of ``dataset`` found on disk, as ``"dataset/name"``.

    Raises
    ------
    DataNotFoundError
        The dataset is not in the data folders (the message says where it was looked for).
    """
    find_dataset(dataset, data_dir)
    out = []
    for s in _sources_of(dataset):
        out += [f"{dataset}/{n}" for n in s.names(data_dir)]
    return out


def open(spec: PathLike, data_dir: PathLike | None = None, **options):  # noqa: A001 (uw.datasets.open)
    """Load the recording ``spec``: ``"dataset/name"`` or a tidy-CSV folder.

    Parameters
    ----------
    spec
        ``"iasl-uwb-imu/scenario2"``, ``"lias-planar-uwb/fast"``, ... (:func:`names` lists
        them), or a folder holding ``ranges.csv`` and ``anchors.csv``.
    data_dir
        Folder holding dataset folders (None: the package's search order).
    options
        Passed to the loader (e.g. ``register=False`` for ``iasl-uwb-imu``).

    Raises
    ------
    DataNotFoundError
        The dataset is absent (where it was looked for), or it is present but holds no
        recording of that name (the names it holds are listed).
    ValueError
        No loader for that dataset, or no name given.
    """
    folder = Path(spec).expanduser()
    if folder.is_dir() and (folder / "ranges.csv").is_file():
        from . import tidy

        anchors, truth = folder / "anchors.csv", folder / "truth.csv"
        if options:
            raise ValueError(f"open: a tidy folder takes no loader options, got {sorted(options)}")
        if not anchors.is_file():
            raise DataNotFoundError(f"{folder}: a tidy recording folder needs ranges.csv and anchors.csv "
                                    f"(and truth.csv to be scored); see uwbwb/datasets/tidy.py")
        return tidy.load_recording(folder / "ranges.csv", anchors, truth if truth.is_file() else None,
                                   name=folder.name)
    dataset, _, name = str(spec).strip("/").partition("/")
    candidates = _sources_of(dataset)
    if not name:
        raise ValueError(f"open: {spec!r} names a dataset but no recording; its names: {names(dataset, data_dir)}")
    find_dataset(dataset, data_dir)
    present = []
    for s in candidates:
        listed = list(s.names(data_dir))
        if name in listed:
            return s.load(name, data_dir, **options)
        present += listed
    shown = ", ".join(present) if present else "none"
    what = "; ".join(s.what for s in candidates)
    raise DataNotFoundError(f"{dataset} has no recording {name!r} (a name is {what}). "
                            f"Names found in {find_dataset(dataset, data_dir)}: {shown}")


def open_pair(calibration: PathLike, test: PathLike, data_dir: PathLike | None = None, **options):
    """The calibration recording and the test recording, both by :func:`open`.

    Refuses to calibrate on the recording that is scored (the same name twice), and a
    pair whose anchor sets share no identifier (a per-pair calibration could not apply).

    Returns
    -------
    calibration, test
    """
    if str(calibration).strip("/") == str(test).strip("/"):
        raise ValueError(f"open_pair: the calibration and the test recording are both {str(test)!r}; "
                         f"calibrate on another recording than the one scored")
    cal, tst = open(calibration, data_dir, **options), open(test, data_dir, **options)
    a, b = getattr(cal, "anchors", None), getattr(tst, "anchors", None)
    if a is not None and b is not None and not set(a.ids) & set(b.ids):
        raise ValueError(f"open_pair: {calibration!r} has anchors {list(a.ids)}, {test!r} has {list(b.ids)}: "
                         f"no anchor in common, a range calibration of one cannot apply to the other")
    return cal, tst


# ---------------------------------------------------------------------------------- built-in sources

def _lazy(module: str, function: str):
    """``function`` of the loader module ``module``, imported on the first call."""
    return lambda *args, **options: getattr(import_module(f".{module}", __package__), function)(*args, **options)


def _lias_names(data_dir):
    from . import lias

    return list(lias.list_recordings(data_dir)["name"])


def _lias_load(name, data_dir, **options):
    from . import lias

    if "/" not in name:
        return lias.load_dynamic(name, data_dir, **options)
    session, pose = name.split("/", 1)
    site, yaw = pose[len("pos"):].split("_deg_")
    return lias.load_static(session, data_dir, site=int(site), yaw_deg=int(yaw), **options)[0]


def _iasl_names(data_dir):
    from . import iasl

    table = iasl.list_recordings(data_dir)
    return list(table.loc[table["has_uwb"], "name"])


def _hanyang_static_names(data_dir):
    from . import hanyang

    try:
        files = hanyang._scan(hanyang._static_root(data_dir))
    except DataNotFoundError:
        return []
    return ["static"] + [f"static/{c}" for c in dict.fromkeys(files["condition"])] if len(files) else []


def _hanyang_static_load(name, data_dir, **options):
    from . import hanyang

    condition = name.split("/", 1)[1] if "/" in name else None
    return hanyang.load_static(data_dir, condition=condition, **options)


register(Source("lias-planar-uwb", _lias_names, _lias_load,
                "a dynamic run (fast, medium, ...) or a static pose SESSION/posK_deg_YAW"))
register(Source("iasl-uwb-imu", _iasl_names, _lazy("iasl", "load_scenario"),
                "a scenario folder (scenario1, scenario2, ...)"))
register(Source("hanyang-outdoor-uwb", _hanyang_static_names, _hanyang_static_load,
                "the static sample table: static, static/LOS or static/NLOS"))
register(Source("hanyang-outdoor-uwb", _lazy("hanyang_dynamic", "dynamic_cases"),
                _lazy("hanyang_dynamic", "load_dynamic_case"), "a dynamic case CONDITION/Trajectory_X/Case_N"))
