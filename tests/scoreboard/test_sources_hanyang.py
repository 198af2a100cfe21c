"""``uwbwb score`` targets: a Hanyang dynamic case by folder or by registry name; a wrong name lists the names present."""

from __future__ import annotations

import numpy as np
import pytest

from tests.fixtures import hanyang as fx
from uwbwb.errors import DataNotFoundError
from uwbwb.scoreboard.sources import LOADERS, load_target


def test_a_case_folder_and_its_name_load_the_same_recording(tmp_path):
    data = tmp_path / "data"
    cases = fx.write_dynamic_tree(data / "hanyang-outdoor-uwb", rng=np.random.default_rng(6),
                                  cases=fx.DYNAMIC_CASES[:2], speed_mps=8.0)
    by_folder = load_target(str(cases[1].folder))
    by_name = load_target(f"hanyang-outdoor-uwb/{cases[1].name}", data)
    assert by_folder.label == by_name.label == f"hanyang-outdoor-uwb/{cases[1].name}"
    np.testing.assert_array_equal(by_folder.ranges["tag"].range_m, by_name.ranges["tag"].range_m)
    assert set(by_name.meta["authors_estimates"]) == {"LS", "ESKF"}
    assert "hanyang-outdoor-uwb" in LOADERS
    with pytest.raises(DataNotFoundError, match="has no recording .LOS/Trajectory_A/Case_9.*Names found.*LOS/Trajectory_A/Case_2"):
        load_target("hanyang-outdoor-uwb/LOS/Trajectory_A/Case_9", data)
