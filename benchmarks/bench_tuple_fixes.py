"""The robust mean's tuple fixes: the compiled loop against the batched multilateration it replaced.

:func:`uwbwb.filters.pruning.tuple_fixes` localises every epoch from every anchor triplet (56 with
eight anchors). It used to put all epoch × triplet rows through :func:`uwbwb.geometry.multilaterate`
at once, the other anchors' ranges masked; it now solves each row in a compiled loop with the same
steps (:data:`uwbwb.filters.twins.TWINS` ``["pruning.tuple_fixes"]`` holds the two equal). Input:
the twin's LIAS-like room (eight anchors near one plane, NLOS excess on 10 % of the ranges),
``--epochs`` epochs, about the size of one notebook 02 static pose at its full-mode stride.

Printed: CPU seconds of each over ``--repeat`` calls (after compilation), their ratio, and the
largest position difference.

Run:  python benchmarks/bench_tuple_fixes.py [--epochs N] [--repeat R]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uwbwb.filters import twins


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    twin = twins.TWINS["pruning.tuple_fixes"]
    r, A, z = twin.inputs()
    reps = -(-args.epochs // r.shape[0])
    inputs = (np.tile(r, (reps, 1))[:args.epochs], A, z)
    twin.fast(inputs)                                           # compile (or load the cache)
    times = {}
    for name, fn in (("compiled loop", twin.fast), ("batched multilaterate (reference)", twin.definition)):
        t0 = time.process_time()
        for _ in range(args.repeat):
            out = fn(inputs)
        times[name] = (time.process_time() - t0) / args.repeat
        print(f"{name:>36}: {times[name] * 1e3:8.1f} ms CPU per call, {len(out['pos_m'])} fixes")
    fast, ref = twin.fast(inputs), twin.definition(inputs)
    print(f"{'ratio':>36}: {times['batched multilaterate (reference)'] / times['compiled loop']:.0f}x; "
          f"largest position difference {np.max(np.abs(fast['pos_m'] - ref['pos_m'])):.1e} m")


if __name__ == "__main__":
    main()
