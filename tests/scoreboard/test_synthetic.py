from dataclasses import replace

import numpy as np
import pytest

from uwbwb.models.motion import RandomForce, RandomJerk
from uwbwb.scoreboard import synthetic as syn


def test_a_motion_object_drives_the_run_like_its_psd_bit_for_bit():
    cfg = syn.SyntheticConfig()
    model = RandomForce(0.4, dim=2)
    a = syn.simulate(cfg, rng=np.random.default_rng(1), motion=model)
    b = syn.simulate(replace(cfg, psd_m2ps3=0.4), rng=np.random.default_rng(1))
    assert a.meta["config"] == b.meta["config"] and a.meta["config"].motion == model
    np.testing.assert_array_equal(a.meta["truth_state"], b.meta["truth_state"])
    np.testing.assert_array_equal(a.ranges["tag"].range_m, b.ranges["tag"].range_m)
    plain = syn.simulate(cfg, rng=np.random.default_rng(1))
    own = syn.simulate(cfg, rng=np.random.default_rng(1), motion=cfg.motion)
    np.testing.assert_array_equal(plain.meta["truth_state"], own.meta["truth_state"])
    assert not np.array_equal(plain.meta["truth_state"], a.meta["truth_state"])
    assert cfg.motion == RandomForce(cfg.psd_m2ps3, dim=2) and cfg.with_motion(None) is cfg
    for bad in (RandomForce(0.4, dim=3), RandomJerk(0.4)):
        with pytest.raises(ValueError, match="2-D RandomForce"):
            syn.simulate(cfg, rng=np.random.default_rng(1), motion=bad)
