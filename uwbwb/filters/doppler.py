"""Position and velocity from Doppler period shifts of independent beacons (paper 003, section 4).

* :func:`assign_chirps` — the receiver's front end: assigns detected chirps to
  beacons by their periodicity and measures ΔP per period (section 2).
* :func:`clock_pseudo_ranges` — pseudo-ranges from a model of the beacons'
  transmission clocks (the ranging term proposed in section 5).
* :class:`DopplerPf` — the 6-D particle filter of section 4.2: particles move
  with their velocity plus random acceleration, one ΔP at a time as chirps
  arrive; vectorised over particles *and* independent runs.
* :class:`ScaatMhEkf` — the Kalman filter of section 4.1: single constraint at a
  time (SCAAT) EKF on eq 1, one hypothesis per plausible source of an ambiguous
  chirp (including noise), pruned by likelihood. Built on
  :class:`uwbwb.filters.ekf.Ekf` with :class:`DopplerMeasurement` (the EKF's view
  of :class:`~uwbwb.models.doppler.DopplerModel`).

Both filters take the same :class:`~uwbwb.models.doppler.DopplerModel` (eq 1,
noise) and :class:`~uwbwb.models.doppler.ReceiverMotion`, and return
:class:`uwbwb.types.Estimates` (one per run).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import parallel
from ..models.doppler import DopplerModel, ReceiverMotion
from ..types import ChirpFlag, ChirpLog, EstimateStatus, Estimates
from ..validate import integer, number, probability
from . import kalman
from .ekf import Ekf, Linearisation
from .kalman import Gaussian
from .particle import effective_sample_size, normalise_log_weights, resample, roughen

__all__ = ["assign_chirps", "clock_pseudo_ranges", "DopplerMeasurement", "DopplerPf", "PfRuns", "ScaatMhEkf"]


def _check_model(owner: str, model) -> None:
    if not isinstance(model, DopplerModel):
        raise ValueError(f"{owner}: model must be a DopplerModel, got {type(model).__name__}")


def _check_motion(owner: str, motion) -> None:
    if not isinstance(motion, ReceiverMotion):
        raise ValueError(f"{owner}: motion must be a ReceiverMotion, got {type(motion).__name__}")


def _check_log(owner: str, log) -> None:
    if not isinstance(log, ChirpLog):
        raise ValueError(f"{owner}: log must be a ChirpLog, got {type(log).__name__}")


def _per_row(name: str, values, n: int) -> np.ndarray:
    """An optional per-row array of ``log`` (pseudo-ranges): shape ``(n,)``, finite or NaN, ≥ 0."""
    a = np.asarray(values, float)
    if a.shape != (n,):
        raise ValueError(f"{name} must have one value per row of the chirp log, shape ({n},), got {a.shape}")
    if np.any(np.isinf(a)) or np.any(a[np.isfinite(a)] < 0):
        raise ValueError(f"{name} must be >= 0 (NaN: none), got an infinite or negative value")
    return a


# ------------------------------------------------------------------------------------ front end

def assign_chirps(t_s, model: DopplerModel, *, window_s: float = 0.004, max_gap: int = 3) -> ChirpLog:
    """Assign detections to beacons by periodicity and measure ΔP (section 2).

    A detection at ``t`` fits beacon ``i`` (whose last assigned chirp arrived at
    ``t_i``) when ``t − t_i`` is close to ``k P_i`` for some ``k = 1 … max_gap``:
    ``ΔP = (t − t_i)/k − P_i`` with ``|ΔP| ≤ window_s`` (``k > 1``: chirps were missed,
    flag ``GAP``). Several fits: the smallest ``|ΔP|`` wins (flag ``AMBIGUOUS``). No
    fit: the detection may start a train — if an earlier unassigned detection lies
    ``P_j ± window_s`` before it for a beacon ``j`` that is not locked, both become
    beacon ``j``'s (flag ``LOCK``, no ΔP); otherwise the detection is ``UNASSIGNED``.
    A beacon unheard for more than ``max_gap + ½`` periods is unlocked.

    Parameters
    ----------
    t_s
        Arrival times, shape ``(N,)``, strictly increasing.
    model
        Supplies the nominal periods (and beacon ids).
    window_s
        Largest period shift accepted (``P v / v_s``: 3 ms at 2 m/s for P ≈ 0.5 s).
    max_gap
        Largest number of periods bridged over missed chirps.
    """
    _check_model("assign_chirps", model)
    window_s = number("window_s", window_s, minimum=0.0, strict_minimum=True)
    max_gap = integer("max_gap", max_gap, minimum=1)
    t_s = np.asarray(t_s, float)
    if t_s.ndim != 1 or not np.all(np.isfinite(t_s)) or np.any(np.diff(t_s) <= 0):
        raise ValueError("t_s must be a 1-D array of finite, strictly increasing arrival times")
    P = model.period_s
    n = P.size
    last = np.full(n, np.nan)
    beacon = np.full(t_s.size, -1)
    dp = np.full(t_s.size, np.nan)
    flags = np.zeros(t_s.size, np.int8)
    pending: list[int] = []
    for r, t in enumerate(t_s):
        stale = np.isfinite(last) & (t - last > (max_gap + 0.5) * P)
        last[stale] = np.nan
        gap = t - last
        k = np.rint(gap / P)
        shift = gap / np.where(k > 0, k, np.nan) - P
        fits = np.isfinite(last) & (k >= 1) & (k <= max_gap) & (np.abs(shift) <= window_s)
        if fits.any():
            cand = np.flatnonzero(fits)
            i = int(cand[np.argmin(np.abs(shift[cand]))])
            beacon[r], dp[r], last[i] = i, shift[i], t
            flags[r] |= (ChirpFlag.GAP if k[i] > 1 else 0) | (ChirpFlag.AMBIGUOUS if cand.size > 1 else 0)
            continue
        pending = [p for p in pending if t - t_s[p] <= P.max() + window_s]
        best = None
        for p in pending:
            off = np.abs(t - t_s[p] - P)
            off[np.isfinite(last)] = np.inf
            j = int(np.argmin(off))
            if off[j] <= window_s and (best is None or off[j] < best[2]):
                best = (p, j, off[j])
        if best is None:
            pending.append(r)
            flags[r] |= ChirpFlag.UNASSIGNED
            continue
        p, j, _ = best
        pending.remove(p)
        beacon[p] = beacon[r] = j
        flags[p] = ChirpFlag.LOCK
        flags[r] = ChirpFlag.LOCK
        last[j] = t
    return ChirpLog(t_s, beacon, dp, flags, model.beacons.ids)


def clock_pseudo_ranges(log: ChirpLog, model: DopplerModel, phase_s) -> np.ndarray:
    """Pseudo-ranges ``v_s (t − t_emit)`` from a beacon-clock model (section 5), metres.

    ``t_emit`` is the emission of the assigned beacon that the clock model (phase
    ``phase_s[i]`` and period ``P_i``) places last before the arrival (flights last
    tens of milliseconds, far less than a period). NaN where the row has no beacon.
    """
    _check_log("clock_pseudo_ranges", log)
    _check_model("clock_pseudo_ranges", model)
    phase = np.asarray(phase_s, float)
    if phase.shape != (model.n_beacons,) or not np.all(np.isfinite(phase)):
        raise ValueError(f"phase_s must hold one finite phase per beacon, shape ({model.n_beacons},), "
                         f"got {phase.shape}")
    out = np.full(len(log), np.nan)
    ok = log.beacon >= 0
    i = log.beacon[ok]
    P = model.period_s[i]
    t_emit = phase[i] + np.floor((log.t_s[ok] - phase[i]) / P) * P
    out[ok] = model.v_s_mps * (log.t_s[ok] - t_emit)
    return out


def _rows(log: ChirpLog, use_ambiguous: bool) -> np.ndarray:
    use = log.measured.copy()
    if not use_ambiguous:
        use &= ~log.has(ChirpFlag.AMBIGUOUS)
    return np.flatnonzero(use)


# ------------------------------------------------------------------------------------ particle filter

@dataclass(frozen=True)
class PfRuns:
    """Several independent particle-filter runs over one chirp log.

    Attributes
    ----------
    t_s
        Update times (the chirps used), shape ``(T,)``.
    pos_m, vel_mps
        Weighted-mean estimates, shape ``(R, T, 3)``.
    ess
        Effective sample size after each update, shape ``(R, T)``.
    name
        Label of the filter.
    meta
        ``rows`` (rows of the log used), ``n_particles``, ``restarts`` (per run: times
        every particle had left the room and the run was started again) and ``tempered``
        (per run: share of updates that were tempered, :attr:`DopplerPf.temper_ess`) and
        ``pos_cov_m2`` (weighted covariance of the particles' positions after each
        update, shape ``(R, T, 3, 3)``, m²: the filter's own uncertainty).
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    vel_mps: np.ndarray
    ess: np.ndarray
    name: str = "PF"
    meta: dict = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return self.pos_m.shape[0]

    def estimates(self, run: int = 0) -> Estimates:
        """Run ``run`` as the common :class:`~uwbwb.types.Estimates` (status UPDATED at every chirp used)."""
        return Estimates(self.t_s, self.pos_m[run], np.full(self.t_s.size, EstimateStatus.UPDATED, np.int8),
                         self.name, vel_mps=self.vel_mps[run], info={"ess": self.ess[run]})

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
        _check_model("DopplerPf", self.model)
        _check_motion("DopplerPf", self.motion)
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
        _check_log("DopplerPf.run", log)
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
        return PfRuns(meas[0], pos, vel, ess, self.name, {"rows": rows, "n_particles": self.n_particles,
                                                          "restarts": restarts, "tempered": tempered,
                                                          "pos_cov_m2": cov})

    def _log_likelihood(self, x, beacon, dp_s, range_m):
        """Per-particle log-likelihood of one chirp, with the outlier mixture; shape ``x.shape[:-1]``."""
        ll = self.model.log_likelihood(x[..., :3], x[..., 3:], np.int64(beacon), dp_s, range_m=range_m)
        if self.outlier_prob > 0:
            ll = np.logaddexp(np.log1p(-self.outlier_prob) + ll,
                              np.log(self.outlier_prob / (2 * self.outlier_window_s)))
        return ll

    def _tempering(self, logw: np.ndarray, ll: np.ndarray) -> np.ndarray:
        """Per run, the largest ``β ≤ 1`` with ``ESS(logw + β ll) ≥ temper_ess · K`` (1 where the full update
        keeps that many; 16 bisection steps otherwise). ``logw`` (R, K) may hold −inf; ``ll`` is finite."""
        R, K = logw.shape
        beta = np.ones(R)
        if self.temper_ess <= 0:
            return beta
        target = self.temper_ess * K
        need = effective_sample_size(logw + ll) < target
        if need.any():
            lo, hi = np.zeros(int(need.sum())), np.ones(int(need.sum()))
            lw, l = logw[need], ll[need]
            for _ in range(16):
                mid = 0.5 * (lo + hi)
                ok = effective_sample_size(lw + mid[:, None] * l) >= target
                lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
            beta[need] = lo
        return beta

    def _run_block(self, meas, R: int, rng: np.random.Generator):
        """``R`` runs over ``(t, beacon, ΔP, range or None)``: positions, velocities, ESS, restarts, tempered share,
        position covariances."""
        t, b, dp, rng_r = meas
        K = self.n_particles
        lo, hi = np.asarray(self.room_lo_m, float), np.asarray(self.room_hi_m, float)
        pos = np.empty((R, t.size, 3))
        vel = np.empty((R, t.size, 3))
        ess = np.empty((R, t.size))
        cov = np.empty((R, t.size, 3, 3))
        restarts = np.zeros(R, int)
        n_tempered = np.zeros(R)
        x = self._draw(rng, R, lo, hi)
        logw = np.full((R, K), -np.log(K))
        t_prev = t[0]
        for k in range(t.size):
            x = self.motion.propagate(x, t[k] - t_prev, rng=rng)
            t_prev = t[k]
            r_k = None
            if rng_r is not None and np.isfinite(rng_r[k]):
                r_k = rng_r[k]
            inside = np.all((x[..., :3] >= lo) & (x[..., :3] <= hi), axis=-1)
            lost = ~np.any(inside, axis=-1)
            if lost.any():                           # the run lost track: start it again
                x[lost] = self._draw(rng, int(lost.sum()), lo, hi)
                logw[lost] = -np.log(K)
                inside[lost] = True
                restarts += lost
            ll = self._log_likelihood(x, b[k], dp[k], r_k)
            prior = np.where(inside, logw, -np.inf)
            beta = self._tempering(prior, ll)
            n_tempered += beta < 1.0
            logw, _ = normalise_log_weights(prior + beta[:, None] * ll)
            w = np.exp(logw)
            pos[:, k] = np.einsum("rk,rkn->rn", w, x[..., :3])
            vel[:, k] = np.einsum("rk,rkn->rn", w, x[..., 3:])
            d = x[..., :3] - pos[:, k, None, :]
            cov[:, k] = np.swapaxes(d * w[..., None], 1, 2) @ d
            ess[:, k] = 1.0 / np.sum(w * w, axis=-1)
            x, logw, resampled = resample(x, logw, rng=rng, threshold=self.resample_threshold)
            if self.roughening > 0 and resampled.any():
                x = roughen(x, rng=rng, k=self.roughening, rows=resampled)
        return pos, vel, ess, restarts, n_tempered / t.size, cov

    def _draw(self, rng, R, lo, hi):
        K = self.n_particles
        return np.concatenate([rng.uniform(lo, hi, (R, K, 3)),
                               rng.uniform(-self.init_speed_mps, self.init_speed_mps, (R, K, 3))], axis=-1)


def _pf_block(start: int, n_runs: int, seed, pf: DopplerPf, meas):
    """One block of :meth:`DopplerPf.run` (a task of :mod:`uwbwb.parallel`)."""
    return pf._run_block(meas, n_runs, np.random.default_rng(seed))


# ------------------------------------------------------------------------------------ SCAAT MH-EKF

@dataclass(frozen=True)
class DopplerMeasurement:
    """One chirp of :class:`~uwbwb.models.doppler.DopplerModel` as :class:`~uwbwb.filters.ekf.Ekf` sees it.

    ``measurement`` is ``(beacon, dp_s, range_m)``: the beacon index (−1: none), the
    measured ΔP (NaN: none) and a pseudo-range (NaN: none). The rows, predictions,
    Jacobians and noise come from :meth:`DopplerModel.measurement_rows` (lagged eq 1).
    """

    model: DopplerModel

    def __post_init__(self):
        _check_model("DopplerMeasurement", self.model)

    def linearise(self, x: np.ndarray, measurement) -> Linearisation | None:
        """:class:`Linearisation` at state ``x = [X, V]`` (6,); None when nothing usable was measured."""
        rows = self.model.measurement_rows(x, measurement)
        return None if rows is None else Linearisation(*rows)


@dataclass
class _Hypothesis:
    state: Gaussian
    t_s: float
    last_s: np.ndarray            # last assigned arrival per beacon (NaN: not locked)
    logw: float
    assigned: bool = False


@dataclass(frozen=True)
class ScaatMhEkf:
    """Section 4.1's Kalman filter: SCAAT EKF on eq 1 with multiple hypotheses per ambiguous chirp.

    Every detection is one constraint. For each live hypothesis, the detection may come
    from any beacon whose train it fits (as in :func:`assign_chirps`, but with that
    hypothesis' own assignment history) or be noise; each possibility becomes a child
    hypothesis. A child that assigns the chirp to beacon ``i`` after ``k`` periods is
    updated by :meth:`Ekf.update` with ``ΔP = (t − t_i)/k − P_i`` and weighted by
    ``p_d (1 − p_d)^(k−1) N(ΔP; h(x⁻), S)``; the noise child keeps its state and is
    weighted by the clutter density ``spurious_rate_hz`` (per second of arrival time,
    the unit of ΔP). Children below ``prune_ratio`` of the best are dropped and at most
    ``max_hypotheses`` kept. Beacon trains are started from the front end's ``LOCK``
    rows. The estimate is the most probable hypothesis' mean.

    Attributes
    ----------
    model, motion
        As for :class:`DopplerPf`.
    p_detect
        Probability that a chirp is detected.
    spurious_rate_hz
        Rate of spurious detections (clutter).
    window_s, max_gap
        Gates of the association, as in :func:`assign_chirps`.
    max_hypotheses, prune_ratio
        Pruning.
    """

    model: DopplerModel
    motion: ReceiverMotion = ReceiverMotion()
    p_detect: float = 0.95
    spurious_rate_hz: float = 0.5
    window_s: float = 0.004
    max_gap: int = 3
    max_hypotheses: int = 8
    prune_ratio: float = 1e-3
    name: str = "MH-EKF"

    def __post_init__(self):
        _check_model("ScaatMhEkf", self.model)
        _check_motion("ScaatMhEkf", self.motion)
        p = probability("p_detect", self.p_detect, open_interval=False)
        if p <= 0.0:
            raise ValueError(f"p_detect must be a number in (0, 1], got {self.p_detect!r}")
        object.__setattr__(self, "p_detect", p)
        object.__setattr__(self, "spurious_rate_hz", number("spurious_rate_hz", self.spurious_rate_hz, minimum=0.0))
        object.__setattr__(self, "window_s", number("window_s", self.window_s, minimum=0.0, strict_minimum=True))
        object.__setattr__(self, "max_gap", integer("max_gap", self.max_gap, minimum=1))
        object.__setattr__(self, "max_hypotheses", integer("max_hypotheses", self.max_hypotheses, minimum=1))
        object.__setattr__(self, "prune_ratio", probability("prune_ratio", self.prune_ratio, open_interval=False))
        if not isinstance(self.name, str):
            raise ValueError(f"name must be text, got {self.name!r}")

    @property
    def ekf(self) -> Ekf:
        return Ekf(self.motion, DopplerMeasurement(self.model), pos_index=(0, 1, 2), vel_index=(3, 4, 5),
                   gate_prob=None)

    def run(self, log: ChirpLog, x0: Gaussian, *, ranges_m=None) -> Estimates:
        """Filter ``log`` from the prior ``x0`` (at the first detection's time).

        Returns
        -------
        Estimates
            One epoch per detection; status UPDATED where the best hypothesis used the
            detection, PREDICTED where it read it as noise. ``info``: ``n_hypotheses``,
            ``beacon`` (the best hypothesis' assignment, −1 for noise).
        """
        _check_log("ScaatMhEkf.run", log)
        if not isinstance(x0, Gaussian) or np.shape(x0.x) != (6,):
            raise ValueError(f"x0 must be a Gaussian over [X, V] (6 components), got {x0!r}")
        ekf = self.ekf
        P = self.model.period_s
        n_b = P.size
        rr = np.full(len(log), np.nan) if ranges_m is None else _per_row("ranges_m", ranges_m, len(log))
        hyps = [_Hypothesis(x0, float(log.t_s[0]) if len(log) else 0.0, np.full(n_b, np.nan), 0.0)]
        T = len(log)
        pos, vel = np.full((T, 3), np.nan), np.full((T, 3), np.nan)
        cov = np.full((T, 3, 3), np.nan)
        status = np.full(T, EstimateStatus.PREDICTED, np.int8)
        n_h, chosen = np.zeros(T, int), np.full(T, -1)
        log_clutter = np.log(self.spurious_rate_hz) if self.spurious_rate_hz > 0 else -np.inf
        lock = log.has(ChirpFlag.LOCK)
        for r, t in enumerate(log.t_s):
            children = []
            for h in hyps:
                last = h.last_s.copy()
                stale = np.isfinite(last) & (t - last > (self.max_gap + 0.5) * P)
                last[stale] = np.nan
                if lock[r] and log.beacon[r] >= 0 and not np.isfinite(last[log.beacon[r]]):
                    started = last.copy()
                    started[log.beacon[r]] = t
                    children.append(_Hypothesis(h.state, h.t_s, started, h.logw, False))
                    continue
                gap = t - last
                k = np.rint(gap / P)
                shift = gap / np.where(k > 0, k, np.nan) - P
                fits = np.flatnonzero(np.isfinite(last) & (k >= 1) & (k <= self.max_gap)
                                      & (np.abs(shift) <= self.window_s))
                if fits.size:
                    prior = ekf.predict(h.state, t - h.t_s)
                for i in fits:
                    meas = (int(i), float(shift[i]), rr[r] if log.beacon[r] == i else np.nan)
                    lin = ekf.measurement.linearise(prior.x, meas)
                    post, inn = kalman.update(prior, lin.z, lin.H, lin.R, h_x=lin.h)   # the EKF step of Ekf.update
                    ll = -0.5 * (inn.nis + np.linalg.slogdet(2 * np.pi * inn.S)[1])
                    moved = last.copy()
                    moved[i] = t
                    children.append(_Hypothesis(post, float(t), moved,
                                                h.logw + ll + np.log(self.p_detect)
                                                + (k[i] - 1) * np.log1p(-self.p_detect), True))
                children.append(_Hypothesis(h.state, h.t_s, last, h.logw + log_clutter, False))
            logw = np.array([c.logw for c in children])
            logw -= logw.max()
            order = np.argsort(-logw, kind="stable")
            keep = [children[j] for j in order[: self.max_hypotheses] if logw[j] >= np.log(self.prune_ratio)]
            for c in keep:
                c.logw -= np.max([c2.logw for c2 in keep])
            hyps = keep
            best = hyps[0]
            x = ekf.predict(best.state, t - best.t_s) if t > best.t_s else best.state
            pos[r], vel[r], cov[r] = x.x[:3], x.x[3:], x.P[:3, :3]
            status[r] = EstimateStatus.UPDATED if best.assigned and best.t_s == t else EstimateStatus.PREDICTED
            n_h[r] = len(hyps)
            if best.assigned and best.t_s == t:
                chosen[r] = int(np.flatnonzero(best.last_s == t)[0])
        return Estimates(np.asarray(log.t_s, float), pos, status, self.name, pos_cov_m2=cov, vel_mps=vel,
                         info={"n_hypotheses": n_h, "beacon": chosen})
