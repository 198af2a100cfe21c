"""The set-noise particle filter (paper 000): inputs, steps, one run, and the batched sweep over trials and σ_d.

See :mod:`uwbwb.filters.setnoise` for the model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
import pandas as pd

from ...metrics import nis_consistency
from ...models.motion import VelocityKick
from ...models.setnoise import SetNoiseModel, log_likelihood
from ... import parallel
from ...types import EstimateStatus, Estimates, EstimatesBatch, SetFixLog
from ...validate import integer, probability
from .. import particle

#: State layout of the set-noise filters (that of a 2-D :class:`~uwbwb.models.motion.VelocityKick`).
STATE = VelocityKick(dim=2).state_labels


# --------------------------------------------------------------------------- inputs

def _times(t_s) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t_s, float)
    if t.ndim != 1 or t.size < 1:
        raise ValueError(f"t_s must be a non-empty 1-D array, got shape {t.shape}")
    dt = np.diff(t, prepend=t[0])
    if np.any(dt[1:] <= 0):
        raise ValueError("t_s must be strictly increasing")
    return t, dt


def _noise_arrays(z_m, mu_m, sigma_m, T: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z = np.asarray(z_m, float)
    mu = np.asarray(mu_m, float)
    sd = np.asarray(sigma_m, float)
    if z.shape != (T, 2):
        raise ValueError(f"z_m must have shape ({T}, 2), got {z.shape}")
    if mu.shape[-2:] != (T, 2) or sd.shape != mu.shape:
        raise ValueError(f"mu_m and sigma_m must have equal shapes (..., {T}, 2), got {mu.shape}, {sd.shape}")
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(mu))):
        raise ValueError("fixes and biases must be finite")
    if not np.all(sd > 0):
        raise ValueError("sigma_m must be positive")
    return z, mu, sd


def _check_n_particles(n_particles) -> None:
    integer("n_particles", n_particles, minimum=1)


def _check_common(n_particles: int, ess_fraction: float, resampler: str) -> None:
    _check_n_particles(n_particles)
    probability("ess_fraction", ess_fraction, open_interval=False)
    if resampler not in particle.RESAMPLERS:
        raise ValueError(f"unknown resampler {resampler!r}; choose from {particle.RESAMPLERS}")


def model_noise(fixes: SetFixLog, model: SetNoiseModel) -> tuple[np.ndarray, np.ndarray]:
    """``(μ, σ)`` of every fix under ``model``, shapes ``(T, 2)``, metres."""
    mu, sd, _ = model.lookup(fixes.set_id)
    return mu, sd


# --------------------------------------------------------------------------- PF steps

@dataclass(frozen=True)
class ParticleState:
    """Particles ``(..., K, 4)`` in the layout :data:`STATE` and their log-weights ``(..., K)``."""

    particles: np.ndarray
    logw: np.ndarray


def pf_init(x0_m, n_particles: int, batch_shape: tuple = ()) -> ParticleState:
    """Eq. 7: every particle at the known start ``x0_m = (x₀, y₀)`` with zero velocity, weights ``1/K``."""
    _check_n_particles(n_particles)
    x0 = np.asarray(x0_m, float)
    if x0.shape != (2,):
        raise ValueError(f"x0_m must be (x, y), got shape {x0.shape}")
    p = np.zeros(tuple(batch_shape) + (n_particles, 4))
    p[..., :2] = x0
    return ParticleState(p, np.full(tuple(batch_shape) + (n_particles,), -np.log(n_particles)))


def pf_predict(state: ParticleState, dt_s: float, motion: VelocityKick, *, rng: np.random.Generator) -> ParticleState:
    """Eq. 3 for every particle: ``x ← x + T ẋ``, ``ẋ ← ẋ + N(0, σ_d)`` per axis (:meth:`VelocityKick.step`)."""
    return ParticleState(motion.step(state.particles, dt_s, rng=rng), state.logw)


def fix_log_likelihood(particles: np.ndarray, fix) -> np.ndarray:
    """Eq. 9 in logs for every particle ``(..., K, 4)``: ``fix = (z_m, mu_m, sigma_m)``, each ``(..., 2)``,
    metres (the fix, its set's bias and spread); shape ``(..., K)``."""
    z_m, mu_m, sigma_m = fix
    return log_likelihood(particles[..., :2], np.asarray(z_m)[..., None, :],
                          np.asarray(mu_m)[..., None, :], np.asarray(sigma_m)[..., None, :])


def pf_update(state: ParticleState, z_m, mu_m, sigma_m) -> ParticleState:
    """Eqs. 8–10: add eq. 9's log-likelihood of fix ``z`` (bias ``μ``, spread ``σ``) and normalise."""
    logw, _ = particle.normalise_log_weights(state.logw + fix_log_likelihood(state.particles, (z_m, mu_m, sigma_m)))
    return ParticleState(state.particles, logw)


def pf_estimate(state: ParticleState) -> np.ndarray:
    """Eq. 11: weighted mean state, shape ``(..., 4)``."""
    return particle.weighted_mean(state.particles, state.logw)


def pf_resample(state: ParticleState, *, rng: np.random.Generator, ess_fraction: float = 0.5,
                method: str = "systematic") -> tuple[ParticleState, np.ndarray]:
    """Eq. 12 and resampling: rows with ``ESS < ess_fraction · K`` are resampled; returns which."""
    p, logw, done = particle.resample(state.particles, state.logw, rng=rng, threshold=ess_fraction, method=method)
    return ParticleState(p, logw), done


# --------------------------------------------------------------------------- one run

@dataclass(frozen=True)
class FilterRun:
    """Output of one filter over one recording.

    Attributes
    ----------
    t_s
        Times, shape ``(T,)``, seconds.
    state
        Posterior mean ``[x, y, ẋ, ẏ]`` after each fix, shape ``(T, 4)``.
    ess
        Effective sample size after each update (before resampling), shape ``(T,)``;
        NaN for a Kalman filter.
    resampled
        Whether the particles were resampled at each step, shape ``(T,)``.
    name
        Label (e.g. ``"set-noise PF"``).
    meta
        Settings of the run (``n_particles``, ``sigma_d_mps``, ...). For older callers it also
        holds ``"cov"`` and ``"nis"`` when the run has them (the same arrays as the fields).
    cov
        Posterior covariance of the state after each fix, shape ``(T, 4, 4)``; None for a
        particle filter (the Kalman filter has one).
    nis
        Normalised innovation squared of each fix, shape ``(T,)`` (2 dof: χ²(2) if the model
        holds); None for a particle filter.
    """

    t_s: np.ndarray
    state: np.ndarray
    ess: np.ndarray
    resampled: np.ndarray
    name: str = "filter"
    meta: dict = field(default_factory=dict, compare=False)
    cov: np.ndarray | None = field(default=None, compare=False)
    nis: np.ndarray | None = field(default=None, compare=False)

    def __post_init__(self):
        meta = dict(self.meta)
        for key in ("cov", "nis"):                       # one value, read as a field or from meta
            if getattr(self, key) is None and meta.get(key) is not None:
                object.__setattr__(self, key, meta[key])
            elif getattr(self, key) is not None:
                meta[key] = getattr(self, key)
        if (self.cov is None) != (self.nis is None):
            raise ValueError("FilterRun: cov and nis come together (a Kalman filter) or not at all (a PF)")
        T = np.shape(self.t_s)[0]
        if self.cov is not None and (np.shape(self.cov) != (T, 4, 4) or np.shape(self.nis) != (T,)):
            raise ValueError(f"FilterRun: cov must have shape ({T}, 4, 4) and nis ({T},), "
                             f"got {np.shape(self.cov)} and {np.shape(self.nis)}")
        object.__setattr__(self, "meta", meta)

    @property
    def pos_m(self) -> np.ndarray:
        """Estimated positions, shape ``(T, 2)``, metres."""
        return self.state[:, :2]

    @property
    def dof(self) -> np.ndarray | None:
        """Size of each fix's innovation (2) where the run has a NIS, else None."""
        return None if self.nis is None else np.full(self.t_s.size, 2)

    def nis_consistency(self, prob: float = 0.95) -> dict:
        """χ² consistency of the Kalman filter's NIS over its fixes (:func:`uwbwb.metrics.nis_consistency`);
        a particle filter has none (``"no updates"``)."""
        if self.nis is None:
            return nis_consistency(np.zeros(0), np.zeros(0, int), prob)
        return nis_consistency(self.nis, self.dof, prob)

    def to_estimates(self) -> Estimates:
        """The common result type: every fix ``UPDATED``, with velocities; the Kalman filter's
        position covariances and ``nis``/``dof`` (2 per fix), the particle filter's ``ess`` and
        ``resampled`` in ``info``."""
        T = self.t_s.size
        status = np.full(T, EstimateStatus.UPDATED, np.int8)
        if self.cov is not None:
            cov = np.asarray(self.cov)[:, :2, :2]
            info = {"nis": np.asarray(self.nis), "dof": self.dof}
        else:
            cov, info = None, {"ess": self.ess, "resampled": self.resampled}
        return Estimates(self.t_s, self.pos_m, status, self.name, cov, self.state[:, 2:], info)

    def to_frame(self) -> pd.DataFrame:
        """Tidy table ``t_s, x_m, y_m, vx_mps, vy_mps, ess, resampled``."""
        df = pd.DataFrame(self.state, columns=list(STATE))
        df.insert(0, "t_s", self.t_s)
        df["ess"], df["resampled"] = self.ess, self.resampled
        return df


def reference_pf(t_s, z_m, mu_m, sigma_m, x0_m, sigma_d_mps: float, *, rng: np.random.Generator,
                 n_particles: int = 1000, ess_fraction: float = 0.5, resampler: str = "systematic",
                 name: str = "PF") -> FilterRun:
    """One particle-filter run: the model's pieces on the particle engine.

    :class:`~uwbwb.filters.particle.ParticleFilter` with :meth:`VelocityKick.step` (eq. 3, no
    prediction before the first fix), :func:`fix_log_likelihood` (eq. 9), the weighted mean
    (eq. 11) and resampling when ``ESS < ess_fraction · K`` (eq. 12): the same epochs as
    :func:`pf_predict`, :func:`pf_update`, :func:`pf_estimate`, :func:`pf_resample` in turn. This
    is the readable reference of the method; :func:`pf_sweep` computes the same filter for many
    trials and parameters at once.

    Parameters
    ----------
    t_s
        Fix times, shape ``(T,)``, seconds.
    z_m
        Fixes, shape ``(T, 2)``, metres.
    mu_m, sigma_m
        Bias and standard deviation for each fix, shape ``(T, 2)``, metres (from the set
        of each fix for the set-noise PF, the facility-wide model for the baseline).
    x0_m
        Known start position, shape ``(2,)``, metres.
    sigma_d_mps
        Velocity noise per step, m/s.
    rng
        Source of the process noise and the resampling variates.

    Returns
    -------
    FilterRun
    """
    _check_common(n_particles, ess_fraction, resampler)
    t, _ = _times(t_s)
    z, mu, sd = _noise_arrays(z_m, mu_m, sigma_m, t.size)
    if mu.shape != (t.size, 2):
        raise ValueError(f"reference_pf runs one filter: mu_m must be ({t.size}, 2), got {mu.shape}")
    engine = particle.ParticleFilter(VelocityKick(sigma_d_mps, dim=2).step, fix_log_likelihood,
                                     ess_fraction=ess_fraction, method=resampler)
    state = pf_init(x0_m, n_particles)
    run = engine.run(state.particles, state.logw, t, list(zip(z, mu, sd)), rng=rng)
    return FilterRun(t, run.estimate, run.ess, run.resampled, name,
                     {"n_particles": n_particles, "sigma_d_mps": sigma_d_mps, "ess_fraction": ess_fraction,
                      "resampler": resampler})


def run_set_noise_pf(fixes: SetFixLog, model: SetNoiseModel, x0_m, sigma_d_mps: float, *,
                     rng: np.random.Generator, n_particles: int = 1000, ess_fraction: float = 0.5,
                     resampler: str = "systematic", name: str | None = None) -> FilterRun:
    """The paper's filter on one recording: the set of each fix selects its ``(μ, σ)``.

    Pass ``model.facility_only()`` for the baseline PF.
    """
    mu, sd = model_noise(fixes, model)
    if name is None:
        name = "set-noise PF" if len(model) else "baseline PF"
    return reference_pf(fixes.t_s, fixes.pos_m, mu, sd, x0_m, sigma_d_mps, rng=rng, n_particles=n_particles,
                        ess_fraction=ess_fraction, resampler=resampler, name=name)


# --------------------------------------------------------------------------- the sweep

@dataclass(frozen=True)
class PFSweep:
    """Monte Carlo sweep of particle filters.

    Attributes
    ----------
    t_s
        Fix times, shape ``(T,)``.
    sigma_d_mps
        Velocity-noise values, shape ``(S,)``, m/s.
    pos_m
        Estimated positions, shape ``(M, n_trials, S, T, 2)``, metres
        (M filter variants, i.e. noise models); None when the sweep kept only
        the errors (``keep_positions=False``).
    n_resampled
        Resampling events per run, shape ``(M, n_trials, S)``.
    ess_mean
        Mean ESS over the run's steps, shape ``(M, n_trials, S)``.
    n_particles, ess_fraction, resampler, common_random_numbers, dtype
        The settings used.
    error_m
        Mean Euclidean error of each run against the ``truth_m`` given to
        :func:`pf_sweep`, shape ``(M, n_trials, S)``, metres (None without truth).
    """

    t_s: np.ndarray
    sigma_d_mps: np.ndarray
    pos_m: np.ndarray
    n_resampled: np.ndarray
    ess_mean: np.ndarray
    n_particles: int
    ess_fraction: float
    resampler: str
    common_random_numbers: bool
    dtype: str
    error_m: np.ndarray | None = None

    @property
    def n_trials(self) -> int:
        return self.n_resampled.shape[1]

    def to_estimates(self) -> EstimatesBatch:
        """Every run's positions as :class:`~uwbwb.types.Estimates` fields batched over
        ``(M, n_trials, S)`` (every fix ``UPDATED``; a PF sweep keeps no covariance or velocity)."""
        if self.pos_m is None:
            raise ValueError("this sweep kept no positions (keep_positions=False): use its error_m")
        return EstimatesBatch(self.t_s, self.pos_m, np.full(self.pos_m.shape[:-1], EstimateStatus.UPDATED, np.int8),
                              "PF")

    def mean_error_m(self, truth_m: np.ndarray) -> np.ndarray:
        """Mean Euclidean error of each run against ``truth_m (T, 2)``: shape ``(M, n_trials, S)``."""
        if self.pos_m is None:
            raise ValueError("this sweep kept no positions (keep_positions=False): use its error_m")
        return np.linalg.norm(self.pos_m - np.asarray(truth_m, float), axis=-1).mean(axis=-1)


def _block_trials(n_rows_per_trial: int, n_particles: int, block_particles: int, n_trials: int) -> int:
    return int(np.clip(block_particles // max(n_rows_per_trial * n_particles, 1), 1, n_trials))


def pf_sweep(t_s, z_m, mu_m, sigma_m, x0_m, sigma_d_mps, *, rng: np.random.Generator, n_trials: int = 1,
             n_particles: int = 1000, ess_fraction: float = 0.5, resampler: str = "systematic",
             common_random_numbers: bool = True, dtype=np.float32, block_particles: int = 1 << 17,
             n_threads: int = 1, scheduler=None, truth_m=None, keep_positions: bool = True,
             progress: bool | None = False, desc: str = "PF sweep", compiled: bool = True) -> PFSweep:
    """Run the PF for every filter variant × trial × σ_d value as one batched computation.

    Parameters
    ----------
    t_s, z_m, x0_m
        As for :func:`reference_pf` (one recording).
    mu_m, sigma_m
        Per-fix bias and spread, shape ``(T, 2)`` or ``(M, T, 2)`` for M filter variants
        (e.g. ``M = 2``: baseline and set-noise PF).
    sigma_d_mps
        Velocity-noise values, scalar or shape ``(S,)``, m/s.
    rng
        Parent generator. Trial ``i`` draws all its randomness from child ``i`` of
        ``rng.spawn(n_trials)``, so its result does not depend on how trials are
        grouped into blocks.
    n_trials
        Independent repetitions (the paper's 100).
    common_random_numbers
        If True (default), within a trial every σ_d value and filter variant uses the
        same standard-normal draws for the process noise (scaled by its own σ_d):
        each run is still an exact PF, but differences between σ_d values and between
        filters are estimated with less Monte Carlo noise, and the draws cost S·M
        times less. If False, every run draws its own noise.
    dtype
        Floating type of the particle arrays (float32 halves memory traffic;
        positions are stored relative to ``x0_m`` to keep full resolution).
    block_particles
        Particles processed together (whole trials); sized to stay in cache. Each
        block is one task of the sweep (:mod:`uwbwb.parallel`).
    n_threads
        Worker threads, each advancing its own blocks of trials, when ``scheduler``
        is None (results do not depend on it).
    scheduler
        None (this process), ``"local"``, a Dask scheduler address or a
        ``distributed.Client``: where the blocks run (results do not depend on it).
    truth_m
        True positions ``(T, 2)``, metres: each block's mean errors are then
        computed where it runs and returned as :attr:`PFSweep.error_m`.
    keep_positions
        False: return no positions (needs ``truth_m``), so only ``M·n_trials·S``
        errors travel back and are held, not ``M·n_trials·S·T·2`` positions.
    progress
        Show a ``tqdm`` bar over trials (None: only when a cluster is used).
    compiled
        True (default): each block's epochs run in the compiled loops of :func:`_sweep_block_compiled`
        (the same draws, faster; positions and ESS in their last bits); False: the NumPy
        :func:`_sweep_block`, their declared twin (:mod:`uwbwb.filters.twins`).

    Returns
    -------
    PFSweep
    """
    _check_common(n_particles, ess_fraction, resampler)
    t, dt = _times(t_s)
    T = t.size
    z, mu, sd = _noise_arrays(z_m, mu_m, sigma_m, T)
    if mu.ndim == 2:
        mu, sd = mu[None], sd[None]
    if mu.ndim != 3:
        raise ValueError(f"mu_m must be (T, 2) or (M, T, 2), got {mu.shape}")
    x0 = np.asarray(x0_m, float)
    if x0.shape != (2,):
        raise ValueError(f"x0_m must be (x, y), got shape {x0.shape}")
    sig_d = np.atleast_1d(np.asarray(sigma_d_mps, float))
    if sig_d.ndim != 1 or not np.all(np.isfinite(sig_d) & (sig_d >= 0)):
        raise ValueError(f"sigma_d_mps must be a finite non-negative scalar or 1-D array, got {sigma_d_mps!r}")
    integer("n_trials", n_trials, minimum=1)
    integer("n_threads", n_threads, minimum=1)
    M, S, K = mu.shape[0], sig_d.size, n_particles
    dtype = np.dtype(dtype)

    # Per-fix constants of eq. 9, relative to the start: centre c = z − μ − x0, a = 1/(2σ²).
    centre = (z[None] - mu - x0).astype(dtype)                       # (M, T, 2)
    half_prec = (0.5 / sd ** 2).astype(dtype)                         # (M, T, 2)
    dt_d = dt.astype(dtype)
    b = _block_trials(M * S, K, block_particles, n_trials)
    seeds = parallel.spawn(rng, n_trials)            # trial i: child i, as rng.spawn(n_trials)[i]
    tasks = [parallel.Task({"trials": range(first, min(first + b, n_trials))},
                           seed=tuple(seeds[first:first + b]), size=min(b, n_trials - first))
             for first in range(0, n_trials, b)]
    truth = None
    if truth_m is not None:
        truth = np.asarray(truth_m, float)
        if truth.shape != (T, 2):
            raise ValueError(f"truth_m must have shape ({T}, 2), got {truth.shape}")
    if truth is None and not keep_positions:
        raise ValueError("keep_positions=False needs truth_m (the errors are then all that is kept)")
    inputs = _SweepInputs(centre, half_prec, dt_d, sig_d, x0, truth, K, M, ess_fraction, resampler,
                          common_random_numbers, dtype.name, keep_positions, compiled)

    pos = np.empty((M, n_trials, S, T, 2)) if keep_positions else None
    err = np.empty((M, n_trials, S)) if truth is not None else None
    n_res = np.zeros((M, n_trials, S), np.int64)
    ess_sum = np.zeros((M, n_trials, S))
    for task, out in parallel.imap(_sweep_task, tasks, shared={"inputs": inputs}, scheduler=scheduler,
                                   workers=n_threads, progress=progress, desc=desc, unit="trial"):
        sl = slice(task.params["trials"].start, task.params["trials"].stop)
        blk_pos, blk_err, blk_res, blk_ess = out
        if pos is not None:
            pos[:, sl] = blk_pos
        if err is not None:
            err[:, sl] = blk_err
        n_res[:, sl] = blk_res
        ess_sum[:, sl] = blk_ess
    return PFSweep(t, sig_d, pos, n_res, ess_sum / T, K, ess_fraction, resampler, common_random_numbers,
                   dtype.name, err)


@dataclass(frozen=True)
class _SweepInputs:
    """What every block of a :func:`pf_sweep` needs (sent once to each worker)."""

    centre: np.ndarray
    half_prec: np.ndarray
    dt: np.ndarray
    sig_d: np.ndarray
    x0: np.ndarray
    truth: np.ndarray | None
    K: int
    M: int
    ess_fraction: float
    resampler: str
    crn: bool
    dtype: str
    keep_positions: bool
    compiled: bool


def _sweep_task(trials: range, seed: tuple, inputs: _SweepInputs):
    """One block of trials: ``(positions (M, b, S, T, 2) or None, errors (M, b, S) or None, resamplings, ESS sums)``.

    Errors are reduced here, on the worker, so that a sweep scored against the
    truth sends ``M·b·S`` numbers back instead of every position.
    """
    d = inputs
    rngs = [np.random.default_rng(s) for s in seed]
    block = _sweep_block_compiled if d.compiled else _sweep_block
    blk_pos, blk_res, blk_ess = block(rngs, d.centre, d.half_prec, d.dt, d.sig_d, d.K, d.M, d.ess_fraction,
                                      d.resampler, d.crn, np.dtype(d.dtype))
    pos = np.moveaxis(blk_pos, 0, 1) + d.x0                      # (M, b, S, T, 2), float64
    err = None if d.truth is None else np.linalg.norm(pos - d.truth, axis=-1).mean(axis=-1)
    return (pos if d.keep_positions else None), err, np.moveaxis(blk_res, 0, 1), np.moveaxis(blk_ess, 0, 1)


def _sweep_block(rngs, centre, half_prec, dt, sig_d, K, M, ess_fraction, resampler, crn, dtype):
    """All steps for one block of trials.

    State components are separate ``(b, M, S, K)`` arrays (trial, variant, σ_d,
    particle), updated in place; resampling gathers into spare buffers and swaps.
    Returns positions ``(b, M, S, T, 2)`` relative to the start, resampling counts
    and ESS sums ``(b, M, S)``.
    """
    b, S, T = len(rngs), sig_d.size, centre.shape[1]
    shape = (b, M, S, K)
    state = [np.zeros(shape, dtype) for _ in range(4)]              # x, ẋ, y, ẏ
    spare = [np.empty(shape, dtype) for _ in range(4)]
    logw = np.full(shape, -np.log(K), dtype)
    w = np.empty(shape, dtype)
    tmp = np.empty(shape, dtype)
    Mn, Sn = (1, 1) if crn else (M, S)
    noise = np.empty((b, 2, Mn, Sn, K), dtype)       # standard normals, one contiguous slab per trial
    kick = np.empty((b, 2, Mn, S, K), dtype)         # scaled by each run's σ_d
    sd_b = sig_d.astype(dtype).reshape(1, 1, 1, S, 1)
    pos = np.empty((b, M, S, T, 2), dtype)
    n_res = np.zeros((b, M, S), np.int64)
    ess_sum = np.zeros((b, M, S))
    rows = _Rows(rngs, M * S, K, resampler)
    c_x, c_y = (centre[:, :, i].T.reshape(T, 1, M, 1, 1) for i in (0, 1))
    a_x, a_y = (half_prec[:, :, i].T.reshape(T, 1, M, 1, 1) for i in (0, 1))
    log_k = dtype.type(-np.log(K))

    for k in range(T):
        x, vx, y, vy = state
        if k:
            # eq. 3: positions move with the old velocity, then the velocity takes its kick
            np.multiply(vx, dt[k], out=tmp)
            x += tmp
            np.multiply(vy, dt[k], out=tmp)
            y += tmp
            for j, g in enumerate(rngs):
                g.standard_normal(out=noise[j], dtype=dtype)
            np.multiply(noise, sd_b, out=kick)
            vx += kick[:, 0]
            vy += kick[:, 1]
        # eq. 9 in logs, eq. 10 by log-sum-exp
        np.subtract(x, c_x[k], out=tmp)
        np.square(tmp, out=tmp)
        tmp *= a_x[k]
        logw -= tmp
        np.subtract(y, c_y[k], out=tmp)
        np.square(tmp, out=tmp)
        tmp *= a_y[k]
        logw -= tmp
        # the log-weights are only shifted (max 0, as in log-sum-exp); the normalisation
        # of eq. 10 is applied to the sums below, which saves two passes over the block
        logw -= logw.max(axis=-1, keepdims=True)
        np.exp(logw, out=w)
        total = w.sum(axis=-1, dtype=np.float64)
        # eq. 11 and eq. 12 (ESS = 1 / Σ w² for normalised w)
        pos[..., k, 0] = np.einsum("...k,...k->...", w, x) / total
        pos[..., k, 1] = np.einsum("...k,...k->...", w, y) / total
        ess = total ** 2 / np.einsum("...k,...k->...", w, w)
        ess_sum += ess
        need = ess < ess_fraction * K
        if need.any():
            flat = rows.ancestors(need, w)
            for i in range(4):
                np.take(state[i].reshape(-1), flat, out=spare[i].reshape(-1))
            state, spare = spare, state
            logw[need] = log_k
            n_res += need
    return pos, n_res, ess_sum


def _sweep_block_compiled(rngs, centre, half_prec, dt, sig_d, K, M, ess_fraction, resampler, crn, dtype):
    """:func:`_sweep_block` with its arithmetic in compiled loops over the block's rows: the same random
    draws in the same order (NumPy's generators), the same float operations for the state, the weights and
    the systematic resampling (bit for bit), ``np.exp`` itself; only the sums of eqs. 11–12 differ (float64
    accumulators instead of NumPy's pairwise and float32 ``einsum`` sums), so positions and ESS differ in
    their last bits, and a resampling decision only where an ESS falls within that of the threshold."""
    b, S, T = len(rngs), sig_d.size, centre.shape[1]
    R = b * M * S
    x, vx, y, vy, logw = (np.zeros((R, K), dtype) for _ in range(5))
    logw[:] = -np.log(K)
    w = np.empty((R, K), dtype)
    Mn, Sn = (1, 1) if crn else (M, S)
    noise = np.empty((b, 2, Mn, Sn, K), dtype)
    sd = sig_d.astype(dtype)
    pos = np.empty((R, T, 2), dtype)
    n_res = np.zeros(R, np.int64)
    ess_sum = np.zeros(R)
    need = np.zeros(R, np.bool_)
    rows = _Rows(rngs, M * S, K, resampler)
    c_x, c_y, a_x, a_y = (np.ascontiguousarray(a[:, :, i].T) for a in (centre, half_prec) for i in (0, 1))
    log_k, one = dtype.type(-np.log(K)), dtype.type(1)
    for k in range(T):
        if k:
            for j, g in enumerate(rngs):
                g.standard_normal(out=noise[j], dtype=dtype)
        _predict_weigh(x, vx, y, vy, logw, noise, sd, dt[k], k > 0, c_x[k], c_y[k], a_x[k], a_y[k], M, S)
        np.exp(logw, out=w)
        _moments(w, x, y, pos, k, ess_sum, need, ess_fraction * K)
        if need.any():
            flagged = np.flatnonzero(need)
            if resampler == "systematic":
                # as particle.systematic_counts: its float32 (1 − u) and K / c_K
                particle._systematic(flagged, one - rows._uniforms(flagged, 1)[:, 0].astype(dtype), dtype.type(K), w,
                                     (x, vx, y, vy), logw, log_k)
            else:
                flat = rows.ancestors(need, w)
                for a in (x, vx, y, vy):
                    a.reshape(-1)[:] = a.reshape(-1)[flat]
                logw[flagged] = log_k
            n_res += need
    return pos.reshape(b, M, S, T, 2), n_res.reshape(b, M, S), ess_sum.reshape(b, M, S)


@numba.njit(cache=True, nogil=True)
def _predict_weigh(x, vx, y, vy, logw, noise, sd, dt, predict, c_x, c_y, a_x, a_y, M, S):
    """Per row ``(trial, variant, σ_d)`` of ``(R, K)`` arrays: eq. 3 (when ``predict``: positions with
    the old velocity, then the kick ``noise · σ_d``), eq. 9 subtracted from the log-weights, and the row's
    maximum subtracted (the ``np.exp`` that follows is NumPy's)."""
    Mn, Sn = noise.shape[2], noise.shape[3]
    for r in range(x.shape[0]):
        j, m, s = r // (M * S), (r // S) % M, r % S
        xr, vxr, yr, vyr, lr = x[r], vx[r], y[r], vy[r], logw[r]
        if predict:
            mn, sn = (m if Mn > 1 else 0), (s if Sn > 1 else 0)
            nx, ny, sd_s = noise[j, 0, mn, sn], noise[j, 1, mn, sn], sd[s]     # contiguous rows: SIMD loops
            for i in range(xr.size):
                xr[i] += vxr[i] * dt
                yr[i] += vyr[i] * dt
                vxr[i] += nx[i] * sd_s
                vyr[i] += ny[i] * sd_s
        cx, cy, ax, ay = c_x[m], c_y[m], a_x[m], a_y[m]
        for i in range(xr.size):
            d, e = xr[i] - cx, yr[i] - cy
            lr[i] = (lr[i] - d * d * ax) - e * e * ay
        top = lr[0]
        for i in range(1, lr.size):
            top = max(top, lr[i])
        for i in range(lr.size):
            lr[i] -= top


@numba.njit(cache=True, nogil=True)
def _moments(w, x, y, pos, k, ess_sum, need, threshold):
    """Eq. 11 into ``pos[:, k]`` and eq. 12 (``ESS = (Σw)² / Σw²``) per row, float64 sums; ``need`` flags
    ``ESS < threshold``."""
    for r in range(w.shape[0]):
        sw = swx = swy = sww = 0.0
        for i in range(w.shape[1]):
            wi = np.float64(w[r, i])
            sw += wi
            swx += wi * x[r, i]
            swy += wi * y[r, i]
            sww += wi * wi
        pos[r, k, 0] = swx / sw
        pos[r, k, 1] = swy / sw
        ess = sw * sw / sww
        ess_sum[r] += ess
        need[r] = ess < threshold


class _Rows:
    """Ancestor indices for the rows of a block, as flat indices into the whole block.

    Rows that are not resampled keep their particles (identity). Each trial's
    uniform variates come from its own generator, drawn in row order for its
    flagged rows only, so a trial's randomness does not depend on its block.
    """

    def __init__(self, rngs, rows_per_trial, K, resampler):
        self.rngs, self.K, self.resampler = rngs, K, resampler
        self.trial_of_row = np.repeat(np.arange(len(rngs)), rows_per_trial)
        self.identity = np.arange(len(rngs) * rows_per_trial * K)

    def _uniforms(self, rows: np.ndarray, per_row: int) -> np.ndarray:
        owner = self.trial_of_row[rows]              # rows ascending: each trial's rows are one run
        cut = np.searchsorted(owner, np.arange(len(self.rngs) + 1))
        u = np.empty((rows.size, per_row))
        for j in np.flatnonzero(np.diff(cut)):
            u[cut[j]:cut[j + 1]] = self.rngs[j].random((int(cut[j + 1] - cut[j]), per_row))
        return u

    def ancestors(self, need: np.ndarray, w: np.ndarray) -> np.ndarray:
        K = self.K
        need = need.reshape(-1)
        rows = np.flatnonzero(need)
        w2 = w.reshape(-1, K)
        if self.resampler == "systematic":
            u = self._uniforms(rows, 1)[:, 0]
            if rows.size > need.size // 2:
                # most rows resample: one pass over the whole block, identity counts elsewhere
                u_all = np.zeros(need.size)
                u_all[rows] = u
                counts = particle.systematic_counts(w2, u_all)
                counts[~need] = 1
                return np.repeat(self.identity, counts.reshape(-1))
            counts = particle.systematic_counts(w2[rows], u)
            flat = self.identity.copy()
            base = self.identity.reshape(-1, K)[rows].reshape(-1)
            flat.reshape(-1, K)[rows] = np.repeat(base, counts.reshape(-1)).reshape(-1, K)
            return flat
        idx = particle.multinomial_indices(w2[rows], self._uniforms(rows, K))
        flat = self.identity.copy()
        flat.reshape(-1, K)[rows] = idx + (rows * K)[:, None]
        return flat
