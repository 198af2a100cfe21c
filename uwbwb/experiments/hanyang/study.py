"""The Hanyang dynamic runs: the dataset authors' numbers reproduced, then their LS/ESKF on our board.

Three steps, each a function the notebooks call:

1. :func:`reproduce_authors` recomputes the RMSE and RMSE_2d of the authors' ``LS.csv`` and
   ``ESKF.csv`` with :mod:`uwbwb.metrics`, following the definition of their
   ``localization_error_analysis.py`` (time window, epochs, the |z| filter on the reference,
   2-D vs 3-D; :func:`authors_window` and :func:`authors_errors`), beside their
   ``RMSD_results.txt``.
2. :func:`case_board` scores every method of the board on one case with the calibration and
   tuning fitted on *another* case (:func:`tuning_case`: same condition, the other trajectory
   shape), the authors' LS and ESKF as rows marked *external* (:class:`AuthorsEstimator`), all
   on the same epochs (the range epochs inside the authors' window).
3. :func:`compare_cases` runs the boards of several cases and gives, per case and method of ours,
   its RMSE_2d and the authors' LS's on the epochs *that pair* covered (:func:`pair_errors`; both
   coverages beside; not the board's all-method common epochs, which depend on what else is on the
   board), the ratio with a block-bootstrap interval whose block length comes from the data
   (:func:`ratio_interval`, :func:`block_length_s`; no verdict with fewer than :data:`MIN_BLOCKS`
   blocks), and a full-coverage variant with ours holding its last position (:func:`held_errors`;
   :func:`ratio_table`). The method set against theirs is picked on the tuning case alone
   (:func:`pick_on_tuning_case`); :mod:`.facts` turns them into sentences.

Front ends differ, so outlier handling is *not* equal between their LS and ours: the authors' LS
(``Technical_validation/``) rejects a per-anchor range that jumps by more than 0.5 m from that
anchor's previous accepted range (up to 4 consecutive rejections, then accepts), holds each anchor's
latest range for up to 0.3 s, solves in 3-D warm-started from its previous solution and outputs on a
10 Hz timer; our LS/NLS solve each epoch's ranges independently (no jump gate, no hold, no warm
start), in 2-D at the calibrated height. The filters and pruned NLS have their own gates. Their
output stamps also lag the reference (``meta["authors_lag_s"]``); that latency is left in.

:func:`static_range_model` fits the static part's bias vs distance and
:class:`StaticModelLs` applies it to the dynamic ranges (does it help? :func:`static_model_effect`).

Height is handled the same way for every method: the tag's height above the reference track is
fitted on the *tuning* case (:func:`~uwbwb.datasets.hanyang_dynamic.load_dynamic_case`'s registration)
and given as a calibration to the scored case; every method then solves in 2-D at that height
(``dim=2``). The authors' LS solved in 3-D (z free); their estimates are used as published.
"""

from __future__ import annotations

import os
import re
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ... import bounds, geometry, metrics
from ...datasets import hanyang, hanyang_dynamic
from ...errors import DataFormatError, DataNotFoundError
from ...filters.ekf import Ekf, Linearisation
from ...filters.gating import AnchorDropping
from ...filters.kalman import Gaussian
from ...filters.pruning import LABELS as PRUNING_LABELS
from ...filters.pruning import PruningConfig, localize
from ...scoreboard import Board, score
from ...models.motion import MotionModel, make_motion_model
from ...scoreboard.estimators import (EKF_GRIDS, NLS_WINDOWS_S, BaseEstimator, TdoaEkfEstimator, WindowNls, _range_bound,
                                      _errors_rmse, calibrated_log, default_estimators, truth_at)
from ...scoreboard.protocol import between
from ...types import EstimateStatus, Estimates, Recording, Trajectory

__all__ = ["AUTHORS_TAG_HEIGHT_M", "AUTHORS_Z_LIMIT_M", "AuthorsEstimator", "CaseComparison", "FAST_SPAN_S",
           "ACF_LEVEL", "AUTHORS_HOLD_S", "AUTHORS_JUMP_M", "AUTHORS_MAX_REJECTS", "AuthorsFrontEndLs", "BLOCK_LAG_FACTOR", "MIN_BLOCKS", "OFFSET_CHECK_S", "PrunedNls", "RangeEkfEstimator", "RangeMeasurement", "StaticModelLs", "StaticRangeModel", "WINDOW_RULES", "authors_errors",
           "authors_front_end", "authors_window", "block_bootstrap_ratio", "block_length_s", "board_epochs", "case_board", "compare_cases",
           "held_errors", "load_pair", "offset_ratio", "pair_errors", "pick_on_tuning_case", "ratio_interval", "ratio_table",
           "read_rmsd_results", "reproduce_authors", "static_model_effect", "static_range_model", "tuning_case"]

PathLike = str | os.PathLike

#: *Input* (the authors' script): the reference z is compared with the estimate's z after adding 1 m.
AUTHORS_TAG_HEIGHT_M = 1.0
#: *Input* (the authors' script): reference rows with |z| at or above this are left out.
AUTHORS_Z_LIMIT_M = 0.5
#: *Input* (the authors' script): the window of each trajectory shape, as rules on the reference
#: track (x, y): it starts at the first row meeting ``start`` and ends at the first later row
#: meeting ``end``.
WINDOW_RULES = {"A": {"start": lambda x, y: (x > 49.3) & (y > -5), "end": lambda x, y: (x <= 12) & (y > 3.4)},
                "B": {"start": lambda x, y: (x < 8.6) & (y < -7), "end": lambda x, y: (x > 8.6) & (y < -7)}}
#: FAST mode scores this many seconds of the window (and tunes on as many of the other case).
FAST_SPAN_S = 30.0
#: Block bootstrap: a block is BLOCK_LAG_FACTOR × the lag (s) at which the autocorrelation of the paired
#: difference e_ours² − e_theirs² first falls below ACF_LEVEL (an assumption: below it, epochs count as
#: independent); with fewer than MIN_BLOCKS blocks no interval and no verdict is given.
ACF_LEVEL = 0.05
BLOCK_LAG_FACTOR = 2.0
MIN_BLOCKS = 10
#: Changes of the reference's clock offset under which the ratio ours / theirs is recomputed, seconds (the
#: loader's registration and the board's own clock check differ by about this much on the real cases).
OFFSET_CHECK_S = (-0.1, 0.1)
#: Gap between two of the authors' outputs beyond which nothing is interpolated, seconds.
AUTHORS_MAX_GAP_S = 0.5

_UP, _NONE = int(EstimateStatus.UPDATED), int(EstimateStatus.NO_ESTIMATE)


# --------------------------------------------------------------------------------------------
# 1. the authors' numbers
# --------------------------------------------------------------------------------------------

def authors_window(reference: Trajectory, shape: str) -> tuple[float, float]:
    """``(t_start, t_end)`` of the authors' evaluation window on ``reference``'s own clock, seconds.

    Raises
    ------
    ValueError
        Unknown shape, or the track never meets the start (or, after it, the end) rule.
    """
    if shape not in WINDOW_RULES:
        raise ValueError(f"shape must be one of {sorted(WINDOW_RULES)}, got {shape!r}")
    x, y = reference.pos_m[:, 0], reference.pos_m[:, 1]
    start = np.flatnonzero(WINDOW_RULES[shape]["start"](x, y))
    if start.size == 0:
        raise ValueError(f"the reference never meets the start rule of trajectory {shape}")
    end = np.flatnonzero(WINDOW_RULES[shape]["end"](x, y) & (np.arange(x.size) > start[0]))
    if end.size == 0:
        raise ValueError(f"the reference never meets the end rule of trajectory {shape} after its start")
    return float(reference.t_s[start[0]]), float(reference.t_s[end[0]])


def authors_errors(reference: Trajectory, est: Estimates, shape: str) -> dict:
    """Errors of ``est`` by the authors' definition (both on the same clock, reference unlifted).

    Window :func:`authors_window`; reference rows in it with ``|z| <`` :data:`AUTHORS_Z_LIMIT_M`;
    the estimate epochs in it (both ends included); the reference interpolated linearly at each
    (held at its first/last row beyond them); 2-D error on x, y; 3-D error with the reference z
    raised by :data:`AUTHORS_TAG_HEIGHT_M`.

    Returns
    -------
    dict
        ``err_2d_m``, ``err_3d_m`` (shape ``(N,)``), ``t_s`` (N,), ``window_s`` (start, end),
        ``n_reference`` (rows used), ``n_z_dropped`` (rows dropped by the |z| rule).
    """
    t0, t1 = authors_window(reference, shape)
    inw = (reference.t_s >= t0) & (reference.t_s <= t1)
    keep = inw & (np.abs(reference.pos_m[:, 2]) < AUTHORS_Z_LIMIT_M)
    ref = reference.select(keep)
    sel = est.has_estimate & (est.t_s >= t0) & (est.t_s <= t1)
    t = est.t_s[sel]
    # hold the ends, as the script does: extend the reference by its end rows at the estimates' extremes
    tt, pp = ref.t_s, ref.pos_m
    if t.size and t[0] < tt[0]:
        tt, pp = np.r_[t[0], tt], np.vstack([pp[:1], pp])
    if t.size and t[-1] > tt[-1]:
        tt, pp = np.r_[tt, t[-1]], np.vstack([pp, pp[-1:]])
    lifted = Trajectory(tt, pp + np.array([0.0, 0.0, AUTHORS_TAG_HEIGHT_M]))
    track = est.select(sel).to_trajectory()
    e2 = metrics.errors_vs_truth(track, lifted, horizontal=True)
    e3 = metrics.errors_vs_truth(track, lifted, horizontal=False)
    return {"err_2d_m": e2.err_m, "err_3d_m": e3.err_m, "t_s": e2.t_s, "window_s": (t0, t1),
            "n_reference": int(keep.sum()), "n_z_dropped": int((inw & ~keep).sum())}


_RMSD = re.compile(r"(?P<method>\w+) (?P<metric>RMSE(?:_2d)?): (?P<value>[-+0-9.eE]+|nan|inf)(?: m)?")


def read_rmsd_results(path: PathLike) -> dict[str, dict[str, float]]:
    """``RMSD_results.txt`` as ``{"LS": {"rmse_m": ..., "rmse_2d_m": ...}, "ESKF": {...}}`` (*input*).

    A line reading ``Insufficient data ...`` gives no value; any other line that is not
    ``<METHOD> RMSE: <v> m`` or ``<METHOD> RMSE_2d: <v>`` is an error naming the line.
    """
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise DataNotFoundError(f"{path}: no such file") from None
    out: dict[str, dict[str, float]] = {}
    for i, ln in enumerate(lines, start=1):
        if not ln.strip() or ln.startswith("Insufficient data"):
            continue
        m = _RMSD.fullmatch(ln.strip())
        if m is None:
            raise DataFormatError(path, f"expected '<METHOD> RMSE: <value> m' or '<METHOD> RMSE_2d: <value>', "
                                        f"got {ln!r}", line=i)
        key = "rmse_2d_m" if m["metric"].endswith("_2d") else "rmse_m"
        out.setdefault(m["method"], {})[key] = float(m["value"])
    return out


def reproduce_authors(case: PathLike, data_dir: PathLike | None = None) -> pd.DataFrame:
    """The authors' RMSE and RMSE_2d recomputed by the package's metric code, beside theirs.

    The case is loaded *unregistered* (the script compares raw stamps and the unlifted
    reference). One row per (method, metric): ``reproduced_m`` (*reproduced*), ``published_m``
    (*input*, from ``RMSD_results.txt``; NaN if absent), ``diff_m``, ``n_epochs``, ``window_s``,
    ``n_z_dropped``.
    """
    rec = hanyang_dynamic.load_dynamic_case(case, data_dir, register=False)
    shape = rec.meta["trajectory"]
    if shape not in WINDOW_RULES:
        raise ValueError(f"{rec.label}: the authors' window needs trajectory shape A or B (case name "
                         f"'<LOS|NLOS>/Trajectory_<A|B>/Case_<n>'), got {shape!r}")
    path = Path(rec.meta["source"]["folder"]) / "RMSD_results.txt"
    published = read_rmsd_results(path) if path.is_file() else {}
    rows = []
    for method, est in hanyang_dynamic.authors_estimates(rec).items():
        e = authors_errors(rec.truth["tag"], est, shape)
        for metric, key, err in (("RMSE 3-D", "rmse_m", e["err_3d_m"]), ("RMSE 2-D", "rmse_2d_m", e["err_2d_m"])):
            mine = metrics.rmse(err) if err.size else float("nan")
            theirs = published.get(method, {}).get(key, float("nan"))
            rows.append({"data": rec.label, "method": method, "metric": metric, "reproduced_m": mine,
                         "published_m": theirs, "diff_m": mine - theirs, "n_epochs": int(err.size),
                         "window_s": float(e["window_s"][1] - e["window_s"][0]), "n_z_dropped": e["n_z_dropped"]})
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------------------------
# 2. estimators of this study
# --------------------------------------------------------------------------------------------

def _nan_bound(t_s, dim: int, kind: str) -> bounds.Bound:
    return bounds.Bound(t_s, np.full((len(t_s), dim, dim), np.nan), kind)


@dataclass(frozen=True)
class AuthorsEstimator(BaseEstimator):
    """The dataset authors' own estimates (``LS.csv``, ``ESKF.csv``) as a row of the board, *external*.

    Nothing is run or tuned: their published positions are placed on the board's epochs by
    linear interpolation between their two neighbouring outputs (none beyond their first/last
    output or across a gap over :data:`AUTHORS_MAX_GAP_S`), on their own stamps (the loader's
    ``authors_lag_s`` is their latency: not corrected) moved by ``shift_s`` (0 by default; a sensitivity
    row sets it to the lag measured on the *tuning* case, which removes their output latency).
    Their ESKF also used the robot's IMU. No bound (kind ``"none (external)"``).
    """

    #: read by the board: rows of outside estimates go to the summary as *input*, not *reproduced*
    external = True
    method: str = "LS"
    shift_s: float = 0.0

    @property
    def name(self) -> str:
        if self.shift_s:
            return f"authors {self.method}, latency removed ({self.shift_s:+.2f} s, tuning case) (external)"
        return f"authors {self.method} (external{', +IMU' if self.method == 'ESKF' else ''})"

    def applies(self, rec, tag, cal):
        if self.method not in rec.meta.get("authors_estimates", {}):
            return f"no authors' {self.method} estimates in this recording"
        return None

    def estimate(self, rec, tag, cal):
        src = rec.meta["authors_estimates"][self.method].to_trajectory()
        src = Trajectory(src.t_s + self.shift_s, src.pos_m) if self.shift_s else src
        t = rec.ranges[tag].t_s
        d = cal.dim
        pos = np.column_stack([np.interp(t, src.t_s, src.pos_m[:, k]) for k in range(d)])
        i = np.clip(np.searchsorted(src.t_s, t, side="right"), 1, max(len(src) - 1, 1))
        ok = (t >= src.t_s[0]) & (t <= src.t_s[-1]) if len(src) else np.zeros(t.size, bool)
        if len(src) > 1:
            ok &= (src.t_s[i] - src.t_s[i - 1] <= AUTHORS_MAX_GAP_S) | np.isin(t, src.t_s)
        pos[~ok] = np.nan
        return Estimates(t, pos, np.where(ok, _UP, _NONE).astype(np.int8), self.name)

    def bound(self, rec, tag, cal, est):
        return _nan_bound(est.t_s, cal.dim, "none (external)")


@dataclass(frozen=True)
class RangeMeasurement:
    """Two-way ranges as :class:`~uwbwb.filters.ekf.Ekf` sees them: one epoch's measurement is a row of
    ``RangeLog.range_m`` (NaN = not measured), ``h_i(p) = |(p, z) − a_i|`` at the known tag height ``z_m``
    in 2-D (``|p − a_i|`` in 3-D), ``R = diag(σ_i²)``. It can re-linearise a subset of its anchors, so the
    anchor-dropping gate applies.
    """

    anchors_m: np.ndarray
    sigma_m: np.ndarray
    motion: MotionModel
    z_m: float | None = None

    def __post_init__(self):
        if self.motion.dim == 2 and self.z_m is None:
            raise ValueError("a 2-D range model needs the tag height z_m")

    def _lin(self, x: np.ndarray, row: np.ndarray, keep: np.ndarray) -> Linearisation:
        p = self.motion.position(x)
        p3 = np.r_[p, self.z_m] if p.size == 2 else p
        d = p3[None, :] - self.anchors_m[keep]
        r = np.linalg.norm(d, axis=1)
        H_pos = d[:, : p.size] / np.maximum(r, 1e-9)[:, None]
        return Linearisation(row[keep], r, H_pos @ self.motion.H_pos, np.diag(self.sigma_m[keep] ** 2))

    def linearise(self, x, measurement):
        row = np.asarray(measurement, float)
        keep = np.flatnonzero(np.isfinite(row))
        return None if keep.size == 0 else self._lin(x, row, keep)

    def components(self, measurement) -> np.ndarray:
        return np.flatnonzero(np.isfinite(np.asarray(measurement, float)))

    def linearise_components(self, x, measurement, keep):
        return self._lin(x, np.asarray(measurement, float), np.asarray(keep))


@dataclass(frozen=True)
class RangeEkfEstimator(BaseEstimator):
    """An EKF on the ranges themselves (no TDoA: with four anchors in a 2 m cluster and the tag up to
    50 m away, range differences carry almost no information, while the ranges do), motion model
    ``model`` (RW, RF, RJ of notebook 03), calibrated ranges and range noise of the board, the
    anchor-dropping χ² gate (``gate_prob``) of the TDoA EKF. ``tune`` picks the driving noise on the
    calibration part over :data:`~uwbwb.scoreboard.estimators.EKF_GRIDS` as the board's EKFs do; the
    filter starts at the first epoch with a multilateration fix. Bound: the posterior CRLB with the
    same motion model and the range information of every epoch.
    """

    model: str = "RF"
    gate_prob: float = 0.9999
    grid: tuple[float, ...] | None = None
    init_sigma: float = 1.0

    @property
    def name(self) -> str:
        return f"EKF-{self.model} ranges"

    def _filter(self, rec, tag, cal, sigma_w) -> Ekf:
        motion = make_motion_model(self.model, sigma=sigma_w, dt_s=1.0 / cal.rate_hz, dim=cal.dim)
        meas = RangeMeasurement(rec.anchors.pos_m, cal.sigma(tag), motion, cal.height(tag))
        d = cal.dim
        return Ekf(motion, meas, tuple(range(d)), tuple(range(d, 2 * d)) if motion.order >= 2 else None,
                   gate=AnchorDropping(prob=self.gate_prob, max_gated=10, min_rows=2))

    def _run(self, rec, tag, cal, sigma_w) -> Estimates:
        log = calibrated_log(rec, tag, cal)
        ekf = self._filter(rec, tag, cal, sigma_w)
        fix = geometry.multilaterate(log.range_m, rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag))
        ok = np.flatnonzero(np.all(np.isfinite(fix.pos_m), axis=1))
        if ok.size == 0:
            T = len(log)
            return Estimates(log.t_s, np.full((T, cal.dim), np.nan), np.full(T, _NONE, np.int8), self.name)
        m = ekf.transition
        s = self.init_sigma
        x0 = Gaussian(m.initial_state(fix.pos_m[ok[0], : cal.dim]), m.initial_covariance(s, s, s))
        return ekf.run(log.t_s, list(log.range_m), x0, start=int(ok[0]), name=self.name).to_estimates()

    def tune(self, rec, tags, cal):
        grid = EKF_GRIDS[self.model] if self.grid is None else np.asarray(self.grid, float)
        cost = [np.mean([_errors_rmse(self._run(rec, t, cal, g), rec, t, cal.dim) for t in tags]) for g in grid]
        best = int(np.argmin(cost))
        return {"sigma_w": float(grid[best]), "grid": tuple(float(g) for g in grid),
                "grid_rmse_m": tuple(float(c) for c in cost)}

    def estimate(self, rec, tag, cal):
        return self._run(rec, tag, cal, cal.params(self.name)["sigma_w"])

    def bound(self, rec, tag, cal, est):
        log = calibrated_log(rec, tag, cal)
        pos = truth_at(rec, tag, log.t_s, cal.dim)
        have = np.all(np.isfinite(pos), axis=1)
        info = np.zeros((len(log), cal.dim, cal.dim))
        if have.any():
            info[have] = bounds.range_information(pos[have], rec.anchors.pos_m, cal.sigma(tag), z_m=cal.height(tag),
                                                  mask=np.isfinite(log.range_m[have]))
        C = np.full((len(log), cal.dim, cal.dim), np.nan)
        start = np.flatnonzero(est.has_estimate)
        kind = f"PCRLB {self.model} ranges"
        if start.size:
            k0 = int(start[0])
            m = self._filter(rec, tag, cal, cal.params(self.name)["sigma_w"]).transition
            s = self.init_sigma
            C[k0:] = bounds.tracking_bound(m, log.t_s[k0:], info[k0:], m.initial_covariance(s, s, s))
            C[~have] = np.nan
        return bounds.Bound(log.t_s, C, kind)


@dataclass(frozen=True)
class PrunedNls(WindowNls):
    """The windowed NLS of the board with one pruning heuristic of paper 001 (Zupanec et al., sec. 2.5)
    inside each window: ``"residual"`` (drop the largest residuals, re-solve) or ``"robust_mean"``
    (triplet fixes, pruned centroid line). Same windows and window tuning as ``NLS``; solved in
    2-D at the calibrated height (:func:`uwbwb.filters.pruning.localize`, ``stationary=False``).
    Bound: the line-fit CRLB of all the window's ranges (a lower bound for a fit that uses fewer).
    """

    heuristic: str = "residual"
    name: str = ""

    def __post_init__(self):
        if self.heuristic not in ("residual", "robust_mean"):
            raise ValueError(f"heuristic must be 'residual' or 'robust_mean' (moving windows), got {self.heuristic!r}")
        if not self.name:
            object.__setattr__(self, "name", f"NLS {PRUNING_LABELS[self.heuristic]}")

    def _run(self, rec, tag, cal, w) -> Estimates:
        log = calibrated_log(rec, tag, cal)
        T, d = len(log), cal.dim
        pos = np.full((T, d), np.nan)
        status = np.full(T, _NONE, np.int8)
        win = self._windows(log, w)
        config = PruningConfig(dim=d)
        for k in np.unique(win):
            idx = np.flatnonzero(win == k)
            part = log.select(idx)
            if idx.size < 3 or np.isfinite(part.range_m).sum() < 2 * d + 2:
                continue
            try:
                res = localize(part, rec.anchors, self.heuristic, config, stationary=False, z_m=cal.height(tag))
            except ValueError:
                continue
            if res.fit is not None and not res.fit.converged:
                continue
            pos[idx] = res.position_at(part.t_s)[:, :d]
            status[idx] = _UP
        return Estimates(log.t_s, pos, status, self.name, None, None, {"window": win})


@dataclass(frozen=True)
class StaticRangeModel:
    """Range error vs distance from the static files: ``range_meas ≈ scale · d + bias_m``.

    Fitted by least squares on the per-file medians of the measured range against the file's
    true range (one point per file: the ~90 samples of a file are one geometry), per condition.
    """

    condition: str
    scale: float
    bias_m: float
    n_files: int
    n_samples: int
    span_m: tuple[float, float]
    resid_sigma_m: float

    def correct(self, range_m: np.ndarray) -> np.ndarray:
        """Ranges with the static bias removed: ``(r − bias) / scale``."""
        return (np.asarray(range_m, float) - self.bias_m) / self.scale

    def describe(self) -> str:
        return (f"static {self.condition} model: range = {self.scale:.4f}·d {self.bias_m:+.3f} m "
                f"({self.n_files} files, {self.n_samples} samples, d {self.span_m[0]:g}–{self.span_m[1]:g} m, "
                f"file-median residual σ {self.resid_sigma_m:.3f} m)")


def static_range_model(condition: str = "LOS", data_dir: PathLike | None = None,
                       min_samples: int = 10) -> StaticRangeModel:
    """Fit :class:`StaticRangeModel` on the static files of ``condition`` (all heights).

    Files with fewer than ``min_samples`` samples are left out (header-only files have none).
    """
    df = hanyang.load_static(data_dir, condition=condition)
    med = df.groupby("file").agg(d=("true_range_m", "first"), r=("range_m", "median"), n=("range_m", "count"))
    med = med[med["n"] >= min_samples]
    if len(med) < 3 or med["d"].nunique() < 2:
        raise ValueError(f"static {condition} files: {len(med)} with at least {min_samples} samples "
                         f"at {med['d'].nunique()} distances; need 3 files at 2 distances for a line")
    A = np.column_stack([med["d"], np.ones(len(med))])
    (scale, bias), *_ = np.linalg.lstsq(A, med["r"].to_numpy(float), rcond=None)
    resid = med["r"].to_numpy(float) - A @ [scale, bias]
    return StaticRangeModel(condition, float(scale), float(bias), int(len(med)), int(med["n"].sum()),
                            (float(med["d"].min()), float(med["d"].max())), float(np.std(resid, ddof=2)))


@dataclass(frozen=True)
class StaticModelLs(BaseEstimator):
    """Unweighted multilateration (as ``raw LS``) of the ranges corrected by a static range model
    (:class:`StaticRangeModel`) instead of the board's per-pair calibration: does the static part's
    bias-vs-distance help the dynamic runs? Bound: the CRLB of the ranges (as ``raw LS``)."""

    model: StaticRangeModel | None = None
    name: str = ""

    def __post_init__(self):
        if self.model is None:
            raise ValueError("StaticModelLs needs a StaticRangeModel (static_range_model(...))")
        if not self.name:
            object.__setattr__(self, "name", f"LS static {self.model.condition} model")

    def estimate(self, rec, tag, cal):
        log = rec.ranges[tag]
        r = self.model.correct(log.range_m)
        res = geometry.multilaterate(np.maximum(r, 0.0), rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag))
        return res.to_estimates(log.t_s, self.name)

    def bound(self, rec, tag, cal, est):
        return _range_bound(rec, tag, cal, rec.ranges[tag])


#: *Input* (the authors' LS front end, ``Technical_validation/``): a range differing from its anchor's
#: previous accepted range by more than this is rejected ...
AUTHORS_JUMP_M = 0.5
#: ... at most this many times in a row (the next one is accepted) ...
AUTHORS_MAX_REJECTS = 4
#: ... and each anchor's latest accepted range is used for up to this long, seconds.
AUTHORS_HOLD_S = 0.3


def authors_front_end(t_s: np.ndarray, range_m: np.ndarray, *, jump_m: float = AUTHORS_JUMP_M,
                      max_rejects: int = AUTHORS_MAX_REJECTS, hold_s: float = AUTHORS_HOLD_S
                      ) -> tuple[np.ndarray, dict]:
    """The authors' LS range front end applied to a range log: per anchor, a jump gate and a hold.

    Per anchor, a measured range whose difference from that anchor's previous accepted range exceeds
    ``jump_m`` is rejected, up to ``max_rejects`` in a row (the next is accepted and becomes the
    reference); at each epoch an anchor without a fresh accepted range uses its latest accepted one if
    it is at most ``hold_s`` old.

    Parameters
    ----------
    t_s
        Epoch times, ``(T,)``, seconds.
    range_m
        Ranges, ``(T, n_anchors)``, metres; NaN = not measured.

    Returns
    -------
    ranges, report
        The ranges the solver sees, ``(T, n_anchors)`` (NaN: none), and per epoch ``(T,)`` the number of
        anchors whose range was rejected (``n_rejected``) and filled by holding (``n_held``).
    """
    t = np.asarray(t_s, float)
    r = np.asarray(range_m, float)
    out = np.full_like(r, np.nan)
    n_rej, n_held = np.zeros(t.size, int), np.zeros(t.size, int)
    for k in range(r.shape[1]):
        prev, rejects, last_t = np.nan, 0, -np.inf
        for i in range(t.size):
            d = r[i, k]
            if np.isfinite(d):
                if np.isfinite(prev) and abs(d - prev) > jump_m:
                    rejects += 1
                    if rejects <= max_rejects:
                        n_rej[i] += 1
                        d = np.nan
                else:
                    rejects = 0
            if np.isfinite(d):
                prev, last_t, out[i, k] = d, t[i], d
            elif np.isfinite(prev) and t[i] - last_t <= hold_s + 1e-9:       # 1 ns: the stamps' resolution
                out[i, k] = prev
                n_held[i] += 1
    return out, {"n_rejected": n_rej, "n_held": n_held}


@dataclass(frozen=True)
class AuthorsFrontEndLs(BaseEstimator):
    """``raw LS`` (per-epoch unweighted multilateration, no calibration, 2-D at the calibrated height) on the
    ranges after the authors' LS front end (:func:`authors_front_end`: jump gate and hold), so that outlier
    handling matches theirs. Their warm-started 3-D solve and 10 Hz output timer are not copied.
    Bound: the CRLB of the ranges (as ``raw LS``)."""

    name: str = "raw LS, authors' front end (jump gate + hold)"

    def estimate(self, rec, tag, cal):
        log = rec.ranges[tag]
        r, report = authors_front_end(log.t_s, log.range_m)
        res = geometry.multilaterate(r, rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag))
        est = res.to_estimates(log.t_s, self.name)
        return replace(est, info={**est.info, **report})

    def bound(self, rec, tag, cal, est):
        return _range_bound(rec, tag, cal, rec.ranges[tag])


# --------------------------------------------------------------------------------------------
# 3. boards
# --------------------------------------------------------------------------------------------

def tuning_case(case: str, cases: Sequence[str]) -> str:
    """The case whose data tunes ``case``'s board: same condition, the other trajectory shape (the
    lowest case number), else another case of the same shape and condition, else any other case.

    Raises
    ------
    ValueError
        ``cases`` holds no case other than ``case``.
    """
    others = [c for c in cases if c != case]
    if not others:
        raise ValueError(f"no other case than {case!r} to tune on: tuning on the scored case is not allowed")
    me = hanyang_dynamic._case_fields(case)

    def key(c):
        f = hanyang_dynamic._case_fields(c)
        return (f["condition"] != me["condition"], f["trajectory"] == me["trajectory"], f["case"] or 0)

    return sorted(others, key=key)[0]


def board_epochs(rec: Recording) -> tuple[float, float]:
    """The authors' window of a registered case on the ranges' clock (their rules on the reference)."""
    ref = rec.truth["tag"]
    return authors_window(ref, rec.meta["trajectory"])


def load_pair(case: str, tune: str, data_dir: PathLike | None = None) -> tuple[Recording, Recording]:
    """``(scored, tuning)`` recordings: the tuning case with its own fitted tag height, the scored case
    with the *tuning case's* height (a calibration)."""
    cal_rec = hanyang_dynamic.load_dynamic_case(tune, data_dir)
    test_rec = hanyang_dynamic.load_dynamic_case(case, data_dir, tag_height_m=cal_rec.meta["tag_height_fit_m"])
    return test_rec, cal_rec


def study_estimators(*, fast: bool = False, static_models: Sequence[StaticRangeModel] = ()) -> list:
    """The board of this study: every ranges-only method of the package (the UWB/INS filters need an
    IMU this dataset does not provide), the EKFs RW/RF/RJ on ranges (:class:`RangeEkfEstimator`),
    NLS with residual pruning and with the robust mean, LS on
    ranges corrected by each static model, raw LS behind the authors' front end (:class:`AuthorsFrontEndLs`),
    then the authors' LS and ESKF (*external*)."""
    coarse = {m: tuple(float(g) for g in EKF_GRIDS[m][::2]) for m in EKF_GRIDS}
    # the TDoA EKFs get the coarse grid in both modes: range differences from a 2 m anchor cluster do not
    # locate a tag tens of metres away (they diverge on every setting), and each setting costs a full run
    base = [replace(e, grid=coarse[e.model]) if isinstance(e, TdoaEkfEstimator) else e
            for e in default_estimators(fast=fast) if e.name not in ("loose", "tight")]
    windows = (1.0,) if fast else NLS_WINDOWS_S
    ekfs = [RangeEkfEstimator(m, grid=coarse[m] if fast else None) for m in ("RW", "RF", "RJ")]
    return [*base, *ekfs, PrunedNls(windows_s=windows, heuristic="residual"),
            PrunedNls(windows_s=windows, heuristic="robust_mean"),
            *[StaticModelLs(m) for m in static_models], AuthorsFrontEndLs(), AuthorsEstimator("LS"),
            AuthorsEstimator("ESKF")]


def case_board(case: str, tune: str, data_dir: PathLike | None = None, *, fast: bool = False,
               estimators: Sequence | None = None, static_models: Sequence[StaticRangeModel] = (),
               progress: bool = False) -> Board:
    """The board of ``case`` with calibration and tuning on ``tune`` (never the scored case).

    Scored epochs: the range epochs inside the authors' window of ``case`` (FAST: its first
    :data:`FAST_SPAN_S` s, and the tuning case cut to as many seconds of its own window).
    Every method runs in 2-D at the tag height of the tuning case, at the native ~10 Hz. With the
    default estimators a sensitivity row is added: the authors' LS with its output latency removed, the
    lag measured on the tuning case (``authors_lag_s``).
    """
    if case == tune:
        raise ValueError(f"{case}: tuning on the scored case is not allowed; give another case")
    test_rec, cal_rec = load_pair(case, tune, data_dir)
    t0, t1 = board_epochs(test_rec)
    c0, c1 = board_epochs(cal_rec)
    if fast:
        t1, c1 = min(t1, t0 + FAST_SPAN_S), min(c1, c0 + FAST_SPAN_S)
    test = between(test_rec, t0, t1, f"{test_rec.name} [authors' window{' , FAST part' if fast else ''}]")
    cal = between(cal_rec, c0, c1, f"{cal_rec.name} [authors' window]") if fast else cal_rec
    if estimators is None:
        est = study_estimators(fast=fast, static_models=static_models)
        lag = cal_rec.meta.get("authors_lag_s", {}).get("LS")
        if lag:                                                 # sensitivity: their latency, measured on the tuning case
            est.append(AuthorsEstimator("LS", shift_s=float(lag)))
    else:
        est = list(estimators)
    return score(test, cal, estimators=est, rate_hz=None, dim=2, fast=fast, progress=progress,
                 label=test_rec.label)


# --------------------------------------------------------------------------------------------
# ours vs theirs
# --------------------------------------------------------------------------------------------

def _external(name: str) -> bool:
    return "external" in name


def pair_errors(board: Board, method: str, reference: str, tag: str = "tag") -> dict | None:
    """Errors of ``method`` and ``reference`` on the epochs *both* covered (and the truth reaches).

    Unlike the board's common epochs, these do not depend on which other methods are on the board.
    Returns None if either did not run. Keys: ``t_s`` ``(N,)``, ``err_m``, ``err_ref_m`` ``(N,)``,
    ``coverage`` and ``coverage_ref`` (each one's share of the scoring epochs with a position) and
    ``n_scoring``.
    """
    ran = {e.method: e for e in board.ran(tag)}
    if method not in ran or reference not in ran:
        return None
    a, b = ran[method], ran[reference]
    both = a.scored & b.scored
    n = int(a.scoring.sum())
    return {"t_s": a.estimates.t_s[both], "err_m": a.error_m[both], "err_ref_m": b.error_m[both],
            "coverage": float(a.scored.sum() / n) if n else float("nan"),
            "coverage_ref": float(b.scored.sum() / n) if n else float("nan"), "n_scoring": n}


def held_errors(board: Board, method: str, reference: str, tag: str = "tag") -> dict | None:
    """Errors of ``method`` on every epoch ``reference`` covered, ``method`` *holding its last position*
    where it has none (NaN before its first position); ``reference``'s errors there. None if either
    did not run. Keys as :func:`pair_errors` (``n_held``: epochs filled by holding)."""
    ran = {e.method: e for e in board.ran(tag)}
    if method not in ran or reference not in ran:
        return None
    a, b = ran[method], ran[reference]
    has = a.estimates.has_estimate
    last = np.maximum.accumulate(np.where(has, np.arange(has.size), -1))
    pos = np.where((last >= 0)[:, None], a.estimates.pos_m[np.maximum(last, 0)], np.nan)
    d = pos[:, :2] - a.truth_pos_m[:, :2]
    err = np.sqrt(np.sum(d * d, axis=1))
    keep = b.scored & np.isfinite(err)
    n = int(a.scoring.sum())
    return {"t_s": a.estimates.t_s[keep], "err_m": err[keep], "err_ref_m": b.error_m[keep],
            "coverage": float(keep.sum() / n) if n else float("nan"),
            "coverage_ref": float(b.scored.sum() / n) if n else float("nan"), "n_scoring": n,
            "n_held": int((keep & ~a.scored).sum())}


def offset_ratio(board: Board, method: str, reference: str, delta_s: float, tag: str = "tag") -> float:
    """RMSE_2d ratio ``method`` / ``reference`` on the epochs both covered, with the reference track's clock
    offset changed by ``delta_s`` (truth'(t) = truth(t − delta_s), interpolated linearly between the board's
    epochs; epochs it does not reach are left out). A sensitivity check of the registration."""
    ran = {e.method: e for e in board.ran(tag)}
    if method not in ran or reference not in ran:
        return float("nan")
    a, b = ran[method], ran[reference]
    t = a.estimates.t_s
    have = a.scoring
    if have.sum() < 2:
        return float("nan")
    tq = t - delta_s
    inside = (tq >= t[have][0]) & (tq <= t[have][-1])
    truth = np.column_stack([np.interp(tq, t[have], a.truth_pos_m[have, k]) for k in range(2)])
    both = a.scored & b.scored & inside
    if not both.any():
        return float("nan")
    ea = np.hypot(*(a.estimates.pos_m[both, :2] - truth[both]).T)
    eb = np.hypot(*(b.estimates.pos_m[both, :2] - truth[both]).T)
    return metrics.rmse(ea) / metrics.rmse(eb)


def block_length_s(err_a: np.ndarray, err_b: np.ndarray, t_s: np.ndarray, *, acf_level: float = ACF_LEVEL) -> float:
    """Block length of the bootstrap, seconds: :data:`BLOCK_LAG_FACTOR` × the first lag at which the
    autocorrelation of the paired difference ``err_a² − err_b²`` falls below ``acf_level``.

    The autocorrelation is taken over the sequence of paired epochs (gaps ignored) and the lag turned
    into seconds with their median spacing; at least two spacings. NaN with fewer than 3 epochs.
    """
    t = np.asarray(t_s, float)
    if t.size < 3:
        return float("nan")
    d = np.asarray(err_a, float) ** 2 - np.asarray(err_b, float) ** 2
    d = d - d.mean()
    dt = float(np.median(np.diff(t)))
    var = float(np.dot(d, d))
    if var <= 0:
        return BLOCK_LAG_FACTOR * dt
    f = np.fft.rfft(d, 2 * d.size)
    acf = np.fft.irfft(f * np.conj(f))[: d.size] / var
    below = np.flatnonzero(acf < acf_level)
    lag = int(below[0]) if below.size else d.size
    return BLOCK_LAG_FACTOR * max(lag, 1) * dt


def ratio_interval(err_a: np.ndarray, err_b: np.ndarray, t_s: np.ndarray, *, rng: np.random.Generator,
                   n_boot: int = 2000, level: float = 0.95, block_s: float | None = None,
                   min_blocks: int = MIN_BLOCKS) -> dict:
    """Interval of ``RMSE(err_a) / RMSE(err_b)`` on paired epochs by a block bootstrap.

    The epochs at ``t_s`` (seconds, ``(N,)``) are cut into contiguous blocks of ``block_s`` seconds
    (default :func:`block_length_s`, derived from the data); the blocks are resampled with replacement.
    With fewer than ``min_blocks`` non-empty blocks there are too few independent pieces for an
    interval: ``lo``/``hi`` are NaN and the verdict is refused.

    Returns
    -------
    dict
        ``lo``, ``hi``, ``block_s``, ``n_blocks``.
    """
    err_a, err_b, t = np.asarray(err_a, float), np.asarray(err_b, float), np.asarray(t_s, float)
    if not (err_a.size == err_b.size == t.size):
        raise ValueError(f"paired errors and times must have the same length, got {err_a.size}, {err_b.size}, {t.size}")
    bl = block_length_s(err_a, err_b, t) if block_s is None else float(block_s)
    if not np.isfinite(bl) or t.size == 0:
        return {"lo": float("nan"), "hi": float("nan"), "block_s": bl, "n_blocks": 0}
    ids = np.floor((t - t[0]) / bl).astype(int)
    _, ids = np.unique(ids, return_inverse=True)
    nb = int(ids.max()) + 1
    if nb < min_blocks:
        return {"lo": float("nan"), "hi": float("nan"), "block_s": bl, "n_blocks": nb}
    sa = np.bincount(ids, err_a ** 2, nb)
    sb = np.bincount(ids, err_b ** 2, nb)
    pick = rng.integers(0, nb, (n_boot, nb))
    ratio = np.sqrt(sa[pick].sum(axis=1) / sb[pick].sum(axis=1))
    lo, hi = np.quantile(ratio, [(1 - level) / 2, (1 + level) / 2])
    return {"lo": float(lo), "hi": float(hi), "block_s": bl, "n_blocks": nb}


def block_bootstrap_ratio(err_a: np.ndarray, err_b: np.ndarray, *, rng: np.random.Generator, t_s=None,
                          n_boot: int = 2000, level: float = 0.95) -> tuple[float, float]:
    """``(lo, hi)`` of :func:`ratio_interval` (``t_s`` None: one epoch per 0.1 s, the runs' rate)."""
    t = 0.1 * np.arange(np.asarray(err_a).size) if t_s is None else t_s
    r = ratio_interval(err_a, err_b, t, rng=rng, n_boot=n_boot, level=level)
    return r["lo"], r["hi"]


@dataclass(frozen=True)
class CaseComparison:
    """Boards and reproductions of several cases (:func:`compare_cases`)."""

    boards: Mapping[str, Board]
    tuning: Mapping[str, str]
    reproduction: pd.DataFrame
    ratios: pd.DataFrame
    fast: bool
    static_models: tuple = ()
    picks: Mapping[str, str | None] = field(default_factory=dict)

    @property
    def mode(self) -> str:
        return "FAST" if self.fast else "full"


THEIRS = "authors LS (external)"


def _ours(board: Board) -> list[str]:
    return [e.method for e in board.ran("tag") if not _external(e.method)]


def pick_on_tuning_case(tune: str, data_dir: PathLike | None = None, *, fast: bool = False,
                        estimators: Sequence | None = None, static_models: Sequence[StaticRangeModel] = (),
                        progress: bool = False) -> tuple[str | None, Board]:
    """Our ranges-only method to set against the authors' LS, picked on the tuning case alone.

    The authors' window of ``tune`` (FAST: its first :data:`FAST_SPAN_S` s) is split in time: its
    first half calibrates and tunes every method (:func:`~uwbwb.scoreboard.score`), its second half
    scores them beside the authors' LS; the pick is the method with the lowest RMSE_2d ratio to the
    authors' LS on the epochs both covered (:func:`pair_errors`). Nothing of the scored case enters
    (its tag height, ranges and truth are not read). Returns ``(method or None, board)``.
    """
    rec = hanyang_dynamic.load_dynamic_case(tune, data_dir)
    c0, c1 = board_epochs(rec)
    if fast:
        c1 = min(c1, c0 + FAST_SPAN_S)
    mid = 0.5 * (c0 + c1)
    first = between(rec, c0, mid, f"{rec.name} [authors' window, first half]")
    second = between(rec, mid, c1, f"{rec.name} [authors' window, second half]")
    est = study_estimators(fast=fast, static_models=static_models) if estimators is None else list(estimators)
    est = [e for e in est if not isinstance(e, AuthorsEstimator) or e.method == "LS"]
    if not any(isinstance(e, AuthorsEstimator) for e in est):
        est.append(AuthorsEstimator("LS"))
    board = score(second, first, estimators=est, rate_hz=None, dim=2, fast=fast, progress=progress,
                  label=f"{rec.label} [pick: tuned on first half, scored on second]")
    score_of = {}
    for m in _ours(board):
        p = pair_errors(board, m, THEIRS)
        if p is not None and p["err_m"].size:
            score_of[m] = metrics.rmse(p["err_m"]) / metrics.rmse(p["err_ref_m"])
    return (min(score_of, key=score_of.get) if score_of else None), board


def _ratio_cols(prefix: str, p: dict | None, case: str, m: str, seed: int) -> dict:
    if p is None or not p["err_m"].size:
        return {}
    rng = np.random.default_rng([seed, zlib.crc32(f"{case}/{m}/{prefix}".encode())])
    iv = ratio_interval(p["err_m"], p["err_ref_m"], p["t_s"], rng=rng)
    r_ours, r_theirs = metrics.rmse(p["err_m"]), metrics.rmse(p["err_ref_m"])
    return {f"{prefix}n": int(p["err_m"].size), f"{prefix}rmse_2d_m": r_ours,
            f"{prefix}authors_ls_rmse_2d_m": r_theirs, f"{prefix}ratio": r_ours / r_theirs,
            f"{prefix}ratio_lo": iv["lo"], f"{prefix}ratio_hi": iv["hi"], f"{prefix}block_s": iv["block_s"],
            f"{prefix}n_blocks": iv["n_blocks"]}


def ratio_table(boards: Mapping[str, Board], reproduction: pd.DataFrame, *, picks: Mapping[str, str | None] | None = None,
                seed: int = 0) -> pd.DataFrame:
    """Per case and our ranges-only method: RMSE_2d of ours and of the authors' LS on the epochs *that
    pair* covered (both have a position; independent of the other methods on the board), the ratio
    ours / theirs and its 95 % block-bootstrap interval (:func:`ratio_interval`: block length from the
    data, ``n_blocks`` beside it), with both coverages (``coverage``: ours, ``coverage_authors_ls``:
    theirs, each over the scoring epochs). Columns ``held_*``: the same on *every* epoch the authors'
    LS covered, ours holding its last position where it has none (full-coverage variant). Columns
    ``nolat_*`` (when the board has it): against the authors' LS with its latency removed (sensitivity).
    ``ratio_dt±0.1s``: the ratio with the reference's clock offset changed by ±0.1 s (:func:`offset_ratio`).

    Two picks: ``best`` marks the lowest ratio on the scored case itself (optimistic: made after seeing
    the scores); ``chosen`` marks ``picks[case]`` (:func:`pick_on_tuning_case`: made on the tuning case
    alone), the fair one to compare with the authors."""
    rows = []
    for case, board in boards.items():
        pub = reproduction[(reproduction["data"] == board.label) & (reproduction["method"] == "LS")
                           & (reproduction["metric"] == "RMSE 2-D")]
        case_rows = []
        for m in _ours(board):
            p = pair_errors(board, m, THEIRS)
            if p is None or not p["err_m"].size:
                continue
            row = {"data": board.label, "case": case, "tuned_on": board.calibration.source, "method": m,
                   "epochs": f"{m} ∩ authors LS", "coverage": p["coverage"], "coverage_authors_ls": p["coverage_ref"],
                   "n_scoring": p["n_scoring"]}
            row.update(_ratio_cols("", p, case, m, seed))
            nolat = [n for n in (e.method for e in board.ran("tag")) if n.startswith("authors LS, latency removed")]
            if nolat:
                row.update(_ratio_cols("nolat_", pair_errors(board, m, nolat[0]), case, m, seed))
            for d in OFFSET_CHECK_S:
                row[f"ratio_dt{d:+.1f}s"] = offset_ratio(board, m, THEIRS, d)
            h = held_errors(board, m, THEIRS)
            row.update(_ratio_cols("held_", h, case, m, seed))
            row["held_n_filled"] = h["n_held"] if h is not None else 0
            row.update(authors_ls_published_2d_m=float(pub["published_m"].iloc[0]) if len(pub) else np.nan,
                       authors_ls_reproduced_2d_m=float(pub["reproduced_m"].iloc[0]) if len(pub) else np.nan)
            case_rows.append(row)
        if case_rows:
            best = min(case_rows, key=lambda r: r["ratio"])["method"]
            for r in case_rows:
                r["best"], r["chosen"] = r["method"] == best, r["method"] == (picks or {}).get(case)
        rows += case_rows
    return pd.DataFrame(rows)


def compare_cases(cases: Sequence[str] | None = None, data_dir: PathLike | None = None, *, fast: bool = False,
                  static: bool = True, seed: int = 0, progress: bool = False) -> CaseComparison:
    """Reproduction and board of every case (default: all present), each tuned on :func:`tuning_case`,
    and per tuning case the pick of :func:`pick_on_tuning_case`."""
    available = hanyang_dynamic.dynamic_cases(data_dir)
    cases = list(available if cases is None else cases)
    if not cases:
        raise DataNotFoundError("no Hanyang dynamic case in the data directories")
    models = []
    if static:
        for cond in ("LOS", "NLOS"):
            try:
                models.append(static_range_model(cond, data_dir))
            except (DataNotFoundError, ValueError):
                pass
    repro = pd.concat([reproduce_authors(c, data_dir) for c in cases], ignore_index=True)
    boards, tuning, pick_of_tune, picks = {}, {}, {}, {}
    for c in cases:
        tuning[c] = tuning_case(c, available)
        boards[c] = case_board(c, tuning[c], data_dir, fast=fast, static_models=models, progress=progress)
        if tuning[c] not in pick_of_tune:
            pick_of_tune[tuning[c]] = pick_on_tuning_case(tuning[c], data_dir, fast=fast, static_models=models,
                                                          progress=progress)[0]
        picks[c] = pick_of_tune[tuning[c]]
    return CaseComparison(boards, tuning, repro, ratio_table(boards, repro, picks=picks, seed=seed), fast,
                          tuple(models), picks)


def static_model_effect(boards: Mapping[str, Board], *, seed: int = 0) -> pd.DataFrame:
    """Per case and static model: RMSE_2d of ``LS static <cond> model`` vs ``raw LS`` (the same solver
    on uncorrected ranges) and vs ``LS`` (per-pair calibration from the tuning case), each pair on the
    epochs both covered, with block-bootstrap intervals of the ratios (``*_n_blocks`` beside them)."""
    rows = []
    for case, board in boards.items():
        for m in [m for m in _ours(board) if m.startswith("LS static")]:
            row = {"data": board.label, "case": case, "method": m}
            for ref in ("raw LS", "LS"):
                p = pair_errors(board, m, ref)
                if p is None or not p["err_m"].size:
                    continue
                rng = np.random.default_rng([seed, zlib.crc32(f"{case}/{m}/{ref}".encode())])
                iv = ratio_interval(p["err_m"], p["err_ref_m"], p["t_s"], rng=rng)
                key = ref.replace(" ", "_").lower()
                row.setdefault("rmse_2d_m", metrics.rmse(p["err_m"]))
                row.update({f"{key}_rmse_2d_m": metrics.rmse(p["err_ref_m"]),
                            f"ratio_vs_{key}": metrics.rmse(p["err_m"]) / metrics.rmse(p["err_ref_m"]),
                            f"ratio_vs_{key}_lo": iv["lo"], f"ratio_vs_{key}_hi": iv["hi"],
                            f"ratio_vs_{key}_n_blocks": iv["n_blocks"]})
            rows.append(row)
    return pd.DataFrame(rows)
