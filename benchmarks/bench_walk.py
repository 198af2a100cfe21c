"""The walk simulator's compiled pursuit loop against the NumPy loop it replaced (notebook 03's largest cost: every
simulated acquisition steers its target at 100 Hz, some 12 000 steps per 120 s walk, and the seeds study simulates
thirty of them).

:func:`uwbwb.sim.walk.steer` finds at each step the nearest of the next path points, commands the velocity towards
a look-ahead point and advances the random-force model; the loop is :func:`uwbwb.sim.walk._steer_loop`, a declared
twin (:data:`uwbwb.filters.twins.TWINS`) of the NumPy loop, run here on the twin's own input (20 s, 2 000 steps).

Printed: CPU milliseconds of each side per call (after compilation, ``--repeat`` calls), their ratio, and the
largest difference of the outputs.

Run:  python benchmarks/bench_walk.py [--repeat R]
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np

from uwbwb.filters import twins


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    twin = twins.TWINS["walk._steer_loop"]
    inputs = twin.inputs()
    twin.fast(copy.deepcopy(inputs))                            # compile (or load the cache)
    ms, out = {}, {}
    for side, fn in (("compiled", twin.fast), ("NumPy", twin.definition)):
        copies = [copy.deepcopy(inputs) for _ in range(args.repeat)]
        t0 = time.process_time()
        for a in copies:
            out[side] = fn(a)
        ms[side] = (time.process_time() - t0) / args.repeat * 1e3
    diff = float(np.max(np.abs(out["compiled"]["x"] - out["NumPy"]["x"])))
    print(f"walk._steer_loop ({len(inputs[0]) - 1} steps): compiled {ms['compiled']:7.2f} ms, NumPy {ms['NumPy']:7.1f} "
          f"ms CPU per call: {ms['NumPy'] / ms['compiled']:.0f}x; largest output difference {diff:.1e}")


if __name__ == "__main__":
    main()
