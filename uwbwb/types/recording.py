"""One recording: anchors, ranges per tag, truth, IMU, cleaning steps and metadata.

**The truth rule.** Truth is compared with an estimate by linear interpolation of the tag's
:class:`Trajectory` at the estimate's times (:meth:`Recording.truth_at`). A time outside the
truth's span, or between two truth samples more than :data:`MAX_TRUTH_GAP_S` apart (a
motion-capture dropout) and not on a sample, has no truth (NaN). A time window
(:meth:`Recording.between`) keeps truth :data:`MAX_TRUTH_GAP_S` beyond each end, so that the
window's first and last epochs can still be interpolated.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from ._base import MAX_TRUTH_GAP_S
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

    def between(self, t_start_s: float, t_end_s: float, name: str | None = None) -> "Recording":
        """The epochs ``t_start_s <= t < t_end_s`` of every tag (the containers' time-window rule).

        Ranges and the IMU log are cut to the window; truth keeps :data:`MAX_TRUTH_GAP_S`
        beyond each end (module docstring). ``name`` renames the part (default: unchanged).
        """
        ranges = {t: log.between(t_start_s, t_end_s) for t, log in self.ranges.items()}
        truth = {t: tr.between(t_start_s - MAX_TRUTH_GAP_S, t_end_s + MAX_TRUTH_GAP_S)
                 for t, tr in self.truth.items()}
        imu = None if self.imu is None else self.imu.between(t_start_s, t_end_s)
        return replace(self, name=name or self.name, ranges=ranges, truth=truth, imu=imu)

    def truth_at(self, tag: str, t_s, dim: int | None = None) -> np.ndarray:
        """True positions of ``tag`` at ``t_s`` by the truth rule (module docstring).

        Parameters
        ----------
        tag
            A tag with truth.
        t_s
            Times, shape ``(T,)``, seconds.
        dim
            Coordinates returned (2: horizontal); default all of the truth's.

        Returns
        -------
        numpy.ndarray
            Shape ``(T, dim)``, metres; NaN where there is no truth.
        """
        if tag not in self.truth:
            raise KeyError(f"{self.label}: tag {tag!r} has no truth; tags with truth: {sorted(self.truth)}")
        tr = self.truth[tag]
        t_s = np.asarray(t_s, float)
        pos = tr.interp(t_s)[:, : (tr.dim if dim is None else dim)]
        if len(tr) > 1:
            i = np.clip(np.searchsorted(tr.t_s, t_s, side="right"), 1, len(tr) - 1)
            exact = np.isin(t_s, tr.t_s)
            pos[~exact & (tr.t_s[i] - tr.t_s[i - 1] > MAX_TRUTH_GAP_S)] = np.nan
        return pos

    def ranges_of(self, tag: str, calibration=None) -> RangeLog:
        """``tag``'s ranges, calibrated by ``calibration`` where one is given (a
        :class:`~uwbwb.calibration.RangeCalibration`, or anything with its ``apply(RangeLog) -> RangeLog``)."""
        return self.ranges[tag] if calibration is None else calibration.apply(self.ranges[tag])

    def range_rate_hz(self) -> float:
        """Range epoch rate: one over the median epoch step of all tags' logs pooled, Hz."""
        steps = np.concatenate([np.diff(log.t_s) for log in self.ranges.values()] or [np.array([])])
        if steps.size == 0:
            raise ValueError(f"{self.label}: no tag has two range epochs; the range rate is undefined")
        return float(1.0 / np.median(steps))

    def decimate(self, step: int | None = None, *, rate_hz: float | None = None) -> "Recording":
        """Every ``step``-th range epoch of every tag: the one thinning rule of the package.

        Ranges keep epochs ``0, step, 2·step, …`` of each tag. A tag's truth that is
        sampled on that tag's range epochs (same time stamps, e.g. static poses or a
        simulator's truth) is thinned alike; truth on its own clock (e.g. motion
        capture at another rate) is kept whole, since estimates are compared with it
        by interpolation. The IMU log is kept whole. ``meta["decimated"]`` holds the
        total step (steps multiply when decimating twice; ``{tag: step}`` when the tags'
        steps differ).

        Parameters
        ----------
        step
            Positive integer; 1 returns the recording unchanged.
        rate_hz
            Instead of ``step``: the epoch rate wanted, Hz. Each tag's step is the largest whole
            step that keeps at least ``rate_hz``: ``max(1, floor(1 / (rate_hz · dt)))``, ``dt`` the
            median step of that tag's range epochs (a tag with fewer than two epochs keeps them
            all); a rate at or above the data's returns the recording unchanged.

        Raises
        ------
        ValueError
            If ``step`` is not a positive integer, ``rate_hz`` not a positive number, or
            both or neither are given.
        """
        if (step is None) == (rate_hz is None):
            raise ValueError(f"{self.label}: decimate takes either step or rate_hz, got step={step!r}, "
                             f"rate_hz={rate_hz!r}")
        if rate_hz is not None:
            if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float, np.integer, np.floating)) \
                    or not np.isfinite(rate_hz) or rate_hz <= 0:
                raise ValueError(f"{self.label}: rate_hz must be a positive number of hertz, got {rate_hz!r}")
            steps = {t: (max(1, int(np.floor(1.0 / (float(rate_hz) * float(np.median(np.diff(log.t_s)))) + 1e-9)))
                         if len(log) > 1 else 1) for t, log in self.ranges.items()}
        else:
            if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 1:
                raise ValueError(f"{self.label}: decimation step must be a positive integer, got {step!r}")
            steps = {t: int(step) for t in self.ranges}
        if all(k == 1 for k in steps.values()):
            return self
        ranges = {t: log.select(slice(None, None, steps[t])) for t, log in self.ranges.items()}
        truth = {}
        for t, tr in self.truth.items():
            log = self.ranges.get(t)
            on_ranges = log is not None and len(tr) == len(log) and np.array_equal(tr.t_s, log.t_s)
            truth[t] = tr.select(slice(None, None, steps[t])) if on_ranges else tr
        before = self.meta.get("decimated", 1)
        total = {t: k * int(before[t] if isinstance(before, Mapping) else before) for t, k in steps.items()}
        meta = {**self.meta, "decimated": total.popitem()[1] if len(set(total.values())) == 1 else total}
        return Recording(self.dataset, self.name, self.anchors, ranges, truth, self.imu, self.cleaning, meta)

    def cleaning_report(self) -> str:
        """One line per cleaning step, or a note that nothing was removed."""
        if not self.cleaning:
            return f"{self.label}: no cleaning steps were needed"
        return "\n".join(f"{self.label}: {s}" for s in self.cleaning)


