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


@pytest.hookimpl(trylast=True)      # after -k / -m have deselected
def pytest_collection_modifyitems(config, items):
    """Note which project notebooks the browser test runs in this session (``browser_support.browser_runs``):
    there each notebook is executed once, and the tests that would execute it again read that run instead."""
    from tests.browser_support import BROWSER_RUN

    config.uwbwb_browser_runs = {item.nodeid[len(BROWSER_RUN):-1] for item in items
                                 if item.nodeid.startswith(BROWSER_RUN)}
    # The files that execute notebooks first (the browser test's before the rest), each file's tests together and
    # in their order: `make test` hands whole files to its workers in this order (``--no-loadscope-reorder``), so
    # the longest files start at once instead of ending the run alone on one worker.
    rank: dict = {}
    for item in items:
        own = 0 if item.get_closest_marker("browser") else 1 if item.get_closest_marker("notebook") else 2
        rank[item.path] = min(rank.get(item.path, own), own)
    items.sort(key=lambda item: rank[item.path])
