"""Shared simulated runs of the notebook 03 study tests."""

import numpy as np
import pytest

from uwbwb.experiments import motion_models as mm
from uwbwb.sim import walk


@pytest.fixture(scope="module")
def office_runs():
    cal, _ = mm.synthetic_acquisition("office", seed=1, duration_s=25.0, role="calibration")
    test, _ = mm.synthetic_acquisition("office", seed=1, duration_s=25.0)
    return cal, test


@pytest.fixture(scope="module")
def los_run():
    """An office walk with no obstacles and no body shadowing: pure DWM1000 LOS noise."""
    cfg = walk.office(duration_s=30.0, obstacles=(), tags=(walk.TagMount("tag1", 0, 0, 1.8),), p_missing_los=0.0)
    rec, _ = walk.simulate_walk(cfg, rng=np.random.default_rng(9))
    return mm.tag_runs(rec, dim=2, z_m={"tag1": 1.8})[0]
