"""Recordings named on the command line: ``DATASET/RECORDING``, a folder of tidy CSV files, or a case
folder of the Hanyang dynamic layout (``A<id>.csv`` per anchor, ``trajectory.csv``)."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import DataNotFoundError
from ..types import Recording

__all__ = ["LOADERS", "load_target"]

#: Datasets whose recordings ``score`` can load by name, and what a name means there.
LOADERS = {
    "lias-planar-uwb": "a dynamic run: RECORDING of UWB_dynamic_exp_RECORDING.csv (fast, medium, ...)",
    "iasl-uwb-imu": "a scenario folder (scenario1, scenario2, ...)",
    "hanyang-outdoor-uwb": "a dynamic case below Dynamic_measurements (LOS/Trajectory_A/Case_1, ...)",
}


def load_target(spec: str, data_dir: str | os.PathLike | None = None) -> Recording:
    """Load ``spec``: a folder with ``ranges.csv``, ``anchors.csv`` (and ``truth.csv``) in the tidy
    format of :mod:`uwbwb.datasets.tidy`, a Hanyang dynamic case folder, or ``DATASET/RECORDING`` for a
    dataset in :data:`LOADERS`.

    A Hanyang case is loaded with its own registration (clock offset and the tag height fitted on its
    ranges, :func:`uwbwb.datasets.hanyang_dynamic.load_dynamic_case`); the authors' LS/ESKF ride along
    in ``meta``."""
    path = Path(spec).expanduser()
    from ..datasets import hanyang_dynamic

    if path.is_dir() and hanyang_dynamic._is_case(path):
        return hanyang_dynamic.load_dynamic_case(path)
    if path.is_dir():
        ranges, anchors, truth = path / "ranges.csv", path / "anchors.csv", path / "truth.csv"
        if not (ranges.is_file() and anchors.is_file()):
            raise DataNotFoundError(f"{path}: a tidy recording folder needs ranges.csv and anchors.csv "
                                    f"(and truth.csv to be scored); see uwbwb/datasets/tidy.py")
        from ..datasets import tidy

        return tidy.load_recording(ranges, anchors, truth if truth.is_file() else None, name=path.name)
    dataset, _, name = str(spec).partition("/")
    if dataset not in LOADERS or not name:
        known = "; ".join(f"{d}/NAME — {what}" for d, what in LOADERS.items())
        raise ValueError(f"{spec!r} is neither a folder nor DATASET/RECORDING of a known dataset ({known})")
    if dataset == "lias-planar-uwb":
        from ..datasets import lias

        return lias.load_dynamic(name, data_dir)
    if dataset == "hanyang-outdoor-uwb":
        return hanyang_dynamic.load_dynamic_case(name, data_dir)
    from ..datasets import iasl

    return iasl.load_scenario(name, data_dir)
