"""The robust mean's compiled loops against the NumPy code they replaced (notebook 02's largest costs).

:func:`uwbwb.filters.pruning.tuple_fixes` localises every epoch from every anchor triplet (56 with
eight anchors): it used to put all epoch × triplet rows through :func:`uwbwb.geometry.multilaterate`
at once, the other anchors' ranges masked, and now solves each row in a compiled loop with the same
steps. :func:`uwbwb.filters.pruning.robust_mean` on a static cloud iterates "drop the furthest 1 %,
recompute the centroid" in a compiled loop instead of NumPy calls. Each pair is a declared twin
(:data:`uwbwb.filters.twins.TWINS`), run here on the twin's own input: a LIAS-like room (eight
anchors near one plane, NLOS excess on 10 % of the ranges), 300 epochs, about one notebook 02
static pose at its full-mode stride (some 14 000 triplet fixes).

Printed: CPU milliseconds of each side per call (after compilation, ``--repeat`` calls), their
ratio, and the largest difference of the outputs.

Run:  python benchmarks/bench_robust_mean.py [--repeat R]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uwbwb.filters import twins


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    for name in ("pruning.tuple_fixes", "pruning.robust_mean[static]"):
        twin = twins.TWINS[name]
        inputs = twin.inputs()
        twin.fast(inputs)                                       # compile (or load the cache)
        ms = {}
        for side, fn in (("compiled", twin.fast), ("NumPy (reference)", twin.definition)):
            t0 = time.process_time()
            for _ in range(args.repeat):
                out = fn(inputs)
            ms[side] = (time.process_time() - t0) / args.repeat * 1e3
        fast, ref = twin.fast(inputs), twin.definition(inputs)
        diff = max(float(np.max(np.abs(np.asarray(fast[k], float) - np.asarray(ref[k], float)))) for k in ref)
        print(f"{name:>28}: compiled {ms['compiled']:7.1f} ms, NumPy {ms['NumPy (reference)']:7.1f} ms CPU per call: "
              f"{ms['NumPy (reference)'] / ms['compiled']:.0f}x; largest output difference {diff:.1e}")


if __name__ == "__main__":
    main()
