"""The fair protocol: one calibration, fitted on data that is never scored, shared by every method.

A recording with ground truth is cut into a *calibration part* and a *scoring part*
(:func:`split_in_time`: the first half calibrates, the second is scored — or another
recording of the same room calibrates, e.g. another IASL scenario). Everything any
method is allowed to know is fitted on the calibration part only and stored in one
:class:`Calibration`:

* the per anchor–tag range bias/scale (:func:`uwbwb.calibration.fit_range_calibration`);
* the range noise per anchor and tag: the robust spread (1.4826·MAD) of the calibrated
  range residuals, floored at ``floor_m`` — the Gaussian core every weighted method and
  every bound uses;
* the tag's mounting height (median truth height on the calibration part) and whether
  the problem is planar (``dim = 2`` when the calibration truth's height varies by less
  than :data:`PLANAR_SPREAD_M`) or 3-D;
* each method's tuning (driving noise of the EKFs, σ_d and the set-noise model of the
  set-noise filters, the NLS window), chosen on the calibration part by the method's own
  ``tune`` (see :mod:`uwbwb.scoreboard.estimators`).

The scoring part's truth is used only to compute errors and bounds.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ..calibration import RangeCalibration, fit_range_calibration
from ..types import Recording

__all__ = ["PLANAR_SPREAD_M", "fit_calibration", "scored_tags", "split_in_time"]

#: Calibration truth whose height (5th–95th percentile) spans less than this is a planar problem.
PLANAR_SPREAD_M = 0.15


def scored_tags(rec: Recording, tags: Sequence[str] | None = None) -> tuple[str, ...]:
    """Tags with ranges and truth (or ``tags``, checked)."""
    have = tuple(t for t in rec.tags if t in rec.truth)
    if tags is None:
        if not have:
            raise ValueError(f"{rec.label}: no tag has ground truth; the board needs truth to score against")
        return have
    missing = [t for t in tags if t not in have]
    if missing:
        raise ValueError(f"{rec.label}: tags {missing} have no ranges or no truth; available {list(have)}")
    return tuple(str(t) for t in tags)


def split_in_time(rec: Recording, fraction: float = 0.5) -> tuple[Recording, Recording]:
    """``(calibration part, scoring part)``: the first ``fraction`` of the run's span and the rest.

    The cut is at the same time for every tag; the parts share no range epoch. Their
    names say which part they are (``"fast [0–67 s]"``).
    """
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must be in (0, 1), got {fraction!r}")
    starts = [log.t_s[0] for log in rec.ranges.values() if len(log)]
    ends = [log.t_s[-1] for log in rec.ranges.values() if len(log)]
    if not starts:
        raise ValueError(f"{rec.label}: no ranges to split")
    t0, t1 = float(min(starts)), float(max(ends))
    tm = t0 + fraction * (t1 - t0)
    return (rec.between(t0, tm, f"{rec.name} [{t0:.0f}–{tm:.0f} s]"),
            rec.between(tm, t1 + 1e-9, f"{rec.name} [{tm:.0f}–{t1:.0f} s]"))


@dataclass(frozen=True)
class Calibration:
    """What every method may know, fitted on the calibration part (module docstring).

    Attributes
    ----------
    source
        Label of the data it was fitted on.
    dim
        2 (horizontal position at the known height) or 3.
    tag_height_m
        Mounting height per tag, metres (used when ``dim == 2``).
    range_calibration
        Per-pair range bias/scale (None: the ranges are used as logged, e.g. notebook 03's simulated runs
        and ranges calibrated beforehand).
    range_sigma_m
        Range-noise standard deviation per anchor, per tag, ``(n_anchors,)``, metres.
    rate_hz
        Epoch rate the methods run at.
    tuned
        Per method name, the parameters its ``tune`` chose on the calibration part.
    """

    source: str
    dim: int
    tag_height_m: Mapping[str, float]
    range_calibration: RangeCalibration | None
    range_sigma_m: Mapping[str, np.ndarray]
    rate_hz: float
    tuned: Mapping[str, Mapping] = field(default_factory=dict)

    def __post_init__(self):
        if self.dim not in (2, 3):
            raise ValueError(f"Calibration.dim must be 2 or 3, got {self.dim!r}")

    def height(self, tag: str) -> float | None:
        """``z_m`` for a 2-D solve (None in 3-D)."""
        return float(self.tag_height_m[tag]) if self.dim == 2 else None

    def sigma(self, tag: str) -> np.ndarray:
        """Range-noise standard deviation per anchor of ``tag``, metres."""
        try:
            return np.asarray(self.range_sigma_m[tag], float)
        except KeyError:
            raise KeyError(f"the calibration ({self.source}) has no tag {tag!r}; it covers "
                           f"{list(self.range_sigma_m)}") from None

    def params(self, name: str) -> Mapping:
        """The tuned parameters of method ``name`` (empty if it tunes nothing)."""
        return self.tuned.get(name, {})

    def with_tuned(self, name: str, params: Mapping) -> "Calibration":
        return replace(self, tuned={**self.tuned, name: dict(params)})

    def describe(self) -> str:
        """One line per fitted quantity."""
        lines = [f"calibration fitted on {self.source}: {self.dim}-D, {self.rate_hz:.3g} Hz"]
        for tag, s in self.range_sigma_m.items():
            h = f", height {self.tag_height_m[tag]:.2f} m" if self.dim == 2 else ""
            lines.append(f"  tag {tag}: range σ {np.min(s):.3f}–{np.max(s):.3f} m (median {np.median(s):.3f}){h}")
        for name, p in self.tuned.items():
            shown = {k: v for k, v in p.items() if np.ndim(v) == 0 and not hasattr(v, "__dataclass_fields__")
                     and not isinstance(v, Mapping)}
            if shown:
                lines.append(f"  {name}: " + ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"
                                                       for k, v in shown.items()))
        return "\n".join(lines)


def fit_calibration(rec: Recording, tags: Sequence[str] | None = None, *, rate_hz: float | None = None,
                    dim: int | None = None, floor_m: float = 0.02,
                    tag_height_m: Mapping[str, float] | None = None) -> Calibration:
    """Fit the shared part of the calibration on ``rec`` (the calibration part).

    Parameters
    ----------
    rec
        Calibration recording with ground truth for ``tags`` (3-D truth, or ``tag_height_m``).
    tags
        Tags to calibrate (default all with truth).
    rate_hz
        Rate the methods will run at (default the native rate); ``rec`` is thinned to it first.
    dim
        Force 2 or 3 (default: ``rec.meta["board_dim"]`` where the loader declares it, e.g. a ground robot's 2-D,
        else from the calibration truth's height spread).
    floor_m
        Lower limit of the range-noise standard deviation (resolution, unmodelled effects).
    tag_height_m
        Known mounting heights (default: median calibration truth height).

    Returns
    -------
    Calibration
        With no tuned parameters yet (see :func:`uwbwb.scoreboard.board.calibrate`).
    """
    tags = scored_tags(rec, tags)
    rec = rec if rate_hz is None else rec.decimate(rate_hz=rate_hz)
    sub = replace(rec, ranges={t: rec.ranges[t] for t in tags}, truth={t: rec.truth[t] for t in tags})
    heights, spreads = {}, []
    for t in tags:
        tr = sub.truth[t]
        if tr.dim == 3:
            z = tr.pos_m[:, 2]
            heights[t] = float(np.median(z))
            spreads.append(float(np.percentile(z, 95) - np.percentile(z, 5)))
        elif tag_height_m is None or t not in tag_height_m:
            raise ValueError(f"{rec.label}: truth of tag {t!r} is 2-D; give its mounting height (tag_height_m)")
    if tag_height_m is not None:
        heights.update({t: float(tag_height_m[t]) for t in tags if t in tag_height_m})
    if dim is None and rec.meta.get("board_dim") in (2, 3):      # a recording that declares its problem's dimension
        dim = int(rec.meta["board_dim"])
    if dim is None:
        dim = 2 if not spreads or max(spreads) < PLANAR_SPREAD_M else 3
    if dim == 3 and any(sub.truth[t].dim != 3 for t in tags):
        raise ValueError(f"{rec.label}: a 3-D board needs 3-D truth for every tag")
    if any(sub.truth[t].dim != 3 for t in tags):
        raise ValueError(f"{rec.label}: the range calibration needs 3-D truth for every tag")
    cal = fit_range_calibration(sub)
    sigma = {t: np.maximum(cal.resid_sigma_m[cal.tag_ids.index(t)], floor_m) for t in tags}
    steps = [np.median(np.diff(sub.ranges[t].t_s)) for t in tags if len(sub.ranges[t]) > 1]
    rate = float(1.0 / np.median(steps)) if steps else float("nan")
    return Calibration(rec.label, int(dim), heights, cal, sigma, rate)
