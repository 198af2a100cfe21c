"""The one scorer: own epochs, common epochs, coverage and statistics on either (uwbwb/metrics/scoring.py)."""

import numpy as np
import pandas as pd
import pytest

from uwbwb import metrics as m

NAN = np.nan
#: Six epochs, no truth at the first; A misses epoch 3, B misses epochs 0 and 2.
TRUTH = np.array([False, True, True, True, True, True])
ERR_M = {"A": np.array([9.0, 1.0, 2.0, NAN, 4.0, 5.0]), "B": np.array([NAN, 3.0, NAN, 1.0, 2.0, 6.0])}


def test_two_methods_with_different_coverage_are_ranked_on_their_common_epochs():
    s = m.score_epochs(ERR_M, TRUTH)
    a, b = s["A"], s["B"]
    assert s.names == ("A", "B")
    np.testing.assert_array_equal(a.scored, [False, True, True, False, True, True])     # epoch 0: no truth
    np.testing.assert_array_equal(b.scored, [False, True, False, True, True, True])
    np.testing.assert_array_equal(a.common, [False, True, False, False, True, True])
    np.testing.assert_array_equal(a.common, b.common)
    assert (a.n_epochs, a.n_scored, a.n_common, a.coverage) == (5, 4, 3, 0.8)
    assert (b.n_epochs, b.n_scored, b.n_common, b.coverage) == (5, 4, 3, 0.8)
    np.testing.assert_array_equal(a.own_m, [1.0, 2.0, 4.0, 5.0])
    np.testing.assert_array_equal(a.common_m, [1.0, 4.0, 5.0])
    np.testing.assert_array_equal(b.common_m, [3.0, 2.0, 6.0])
    np.testing.assert_array_equal(a.failed_counted_m, [1.0, 2.0, np.inf, 4.0, 5.0])
    st = a.stats(own={"median_m": np.median}, common={"rmse_common_m": m.rmse, "max_common_m": np.max},
                 failed_counted={"max_failed_m": np.max})
    assert st == {"median_m": 3.0, "rmse_common_m": np.sqrt(14.0), "max_common_m": 5.0, "max_failed_m": np.inf}
    t = s.table(own={"median_m": np.median}, common={"rmse_common_m": m.rmse})
    assert list(t.columns) == ["n_epochs", "n_scored", "coverage", "n_common", "median_m", "rmse_common_m"]
    assert t.index.name == "method" and list(t.index) == ["A", "B"]
    assert t.loc["B", "median_m"] == 2.5 and t.loc["B", "rmse_common_m"] == pytest.approx(np.sqrt(49.0 / 3))


def test_without_truth_mask_every_epoch_counts_and_per_method_masks_are_allowed():
    s = m.score_epochs(ERR_M)
    assert s["A"].n_epochs == 6 and s["A"].coverage == 5 / 6 and s["A"].n_common == 3
    s = m.score_epochs(ERR_M, {"A": TRUTH, "B": np.ones(6, bool)})
    assert s["A"].n_epochs == 5 and s["B"].n_epochs == 6 and s["A"].n_common == 3
    with pytest.raises(ValueError, match="truth masks given"):
        m.score_epochs(ERR_M, {"A": TRUTH})
    with pytest.raises(ValueError, match="one epoch grid"):
        m.score_epochs({"A": np.ones(3), "B": np.ones(4)})
    alone = m.score_epochs({"A": np.ones(3), "B": np.r_[1.0, NAN, 2.0, 3.0]}, compare=False)
    np.testing.assert_array_equal(alone["B"].common, alone["B"].scored)


def test_nan_is_no_estimate_an_infinite_error_is_one_and_a_method_with_none_has_nan_statistics():
    err = {**ERR_M, "C": np.full(6, NAN)}
    s = m.score_epochs(err, TRUTH)
    c = s["C"]
    assert (c.n_scored, c.coverage, c.n_common) == (0, 0.0, 0)
    assert s["A"].n_common == 0                                            # nothing is common with C
    st = c.stats(own={"rmse_m": m.rmse}, common={"rmse_common_m": m.rmse},
                 failed_counted={"p90_failed_counted_m": lambda e: np.quantile(e, 0.9, method="inverted_cdf")})
    assert np.isnan(st["rmse_m"]) and np.isnan(st["rmse_common_m"]) and st["p90_failed_counted_m"] == np.inf
    assert np.isnan(s["A"].stats(common={"x": m.rmse})["x"])
    inf = m.score_epochs({"A": np.array([1.0, np.inf])})["A"]        # a diverged estimate is not hidden
    assert inf.n_scored == 2 and inf.coverage == 1.0 and inf.own_m[-1] == np.inf
    empty = m.score_epochs({"A": np.zeros(0)})["A"]
    assert empty.n_epochs == 0 and np.isnan(empty.coverage)
    with pytest.raises(ValueError, match="common epoch"):
        m.MethodEpochs("A", np.array([NAN]), np.array([True]), np.array([True]))


def test_pooling_concatenates_each_method_in_part_order():
    p1 = m.score_epochs(ERR_M, TRUTH)
    p2 = m.score_epochs({"B": np.array([7.0, NAN]), "D": np.array([1.0, 1.0])})
    pooled = m.pool_scores([p1, p2])
    assert pooled.names == ("A", "B", "D")
    b = pooled["B"]
    np.testing.assert_array_equal(b.own_m, [3.0, 1.0, 2.0, 6.0, 7.0])
    np.testing.assert_array_equal(b.common_m, [3.0, 2.0, 6.0, 7.0])          # common within each part
    assert b.n_epochs == 7 and b.coverage == 5 / 7
    np.testing.assert_array_equal(pooled["A"].own_m, p1["A"].own_m)
    np.testing.assert_array_equal(m.pool_scores([p2, p1])["B"].own_m, [7.0, 3.0, 1.0, 2.0, 6.0])


def test_errors_on_grid_by_exact_time():
    s = {"A": m.ErrorSeries("A", [0.0, 0.1, 0.2], [1.0, 2.0, 3.0]),
         "B": m.ErrorSeries("B", [0.1, 0.2, 0.3], [4.0, NAN, 6.0])}
    t, err = m.errors_on_grid(s)
    np.testing.assert_array_equal(t, [0.0, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(err["A"], [1.0, 2.0, 3.0, NAN])
    np.testing.assert_array_equal(err["B"], [NAN, 4.0, NAN, 6.0])
    sc = m.score_epochs(err)
    np.testing.assert_array_equal(t[sc["A"].common], [0.1])
    with pytest.raises(ValueError, match="strictly increasing"):
        m.errors_on_grid({"A": m.ErrorSeries("A", [0.0, 0.0], [1.0, 1.0])})
    with pytest.raises(ValueError, match="no error series"):
        m.errors_on_grid({})


def test_epoch_summary_is_the_scorer_with_each_estimator_alone():
    ep = pd.DataFrame({"estimator": ["a"] * 4 + ["b"] * 3, "err_m": [1.0, NAN, 3.0, 2.0, 5.0, 6.0, NAN]})
    s = m.epoch_summary(ep)
    sc = m.score_epochs({"a": [1.0, NAN, 3.0, 2.0], "b": [5.0, 6.0, NAN]}, compare=False)
    assert list(s["n_epochs"]) == [4, 3] and list(s["coverage"]) == [sc["a"].coverage, sc["b"].coverage]
    assert s.loc["a", "median_m"] == 2.0 and s.loc["b", "p90_failed_counted_m"] == np.inf
