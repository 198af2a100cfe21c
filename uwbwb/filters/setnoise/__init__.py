"""Set-noise particle filter, its set-blind baseline, and the exact set-noise Kalman filter (paper 000).

Model (paper 000, eqs. 2–6). Motion: :class:`uwbwb.models.motion.VelocityKick`, state
``[x, y, ẋ, ẏ]`` (m, m/s); between fixes ``T`` seconds apart (eq. 3)::

    x ← x + T ẋ,   ẋ ← ẋ + N(0, σ_d)      (same for y)

so σ_d (m/s) is the standard deviation of the velocity change *per step*.
A fix ``(x̃, ỹ)`` taken with sensor set ``s`` is ``x̃ = x + N(μx_s, σx_s)``, ``ỹ = y + N(μy_s, σy_s)``
(eq. 6), with ``(μ, σ)`` from a :class:`uwbwb.models.setnoise.SetNoiseModel`.

Filters
-------
* **Set-noise PF** (eqs. 7–12): K particles start at the known position with zero
  velocity and equal weights; each fix multiplies the weights by eq. 9 with the
  observed set's ``(μ, σ)``; weights are normalised (eq. 10); the output is the
  weighted mean (eq. 11); when ``ESS = K/(1+CV) < 0.5·K`` (eq. 12) the particles
  are resampled. The paper writes "ESS < 0.5"; we read it as a fraction of K.
  Resampling is systematic by default; ``resampler="multinomial"`` is the paper's
  "select with replacement" (same expectation, more variance, O(K log K)).
* **Baseline PF**: the same filter fed the facility-wide model for every fix
  (:meth:`~uwbwb.models.setnoise.SetNoiseModel.facility_only`).
* **Set-noise KF**: given the observed sets the model is linear-Gaussian, so a
  Kalman filter with the set's bias and variance is the exact posterior the PF
  approximates. With the known start (``P₀ = 0``) both filters share the prior.

Timing: the prior holds at the first fix (step 0 is an update only); every later
fix is preceded by one prediction over the actual interval ``T = t_k − t_{k−1}``.

The PF equations are implemented at three levels:

* :func:`pf_init`, :func:`pf_predict`, :func:`pf_update`, :func:`pf_estimate`,
  :func:`pf_resample` — the textbook steps on ``(..., K, 4)`` particles, the prediction
  being the motion model's own :meth:`~uwbwb.models.motion.VelocityKick.step`;
* :func:`reference_pf` — one filter run: the motion model's step and eq. 9's
  :func:`fix_log_likelihood` on the particle engine
  (:class:`~uwbwb.filters.particle.ParticleFilter`), epoch for epoch those steps (the
  readable reference, and the "per-trial loop" of ``benchmarks/bench_setnoise_pf.py``);
* :func:`pf_sweep` — the Monte Carlo sweep: filter variants × trials × σ_d values
  as leading array axes, processed in cache-sized blocks with in-place updates (eq. 3
  written out per state component; tested to reproduce :func:`reference_pf`).

The Kalman filter (:func:`kf_sweep`) runs the same model in closed form per axis; it is a
declared kernel whose twin is :class:`~uwbwb.filters.ekf.Ekf` over
:class:`~uwbwb.models.motion.VelocityKick` without a gate (:mod:`uwbwb.filters.twins`).

Modules
-------
:mod:`.pf` (inputs, the particle-filter steps, one run, the batched sweep) and :mod:`.kf` (the
closed-form Kalman filter); every name importable from here.
"""

from .kf import KFSweep, kf_sweep, run_set_noise_kf
from .pf import (STATE, FilterRun, ParticleState, PFSweep, _block_trials, _sweep_block,  # noqa: F401 (benchmarks)
                 fix_log_likelihood, model_noise, pf_estimate, pf_init, pf_predict, pf_resample, pf_sweep, pf_update,
                 reference_pf, run_set_noise_pf)

__all__ = ["STATE", "FilterRun", "KFSweep", "PFSweep", "ParticleState", "fix_log_likelihood", "kf_sweep", "model_noise",
           "pf_estimate", "pf_init", "pf_predict", "pf_resample", "pf_sweep", "pf_update", "reference_pf",
           "run_set_noise_kf", "run_set_noise_pf"]
