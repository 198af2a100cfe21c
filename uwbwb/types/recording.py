"""One recording: anchors, ranges per tag, truth, IMU, cleaning steps and metadata."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .containers import Anchors, CleaningStep, ImuLog, RangeLog, Trajectory


@dataclass(frozen=True)
class Recording:
    """Everything loaded from one recording of a dataset.

    Attributes
    ----------
    dataset
        Dataset name, e.g. ``"lias-planar-uwb"``.
    name
        Recording name within the dataset, e.g. ``"fast"`` or ``"8.14/pos1_deg_0"``.
    anchors
        Anchor positions in the frame of ``truth``.
    ranges
        One :class:`RangeLog` per tag, keyed by tag id.
    truth
        Ground-truth :class:`Trajectory` per tag id (may be empty), on the same
        clock as ``ranges`` after the loader's registration.
    imu
        Optional inertial log on the same clock.
    cleaning
        What the loader removed or changed, step by step.
    meta
        Anything else worth reporting (estimated clock offset, source paths, ...).
    """

    dataset: str
    name: str
    anchors: Anchors
    ranges: Mapping[str, RangeLog]
    truth: Mapping[str, Trajectory] = field(default_factory=dict)
    imu: ImuLog | None = None
    cleaning: tuple[CleaningStep, ...] = ()
    meta: Mapping[str, object] = field(default_factory=dict)

    def __post_init__(self):
        for tag, log in self.ranges.items():
            if tuple(log.anchor_ids) != tuple(self.anchors.ids):
                raise ValueError(f"range log of tag {tag!r} has anchors {log.anchor_ids}, "
                                 f"recording anchors are {self.anchors.ids}")
        unknown = set(self.truth) - set(self.ranges)
        if unknown:
            raise ValueError(f"truth given for tags {sorted(unknown)} that have no ranges")
        object.__setattr__(self, "cleaning", tuple(self.cleaning))

    @property
    def tags(self) -> tuple[str, ...]:
        return tuple(self.ranges)

    @property
    def label(self) -> str:
        """``dataset/name``, as used in the ``data`` column of summaries."""
        return f"{self.dataset}/{self.name}"

    def decimate(self, step: int) -> "Recording":
        """Every ``step``-th range epoch of every tag: the one thinning rule of the package.

        Ranges keep epochs ``0, step, 2·step, …`` of each tag. A tag's truth that is
        sampled on that tag's range epochs (same time stamps, e.g. static poses or a
        simulator's truth) is thinned alike; truth on its own clock (e.g. motion
        capture at another rate) is kept whole, since estimates are compared with it
        by interpolation. The IMU log is kept whole. ``meta["decimated"]`` holds the
        total step (steps multiply when decimating twice).

        Parameters
        ----------
        step
            Positive integer; 1 returns the recording unchanged.

        Raises
        ------
        ValueError
            If ``step`` is not a positive integer.
        """
        if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 1:
            raise ValueError(f"{self.label}: decimation step must be a positive integer, got {step!r}")
        step = int(step)
        if step == 1:
            return self
        ranges = {t: log.select(slice(None, None, step)) for t, log in self.ranges.items()}
        truth = {}
        for t, tr in self.truth.items():
            log = self.ranges[t]
            on_ranges = len(tr) == len(log) and np.array_equal(tr.t_s, log.t_s)
            truth[t] = tr.select(slice(None, None, step)) if on_ranges else tr
        meta = {**self.meta, "decimated": step * int(self.meta.get("decimated", 1))}
        return Recording(self.dataset, self.name, self.anchors, ranges, truth, self.imu, self.cleaning, meta)

    def cleaning_report(self) -> str:
        """One line per cleaning step, or a note that nothing was removed."""
        if not self.cleaning:
            return f"{self.label}: no cleaning steps were needed"
        return "\n".join(f"{self.label}: {s}" for s in self.cleaning)


