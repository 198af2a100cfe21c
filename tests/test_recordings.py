"""Recording helpers every notebook shares: thinning, mount height, load-or-stand-in, data banner."""

import dataclasses

import numpy as np
import pytest

from uwbwb.widgets import data_banner

from uwbwb import widgets
from uwbwb.calibration import tag_mount_height
from uwbwb.datasets import load_lias_room
from uwbwb.errors import DataNotFoundError
from uwbwb.sim import rig
from uwbwb.types import Anchors, RangeLog, Recording, Trajectory
from tests.fixtures import lias as fx

SMALL_RIG = rig.RigConfig(duration_s=4.0)


def _recording(n=25, truth_t_s=None, z_m=1.0):
    t = np.arange(n) * 0.1
    anchors = Anchors(("a0", "a1", "a2"), np.array([[0.0, 0, 2], [5, 0, 2], [0, 5, 2]]))
    log = RangeLog(t, np.full((n, 3), 3.0), anchors.ids, "t0")
    tt = t if truth_t_s is None else truth_t_s
    truth = Trajectory(tt, np.column_stack([np.ones_like(tt), np.ones_like(tt), np.full_like(tt, z_m)]))
    return Recording("synthetic", "r", anchors, {"t0": log}, {"t0": truth}, meta={"x": 1})


def test_decimate_thins_ranges_and_truth_on_the_range_epochs():
    rec = _recording(25)
    d = rec.decimate(10)
    assert np.array_equal(d.ranges["t0"].t_s, rec.ranges["t0"].t_s[::10])
    assert np.array_equal(d.truth["t0"].t_s, d.ranges["t0"].t_s)
    assert d.meta == {"x": 1, "decimated": 10}
    assert d.decimate(3).meta["decimated"] == 30


def test_decimate_keeps_truth_on_its_own_clock_whole():
    rec = _recording(25, truth_t_s=np.arange(0, 2.6, 0.01))
    d = rec.decimate(5)
    assert len(d.ranges["t0"]) == 5
    assert d.truth["t0"] is rec.truth["t0"]


@pytest.mark.parametrize("step", [0, -2, 2.0, True, "3"])
def test_decimate_rejects_a_bad_step(step):
    with pytest.raises(ValueError, match="positive integer"):
        _recording().decimate(step)


def test_decimate_by_one_is_the_same_recording():
    rec = _recording()
    assert rec.decimate(1) is rec


def test_mount_height_comes_from_the_static_poses_and_reports_its_range_effect():
    rng = np.random.default_rng(3)
    static, _ = rig.simulate_static(SMALL_RIG, duration_s=1.0, rng=rng)
    h = tag_mount_height(static)
    offsets_z = np.asarray(SMALL_RIG.tag_offsets_m)[:, 2]
    assert h.z_m == pytest.approx(SMALL_RIG.centroid_z_m + np.median(offsets_z), abs=1e-9)
    assert set(h.per_tag_m) == set(static[0].tags)
    # the rig's anchors sit above the tags: a height error moves ranges, but by less than itself
    assert 0 < h.range_slope < 1
    assert h.range_change_m(0.1) == pytest.approx(0.1 * h.range_slope)


def test_mount_height_refuses_a_moving_recording():
    rng = np.random.default_rng(3)
    dynamic, _ = rig.simulate_dynamic(SMALL_RIG, rng=rng)
    moving = dataclasses.replace(dynamic, truth={t: Trajectory(tr.t_s, tr.pos_m + np.c_[0 * tr.t_s, 0 * tr.t_s,
                                                                                       tr.t_s])
                                                 for t, tr in dynamic.truth.items()})
    with pytest.raises(ValueError, match="not a static calibration pose"):
        tag_mount_height([moving])
    with pytest.raises(ValueError, match="at least one"):
        tag_mount_height([])


def test_mount_height_of_lias_static_poses_is_the_declared_rig_height(tmp_path):
    from uwbwb.datasets import lias

    rng = np.random.default_rng(5)
    fx.make_tree(tmp_path, rng=rng, dynamic={"medium": {"duration_s": 5.0}}, sessions=[fx.session_814(rng)])
    static = lias.load_static("8.14", tmp_path, centroid_z_m=0.8)
    h = tag_mount_height(static)
    assert h.z_m == pytest.approx(0.8, abs=0.005)
    assert "declared" in h.source and "0.800" in h.source


def test_absent_lias_gives_the_stand_in_with_the_reason(tmp_path):
    room = load_lias_room(tmp_path, stand_in=SMALL_RIG, static_duration_s=1.0, rng=np.random.default_rng(0))
    assert room.synthetic and not room.real and room.dynamic is not None
    assert room.data_label == "synthetic"
    assert "not found" in room.reason
    assert len(room.static) == 30 and room.dynamic.dataset == "synthetic"
    html = data_banner(**room.banner_args()).data
    assert "not available" in html and "synthetic stand-in" in html


def test_absent_lias_without_stand_in_gives_nothing(tmp_path):
    room = load_lias_room(tmp_path)
    assert room.dynamic is None and not room.static
    assert "skipped" in data_banner(**room.banner_args()).data
    with pytest.raises(ValueError, match="no data"):
        room.data_label


def test_stand_in_is_the_same_for_the_same_seed(tmp_path):
    a = load_lias_room(tmp_path, stand_in=SMALL_RIG, static_duration_s=1.0, rng=np.random.default_rng(4))
    b = load_lias_room(tmp_path, stand_in=SMALL_RIG, static_duration_s=1.0, rng=np.random.default_rng(4))
    assert np.array_equal(a.dynamic.ranges["t0"].range_m, b.dynamic.ranges["t0"].range_m, equal_nan=True)


def test_another_lias_recording_loads_and_a_missing_one_says_why(tmp_path):
    rng = np.random.default_rng(6)
    fx.make_tree(tmp_path, rng=rng, dynamic={"medium": {"duration_s": 5.0}}, sessions=[fx.session_814(rng)])
    room = load_lias_room(tmp_path, "medium", "8.14")
    assert room.real and room.data_label == "lias-planar-uwb/medium"
    assert room.static and all(r.meta["session"] == "8.14" for r in room.static)
    yaws = {r.meta["nominal_yaw_deg"] for r in room.static}
    first = sorted(yaws)[0]
    only = load_lias_room(tmp_path, "medium", "8.14", static_yaws=[first])
    assert {r.meta["nominal_yaw_deg"] for r in only.static} == {first}
    assert "found" in data_banner(**room.banner_args()).data
    with pytest.raises(DataNotFoundError, match="medium"):
        load_lias_room(tmp_path, "fast", "8.14")


def test_banner_escapes_its_text():
    html = widgets.data_banner("x<y", False, detail="a & b", instead="skip <this>").data
    assert "x&lt;y" in html and "a &amp; b" in html and "skip &lt;this&gt;" in html
    assert "uwbwb-data-banner" in html
