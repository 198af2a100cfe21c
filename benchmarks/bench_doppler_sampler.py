"""Throughput of the Doppler solution-space samplers against chunked-NumPy references.

All estimate the fraction of the 6-D box (X ∈ [−5, 5]³ m, V ∈ [−3, 3]³ m/s) whose
δ = v_s ‖ΔP_ref − ΔP(X, V)‖ is under 15 cm, for the cubic layout and the reference pair
of paper 003, section 3:

* **reference (as before)** — chunked NumPy through the model's methods
  (``delta_p`` then ``distance_m``), chunks of 10⁶ draws;
* **reference (plain eq 1)** — chunked NumPy that evaluates eq 1 directly on
  ``(n, beacons, 3)`` arrays and compares δ² with τ² (no square root, no model
  overhead), chunks of 2¹⁶ draws: the faster NumPy reading, one thread like the first;
* **brute force** — :func:`uwbwb.sampling.brute_force`: the same uniform draws (the same
  stream as NumPy), compiled; timed with 1 thread and with ``--workers`` threads, each with
  its early exit (a draw abandoned once its partial δ exceeds the threshold) and without it
  (a second threshold of 10⁹ m keeps every beacon evaluated);
* **conditional** — :func:`uwbwb.sampling.conditional`: uniform positions, the velocity
  handled per position through its δ-ellipsoid;
* **ellipsoids** — the conditional sampler's set-up per position (the ellipsoid's centre, Cholesky factor and
  radius), compiled (:func:`uwbwb.sampling._ellipsoids`) against its NumPy definition (the declared twin in
  ``uwbwb/filters/twins.py``) on the same positions, one thread, CPU time.

Printed: draws (positions) per second of each (timed in this process, after compilation) and three
ratios side by side — the figure reported so far (brute force on ``--workers`` threads
with early exit over the model-method reference on one), the like-for-like ratio (brute
force on one thread *without* early exit over the plain-eq-1 reference on one thread), and
the factors that separate them (early exit, threads, reference) — plus the projected time
for 10⁹ draws (target ≤ 2 min) and, for the conditional estimator, the positions and exact
δ evaluations it needs for the relative interval half-width of 10⁹ brute-force draws.

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
    """Chunked NumPy through the model's methods: draw, ``delta_p`` for every beacon, ``distance_m``, count δ < τ."""
    rng = np.random.default_rng(seed)
    b = model.delta_p(ref_pos, ref_vel)
    hits = 0
    for start in range(0, n, chunk):
        m = min(chunk, n - start)
        u = rng.random((m, 6))
        X, V = -5 + 10 * u[:, :3], -3 + 6 * u[:, 3:]
        hits += int(np.count_nonzero(model.distance_m(model.delta_p(X, V), b) < TAU_M))
    return hits / n


def reference_plain(model, ref_pos, ref_vel, n, *, seed, chunk=1 << 16):
    """Chunked NumPy, eq 1 written out: ``g_i = v_s P_i r_i / (1 − r_i) − b_i``, count ``Σ g² < τ²``."""
    rng = np.random.default_rng(seed)
    T, P, v_s = model.beacons.pos_m, model.period_s, model.v_s_mps
    b = v_s * model.delta_p(ref_pos, ref_vel)
    hits = 0
    for start in range(0, n, chunk):
        m = min(chunk, n - start)
        u = rng.random((m, 6))
        X, V = -5 + 10 * u[:, :3], -3 + 6 * u[:, 3:]
        d = X[:, None, :] - T
        r = np.einsum("nbk,nk->nb", d, V) / (np.sqrt(np.einsum("nbk,nbk->nb", d, d)) * v_s)
        g = (v_s * P) * r / (1.0 - r) - b
        hits += int(np.count_nonzero(np.einsum("nb,nb->n", g, g) < TAU_M * TAU_M))
    return hits / n


def ellipsoid_rates(n: int, *, seed=4) -> dict[str, float]:
    """Positions per CPU second of the ellipsoid set-up, compiled and by its twin's NumPy definition."""
    from uwbwb.filters import twins

    a = twins._ellipsoid_inputs(False)()
    a["X"] = np.random.default_rng(seed).uniform(-5.0, 5.0, (n, 3))
    twins._ellipsoid_fast(dict(a, X=a["X"][:100]))                    # compile outside the timing
    rates = {}
    for name, fn in (("ellipsoids, compiled", twins._ellipsoid_fast), ("ellipsoids, NumPy definition",
                                                                      twins._ellipsoid_definition)):
        t = time.process_time()
        for start in range(0, n, 1 << 15):                             # the sampler's chunk size
            fn(dict(a, X=a["X"][start:start + (1 << 15)]))
        rates[name] = n / (time.process_time() - t)
    return rates


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=float, default=2e7, help="draws for the compiled brute force")
    ap.add_argument("--reference-draws", type=float, default=3e6, help="draws for the NumPy references")
    ap.add_argument("--positions", type=float, default=5e5, help="positions for the conditional estimator")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    model = dm.DopplerModel.for_layout(dm.cubic_layout())
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    n_ref, n_bf = int(args.reference_draws), int(args.draws)

    smp.brute_force(model, *ref, 10_000, seed=0, workers=1)           # compile outside the timing
    rate = {}
    rate["reference (as before)"] = n_ref / _time(lambda: reference_fraction(model, *ref, n_ref, seed=0))
    rate["reference (plain eq 1)"] = n_ref / _time(lambda: reference_plain(model, *ref, n_ref, seed=0))
    for w in sorted({1, args.workers}):
        for early, th in (("early exit", (TAU_M,)), ("no early exit", (TAU_M, 1e9))):
            rate[f"brute force, {w} thread(s), {early}"] = n_bf / _time(
                lambda: smp.brute_force(model, *ref, n_bf, seed=1, thresholds_m=th, keep_below_m=None, workers=w))
    t = time.perf_counter()
    cond = smp.conditional(model, *ref, int(args.positions), seed=2, thresholds_m=(TAU_M,), workers=args.workers)
    t_cond = time.perf_counter() - t
    rate["reference (as before), again"] = n_ref / _time(lambda: reference_fraction(model, *ref, n_ref, seed=3))
    rate["reference (plain eq 1), again"] = n_ref / _time(lambda: reference_plain(model, *ref, n_ref, seed=3))

    for k, v in rate.items():
        print(f"{k:45s} {v / 1e6:8.2f} M draws/s")
    ell = ellipsoid_rates(int(args.positions))
    for k, v in ell.items():
        print(f"{k:45s} {v / 1e6:8.2f} M positions per CPU second")
    print(f"ratio ellipsoids (compiled / NumPy definition, 1 thread, CPU time): "
          f"{ell['ellipsoids, compiled'] / ell['ellipsoids, NumPy definition']:.1f}")
    old_ref = min(rate["reference (as before)"], rate["reference (as before), again"])
    new_ref = max(rate["reference (plain eq 1)"], rate["reference (plain eq 1), again"])
    w = args.workers
    current = rate[f"brute force, {w} thread(s), early exit"] / old_ref
    like = rate["brute force, 1 thread(s), no early exit"] / new_ref
    print(f"ratio as reported so far ({w} threads + early exit / model-method reference, 1 thread): {current:.1f}")
    print(f"ratio like for like (1 thread, no early exit / plain-eq-1 reference, 1 thread):     {like:.1f}")
    print(f"  factors: early exit x{rate['brute force, 1 thread(s), early exit'] / rate['brute force, 1 thread(s), no early exit']:.2f}, "
          f"threads x{rate[f'brute force, {w} thread(s), early exit'] / rate['brute force, 1 thread(s), early exit']:.2f}, "
          f"faster reference x{new_ref / old_ref:.2f}")
    best = rate[f"brute force, {w} thread(s), early exit"]
    print(f"projected 1e9 draws: brute force {1e9 / best:.0f} s ({w} threads, early exit; target <= 120 s), "
          f"plain-eq-1 reference {1e9 / new_ref:.0f} s (on this machine, under its current load)")
    brute = smp.brute_force(model, *ref, n_bf, seed=1, thresholds_m=(TAU_M,), keep_below_m=None, workers=w)
    e_b, e_c = brute.estimate(TAU_M), cond.estimate(TAU_M)
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
