"""Shared test fixtures."""

import numpy as np
import pytest

from uwbwb.datasets import dataset_available, find_dataset


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def real_dataset(name: str):
    """Root of a real dataset, or skip the test with the reason."""
    if not dataset_available(name):
        pytest.skip(f"real dataset {name!r} not found (set UWBWB_DATA or run "
                    f"`python -m uwbwb fetch {name}`)")
    return find_dataset(name)
