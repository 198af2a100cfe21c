"""Tests for uwbwb.datasets.lias on synthetic trees in the upstream format (and on the real
data when it is present)."""


import numpy as np
import pandas as pd
import pytest

from tests.conftest import real_dataset
from tests.fixtures import lias as fx
from uwbwb import DataFormatError, DataNotFoundError, Recording
from uwbwb.datasets import lias, registration

OFFSET_S = 0.35


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    root = tmp_path_factory.mktemp("lias")
    rng = np.random.default_rng(4)
    info = fx.make_tree(root, rng=rng, sessions=[fx.session_814(rng), fx.session_820(rng)], dynamic={
        "fast": dict(clock_offset_s=OFFSET_S),
        "medium": dict(duration_s=8.0, uwb_rate_hz=50.0, start="2022-08-15 10:12:03.008"),
        "conv_wxyz": dict(duration_s=12.0, quaternion="wxyz", body_flip="none", clock_offset_s=-0.2),
        "conv_xyzw": dict(duration_s=12.0, quaternion="xyzw", body_flip="none", clock_offset_s=0.1),
    })
    info["data_dir"] = root
    return info


@pytest.fixture(scope="module")
def fast(tree):
    return lias.load_dynamic("fast", tree["data_dir"])


def _steps(rec_or_list):
    return {s.name: s.n_affected for s in rec_or_list}


# ----------------------------------------------------------------------------- discovery

def test_list_recordings_globs_every_run_and_static_file(tree):
    df = lias.list_recordings(tree["data_dir"])
    assert {"kind", "name", "session", "path", "site", "yaw_deg", "truth_path"} <= set(df.columns)
    dyn = df[df.kind == "dynamic"]
    assert set(dyn.name) == {"fast", "medium", "conv_wxyz", "conv_xyzw"}
    assert dyn.session.isna().all() and all(p.is_file() for p in dyn.truth_path)
    medium = dyn[dyn.name == "medium"].iloc[0]
    assert medium.path.name == "UWB_dynamic_exp_medium.csv"
    assert medium.truth_path.name == "motion_capture_dynamic_exp_medium.csv"
    st = df[df.kind == "static"]
    assert list(st.name) == ["8.14/pos1_deg_0", "8.14/pos1_deg_60", "8.14/pos2_deg_120",
                             "8.14/pos3_deg_300", "8.20/pos1_deg_0", "8.20/pos2_deg_180"]
    assert list(st.session) == ["8.14"] * 4 + ["8.20"] * 2
    assert st.iloc[2].site == 2 and st.iloc[2].yaw_deg == 120


def test_list_recordings_of_a_tree_without_planar_folder_is_empty(tmp_path):
    (tmp_path / "lias-planar-uwb").mkdir()
    df = lias.list_recordings(tmp_path)
    assert df.empty and "kind" in df.columns


def test_unknown_run_and_missing_motion_capture_are_reported(tree, tmp_path):
    with pytest.raises(DataNotFoundError, match="medium"):
        lias.load_dynamic("slow", tree["data_dir"])
    fx.make_tree(tmp_path, rng=np.random.default_rng(1), sessions=[],
                 dynamic={"lonely": dict(duration_s=3.0, quirks=False)})
    (tmp_path / "lias-planar-uwb/Planar_Dataset/Dynamic/motion_capture_dynamic_exp_lonely.csv").unlink()
    assert lias.list_recordings(tmp_path).truth_path.tolist() == [None]
    with pytest.raises(DataNotFoundError, match="motion-capture"):
        lias.load_dynamic("lonely", tmp_path)


# ----------------------------------------------------------------------------- readers

def test_read_uwb_csv_values_order_and_quirks(tree):
    d = tree["dynamic"]["fast"]
    t_s, r, t0, cleaning = lias.read_uwb_csv(d.uwb_path, return_cleaning=True)
    assert r.shape == (t_s.size, 8, 3)
    assert t0 == pd.Timestamp("2022-08-15 09:59:48.214") and t_s[0] == 0.0
    assert np.all(np.diff(t_s) > 0)
    # 9:59:59 -> 10:00:00 (unpadded to padded hour) is an ordinary 10 ms step
    assert np.diff(t_s).max() < 0.05 and t_s[-1] > 12.0
    first = d.uwb_path.read_text().splitlines()[0].split(",")
    np.testing.assert_array_equal(r[0], np.array(first[1:], float).reshape(8, 3))  # a0-t0, a0-t1, ...
    assert _steps(cleaning) == {"incomplete UWB rows": 4, "repeated rows dropped": 1, "zero ranges -> missing": 1}
    assert np.isnan(r).sum() == 1 and np.isnan(r[:, 3, 1]).sum() == 1
    assert t_s.size == len(d.t_uwb_s) - 4 - 1


def test_read_uwb_csv_wide_file_with_garbage_slots(tree):
    session, paths = tree["static"]["8.14"]
    wide = next(p for p in paths if p.name.endswith("pos2_deg_120.csv"))
    assert wide.read_text().splitlines()[0].count(",") == 27
    t_s, r, _, cleaning = lias.read_uwb_csv(wide, return_cleaning=True)
    assert r.shape == (t_s.size, 8, 3) and np.all(r < 10)
    assert _steps(cleaning)["extra range slots ignored"] == 1


def test_read_mocap_csv(tree):
    d = tree["dynamic"]["fast"]
    t_s, pos, quat, t0, cleaning = lias.read_mocap_csv(d.mocap_path, return_cleaning=True)
    assert pos.shape == (t_s.size, 3) and quat.shape == (t_s.size, 4)
    assert np.all(np.diff(t_s) > 0) and t_s[0] == 0.0
    assert t0 == pd.Timestamp("2022-08-15 09:59:48.214") + pd.Timedelta(seconds=OFFSET_S - 1.8)
    row = d.mocap_path.read_text().splitlines()[1].split(",")
    np.testing.assert_array_equal(quat[0], np.array(row[4:], float))  # raw column order
    assert _steps(cleaning) == {"repeated rows dropped": 3}
    assert "motion-capture" in cleaning[0].detail and d.mocap_path.name in cleaning[0].detail


def test_frame_rotation_quaternion_orders_agree():
    q = np.array([[np.cos(0.3), 0.0, 0.0, np.sin(0.3)]])
    rz = registration.frame_rotation(q, "wxyz", "none")[0]
    np.testing.assert_allclose(rz, [[np.cos(0.6), -np.sin(0.6), 0], [np.sin(0.6), np.cos(0.6), 0], [0, 0, 1]],
                               atol=1e-12)
    np.testing.assert_allclose(registration.frame_rotation(q[:, [1, 2, 3, 0]], "xyzw", "none")[0], rz, atol=1e-12)
    with pytest.raises(ValueError):
        registration.frame_rotation(q, "zyxw", "none")


def test_read_tables_parses_every_section(tree):
    readme = tree["root"] / "Planar_Dataset/Static/README.md"
    for session, room in (("8.14", fx.ROOM_A), ("8.20", fx.ROOM_B)):
        tab = lias.read_tables(readme, session)
        assert tab.anchors.ids == tuple(f"a{i}" for i in range(8)) and tab.tag_ids == ("t0", "t1", "t2")
        np.testing.assert_array_equal(tab.anchors.pos_m, room.anchors_m)
        np.testing.assert_array_equal(tab.tag_offsets_m, room.tag_offsets_m)
        poses = tree["static"][session][0].poses
        assert list(tab.poses.site) == [p.site for p in poses]
        np.testing.assert_array_equal(tab.poses[["yaw_deg", "x_m", "y_m"]].to_numpy(),
                                      [[p.yaw_deg, p.x_m, p.y_m] for p in poses])
    dyn = lias.read_tables(tree["root"] / "Planar_Dataset/Dynamic/README.md")
    assert dyn.poses is None and dyn.session is None
    np.testing.assert_array_equal(dyn.anchors.pos_m, fx.ROOM_A.anchors_m)
    with pytest.raises(ValueError, match="8.14, 8.20"):
        lias.read_tables(readme)
    with pytest.raises(DataFormatError, match="8.21"):
        lias.read_tables(readme, "8.21")


# ----------------------------------------------------------------------------- dynamic

def test_load_dynamic_shapes_ids_and_meta(fast):
    assert isinstance(fast, Recording) and fast.name == "fast" and fast.dataset == "lias-planar-uwb"
    assert fast.tags == ("t0", "t1", "t2") and fast.anchors.ids == tuple(f"a{i}" for i in range(8))
    t0 = fast.meta["t0"]
    for tag in fast.tags:
        log, truth = fast.ranges[tag], fast.truth[tag]
        assert log.range_m.shape == (log.t_s.size, 8) and log.t0 == t0 and log.t_s[0] == 0.0
        assert truth.pos_m.shape == (truth.t_s.size, 3) and truth.rot.shape == (truth.t_s.size, 3, 3)
        assert np.all(np.isfinite(truth.pos_m))
        assert log.t_s[0] <= truth.t_s[0] and truth.t_s[-1] <= log.t_s[-1]
        np.testing.assert_allclose(np.linalg.det(truth.rot), 1.0, atol=1e-9)
    for key in ("clock_offset_s", "clock_offset_method", "quaternion", "body_flip",
                "quaternion_spreads_m", "convention_spreads_m", "registration"):
        assert key in fast.meta
    steps = _steps(fast.cleaning)
    repeats = {s.detail.split(":")[0]: s.n_affected for s in fast.cleaning if s.name == "repeated rows dropped"}
    assert steps["incomplete UWB rows"] == 4 and repeats["motion_capture_dynamic_exp_fast.csv"] == 3
    assert steps["truth outside the UWB span"] > 0


def test_clock_offset_is_recovered(fast):
    assert fast.meta["clock_offset_s"] == pytest.approx(OFFSET_S, abs=0.02)


def test_truth_matches_the_generating_trajectory(fast, tree):
    d = tree["dynamic"]["fast"]
    truth = fast.truth["t2"]
    centre, yaw = fx.trolley_path(truth.t_s)
    expected = fx.tag_positions(centre, yaw, fx.ROOM_A.tag_offsets_m)[:, 2]
    err = np.linalg.norm(truth.pos_m - expected, axis=1)
    # residual clock-offset error (<20 ms at ~0.5 m/s), 1 ms stamps and ~3 mrad of tilt
    assert np.median(err) < 0.005 and err.max() < 0.015
    # every pair's measured - true range is its bias (0.1-0.4 m) plus 3 cm noise: checks the
    # a0-t0, a0-t1, ... column order and the tag assignment end to end
    for j, tag in enumerate(fast.tags):
        log = fast.ranges[tag]
        pos = fast.truth[tag].interp(log.t_s)
        res = log.range_m - np.linalg.norm(pos[:, None, :] - fast.anchors.pos_m[None], axis=-1)
        bias = np.nanmedian(res, axis=0)
        assert np.all((bias > 0.05) & (bias < 0.45)), (tag, bias)
        assert np.nanmedian(np.abs(res - bias)) < 0.03
    assert d.quaternion == fast.meta["quaternion"]


@pytest.mark.parametrize("run", ["fast", "conv_wxyz", "conv_xyzw"])
def test_frame_convention_is_decided_from_the_data(tree, fast, run):
    rec = fast if run == "fast" else lias.load_dynamic(run, tree["data_dir"])
    d = tree["dynamic"][run]
    assert (rec.meta["quaternion"], rec.meta["body_flip"]) == (d.quaternion, d.body_flip)
    spreads = rec.meta["quaternion_spreads_m"]
    other = "xyzw" if d.quaternion == "wxyz" else "wxyz"
    assert spreads[d.quaternion] < 0.05 and spreads[other] > 2 * spreads[d.quaternion]
    assert len(rec.meta["convention_spreads_m"]) == 8
    assert rec.meta["clock_offset_s"] == pytest.approx(d.clock_offset_s, abs=0.02)


def test_convention_can_be_forced(tree, fast):
    forced = lias.load_dynamic("fast", tree["data_dir"], quaternion="xyzw", body_flip="none")
    assert (forced.meta["quaternion"], forced.meta["body_flip"]) == ("xyzw", "none")
    assert list(forced.meta["convention_spreads_m"]) == ["xyzw/none"]
    assert forced.meta["residual_spread_m"] > 2 * fast.meta["residual_spread_m"]
    half = lias.load_dynamic("fast", tree["data_dir"], body_flip="x")
    assert set(half.meta["convention_spreads_m"]) == {"wxyz/x", "xyzw/x"}
    with pytest.raises(ValueError, match="quaternion"):
        lias.load_dynamic("fast", tree["data_dir"], quaternion="qwxyz")
    with pytest.raises(ValueError, match="body_flip"):
        lias.load_dynamic("fast", tree["data_dir"], body_flip="w")


def test_medium_run_loads_by_name(tree):
    rec = lias.load_dynamic("medium", tree["data_dir"])
    assert rec.name == "medium" and rec.meta["t0"] == pd.Timestamp("2022-08-15 10:12:03.008")
    assert abs(rec.meta["clock_offset_s"]) < 0.02


def test_motion_capture_that_cannot_overlap_is_an_error(tree, tmp_path):
    fx.make_tree(tmp_path, rng=np.random.default_rng(2), sessions=[],
                 dynamic={"late": dict(duration_s=4.0, clock_offset_s=60.0, quirks=False)})
    with pytest.raises(DataFormatError, match="cannot align"):
        lias.load_dynamic("late", tmp_path)


# ----------------------------------------------------------------------------- static

def test_static_truth_is_pose_plus_rotated_offset(tmp_path):
    session = fx.StaticSession("8.14", "2022/8/14", fx.ROOM_A,
                               (fx.Pose(1, 0.5, -1.5, -1.0), fx.Pose(2, 90.0, 1.0, -1.0)),
                               files=((2, 90),))
    fx.make_tree(tmp_path, rng=np.random.default_rng(3), dynamic={}, sessions=[session], static_rows=30)
    (rec,) = lias.load_static("8.14", tmp_path)
    assert rec.name == "8.14/pos2_deg_90"
    assert (rec.meta["site"], rec.meta["yaw_deg"], rec.meta["x_m"], rec.meta["y_m"]) == (2, 90.0, 1.0, -1.0)
    # tag 0 offset (-0.0710, -0.1380, 0.0012) turned by 90 deg is (0.1380, -0.0710)
    np.testing.assert_allclose(rec.truth["t0"].pos_m[0], [1.1380, -1.0710, 0.97 + 0.0012], atol=1e-12)
    # tag 2 offset (0.1980, 0.1510, -0.0011) -> (-0.1510, 0.1980)
    np.testing.assert_allclose(rec.truth["t2"].pos_m[-1], [0.8490, -0.8020, 0.97 - 0.0011], atol=1e-12)
    np.testing.assert_array_equal(rec.truth["t1"].t_s, rec.ranges["t1"].t_s)
    (low,) = lias.load_static("8.14", tmp_path, centroid_z_m=0.5)
    assert low.truth["t0"].pos_m[0, 2] == pytest.approx(0.5012)


def test_load_static_session_and_selection(tree):
    recs = lias.load_static("8.14", tree["data_dir"])
    assert [r.name for r in recs] == ["8.14/pos1_deg_0", "8.14/pos1_deg_60", "8.14/pos2_deg_120",
                                      "8.14/pos3_deg_300"]
    for r in recs:
        assert r.tags == ("t0", "t1", "t2") and len(r.anchors) == 8
        assert abs((r.meta["yaw_deg"] - r.meta["nominal_yaw_deg"] + 180) % 360 - 180) < 5
        assert _steps(r.cleaning)["incomplete UWB rows"] == 2
    assert [r.name for r in lias.load_static("8.14", tree["data_dir"], site=1)] == \
        ["8.14/pos1_deg_0", "8.14/pos1_deg_60"]
    assert [r.name for r in lias.load_static("8.14", tree["data_dir"], yaw_deg=300)] == ["8.14/pos3_deg_300"]
    with pytest.raises(DataNotFoundError):
        lias.load_static("8.14", tree["data_dir"], site=9)
    with pytest.raises(DataNotFoundError, match="8.14"):
        lias.load_static("9.1", tree["data_dir"])


def test_other_room_session_loads_with_its_own_tables(tree):
    recs = lias.load_static("8.20", tree["data_dir"])
    assert [r.name for r in recs] == ["8.20/pos1_deg_0", "8.20/pos2_deg_180"]
    for r in recs:
        np.testing.assert_array_equal(r.anchors.pos_m, fx.ROOM_B.anchors_m)
        np.testing.assert_array_equal(r.meta["tag_offsets_m"], fx.ROOM_B.tag_offsets_m)
        for tag in r.tags:  # measured - true range is the pair bias (0.1-0.4 m) + noise
            res = r.ranges[tag].range_m - np.linalg.norm(
                r.truth[tag].pos_m[:, None] - r.anchors.pos_m[None], axis=-1)
            assert np.all((np.nanmedian(res, axis=0) > 0.05) & (np.nanmedian(res, axis=0) < 0.45))


def test_file_without_a_matching_pose_is_an_error(tmp_path):
    session = fx.StaticSession("8.14", "2022/8/14", fx.ROOM_A,
                               (fx.Pose(1, 0.2, -1.5, -1.0), fx.Pose(1, 59.0, -1.5, -1.0)),
                               files=((1, 30),))
    fx.make_tree(tmp_path, rng=np.random.default_rng(5), dynamic={}, sessions=[session], static_rows=20)
    with pytest.raises(DataFormatError, match="within 20 deg") as err:
        lias.load_static("8.14", tmp_path)
    assert "README.md" in str(err.value) and "line" in str(err.value)
    assert len(lias.load_static("8.14", tmp_path, max_yaw_mismatch_deg=31)) == 1


# ----------------------------------------------------------------------------- bad input

def _edit_line(lines, i, fn):
    lines = list(lines)
    lines[i] = fn(lines[i])
    return lines


def _replace_field(k, value):
    def fn(line):
        f = line.split(",")
        f[k] = value
        return ",".join(f)
    return fn


UWB_CASES = {  # name: (edit of the line list, 1-based line the error names)
    "malformed row": (lambda L: _edit_line(L, 4, lambda s: s.replace(",", ";")), 5),
    "wrong column count": (lambda L: _edit_line(L, 6, lambda s: s + ",4.21"), 7),
    "non-numeric value": (lambda L: _edit_line(L, 7, _replace_field(5, "4.o2")), 8),
    "bad timestamp": (lambda L: _edit_line(L, 8, lambda s: s.replace(" ", "T", 1)), 9),
    "impossible date": (lambda L: _edit_line(L, 9, lambda s: "2022-02-30" + s[10:]), 10),
    "negative range": (lambda L: _edit_line(L, 10, _replace_field(3, "-0.31")), 11),
    "empty field between values": (lambda L: _edit_line(L, 11, _replace_field(2, "")), 12),
    "partial anchor group": (lambda L: _edit_line(L, 12, lambda s: ",".join(s.split(",")[:-1]) + ","), 13),
    "time going back": (lambda L: L[:13] + [L[14], L[13]] + L[15:], 15),
    "infinite value": (lambda L: _edit_line(L, 15, _replace_field(1, "inf")), 16),
    "blank line": (lambda L: L[:16] + [""] + L[16:], 17),
}


@pytest.mark.parametrize("case", list(UWB_CASES))
def test_bad_uwb_rows_name_file_and_line(tree, tmp_path, case):
    edit, line = UWB_CASES[case]
    lines = tree["dynamic"]["medium"].uwb_path.read_text().splitlines()
    path = fx.write_lines(tmp_path / "UWB_dynamic_exp_bad.csv", edit(lines))
    with pytest.raises(DataFormatError) as err:
        lias.read_uwb_csv(path)
    assert str(path) in str(err.value) and f"line {line}" in str(err.value), str(err.value)
    assert err.value.line == line


def test_empty_and_undecodable_uwb_files(tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    with pytest.raises(DataFormatError, match="empty") as err:
        lias.read_uwb_csv(empty)
    assert str(empty) in str(err.value) and "line 1" in str(err.value)
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"2022-08-15 9:00:00.000" + b",1" * 24 + b"\n\xff\xfe\n")
    with pytest.raises(DataFormatError, match="line 2"):
        lias.read_uwb_csv(binary)


def test_uwb_file_with_more_anchors_than_expected(tree, tmp_path):
    lines = tree["dynamic"]["medium"].uwb_path.read_text().splitlines()
    path = fx.write_lines(tmp_path / "u.csv", [s + ",1,2,3" for s in lines if not s.endswith(",")])
    with pytest.raises(DataFormatError, match="more anchors or tags"):
        lias.read_uwb_csv(path)
    t_s, r, _ = lias.read_uwb_csv(path, n_anchors=9)
    assert r.shape == (t_s.size, 9, 3)


def test_uwb_failure_values_become_nan_and_are_counted(tree, tmp_path):
    lines = tree["dynamic"]["medium"].uwb_path.read_text().splitlines()
    path = fx.write_lines(tmp_path / "u.csv", _edit_line(lines, 3, _replace_field(4, "652.8")))
    _, r, _, cleaning = lias.read_uwb_csv(path, return_cleaning=True)
    assert _steps(cleaning)["implausible ranges -> missing"] == 1 and np.isnan(r[3, 1, 0])


MOCAP_CASES = {
    "missing header": (lambda L: L[1:], 1),
    "other header": (lambda L: ["t,x,y,z,qw,qx,qy,qz"] + L[1:], 1),
    "wrong column count": (lambda L: _edit_line(L, 5, lambda s: s + ","), 6),
    "non-numeric value": (lambda L: _edit_line(L, 6, _replace_field(2, "1.2.3")), 7),
    "empty value": (lambda L: _edit_line(L, 7, _replace_field(6, "")), 8),
    "not a unit quaternion": (lambda L: _edit_line(L, 8, _replace_field(5, "0.5")), 9),
    "bad timestamp": (lambda L: _edit_line(L, 9, lambda s: s.replace(":", "-", 1)), 10),
    "time going back": (lambda L: L[:20] + [L[21], L[20]] + L[22:], 22),
    "position far away": (lambda L: _edit_line(L, 10, _replace_field(1, "4e5")), 11),
}


@pytest.mark.parametrize("case", list(MOCAP_CASES))
def test_bad_mocap_rows_name_file_and_line(tree, tmp_path, case):
    edit, line = MOCAP_CASES[case]
    lines = tree["dynamic"]["medium"].mocap_path.read_text().splitlines()
    path = fx.write_lines(tmp_path / "motion_capture_dynamic_exp_bad.csv", edit(lines))
    with pytest.raises(DataFormatError) as err:
        lias.read_mocap_csv(path)
    assert str(path) in str(err.value) and f"line {line}" in str(err.value), str(err.value)


def test_mocap_dropout_rows_are_dropped_and_counted(tree, tmp_path):
    lines = tree["dynamic"]["medium"].mocap_path.read_text().splitlines()
    lines = _edit_line(lines, 30, lambda s: s.split(",")[0] + ",0,0,0,0,0,0,0")
    path = fx.write_lines(tmp_path / "m.csv", lines)
    t_s, *_, cleaning = lias.read_mocap_csv(path, return_cleaning=True)
    assert _steps(cleaning)["motion-capture dropouts"] == 1


def _break_readme(path, old, new):
    text = path.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return text[: text.index(old)].count("\n") + 1


def _static_only_tree(tmp_path, seed=6):
    rng = np.random.default_rng(seed)
    fx.make_tree(tmp_path, rng=rng, dynamic={}, sessions=[fx.session_814(rng, files=((1, 0),))],
                 static_rows=20)
    return tmp_path / "lias-planar-uwb/Planar_Dataset/Static/README.md"


def test_missing_anchor_table_names_readme_and_section_line(tmp_path):
    readme = _static_only_tree(tmp_path)
    text = readme.read_text(encoding="utf-8")
    heading = text.splitlines().index("### 2022/8/14") + 1
    table = "\n".join(ln for ln in text.splitlines() if ln.startswith("| Anchor"))
    _break_readme(readme, table, "")
    with pytest.raises(DataFormatError, match="no anchor table") as err:
        lias.load_static("8.14", tmp_path)
    assert str(readme) in str(err.value) and f"line {heading}" in str(err.value)


@pytest.mark.parametrize("old,new,match", [
    ("| Anchor 3 | 3.5870 ", "| Anchor 3 | 3.58x0 ", "not a number"),
    ("| Tag 1 |", "| Tag 4 |", "tag numbers"),
    ("| Anchor 5 | 0.0370", "| Anchor 5 | 0.0370 | 9.9", "expected 'Anchor k"),
    ("| Pose 2 |", "| Site 2 |", "pose label"),
    ("| Poses  |", "| Poses  | extra |", "pose table header"),
])
def test_garbled_readme_rows_name_the_line(tmp_path, old, new, match):
    readme = _static_only_tree(tmp_path)
    line = _break_readme(readme, old, new)
    with pytest.raises(DataFormatError, match=match) as err:
        lias.load_static("8.14", tmp_path)
    assert str(readme) in str(err.value) and "line" in str(err.value)
    if match in ("not a number", "expected 'Anchor k", "pose label"):
        assert err.value.line == line


def test_missing_pose_table_and_missing_dynamic_tables(tmp_path, tree):
    readme = _static_only_tree(tmp_path)
    _break_readme(readme, "| Poses  |", "| Setups |")
    with pytest.raises(DataFormatError, match="no pose table"):
        lias.load_static("8.14", tmp_path)
    other = tmp_path / "dyn"
    fx.make_tree(other, rng=np.random.default_rng(8), sessions=[],
                 dynamic={"fast": dict(duration_s=3.0, quirks=False)})
    dyn_readme = other / "lias-planar-uwb/Planar_Dataset/Dynamic/README.md"
    text = dyn_readme.read_text(encoding="utf-8")
    dyn_readme.write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("| Tag")),
                          encoding="utf-8")
    with pytest.raises(DataFormatError, match="no tag table") as err:
        lias.load_dynamic("fast", other)
    assert str(dyn_readme) in str(err.value) and "line 1" in str(err.value)


# ----------------------------------------------------------------------------- sample tree

def test_sample_tree_is_small_and_loads(tmp_path):
    root = fx.write_sample(tmp_path / "lias-planar-uwb")
    assert sum(p.stat().st_size for p in root.rglob("*") if p.is_file()) < 60_000
    rec = lias.load_dynamic("fast", tmp_path)
    assert rec.meta["clock_offset_s"] == pytest.approx(0.12, abs=0.03)
    assert (rec.meta["quaternion"], rec.meta["body_flip"]) == ("wxyz", "x")
    assert [r.name for r in lias.load_static("8.14", tmp_path)] == ["8.14/pos1_deg_0", "8.14/pos2_deg_120"]


# ----------------------------------------------------------------------------- real data

@pytest.fixture(scope="module")
def real_fast():
    real_dataset(lias.NAME)
    return lias.load_dynamic("fast")


@pytest.fixture(scope="module")
def real_static():
    root = real_dataset(lias.NAME)
    files = sorted((root / "Planar_Dataset/Static/8.14").glob("UWB_static_exp_*.csv"))
    return files, lias.load_static("8.14")


@pytest.mark.realdata
def test_real_fast_run(real_fast):
    rec = real_fast
    assert rec.tags == ("t0", "t1", "t2") and len(rec.anchors) == 8
    assert all(rec.ranges[t].range_m.shape[1] == 8 for t in rec.tags)
    assert abs(rec.meta["clock_offset_s"]) < 1.0
    spreads = rec.meta["convention_spreads_m"]
    chosen = f"{rec.meta['quaternion']}/{rec.meta['body_flip']}"
    assert spreads[chosen] == min(spreads.values()) and spreads[chosen] < 0.1
    others = rec.meta["quaternion_spreads_m"]
    assert max(others.values()) > 1.5 * min(others.values())
    # physical check independent of the residual criterion: a trolley on a floor only yaws,
    # so the chosen tag frame's z axis must stay vertical
    assert np.median(rec.truth["t0"].rot[:, 2, 2]) > 0.99
    for tag in rec.tags:
        log, truth = rec.ranges[tag], rec.truth[tag]
        assert log.t_s[0] <= truth.t_s[0] <= truth.t_s[-1] <= log.t_s[-1]


@pytest.mark.realdata
def test_real_static_session_loads_every_file(real_static):
    files, recs = real_static
    assert len(recs) == len(files) > 0
    for r in recs:
        assert r.tags == ("t0", "t1", "t2") and len(r.anchors) == 8
        assert abs((r.meta["yaw_deg"] - r.meta["nominal_yaw_deg"] + 180) % 360 - 180) < 20
        assert r.ranges["t0"].range_m.shape == (r.truth["t0"].t_s.size, 8)


@pytest.mark.realdata
def test_real_static_and_dynamic_pair_biases_agree(real_fast, real_static):
    """The per-pair range biases seen in the static poses (README tables only) must match the
    dynamic run's under the chosen motion-capture convention: an independent check of it."""
    _, recs = real_static

    def bias(rec, truth_at):
        return np.stack([np.nanmedian(rec.ranges[t].range_m - np.linalg.norm(
            truth_at(t)[:, None] - rec.anchors.pos_m[None], axis=-1), axis=0) for t in rec.tags])

    static = np.median([bias(r, lambda t, r=r: r.truth[t].pos_m) for r in recs], axis=0)
    dynamic = bias(real_fast, lambda t: real_fast.truth[t].interp(real_fast.ranges[t].t_s))
    assert np.sqrt(np.mean((static - dynamic) ** 2)) < 0.04


@pytest.mark.realdata
def test_real_readme_tables():
    root = real_dataset(lias.NAME)
    readme = root / "Planar_Dataset/Static/README.md"
    for session in ("8.14", "8.20"):
        tab = lias.read_tables(readme, session)
        assert len(tab.anchors) == 8 and tab.tag_offsets_m.shape == (3, 3)
        assert (tab.poses.groupby("site").size() == 6).all()
