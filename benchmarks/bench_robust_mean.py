"""The robust mean's and residual pruning's compiled loops against the NumPy code they replaced (notebook 02's
largest costs).

:func:`uwbwb.filters.pruning.tuple_fixes` localises every epoch from every anchor triplet (56 with
eight anchors): it used to put all epoch × triplet rows through :func:`uwbwb.geometry.multilaterate`
at once, the other anchors' ranges masked, and now solves each row in a compiled loop with the same
steps. :func:`uwbwb.filters.pruning.robust_mean` on a static cloud iterates "drop the furthest 1 %,
recompute the centroid" in a compiled loop instead of NumPy calls. Each pair is a declared twin
(:data:`uwbwb.filters.twins.TWINS`), run here on the twin's own input: a LIAS-like room (eight
anchors near one plane, NLOS excess on 10 % of the ranges), 300 epochs, about one notebook 02
static pose at its full-mode stride (some 14 000 triplet fixes). Residual pruning re-solves eq. (1) some twenty
times a segment, and every BFGS step evaluates its residuals and Jacobian
(:meth:`uwbwb.models.track.LinearTrackRanges.residuals_jacobian`): one compiled loop over the ranges instead of
NumPy calls, timed on its twin's input (800 ranges of a 20 s walk), and inside a whole
:func:`uwbwb.filters.pruning.residual_pruning` of that walk (the NumPy side by ``compiled=False``).

Printed: CPU milliseconds of each side per call (after compilation, ``--repeat`` calls), their
ratio, and the largest difference of the outputs.

Run:  python benchmarks/bench_robust_mean.py [--repeat R]
"""

from __future__ import annotations

import argparse
import time

from functools import partialmethod

import numpy as np

from uwbwb.filters import twins
from uwbwb.filters.pruning import residual_pruning
from uwbwb.models.track import LinearTrackRanges
from uwbwb.types import RangeSamples


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    for name in ("pruning.tuple_fixes", "pruning.robust_mean[static]", "track.residuals_jacobian[2-D]"):
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

    residual_pruning_ratio(args.repeat)


def residual_pruning_ratio(repeat: int) -> None:
    """CPU of one residual pruning of the walk of the residuals twin, with the compiled and the NumPy residuals."""
    model, _, t, k, r = twins.TWINS["track.residuals_jacobian[2-D]"].inputs()
    samples = RangeSamples(t, k, r, tuple("ABCDEFGH"))
    kernel = LinearTrackRanges.residuals_jacobian
    ms, fits = {}, {}
    for side, compiled in (("compiled", True), ("NumPy", False)):
        LinearTrackRanges.residuals_jacobian = partialmethod(kernel, compiled=compiled)
        try:
            fits[side] = residual_pruning(samples, model.anchor_pos_m, dim=2, z_m=model.z_m)
            t0 = time.process_time()
            for _ in range(repeat):
                residual_pruning(samples, model.anchor_pos_m, dim=2, z_m=model.z_m)
            ms[side] = (time.process_time() - t0) / repeat * 1e3
        finally:
            LinearTrackRanges.residuals_jacobian = kernel
    same = np.array_equal(fits["compiled"].fit.theta, fits["NumPy"].fit.theta)
    print(f"{'residual_pruning (800 ranges)':>28}: compiled residuals {ms['compiled']:7.1f} ms, NumPy {ms['NumPy']:7.1f} "
          f"ms CPU per call: {ms['NumPy'] / ms['compiled']:.2f}x; {fits['NumPy'].n_rounds} rounds; "
          f"same solution bit for bit: {same}")


if __name__ == "__main__":
    main()
