"""Section 4.2's 6-D particle filter over ``[X, V]`` for independent ultrasonic beacons (paper 003).

:class:`DopplerPf` moves particles with their velocity plus random acceleration and weights them
by one ΔP at a time as chirps arrive, vectorised over particles *and* independent runs: the model's
pieces (motion, ΔP likelihood, the room as a constraint with restarts, tempering) on the particle
engine :class:`~uwbwb.filters.particle.ParticleFilter` (log-weights normalised with log-sum-exp, ESS,
systematic resampling and roughening with an injected ``rng``). :class:`PfRuns` holds ``R`` runs as an
:class:`~uwbwb.types.EstimatesBatch` (the ``Estimates`` fields batched along a leading run axis).
Part of the :mod:`uwbwb.filters.doppler` package.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from ... import parallel
from ...models.doppler import DopplerModel
from ...models.motion import ReceiverMotion
from ...types import ChirpFlag, ChirpLog, EstimateStatus, EstimatesBatch
from ...validate import integer, number, probability
from ..particle import ParticleFilter
from .frontend import _check, _per_row

__all__ = ["DopplerPf", "PfRuns"]


def _rows(log: ChirpLog, use_ambiguous: bool) -> np.ndarray:
    use = log.measured.copy()
    if not use_ambiguous:
        use &= ~log.has(ChirpFlag.AMBIGUOUS)
    return np.flatnonzero(use)


@dataclass(frozen=True)
class PfRuns(EstimatesBatch):
    """``R`` independent particle-filter runs over one chirp log: an
    :class:`~uwbwb.types.EstimatesBatch` with one batch axis (the run) and 3-D positions.

    Every run shares the update times; :meth:`estimates` gives one run as an
    :class:`~uwbwb.types.Estimates`, :meth:`to_estimates` the plain batch (iterate it for every run).

    Attributes
    ----------
    t_s
        Update times (the chirps used), shape ``(T,)``, seconds.
    pos_m
        Weighted-mean positions, shape ``(R, T, 3)``, metres.
    status
        :class:`~uwbwb.types.EstimateStatus` per run and update, shape ``(R, T)``
        (``UPDATED`` at every chirp used).
    name
        Label of the filter.
    pos_cov_m2
        Weighted covariance of the particles' positions after each update, shape
        ``(R, T, 3, 3)``, m²: the filter's own uncertainty.
    vel_mps
        Weighted-mean velocities, shape ``(R, T, 3)``, m/s.
    info
        Per-run, per-update columns, each shape ``(R, T)``: ``ess`` (effective sample size
        after each update).
    meta
        Per-run and per-log values: ``rows`` (rows of the log used, ``(T,)``),
        ``n_particles``, ``restarts`` (per run, ``(R,)``: times every particle had left the
        room and the run was started again) and ``tempered`` (per run, ``(R,)``: share of
        updates that were tempered, :attr:`DopplerPf.temper_ess`).
    """

    name: str = "PF"
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        p = np.asarray(self.pos_m, float)
        if np.ndim(self.t_s) != 1 or p.ndim != 3 or p.shape[1:] != (np.size(self.t_s), 3):
            raise ValueError(f"PfRuns: t_s (T,) and pos_m (R, T, 3) expected, got {np.shape(self.t_s)} and {p.shape}")
        super().__post_init__()

    @property
    def n_runs(self) -> int:
        return self.pos_m.shape[0]

    @property
    def ess(self) -> np.ndarray:
        """Effective sample size after each update, shape ``(R, T)`` (``info["ess"]``)."""
        return self.info["ess"]

    @property
    def restarts(self) -> np.ndarray:
        """Restarts per run, shape ``(R,)`` (zeros when not recorded)."""
        return np.asarray(self.meta.get("restarts", np.zeros(self.n_runs, int)))

    def at(self, t_s: float) -> np.ndarray:
        """Every run's position estimate at the last update at or before ``t_s``, shape ``(R, 3)``."""
        k = int(np.searchsorted(self.t_s, t_s, side="right")) - 1
        if k < 0:
            raise ValueError(f"no update at or before t = {t_s} s")
        return self.pos_m[:, k]


@dataclass(frozen=True)
class DopplerPf:
    """Section 4.2's particle filter over ``[X, V]``.

    Attributes
    ----------
    model
        Eq 1 and its noise (lagged evaluation, :attr:`DopplerModel.lag`).
    motion
        Random-acceleration motion of the particles.
    n_particles
        Particles per run (≥ 2).
    room_lo_m, room_hi_m
        The room (3 finite values each, ``hi > lo``): initial positions are uniform in it,
        and particles that leave it get zero weight (the receiver is known to be inside the
        room; without this, Doppler ghosts far below the floor attract the particles).
    init_speed_mps
        Initial velocities are uniform in ``[−init_speed, init_speed]³`` (> 0).
    resample_threshold
        Resample when ESS < threshold · K (systematic), in ``[0, 1]``.
    roughening
        Roughening constant applied after each resampling (:func:`~uwbwb.filters.particle.roughen`;
        0 = none, ≥ 0). One ΔP is far narrower than the prior, so without it the first
        updates collapse the particles onto a handful of states.
    outlier_prob
        Probability in ``[0, 1)`` that a used ΔP is an outlier (a chirp given to the wrong
        beacon by the front end), uniform over ``±outlier_window_s``: the likelihood is
        ``(1 − ε) N(ΔP; h, σ²) + ε / (2 · window)``, so one bad chirp cannot wipe out
        every particle.
    outlier_window_s
        Half-width of the outlier density (> 0), seconds of ΔP.
    temper_ess
        Tempered update, as a fraction of ``K`` in ``[0, 1)`` (0 = off): where the full
        likelihood would leave fewer than ``temper_ess · K`` effective particles, the
        update uses ``likelihood^β`` with the largest ``β ≤ 1`` that keeps that many
        (found by bisection per run). A likelihood far sharper than the cloud's
        resolution (1.5 cm pseudo-ranges against a room-sized cloud of a thousand
        particles) would otherwise collapse the cloud onto one wrong particle, after
        which every measurement lands in the outlier floor and the run never recovers;
        tempering gives up that update's excess sharpness instead (an approximation
        on those updates, reported per run in ``PfRuns.meta["tempered"]``). The default
        0.02 is an *assumption*, not tuned: the only evidence for it is one simulated
        lab recording (seed 101, 12 s, 8 runs of 800 particles, in
        ``tests/filters/test_doppler.py``) on which 0.0 loses track with pseudo-ranges
        (95th percentile error over 0.5 m) and 0.02 keeps every run within 0.2 m.
    use_ambiguous
        Also use chirps flagged ``AMBIGUOUS`` (as assigned by the front end).

    Particles of a run that all leave the room are drawn again uniformly in it (the
    run has lost track); ``PfRuns.meta["restarts"]`` counts these per run.
    """

    model: DopplerModel
    motion: ReceiverMotion = ReceiverMotion()
    n_particles: int = 2000
    room_lo_m: tuple = (-3.0, -2.5, -1.2)
    room_hi_m: tuple = (3.0, 2.5, 1.5)
    init_speed_mps: float = 1.5
    resample_threshold: float = 0.5
    roughening: float = 0.2
    outlier_prob: float = 0.05
    outlier_window_s: float = 0.004
    temper_ess: float = 0.02
    use_ambiguous: bool = False
    name: str = "PF"

    def __post_init__(self):
        _check("DopplerPf", "model", self.model, DopplerModel)
        _check("DopplerPf", "motion", self.motion, ReceiverMotion)
        object.__setattr__(self, "n_particles", integer("n_particles", self.n_particles, minimum=2))
        room = []
        for name in ("room_lo_m", "room_hi_m"):
            try:
                v = np.asarray(getattr(self, name), float)
            except (TypeError, ValueError):
                v = np.full(1, np.nan)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be three finite values (m), got {getattr(self, name)!r}")
            room.append(tuple(float(c) for c in v))
        if not np.all(np.asarray(room[1]) > np.asarray(room[0])):
            raise ValueError("room_hi_m must exceed room_lo_m on every axis")
        object.__setattr__(self, "room_lo_m", room[0])
        object.__setattr__(self, "room_hi_m", room[1])
        object.__setattr__(self, "init_speed_mps",
                           number("init_speed_mps", self.init_speed_mps, minimum=0.0, strict_minimum=True))
        object.__setattr__(self, "resample_threshold",
                           probability("resample_threshold", self.resample_threshold, open_interval=False))
        object.__setattr__(self, "roughening", number("roughening", self.roughening, minimum=0.0))
        p = probability("outlier_prob", self.outlier_prob, open_interval=False)
        if p >= 1.0:
            raise ValueError(f"outlier_prob must be a number in [0, 1), got {self.outlier_prob!r}")
        object.__setattr__(self, "outlier_prob", p)
        object.__setattr__(self, "outlier_window_s",
                           number("outlier_window_s", self.outlier_window_s, minimum=0.0, strict_minimum=True))
        t = probability("temper_ess", self.temper_ess, open_interval=False)
        if t >= 1.0:
            raise ValueError(f"temper_ess must be a number in [0, 1), got {self.temper_ess!r}")
        object.__setattr__(self, "temper_ess", t)
        if not isinstance(self.use_ambiguous, (bool, np.bool_)):
            raise ValueError(f"use_ambiguous must be True or False, got {self.use_ambiguous!r}")
        if not isinstance(self.name, str):
            raise ValueError(f"name must be text, got {self.name!r}")

    def run(self, log: ChirpLog, *, n_runs: int = 1, rng: np.random.Generator, ranges_m=None,
            block_runs: int = 100, progress: bool | None = False, workers: int = 1, scheduler=None) -> PfRuns:
        """Filter ``log`` ``n_runs`` times with independent particles.

        Parameters
        ----------
        rng
            Parent generator: block ``j`` of runs draws from child ``j`` of
            ``rng.spawn(n_blocks)``, so the cloud depends on ``rng`` and
            ``block_runs`` only, not on where the blocks run.
        ranges_m
            Optional pseudo-range per row of ``log`` (:func:`clock_pseudo_ranges`); NaN = none.
        block_runs
            Runs filtered together, one task of the sweep (memory: block × K × 6 floats per array).
        workers, scheduler
            Threads in this process, or a Dask scheduler (``"local"``, an address or a
            ``distributed.Client``): where the blocks run (:mod:`uwbwb.parallel`).
        """
        _check("DopplerPf.run", "log", log, ChirpLog)
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        n_runs = integer("n_runs", n_runs, minimum=1)
        block_runs = integer("block_runs", block_runs, minimum=1)
        workers = integer("workers", workers, minimum=1)
        ranges_m = None if ranges_m is None else _per_row("ranges_m", ranges_m, len(log))
        rows = _rows(log, self.use_ambiguous)
        if rows.size == 0:
            raise ValueError("the chirp log has no usable ΔP measurement")
        meas = (log.t_s[rows], log.beacon[rows], log.dp_s[rows], None if ranges_m is None else ranges_m[rows])
        starts = range(0, n_runs, block_runs)
        tasks = [parallel.Task({"start": s, "n_runs": min(block_runs, n_runs - s)}, seed=ss,
                               size=min(block_runs, n_runs - s))
                 for s, ss in zip(starts, parallel.spawn(rng, len(starts)))]
        pos = np.empty((n_runs, rows.size, 3))
        vel = np.empty((n_runs, rows.size, 3))
        ess = np.empty((n_runs, rows.size))
        restarts = np.zeros(n_runs, int)
        tempered = np.zeros(n_runs)
        cov = np.empty((n_runs, rows.size, 3, 3))
        for task, out in parallel.imap(_pf_block, tasks, shared={"pf": self, "meas": meas}, scheduler=scheduler,
                                       workers=workers, progress=progress, desc=self.name, unit="run"):
            sl = slice(task.params["start"], task.params["start"] + task.params["n_runs"])
            pos[sl], vel[sl], ess[sl], restarts[sl], tempered[sl], cov[sl] = out
        status = np.full((n_runs, rows.size), EstimateStatus.UPDATED, np.int8)
        return PfRuns(meas[0], pos, status, self.name, cov, vel, {"ess": ess},
                      {"rows": rows, "n_particles": self.n_particles, "restarts": restarts, "tempered": tempered})

    def _log_likelihood(self, x, chirp):
        """Per-particle log-likelihood of one chirp ``(beacon, ΔP, range or None)``, with the outlier mixture;
        shape ``x.shape[:-1]``. :meth:`DopplerModel.log_likelihood` (its declared twin, bit for bit) compiled over
        the particles, its scalars (σ and the log normalisers) computed by NumPy as there; the mixture in NumPy."""
        beacon, dp_s, range_m = chirp
        m, b = self.model, np.int64(beacon)
        s = m.sigma_dp_s(b)
        if s <= 0:
            raise ValueError("log_likelihood needs sigma_t_s > 0 or sigma_model_mps > 0")
        sr = m.sigma_m
        ll = np.empty(x.shape[:-1])
        _chirp_log_likelihood(np.ascontiguousarray(x, float).reshape(-1, x.shape[-1]), m.beacons.pos_m[b],
                              m.period_s[b], m.lag * m.period_s[b], bool(m.lag), m.v_s_mps, float(dp_s), s,
                              np.log(s * np.sqrt(2 * np.pi)), range_m is not None,
                              np.nan if range_m is None else float(range_m), sr,
                              np.log(sr * np.sqrt(2 * np.pi)) if range_m is not None else np.nan, ll.reshape(-1))
        if self.outlier_prob > 0:
            ll = np.logaddexp(np.log1p(-self.outlier_prob) + ll,
                              np.log(self.outlier_prob / (2 * self.outlier_window_s)))
        return ll

    def engine(self) -> ParticleFilter:
        """This filter on the particle engine: :meth:`ReceiverMotion.propagate`, the ΔP likelihood with its
        outlier mixture, the particles' moments as the estimate, the room as the constraint (with restarts),
        tempering, systematic resampling when ESS < ``resample_threshold`` · K and roughening."""
        return ParticleFilter(self.motion.propagate, self._log_likelihood,
                              estimate=_moments, ess_fraction=self.resample_threshold, roughening=self.roughening,
                              temper_ess=self.temper_ess, constrain=self._keep_in_room, ess_renormalises=False)

    def _keep_in_room(self, x: np.ndarray, logw: np.ndarray, *, rng: np.random.Generator):
        """Zero weight outside the room; a run with no particle left inside is drawn again (a restart)."""
        lo, hi = np.asarray(self.room_lo_m, float), np.asarray(self.room_hi_m, float)
        inside = np.empty(x.shape[:-1], bool)
        _inside_room(np.ascontiguousarray(x).reshape(-1, x.shape[-1]), lo, hi, inside.reshape(-1))
        lost = ~np.any(inside, axis=-1)
        if lost.any():                           # the run lost track: start it again
            x, logw = x.copy(), logw.copy()
            x[lost] = self._draw(rng, int(lost.sum()), lo, hi)
            logw[lost] = -np.log(self.n_particles)
            inside[lost] = True
        return x, np.where(inside, logw, -np.inf), lost

    def _run_block(self, meas, R: int, rng: np.random.Generator):
        """``R`` runs over ``(t, beacon, ΔP, range or None)``: positions, velocities, ESS, restarts, tempered share,
        position covariances."""
        t, b, dp, rng_r = meas
        K = self.n_particles
        x = self._draw(rng, R, np.asarray(self.room_lo_m, float), np.asarray(self.room_hi_m, float))
        chirps = [(b[k], dp[k], rng_r[k] if rng_r is not None and np.isfinite(rng_r[k]) else None)
                  for k in range(t.size)]
        run = self.engine().run(x, np.full((R, K), -np.log(K)), t, chirps, rng=rng, t0_s=t[0])
        pos, vel, cov = run.estimate
        return pos, vel, run.ess, run.restarted.sum(axis=-1), (run.beta < 1.0).sum(axis=-1) / t.size, cov

    def _draw(self, rng, R, lo, hi):
        K = self.n_particles
        return np.concatenate([rng.uniform(lo, hi, (R, K, 3)),
                               rng.uniform(-self.init_speed_mps, self.init_speed_mps, (R, K, 3))], axis=-1)


def _moments(x: np.ndarray, logw: np.ndarray):
    """Weighted mean position ``(R, 3)``, velocity ``(R, 3)`` and position covariance ``(R, 3, 3)`` of
    particles ``(R, K, 6)`` with normalised log-weights ``(R, K)``: ``w = exp(logw)`` (NumPy), the sums compiled
    (declared twin: the einsum and matmul definition, to rounding: the sums are taken in another order)."""
    w = np.exp(logw)
    R = w.shape[0]
    pos, vel, cov = np.empty((R, 3)), np.empty((R, 3)), np.empty((R, 3, 3))
    _moments_rows(np.ascontiguousarray(x, float), np.ascontiguousarray(w), pos, vel, cov)
    return pos, vel, cov


@numba.njit(cache=True, nogil=True)
def _moments_rows(x, w, pos, vel, cov):
    """:func:`_moments` on rows: ``pos = Σ w x[:3]``, ``vel = Σ w x[3:]``, ``cov = Σ (d w) dᵀ`` with
    ``d = x[:3] − pos``, each sum over the particles in their order."""
    R, K = w.shape
    for r in range(R):
        m = np.zeros(6)
        for k in range(K):
            for j in range(6):
                m[j] += w[r, k] * x[r, k, j]
        pos[r], vel[r] = m[:3], m[3:]
        c = np.zeros((3, 3))
        for k in range(K):
            for i in range(3):
                dw = (x[r, k, i] - m[i]) * w[r, k]
                for j in range(3):
                    c[i, j] += dw * (x[r, k, j] - m[j])
        cov[r] = c


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _chirp_log_likelihood(x, T, P, lag_p, lagged, v_s, dp, s, log_norm, ranged, range_m, sr, log_norm_r, out):
    """:meth:`DopplerModel.log_likelihood` of one chirp for particles ``(N, 6)`` (beacon at ``T``, period ``P``,
    ``lag_p = lag · P``): the lagged eq 1 ``h``, ``−½ y² − log_norm`` with ``y = (ΔP − h) / s``, and with ``ranged``
    the pseudo-range term; the operations of the NumPy definition in its order."""
    for n in range(x.shape[0]):
        v0, v1, v2 = x[n, 3], x[n, 4], x[n, 5]
        if lagged:
            d0, d1, d2 = (x[n, 0] - lag_p * v0) - T[0], (x[n, 1] - lag_p * v1) - T[1], (x[n, 2] - lag_p * v2) - T[2]
        else:
            d0, d1, d2 = x[n, 0] - T[0], x[n, 1] - T[1], x[n, 2] - T[2]
        r = (d0 * v0 + d1 * v1 + d2 * v2) / (math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) * v_s)
        y = (dp - P * r / (1.0 - r)) / s
        ll = -0.5 * y * y - log_norm
        if ranged:
            e0, e1, e2 = x[n, 0] - T[0], x[n, 1] - T[1], x[n, 2] - T[2]
            yr = (range_m - math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)) / sr
            ll = ll - 0.5 * yr * yr - log_norm_r
        out[n] = ll


@numba.njit(cache=True, nogil=True)
def _inside_room(x, lo, hi, inside):
    """Per particle ``(N, n_x)``: whether its position ``x[:, :3]`` lies in the box ``[lo, hi]`` (bounds included)."""
    for n in range(x.shape[0]):
        inside[n] = (lo[0] <= x[n, 0] <= hi[0]) and (lo[1] <= x[n, 1] <= hi[1]) and (lo[2] <= x[n, 2] <= hi[2])


def _pf_block(start: int, n_runs: int, seed, pf: DopplerPf, meas):
    """One block of :meth:`DopplerPf.run` (a task of :mod:`uwbwb.parallel`)."""
    return pf._run_block(meas, n_runs, np.random.default_rng(seed))
