"""Containers of :mod:`uwbwb.types` that carry method-specific logs: TDoAs, set fixes, range samples, tag runs."""

import numpy as np
import pytest

from uwbwb.types import (Anchors, RangeLog, RangeSamples, SetFixLog, TagRun, TdoaLog, Trajectory, parse_set_label,
                         pseudo_tdoa, set_id_from_mask, set_label, set_mask, set_members)


# --------------------------------------------------------------------------- TDoA logs

def test_pseudo_tdoa_reference_fallback():
    r = np.array([[5.0, 3.0, 4.0, 7.0],
                  [np.nan, 6.0, 2.0, 9.0],
                  [np.nan, np.nan, np.nan, 1.0],
                  [1.0, 1.0, np.nan, np.nan]])
    d, ref = pseudo_tdoa(r, 0)
    np.testing.assert_array_equal(ref, [0, 2, -1, 0])
    np.testing.assert_allclose(d[0], [0.0, -2.0, -1.0, 2.0])
    np.testing.assert_allclose(d[1], [np.nan, 4.0, 0.0, 7.0])
    assert np.all(np.isnan(d[2]))
    np.testing.assert_allclose(d[3], [0.0, 0.0, np.nan, np.nan])    # equal ranges: a real 0 TDoA
    _, ref_first = pseudo_tdoa(r, 0, fallback="first")
    np.testing.assert_array_equal(ref_first, [0, 1, -1, 0])
    with pytest.raises(ValueError, match="fallback"):
        pseudo_tdoa(r, 0, fallback="random")
    with pytest.raises(ValueError, match="reference index"):
        pseudo_tdoa(r, 4)


def test_tdoa_log_from_ranges_and_frame():
    log = RangeLog(np.array([0.0, 0.1]), np.array([[5.0, 3.0, 4.0], [np.nan, 6.0, 2.0]]), ("a", "b", "c"), "t1")
    tl = TdoaLog.from_ranges(log, "b")
    np.testing.assert_array_equal(tl.ref, [1, 1])
    np.testing.assert_array_equal(tl.n_tdoa, [2, 1])
    df = tl.to_frame()
    assert list(df.columns) == ["t_s", "anchor_id", "ref_id", "tdoa_m"]
    assert len(df) == 3 and set(df.ref_id) == {"b"}
    assert len(tl.between(0.05, 1.0)) == 1


def test_tdoa_log_validation():
    ids = ("a", "b", "c")
    with pytest.raises(ValueError, match="exactly 0"):
        TdoaLog([0.0], [[1.0, 2.0, 3.0]], [0], ids)
    with pytest.raises(ValueError, match="all NaN"):
        TdoaLog([0.0], [[0.0, 2.0, np.nan]], [-1], ids)
    with pytest.raises(ValueError, match="at least one other"):
        TdoaLog([0.0], [[0.0, np.nan, np.nan]], [0], ids)
    with pytest.raises(ValueError, match="strictly increasing"):
        TdoaLog([0.0, 0.0], [[0.0, 1.0, 1.0]] * 2, [0, 0], ids)
    with pytest.raises(ValueError, match="need t_s"):
        TdoaLog([0.0], [[0.0, 1.0]], [0], ids)


# --------------------------------------------------------------------------- sensor-set fixes

def test_set_ids_round_trip_and_paper_labels():
    used = np.zeros((2, 8), bool)
    used[0, [0, 4, 5, 6, 7]] = True
    used[1, [0, 2, 4, 5, 7]] = True
    ids = set_id_from_mask(used)
    assert ids.tolist() == [0b11110001, 0b10110101]
    assert set_label(ids[0]) == "76540"
    assert set_label(ids[1]) == "75420"
    assert parse_set_label("76540") == ids[0]
    assert set_members(ids[1]) == (0, 2, 4, 5, 7)
    np.testing.assert_array_equal(set_mask(ids, 8), used)
    assert set_label(ids[0], ("a0", "a1", "a2", "a3", "a4", "a5", "a6", "a7")) == "a7+a6+a5+a4+a0"


def test_parse_set_label_rejects_non_sets():
    for bad in ("7654a", "76640", ""):
        with pytest.raises(ValueError):
            parse_set_label(bad)


def _fix_log(n=6, name="loc"):
    t = np.arange(n) * 0.1
    sets = np.array([0b11111, 0b11111, 0b101111, 0b11111, 0b101111, 0b1110011])[:n]
    return SetFixLog(t, np.zeros((n, 2)) + 0.1, sets, tuple(str(i) for i in range(8)), np.zeros((n, 2)), name)


def test_fix_log_frequency_and_frame():
    log = _fix_log()
    fr = log.set_frequency()
    assert fr["label"].tolist() == ["43210", "53210", "65410"]
    assert fr["count"].tolist() == [3, 2, 1]
    np.testing.assert_allclose(fr["cum_share"], [0.5, 5 / 6, 1.0])
    df = log.to_frame()
    assert list(df.columns) == ["t_s", "x_m", "y_m", "set_id", "set_label", "true_x_m", "true_y_m"]
    np.testing.assert_allclose(log.error_m, 0.1)
    assert len(log.select(slice(0, 3))) == 3


def test_fix_log_rejects_bad_input():
    ids = tuple("01234567")
    with pytest.raises(ValueError, match="strictly increasing"):
        SetFixLog([0.0, 0.0], np.zeros((2, 2)), [1, 1], ids)
    with pytest.raises(ValueError, match="finite"):
        SetFixLog([0.0, 1.0], [[0.0, np.nan], [0.0, 0.0]], [1, 1], ids)
    with pytest.raises(ValueError, match="non-empty sets"):
        SetFixLog([0.0, 1.0], np.zeros((2, 2)), [1, 256], ids)
    with pytest.raises(ValueError, match="shape"):
        SetFixLog([0.0, 1.0], np.zeros((3, 2)), [1, 1], ids)
    with pytest.raises(ValueError, match="no truth"):
        SetFixLog([0.0], np.zeros((1, 2)), [1], ids).error_m


# --------------------------------------------------------------------------- range samples

def test_range_samples_from_ranges_and_back():
    r = np.array([[1.0, np.nan, 2.0], [np.nan, 3.0, 4.0]])
    s = RangeSamples.from_ranges(r, [0.0, 0.5], anchor_ids=("a", "b", "c"))
    np.testing.assert_array_equal(s.anchor_index, [0, 2, 1, 2])
    t, R = s.to_matrix()
    np.testing.assert_array_equal(R, r)
    assert list(s.to_frame().anchor_id) == ["a", "c", "b", "c"]
    with pytest.raises(ValueError, match="finite"):
        RangeSamples([0.0], [0], [np.nan], ("a",))
    with pytest.raises(ValueError, match="non-decreasing"):
        RangeSamples([1.0, 0.0], [0, 0], [1.0, 1.0], ("a",))
    with pytest.raises(ValueError, match="t_s"):
        RangeSamples.from_ranges(r)


# --------------------------------------------------------------------------- tag runs

def test_tag_run_true_ranges_and_window():
    anchors = Anchors(tuple("ABCD"), np.array([[0, 0, 2.5], [10, 0, 2.5], [10, 8, 2.4], [0, 8, 2.6]]))
    t = np.arange(40) * 0.1
    pos = np.column_stack([2 + 0.5 * t, 3 + 0.2 * t, np.full(t.size, 1.2)])
    r = np.linalg.norm(pos[:, None] - anchors.pos_m, axis=-1)
    run = TagRun("synthetic", "x", "t", RangeLog(t, r, anchors.ids, "t"), Trajectory(t, pos), anchors, 2, 1.2)
    assert run.key == "x/t" and run.dt_s == pytest.approx(0.1)
    np.testing.assert_allclose(run.true_range_m(), r, atol=1e-12)
    cut = run.between(1.0, 2.0, name="part")
    assert cut.name == "part" and len(cut.ranges) == 10
    assert cut.truth.t_s[0] == pytest.approx(1.0 - TagRun.max_truth_gap_s)
    assert run.tdoa(1).ref.tolist() == [1] * 40
    with pytest.raises(ValueError, match="anchors"):
        TagRun("synthetic", "x", "t", RangeLog(t, r[:, :3], anchors.ids[:3], "t"), Trajectory(t, pos), anchors)
    with pytest.raises(ValueError, match="dim"):
        TagRun("synthetic", "x", "t", RangeLog(t, r, anchors.ids, "t"), Trajectory(t, pos), anchors, dim=4)


# --------------------------------------------------------------------------- the array-record base

def _chirps(t_s):
    from uwbwb.types import ChirpFlag, ChirpLog
    n = len(t_s)
    return ChirpLog(t_s, np.zeros(n, int), np.full(n, 1e-6), np.full(n, int(ChirpFlag.GAP), np.int8), ("b0",))


def test_between_keeps_the_start_and_leaves_out_the_end_for_every_container():
    from uwbwb.types import Estimates, ImuLog
    t = np.arange(6) * 1.0                                          # 0 .. 5 s
    logs = [RangeLog(t, np.ones((6, 2)), ("a", "b")), Trajectory(t, np.zeros((6, 2))),
            ImuLog(t, np.zeros((6, 3)), np.zeros((6, 3))), TdoaLog.from_ranges(RangeLog(t, np.ones((6, 2)), ("a", "b"))),
            Estimates(t, np.zeros((6, 2)), np.zeros(6, int), info={"nis": t}), _chirps(t),
            SetFixLog(t, np.zeros((6, 2)), np.ones(6, int), ("s0",)), RangeSamples(t, np.zeros(6, int), t, ("a",))]
    for log in logs:
        first, second = log.between(1.0, 3.0), log.between(3.0, 5.0)
        np.testing.assert_array_equal(first.t_s, [1.0, 2.0], err_msg=type(log).__name__)
        np.testing.assert_array_equal(second.t_s, [3.0, 4.0], err_msg=type(log).__name__)
        assert type(first) is type(log)


def test_chirp_log_between_now_leaves_out_the_end_time():
    # ChirpLog.between used to keep a chirp exactly at the end time (t <= t_end); it follows the
    # containers' one rule now, so back-to-back windows never count a chirp twice.
    log = _chirps([0.5, 1.0, 2.0, 3.0])
    assert len(log.between(0.0, 3.0)) == 3
    assert len(log.between(0.0, 3.0)) + len(log.between(3.0, 4.0)) == len(log)


def test_select_keeps_optional_fields_and_info_columns_and_freezes_them():
    from uwbwb.types import Estimates, ImuLog
    t = np.arange(4) * 0.5
    est = Estimates(t, np.ones((4, 2)), np.zeros(4, int), "e", np.tile(np.eye(2), (4, 1, 1)), np.zeros((4, 2)),
                    {"nis": t * 2})
    part = est.select(np.array([True, False, True, False]))
    np.testing.assert_array_equal(part.info["nis"], [0.0, 2.0])
    assert part.pos_cov_m2.shape == (2, 2, 2) and part.vel_mps.shape == (2, 2) and part.name == "e"
    assert not part.pos_m.flags.writeable and not part.info["nis"].flags.writeable
    imu = ImuLog(t, np.arange(12.0).reshape(4, 3), np.zeros((4, 3)))
    np.testing.assert_array_equal(imu.select(slice(1, 3)).acc_mps2, [[3, 4, 5], [6, 7, 8]])
    assert list(imu.to_frame().columns) == ["t_s", "acc_x_mps2", "acc_y_mps2", "acc_z_mps2",
                                            "gyro_x_radps", "gyro_y_radps", "gyro_z_radps"]
    pd_frame = imu.to_frame()
    back = ImuLog.from_frame(pd_frame)
    np.testing.assert_array_equal(back.acc_mps2, imu.acc_mps2)
    np.testing.assert_array_equal(imu.shifted(1.0).t_s, t + 1.0)


def _recording():
    from uwbwb.types import Anchors, ImuLog, Recording
    anchors = Anchors(("a", "b"), np.array([[0.0, 0.0, 2.0], [5.0, 0.0, 2.0]]))
    t = np.arange(0.0, 4.0, 0.1)
    ranges = {"tag": RangeLog(t, np.ones((t.size, 2)), anchors.ids, "tag")}
    tt = np.r_[np.arange(0.0, 2.01, 0.25), 3.5, 3.75, 4.0]         # a 1.5 s gap between 2.0 and 3.5
    truth = {"tag": Trajectory(tt, np.column_stack([tt, 2 * tt, np.ones(tt.size)]))}
    imu = ImuLog(np.arange(0.0, 4.0, 0.01), np.zeros((400, 3)), np.zeros((400, 3)))
    return Recording("synthetic", "r", anchors, ranges, truth, imu)


def test_recording_truth_at_follows_the_one_gap_rule():
    from uwbwb.types import MAX_TRUTH_GAP_S
    rec = _recording()
    pos = rec.truth_at("tag", [0.5, 2.0, 2.5, 3.5, 4.5], dim=2)
    np.testing.assert_allclose(pos[0], [0.5, 1.0])
    np.testing.assert_allclose(pos[1], [2.0, 4.0])               # on a sample: kept although a gap follows
    assert np.all(np.isnan(pos[2])) and 3.5 - 2.0 > MAX_TRUTH_GAP_S
    np.testing.assert_allclose(pos[3], [3.5, 7.0])
    assert np.all(np.isnan(pos[4]))                              # outside the span
    assert rec.truth_at("tag", [0.5]).shape == (1, 3)
    with pytest.raises(KeyError, match="no truth"):
        rec.truth_at("other", [0.5])


def test_recording_between_cuts_ranges_and_imu_and_pads_truth():
    from uwbwb.types import MAX_TRUTH_GAP_S
    rec = _recording()
    part = rec.between(1.0, 2.0, name="part")
    t = part.ranges["tag"].t_s
    assert part.name == "part" and t[0] >= 1.0 and t[-1] < 2.0 and len(t) in (9, 10, 11)
    assert part.imu.t_s[0] >= 1.0 and part.imu.t_s[-1] < 2.0
    np.testing.assert_array_equal(part.truth["tag"].t_s, np.arange(0.5, 2.01, 0.25))
    assert part.truth["tag"].t_s[0] >= 1.0 - MAX_TRUTH_GAP_S


def test_recording_decimate_by_step_or_rate():
    rec = _recording()                                           # ranges at 10 Hz
    assert rec.range_rate_hz() == pytest.approx(10.0)
    by_rate = rec.decimate(rate_hz=2.5)
    by_step = rec.decimate(4)
    np.testing.assert_array_equal(by_rate.ranges["tag"].t_s, by_step.ranges["tag"].t_s)
    assert by_rate.meta["decimated"] == 4
    assert rec.decimate(rate_hz=50.0) is rec                     # faster than the data: step 1
    assert rec.decimate(rate_hz=4.0).meta["decimated"] == 2      # the largest step keeping at least 4 Hz
    assert rec.decimate(rate_hz=3.0).meta["decimated"] == 3
    for bad in (dict(), dict(step=2, rate_hz=1.0), dict(rate_hz=0.0), dict(rate_hz=True)):
        with pytest.raises(ValueError):
            rec.decimate(**bad)


def test_recording_decimate_by_rate_steps_each_tag_on_its_own_rate():
    """Two tags at 10 and 20 Hz thinned to 5 Hz: steps 2 and 4, both at 5 Hz; the meta says each step; a tag's
    truth on its range epochs is thinned alike, and decimating again multiplies the steps."""
    from uwbwb.types import Anchors, Recording
    anchors = Anchors(("a", "b"), np.array([[0.0, 0.0, 2.0], [5.0, 0.0, 2.0]]))
    t10, t20 = np.arange(0.0, 4.0, 0.1), np.arange(0.0, 4.0, 0.05)
    ranges = {"slow": RangeLog(t10, np.ones((t10.size, 2)), anchors.ids, "slow"),
              "fast": RangeLog(t20, np.ones((t20.size, 2)), anchors.ids, "fast")}
    truth = {"fast": Trajectory(t20, np.zeros((t20.size, 3)))}
    rec = Recording("synthetic", "r", anchors, ranges, truth).decimate(rate_hz=5.0)
    assert rec.meta["decimated"] == {"slow": 2, "fast": 4}
    for tag in ("slow", "fast"):
        assert np.median(np.diff(rec.ranges[tag].t_s)) == pytest.approx(0.2)
    np.testing.assert_array_equal(rec.truth["fast"].t_s, rec.ranges["fast"].t_s)
    assert rec.decimate(2).meta["decimated"] == {"slow": 4, "fast": 8}


def test_estimates_batch_members_are_estimates_in_batch_order():
    from uwbwb.types import Estimates, EstimatesBatch
    t = np.arange(4) * 0.1
    pos = np.arange(2 * 3 * 4 * 2, dtype=float).reshape(2, 3, 4, 2)
    st = np.zeros((2, 3, 4), np.int8)
    b = EstimatesBatch(t, pos, st, "sweep", np.broadcast_to(np.eye(2), (2, 3, 4, 2, 2)), None,
                       {"nis": np.ones((2, 3, 4))})
    assert len(b) == 6 and b.batch_shape == (2, 3) and b.dim == 2
    members = list(b)
    assert all(isinstance(e, Estimates) and e.name == "sweep" for e in members)
    np.testing.assert_array_equal(members[4].pos_m, pos[1, 1])      # C order of the batch axes
    np.testing.assert_array_equal(b[(1, 2)].pos_m, pos[1, 2])
    assert b[0].info["nis"].shape == (4,) and b[0].pos_cov_m2.shape == (4, 2, 2) and b[0].vel_mps is None
    assert type(b.to_estimates()) is EstimatesBatch
    for bad, what in ((dict(status=st[..., :-1]), "status"), (dict(info={"nis": np.ones(4)}), "info"),
                      (dict(vel_mps=np.zeros((2, 3, 4, 3))), "vel_mps"), (dict(pos_m=pos[..., :1]), "pos_m")):
        with pytest.raises(ValueError, match=what):
            EstimatesBatch(**{**dict(t_s=t, pos_m=pos, status=st), **bad})


def test_imu_log_refuses_non_finite_samples_naming_the_first():
    """A NaN in an IMU sample would be integrated and blamed on the next UWB measurement: the container refuses it."""
    from uwbwb.types import ImuLog
    t = np.arange(0.0, 1.0, 0.01)
    acc, gyro = np.zeros((t.size, 3)), np.zeros((t.size, 3))
    ImuLog(t, acc, gyro)
    acc[37, 1] = np.nan
    with pytest.raises(ValueError, match=r"acc_mps2 must be finite: 1 sample\(s\).*index 37 \(t = 0\.370 s\)"):
        ImuLog(t, acc, gyro)
    gyro[5, 2] = np.inf
    with pytest.raises(ValueError, match="gyro_radps must be finite"):
        ImuLog(t, np.zeros((t.size, 3)), gyro)
