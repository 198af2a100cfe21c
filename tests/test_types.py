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
