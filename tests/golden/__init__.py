"""Golden outputs of the estimators, and the one comparison every golden test makes.

What "the same numbers" means here:

* **On one machine, bit for bit.** Two runs of a case in the same environment give identical bytes
  (``test_same_machine.py`` runs every case again in a second process and compares the bytes).
* **Across machines, to a stated tolerance.** A golden file was written on one machine; on another, the
  BLAS kernel OpenBLAS picks for the CPU and NumPy's SIMD paths (AVX2, AVX-512, ...) sum the same products
  in another order, so the last bits differ, and a filter carries those differences on from epoch to
  epoch. Each element of a float array must be within :data:`RTOL` of its component's scale — the largest
  golden magnitude of that component over the epochs (the first axis; for a 1-D series, over the series),
  so a small variance beside a large one keeps its own scale; NaNs in the same places; integer and boolean
  arrays (status, gate counts, resampling counts) exactly equal.
"""

import numpy as np

#: Relative tolerance of a recomputed float array against its golden: ``|new − golden| <= RTOL · scale``
#: elementwise, ``scale`` the component's largest golden magnitude over the epochs. Measured on one AVX-512
#: machine across OpenBLAS's auto-selected, Prescott, Haswell and SkylakeX kernels, with NumPy's optional
#: SIMD paths on and off, against files written on another CPU: the largest difference was 1.6e-11 of its
#: component's scale (a tight-ESKF covariance entry); 1e-9 of a metre is a nanometre.
RTOL = 1e-9


def component_scale(want: np.ndarray) -> np.ndarray | float:
    """Largest finite magnitude per component over the epochs (axis 0) of a golden array; over the whole
    array for a 1-D series."""
    mag = np.where(np.isfinite(want), np.abs(want), 0.0)
    return mag.max(axis=0) if want.ndim >= 2 else float(mag.max(initial=0.0))


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
    allowed = RTOL * np.broadcast_to(component_scale(want), want.shape)
    excess = np.where(finite, np.abs(value - want) - allowed, -np.inf)
    if not (excess > 0).any():
        return None
    i = np.unravel_index(int(np.argmax(excess)), want.shape)
    return (f"differs at {tuple(int(j) for j in i)} by {abs(value[i] - want[i]):.3g}, over {RTOL:g} x its "
            f"component's scale = {allowed[i]:.3g}")


def assert_reproduces(recomputed: dict, cases) -> None:
    """``recomputed`` equals the golden arrays of ``cases`` to the tolerance of this module (any machine)."""
    stored, _ = stored_arrays(cases)
    assert sorted(recomputed) == sorted(stored)
    problems = [f"{k}: {why}" for k in sorted(stored) if (why := mismatch(np.asarray(recomputed[k]), stored[k]))]
    assert not problems, "\n".join(problems)
