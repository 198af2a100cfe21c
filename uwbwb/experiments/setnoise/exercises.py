"""Exercises of notebook 01 ("change X, predict Y").

Each exercise runs both settings on the same recording and set-noise model and returns a
:class:`uwbwb.widgets.ExerciseCheck` (the direction to predict, whether this run shows it, the
numbers). The reasoning is the check's ``why``, shown
once the student has predicted; ``TEACHING.md`` gives one run's numbers.
"""

from __future__ import annotations

import numpy as np

from ... import validate
from ...models.setnoise import SetNoiseModel
from ...filters import setnoise as filt
from ...types import SetFixLog
from ...widgets import ExerciseCheck
from .diagnostics import pf_kf_gap
from .study import raw_error_m


def few_particles(log: SetFixLog, model: SetNoiseModel, *, sigma_d_mps: float = 0.02, reference_mps: float = 0.30,
                  n_particles: int = 50, n_trials: int = 3, factor: float = 1.5,
                  rng: np.random.Generator) -> ExerciseCheck:
    """Exercise: K = ``n_particles`` at a small σ_d; predict the set-noise PF error against the exact KF.

    The KF is the exact posterior mean of the same model, so the PF can only lose to it by
    Monte Carlo error. With few particles and a small σ_d, the velocity reversal at each turn of
    the track lies far in the tail of the prior: no particle follows, and the PF error grows far
    above the KF's. How far depends on the recording (on the slowest synthetic recording, rec1,
    the PF stays within 1.2× of the KF); the claim is checked with ``factor``. The same K at
    ``reference_mps`` (inside the paper's band) is reported beside, for comparison only.

    Returns
    -------
    ExerciseCheck
        Claim "at σ_d the PF error is more than ``factor`` × the KF error"; numbers: PF and KF mean
        error (cm) at both σ_d, the PF's averaged over ``n_trials`` runs.
    """
    sigma_d_mps = validate.number("sigma_d_mps", sigma_d_mps, minimum=0.0, strict_minimum=True)
    reference_mps = validate.number("reference_mps", reference_mps, minimum=0.0, strict_minimum=True)
    n_particles = validate.integer("n_particles", n_particles, minimum=1)
    factor = validate.number("factor", factor, minimum=1.0)
    small_rng, ref_rng = rng.spawn(2)
    small = pf_kf_gap(log, model, sigma_d_mps, (n_particles,), n_trials=n_trials, rng=small_rng).iloc[0]
    ref = pf_kf_gap(log, model, reference_mps, (n_particles,), n_trials=n_trials, rng=ref_rng).iloc[0]
    s, r = f"{100 * sigma_d_mps:g}", f"{100 * reference_mps:g}"
    return ExerciseCheck(
        f"K = {n_particles}, σ_d = {s} cm/s on {log.name}: set-noise PF error more than {factor:g}× the exact KF's",
        small.pf_error_m > factor * small.kf_error_m,
        {f"PF at {s} cm/s (cm)": 100 * float(small.pf_error_m), f"KF at {s} cm/s (cm)": 100 * float(small.kf_error_m),
         f"PF at {r} cm/s (cm)": 100 * float(ref.pf_error_m), f"KF at {r} cm/s (cm)": 100 * float(ref.kf_error_m)},
        (f"more than {factor:g}× the KF's", f"at most {factor:g}× the KF's"),
        "With little velocity noise, resampling leaves copies of a few particles that the small σ_d cannot spread "
        "again: the cloud stops following the set's moves. The exact KF has no sampling error; at 30 cm/s the "
        "spread keeps the PF close to it.")


def no_resampling(log: SetFixLog, model: SetNoiseModel, *, sigma_d_mps: float = 0.30, n_particles: int = 200,
                  n_trials: int = 3, rng: np.random.Generator) -> ExerciseCheck:
    """Exercise: never resample (ESS threshold 0); predict the set-noise PF error.

    Without resampling the weights concentrate on fewer and fewer particles (the ESS falls
    towards 1), the rest carry no weight, and the estimate becomes one particle's own random
    path: the error grows, here above that of the raw fixes. Both runs use the same trials'
    random numbers (the same ``rng`` state), so only the threshold differs.

    Returns
    -------
    ExerciseCheck
        Claim "without resampling the PF error is higher, and above the raw fixes' error"; numbers:
        mean error (cm) with ESS threshold 0.5·K and 0, and of the raw fixes; the median ESS over the fixes
        and the ESS at the last fix of one run that never resamples (:func:`~uwbwb.filters.setnoise.reference_pf`).
    """
    sigma_d_mps = validate.number("sigma_d_mps", sigma_d_mps, minimum=0.0, strict_minimum=True)
    mu, sd, _ = model.lookup(log.set_id)
    err = {}
    seed = int(rng.integers(2**63))                               # same trials' draws for both thresholds
    for fraction in (0.5, 0.0):
        pf = filt.pf_sweep(log.t_s, log.pos_m, mu, sd, log.truth_m[0], sigma_d_mps, rng=np.random.default_rng(seed),
                           n_trials=n_trials, n_particles=n_particles, ess_fraction=fraction)
        err[fraction] = float(pf.mean_error_m(log.truth_m).mean())
    raw = raw_error_m(log)
    one = filt.reference_pf(log.t_s, log.pos_m, mu, sd, log.truth_m[0], sigma_d_mps, rng=np.random.default_rng(seed),
                            n_particles=n_particles, ess_fraction=0.0)     # one run, step by step, for its ESS
    return ExerciseCheck(
        f"K = {n_particles}, σ_d = {100 * sigma_d_mps:g} cm/s on {log.name}: without resampling the set-noise PF error is higher, "
        "and above the raw fixes'",
        err[0.0] > err[0.5] and err[0.0] > raw,
        {"resample when ESS < 0.5 K (cm)": 100 * err[0.5], "never resample (cm)": 100 * err[0.0],
         "raw fixes (cm)": 100 * raw, "median ESS, never resample": float(np.median(one.ess)),
         "ESS at the last fix, never resample": float(one.ess[-1])},
        ("above both", "not above both"),
        "Without resampling the weights pile up on one particle (the ESS falls to 1): the filter then follows one "
        "hypothesis that drifts away, worse than the raw fixes it is given.")
