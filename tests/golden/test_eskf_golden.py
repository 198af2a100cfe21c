"""Every UWB/INS fusion configuration gives the recorded outputs to the bit (see
:mod:`tests.golden.eskf_cases`).

A refactor leaves the file unchanged; an intended numerical change is a separate commit that
rewrites it (``python -m tests.golden.eskf_cases``) and says why.
"""

import pytest

from tests.golden import assert_digest, assert_reproduces, eskf_cases


@pytest.fixture(scope="module")
def recomputed():
    return eskf_cases.arrays(eskf_cases.runs())


def test_golden_file_is_what_its_digest_says():
    assert_digest(eskf_cases)


def test_every_fusion_configuration_reproduces_the_golden_outputs_exactly(recomputed):
    assert_reproduces(recomputed, eskf_cases)


def test_golden_cases_exercise_the_gate_the_outage_and_both_paths(recomputed):
    status = {k.split("/")[0]: v for k, v in recomputed.items() if k.endswith("/status")}
    assert (status["tight-p0.6-max2-compiled"] == 2).sum() > 0            # gated epochs
    assert (status["loose2d-gated"] == 2).sum() > 0
    assert (status["tight-outage-compiled"] == 1).sum() > 0                # predicted only (outage)
    assert len(status["tight-outage-absent-compiled"]) < len(status["tight-outage-compiled"])
    assert {k.rsplit("-", 1)[1] for k in status if k.startswith("tight")} == {"compiled", "reference"}
