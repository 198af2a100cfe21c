"""Throughput of the Doppler solution-space samplers against a chunked-NumPy reference.

All three estimate the fraction of the 6-D box (X ∈ [−5, 5]³ m, V ∈ [−3, 3]³ m/s)
whose δ = v_s ‖ΔP_ref − ΔP(X, V)‖ is under 15 cm, for the cubic layout and the
reference pair of paper 003, section 3:

* **reference** — a straightforward chunked NumPy implementation: draw 10⁶ pairs,
  evaluate eq 1 for all 8 beacons with array operations, count;
* **brute force** — :func:`uwbwb.sampling.brute_force`: the same uniform draws
  (the same stream as NumPy), compiled, each draw abandoned as soon as its partial
  δ exceeds the threshold, chunks on ``--workers`` threads;
* **conditional** — :func:`uwbwb.sampling.conditional`: uniform positions, the
  velocity handled per position through its δ-ellipsoid.

Printed: draws per second of each (timed in this process, after compilation),
the ratio brute force / reference (target ≥ 9, i.e. 10⁹ draws in ≤ 2 min where
the reference does ~0.9 M/s), the projected time for 10⁹ draws, and for the
conditional estimator the number of positions and exact δ evaluations it needs
to reach the relative interval half-width that 10⁹ brute-force draws would give.

Run:  python benchmarks/bench_doppler_sampler.py [--draws N] [--workers W]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uwbwb import sampling as smp
from uwbwb.models import doppler as dm

TAU_M = 0.15


def reference_fraction(model, ref_pos, ref_vel, n, *, seed, chunk=1_000_000):
    """Chunked NumPy: draw, evaluate eq 1 for every beacon, count δ < τ."""
    rng = np.random.default_rng(seed)
    b = model.delta_p(ref_pos, ref_vel)
    hits = 0
    for start in range(0, n, chunk):
        m = min(chunk, n - start)
        u = rng.random((m, 6))
        X, V = -5 + 10 * u[:, :3], -3 + 6 * u[:, 3:]
        hits += int(np.count_nonzero(model.distance_m(model.delta_p(X, V), b) < TAU_M))
    return hits / n


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=float, default=2e7, help="draws for the compiled brute force")
    ap.add_argument("--reference-draws", type=float, default=3e6, help="draws for the NumPy reference")
    ap.add_argument("--positions", type=float, default=5e5, help="positions for the conditional estimator")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    model = dm.DopplerModel.for_layout(dm.cubic_layout())
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)

    smp.brute_force(model, *ref, 10_000, seed=0, workers=1)           # compile outside the timing
    t = time.perf_counter()
    reference_fraction(model, *ref, int(args.reference_draws), seed=0)
    rate_ref = args.reference_draws / (time.perf_counter() - t)
    t = time.perf_counter()
    brute = smp.brute_force(model, *ref, int(args.draws), seed=1, thresholds_m=(TAU_M,), keep_below_m=None,
                            workers=args.workers)
    rate_bf = args.draws / (time.perf_counter() - t)
    t = time.perf_counter()
    cond = smp.conditional(model, *ref, int(args.positions), seed=2, thresholds_m=(TAU_M,), workers=args.workers)
    t_cond = time.perf_counter() - t
    rate_ref_again = args.reference_draws / _time(lambda: reference_fraction(model, *ref, int(args.reference_draws),
                                                                             seed=3))

    e_b, e_c = brute.estimate(TAU_M), cond.estimate(TAU_M)
    print(f"reference (chunked NumPy): {rate_ref / 1e6:.2f} M draws/s (again at the end: {rate_ref_again / 1e6:.2f})")
    print(f"brute force (compiled, {args.workers} workers): {rate_bf / 1e6:.2f} M draws/s")
    ratio = rate_bf / min(rate_ref, rate_ref_again), rate_bf / max(rate_ref, rate_ref_again)
    print(f"ratio brute force / reference: {ratio[1]:.1f} to {ratio[0]:.1f}  (target >= 9)")
    print(f"projected 1e9 draws: brute force {1e9 / rate_bf:.0f} s, reference {1e9 / rate_ref:.0f} s "
          "(on this machine, under its current load)")
    print(f"fraction δ < 15 cm: brute force {e_b}")
    print(f"                    conditional {e_c}  [{t_cond:.1f} s]")
    # relative half-width of 1e9 brute-force draws at this fraction: z sqrt((1 − p) / (p n))
    p = e_c.fraction
    rel_1e9 = 1.96 * np.sqrt((1 - p) / (p * 1e9))
    rel_c = (e_c.ci_high - e_c.ci_low) / 2 / p
    need = int(args.positions * (rel_c / rel_1e9) ** 2)
    print(f"relative 95 % half-width: 1e9 brute-force draws {100 * rel_1e9:.1f} %; conditional now "
          f"{100 * rel_c:.1f} % -> {need:.3g} positions ({need / args.positions * e_c.n_draws:.3g} exact δ "
          f"evaluations, ~{need / args.positions * t_cond:.0f} s) for the same width")


def _time(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


if __name__ == "__main__":
    main()
