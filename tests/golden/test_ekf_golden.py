"""Every EKF configuration gives the recorded outputs to the bit (see :mod:`tests.golden.ekf_cases`).

The golden file was written before the gate became an injected policy; an intended numerical
change is a separate commit that rewrites it (``python -m tests.golden.ekf_cases``) and says why.
"""

import numpy as np
import pytest

from tests.golden import ekf_cases


@pytest.fixture(scope="module")
def recomputed():
    return ekf_cases.arrays(ekf_cases.runs())


def test_golden_file_is_what_its_digest_says():
    stored = np.load(ekf_cases.GOLDEN)
    flat = {k: stored[k] for k in stored.files if k != "__fingerprint__"}
    assert ekf_cases.digest(flat) == ekf_cases.DIGEST.read_text().split()[0]


def test_every_ekf_configuration_reproduces_the_golden_outputs_exactly(recomputed):
    stored = np.load(ekf_cases.GOLDEN)
    assert sorted(recomputed) == sorted(k for k in stored.files if k != "__fingerprint__")
    same_platform = str(stored["__fingerprint__"]) == ekf_cases.fingerprint()
    for key, value in recomputed.items():
        want = stored[key]
        assert value.dtype == want.dtype and value.shape == want.shape, key
        if same_platform:
            # bit for bit, NaNs in the same places
            assert value.tobytes() == want.tobytes(), f"{key} differs from the golden output"
        else:
            # another numpy/BLAS may round the last bits differently; the structure must still agree
            np.testing.assert_array_equal(np.isnan(value), np.isnan(want), err_msg=key)
            np.testing.assert_allclose(value, want, rtol=1e-9, atol=1e-12, err_msg=key)


def test_golden_cases_exercise_every_gate_path(recomputed):
    # the comparison means something only if the cases gate epochs and drop anchors
    status = {k.split("/")[0]: v for k, v in recomputed.items() if k.endswith("/status")}
    rejected = {k.split("/")[0]: v for k, v in recomputed.items() if k.endswith("/n_rejected")}
    assert (status["fix-default"] == 2).sum() > 0 and (status["fix-nogate"] == 2).sum() == 0
    assert rejected["tdoa2d-RF-default"].sum() > 0 and rejected["tdoa2d-RF-nogate"].sum() == 0
    assert (status["tdoa2d-RW-offprior-skip4"] == 2).sum() > 10
