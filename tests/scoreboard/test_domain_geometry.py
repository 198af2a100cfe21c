"""The board judges each measurement domain on the calibration part: the TDoA methods do not run where the TDoAs
locate the tag far worse than the ranges (a small anchor cluster far from the tag), and say why; the EKFs on the
ranges run everywhere."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from uwbwb.scoreboard import score, split_in_time
from uwbwb.scoreboard import synthetic as syn
from uwbwb.scoreboard.estimators import CalibratedLs, RangeEkfEstimator, TdoaEkfEstimator, TdoaLs
from uwbwb.scoreboard.interface import GEOMETRY, MAX_TDOA_OVER_RANGES, tdoa_geometry_note
from uwbwb.scoreboard.protocol import fit_calibration
from uwbwb.types import Anchors, RangeLog, Recording, Trajectory

TDOA = ("TDoA LS", "EKF-RF")


def _methods():
    return [CalibratedLs(), TdoaLs(), TdoaEkfEstimator("RF", grid=(1.0,)), RangeEkfEstimator("RF", grid=(0.3, 1.0))]


CLUSTER = Anchors(("A0", "A1", "A2", "A3"), np.array([[0.0, 0.0, 2.0], [2.0, 0.0, 1.8], [2.0, 2.0, 0.5], [0.0, 2.0, 1.5]]))


def _recording(anchors: Anchors, offset_m: float, seed: int = 4, duration_s: float = 40.0) -> Recording:
    """The synthetic hall's random-force track (from its centre) moved ``offset_m`` along x, ranged by ``anchors``
    with 5 cm Gaussian noise."""
    rng = np.random.default_rng(seed)
    tr = syn.simulate(syn.SyntheticConfig(duration_s=duration_s), rng=rng).truth["tag"]
    pos = tr.pos_m + np.array([offset_m, 0.0, 0.0])
    r = np.linalg.norm(pos[:, None, :] - anchors.pos_m[None], axis=-1)
    r = r + 0.05 * rng.standard_normal(r.shape)
    return Recording("synthetic", f"offset-{offset_m:g}", anchors, {"tag": RangeLog(tr.t_s, r, anchors.ids, "tag")},
                     {"tag": Trajectory(tr.t_s, pos, name="truth")})


def _far_cluster(seed: int = 4, duration_s: float = 40.0) -> Recording:
    """Four anchors in a 2 m cluster, the tag about 40 m away (the Hanyang geometry)."""
    return _recording(CLUSTER, 40.0, seed, duration_s)


def _board(rec):
    cal, test = split_in_time(rec)
    return score(test, cal, estimators=_methods(), rate_hz=None, fast=True)


def test_a_far_anchor_cluster_leaves_out_the_tdoa_methods_and_keeps_the_range_ekf():
    board = _board(_far_cluster())
    df = board.table().set_index("method")
    geo = board.calibration.params(GEOMETRY)["tag"]
    assert geo["tdoa_over_ranges"] > MAX_TDOA_OVER_RANGES and geo["n_epochs"] > 100
    for m in TDOA:
        assert df.loc[m, "n_scored"] == 0
        note = df.loc[m, "note"]
        assert note.startswith("not run: TDoAs uninformative here: on the calibration part")
        assert f"{geo['tdoa_over_ranges']:.3g}× the ranges' {geo['crlb_ranges_m']:.3g} m" in note
    assert "TDoA LS" not in board.calibration.tuned and "EKF-RF" not in board.calibration.tuned   # not tuned either
    rf = df.loc["EKF-RF ranges"]
    assert rf.coverage > 0.95 and rf.rmse_m < df.loc["LS", "rmse_m"] and rf.bound_kind == "PCRLB RF ranges"


def test_spread_anchors_keep_the_tdoa_methods():
    board = _board(syn.simulate(syn.SyntheticConfig(duration_s=20.0), rng=np.random.default_rng(4)))
    df = board.table().set_index("method")
    assert board.calibration.params(GEOMETRY)["tag"]["tdoa_over_ranges"] < MAX_TDOA_OVER_RANGES
    for m in (*TDOA, "EKF-RF ranges"):
        assert df.loc[m, "coverage"] > 0.95 and not df.loc[m, "note"].startswith("not run"), m


@pytest.mark.parametrize("ratio, runs", [(0.99 * MAX_TDOA_OVER_RANGES, True), (1.01 * MAX_TDOA_OVER_RANGES, False),
                                         (np.inf, False), (np.nan, True)])
def test_the_rule_is_the_declared_factor_on_the_calibration_geometry(ratio, runs):
    rec = _far_cluster(duration_s=5.0)
    cal = fit_calibration(rec, dim=2)
    assert tdoa_geometry_note(cal, "tag") is None                       # not measured: the method runs
    cal = cal.with_tuned(GEOMETRY, {"tag": {"crlb_ranges_m": 0.1, "crlb_tdoa_m": 0.1 * ratio,
                                            "tdoa_over_ranges": ratio, "n_epochs": 10}})
    assert (tdoa_geometry_note(cal, "tag") is None) == runs
    assert (TdoaLs().applies(rec, "tag", cal) is None) == runs
    assert (TdoaEkfEstimator("RW").applies(rec, "tag", cal) is None) == runs
    assert RangeEkfEstimator("RW").applies(rec, "tag", cal) is None


def test_a_given_calibration_gets_the_geometry_of_its_calibration_part():
    rec = _far_cluster(duration_s=20.0)
    cal_rec, test = split_in_time(rec)
    given = fit_calibration(cal_rec, dim=2)
    assert GEOMETRY not in given.tuned
    board = score(test, cal_rec, estimators=[CalibratedLs(), TdoaLs()], rate_hz=None, calibration=given)
    assert board.calibration.params(GEOMETRY)["tag"]["tdoa_over_ranges"] > MAX_TDOA_OVER_RANGES
    assert board.table().set_index("method").loc["TDoA LS", "note"].startswith("not run: TDoAs")


@pytest.mark.parametrize("cal_offset_m, test_offset_m, runs", [(0.0, 300.0, True), (300.0, 0.0, False)])
def test_the_calibration_part_decides_not_the_scored_part(cal_offset_m, test_offset_m, runs):
    """The hall's eight spread anchors: inside the hall the TDoAs are informative, 300 m outside they are not. The
    board follows the calibration part's geometry whatever the scored part's."""
    hall = syn.SyntheticConfig().anchors()
    cal_rec, test = _recording(hall, cal_offset_m, seed=1, duration_s=15.0), _recording(hall, test_offset_m, seed=2,
                                                                                         duration_s=15.0)
    board = score(test, cal_rec, estimators=[CalibratedLs(), TdoaLs()], rate_hz=None)
    assert (board.calibration.params(GEOMETRY)["tag"]["tdoa_over_ranges"] < MAX_TDOA_OVER_RANGES) == runs
    assert (board.table().set_index("method").loc["TDoA LS", "n_scored"] > 0) == runs
