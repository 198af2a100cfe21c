"""Pruning heuristics around the NLS resolution routine (Zupanec et al., sec. 2.5, Fig. 7).

The localisation pipeline is *heuristic -> resolution routine -> (P0, v)*. One
heuristic is used per computation (:func:`localize`, ``heuristic=``):

``"none"``
    Plain NLS: every range goes into eq. (1) (:func:`uwbwb.filters.nls.fit_trajectory`).
``"percentile"`` -- 5th percentile of distances (pre-processing, sec. 2.5.1)
    Stationary segments only. Per anchor, the ``q``-th percentile of its
    ranges replaces them all; eq. (1) with ``v = 0`` is solved on those
    ``n_anchors`` values. The low percentile skips the large positive NLOS
    mode of the bimodal range-error distribution (Figs 4--5).
``"robust_mean"`` -- robust mean over n-tuples (pre- and post-processing, sec. 2.5.2)
    Every epoch is localised from every ``k``-tuple of anchors
    (``C(6,3) = 20``, ``C(8,3) = 56`` triplets) by point-based least squares in
    the horizontal plane at the node's known height; the clouds are pooled, the
    centroid taken, the furthest ``dropout`` of the points dropped, the
    centroid recomputed, until ``retention`` of the points remain (Fig. 6). On
    a moving segment the "centroid" is a straight line ``c + v (t - t0)``
    fitted to the points over time and distances are taken to the line at each
    point's time (our extension; the paper shows the static case only).
``"residual"`` -- residual pruning (post-processing, sec. 2.5.3)
    Solve eq. (1), sort the absolute residuals, drop the largest ``dropout``
    of the measurements, re-solve (warm start), until ``retention`` remain.

Interpretations (the paper leaves them open): a *dropout* fraction is a
fraction of the **initial** number of points/measurements per iteration (at
least one; the last step trims exactly to the target), so the number of
iterations is ``ceil((1 - retention) / dropout)``. Tuples whose anchors are
nearly collinear in plan (smallest singular value of their centred horizontal
coordinates below ``min_tuple_spread`` of the largest) are skipped and counted:
their fixes have a mirror ambiguity that no amount of pruning repairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from itertools import combinations

import numba
import numpy as np

from ..geometry.solvers import _MAX_HALVINGS, RCOND
from ..models.ranging import TINY_RANGE_M
from ..models.track import LinearTrackRanges, anchor_array
from ..types import EstimateStatus, Estimates, RangeLog, RangeSamples
from ..validate import integer, number
from .nls import TrajectoryFit, fit_trajectory

__all__ = ["HEURISTICS", "LABELS", "LocalizationResult", "PruningConfig", "ResidualPruning",
           "RobustMean", "TupleCloud", "drop_schedule", "localize", "percentile_fix", "percentile_ranges",
           "residual_pruning", "robust_mean", "tuple_fixes"]

#: Heuristic names accepted by :func:`localize`, in the order used in tables.
HEURISTICS = ("none", "percentile", "robust_mean", "residual")
#: Display names.
LABELS = {"none": "NLS (no pruning)", "percentile": "5th percentile", "robust_mean": "robust mean",
          "residual": "residual pruning"}


@dataclass(frozen=True)
class PruningConfig:
    """Parameters of the heuristics and of the resolution routine.

    Attributes
    ----------
    percentile
        Percentile of each anchor's ranges (``"percentile"``), in (0, 100).
    tuple_size
        ``k`` of the anchor k-tuples (``"robust_mean"``); 3 = triplets.
    rm_retention, rm_dropout
        Robust mean: fraction of the points kept at the end (0.5) and dropped
        per iteration (0.01, of the initial number).
    min_tuple_spread
        Robust mean: skip k-tuples whose anchors are nearly collinear in plan
        (see module notes).
    res_retention, res_dropout
        Residual pruning: fraction of the measurements kept (0.8--0.9) and
        dropped per iteration (0.005, of the initial number).
    dim
        Resolution routine in 3-D (paper) or 2-D at the node's known height.
    method
        ``"bfgs"`` or ``"least_squares"`` (see :func:`~uwbwb.filters.nls.fit_trajectory`).
    """

    percentile: float = 5.0
    tuple_size: int = 3
    rm_retention: float = 0.5
    rm_dropout: float = 0.01
    min_tuple_spread: float = 0.02
    res_retention: float = 0.9
    res_dropout: float = 0.005
    dim: int = 3
    method: str = "bfgs"

    def __post_init__(self):
        if not 0 < self.percentile < 100:
            raise ValueError(f"percentile must lie in (0, 100), got {self.percentile!r}")
        if int(self.tuple_size) != self.tuple_size or self.tuple_size < 3:
            raise ValueError(f"tuple_size must be an integer >= 3, got {self.tuple_size!r}")
        for name in ("rm_retention", "res_retention"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"{name} must lie in (0, 1], got {getattr(self, name)!r}")
        for name in ("rm_dropout", "res_dropout"):
            if not 0 < getattr(self, name) < 1:
                raise ValueError(f"{name} must lie in (0, 1), got {getattr(self, name)!r}")
        if not 0 <= self.min_tuple_spread < 1:
            raise ValueError(f"min_tuple_spread must lie in [0, 1), got {self.min_tuple_spread!r}")
        if self.dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {self.dim!r}")
        if self.method not in ("bfgs", "least_squares"):
            raise ValueError(f"method must be 'bfgs' or 'least_squares', got {self.method!r}")


def drop_schedule(n0: int, retention: float, dropout: float) -> np.ndarray:
    """Number of items to drop at each iteration.

    ``max(1, round(dropout * n0))`` per iteration until ``ceil(retention * n0)``
    remain (the last step may be smaller). Empty when nothing is to be dropped.
    """
    n0 = integer("n0", n0, minimum=0)
    retention = number("retention", retention, minimum=0.0, maximum=1.0, strict_minimum=True)
    dropout = number("dropout", dropout, minimum=0.0, maximum=1.0, strict_minimum=True)
    target = max(1, math.ceil(retention * n0 - 1e-9))
    step = max(1, int(round(dropout * n0)))
    n_drop = max(0, n0 - target)
    steps = np.full(n_drop // step, step, dtype=int)
    if n_drop % step:
        steps = np.append(steps, n_drop % step)
    return steps


# --------------------------------------------------------------------------- 5th percentile


def percentile_ranges(range_m, q: float = 5.0) -> np.ndarray:
    """Per-anchor ``q``-th percentile of a stationary segment's ranges.

    Parameters
    ----------
    range_m
        Ranges, shape ``(T, n_anchors)``, metres, NaN = missing.
    q
        Percentile in (0, 100) (linear interpolation between order statistics).

    Returns
    -------
    numpy.ndarray
        Shape ``(n_anchors,)``, metres; NaN for an anchor without ranges.
    """
    number("q", q, minimum=0.0, maximum=100.0)
    r = np.asarray(range_m, float)
    if r.ndim != 2:
        raise ValueError(f"range_m must have shape (T, n_anchors), got {r.shape}")
    out = np.full(r.shape[1], np.nan)
    have = np.isfinite(r).any(axis=0)
    if have.any():
        out[have] = np.nanpercentile(r[:, have], q, axis=0)
    return out


def percentile_fix(samples: RangeSamples, anchors, *, q: float = 5.0, dim: int = 3,
                   z_m: float | None = None, method: str = "bfgs") -> tuple[TrajectoryFit, np.ndarray]:
    """Static position from the per-anchor ``q``-th percentile ranges (sec. 2.5.1).

    Returns
    -------
    fit : TrajectoryFit
        Static fit of eq. (1) to one range per anchor (``t0_s``/``t_end_s`` of the segment).
    range_m : numpy.ndarray
        The percentile range per anchor, shape ``(n_anchors,)`` (NaN = no ranges).
    """
    t, R = samples.to_matrix()
    d = percentile_ranges(R, q)
    sel = np.flatnonzero(np.isfinite(d))
    pct = RangeSamples(np.full(sel.size, t[0]), sel, d[sel], samples.anchor_ids)
    fit = fit_trajectory(pct, anchors, dim=dim, static=True, z_m=z_m, method=method)
    return replace(fit, t_end_s=float(t[-1])), d


# --------------------------------------------------------------------------- robust mean


@dataclass(frozen=True)
class TupleCloud:
    """Point-based fixes from every anchor k-tuple at every epoch.

    Attributes
    ----------
    pos_m
        Horizontal fixes, shape ``(N, 2)``, metres (at the node height ``z_m``).
    t_s
        Epoch of each fix, shape ``(N,)``, seconds.
    tuple_index
        Which tuple produced each fix, shape ``(N,)``, into ``tuples``.
    tuples
        Anchor indices of every tuple used, shape ``(C, k)``.
    skipped_tuples
        Tuples left out for a nearly collinear geometry, shape ``(C_skip, k)``.
    n_failed
        Epoch-tuple pairs without a fix (a missing range, singular geometry, no convergence).
    z_m
        Node height used, metres.
    """

    pos_m: np.ndarray
    t_s: np.ndarray
    tuple_index: np.ndarray
    tuples: np.ndarray
    skipped_tuples: np.ndarray
    n_failed: int
    z_m: float

    def __len__(self) -> int:
        return self.t_s.size


def tuple_fixes(range_m, anchors, *, z_m: float, t_s=None, k: int = 3,
                min_tuple_spread: float = 0.02) -> TupleCloud:
    """Localise every epoch from every k-tuple of anchors (the clouds of Fig. 6).

    Parameters
    ----------
    range_m
        Ranges, shape ``(T, n_anchors)``, metres, NaN = missing.
    anchors
        Anchor positions ``(n_anchors, 3)`` or :class:`~uwbwb.Anchors`, metres.
    z_m
        The node's (known) height, metres: each fix is horizontal least squares
        at that height (:func:`uwbwb.geometry.multilaterate` with ``dim=2``),
        since a triplet cannot resolve a 3-D position without a mirror ambiguity.
    t_s
        Epoch times ``(T,)``, seconds (default ``0, 1, 2, ...``).
    k
        Tuple size.
    min_tuple_spread
        Skip tuples that are nearly collinear in plan (see module notes).
    """
    A = anchor_array(anchors)
    R = np.asarray(range_m, float)
    if R.ndim != 2 or R.shape[1] != A.shape[0]:
        raise ValueError(f"range_m must have shape (T, {A.shape[0]}), got {R.shape}")
    T, n = R.shape
    t = np.arange(T, dtype=float) if t_s is None else np.asarray(t_s, float)
    if t.shape != (T,):
        raise ValueError(f"t_s must have shape ({T},), got {t.shape}")
    if not 3 <= k <= n:
        raise ValueError(f"tuple size k={k} must lie in [3, {n}]")
    combos = np.array(list(combinations(range(n), k)), dtype=int)
    xy = A[combos, :2] - A[combos, :2].mean(axis=1, keepdims=True)          # (C, k, 2)
    sv = np.linalg.svd(xy, compute_uv=False)                                 # (C, 2)
    spread_ok = sv[:, 1] > min_tuple_spread * sv[:, 0]
    used, skipped = combos[spread_ok], combos[~spread_ok]
    C = used.shape[0]
    centre = A[:, :2].mean(axis=0)                # the frame multilaterate solves in
    pos, ok = _tuple_gauss_newton(R, A[:, :2] - centre, (A[:, 2] - float(z_m)) ** 2, used, _GN_MAX_ITER, _GN_TOL_M)
    rows = np.flatnonzero(ok)
    return TupleCloud(pos[rows] + centre, t[rows // C], rows % C, used, skipped,
                      int(T * C - rows.size), float(z_m))


#: :func:`uwbwb.geometry.multilaterate`'s defaults, which the tuple fixes follow.
_GN_MAX_ITER, _GN_TOL_M = 50, 1e-9


@numba.njit(cache=True, nogil=True)
def _solve2(a, b, c, g0, g1):
    """``[[a, b], [b, c]]⁻¹ g`` and whether the matrix is regular as :func:`uwbwb.geometry.solvers._solve_psd`
    judges it (largest eigenvalue positive, smallest above ``RCOND`` of it); ``(0, 0)`` when not."""
    lam1 = 0.5 * (a + c) + math.sqrt((0.5 * (a - c)) ** 2 + b * b)
    det = a * c - b * b
    if not (lam1 > 0.0 and det / lam1 > RCOND * lam1):
        return 0.0, 0.0, False
    return (c * g0 - b * g1) / det, (a * g1 - b * g0) / det, True


@numba.njit(cache=True, nogil=True)
def _tuple_gauss_newton(R, A, dz2, used, max_iter, tol_m):
    """Every epoch × tuple of :func:`tuple_fixes` solved as :func:`uwbwb.geometry.multilaterate` (``dim=2``,
    Gauss--Newton with its Newton step and step halving) solves its rows, one row at a time.

    ``R`` ranges (T, n), NaN = missing; ``A`` horizontal anchors (n, 2) centred as multilaterate centres them;
    ``dz2`` squared height differences (n,); ``used`` tuples (C, k). Returns ``pos`` (T·C, 2) in ``A``'s frame
    and ``ok`` (T·C,): a complete tuple, a regular linear start, converged, regular at the solution.
    """
    T, C, k = R.shape[0], used.shape[0], used.shape[1]
    pos = np.full((T * C, 2), np.nan)
    ok = np.zeros(T * C, np.bool_)
    ax, ay, d2, r = np.empty(k), np.empty(k), np.empty(k), np.empty(k)
    for row in range(T * C):
        complete = True
        for j in range(k):
            a = used[row % C, j]
            ax[j], ay[j], d2[j], r[j] = A[a, 0], A[a, 1], dz2[a], R[row // C, a]
            complete = complete and np.isfinite(r[j])
        if not complete:
            continue
        # the closed-form linear start (solvers._linear)
        mx, my, bb = 0.0, 0.0, 0.0
        for j in range(k):
            mx, my, bb = mx + ax[j], my + ay[j], bb + (r[j] * r[j] - d2[j] - (ax[j] * ax[j] + ay[j] * ay[j]))
        mx, my, bb = mx / k, my / k, bb / k
        hxx, hxy, hyy, gx, gy = 0.0, 0.0, 0.0, 0.0, 0.0
        for j in range(k):
            dx, dy = ax[j] - mx, ay[j] - my
            e = r[j] * r[j] - d2[j] - (ax[j] * ax[j] + ay[j] * ay[j]) - bb
            hxx, hxy, hyy, gx, gy = hxx + dx * dx, hxy + dx * dy, hyy + dy * dy, gx + dx * e, gy + dy * e
        sx, sy, regular = _solve2(hxx, hxy, hyy, gx, gy)
        if not regular:
            continue
        x, y = -0.5 * sx, -0.5 * sy
        cost = 0.0
        for j in range(k):
            e = r[j] - max(math.sqrt((x - ax[j]) ** 2 + (y - ay[j]) ** 2 + d2[j]), TINY_RANGE_M)
            cost += e * e
        converged = False
        for _ in range(max_iter):
            # Gauss-Newton normal equations, and the full Hessian with the range model's curvature
            hxx, hxy, hyy, gx, gy, sxx, sxy, syy = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
            for j in range(k):
                rh = max(math.sqrt((x - ax[j]) ** 2 + (y - ay[j]) ** 2 + d2[j]), TINY_RANGE_M)
                jx, jy, e = (x - ax[j]) / rh, (y - ay[j]) / rh, r[j] - rh
                hxx, hxy, hyy, gx, gy = hxx + jx * jx, hxy + jx * jy, hyy + jy * jy, gx + jx * e, gy + jy * e
                f = e / rh
                sxx, sxy, syy = sxx + f * (1.0 - jx * jx), sxy - f * jx * jy, syy + f * (1.0 - jy * jy)
            px, py, regular = _solve2(hxx, hxy, hyy, gx, gy)
            nx, ny, newton_ok = _solve2(hxx - sxx, hxy - sxy, hyy - syy, gx, gy)
            if newton_ok:
                px, py = nx, ny
            if not regular:
                break
            norm = math.sqrt(px * px + py * py)
            if norm < tol_m:
                x, y, converged = x + px, y + py, True
                break
            alpha, accepted = 1.0, False
            for _h in range(_MAX_HALVINGS):
                xt, yt, ct = x + alpha * px, y + alpha * py, 0.0
                for j in range(k):
                    e = r[j] - max(math.sqrt((xt - ax[j]) ** 2 + (yt - ay[j]) ** 2 + d2[j]), TINY_RANGE_M)
                    ct += e * e
                if ct <= cost * (1.0 + 1e-12):
                    x, y, cost, accepted = xt, yt, ct, True
                    break
                alpha *= 0.5
            if not accepted:
                break
            if alpha * norm < tol_m:
                converged = True
                break
        # multilaterate's last check: the geometry matrix regular at the solution
        hxx, hxy, hyy = 0.0, 0.0, 0.0
        for j in range(k):
            rh = max(math.sqrt((x - ax[j]) ** 2 + (y - ay[j]) ** 2 + d2[j]), TINY_RANGE_M)
            jx, jy = (x - ax[j]) / rh, (y - ay[j]) / rh
            hxx, hxy, hyy = hxx + jx * jx, hxy + jx * jy, hyy + jy * jy
        if converged and _solve2(hxx, hxy, hyy, 0.0, 0.0)[2]:
            pos[row, 0], pos[row, 1], ok[row] = x, y, True
    return pos, ok


@dataclass(frozen=True)
class RobustMean:
    """Result of the iterated robust mean (sec. 2.5.2, Fig. 6).

    Attributes
    ----------
    center_m
        Final centroid (static) or line position at ``t0_s`` (moving), shape ``(d,)``.
    vel_mps
        Line velocity, shape ``(d,)`` (zeros for the static centroid).
    t0_s
        Time of ``center_m``.
    kept
        Points retained, bool, shape ``(N,)``.
    history_m
        Centroid after each iteration (first row: all points), shape ``(n_iter + 1, d)``.
    """

    center_m: np.ndarray
    vel_mps: np.ndarray
    t0_s: float
    kept: np.ndarray
    history_m: np.ndarray = field(repr=False)

    @property
    def n_iter(self) -> int:
        return self.history_m.shape[0] - 1


def _line(P, t, t0):
    G = np.column_stack([np.ones_like(t), t - t0])
    coef, *_ = np.linalg.lstsq(G, P, rcond=None)
    return coef[0], coef[1]


def robust_mean(points_m, *, retention: float = 0.5, dropout: float = 0.01, t_s=None) -> RobustMean:
    """Iterated centroid with dropping of the furthest points (sec. 2.5.2).

    Parameters
    ----------
    points_m
        Point cloud, shape ``(N, d)``, metres.
    retention
        Fraction of the points left at the end.
    dropout
        Fraction of the initial points dropped per iteration.
    t_s
        Optional time of each point ``(N,)``: fit a constant-velocity line
        instead of a centroid (moving segments).

    Returns
    -------
    RobustMean
    """
    number("retention", retention, minimum=0.0, maximum=1.0, strict_minimum=True)
    number("dropout", dropout, minimum=0.0, maximum=1.0, strict_minimum=True)
    P = np.asarray(points_m, float)
    if P.ndim != 2 or P.shape[0] == 0:
        raise ValueError(f"points_m must have shape (N, d) with N >= 1, got {P.shape}")
    t = np.zeros(P.shape[0]) if t_s is None else np.asarray(t_s, float)
    if t.shape != (P.shape[0],):
        raise ValueError(f"t_s must have shape ({P.shape[0]},), got {t.shape}")
    t0 = float(t.min())
    steps = drop_schedule(P.shape[0], retention, dropout)
    if t_s is None or not np.ptp(t) > 0:
        kept, history = _static_robust_mean(P, steps)
        return RobustMean(history[-1].copy(), np.zeros(P.shape[1]), t0, kept, history)
    kept = np.ones(P.shape[0], bool)
    c, v = _line(P, t, t0)
    history = [c]
    for n_drop in steps:
        idx = np.flatnonzero(kept)
        dist = np.linalg.norm(P[idx] - (c + np.multiply.outer(t[idx] - t0, v)), axis=1)
        far = idx[np.argpartition(dist, dist.size - n_drop)[dist.size - n_drop:]]
        kept[far] = False
        c, v = _line(P[kept], t[kept], t0)
        history.append(c)
    return RobustMean(c, v, t0, kept, np.array(history))


@numba.njit(cache=True, nogil=True)
def _static_robust_mean(P, steps):
    """:func:`robust_mean`'s loop for a static cloud, compiled: drop the ``steps[i]`` points furthest from the
    centroid of those kept, recompute it. Returns ``(kept (N,), history (len(steps) + 1, d))``; the sums run in
    NumPy's order (``mean(axis=0)`` adds the rows in turn), the points at exactly the cut distance are dropped
    first come, first dropped (NumPy's ``argpartition`` leaves that choice open)."""
    N, d = P.shape
    kept = np.ones(N, np.bool_)
    history = np.zeros((steps.size + 1, d))
    dist, idx = np.empty(N), np.empty(N, np.int64)
    for s in range(steps.size + 1):
        n = 0
        for i in range(N):
            if kept[i]:
                n += 1
                for j in range(d):
                    history[s, j] += P[i, j]
        for j in range(d):
            history[s, j] /= n
        if s == steps.size:
            break
        m = 0
        for i in range(N):
            if kept[i]:
                acc = 0.0
                for j in range(d):
                    acc += (P[i, j] - history[s, j]) ** 2
                dist[m], idx[m], m = math.sqrt(acc), i, m + 1
        cut = np.partition(dist[:m], m - steps[s])[m - steps[s]]
        left = steps[s]
        for q in range(m):                       # beyond the cut, then at it
            if dist[q] > cut:
                kept[idx[q]], left = False, left - 1
        for q in range(m):
            if left > 0 and dist[q] == cut:
                kept[idx[q]], left = False, left - 1
    return kept, history


# --------------------------------------------------------------------------- residual pruning


@dataclass(frozen=True)
class ResidualPruning:
    """Result of residual pruning (sec. 2.5.3).

    Attributes
    ----------
    fit
        The final fit on the retained measurements.
    kept
        Retained measurements, bool, shape ``(M,)`` over the input samples.
    rms_history_m
        Residual RMS of the retained set after each solve, shape ``(n_rounds + 1,)``.
    """

    fit: TrajectoryFit
    kept: np.ndarray
    rms_history_m: np.ndarray = field(repr=False)

    @property
    def n_rounds(self) -> int:
        return self.rms_history_m.size - 1


def residual_pruning(samples: RangeSamples, anchors, *, retention: float = 0.9, dropout: float = 0.005,
                     static: bool = False, dim: int = 3, z_m: float | None = None,
                     method: str = "bfgs", fit: TrajectoryFit | None = None) -> ResidualPruning:
    """Solve, drop the largest absolute residuals, re-solve, until ``retention`` remain.

    Parameters are as in :func:`~uwbwb.filters.nls.fit_trajectory` and
    :class:`PruningConfig`. Each re-solve starts from the previous solution.
    ``fit``: the first solve, :func:`~uwbwb.filters.nls.fit_trajectory` of all ``samples`` with
    these settings, where the caller has it already (plain NLS of the same segment).
    """
    number("retention", retention, minimum=0.0, maximum=1.0, strict_minimum=True)
    number("dropout", dropout, minimum=0.0, maximum=1.0, strict_minimum=True)
    kw = dict(dim=dim, static=static, z_m=z_m, method=method)
    kept = np.ones(len(samples), bool)
    fit = fit_trajectory(samples, anchors, **kw) if fit is None else fit
    model = LinearTrackRanges(anchors, dim, static, z_m if dim == 2 else None)
    history = [fit.residual_rms_m]
    for n_drop in drop_schedule(len(samples), retention, dropout):
        idx = np.flatnonzero(kept)
        r = model.residuals(fit.theta, samples, t0_s=fit.t0_s)[idx]
        worst = idx[np.argsort(np.abs(r), kind="stable")[-n_drop:]]
        kept[worst] = False
        sub = samples.select(kept)
        # warm start: the previous line, moved to the new first sample's time
        x0 = (fit.position_at(sub.t_s[0]), fit.vel_mps)
        fit = fit_trajectory(sub, anchors, x0=x0, **kw)
        history.append(fit.residual_rms_m)
    return ResidualPruning(fit, kept, np.array(history))


# --------------------------------------------------------------------------- pipeline


@dataclass(frozen=True)
class LocalizationResult:
    """Output of the pipeline of Fig. 7 for one segment.

    Attributes
    ----------
    heuristic
        Name from :data:`HEURISTICS`.
    p0_m, vel_mps
        Position at ``t0_s`` and velocity, shape ``(3,)`` each (m, m/s).
    t0_s, t_end_s
        Segment start and end (first and last range), seconds.
    n_used
        Ranges (``"none"``, ``"residual"``), percentile ranges (``"percentile"``)
        or tuple fixes (``"robust_mean"``) that determined the result.
    fit
        The resolution routine's fit (None for ``"robust_mean"``).
    detail
        The heuristic's own result: :class:`ResidualPruning`, the percentile
        ranges ``(n_anchors,)``, or ``(TupleCloud, RobustMean)``.
    """

    heuristic: str
    p0_m: np.ndarray
    vel_mps: np.ndarray
    t0_s: float
    t_end_s: float
    n_used: int
    fit: TrajectoryFit | None = None
    detail: object = field(default=None, repr=False)

    def position_at(self, t_s) -> np.ndarray:
        """``P0 + v (t - t0)``, shape ``(..., 3)``."""
        return self.p0_m + np.multiply.outer(np.asarray(t_s, float) - self.t0_s, self.vel_mps)

    @property
    def label(self) -> str:
        return LABELS[self.heuristic]

    def to_estimates(self, t_s=None, name: str | None = None) -> Estimates:
        """The common result type at epochs ``t_s`` (default: the segment's start and end), labelled
        :attr:`label`: the resolution routine's line and covariance
        (:meth:`TrajectoryFit.to_estimates`), or for ``"robust_mean"`` the 3-D point without a
        covariance."""
        t = np.array([self.t0_s, self.t_end_s] if t_s is None else t_s, float)
        if t.size == 2 and t[0] == t[1]:
            t = t[:1]
        name = name or self.label
        if self.fit is not None:
            return self.fit.to_estimates(t, name)
        return Estimates(t, self.position_at(t), np.full(t.size, EstimateStatus.UPDATED, np.int8), name, None,
                         np.broadcast_to(self.vel_mps, (t.size, 3)))


def localize(ranges: RangeLog | RangeSamples, anchors, heuristic: str = "residual",
             config: PruningConfig = PruningConfig(), *, stationary: bool, z_m: float | None = None,
             fit: TrajectoryFit | None = None) -> LocalizationResult:
    """Heuristic -> resolution routine -> ``(P0, v)`` for one segment (Fig. 7).

    Parameters
    ----------
    ranges
        The segment's ranges (NaN = missing in a :class:`~uwbwb.RangeLog`).
    anchors
        :class:`~uwbwb.Anchors` or ``(n_anchors, 3)`` array, metres.
    heuristic
        One of :data:`HEURISTICS`.
    config
        Heuristic and solver parameters.
    stationary
        The node is at rest during the segment (``v = 0`` is imposed).
    z_m
        The node's height, metres: required with ``config.dim == 2`` and for
        ``"robust_mean"``; the initial-guess height hint otherwise.
    fit
        Plain NLS of this segment with these settings (the ``"none"`` result's :attr:`~LocalizationResult.fit`)
        where the caller has it: ``"none"`` returns it, ``"residual"`` starts from it, instead of solving it again.

    Raises
    ------
    ValueError
        Unknown heuristic, ``"percentile"`` on a moving segment, or too few ranges.
    """
    if heuristic not in HEURISTICS:
        raise ValueError(f"heuristic must be one of {HEURISTICS}, got {heuristic!r}")
    samples = RangeSamples.from_ranges(ranges) if isinstance(ranges, RangeLog) else ranges
    if len(samples) == 0:
        raise ValueError("the segment holds no ranges")
    t0, t_end = float(samples.t_s[0]), float(samples.t_s[-1])
    kw = dict(dim=config.dim, z_m=z_m, method=config.method)
    if heuristic == "none":
        fit = fit_trajectory(samples, anchors, static=stationary, **kw) if fit is None else fit
        return LocalizationResult(heuristic, fit.p0_m, fit.vel_mps, t0, t_end, fit.n_used, fit)
    if heuristic == "percentile":
        if not stationary:
            raise ValueError("the percentile heuristic applies to stationary segments only (sec. 2.5.1)")
        fit, d = percentile_fix(samples, anchors, q=config.percentile, **kw)
        return LocalizationResult(heuristic, fit.p0_m, fit.vel_mps, t0, t_end, fit.n_used, fit, d)
    if heuristic == "residual":
        rp = residual_pruning(samples, anchors, retention=config.res_retention, dropout=config.res_dropout,
                              static=stationary, fit=fit, **kw)
        f = rp.fit
        return LocalizationResult(heuristic, f.position_at(t0), f.vel_mps, t0, t_end, f.n_used, f, rp)
    # robust mean over k-tuples
    if z_m is None:
        raise ValueError("the robust mean localises each tuple at the node's known height: pass z_m")
    t, R = samples.to_matrix()
    cloud = tuple_fixes(R, anchors, z_m=z_m, t_s=t, k=config.tuple_size,
                        min_tuple_spread=config.min_tuple_spread)
    if len(cloud) == 0:
        raise ValueError("no k-tuple produced a fix (too few ranges per epoch)")
    rm = robust_mean(cloud.pos_m, retention=config.rm_retention, dropout=config.rm_dropout,
                     t_s=None if stationary else cloud.t_s)
    c = np.append(rm.center_m, z_m)
    v = np.append(rm.vel_mps, 0.0)
    p0 = c + v * (t0 - rm.t0_s)
    return LocalizationResult(heuristic, p0, v, t0, t_end, int(rm.kept.sum()), None, (cloud, rm))
