"""Throughput of the batched set-noise particle filter against a per-trial NumPy loop.

Both run the same filter (paper 000: constant-velocity particles, eq. 9 weights,
systematic resampling when ESS < 0.5 K) on the same simulated recording, for
baseline and set-noise noise models and every σ_d value of the Fig. 9 sweep:

* **loop** — :func:`uwbwb.filters.setnoise.reference_pf`, one filter run at a time
  (one trial, one σ_d, one noise model), vectorised over the K particles only;
* **batched** — :func:`uwbwb.filters.setnoise.pf_sweep`, all trials × filters × σ_d
  values as leading array axes, in cache-sized blocks.

Throughput is particle-steps per second (particles × fixes × runs / wall time),
measured in this process, and the ratio batched / loop is printed for several
batched settings (float64 with independent noise is the like-for-like one; the
sweep's defaults are float32 with common random numbers). The sweep's blocks run compiled
loops by default; the same sweep with the NumPy block (``compiled=False``, their declared twin)
is timed too, and the ratio compiled / NumPy printed from the same run. A final check confirms
that one batched trial reproduces the loop to rounding when given the same
random stream.

Run:  python benchmarks/bench_setnoise_pf.py [--full]
(--full also times the complete Fig. 9 sweep: 5 recordings × 100 trials × 15 σ_d × K = 1000, both PFs.)
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from uwbwb.experiments import setnoise as ex
from uwbwb.filters import setnoise as sf


def _setup(seed: int):
    study = ex.synthetic_study(rng=np.random.default_rng(seed))
    rec = study.recording("rec2")
    mu_b, sd_b, _ = study.model.facility_only().lookup(rec.set_id)
    mu_s, sd_s, _ = study.model.lookup(rec.set_id)
    return study, rec, np.stack([mu_b, mu_s]), np.stack([sd_b, sd_s])


def _in_band(sigma_d) -> np.ndarray:
    return (sigma_d >= ex.BAND_MPS[0] - 1e-12) & (sigma_d <= ex.BAND_MPS[1] + 1e-12)


def loop_rate(rec, mu, sd, sigma_d, n_trials, K, seed) -> tuple[float, float]:
    """Particle-steps per second of the per-run loop, and its set-noise PF error (m) in the 30-50 cm/s band."""
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    errors = np.zeros((n_trials, len(sigma_d)))
    for i in range(n_trials):
        for j, s in enumerate(sigma_d):
            for m in range(mu.shape[0]):
                run = sf.reference_pf(rec.t_s, rec.pos_m, mu[m], sd[m], rec.truth_m[0], s, rng=rng,
                                      n_particles=K, resampler="systematic")
                if m == 1:
                    errors[i, j] = np.linalg.norm(run.pos_m - rec.truth_m, axis=1).mean()
    wall = time.perf_counter() - t0
    return n_trials * len(sigma_d) * mu.shape[0] * K * len(rec) / wall, float(errors[:, _in_band(sigma_d)].mean())


def batched_rate(rec, mu, sd, sigma_d, n_trials, K, seed, **kw) -> tuple[float, float]:
    """Particle-steps per second of :func:`pf_sweep`, and its set-noise PF error (m) in the 30-50 cm/s band."""
    t0 = time.perf_counter()
    res = sf.pf_sweep(rec.t_s, rec.pos_m, mu, sd, rec.truth_m[0], sigma_d, rng=np.random.default_rng(seed),
                      n_trials=n_trials, n_particles=K, resampler="systematic", **kw)
    wall = time.perf_counter() - t0
    err = res.mean_error_m(rec.truth_m)[1][:, _in_band(sigma_d)].mean()
    return n_trials * len(sigma_d) * mu.shape[0] * K * len(rec) / wall, float(err)


def exactness(rec, mu, sd, K, seed) -> float:
    """Max |batched − loop| position difference (m) for one trial on the same random stream."""
    ref = sf.reference_pf(rec.t_s, rec.pos_m, mu[1], sd[1], rec.truth_m[0], 0.3,
                          rng=np.random.default_rng(seed).spawn(1)[0], n_particles=K, resampler="systematic")
    bat = sf.pf_sweep(rec.t_s, rec.pos_m, mu[1], sd[1], rec.truth_m[0], 0.3, rng=np.random.default_rng(seed),
                      n_particles=K, resampler="systematic", dtype=np.float64)
    return float(np.abs(bat.pos_m[0, 0, 0] - ref.pos_m).max())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--particles", type=int, default=1000)
    p.add_argument("--loop-trials", type=int, default=1, help="trials timed in the per-run loop")
    p.add_argument("--batched-trials", type=int, default=20, help="trials timed in the batched sweep")
    p.add_argument("--full", action="store_true", help="also time the full-fidelity Fig. 9 sweep")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    study, rec, mu, sd = _setup(args.seed)
    sig = np.asarray(ex.SIGMA_D_GRID_MPS)
    K = args.particles
    print(f"recording {rec.name}: {len(rec)} fixes; 2 noise models x {sig.size} sigma_d values x K = {K}; "
          f"{os.cpu_count()} CPUs")

    loop, loop_err = loop_rate(rec, mu, sd, sig, args.loop_trials, K, args.seed)
    print(f"per-run loop (reference_pf, float64):            {loop:10.3g} particle-steps/s   "
          f"(set-noise PF error in band {100 * loop_err:.2f} cm)")
    settings = [
        ("float64, independent noise, 1 thread", dict(dtype=np.float64, common_random_numbers=False)),
        ("float32, independent noise, 1 thread", dict(common_random_numbers=False)),
        ("float32, common random numbers, 1 thread", dict()),
        ("float32, common random numbers, 2 threads", dict(n_threads=2)),
    ]
    for dtype in (np.float64, np.float32):       # numba loads (or compiles) the block's kernels outside the timings
        sf.pf_sweep(rec.t_s[:5], rec.pos_m[:5], mu[:, :5], sd[:, :5], rec.truth_m[0], sig[:2],
                    rng=np.random.default_rng(0), n_particles=10, dtype=dtype, compiled=True)
    for name, kw in settings:
        rate, err = batched_rate(rec, mu, sd, sig, args.batched_trials, K, args.seed + 1, **kw)
        print(f"batched pf_sweep ({name}): {rate:10.3g} particle-steps/s = {rate / loop:5.1f} x loop   "
              f"(set-noise PF error in band {100 * err:.2f} cm)")
    block = {c: batched_rate(rec, mu, sd, sig, args.batched_trials, K, args.seed + 1, compiled=c)[0]
             for c in (True, False)}
    print(f"float32, common random numbers, 1 thread: compiled block {block[True]:10.3g}, "
          f"NumPy block {block[False]:10.3g} particle-steps/s; compiled / NumPy = {block[True] / block[False]:.2f} x")
    print(f"same random stream, one trial: max |batched - loop| = {exactness(rec, mu, sd, K, args.seed):.2e} m")

    if args.full:
        cfg = ex.SweepConfig(n_threads=2)
        n_ps = 2 * cfg.n_trials * len(cfg.sigma_d_mps) * cfg.n_particles * sum(map(len, study.recordings))
        t0 = time.perf_counter()
        ex.sweep(study.recordings, study.model, cfg, rng=np.random.default_rng(args.seed), progress=False)
        wall = time.perf_counter() - t0
        print(f"full Fig. 9 sweep (5 recordings x {cfg.n_trials} trials x {len(cfg.sigma_d_mps)} sigma_d x "
              f"K = {cfg.n_particles}, both PFs, 2 threads): {wall:.0f} s, {n_ps / wall:.3g} particle-steps/s")


if __name__ == "__main__":
    main()
