"""Monte Carlo maps of the Doppler solution space (paper 003, section 3).

Position–velocity pairs ``(X, V)`` are drawn uniformly in a box (the paper:
``X ∈ [−5, 5]³`` m, ``V ∈ [−3, 3]³`` m/s) and compared with a reference pair
through ``δ = v_s ‖ΔP_ref − ΔP(X, V)‖`` (metres; :meth:`DopplerModel.distance_m`).
Two estimators of the fraction of the 6-D box with ``δ < τ``:

* :func:`brute_force` — plain uniform draws, counted with a compiled kernel
  (numba) that stops evaluating a draw as soon as its partial δ exceeds the
  largest threshold. The count is binomial: exact Clopper–Pearson interval.
* :func:`conditional` — Rao–Blackwellised over ``V``. For a fixed ``X``, eq 1 is
  nearly linear in ``V``: ``v_s ΔP_i = L_i(1 + O(|V|/v_s))`` with
  ``L_i = P_i u_i(X)·V``. The set ``{V : ‖L − b‖ < τ'}`` (``b = v_s ΔP_ref``) is an
  ellipsoid, and with ``τ' = τ + ‖e‖``, ``e_i = (|b_i| + τ)² / (v_s P_i − |b_i| − τ)``
  (a bound on ``|L_i − v_s ΔP_i|`` wherever ``|v_s ΔP_i − b_i| < τ``) it contains
  every ``V`` with exact ``δ < τ``. Per ``X`` the probability
  ``p(X) = P(δ < τ, V ∈ box | X)`` is estimated without bias by drawing ``V``
  uniformly in that ellipsoid and evaluating the *exact* δ:
  ``p̂(X) = vol(ellipsoid) / vol(V box) · mean(1[δ < τ, V ∈ box])``; positions
  whose ellipsoid is empty contribute exactly 0 with no draw at all. The fraction
  is the mean of ``p̂`` over uniform ``X`` (normal interval from its standard error).

Work is split into chunks; chunk ``k`` draws from
``numpy.random.default_rng(SeedSequence(seed).spawn(n_chunks)[k])`` and returns
counts and kept samples, so the result depends only on ``(seed, chunk size,
number of draws)`` — not on how many threads (or machines) run the chunks.
Same seed, same numbers.

With ``ranges=True`` δ also includes pseudo-range residuals
``‖ρ(X) − ρ(X_ref)‖`` (the ranging term of section 5). The set under ``τ`` then
lies in a small region around ``X_ref``: with ``d = X − X_ref`` and
``e_i = ρ_i(X)² − ρ_i(X_ref)² = |d|² + 2 d·(X_ref − T_i)``, every pair of beacons gives
``e_i − e_j = 2 d·(T_j − T_i)`` (linear in ``d``), and ``|ρ_i − ρ_i,ref| < τ`` bounds
``|e_i| < τ (2 ρ_i,ref + τ)``. So the set lies in the slab
``|2 d·(T_j − T_i)| < c_i + c_j`` of every pair; the conditional estimator draws ``X``
uniformly in the parallelepiped of the three slabs with the smallest volume
(:func:`ranging_region`) and weights by its share of the position box.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
from scipy import stats

from . import parallel
from .models.doppler import DopplerModel
from .validate import integer, number, probability

__all__ = ["SearchBox", "FractionEstimate", "GhostSamples", "SamplerResult", "chunk_seeds",
           "brute_force", "conditional", "clopper_pearson", "ranging_region", "DEFAULT_THRESHOLDS_M"]

DEFAULT_THRESHOLDS_M = (0.02, 0.04, 0.06, 0.08, 0.15)


@dataclass(frozen=True)
class SearchBox:
    """Axis-aligned sampling box: ``X ∈ [pos_lo_m, pos_hi_m]³``, ``V ∈ [vel_lo_mps, vel_hi_mps]³``."""

    pos_lo_m: float = -5.0
    pos_hi_m: float = 5.0
    vel_lo_mps: float = -3.0
    vel_hi_mps: float = 3.0

    def __post_init__(self):
        if not (self.pos_hi_m > self.pos_lo_m and self.vel_hi_mps > self.vel_lo_mps):
            raise ValueError(f"empty search box {self}")

    @property
    def vel_volume(self) -> float:
        return (self.vel_hi_mps - self.vel_lo_mps) ** 3


@dataclass(frozen=True)
class FractionEstimate:
    """Fraction of the box with ``δ < threshold_m``, with a confidence interval.

    ``n_draws`` counts the (X, V) pairs whose exact δ was evaluated; ``n_positions``
    the positions drawn (equal to ``n_draws`` for brute force).
    """

    threshold_m: float
    fraction: float
    ci_low: float
    ci_high: float
    confidence: float
    estimator: str
    n_draws: int
    n_positions: int
    n_hits: int


@dataclass(frozen=True)
class GhostSamples:
    """Kept samples: ``pos_m (N, 3)``, ``vel_mps (N, 3)``, ``delta_m (N,)`` and ``weight (N,)``.

    ``weight`` is each sample's share of the box volume fraction: ``1 / n_draws``
    for brute force, ``p̂``-weights for the conditional estimator, so
    ``sum(weight[delta_m < τ])`` estimates the fraction under ``τ`` either way.
    """

    pos_m: np.ndarray
    vel_mps: np.ndarray
    delta_m: np.ndarray
    weight: np.ndarray

    def __len__(self) -> int:
        return int(self.delta_m.size)

    def below(self, threshold_m: float) -> "GhostSamples":
        m = self.delta_m < threshold_m
        return GhostSamples(self.pos_m[m], self.vel_mps[m], self.delta_m[m], self.weight[m])


@dataclass(frozen=True)
class SamplerResult:
    """Fractions per threshold and the kept samples of one sampler run."""

    estimates: tuple[FractionEstimate, ...]
    samples: GhostSamples
    overflow: int = 0
    meta: dict = field(default_factory=dict)

    def estimate(self, threshold_m: float) -> FractionEstimate:
        for e in self.estimates:
            if math.isclose(e.threshold_m, threshold_m):
                return e
        raise KeyError(f"no estimate for threshold {threshold_m} m; have {[e.threshold_m for e in self.estimates]}")


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval for ``k`` successes in ``n`` trials."""
    if n <= 0 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n > 0, got k={k}, n={n}")
    a = 1.0 - confidence
    lo = 0.0 if k == 0 else float(stats.beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(stats.beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def chunk_seeds(seed, n_total: int, chunk_size: int) -> list[tuple[np.random.SeedSequence, int]]:
    """The chunk plan: ``(SeedSequence child, number of draws)`` per chunk, in order."""
    if n_total < 1 or chunk_size < 1:
        raise ValueError(f"need n_total >= 1 and chunk_size >= 1, got {n_total}, {chunk_size}")
    root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    n_chunks = -(-int(n_total) // int(chunk_size))
    sizes = [chunk_size] * (n_chunks - 1) + [int(n_total) - chunk_size * (n_chunks - 1)]
    return list(zip(root.spawn(n_chunks), sizes))


def _reference(model: DopplerModel, ref_pos_m, ref_vel_mps, ranges: bool):
    b = model.v_s_mps * model.delta_p(np.asarray(ref_pos_m, float), np.asarray(ref_vel_mps, float))
    rho = model.pseudo_range_m(np.asarray(ref_pos_m, float)) if ranges else np.zeros(model.n_beacons)
    return b, rho


def ranging_region(model: DopplerModel, ref_pos_m, threshold_m: float) -> tuple[np.ndarray, np.ndarray, float]:
    """A parallelepiped around ``ref_pos_m`` that holds every position with range residual ``< threshold_m``.

    Returns ``(M, half, volume_m3)``: the region is ``{X_ref + d : |M d| < half}``
    (componentwise), ``M`` (3, 3) the rows ``2 (T_j − T_i)`` of the three beacon pairs
    whose slabs enclose the smallest volume (see the module docstring).
    """
    from itertools import combinations

    X = np.asarray(ref_pos_m, float)
    T = model.beacons.pos_m
    c = threshold_m * (2 * np.linalg.norm(X - T, axis=1) + threshold_m)
    pairs = list(combinations(range(len(T)), 2))
    rows = np.array([2 * (T[j] - T[i]) for i, j in pairs])
    half = np.array([c[i] + c[j] for i, j in pairs])
    best = None
    for tri in combinations(range(len(pairs)), 3):
        det = abs(np.linalg.det(rows[list(tri)]))
        if det < 1e-9:
            continue
        vol = 8 * np.prod(half[list(tri)]) / det
        if best is None or vol < best[0]:
            best = (vol, tri)
    if best is None:
        raise ValueError("the beacons are coplanar: ranges do not bound the position")
    tri = list(best[1])
    return rows[tri], half[tri], float(best[0])


def _thresholds(thresholds_m) -> np.ndarray:
    try:
        t = np.sort(np.asarray(thresholds_m, float))
    except (TypeError, ValueError):
        t = np.full(1, np.nan)
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) or np.any(t <= 0):
        raise ValueError(f"thresholds_m must be one or more finite values > 0 (m), got {thresholds_m!r}")
    return t


def _common(model, n, n_name, chunk_size, workers, confidence):
    """Checks shared by both samplers (each raises a ValueError naming the parameter)."""
    if not isinstance(model, DopplerModel):
        raise ValueError(f"model must be a DopplerModel, got {type(model).__name__}")
    integer(n_name, n, minimum=1)
    integer("chunk_size", chunk_size, minimum=1)
    integer("workers", workers, minimum=1)
    probability("confidence", confidence)


def _run_chunks(fn, plan, workers: int, progress: bool, desc: str, scheduler=None):
    """``fn(seed, n)`` for every chunk of ``plan``, results in chunk order (:func:`uwbwb.parallel.imap`)."""
    tasks = [parallel.Task({"chunk": k, "n": n}, seed=s, size=n) for k, (s, n) in enumerate(plan)]
    return [r for _, r in parallel.imap(_chunk_task, tasks, shared={"fn": fn}, scheduler=scheduler, workers=workers,
                                        progress=progress or None, desc=desc, unit="draw")]


def _chunk_task(chunk: int, n: int, seed, fn):
    return fn(seed, n)


# ----------------------------------------------------------------------------------- brute force

@numba.njit(nogil=True, cache=True)
def _brute_kernel(rng, n, T, P, b, rho_ref, v_s, ranges, pos_lo, pos_hi, vel_lo, vel_hi, tau2, keep2,
                  counts, kept):
    """Draw ``n`` pairs (6 uniforms each, X then V), count δ² under each of ``tau2`` (sorted)."""
    nb = T.shape[0]
    nt = tau2.shape[0]
    stop = tau2[nt - 1]
    if keep2 > stop:
        stop = keep2
    n_kept = 0
    n_over = 0
    pw = pos_hi - pos_lo
    vw = vel_hi - vel_lo
    for _ in range(n):
        x0 = pos_lo + pw * rng.random()
        x1 = pos_lo + pw * rng.random()
        x2 = pos_lo + pw * rng.random()
        v0 = vel_lo + vw * rng.random()
        v1 = vel_lo + vw * rng.random()
        v2 = vel_lo + vw * rng.random()
        acc = 0.0
        for i in range(nb):
            d0 = x0 - T[i, 0]
            d1 = x1 - T[i, 1]
            d2 = x2 - T[i, 2]
            rr = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            r = (d0 * v0 + d1 * v1 + d2 * v2) / (rr * v_s)
            g = v_s * P[i] * r / (1.0 - r) - b[i]
            acc += g * g
            if ranges:
                e = rr - rho_ref[i]
                acc += e * e
            if acc >= stop:
                break
        if acc < stop:
            for j in range(nt):
                if acc < tau2[j]:
                    counts[j] += 1
            if acc < keep2:
                if n_kept < kept.shape[0]:
                    kept[n_kept, 0] = x0
                    kept[n_kept, 1] = x1
                    kept[n_kept, 2] = x2
                    kept[n_kept, 3] = v0
                    kept[n_kept, 4] = v1
                    kept[n_kept, 5] = v2
                    kept[n_kept, 6] = math.sqrt(acc)
                    n_kept += 1
                else:
                    n_over += 1
    return n_kept, n_over


def brute_force(model: DopplerModel, ref_pos_m, ref_vel_mps, n_draws: int, *, seed,
                thresholds_m=DEFAULT_THRESHOLDS_M, keep_below_m: float | None = 0.08,
                box: SearchBox = SearchBox(), ranges: bool = False, chunk_size: int = 1 << 23,
                max_kept_per_chunk: int = 1 << 16, workers: int = 2, confidence: float = 0.95,
                progress: bool = False, scheduler=None) -> SamplerResult:
    """Fraction of the box with ``δ < τ`` for each threshold, by uniform sampling.

    Parameters
    ----------
    model
        Beacons, periods and speed of sound (eq 1 evaluated instantaneously, as in section 3).
    ref_pos_m, ref_vel_mps
        The reference pair, shape ``(3,)`` each.
    n_draws
        Number of uniform (X, V) pairs.
    seed
        Integer or :class:`numpy.random.SeedSequence`; chunk ``k`` uses its ``k``-th child.
    thresholds_m
        δ thresholds (metres) to count.
    keep_below_m
        Samples with δ below this are returned (None: none kept). Each chunk keeps at
        most ``max_kept_per_chunk``; any excess is counted in ``overflow``, never silently lost.
    ranges
        Include pseudo-range residuals in δ (section 5's ranging term).
    chunk_size
        Draws per chunk (the unit of seeding and of parallel work).
    workers
        Threads running chunks (the kernel releases the GIL) when ``scheduler`` is None.
    scheduler
        None (this process), ``"local"``, a Dask scheduler address or a
        ``distributed.Client``: where the chunks run (:mod:`uwbwb.parallel`). Each
        chunk sends back its counts and kept samples only; the numbers do not
        depend on where it ran.

    Returns
    -------
    SamplerResult
        Estimator ``"brute force"``; Clopper–Pearson intervals.
    """
    _common(model, n_draws, "n_draws", chunk_size, workers, confidence)
    tau = _thresholds(thresholds_m)
    keep = 0.0 if keep_below_m is None else number("keep_below_m", keep_below_m, minimum=0.0)
    max_kept_per_chunk = integer("max_kept_per_chunk", max_kept_per_chunk, minimum=0)
    b, rho = _reference(model, ref_pos_m, ref_vel_mps, ranges)
    T = np.ascontiguousarray(model.beacons.pos_m)
    P = np.ascontiguousarray(model.period_s)
    plan = chunk_seeds(seed, n_draws, chunk_size)
    cap = int(max_kept_per_chunk) if keep > 0 else 0

    def run(ss, n):
        counts = np.zeros(tau.size, np.int64)
        kept = np.empty((cap, 7))
        n_kept, n_over = _brute_kernel(np.random.default_rng(ss), n, T, P, b, rho, model.v_s_mps, ranges,
                                       box.pos_lo_m, box.pos_hi_m, box.vel_lo_mps, box.vel_hi_mps,
                                       tau * tau, keep * keep, counts, kept)
        return counts, kept[:n_kept].copy(), n_over

    results = _run_chunks(run, plan, workers, progress, "brute force", scheduler)
    counts = np.sum([r[0] for r in results], axis=0)
    kept = np.concatenate([r[1] for r in results]) if results else np.empty((0, 7))
    overflow = int(sum(r[2] for r in results))
    n = int(n_draws)
    estimates = tuple(FractionEstimate(float(t), int(c) / n, *clopper_pearson(int(c), n, confidence), confidence,
                                       "brute force", n, n, int(c)) for t, c in zip(tau, counts))
    samples = GhostSamples(kept[:, :3], kept[:, 3:6], kept[:, 6], np.full(len(kept), 1.0 / n))
    return SamplerResult(estimates, samples, overflow, {"seed": seed, "chunk_size": chunk_size, "ranges": ranges})


# ----------------------------------------------------------------------------------- conditional

def _conditional_chunk(model: DopplerModel, b, rho_ref, ranges, box: SearchBox, tau, draws, rng, n, region):
    T, P, v_s = model.beacons.pos_m, model.period_s, model.v_s_mps
    tau_max = tau[-1]
    if region is None:
        X = rng.uniform(box.pos_lo_m, box.pos_hi_m, (n, 3))
        w_x = 1.0
    else:                                      # uniform in the parallelepiped that holds the whole set
        centre, M, half, volume = region
        X = centre + np.linalg.solve(M, (rng.uniform(-1.0, 1.0, (n, 3)) * half).T).T
        w_x = volume / (box.pos_hi_m - box.pos_lo_m) ** 3
    e = (np.abs(b) + tau_max) ** 2 / (v_s * P - np.abs(b) - tau_max)
    L, v_star, r2, rr2 = (np.empty((n, 3, 3)), np.empty((n, 3)), np.empty(n), np.empty(n))
    active = np.empty(n, np.bool_)
    _ellipsoids(X, T, P, b, rho_ref, ranges, tau_max, float(np.linalg.norm(e)), box.pos_lo_m, box.pos_hi_m,
                L, v_star, r2, rr2, active)
    p_hat = np.zeros((n, tau.size))
    ia = np.flatnonzero(active)
    if ia.size == 0:
        return p_hat, np.empty((0, 8)), 0
    L = L[ia]                                                            # M = L Lᵀ
    r_e = np.sqrt(r2[ia])
    vol = 4.0 / 3.0 * np.pi * r_e ** 3 / np.prod(np.diagonal(L, axis1=1, axis2=2), axis=-1)
    g = rng.standard_normal((ia.size, draws, 3))
    w = g / np.linalg.norm(g, axis=-1, keepdims=True) * rng.random((ia.size, draws, 1)) ** (1.0 / 3.0)
    # V = V* + r L⁻ᵀ w  gives (V − V*)ᵀ M (V − V*) = r² |w|²
    Lt = np.swapaxes(L, 1, 2)
    dv = np.linalg.solve(Lt[:, None], w[..., None])[..., 0]
    V = v_star[ia, None, :] + r_e[:, None, None] * dv                    # (na, draws, 3)
    Xa = np.broadcast_to(X[ia, None, :], V.shape)
    dp = model.delta_p(Xa, V)
    delta2 = np.sum((v_s * dp - b) ** 2, axis=-1) + rr2[ia, None]
    inside = np.all((V >= box.vel_lo_mps) & (V <= box.vel_hi_mps), axis=-1)
    weight = w_x * vol / box.vel_volume / draws                          # per draw
    hits = inside[..., None] & (delta2[..., None] < tau * tau)           # (na, draws, nt)
    p_hat[ia] = weight[:, None] * hits.sum(axis=1)
    keep = hits[..., -1]
    kept = np.concatenate([Xa[keep], V[keep], np.sqrt(delta2[keep])[:, None],
                           np.broadcast_to(weight[:, None], keep.shape)[keep][:, None]], axis=1)
    return p_hat, kept, ia.size * draws


@numba.njit(nogil=True, cache=True)
def _ellipsoids(X, T, P, b, rho_ref, ranges, tau_max, e_norm, pos_lo, pos_hi, L, v_star, r2, rr2, active):
    """Per position ``X[n]`` (rows ``(n, 3)``) the velocity ellipsoid of :func:`conditional` (module docstring).

    With ``d_i = X − T_i``, ``ρ_i = ‖d_i‖`` and the rows ``A_i = P_i d_i / ρ_i`` (eq 1's linear part is ``A V``):
    ``rr2`` the range part ``Σ (ρ_i − ρ_ref,i)²`` (0 without ``ranges``), ``M = AᵀA`` as its Cholesky factor
    ``L`` (lower, ``M = L Lᵀ``), the centre ``v* = M⁻¹ Aᵀb``, the squared radius
    ``r2 = (√max(τ² − rr2, 0) + ‖e‖)² − ‖A v* − b‖²`` and ``active`` where the ellipsoid may hold a draw
    (``rr2 < τ²``, ``r2 > 0``, ``X`` in the position box). A position whose ``M`` is not positive definite
    gets NaN (not active)."""
    nb = T.shape[0]
    A = np.empty((nb, 3))
    rho = np.empty(nb)
    c = np.empty(3)
    y = np.empty(3)
    tau2 = tau_max * tau_max
    for n in range(X.shape[0]):
        for i in range(nb):
            d0, d1, d2 = X[n, 0] - T[i, 0], X[n, 1] - T[i, 1], X[n, 2] - T[i, 2]
            rho[i] = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            A[i, 0] = P[i] * d0 / rho[i]
            A[i, 1] = P[i] * d1 / rho[i]
            A[i, 2] = P[i] * d2 / rho[i]
        acc = 0.0
        if ranges:
            for i in range(nb):
                acc += (rho[i] - rho_ref[i]) ** 2
        rr2[n] = acc
        radius = math.sqrt(max(tau2 - acc, 0.0)) + e_norm
        Ln = L[n]
        for p in range(3):                    # M = AᵀA and Aᵀb, then M = L Lᵀ (Cholesky, row by row)
            s = 0.0
            for i in range(nb):
                s += A[i, p] * b[i]
            c[p] = s
            for q in range(p + 1):
                s = 0.0
                for i in range(nb):
                    s += A[i, p] * A[i, q]
                for k in range(q):
                    s -= Ln[p, k] * Ln[q, k]
                Ln[p, q] = math.sqrt(s) if p == q and s > 0 else (s / Ln[q, q] if p != q else np.nan)
            for q in range(p + 1, 3):
                Ln[p, q] = 0.0
        for p in range(3):                    # L y = c, then Lᵀ v* = y
            s = c[p]
            for k in range(p):
                s -= Ln[p, k] * y[k]
            y[p] = s / Ln[p, p]
        for p in range(2, -1, -1):
            s = y[p]
            for k in range(p + 1, 3):
                s -= Ln[k, p] * v_star[n, k]
            v_star[n, p] = s / Ln[p, p]
        res2 = 0.0
        for i in range(nb):
            g = A[i, 0] * v_star[n, 0] + A[i, 1] * v_star[n, 1] + A[i, 2] * v_star[n, 2] - b[i]
            res2 += g * g
        r2[n] = radius * radius - res2
        in_box = True
        for k in range(3):
            in_box = in_box and pos_lo <= X[n, k] <= pos_hi
        active[n] = acc < tau2 and r2[n] > 0 and in_box


def conditional(model: DopplerModel, ref_pos_m, ref_vel_mps, n_positions: int, *, seed,
                thresholds_m=DEFAULT_THRESHOLDS_M, draws_per_position: int = 8, box: SearchBox = SearchBox(),
                ranges: bool = False, chunk_size: int = 1 << 15, workers: int = 2, confidence: float = 0.95,
                progress: bool = False, scheduler=None) -> SamplerResult:
    """Fraction of the box with ``δ < τ``, Rao–Blackwellised over the velocity (see module docstring).

    Parameters
    ----------
    n_positions
        Number of uniform positions X (in the position box; with ``ranges``, in the
        region of :func:`ranging_region`). Each position whose velocity ellipsoid is not
        empty gets ``draws_per_position`` exact δ evaluations.
    seed, chunk_size, workers, scheduler, ranges, box
        As in :func:`brute_force` (chunks count positions).

    Returns
    -------
    SamplerResult
        Estimator ``"conditional"``; normal intervals from the standard error of the
        per-position estimates (NaN when fewer than 10 positions contribute). Kept samples are every draw with δ below the largest
        threshold, weighted so that ``sum(weight)`` estimates the fraction.
    """
    _common(model, n_positions, "n_positions", chunk_size, workers, confidence)
    tau = _thresholds(thresholds_m)
    integer("draws_per_position", draws_per_position, minimum=1)
    b, rho = _reference(model, ref_pos_m, ref_vel_mps, ranges)
    if np.any(model.v_s_mps * model.period_s <= np.abs(b) + tau[-1]):
        raise ValueError("threshold too large for the linear bound of the conditional estimator")
    plan = chunk_seeds(seed, n_positions, chunk_size)
    region = None
    if ranges:
        region = (np.asarray(ref_pos_m, float), *ranging_region(model, ref_pos_m, tau[-1]))

    def run(ss, n):
        p_hat, kept, n_eval = _conditional_chunk(model, b, rho, ranges, box, tau, draws_per_position,
                                                 np.random.default_rng(ss), n, region)
        return p_hat.sum(axis=0), (p_hat ** 2).sum(axis=0), n_eval, kept, np.count_nonzero(p_hat, axis=0)

    results = _run_chunks(run, plan, workers, progress, "conditional", scheduler)
    s1 = np.sum([r[0] for r in results], axis=0)
    s2 = np.sum([r[1] for r in results], axis=0)
    kept = np.concatenate([r[3] for r in results])
    n = int(n_positions)
    mean = s1 / n
    var = np.clip(s2 / n - mean ** 2, 0.0, None) * n / max(n - 1, 1)
    half = stats.norm.ppf(0.5 + confidence / 2) * np.sqrt(var / n)
    contributing = np.sum([r[4] for r in results], axis=0)
    # the normal interval needs enough contributing positions; below 10 it is not given (NaN)
    half = np.where(contributing >= 10, half, np.nan)
    n_draws = int(sum(r[2] for r in results))
    hits = [int(np.count_nonzero(kept[:, 6] < t)) for t in tau]
    estimates = tuple(FractionEstimate(float(t), float(m), float(max(m - h, 0.0)) if np.isfinite(h) else np.nan,
                                       float(m + h), confidence, "conditional", n_draws, n, k)
                      for t, m, h, k in zip(tau, mean, half, hits))
    samples = GhostSamples(kept[:, :3], kept[:, 3:6], kept[:, 6], kept[:, 7] / n)
    return SamplerResult(estimates, samples, 0,
                         {"seed": seed, "chunk_size": chunk_size, "ranges": ranges,
                          "position region volume (m³)": None if region is None else region[3]})
