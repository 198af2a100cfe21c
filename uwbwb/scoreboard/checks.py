"""Is this recording scorable? Checks run before any method, with a diagnosis instead of a silent board.

A recording brought by a user (a tidy folder, :mod:`uwbwb.datasets.tidy`) can be wrong in ways
no loader sees: ranges or anchors in millimetres, a truth clock offset, x and y swapped, anchor
positions that do not belong to the ranges labelled with them, an anchor that never answers,
truth that does not cover the scored part, a 2-D truth without the tag height. Each of these
used to give a board of nonsense (RMSE 315 m), a refusal from deep inside the calibration
("scale must be positive") or an ``IndexError``. Here the measured ranges are compared with
the ranges *predicted* from the anchors and the truth, before anything is fitted:

* :func:`lift_truth` — a 2-D truth gets the tag height (given, or :func:`fit_tag_height`: the
  height at which the predicted ranges fit the measured ones best on the calibration part);
* :func:`drop_silent_anchors` — an anchor with fewer than ``min_samples`` ranges on the
  calibration part is dropped from both parts and counted in the recordings' cleaning steps;
* :func:`check_ranges_against_truth` — the median absolute residual
  ``|r_measured − ‖p_truth − a‖|`` per anchor, the truth clock offset that minimises it (always
  estimated and reported), and, where the residuals are gross, which single defect explains
  them (units, swapped or mirrored axes, a shifted truth frame, clock offset, mislabelled or misplaced
  anchors — anchors only when the evidence points at them, not at the truth);
* :func:`check_overlap` — the scored part must hold at least :data:`MIN_SCORED_EPOCHS` epochs
  with truth for every tag.

The thresholds are in the module constants; they are generous (a UWB range bias is decimetres;
these defects give metres).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..datasets.registration import residual_spread
from ..models.imu import RATE_SCALE_DEG_LIMIT
from ..models.ranging import predict_ranges
from ..types import CleaningStep, RangeLog, Recording, Trajectory

__all__ = ["MAX_RESIDUAL_M", "MIN_SCORED_EPOCHS", "MAX_OFFSET_S", "MIN_ANCHOR_SAMPLES", "RangeCheck",
           "check_overlap", "check_ranges_against_truth", "drop_silent_anchors", "fit_tag_height", "lift_truth",
           "shift_truth"]

#: Median |measured − predicted| range (over anchors, of the per-anchor medians) above which a recording is refused.
MAX_RESIDUAL_M = 1.0
#: Fewest scored epochs with truth per tag: twice the board's 20 blocks of the block standard error.
MIN_SCORED_EPOCHS = 40
#: Largest truth clock offset searched, seconds (a truth log started by hand may be tens of seconds off).
MAX_OFFSET_S = 30.0
#: Fewest ranges an anchor must give on the calibration part (the range calibration's minimum per pair).
MIN_ANCHOR_SAMPLES = 30
#: A defect is named when undoing it brings the residual below :data:`MAX_RESIDUAL_M` and by this factor.
EXPLAINS_FACTOR = 3.0


def _where(rec: Recording) -> str:
    files = rec.meta.get("source") if isinstance(rec.meta, Mapping) else None
    if isinstance(files, Mapping):
        shown = [str(v) for v in files.values() if isinstance(v, (str, Path))]
        if shown:
            return f"{rec.label} ({', '.join(shown)})"
    return rec.label


def _units_hint(rec: Recording) -> str:
    """What the loader's cleaning says when ranges went missing as implausibly long."""
    huge = [s for s in rec.cleaning if "implausible" in s.name]
    if not huge:
        return ""
    return (" — the loader set ranges above its plausible maximum to missing (" + "; ".join(str(s) for s in huge)
            + "): are the ranges in centimetres or millimetres? range_m must be metres")


def shift_truth(rec: Recording, offset_s: float) -> Recording:
    """``rec`` with every truth time stamp moved by ``−offset_s`` (truth that runs ``offset_s`` late)."""
    if not np.isfinite(offset_s):
        raise ValueError(f"truth offset must be finite, got {offset_s!r}")
    if offset_s == 0:
        return rec
    truth = {t: replace(tr, t_s=tr.t_s - float(offset_s)) for t, tr in rec.truth.items()}
    step = CleaningStep("truth clock shifted", sum(len(tr) for tr in truth.values()),
                        f"truth time stamps moved by {-offset_s:+.3f} s (given)")
    return replace(rec, truth=truth, cleaning=(*rec.cleaning, step))


def fit_tag_height(rec: Recording, tag: str) -> float:
    """The height at which ranges predicted from a 2-D truth fit the measured ranges best.

    Mean squared residual, each clipped at 1 m² (so that outliers do not decide), over a 1 cm grid
    from 3 m below the lowest anchor to 3 m above the highest. Refused (``ValueError``) when the fit
    is ambiguous — another local minimum of the cost (a mirror height when the anchors are nearly
    coplanar) within 10 % of the best — or the best fit leaves gross residuals.
    """
    log, tr = rec.ranges[tag], rec.truth[tag]
    a = rec.anchors.pos_m
    inside = (log.t_s >= tr.t_s[0]) & (log.t_s <= tr.t_s[-1])
    if inside.sum() < MIN_ANCHOR_SAMPLES:
        raise ValueError(f"{_where(rec)}: only {int(inside.sum())} range epochs of tag {tag!r} lie within its truth; "
                         f"cannot fit the tag height (give it: --tag-height-m)")
    idx = np.flatnonzero(inside)[:: max(1, int(inside.sum()) // 2000)]
    xy = tr.interp(log.t_s[idx])[:, :2]
    r = log.range_m[idx]
    z = np.arange(a[:, 2].min() - 3.0, a[:, 2].max() + 3.0, 0.01)
    d2 = np.sum((xy[:, None, :] - a[None, :, :2]) ** 2, axis=-1)                 # (T, n)
    cost = np.array([np.nanmean(np.minimum((r - np.sqrt(d2 + (zk - a[:, 2]) ** 2)) ** 2, 1.0)) for zk in z])
    best = int(np.nanargmin(cost))
    lm = np.flatnonzero((cost[1:-1] < cost[:-2]) & (cost[1:-1] <= cost[2:])) + 1
    rivals = [k for k in lm if k != best and cost[k] <= 1.1 * cost[best]]
    med = float(np.nanmedian(np.abs(r - np.sqrt(d2 + (z[best] - a[:, 2]) ** 2))))
    if med > MAX_RESIDUAL_M:
        raise ValueError(f"{_where(rec)}: no tag height makes the ranges of tag {tag!r} fit its 2-D truth (best "
                         f"median |residual| {med:.2f} m at z = {z[best]:.2f} m); check units and frames, "
                         f"or give the height (--tag-height-m)")
    if rivals:
        raise ValueError(f"{_where(rec)}: the tag height of {tag!r} is ambiguous from its ranges (z = {z[best]:.2f} m "
                         f"and z = {z[rivals[0]]:.2f} m fit alike: the anchors are nearly coplanar); give it "
                         f"(--tag-height-m)")
    return float(z[best])


def lift_truth(rec: Recording, tag_height_m: Mapping[str, float] | float | None = None
               ) -> tuple[Recording, dict[str, str]]:
    """``rec`` with every 2-D truth made 3-D at the tag's height.

    Parameters
    ----------
    tag_height_m
        A height for every tag, or per tag; None: fitted (:func:`fit_tag_height`) on the ranges of ``rec``.

    Returns
    -------
    (Recording, dict)
        The recording, and per lifted tag where its height came from.
    """
    truth, how = dict(rec.truth), {}
    for tag, tr in rec.truth.items():
        if tr.dim == 3:
            continue
        if isinstance(tag_height_m, Mapping):
            h = tag_height_m.get(tag)
        else:
            h = tag_height_m
        if h is None:
            h = fit_tag_height(rec, tag)
            how[tag] = f"height {h:.2f} m fitted from the ranges of {rec.label}"
        else:
            if not np.isfinite(h):
                raise ValueError(f"tag_height_m must be finite, got {h!r}")
            how[tag] = f"height {float(h):.2f} m given"
        truth[tag] = Trajectory(tr.t_s, np.column_stack([tr.pos_m, np.full(len(tr), float(h))]), name=tr.name)
    return (replace(rec, truth=truth) if how else rec), how


#: Anchors of a calibration and a scored recording that differ by more than this are different set-ups (m).
SAME_ANCHOR_TOL_M = 0.01


def check_same_anchors(cal: Recording, test: Recording, *, allow_moved: bool = False) -> str:
    """Refuse a calibration recording whose anchors are not the scored one's: every method would be tuned, and
    the ranges calibrated, for another set-up (``ValueError`` naming both and the largest difference). With
    ``allow_moved`` the same anchors (ids) may sit elsewhere — a deliberate transfer across layouts, e.g. the
    Hanyang trajectories — and the largest move is returned for the board's notes; "" when none moved."""
    if tuple(cal.anchors.ids) != tuple(test.anchors.ids):
        raise ValueError(f"calibration recording {cal.label} has anchors {list(cal.anchors.ids)}, the scored recording "
                         f"{test.label} {list(test.anchors.ids)}: calibrate on a recording of the same anchors")
    d = np.linalg.norm(np.asarray(cal.anchors.pos_m, float) - np.asarray(test.anchors.pos_m, float), axis=1)
    if np.any(d > SAME_ANCHOR_TOL_M):
        k = int(np.argmax(d))
        if allow_moved:
            return f"anchor {cal.anchors.ids[k]} {d[k]:.2f} m away, the largest move"
        raise ValueError(f"calibration recording {cal.label} places anchor {cal.anchors.ids[k]} {d[k]:.3f} m away from "
                         f"where the scored recording {test.label} has it (at most {SAME_ANCHOR_TOL_M:g} m): calibrate "
                         "on a recording of the same set-up")
    return ""


def check_height_applies(test: Recording, cal: Recording, tags: Sequence[str]) -> None:
    """A given tag height is for a 2-D truth: refuse it for a tag whose truth is 3-D (its height is in the truth;
    a second one would put the planar methods at another height than the one they are scored at)."""
    three_d = [t for t in tags if any(t in r.truth and r.truth[t].dim == 3 for r in (test, cal))]
    if three_d:
        raise ValueError(f"a tag height was given, but the truth of {', '.join(map(repr, three_d))} is 3-D: its "
                         "height comes from the truth (--tag-height-m is for a 2-D truth only)")


def drop_silent_anchors(cal: Recording, test: Recording, tags: Sequence[str], *,
                        min_samples: int = MIN_ANCHOR_SAMPLES) -> tuple[Recording, Recording, tuple[str, ...]]:
    """Drop anchors that give fewer than ``min_samples`` ranges to any of ``tags`` on ``cal``.

    Such an anchor cannot be calibrated. It is removed from both recordings (their ``cleaning``
    gets a counted step); a refusal only if fewer than three anchors remain.
    """
    n = np.array([np.isfinite(cal.ranges[t].range_m).sum(axis=0) for t in tags])        # (tags, anchors)
    silent = np.any(n < min_samples, axis=0)
    if not silent.any():
        return cal, test, ()
    ids = tuple(cal.anchors.ids)
    dropped = tuple(i for i, s in zip(ids, silent) if s)
    keep = ~silent
    if keep.sum() < 3:
        raise ValueError(f"{_where(cal)}: only {int(keep.sum())} anchors give at least {min_samples} ranges on the "
                         f"calibration part ({', '.join(f'{a}: {int(k)}' for a, k in zip(ids, n.min(axis=0)))}); "
                         f"at least 3 are needed{_units_hint(cal)}")

    def cut(rec: Recording) -> Recording:
        counts = {a: int(np.isfinite(log.range_m[:, ids.index(a)]).sum()) for log in rec.ranges.values()
                  for a in dropped}
        ranges = {t: RangeLog(log.t_s, log.range_m[:, keep], tuple(np.asarray(ids)[keep]), log.tag_id, log.t0)
                  for t, log in rec.ranges.items()}
        detail = ", ".join(f"{a} ({int(n.min(axis=0)[ids.index(a)])} ranges on the calibration part)"
                           for a in dropped)
        step = CleaningStep("silent anchors dropped", len(dropped),
                            f"anchors {detail}: fewer than {min_samples} ranges, cannot be calibrated; "
                            f"{sum(counts.values())} ranges of them removed here")
        return replace(rec, anchors=rec.anchors.subset(tuple(np.asarray(ids)[keep])), ranges=ranges,
                       cleaning=(*rec.cleaning, step))

    return cut(cal), cut(test), dropped


def check_overlap(rec: Recording, tags: Sequence[str], *, min_epochs: int = MIN_SCORED_EPOCHS,
                  part: str = "scored part") -> dict[str, int]:
    """Range epochs within the truth per tag; ``ValueError`` naming both spans if fewer than ``min_epochs``."""
    out = {}
    for tag in tags:
        log, tr = rec.ranges[tag], rec.truth[tag]
        n = int(np.sum((log.t_s >= tr.t_s[0]) & (log.t_s <= tr.t_s[-1]))) if len(tr) and len(log) else 0
        if n < min_epochs:
            span_r = f"{log.t_s[0]:.2f}–{log.t_s[-1]:.2f} s" if len(log) else "no epochs"
            span_t = f"{tr.t_s[0]:.2f}–{tr.t_s[-1]:.2f} s" if len(tr) else "no samples"
            raise ValueError(f"{_where(rec)}: tag {tag!r} has {n} epochs within its truth on the {part} (ranges "
                             f"{span_r}, truth {span_t}); at least {min_epochs} are needed — the truth does not "
                             f"cover the {part}, or --fraction leaves too little of it")
        out[tag] = n
    return out


@dataclass(frozen=True)
class RangeCheck:
    """Measured against predicted ranges for one tag (:func:`check_ranges_against_truth`).

    Attributes
    ----------
    tag
        The tag.
    residual_m
        Median over anchors of the per-anchor median ``|r_measured − r_predicted|``, metres.
    per_anchor_m
        Per anchor id, its median absolute residual, metres.
    offset_s
        Truth clock offset that minimises the residual (truth time = range time + offset), seconds.
    residual_at_offset_m
        The residual with that offset applied, metres.
    n_epochs
        Range epochs compared.
    shift_m
        Horizontal displacement of the truth from the anchors' frame that best explains the residuals (the
        truth minus this fits best), metres, within ±1 m.
    residual_at_shift_m
        The residual with that displacement undone, metres.
    """

    tag: str
    residual_m: float
    per_anchor_m: Mapping[str, float]
    offset_s: float
    residual_at_offset_m: float
    n_epochs: int
    shift_m: tuple[float, float] = (0.0, 0.0)
    residual_at_shift_m: float = np.nan

    @property
    def findings(self) -> list[str]:
        """Defects under the error threshold that the ranges still show: a truth clock offset of at least
        :data:`MIN_REPORTED_OFFSET_S`, or a horizontal truth shift of at least :data:`MIN_REPORTED_SHIFT_M`,
        that lowers the median residual by :data:`REPORT_GAIN` or more (smaller ones are not reported). On a
        straight stretch a clock offset and a shift along the track look alike: the one that explains more is
        named, and the other beside it when it explains about as much (within 20 %)."""
        found = []
        if abs(self.offset_s) >= MIN_REPORTED_OFFSET_S and self.residual_at_offset_m <= (1 - REPORT_GAIN) * self.residual_m:
            found.append((self.residual_at_offset_m,
                          f"the truth clock looks offset by {self.offset_s:+.2f} s (median residual "
                          f"{self.residual_m:.3f} → {self.residual_at_offset_m:.3f} m with it; if so, rerun with "
                          f"--truth-offset-s {self.offset_s:.2f})"))
        if (float(np.hypot(*self.shift_m)) >= MIN_REPORTED_SHIFT_M
                and self.residual_at_shift_m <= (1 - REPORT_GAIN) * self.residual_m):
            found.append((self.residual_at_shift_m,
                          f"the truth looks shifted by ({self.shift_m[0]:+.2f}, {self.shift_m[1]:+.2f}) m from the "
                          f"anchors' frame (median residual {self.residual_m:.3f} → {self.residual_at_shift_m:.3f} m "
                          "with the shift undone; check that truth and anchors share one frame)"))
        found.sort()
        keep = [text for res, text in found if res <= 1.2 * found[0][0]]
        return [f"tag {self.tag}: " + " — or ".join(keep)] if keep else []

    def describe(self) -> str:
        found = self.findings
        return (f"tag {self.tag}: measured vs predicted ranges, median |residual| {self.residual_m:.3f} m over "
                f"{self.n_epochs} epochs; truth clock offset estimate {self.offset_s:+.2f} s "
                f"(residual {self.residual_at_offset_m:.3f} m there); horizontal truth shift estimate "
                f"({self.shift_m[0]:+.2f}, {self.shift_m[1]:+.2f}) m (residual {self.residual_at_shift_m:.3f} m there); "
                + ("; ".join(f"WARNING {f}" for f in found) if found else
                   f"no offset ≥ {MIN_REPORTED_OFFSET_S:g} s or shift ≥ {MIN_REPORTED_SHIFT_M:g} m that lowers the "
                   f"residual by {100 * REPORT_GAIN:g} % (smaller ones are not reported)"))


#: What a range check reports below its error threshold (assumptions): a truth clock offset of at least this
#: many seconds, or a horizontal truth shift of at least this many metres, that at least halves the median range
#: residual. Per-anchor range biases are partly absorbed by a shift or an offset: on the real recordings
#: (LIAS fast t0–t2, i-ASL scenario 2, the four Hanyang cases) the best shifts are 0.05–0.32 m and lower the
#: residual by at most 65 % (a 0.16 m one), the best offsets up to 0.39 s by less than 20 %; none of them is
#: reported, while a truth 0.3 s late or shifted 0.7 m (the defects that passed silently before) are.
MIN_REPORTED_OFFSET_S = 0.05
MIN_REPORTED_SHIFT_M = 0.3
REPORT_GAIN = 0.5


def _cost(t: np.ndarray, r: np.ndarray, pos: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Median over anchors of the per-anchor median ``|r − ‖p − a‖|`` for each candidate truth ``pos`` (``(K, 3)``
    or ``(K, S, 3)`` on the epochs ``t``): the registration's statistic without its bias removal, ``(S,)``."""
    pts = pos if pos.ndim == 3 else pos[:, None, :]
    if t.size < 2:
        return np.full(pts.shape[1], np.inf)
    meas = np.broadcast_to(r[:, :, None], (*r.shape, pts.shape[1]))
    return residual_spread(t, meas, a, t, pts, [0.0], 0.0, statistic="median_abs")[0]


def _search_shift(t: np.ndarray, r: np.ndarray, pos: np.ndarray, a: np.ndarray,
                  stages: Sequence[tuple[float, float]]) -> tuple[tuple[float, float], float]:
    """The horizontal truth translation minimising the median range residual, coarse to fine: each stage
    ``(half, step)`` searches ±``half`` in steps of ``step`` around the previous stage's best."""
    centre, cost = (0.0, 0.0), float("inf")
    for half, step in stages:
        grid = np.arange(-half, half + 1e-9, step)
        c = np.array([_cost(t, r, pos[:, None, :] + np.column_stack([np.full(grid.size, centre[0] + dx),
                                                                      centre[1] + grid, np.zeros(grid.size)]), a)
                      for dx in grid])                                   # (dx, dy)
        i, j = np.unravel_index(int(np.argmin(c)), c.shape)
        centre, cost = (float(centre[0] + grid[i]), float(centre[1] + grid[j])), float(c[i, j])
    return centre, cost


#: Largest horizontal truth translation a diagnosis tries, metres (a reference frame whose origin is elsewhere).
MAX_DIAGNOSED_SHIFT_M = 5.0


def _offset(t: np.ndarray, r: np.ndarray, tr: Trajectory, a: np.ndarray, max_offset_s: float) -> tuple[float, float]:
    """The truth clock offset minimising the median range residual (the registration's
    :func:`~uwbwb.datasets.registration.residual_spread`, statistic ``median_abs``): 0.1 s grid, then 5 ms around the
    best; an offset at which the truth covers fewer than 20 % (or 10) of the epochs does not count."""
    n, best, c = int(np.floor(max_offset_s / 0.1 + 1e-9)), 0.0, np.full(1, np.inf)
    for grid in (np.arange(-n, n + 1) * 0.1, np.arange(-20, 21) * 0.005) if len(tr) > 1 else ():
        c = residual_spread(t, r[:, :, None], a, tr.t_s, tr.pos_m[:, None, :], best + grid, max(0.2, 10 / t.size),
                            statistic="median_abs")[:, 0]
        if not np.isfinite(c).any():
            return 0.0, float("inf")
        best = float(best + grid[int(np.argmin(c))])
    return best, float(np.min(c))


#: Slowest truth speed at which the track's course is read as the platform's heading, m/s.
MIN_COURSE_SPEED_MPS = 0.2


def check_gyro_against_truth(rec: Recording, tag: str) -> str:
    """Is the gyro in rad/s? The turn rate of the truth track against the gyro's vertical rate.

    The tilt test of the loaders (:func:`uwbwb.models.imu.imu_evidence`) needs tilt; a ground robot that only
    turns about the vertical shows none, so a gyro in deg/s passes it. With a truth, the course of the track
    (direction of the horizontal velocity, where the speed exceeds :data:`MIN_COURSE_SPEED_MPS`) turns at the
    heading rate for a platform that drives where it points, and the gyro's rate about the vertical (projected
    on the mean specific force, so any sensor frame will do) should match it: the least-squares factor ``k``
    between the two is about ±1 in rad/s and ±π/180 in deg/s. Raises ``ValueError`` when ``|k|`` is confidently
    below :data:`uwbwb.models.imu.RATE_SCALE_DEG_LIMIT` while course and gyro turn together (correlation above
    0.5; a platform that flies sideways, whose course is not its heading, makes no claim). Returns a line for
    the board's checks otherwise.
    """
    imu, tr = rec.imu, rec.truth[tag]
    t = np.arange(max(imu.t_s[0], tr.t_s[0]), min(imu.t_s[-1], tr.t_s[-1]), 0.1)
    if t.size < 50:
        return "gyro against the truth's course: too little overlap to compare"
    xy = tr.interp(t)[:, :2]
    kern = np.ones(5) / 5                                  # 0.5 s moving average against truth jitter
    v = np.column_stack([np.convolve(np.gradient(xy[:, i], t), kern, "same") for i in range(2)])
    a = np.column_stack([np.gradient(v[:, i], t) for i in range(2)])
    speed2 = np.sum(v ** 2, axis=1)
    up = np.median(imu.acc_mps2, axis=0)
    up = up / np.linalg.norm(up)
    w_up = np.interp(t, imu.t_s, imu.gyro_radps @ up)
    w_up = np.convolve(w_up, kern, "same")
    ok = (speed2 > MIN_COURSE_SPEED_MPS ** 2) & (np.arange(t.size) >= 2) & (np.arange(t.size) < t.size - 2)
    if ok.sum() < 50 or not np.any(w_up[ok]):
        return "gyro against the truth's course: the truth moves too little to compare"
    course_rate = (v[ok, 0] * a[ok, 1] - v[ok, 1] * a[ok, 0]) / speed2[ok]
    w = w_up[ok]
    k = float(course_rate @ w / (w @ w))
    r = course_rate - k * w
    se = float(np.sqrt((r @ r) / max(r.size - 1, 1) / (w @ w)))
    corr = float(np.corrcoef(course_rate, w)[0, 1]) if np.std(course_rate) > 0 and np.std(w) > 0 else 0.0
    line = (f"the truth's course turns at {k:+.3g} ± {se:.2g} × the gyro's vertical rate (correlation {corr:.2f}; "
            f"±1 for rad/s, ±{np.pi / 180:.4f} for deg/s)")
    if abs(corr) > 0.5 and abs(k) + 3 * se < RATE_SCALE_DEG_LIMIT:
        raise ValueError(f"{_where(rec)}: gyro rates look like deg/s, not rad/s: {line}, over {int(ok.sum())} "
                         f"samples of tag {tag!r}'s truth")
    return f"IMU: {line}"


def check_ranges_against_truth(rec: Recording, tag: str, *, max_residual_m: float = MAX_RESIDUAL_M,
                               max_offset_s: float = MAX_OFFSET_S) -> RangeCheck:
    """Compare ``tag``'s measured ranges with those predicted from the anchors and its (3-D) truth.

    Returns the :class:`RangeCheck` when the median residual is at most ``max_residual_m``;
    otherwise raises ``ValueError`` with the diagnosis: which single defect (ranges in cm or mm,
    anchors in mm, truth in mm, x/y swapped, an axis of the truth mirrored, the truth translated by up to
    :data:`MAX_DIAGNOSED_SHIFT_M`, a truth clock offset, anchors whose ranges fit another anchor's
    position, a minority of anchors that fit nothing) brings the residual down, or the per-anchor
    residuals when none does.
    """
    log, tr = rec.ranges[tag], rec.truth[tag]
    a = rec.anchors.pos_m
    where = _where(rec)
    if tr.dim != 3:
        raise ValueError(f"{where}: truth of tag {tag!r} is 2-D; lift it to the tag height first (lift_truth)")
    n_finite = int(np.isfinite(log.range_m).sum())
    if n_finite < MIN_ANCHOR_SAMPLES:
        raise ValueError(f"{where}: tag {tag!r} has only {n_finite} valid ranges{_units_hint(rec)}")
    inside = (log.t_s >= tr.t_s[0]) & (log.t_s <= tr.t_s[-1])
    ok_offset = inside.sum() >= 10
    idx = np.flatnonzero(inside)
    idx = idx[:: max(1, idx.size // 1500)]
    if ok_offset:
        pred = predict_ranges(tr.interp(log.t_s[idx]), a)
        r = log.range_m[idx]
        per = np.nanmedian(np.abs(r - pred), axis=0)
        base = float(np.nanmedian(per))
    else:
        per, base = np.full(len(a), np.nan), float("inf")
    all_idx = np.arange(len(log))[:: max(1, len(log) // 1500)]
    off, at_off = _offset(log.t_s[all_idx], log.range_m[all_idx], tr, a, max_offset_s)
    if ok_offset:   # ±1 m on 20, 4, then 1 cm grids, on at most 400 of the epochs
        few = idx[:: max(1, idx.size // 400)]
        shift, at_shift = _search_shift(log.t_s[few], log.range_m[few], tr.interp(log.t_s[few]), a,
                                        ((1.0, 0.2), (0.2, 0.04), (0.04, 0.01)))
    else:
        shift, at_shift = (0.0, 0.0), np.nan
    check = RangeCheck(tag, base, dict(zip(rec.anchors.ids, per.tolist())), off, at_off, int(idx.size),
                       (-shift[0] + 0.0, -shift[1] + 0.0), at_shift)
    if base <= max_residual_m and not np.any(per > max_residual_m):
        return check
    if not ok_offset and not np.isfinite(at_off):
        raise ValueError(f"{where}: the truth of tag {tag!r} ({tr.t_s[0]:.2f}–{tr.t_s[-1]:.2f} s) does not overlap "
                         f"its ranges ({log.t_s[0]:.2f}–{log.t_s[-1]:.2f} s), even {max_offset_s:g} s apart")
    # which single defect explains the residuals?
    t, r = log.t_s[idx], log.range_m[idx]
    pos = tr.interp(t)
    trials = {
        "the ranges look like millimetres (range_m must be metres)": (r / 1000.0, pos, a),
        "the ranges look like centimetres (range_m must be metres)": (r / 100.0, pos, a),
        "the anchor positions look like millimetres (x_m, y_m, z_m must be metres)": (r, pos, a / 1000.0),
        "the truth positions look like millimetres (x_m, y_m, z_m must be metres)": (r, pos / 1000.0, a),
        "x and y of the truth look swapped relative to the anchors": (r, pos[:, [1, 0, 2]], a),
        "x and y of the anchors look swapped relative to the truth": (r, pos, a[:, [1, 0, 2]]),
    }
    costs = {k: float(_cost(t, *v)[0]) for k, v in trials.items()} if base > max_residual_m else {}
    # defects of the truth's frame: they move every anchor's residual, so they are tried before blaming anchors.csv
    for axis, name in ((1, "y"), (0, "x")):
        flip = np.ones(3)
        flip[axis] = -1.0
        costs[f"the {name} axis of the truth looks mirrored relative to the anchors' ({name} → −{name}): truth and "
              "anchors must share one frame"] = float(_cost(t, r, pos * flip, a)[0])
    # a reference frame whose origin is elsewhere: ±MAX_DIAGNOSED_SHIFT_M on 50, 10, then 2 cm grids
    (dx, dy), at = _search_shift(t, r, pos, a, ((MAX_DIAGNOSED_SHIFT_M, 0.5), (0.5, 0.1), (0.1, 0.02)))
    costs[f"the truth looks shifted by ({-dx + 0.0:+.2f}, {-dy + 0.0:+.2f}) m from the anchors' frame (another origin?): truth "
          "and anchors must share one frame"] = at
    costs[f"the truth clock is offset: truth time = range time {off:+.2f} s (shift the truth, e.g. "
          f"--truth-offset-s {off:.2f})"] = at_off
    # defects the ranges cannot tell apart (x/y swapped in the truth or in the anchors: the same distances) tie up to
    # rounding; within a nanometre the first tried is named
    best = min(costs, key=lambda k: round(costs[k], 9))
    head = (f"{where}: measured ranges of tag {tag!r} do not fit the ranges predicted from the anchors and the "
            f"truth (median |residual| {base:.2f} m over {idx.size} epochs, worst anchor {np.nanmax(per):.2f} m; "
            f"at most {max_residual_m:g} m expected)")
    if costs[best] <= max_residual_m and costs[best] * EXPLAINS_FACTOR <= base:
        raise ValueError(f"{head}: {best} — undoing it leaves {costs[best]:.3f} m")
    # per anchor: do the ranges labelled i fit another anchor's position, or none?
    ids = rec.anchors.ids
    bad = [i for i, p in enumerate(per) if not p <= max_residual_m]
    good = len(per) - len(bad)
    pred = predict_ranges(pos, a)
    lines, matched = [], 0
    for i in bad:
        cross = np.nanmedian(np.abs(r[:, [i]] - pred), axis=0)
        j = int(np.nanargmin(cross)) if np.isfinite(cross).any() else i
        if j != i and cross[j] <= max_residual_m:
            matched += 1
            lines.append(f"the ranges labelled {ids[i]} fit the position of {ids[j]} (residual {cross[j]:.2f} m "
                         f"vs {per[i]:.2f} m for its own)")
        else:
            lines.append(f"the position of {ids[i]} does not fit its ranges (residual {per[i]:.2f} m)")
    # anchors.csv is blamed only where the evidence points at anchors: ranges that fit another anchor's position,
    # or a minority of anchors off while the rest fit (a defect of the truth or its clock moves them all)
    if bad and (matched or (good >= 3 and len(bad) < good)):
        raise ValueError(f"{head}: anchors.csv does not match the ranges: " + "; ".join(lines))
    shown = ", ".join(f"{i}: {p:.2f} m" for i, p in zip(ids, per))
    raise ValueError(f"{head}; no single defect tried explains it — units, swapped or mirrored axes, a truth shift "
                     f"within ±{MAX_DIAGNOSED_SHIFT_M:g} m, a clock offset within ±{max_offset_s:g} s (per anchor: "
                     f"{shown}); check that anchors, ranges and truth share one frame, metres and one clock")
