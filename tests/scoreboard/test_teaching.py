"""Notebook 06's teaching pieces: the exercises' checks, the class-size board and the panel."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from uwbwb.scoreboard import exercises as sbx
from uwbwb.scoreboard import synthetic as syn
from uwbwb.scoreboard import teaching as sbt
from uwbwb.scoreboard.estimators import CalibratedLs, RawLs, TdoaEkfEstimator
from tests.test_teaching import assert_reads_predictions

CONFIG = syn.SyntheticConfig()


@pytest.fixture(scope="module")
def board():
    ests = [RawLs(), CalibratedLs(), TdoaEkfEstimator("RJ", grid=(0.05, 0.5, 5.0)), TdoaEkfEstimator("RF", grid=(1.0,))]
    return syn.synthetic_board(CONFIG, seed=1, estimators=ests, fast=True)


def test_doubling_the_range_noise_doubles_the_ls_bound_and_rmse():
    check = sbx.noisier_ranges(CONFIG, factor=2.0, n_runs=2, seed=3)
    assert check.holds, check
    assert check.numbers["bound ratio"] == pytest.approx(2.0, rel=0.01)
    assert check.numbers["RMSE ratio"] != pytest.approx(2.0, rel=1e-3)     # fresh draws: not scaled copies
    assert_reads_predictions(check)


def test_the_noise_check_fails_where_the_fix_is_not_linear_in_the_ranges():
    # a 3 m hall with 0.5 -> 1 m of range noise: the noise is not small against the distances (and the tag soon
    # walks out of the hall), so the LS error does not scale with σ
    check = sbx.noisier_ranges(replace(CONFIG, sigma_m=0.5, hall_m=3.0), factor=2.0, n_runs=2, seed=0)
    assert not check.holds, check
    assert check.holds == (abs(check.numbers["RMSE ratio"] / 2.0 - 1) < 0.2)
    assert_reads_predictions(check)
    with pytest.raises(ValueError, match="factor"):
        sbx.noisier_ranges(CONFIG, factor=0.0)


def test_a_lower_rate_raises_the_filter_bound_and_not_the_snapshot_bound():
    check = sbx.lower_rate(CONFIG, rate_hz=4.0, n_runs=2, seed=4)
    assert check.holds, check
    n = check.numbers
    assert n["EKF-RF bound at 4 Hz (cm)"] > 1.1 * n["EKF-RF bound at 10 Hz (cm)"]
    assert n["LS bound at 4 Hz (cm)"] == pytest.approx(n["LS bound at 10 Hz (cm)"], rel=0.1)
    assert check.holds == (n["EKF-RF RMSE at 4 Hz (cm)"] > n["EKF-RF RMSE at 10 Hz (cm)"])
    assert_reads_predictions(check)


def test_the_rate_check_goes_either_way_when_the_rate_hardly_changes():
    # 10 -> 9.5 Hz moves the EKF-RF bound by about 1 %: whether its RMSE rises depends on the runs
    checks = [sbx.lower_rate(CONFIG, rate_hz=9.5, n_runs=2, seed=s) for s in (0, 2)]
    assert [c.holds for c in checks] == [False, True]
    for c in checks:
        assert c.numbers["EKF-RF bound ratio"] == pytest.approx(1.0, abs=0.03)
        assert c.holds == (c.numbers["EKF-RF RMSE at 9.5 Hz (cm)"] > c.numbers["EKF-RF RMSE at 10 Hz (cm)"])
        assert_reads_predictions(c)


def test_the_rate_check_refuses_a_rate_that_is_not_lower():
    with pytest.raises(ValueError, match="rate_hz"):
        sbx.lower_rate(CONFIG, rate_hz=20.0)
    with pytest.raises(ValueError, match="n_runs"):
        sbx.lower_rate(CONFIG, n_runs=1)


def test_short_table_keeps_the_main_columns_of_the_methods_that_ran(board):
    t = sbt.short_table(board)
    assert list(t.index) == ["raw LS", "LS", "EKF-RJ", "EKF-RF"]
    assert tuple(t.columns) == sbt.SHORT_COLUMNS[1:]
    np.testing.assert_allclose(t["rmse_m"], board.table().set_index("method").loc[t.index, "rmse_m"], atol=5e-4)


def test_panel_offers_only_the_tags_the_boards_have(board):
    panel = sbt.panel({"synthetic": board})
    assert len(panel.controls["tag_index"].options) == len(board.tags) == 1
    panel.set(methods="per-epoch fixes (LS family)")
    assert "methods shown" in panel.readout_text
