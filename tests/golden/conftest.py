"""Each golden module's cases, computed once per session: the golden tests and the same-machine test share them."""

import pytest

from tests.golden import computed, doppler_cases, ekf_cases, eskf_cases


@pytest.fixture(scope="session")
def ekf_recomputed():
    return computed(ekf_cases)


@pytest.fixture(scope="session")
def eskf_recomputed():
    return computed(eskf_cases)


@pytest.fixture(scope="session")
def doppler_recomputed():
    return computed(doppler_cases)
