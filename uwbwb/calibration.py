"""Noise-model fitting, all in one place.

* Per anchor–tag range calibration from recordings with known positions
  (:class:`RangeCalibration`, :func:`fit_range_calibration`), described below;
* range-noise level per anchor and the empirical TDoA covariance, for the TDoA filters
  (:func:`range_sigma_from_truth`, :func:`fit_range_sigma`, :func:`empirical_tdoa_covariance`);
* where a low percentile of NLOS-affected ranges lands, per static file (:func:`percentile_by_file`);
* the sensor-set noise model of paper 000 (:func:`fit_set_noise`, :func:`fit_set_noise_from_fixes`,
  :func:`location_statistics`).

Range calibration
-----------------

Two-way ranges carry systematic, pair-specific distortions (antenna delays,
body shadowing). We model them as in :mod:`uwbwb.models.ranging`::

    range_meas = scale * range_true + bias + noise

and fit ``(bias, scale)`` for every anchor–tag pair by robust linear regression
of measured on true ranges, where the true range comes from the recording's
ground truth (static poses: pose ⊕ tag offset; dynamic runs: motion capture).
Applying the calibration inverts the model: ``range_true ≈ (range_meas − bias) / scale``.

Fit: Huber M-estimation by iteratively reweighted least squares, vectorised
over all pairs at once. The Huber threshold is ``1.345 × σ̂`` with σ̂ the
normalised median absolute deviation of the current residuals, which keeps
95 % efficiency for Gaussian noise while bounding the pull of NLOS outliers.
A pair whose true ranges span less than ``min_span_m`` cannot separate scale
from bias: it gets a bias-only fit (scale fixed at 1) and is flagged.

Results are plain tables, saved as CSV or JSON (never pickle).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
import pandas as pd

from .models.setnoise import SetNoiseModel
from .models.ranging import ranges
from .types import RangeLog, Recording, TagRun
from .validate import integer, number

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
        from dataclasses import replace

        from .types import CleaningStep

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


def _robust_sigma(resid: np.ndarray, mask: np.ndarray) -> np.ndarray:
    r = np.where(mask, resid, np.nan)
    med = np.nanmedian(r, axis=0)
    return MAD_TO_SIGMA * np.nanmedian(np.abs(r - med), axis=0)


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
    x0 = np.where(mask, x, 0.0)
    y0 = np.where(mask, y, 0.0)
    w = mask.astype(float)
    bias = np.zeros(n.shape)
    scale = np.ones(n.shape)
    for _ in range(n_iter):
        # weighted normal equations of y = scale * x + bias, all pairs at once
        sw, sx, sy = w.sum(0), (w * x0).sum(0), (w * y0).sum(0)
        sxx, sxy = (w * x0 * x0).sum(0), (w * x0 * y0).sum(0)
        det = sw * sxx - sx * sx
        with np.errstate(invalid="ignore", divide="ignore"):
            s_full = (sw * sxy - sx * sy) / det
            b_full = (sy - s_full * sx) / sw
            b_only = (sy - sx) / sw
        scale = np.where(with_scale, s_full, 1.0)
        bias = np.where(with_scale, b_full, b_only)
        resid = y0 - (scale * x0 + bias)
        sigma = np.maximum(_robust_sigma(resid, mask), 1e-4)
        thr = _HUBER_K * sigma
        a = np.abs(resid)
        w = np.where(mask, np.where(a <= thr, 1.0, thr / np.maximum(a, 1e-12)), 0.0)
    resid = np.where(mask, y0 - (scale * x0 + bias), np.nan)
    return RangeCalibration(
        anchor_ids, tag_ids, bias, scale, with_scale, n, span,
        resid_median_m=np.nanmedian(resid, axis=0),
        resid_sigma_m=_robust_sigma(resid, mask),
        resid_rms_m=np.sqrt(np.nanmean(resid ** 2, axis=0)),
        source=tuple(r.label for r in recordings))


def range_residuals(rec: Recording, calibration: RangeCalibration | None = None) -> pd.DataFrame:
    """Measured (optionally calibrated) minus truth-predicted range, per pair.

    Returns a table with one row per pair: ``tag_id, anchor_id, n, median_m,
    sigma_m`` (1.4826·MAD), ``rms_m``, ``p95_abs_m``.
    """
    rows = []
    for tag in rec.tags:
        log = rec.ranges[tag] if calibration is None else calibration.apply(rec.ranges[tag])
        r = log.range_m - true_ranges(rec, tag)
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


# ------------------------------------------------------- range noise per anchor, TDoA covariance (paper 002)

def range_sigma_from_truth(range_m: np.ndarray, true_range_m: np.ndarray, *, robust: bool = True) -> np.ndarray:
    """Per-anchor range-noise standard deviation from measurements with known truth.

    Parameters
    ----------
    range_m, true_range_m
        Measured and true ranges, shape ``(T, n_anchors)``, metres (NaN = missing).
    robust
        True: ``1.4826 · MAD`` of the residuals around their median (the spread,
        insensitive to NLOS outliers and to a constant bias). False: the RMS of
        the residuals (bias and outliers included: the total error a filter sees
        if nothing corrects them).

    Returns
    -------
    ndarray, shape ``(n_anchors,)``, metres
    """
    res = np.asarray(range_m, float) - np.asarray(true_range_m, float)
    if res.ndim != 2:
        raise ValueError(f"range_sigma_from_truth: need (T, n_anchors) arrays, got shape {res.shape}")
    n_ok = np.isfinite(res).sum(axis=0)
    if np.any(n_ok < 2):
        bad = np.flatnonzero(n_ok < 2).tolist()
        raise ValueError(f"range_sigma_from_truth: anchors {bad} have fewer than two residuals")
    if robust:
        med = np.nanmedian(res, axis=0)
        return MAD_TO_SIGMA * np.nanmedian(np.abs(res - med), axis=0)
    return np.sqrt(np.nanmean(res ** 2, axis=0))


def fit_range_sigma(run: TagRun, *, method: str = "tdoa", floor_m: float = 0.02) -> np.ndarray:
    """Range-noise standard deviation per anchor from a run with truth, ``(n_anchors,)``, metres.

    For the TDoA filters of notebook 03 (De Angelis, paper 002). The thesis builds its TDoA covariance from the measurement errors of its
    acquisitions; three readings of that are offered:

    ``"tdoa"`` (default)
        RMS of the range errors after removing, at every epoch, their mean over
        the anchors measured (× ``sqrt(n/(n−1))`` to undo the shrinkage for
        independent errors). A range error common to all anchors cancels in
        every TDoA, so this is the part of the error the TDoA filter sees; the
        rest (per-anchor biases, NLOS excursions) stays in.
    ``"rms"``
        RMS of the range errors themselves (common part included).
    ``"robust"``
        1.4826·MAD around the median (spread only, biases and outliers excluded).

    Values are floored at ``floor_m`` (range resolution, unmodelled effects).
    """
    err = run.ranges.range_m - run.true_range_m()
    if method == "tdoa":
        ok = np.isfinite(err)
        n = ok.sum(axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            common = np.where(n >= 2, np.nansum(np.where(ok, err, 0.0), axis=1, keepdims=True) / n, np.nan)
            shrink = np.where(n >= 2, n / np.maximum(n - 1, 1), np.nan)
        centred = (err - common) * np.sqrt(shrink)
        sig = range_sigma_from_truth(centred, np.zeros_like(centred), robust=False)
    elif method in ("rms", "robust"):
        sig = range_sigma_from_truth(run.ranges.range_m, run.true_range_m(), robust=method == "robust")
    else:
        raise ValueError(f"method must be 'tdoa', 'rms' or 'robust', got {method!r}")
    return np.maximum(sig, floor_m)


def empirical_tdoa_covariance(tdoa_m: np.ndarray, true_tdoa_m: np.ndarray, ref: int) -> np.ndarray:
    """Sample covariance of TDoA errors for a fixed reference, shape ``(n_anchors − 1, n_anchors − 1)``.

    Uses the epochs where all anchors and the reference ``ref`` were measured
    (``tdoa_m[:, ref] == 0``); rows and columns are the anchors other than
    ``ref`` in index order. Compare with :meth:`uwbwb.models.tdoa.TdoaModel.covariance`.
    """
    d = np.asarray(tdoa_m, float)
    e = d - np.asarray(true_tdoa_m, float)
    full = np.all(np.isfinite(e), axis=1) & (d[:, ref] == 0.0)
    if full.sum() < d.shape[1] + 1:
        raise ValueError(f"empirical_tdoa_covariance: only {int(full.sum())} complete epochs with reference {ref}")
    others = np.delete(np.arange(d.shape[1]), ref)
    return np.cov(e[full][:, others], rowvar=False)


# ------------------------------------------------------- NLOS range errors per file (paper 001, Hanyang)

def percentile_by_file(samples: pd.DataFrame, q: float = 5.0, min_samples: int = 20) -> pd.DataFrame:
    """Where the ``q``-th percentile of each static file's ranges lands, vs the true range.

    Parameters
    ----------
    samples
        Tidy samples with ``condition, height_m, true_range_m, range_m, file``
        (:func:`uwbwb.datasets.hanyang.load_static`).
    q
        Percentile.
    min_samples
        Files with fewer samples are left out (counted in ``attrs["n_skipped"]``):
        a 5th percentile of fewer than 20 samples is the minimum.

    Returns
    -------
    pandas.DataFrame
        One row per file: ``condition, height_m, true_range_m, n, median_err_m,
        pq_err_m`` (percentile minus true range), ``iqr_m``, ``frac_over_1m``
        (fraction of samples more than 1 m long). Possibly empty.
    """
    need = {"condition", "height_m", "true_range_m", "range_m", "file"}
    if need - set(samples.columns):
        raise ValueError(f"samples lack columns {sorted(need - set(samples.columns))}")
    err = samples["range_m"] - samples["true_range_m"]
    g = samples.assign(err=err).groupby(["file", "condition", "height_m", "true_range_m"], sort=False)["err"]
    out = pd.DataFrame({"n": g.size(), "median_err_m": g.median(), "pq_err_m": g.quantile(q / 100.0),
                        "iqr_m": g.quantile(0.75) - g.quantile(0.25),
                        "frac_over_1m": g.apply(lambda e: float(np.mean(e > 1.0)))}).reset_index()
    keep = out["n"] >= min_samples
    out = out[keep].reset_index(drop=True)
    out.attrs["n_skipped"] = int((~keep).sum())
    out.attrs["q"] = q
    return out


# ------------------------------------------------------- set-noise model (paper 000)

#: Minimum number of measurements of a set at one location for the paper's calibration to model it.
SET_MIN_COUNT = 30


def location_statistics(error_m: np.ndarray, set_id: np.ndarray, location: np.ndarray) -> pd.DataFrame:
    """Per location and set: count, mean and sample standard deviation of the fix errors.

    Parameters
    ----------
    error_m
        Fix minus true position, shape ``(N, 2)``, metres.
    set_id
        Set of each fix, shape ``(N,)``.
    location
        Calibration location label of each fix, shape ``(N,)``.

    Returns
    -------
    DataFrame
        ``location, set_id, n, mu_x_m, mu_y_m, sigma_x_m, sigma_y_m`` (σ with ``ddof=1``,
        NaN for a single measurement), sorted by location then decreasing ``n``.
    """
    error_m = np.asarray(error_m, float)
    set_id = np.asarray(set_id, np.int64)
    location = np.asarray(location)
    if error_m.ndim != 2 or error_m.shape[1] != 2 or set_id.shape != (error_m.shape[0],) \
            or location.shape != set_id.shape:
        raise ValueError(f"need error_m (N, 2), set_id (N,), location (N,); got {error_m.shape}, "
                         f"{set_id.shape}, {location.shape}")
    if not np.all(np.isfinite(error_m)):
        raise ValueError("error_m contains non-finite values")
    df = pd.DataFrame({"location": location, "set_id": set_id, "ex": error_m[:, 0], "ey": error_m[:, 1]})
    g = df.groupby(["location", "set_id"], sort=True)
    out = pd.DataFrame({"n": g.size(), "mu_x_m": g["ex"].mean(), "mu_y_m": g["ey"].mean(),
                        "sigma_x_m": g["ex"].std(ddof=1), "sigma_y_m": g["ey"].std(ddof=1)}).reset_index()
    out = out.sort_values(["location", "n", "set_id"], ascending=[True, False, True], kind="stable")
    return out.reset_index(drop=True)


def fit_set_noise(error_m: np.ndarray, set_id: np.ndarray, location: np.ndarray, *,
                  min_count: int = SET_MIN_COUNT, sigma_rule: str = "paper", min_sigma_m: float = 1e-3,
                  sensor_ids=None) -> SetNoiseModel:
    """Calibrate from fixes at known locations (paper section II-B2).

    Rules, in the paper's words and order:

    1. at each location, ``(μx, μy, σx, σy)`` of every set with at least
       ``min_count`` (30) measurements there; sets below the gate get no model
       at that location;
    2. each set's parameters are averaged across locations, weighted by the
       number of its measurements at each location;
    3. a facility-wide model — mean and standard deviation of all calibration
       errors — serves every set that has no model.

    Rule 2 applied to σ (``sigma_rule="paper"``) keeps only the spread *within*
    locations: when a set's bias changes from place to place (multipath,
    geometry), the model is overconfident away from the calibration spots.
    ``sigma_rule="pooled"`` instead uses the law of total variance over the gated
    locations, ``σ² = Σ n_l (σ_l² + (μ_l − μ)²) / Σ n_l`` — the spread of the set's
    error when the location is not known (μ is the same weighted mean).

    Parameters
    ----------
    error_m, set_id, location
        As in :func:`location_statistics` (locations: any hashable labels).
    min_count
        The per-location gate (must be ≥ 2 so that σ exists).
    min_sigma_m
        Floor on every fitted σ (quantised fixes can repeat exactly, and a zero σ
        would make eq. 9 infinite); ``meta["n_sigma_floored"]`` counts the raised values.
    sigma_rule
        ``"paper"`` (count-weighted average of σ) or ``"pooled"`` (see above).
    sensor_ids
        Sensor names for labels; defaults to ``'0'..'7'`` (or as many as the ids need).

    Returns
    -------
    SetNoiseModel
        With ``meta["per_location"]``, the table of rule 1 (all sets, gate flag included).
    """
    if sigma_rule not in ("paper", "pooled"):
        raise ValueError(f"sigma_rule must be 'paper' or 'pooled', got {sigma_rule!r}")
    if min_count < 2:
        raise ValueError(f"min_count must be >= 2 (a standard deviation needs two samples), got {min_count}")
    stats = location_statistics(error_m, set_id, location)
    stats["gated_in"] = stats["n"] >= min_count
    kept = stats[stats["gated_in"]]
    w = kept["n"].to_numpy(float)
    grp = kept.groupby("set_id", sort=True)
    cols = ["mu_x_m", "mu_y_m", "sigma_x_m", "sigma_y_m"]
    weighted = kept[cols].mul(w, axis=0).groupby(kept["set_id"], sort=True).sum()
    n_set = grp["n"].sum()
    avg = weighted.div(n_set.astype(float), axis=0)
    err = np.asarray(error_m, float)
    if err.shape[0] < 2:
        raise ValueError("the facility-wide model needs at least two calibration measurements")
    if sensor_ids is None:
        top = int(np.max(np.asarray(set_id, np.int64))).bit_length()
        sensor_ids = tuple(str(i) for i in range(max(8, top)))
    sigma = avg[["sigma_x_m", "sigma_y_m"]].to_numpy(float)
    if sigma_rule == "pooled":
        mean_of_set = avg.loc[kept["set_id"], ["mu_x_m", "mu_y_m"]].to_numpy()
        spread = kept[["sigma_x_m", "sigma_y_m"]].to_numpy() ** 2 \
            + (kept[["mu_x_m", "mu_y_m"]].to_numpy() - mean_of_set) ** 2
        var = pd.DataFrame(spread * w[:, None]).groupby(kept["set_id"].to_numpy(), sort=True).sum()
        sigma = np.sqrt(var.to_numpy() / n_set.to_numpy(float)[:, None])
    default_sigma = err.std(axis=0, ddof=1)
    n_floored = int(np.sum(sigma < min_sigma_m) + np.sum(default_sigma < min_sigma_m))
    return SetNoiseModel(set_id=avg.index.to_numpy(np.int64),
                         mu_m=avg[["mu_x_m", "mu_y_m"]].to_numpy(float),
                         sigma_m=np.maximum(sigma, min_sigma_m),
                         n=n_set.to_numpy(np.int64),
                         default_mu_m=err.mean(axis=0), default_sigma_m=np.maximum(default_sigma, min_sigma_m),
                         default_n=err.shape[0], sensor_ids=sensor_ids,
                         meta={"per_location": stats, "min_count": min_count, "sigma_rule": sigma_rule,
                               "min_sigma_m": min_sigma_m, "n_sigma_floored": n_floored})


def fit_set_noise_from_fixes(logs, *, min_count: int = SET_MIN_COUNT, sigma_rule: str = "paper") -> SetNoiseModel:
    """:func:`fit_set_noise` on calibration logs, one :class:`~uwbwb.types.SetFixLog` (with truth) per location.

    The logs' names label the locations, so they must be distinct.
    """
    logs = list(logs)
    if not logs:
        raise ValueError("no calibration logs")
    names = [log.name for log in logs]
    if len(set(names)) != len(names):
        raise ValueError(f"calibration logs need distinct names (they label the locations), got {names}")
    ids = logs[0].sensor_ids
    if any(log.sensor_ids != ids for log in logs):
        raise ValueError("calibration logs use different sensors")
    return fit_set_noise(np.concatenate([log.error_m for log in logs]), np.concatenate([log.set_id for log in logs]),
                         np.repeat(np.array(names, dtype=object), [len(log) for log in logs]),
                         min_count=min_count, sigma_rule=sigma_rule, sensor_ids=ids)
