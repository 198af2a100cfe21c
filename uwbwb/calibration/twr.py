"""Two-way range calibration: per anchor–tag ``(bias, scale)`` by robust regression on truth (see :mod:`uwbwb.calibration`)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterable, Sequence

import numba
import numpy as np
import pandas as pd

from ..models.ranging import ranges
from ..types import CleaningStep, RangeLog, Recording
from ..validate import integer, number

_HUBER_K = 1.345
#: Normal-consistent scale of the median absolute deviation: σ ≈ 1.4826 · MAD.
MAD_TO_SIGMA = 1.4826
_FORMAT = "uwbwb.range_calibration"
_COLUMNS = ["tag_id", "anchor_id", "bias_m", "scale", "scale_fitted", "n_samples",
            "true_span_m", "resid_median_m", "resid_sigma_m", "resid_rms_m"]


@dataclass(frozen=True)
class RangeCalibration:
    """Fitted per-pair range distortion; apply it to range logs of the same anchors and tags.

    Attributes
    ----------
    anchor_ids, tag_ids
        Labels of the pairs' anchors and tags.
    bias_m, scale
        Shape ``(n_tags, n_anchors)``; ``range_meas ≈ scale * range_true + bias_m``.
    scale_fitted
        Shape ``(n_tags, n_anchors)``, bool; False where only a bias was fitted.
    n_samples
        Samples each pair's fit used, shape ``(n_tags, n_anchors)``.
    true_span_m
        Spread (max − min) of the true ranges each fit saw, metres.
    resid_median_m, resid_sigma_m, resid_rms_m
        Post-fit residual median, robust σ (1.4826·MAD) and RMS per pair, metres.
    source
        Labels of the recordings the fit used.
    loss
        Description of the robust loss.
    """

    anchor_ids: tuple[str, ...]
    tag_ids: tuple[str, ...]
    bias_m: np.ndarray
    scale: np.ndarray
    scale_fitted: np.ndarray
    n_samples: np.ndarray
    true_span_m: np.ndarray
    resid_median_m: np.ndarray
    resid_sigma_m: np.ndarray
    resid_rms_m: np.ndarray
    source: tuple[str, ...] = ()
    loss: str = f"huber (IRLS, threshold {_HUBER_K} x 1.4826 MAD)"
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        shape = (len(self.tag_ids), len(self.anchor_ids))
        object.__setattr__(self, "anchor_ids", tuple(map(str, self.anchor_ids)))
        object.__setattr__(self, "tag_ids", tuple(map(str, self.tag_ids)))
        object.__setattr__(self, "source", tuple(map(str, self.source)))
        for name, dtype in (("bias_m", float), ("scale", float), ("scale_fitted", bool), ("n_samples", int),
                            ("true_span_m", float), ("resid_median_m", float), ("resid_sigma_m", float),
                            ("resid_rms_m", float)):
            arr = np.array(getattr(self, name), dtype=dtype)
            if arr.shape != shape:
                raise ValueError(f"RangeCalibration.{name} must have shape {shape}, got {arr.shape}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if np.any(self.scale <= 0):
            raise ValueError("RangeCalibration.scale must be positive")

    # ------------------------------------------------------------------ use
    def _check(self, log: RangeLog) -> int:
        if log.tag_id not in self.tag_ids:
            raise ValueError(f"calibration has no tag {log.tag_id!r} (it covers tags {list(self.tag_ids)})")
        if tuple(log.anchor_ids) != self.anchor_ids:
            raise ValueError(f"range log of tag {log.tag_id!r} has anchors {list(log.anchor_ids)}, "
                             f"the calibration was fitted for anchors {list(self.anchor_ids)}")
        return self.tag_ids.index(log.tag_id)

    def apply(self, log: RangeLog) -> RangeLog:
        """Calibrated copy of ``log``: ``(range_m − bias_m) / scale`` per anchor.

        A calibrated range that would be negative (a measurement below its
        pair's bias) is set missing (NaN); :meth:`apply_recording` counts them.
        """
        k = self._check(log)
        r = (log.range_m - self.bias_m[k]) / self.scale[k]
        return RangeLog(log.t_s, np.where(r < 0, np.nan, r), log.anchor_ids, log.tag_id, log.t0)

    def apply_recording(self, rec: Recording) -> Recording:
        """A copy of ``rec`` with every tag's ranges calibrated (a cleaning step records it)."""
        ranges = {tag: self.apply(log) for tag, log in rec.ranges.items()}
        n_clip = sum(int(np.sum((log.range_m - self.bias_m[self._check(log)]) < 0)) for log in rec.ranges.values())
        step = CleaningStep("range calibration", n_clip,
                            f"(range - bias)/scale per pair from {', '.join(self.source) or 'a fit'}; "
                            f"{n_clip} ranges below their pair's bias set missing")
        return replace(rec, ranges=ranges, cleaning=rec.cleaning + (step,),
                       meta={**rec.meta, "range_calibration": list(self.source)})

    # ------------------------------------------------------------- tables
    def to_frame(self) -> pd.DataFrame:
        """One row per pair with the columns of the CSV format."""
        t, a = np.meshgrid(np.arange(len(self.tag_ids)), np.arange(len(self.anchor_ids)), indexing="ij")
        df = pd.DataFrame({"tag_id": np.asarray(self.tag_ids, object)[t.ravel()],
                           "anchor_id": np.asarray(self.anchor_ids, object)[a.ravel()]})
        for col in _COLUMNS[2:]:
            df[col] = getattr(self, col).ravel()
        return df

    @classmethod
    def from_frame(cls, df: pd.DataFrame, *, source=(), loss=None, where="table") -> "RangeCalibration":
        missing = [c for c in _COLUMNS if c not in df.columns]
        if missing:
            hint = ""
            if any(c.endswith(("_cm", "_mm")) for c in df.columns):
                hint = " (this table is not in metres; uwbwb stores calibrations in SI units)"
            raise ValueError(f"{where}: calibration table lacks columns {missing}{hint}")
        tags = tuple(dict.fromkeys(df["tag_id"].astype(str)))
        anchors = tuple(dict.fromkeys(df["anchor_id"].astype(str)))
        if len(df) != len(tags) * len(anchors) or df.duplicated(["tag_id", "anchor_id"]).any():
            raise ValueError(f"{where}: calibration table must hold each (tag_id, anchor_id) pair exactly once")
        df = df.assign(tag_id=df["tag_id"].astype(str), anchor_id=df["anchor_id"].astype(str))
        df = df.set_index(["tag_id", "anchor_id"]).loc[pd.MultiIndex.from_product([tags, anchors])]
        shape = (len(tags), len(anchors))
        kw = {c: df[c].to_numpy().reshape(shape) for c in _COLUMNS[2:]}
        kw["scale_fitted"] = kw["scale_fitted"].astype(str).isin(["True", "true", "1"]) if \
            kw["scale_fitted"].dtype == object else kw["scale_fitted"].astype(bool)
        extra = {} if loss is None else {"loss": loss}
        return cls(anchors, tags, source=tuple(source), **kw, **extra)

    def save(self, path: str | Path) -> Path:
        """Write as ``.csv`` (one row per pair) or ``.json`` (with provenance)."""
        path = Path(path)
        if path.suffix == ".csv":
            self.to_frame().to_csv(path, index=False, float_format="%.6g")
        elif path.suffix == ".json":
            doc = {"format": _FORMAT, "version": 1, "units": {"bias": "m", "scale": "1", "resid": "m"},
                   "model": "range_meas = scale * range_true + bias", "loss": self.loss,
                   "source": list(self.source), "pairs": self.to_frame().to_dict(orient="records")}
            path.write_text(json.dumps(doc, indent=1, default=_json_default))
        else:
            raise ValueError(f"{path}: calibration files are .csv or .json")
        return path

    @classmethod
    def load(cls, path: str | Path) -> "RangeCalibration":
        """Read a file written by :meth:`save`."""
        path = Path(path)
        if path.suffix == ".csv":
            return cls.from_frame(pd.read_csv(path, dtype={"tag_id": str, "anchor_id": str}), where=str(path))
        if path.suffix == ".json":
            doc = json.loads(path.read_text())
            if doc.get("format") != _FORMAT:
                raise ValueError(f"{path}: not a uwbwb range calibration (format={doc.get('format')!r})")
            if doc.get("units", {}).get("bias") != "m":
                raise ValueError(f"{path}: bias units {doc.get('units')!r}; expected metres")
            return cls.from_frame(pd.DataFrame(doc["pairs"]), source=doc.get("source", ()),
                                  loss=doc.get("loss"), where=str(path))
        raise ValueError(f"{path}: calibration files are .csv or .json")


def _json_default(x):
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"cannot serialise {type(x).__name__}")


# ---------------------------------------------------------------------- fit
def true_ranges(rec: Recording, tag: str) -> np.ndarray:
    """Ranges predicted from ground truth at the range log's epochs, ``(T, n_anchors)``, metres.

    Epochs where the truth does not cover the range time stamp are NaN.
    """
    log, truth = rec.ranges[tag], rec.truth[tag]
    if truth.dim != 3:
        raise ValueError(f"{rec.label}: truth of tag {tag!r} is {truth.dim}-D; range calibration needs 3-D positions")
    pos = truth.interp(log.t_s)
    return ranges(pos, rec.anchors.pos_m)


def pair_samples(recordings: Iterable[Recording]):
    """Stack (true, measured) samples per pair over recordings.

    Returns
    -------
    anchor_ids, tag_ids, true_m, meas_m
        ``true_m`` and ``meas_m`` have shape ``(N, n_tags, n_anchors)`` with NaN
        where a pair has no sample at that row.
    """
    recordings = list(recordings)
    if not recordings:
        raise ValueError("no recordings to calibrate from")
    anchor_ids = recordings[0].anchors.ids
    tag_ids = recordings[0].tags
    trues, meas = [], []
    for rec in recordings:
        if rec.anchors.ids != anchor_ids or rec.tags != tag_ids:
            raise ValueError(f"{rec.label}: anchors {rec.anchors.ids} / tags {rec.tags} differ from "
                             f"{recordings[0].label}: {anchor_ids} / {tag_ids}")
        if not np.allclose(rec.anchors.pos_m, recordings[0].anchors.pos_m):
            raise ValueError(f"{rec.label}: anchor positions differ from {recordings[0].label}")
        missing = [t for t in tag_ids if t not in rec.truth]
        if missing:
            raise ValueError(f"{rec.label}: no ground truth for tags {missing}")
        n = max(len(rec.ranges[t]) for t in tag_ids)
        tr = np.full((n, len(tag_ids), len(anchor_ids)), np.nan)
        me = np.full_like(tr, np.nan)
        for k, tag in enumerate(tag_ids):
            m = len(rec.ranges[tag])
            tr[:m, k] = true_ranges(rec, tag)
            me[:m, k] = rec.ranges[tag].range_m
        trues.append(tr)
        meas.append(me)
    return anchor_ids, tag_ids, np.concatenate(trues), np.concatenate(meas)


@numba.njit(cache=True, nogil=True)
def _median(v):
    """``np.nanmedian(v)`` from a bracket: a sorted sample of every ``len(v) // 4096``-th element gives two values
    around the median, one pass counts the elements below the bracket and gathers those inside, and the middle
    element (or the two middle ones, ``(a + b) / 2``) is picked from the gathered few: the same order statistics,
    so the same value, in about a sixth of a full selection. Where the bracket misses them, ``v`` holds NaN or is
    short, ``np.nanmedian(v)`` itself."""
    n = len(v)
    if n < 5000:
        return np.nanmedian(v)
    s = np.sort(v[::n // 4096])
    lo, hi = s[len(s) // 2 - 128], s[len(s) // 2 + 128]
    inside, below, n_nan = np.empty(n), 0, 0
    k = 0
    for x in v:      # without branches: which side of the bracket a residual falls is a coin toss
        below += x < lo
        inside[k] = x
        k += (x >= lo) & (x <= hi)
        n_nan += x != x
    i, j = (n - 1) // 2 - below, n // 2 - below
    if n_nan or i < 0 or j >= k:
        return np.nanmedian(v)
    part = np.partition(inside[:k], i)
    return part[i] if i == j else (part[i] + np.min(part[j:])) / 2


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _irls(x, y, mask, with_scale, n_iter):
    """The IRLS of :func:`fit_range_calibration`, pair by pair on that pair's samples gathered once (rows where
    ``mask``, in order). Iteration: the weighted least-squares line ``y = scale·x + bias`` (bias only where not
    ``with_scale``) from its normal equations, residuals, robust σ = 1.4826·MAD (at least 0.1 mm) and Huber
    weights. Returns ``(5, n_tags, n_anchors)``: bias, scale and the final residuals' median, robust σ and RMS.
    A compiled loop; its definition, the same steps on every pair at once in NumPy, is its declared twin
    (``calibration._irls``)."""
    n_rows, n_tags, n_anchors = x.shape
    out = np.empty((5, n_tags, n_anchors))
    for k in range(n_tags):
        for a in range(n_anchors):
            xs, ys = np.empty(n_rows), np.empty(n_rows)
            n = 0
            for i in range(n_rows):
                if mask[i, k, a]:
                    xs[n], ys[n] = x[i, k, a], y[i, k, a]
                    n += 1
            xs, ys, w, r = xs[:n], ys[:n], np.ones(n), np.empty(n)
            bias = scale = med = sigma = np.nan
            for _ in range(n_iter):
                sw = sx = sy = sxx = sxy = 0.0
                for i in range(n):     # the sums in row order, as NumPy's sums over the rows
                    wx = w[i] * xs[i]
                    sw, sx, sy, sxx, sxy = sw + w[i], sx + wx, sy + w[i] * ys[i], sxx + wx * xs[i], sxy + wx * ys[i]
                if with_scale[k, a]:
                    scale = (sw * sxy - sx * sy) / (sw * sxx - sx * sx)
                    bias = (sy - scale * sx) / sw
                else:
                    scale, bias = 1.0, (sy - sx) / sw
                for i in range(n):
                    r[i] = ys[i] - (scale * xs[i] + bias)
                med = _median(r)
                sigma = MAD_TO_SIGMA * _median(np.abs(r - med))
                thr = _HUBER_K * (1e-4 if sigma < 1e-4 else sigma)       # NaN stays NaN, as np.maximum
                for i in range(n):
                    d = abs(r[i])
                    w[i] = 1.0 if d <= thr else thr / (1e-12 if d < 1e-12 else d)
            out[0, k, a], out[1, k, a], out[2, k, a], out[3, k, a] = bias, scale, med, sigma
            out[4, k, a] = np.sqrt(np.sum(r * r) / n)
    return out


def fit_range_calibration(recordings: Sequence[Recording] | Recording, *, fit_scale: bool = True,
                          min_span_m: float = 1.0, min_samples: int = 30, n_iter: int = 30
                          ) -> RangeCalibration:
    """Fit per-pair ``(bias, scale)`` from recordings that carry ground truth.

    Parameters
    ----------
    recordings
        Recordings of the same anchors and tags, each with per-tag truth
        (e.g. :func:`uwbwb.datasets.lias.load_static` poses, or a dynamic run).
    fit_scale
        Fit a scale per pair; if False, only a bias (scale = 1).
    min_span_m
        A pair whose true ranges span less than this gets a bias-only fit.
    min_samples
        A pair with fewer usable samples is an error (its calibration would be a guess).
    n_iter
        IRLS iterations.

    Returns
    -------
    RangeCalibration
    """
    integer("n_iter", n_iter, minimum=1)          # 0 would return an unfitted identity
    integer("min_samples", min_samples, minimum=2)
    number("min_span_m", min_span_m, minimum=0.0)
    if isinstance(recordings, Recording):
        recordings = [recordings]
    anchor_ids, tag_ids, x, y = pair_samples(recordings)
    mask = np.isfinite(x) & np.isfinite(y)
    n = mask.sum(axis=0)
    if np.any(n < min_samples):
        k, a = np.argwhere(n < min_samples)[0]
        raise ValueError(f"pair {tag_ids[k]}-{anchor_ids[a]} has only {n[k, a]} samples with truth "
                         f"(need {min_samples})")
    xs = np.where(mask, x, np.nan)
    span = np.nanmax(xs, axis=0) - np.nanmin(xs, axis=0)
    with_scale = fit_scale & (span >= min_span_m)
    bias, scale, resid_median, resid_sigma, resid_rms = _irls(x, y, mask, with_scale, n_iter)
    return RangeCalibration(
        anchor_ids, tag_ids, bias, scale, with_scale, n, span,
        resid_median_m=resid_median, resid_sigma_m=resid_sigma, resid_rms_m=resid_rms,
        source=tuple(r.label for r in recordings))


def range_residuals(rec: Recording, calibration: RangeCalibration | None = None) -> pd.DataFrame:
    """Measured (optionally calibrated) minus truth-predicted range, per pair.

    Returns a table with one row per pair: ``tag_id, anchor_id, n, median_m,
    sigma_m`` (1.4826·MAD), ``rms_m``, ``p95_abs_m``.
    """
    rows = []
    for tag in rec.tags:
        r = rec.ranges_of(tag, calibration).range_m - true_ranges(rec, tag)
        for j, anchor in enumerate(rec.anchors.ids):
            v = r[:, j][np.isfinite(r[:, j])]
            med = np.median(v) if v.size else np.nan
            rows.append({"tag_id": tag, "anchor_id": anchor, "n": v.size, "median_m": med,
                         "sigma_m": MAD_TO_SIGMA * np.median(np.abs(v - med)) if v.size else np.nan,
                         "rms_m": np.sqrt(np.mean(v ** 2)) if v.size else np.nan,
                         "p95_abs_m": np.quantile(np.abs(v), 0.95) if v.size else np.nan})
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class MountHeight:
    """The height at which rigidly mounted tags ride, taken from calibration recordings.

    2-D solvers need the tag height; it must not come from the truth of the recording
    that is then scored. This comes from static calibration poses, whose truth is the
    surveyed (or declared) pose, never from a moving test run.

    Attributes
    ----------
    z_m
        Common mount height: the median of ``per_tag_m``, metres.
    per_tag_m
        Height of each tag, metres (median over the calibration recordings).
    source
        One sentence saying where the height came from.
    range_slope
        Largest ``|z_anchor − z_tag| / range`` over the calibration poses and anchors:
        a height error ``dz`` changes a range by at most about ``range_slope · dz``
        (plus ``dz² / (2 r)``). Near 0 when anchors and tags share a plane, where the
        height is also unobservable from the ranges.
    """

    z_m: float
    per_tag_m: dict
    source: str
    range_slope: float

    def range_change_m(self, dz_m: float) -> float:
        """Worst-case change of a true range for a height error ``dz_m``, metres (first order)."""
        return self.range_slope * abs(float(dz_m))


def tag_mount_height(static: Sequence[Recording] | Recording, *, tags=None,
                     max_spread_m: float = 0.05) -> MountHeight:
    """Tag mount height from static calibration recordings (never from a test run's truth).

    Parameters
    ----------
    static
        Static recordings with 3-D truth per tag (e.g. ``lias.load_static`` poses, or
        ``uwbwb.sim.rig.simulate_static``).
    tags
        Tags to use (default: every tag with truth in the first recording).
    max_spread_m
        A recording whose truth height of a tag spans more than this is not a static
        pose: ``ValueError``.

    Returns
    -------
    MountHeight

    Raises
    ------
    ValueError
        No recordings, a tag without 3-D truth, or a moving "static" recording.
    """
    number("max_spread_m", max_spread_m, minimum=0.0)
    recs = [static] if isinstance(static, Recording) else list(static)
    if not recs:
        raise ValueError("tag_mount_height needs at least one static calibration recording")
    tags = tuple(recs[0].truth) if tags is None else tuple(tags)
    if not tags:
        raise ValueError(f"{recs[0].label}: no tag has ground truth, so no mount height can be read")
    heights = {t: [] for t in tags}
    slope = 0.0
    for rec in recs:
        for t in tags:
            tr = rec.truth.get(t)
            if tr is None or tr.dim != 3 or len(tr) == 0:
                raise ValueError(f"{rec.label}: tag {t!r} needs 3-D truth to give its mount height")
            z = tr.pos_m[:, 2]
            if np.ptp(z) > max_spread_m:
                raise ValueError(f"{rec.label}: truth height of tag {t!r} spans {np.ptp(z):.3f} m "
                                 f"(> {max_spread_m} m): not a static calibration pose")
            heights[t].append(float(np.median(z)))
            p = np.median(tr.pos_m, axis=0)
            d = np.linalg.norm(rec.anchors.pos_m - p, axis=1)
            slope = max(slope, float(np.max(np.abs(rec.anchors.pos_m[:, 2] - p[2]) / np.maximum(d, 1e-9))))
    per_tag = {t: float(np.median(h)) for t, h in heights.items()}
    declared = {rec.meta.get("centroid_z_m") for rec in recs}
    if len(declared) == 1 and None not in declared:
        src = (f"rig height {declared.pop():.3f} m declared for the {len(recs)} static poses "
               f"(plus each tag's body offset)")
    else:
        src = f"truth of {len(recs)} static calibration recordings"
    return MountHeight(float(np.median(list(per_tag.values()))), per_tag, src, slope)
