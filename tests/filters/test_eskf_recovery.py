"""The fusion filters recover: in-motion heading alignment on i-ASL-format flights at low UWB
rates, and re-acquisition after a UWB outage (no epochs, or epochs present but empty)."""

import numpy as np
import pytest

from tests.fixtures import iasl as fx
from uwbwb.filters import eskf
from uwbwb.models.imu import GRADES
from uwbwb.sim import robot
from uwbwb.types import EstimateStatus

SEEDS = range(8)


@pytest.fixture(scope="module")
def iasl_flights(tmp_path_factory):
    """One calibration flight and eight scored flights (30 s each) in the upstream format."""
    from uwbwb.datasets import iasl
    from uwbwb.experiments.uwb_ins import study

    data = tmp_path_factory.mktemp("iasl")
    root = data / "iasl-uwb-imu"
    root.mkdir()
    (root / "uwb.yaml").write_text(fx.YAML_TEXT)
    fx.write_scenario(root / "cal", rng=np.random.default_rng(100), duration_s=30.0)
    for s in SEEDS:
        fx.write_scenario(root / f"flight{s}", rng=np.random.default_rng(s), duration_s=30.0)
    cal = study.calibrate_iasl(iasl.load_scenario("cal", data))
    return data, cal


@pytest.mark.parametrize("rate_hz", [5.0, 10.0, None], ids=["5Hz", "10Hz", "native"])
def test_in_motion_heading_alignment_does_not_lock_the_filters_out(iasl_flights, rate_hz):
    """The board's start-up (levelling, then tight range filter from yaw 0 ± 60° for the
    alignment window) on eight flights per rate: every fusion filter tracks afterwards (RMSE
    below 0.5 m; UWB-only is about 0.02 m, and at 5 Hz a few runs stay at 0.1–0.25 m).
    Before the start-up gate rule the filters diverged (28–600 m) at 5 Hz on most seeds and
    at 10 Hz on some: the χ² gate rejected every range while the heading was unresolved."""
    from uwbwb.datasets import iasl
    from uwbwb.experiments.uwb_ins import study
    from uwbwb.scoreboard.protocol import thin

    data, cal = iasl_flights
    worst = {}
    for s in SEEDS:
        rec = thin(iasl.load_scenario(f"flight{s}", data), rate_hz)
        t = study.compare_iasl(rec, cal, still_s=1.0, align_s=10.0).table()
        for name in ("tight", "tight (ranges)", "loose"):
            worst[(s, name)] = float(t.loc[name, "RMSE (m)"])
        assert t.loc["tight", "coverage"] > 0.95
    bad = {k: v for k, v in worst.items() if not v < 0.5}
    assert not bad, bad
