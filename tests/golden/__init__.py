"""Golden outputs of the estimators, and the one comparison every golden test makes.

What "the same numbers" means here:

* **On one machine, bit for bit.** Two runs of a case in the same environment give identical bytes
  (``test_same_machine.py`` runs every case again in a second process and compares the bytes).
* **Across machines, to a stated tolerance.** A golden file was written on one machine; on another, the
  BLAS kernel OpenBLAS picks for the CPU and NumPy's SIMD paths (AVX2, AVX-512, ...) sum the same products
  in another order, so the last bits differ, and a filter carries those differences on from epoch to
  epoch. Each float array must be within :data:`RTOL` of its largest golden element; NaNs in the same
  places; integer and boolean arrays (status, gate counts, resampling counts) exactly equal.
"""

import numpy as np

#: Normwise relative tolerance of a recomputed float array against its golden: ``|new − golden| <=
#: RTOL · max|golden|`` elementwise. Measured across OpenBLAS's Prescott, Haswell and SkylakeX kernels,
#: with NumPy's optional SIMD paths on and off, the largest difference was 2.6e-12 of the array's largest
#: element (the tight ESKF's velocity after its gated epochs); 1e-9 of a metre is a nanometre.
RTOL = 1e-9


def computed(cases) -> dict[str, np.ndarray]:
    """Every case of a ``*_cases`` module, computed now: the flat ``{"<case>/<field>": array}`` dictionary."""
    return cases.arrays(cases.runs()) if hasattr(cases, "runs") else cases.arrays()


def stored_arrays(cases) -> tuple[dict, str]:
    """The arrays of ``cases.GOLDEN`` (without the platform fingerprint) and that fingerprint."""
    stored = np.load(cases.GOLDEN)
    return {k: stored[k] for k in stored.files if k != "__fingerprint__"}, str(stored["__fingerprint__"])


def assert_digest(cases) -> None:
    """The golden file holds what its ``.sha256`` file says (nobody rewrote one without the other)."""
    flat, _ = stored_arrays(cases)
    assert cases.digest(flat) == cases.DIGEST.read_text().split()[0]


def mismatch(value: np.ndarray, want: np.ndarray) -> str | None:
    """Why ``value`` is not ``want`` under the cross-machine rule of this module, or None."""
    if value.dtype != want.dtype or value.shape != want.shape:
        return f"{value.dtype}{value.shape} against the golden {want.dtype}{want.shape}"
    if value.dtype.kind != "f":
        return None if np.array_equal(value, want) else "differs (integer or boolean: compared exactly)"
    if not np.array_equal(np.isnan(value), np.isnan(want)):
        return "NaN in other places"
    finite = np.isfinite(want)
    if not np.array_equal(value[~finite & ~np.isnan(want)], want[~finite & ~np.isnan(want)]):
        return "infinities differ"
    if not finite.any():
        return None
    scale = float(np.abs(want[finite]).max())
    worst = float(np.abs(value[finite] - want[finite]).max())
    return None if worst <= RTOL * scale else f"differs by {worst:.3g}, over {RTOL:g} x max|golden| = {RTOL * scale:.3g}"


def assert_reproduces(recomputed: dict, cases) -> None:
    """``recomputed`` equals the golden arrays of ``cases`` to the tolerance of this module (any machine)."""
    stored, _ = stored_arrays(cases)
    assert sorted(recomputed) == sorted(stored)
    problems = [f"{k}: {why}" for k in sorted(stored) if (why := mismatch(np.asarray(recomputed[k]), stored[k]))]
    assert not problems, "\n".join(problems)
