"""Golden outputs of the estimators, and the one comparison every golden test makes."""

import numpy as np


def stored_arrays(cases) -> tuple[dict, str]:
    """The arrays of ``cases.GOLDEN`` (without the platform fingerprint) and that fingerprint."""
    stored = np.load(cases.GOLDEN)
    return {k: stored[k] for k in stored.files if k != "__fingerprint__"}, str(stored["__fingerprint__"])


def assert_digest(cases) -> None:
    """The golden file holds what its ``.sha256`` file says (nobody rewrote one without the other)."""
    flat, _ = stored_arrays(cases)
    assert cases.digest(flat) == cases.DIGEST.read_text().split()[0]


def assert_reproduces(recomputed: dict, cases) -> None:
    """``recomputed`` equals the golden arrays: to the bit (NaNs in the same places) on the platform that
    wrote them; elsewhere, where another numpy/BLAS may round the last bits differently, to 1e-9 relative
    (digests, keys ending in ``_sha256``, are comparable only on the same platform)."""
    stored, fp = stored_arrays(cases)
    assert sorted(recomputed) == sorted(stored)
    same_platform = fp == cases.fingerprint()
    for key, value in recomputed.items():
        want = stored[key]
        assert value.dtype == want.dtype and value.shape == want.shape, key
        if same_platform:
            assert value.tobytes() == want.tobytes(), f"{key} differs from the golden output"
        elif not key.endswith("_sha256"):
            np.testing.assert_array_equal(np.isnan(value), np.isnan(want), err_msg=key)
            np.testing.assert_allclose(value, want, rtol=1e-9, atol=1e-12, err_msg=key)
