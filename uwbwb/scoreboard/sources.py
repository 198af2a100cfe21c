"""Recordings named on the command line: ``DATASET/RECORDING``, a folder of tidy CSV files, or a case
folder of the Hanyang dynamic layout (``A<id>.csv`` per anchor, ``trajectory.csv``).

A name goes through the package's one registry of recordings (:func:`uwbwb.datasets.open`): a
name that a present dataset does not hold is an error listing the names it does hold, and nothing
is ever replaced by synthetic data.

:func:`external_estimators` gives the *external* rows a loaded recording brings (a tidy folder's
``external/*.csv``, :mod:`uwbwb.datasets.tidy`; a Hanyang case's authors' LS/ESKF).
"""

from __future__ import annotations

import os
from pathlib import Path

from .. import datasets
from ..datasets import hanyang_dynamic
from ..errors import DataNotFoundError
from ..types import Recording
from .estimators import ExternalEstimates

__all__ = ["LOADERS", "external_estimators", "load_target"]

#: Datasets whose recordings ``score`` can load by name, and what a name means there.
LOADERS = {
    "lias-planar-uwb": "a dynamic run: RECORDING of UWB_dynamic_exp_RECORDING.csv (fast, medium, ...)",
    "iasl-uwb-imu": "a scenario folder (scenario1, scenario2, ...)",
    "hanyang-outdoor-uwb": "a dynamic case below Dynamic_measurements (LOS/Trajectory_A/Case_1, ...)",
}


def load_target(spec: str, data_dir: str | os.PathLike | None = None) -> Recording:
    """Load ``spec``: a folder with ``ranges.csv``, ``anchors.csv`` (and ``truth.csv``) in the tidy
    format of :mod:`uwbwb.datasets.tidy`, a Hanyang dynamic case folder, or ``DATASET/RECORDING`` for a
    dataset in :data:`LOADERS` (opened by :func:`uwbwb.datasets.open`).

    A Hanyang case is loaded with its own registration (clock offset and the tag height fitted on its
    ranges, :func:`uwbwb.datasets.hanyang_dynamic.load_dynamic_case`); the authors' LS/ESKF ride along
    in ``meta``.

    Raises
    ------
    DataNotFoundError
        A folder that is not a recording, a dataset that is absent, or a name its dataset does not
        hold (the names it holds are listed).
    ValueError
        Neither a folder nor ``DATASET/RECORDING`` of a dataset in :data:`LOADERS`.
    """
    path = Path(spec).expanduser()
    if path.is_dir() and hanyang_dynamic._is_case(path):
        return hanyang_dynamic.load_dynamic_case(path)
    if path.is_dir():
        if not ((path / "ranges.csv").is_file() and (path / "anchors.csv").is_file()):
            raise DataNotFoundError(f"{path}: a tidy recording folder needs ranges.csv and anchors.csv "
                                    f"(and truth.csv to be scored); see uwbwb/datasets/tidy.py")
        return datasets.open(path)
    dataset, _, name = str(spec).partition("/")
    if dataset not in LOADERS or not name:
        known = "; ".join(f"{d}/NAME — {what}" for d, what in LOADERS.items())
        raise ValueError(f"{spec!r} is neither a folder nor DATASET/RECORDING of a known dataset ({known})")
    return datasets.open(spec, data_dir)


def external_estimators(rec: Recording, authors: tuple[str, ...] = ("LS", "ESKF")) -> list[ExternalEstimates]:
    """One *external* row per outside method of ``rec``, in the order given: a tidy folder's
    (``meta["external_estimates"]``: method → tag → trajectory, as :func:`uwbwb.datasets.tidy.load_recording` reads
    its ``external/*.csv``), then the Hanyang authors' ``authors`` of a case folder (``meta["authors_estimates"]``,
    ``LS.csv`` / ``ESKF.csv``; their ESKF also used the robot's IMU) — a Hanyang case without one of those files
    keeps that row, which then says it has no outside estimates; none for a recording with neither."""
    theirs, given = rec.meta.get("authors_estimates"), rec.meta.get("external_estimates", {})
    return ([ExternalEstimates(method, dict(tracks)) for method, tracks in given.items()]
            + [ExternalEstimates(f"authors {m} (external{', +IMU' if m == 'ESKF' else ''})",
                                 {"tag": theirs[m].to_trajectory()} if m in theirs else {})
               for m in (authors if theirs is not None else ())])
