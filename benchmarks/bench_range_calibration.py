"""The range calibration's compiled IRLS against the NumPy iterations it replaced (notebook 03's LIAS section spent
three quarters of its time there; notebooks 01, 02 and 06 fit the same calibration on LIAS static poses).

:func:`uwbwb.calibration.fit_range_calibration` runs 30 IRLS iterations per anchor–tag pair, each a weighted line
fit and two medians over the pair's samples; the loop is :func:`uwbwb.calibration.twr._irls`, a declared twin
(:data:`uwbwb.filters.twins.TWINS`) of the NumPy iterations on every pair at once. Run here on an input built as
the twin's (ranges with a bias and scale per pair, noise, outliers, missing samples), with ``--rows`` rows of
3 tags × 8 anchors (default 330 000, a LIAS static session's size; the NumPy side then takes some 30 s).

Printed: CPU seconds of each side per call (after compilation), their ratio, and whether the outputs are equal.

Run:  python benchmarks/bench_range_calibration.py [--rows N]
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np

from uwbwb.filters import twins


def _inputs(rows: int):
    rng = np.random.default_rng(17)
    x = rng.uniform(1.0, 9.0, (rows, 3, 8))
    y = 1.01 * x + 0.2 + rng.normal(0.0, 0.05, x.shape) + (rng.random(x.shape) < 0.05) * rng.uniform(1, 3, x.shape)
    with_scale = np.ones((3, 8), bool)
    with_scale[2, 7] = False
    return x, y, rng.random(x.shape) > 0.1, with_scale, 30


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=330_000)
    args = ap.parse_args()
    twin = twins.TWINS["calibration._irls"]
    inputs = _inputs(args.rows)
    twin.fast(twin.inputs())                                    # compile (or load the cache)
    s, out = {}, {}
    for side, fn in (("compiled", twin.fast), ("NumPy", twin.definition)):
        a = copy.deepcopy(inputs)
        t0 = time.process_time()
        out[side] = fn(a)
        s[side] = time.process_time() - t0
    equal = all(np.array_equal(out["compiled"][k], out["NumPy"][k], equal_nan=True) for k in out["NumPy"])
    print(f"calibration._irls ({args.rows} rows x 24 pairs, 30 iterations): compiled {s['compiled']:6.2f} s, "
          f"NumPy {s['NumPy']:6.2f} s CPU: {s['NumPy'] / s['compiled']:.1f}x; outputs bit for bit equal: {equal}")


if __name__ == "__main__":
    main()
