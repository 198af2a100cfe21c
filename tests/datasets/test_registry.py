"""One registry of recordings by name: wrong names are errors listing the names present, a stand-in
only where the caller asked for one and the dataset is absent, loaders can register."""

import numpy as np
import pytest

from tests.fixtures import iasl as fx_iasl
from tests.fixtures import lias as fx_lias
from uwbwb import Recording
from uwbwb.datasets import load_lias_room, registry
from uwbwb.datasets import open as open_recording
from uwbwb.datasets import open_pair
from uwbwb.errors import DataNotFoundError
from uwbwb.sim.rig import RigConfig


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    rng = np.random.default_rng(3)
    fx_iasl.write_dataset(root / "iasl-uwb-imu", rng=rng, duration_s=8.0)
    fx_lias.make_tree(root, rng=rng, dynamic={"medium": {"duration_s": 6.0, "clock_offset_s": 0.1}},
                      sessions=[fx_lias.session_814(rng, files=((1, 0), (2, 120)))], static_rows=24)
    return root


def test_names_lists_what_is_on_disk(data_dir):
    assert registry.names("iasl-uwb-imu", data_dir) == ["iasl-uwb-imu/scenario1", "iasl-uwb-imu/scenario2"]
    lias = registry.names("lias-planar-uwb", data_dir)
    assert lias[0] == "lias-planar-uwb/medium" and "lias-planar-uwb/8.14/pos2_deg_120" in lias


def test_open_loads_by_name(data_dir):
    rec = open_recording("iasl-uwb-imu/scenario2", data_dir)
    assert isinstance(rec, Recording) and rec.name.endswith("scenario2")
    assert open_recording("lias-planar-uwb/medium", data_dir).tags == ("t0", "t1", "t2")
    pose = open_recording("lias-planar-uwb/8.14/pos2_deg_120", data_dir)
    assert pose.meta["site"] == 2


def test_a_name_a_present_dataset_does_not_hold_is_an_error_listing_the_names(data_dir):
    with pytest.raises(DataNotFoundError, match="scenario9") as exc:
        open_recording("iasl-uwb-imu/scenario9", data_dir)
    assert "scenario1" in str(exc.value) and "scenario2" in str(exc.value)
    with pytest.raises(DataNotFoundError, match="medium"):
        open_recording("lias-planar-uwb/fsat", data_dir)


def test_absent_dataset_and_unknown_dataset(tmp_path, data_dir):
    with pytest.raises(DataNotFoundError, match="not found"):
        open_recording("iasl-uwb-imu/scenario1", tmp_path)
    with pytest.raises(ValueError, match="iasl-uwb-imu"):
        open_recording("no-such-dataset/x", data_dir)
    with pytest.raises(ValueError, match="scenario1"):
        open_recording("iasl-uwb-imu", data_dir)


def test_open_pair_refuses_to_calibrate_on_the_scored_recording(data_dir):
    cal, test = open_pair("iasl-uwb-imu/scenario1", "iasl-uwb-imu/scenario2", data_dir)
    assert cal.name.endswith("scenario1") and test.name.endswith("scenario2")
    with pytest.raises(ValueError, match="another recording"):
        open_pair("iasl-uwb-imu/scenario2", "iasl-uwb-imu/scenario2", data_dir)


def test_lias_room_wrong_recording_is_an_error_not_synthetic_data(tmp_path, data_dir):
    with pytest.raises(DataNotFoundError, match="fsat") as exc:
        load_lias_room(data_dir, "fsat", stand_in=RigConfig(duration_s=5.0), rng=np.random.default_rng(0))
    assert "medium" in str(exc.value) and "8.14" in str(exc.value)
    with pytest.raises(DataNotFoundError, match="8.99"):
        load_lias_room(data_dir, "medium", "8.99")
    room = load_lias_room(data_dir, "medium", "8.14")
    assert room.real and room.data_label == "lias-planar-uwb/medium" and room.banner_args()["found"]
    # the dataset absent: the stand-in the caller asked for, with the reason (the notebooks' CI path)
    empty = tmp_path / "empty"
    empty.mkdir()
    room = load_lias_room(empty, "fsat", stand_in=RigConfig(duration_s=5.0), static_duration_s=1.0,
                          rng=np.random.default_rng(0))
    assert room.synthetic and room.data_label == "synthetic" and "not found" in room.reason
    assert room.banner_args()["found"] is False and "stand-in" in room.banner_args()["instead"]
    assert load_lias_room(empty).dynamic is None


def test_quickstart_with_a_misspelt_recording_raises(data_dir):
    # notebook 00 loads through this: its cell raises, so `reproduce --only 00 -p RECORDING fsat` fails
    # (a raising notebook makes reproduce exit non-zero: tests/test_reproduce.py)
    from uwbwb.experiments.quickstart import study as qs

    with pytest.raises(DataNotFoundError, match="fsat"):
        qs.load(data_dir, "fsat", "8.14", fast=True)


def test_a_loader_can_register(monkeypatch, tmp_path):
    monkeypatch.setattr(registry, "_SOURCES", list(registry._SOURCES))
    (tmp_path / "toy-set").mkdir()
    registry.register(registry.Source("toy-set", lambda d: ["a", "b"], lambda name, d, **kw: f"toy {name} {kw}",
                                      "a letter"))
    assert "toy-set" in registry.datasets()
    assert open_recording("toy-set/b", tmp_path, scale=2) == "toy b {'scale': 2}"
    with pytest.raises(DataNotFoundError, match="a, b"):
        open_recording("toy-set/c", tmp_path)
    with pytest.raises(ValueError, match="Source"):
        registry.register("toy-set")


def test_a_tidy_folder_opens_by_path(tmp_path):
    paths = fx_iasl.write_tidy_sample(tmp_path / "tidy")
    folder = next(iter(paths.values())).parent
    rec = open_recording(folder)
    assert isinstance(rec, Recording) and len(rec.tags) == 2


def test_hanyang_dynamic_cases_are_registered_when_the_loader_is_installed(tmp_path):
    pytest.importorskip("uwbwb.datasets.hanyang_dynamic")
    from tests.fixtures import hanyang as fx_hanyang

    root = tmp_path / "hanyang-outdoor-uwb"
    cases = fx_hanyang.write_dynamic_tree(root, rng=np.random.default_rng(4))
    names = registry.names("hanyang-outdoor-uwb", tmp_path)
    assert {f"hanyang-outdoor-uwb/{c.name}" for c in cases} <= set(names)
    rec = open_recording(f"hanyang-outdoor-uwb/{cases[0].name}", tmp_path)
    assert isinstance(rec, Recording)
