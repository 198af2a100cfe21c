import json

import numpy as np
import pandas as pd
import pytest

import uwbwb as uw
from uwbwb import metrics as m


# --------------------------------------------------------------------------- errors


def test_position_error_horizontal_and_3d():
    est = np.array([[3.0, 4.0, 10.0], [0.0, 0.0, 0.0]])
    true = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    np.testing.assert_allclose(m.position_error_m(est, true), [5.0, 0.0])
    np.testing.assert_allclose(m.position_error_m(est, true, horizontal=False), [np.sqrt(125.0), 2.0])
    np.testing.assert_allclose(m.position_error_m(est[:, :2], true), [5.0, 0.0])
    with pytest.raises(ValueError, match="equal dimension"):
        m.position_error_m(est[:, :2], true, horizontal=False)
    with pytest.raises(ValueError, match="epochs"):
        m.position_error_m(est, true[:1])
    with pytest.raises(ValueError):
        m.position_error_m(est[0], true[0])


def test_errors_vs_truth_interpolates_and_counts_exclusions():
    t_truth = np.linspace(0.0, 10.0, 11)
    truth = uw.Trajectory(t_truth, np.column_stack([t_truth, 2 * t_truth]), name="truth")
    t_est = np.array([-1.0, 0.0, 2.5, 7.25, 10.0, 10.5, 12.0])
    offset = np.array([0.0, 0.3, 0.0, 0.4, 0.0, 0.0, 0.0])
    est = uw.Trajectory(t_est, np.column_stack([t_est + offset, 2 * t_est]), name="LS")
    es = m.errors_vs_truth(est, truth)
    assert es.name == "LS" and es.n_outside == 3 and es.n_in_gap == 0 and es.n_excluded == 3
    np.testing.assert_allclose(es.t_s, [0.0, 2.5, 7.25, 10.0])
    np.testing.assert_allclose(es.err_m, [0.3, 0.0, 0.4, 0.0], atol=1e-12)
    assert "3 outside the truth time span excluded" in es.report()
    assert es.stats()["n_excluded"] == 3


def test_errors_vs_truth_gaps():
    t_truth = np.array([0.0, 1.0, 2.0, 5.0, 6.0])
    truth = uw.Trajectory(t_truth, np.zeros((5, 3)))
    t_est = np.array([0.5, 2.0, 3.0, 4.5, 5.5])
    est = uw.Trajectory(t_est, np.ones((5, 3)))
    es = m.errors_vs_truth(est, truth, max_gap_s=1.5, horizontal=False)
    np.testing.assert_allclose(es.t_s, [0.5, 2.0, 5.5])          # 2.0 is a truth sample: kept
    assert es.n_in_gap == 2 and es.n_outside == 0
    np.testing.assert_allclose(es.err_m, np.sqrt(3.0))
    assert "2 in truth gaps excluded" in es.report()
    assert len(m.errors_vs_truth(est, truth)) == 5
    with pytest.raises(ValueError):
        m.errors_vs_truth(est, truth, max_gap_s=0.0)
    with pytest.raises(ValueError):
        m.errors_vs_truth(est.pos_m, truth)


# --------------------------------------------------------------------------- statistics


def test_ecdf_and_quantile_rule():
    x, F = m.ecdf([3.0, 1.0, 2.0, 4.0])
    np.testing.assert_allclose(x, [1, 2, 3, 4])
    np.testing.assert_allclose(F, [0.25, 0.5, 0.75, 1.0])
    assert m.cep([3.0, 1.0, 2.0, 4.0], 0.5) == 2.0          # ceil(0.5 * 4) = 2nd smallest
    assert m.cep([3.0, 1.0, 2.0, 4.0], 0.51) == 3.0
    assert m.cep([3.0, 1.0, 2.0, 4.0], 1.0) == 4.0
    e = np.arange(1.0, 101.0)
    assert m.cep95(e) == 95.0 and m.cep50(e) == 50.0       # 0.95 * 100 must not round up to 96
    rng = np.random.default_rng(3)
    for n in (1, 7, 20, 333):
        e = rng.exponential(size=n)
        for p in (0.05, 0.5, 0.9, 0.95, 1.0):
            assert m.cep(e, p) == np.quantile(e, p, method="inverted_cdf")
            x, F = m.ecdf(e)
            assert F[np.searchsorted(x, m.cep(e, p))] >= p   # the CEP is a point on the ECDF


def test_cep_of_rayleigh_errors():
    rng = np.random.default_rng(42)
    sigma = 0.2
    err = np.linalg.norm(sigma * rng.standard_normal((20_000, 2)), axis=1)
    assert m.cep50(err) == pytest.approx(sigma * np.sqrt(2 * np.log(2)), rel=0.02)
    assert m.cep95(err) == pytest.approx(sigma * np.sqrt(-2 * np.log(0.05)), rel=0.02)
    assert m.rmse(err) == pytest.approx(sigma * np.sqrt(2), rel=0.02)


def test_error_stats_and_nan_policy():
    s = m.error_stats([1.0, 2.0, 3.0, 4.0])
    assert s == {"n": 4, "n_omitted": 0, "mean": 2.5, "median": 2.5, "rmse": pytest.approx(np.sqrt(7.5)),
                 "cep50": 2.0, "cep95": 4.0, "max": 4.0}
    with pytest.raises(ValueError, match="1 NaN"):
        m.error_stats([1.0, np.nan])
    for f in (m.ecdf, m.cep50, m.cep95, m.rmse):
        with pytest.raises(ValueError, match="NaN"):
            f([1.0, np.nan])
    s = m.error_stats([1.0, np.nan, 3.0], nan="omit")
    assert s["n"] == 2 and s["n_omitted"] == 1 and s["mean"] == 2.0
    for bad in ([], [np.nan], [1.0, np.inf], [-1.0, 1.0], [[1.0, 2.0]]):
        with pytest.raises(ValueError):
            m.error_stats(bad, nan="omit")
    with pytest.raises(ValueError):
        m.error_stats([1.0], nan="drop")
    with pytest.raises(ValueError):
        m.cep([1.0], 0.0)
    assert m.rmse([-3.0, 3.0]) == 3.0                         # signed values are fine for RMSE / ECDF


# --------------------------------------------------------------------------- summary


def _summary():
    s = m.Summary("00_quickstart", fast=False)
    s.add(quantity="CEP95, tag t0, raw multilateration", value=0.31, unit="m",
          paper_value=None, data="lias-planar-uwb/fast", kind="reproduced")
    s.add(quantity="RMSE, EKF", value=np.float32(12.5), unit="cm", paper_value=np.int64(11), data="synthetic",
          kind="target")
    s.add(quantity="epochs", value=np.int64(500), unit="", paper_value=float("nan"), data="synthetic",
          kind="input")
    return s


def test_summary_frame():
    s = _summary()
    df = s.frame()
    assert list(df.columns) == ["notebook", "quantity", "value", "unit", "paper_value", "data", "kind", "mode"]
    assert df["kind"].tolist() == ["reproduced", "target", "input"] and (df["mode"] == "full").all()
    assert len(s) == len(df) == 3
    assert (df["notebook"] == "00_quickstart").all()
    assert df["value"].tolist() == [0.31, 12.5, 500.0]
    assert np.isnan(df["paper_value"][0]) and df["paper_value"][1] == 11.0 and np.isnan(df["paper_value"][2])
    assert len(m.Summary("x", fast=True)) == 0 and m.Summary("x", fast=True).mode == "FAST"
    empty = m.Summary("x", fast=False).frame()
    assert list(empty.columns) == list(m.Summary.COLUMNS) and len(empty) == 0


@pytest.mark.parametrize("field, bad", [
    ("value", "0.3"), ("value", float("nan")), ("value", np.inf), ("value", True), ("value", 1 + 2j),
    ("value", None), ("value", np.array([1.0])), ("paper_value", np.inf), ("paper_value", "3"),
    ("unit", None), ("unit", 3), ("data", "fast"), ("data", "/fast"), ("data", "lias/"), ("data", None),
    ("quantity", ""), ("quantity", 3), ("kind", "reproduce"), ("kind", None), ("kind", "Target"),
])
def test_summary_validation(field, bad):
    row = dict(quantity="q", value=1.0, unit="m", paper_value=None, data="synthetic", kind="reproduced")
    row[field] = bad
    with pytest.raises(ValueError, match=field):
        m.Summary("nb", fast=False).add(**row)


def test_summary_names_an_assumption_as_its_own_kind():
    s = m.Summary("nb", fast=False)      # a simulator setting the paper does not give is neither input nor target
    s.add(quantity="timing jitter", value=1.5, unit="cm", paper_value=None, data="synthetic", kind="assumption")
    assert s.frame()["kind"].tolist() == ["assumption"]
    assert m.Headline("timing jitter", "cm", "assumption", lambda f: f["jitter"]).row({"jitter": 1.5})["kind"] == \
        "assumption"


def test_summary_needs_kind_and_mode():
    with pytest.raises(TypeError):
        m.Summary("nb")                      # the mode is not guessed
    with pytest.raises(TypeError):
        m.Summary("nb", fast=True).add(quantity="q", value=1.0, unit="m", data="synthetic")
    with pytest.raises(ValueError, match="fast"):
        m.Summary("nb", fast="yes")


def test_summary_rejects_duplicates_and_bad_notebook():
    s = _summary()
    with pytest.raises(ValueError, match="already added"):
        s.add(quantity="RMSE, EKF", value=1.0, unit="cm", data="synthetic", kind="reproduced")
    s.add(quantity="RMSE, EKF", value=1.0, unit="cm", data="lias-planar-uwb/fast", kind="reproduced")
    with pytest.raises(ValueError):
        m.Summary("", fast=False)
    with pytest.raises(ValueError, match="nothing to publish"):
        m.Summary("nb", fast=False).publish("unused.json")


def test_summary_publish_json_round_trip(tmp_path):
    s = _summary()
    path = tmp_path / "deep" / "er" / "00_quickstart.summary.json"
    df = s.publish(path)
    pd.testing.assert_frame_equal(df, s.frame())
    rows = json.loads(path.read_text())
    assert rows[0] == {"notebook": "00_quickstart", "quantity": "CEP95, tag t0, raw multilateration",
                       "value": 0.31, "unit": "m", "paper_value": None, "data": "lias-planar-uwb/fast",
                       "kind": "reproduced", "mode": "full"}
    assert rows[1]["paper_value"] == 11.0 and rows[2]["paper_value"] is None
    assert "NaN" not in path.read_text()
    # publish() without a path only returns the frame.
    assert s.publish() is not None and sorted(p.name for p in tmp_path.rglob("*.json")) == [path.name]


def test_epoch_summary_counts_failures_beside_accuracy():
    ep = pd.DataFrame({"estimator": ["none"] * 10 + ["point"] * 10,
                       "err_m": np.r_[np.arange(10.0), np.arange(8.0), np.nan, np.nan]})
    s = m.epoch_summary(ep)
    assert list(s.index) == ["none", "point"] and list(m.epoch_summary(ep, order=("point",)).index) == ["point", "none"]
    assert s.loc["none", "coverage"] == 1.0 and s.loc["point", "coverage"] == 0.8
    assert s.loc["point", "median_m"] == 3.5 and s.loc["none", "p90_failed_counted_m"] == 8.0
    assert np.isinf(s.loc["point", "p90_failed_counted_m"])


def test_nees_is_the_quadratic_form_where_evaluated():
    e = np.array([[1.0, 2.0], [0.5, -1.0], [np.nan, 0.0], [1.0, 1.0]])
    P = np.stack([np.diag([1.0, 4.0]), np.array([[2.0, 0.5], [0.5, 1.0]]), np.eye(2), np.eye(2)])
    out = m.nees(e, P, where=[True, True, True, False])
    assert out[0] == pytest.approx(2.0)
    assert out[1] == pytest.approx(e[1] @ np.linalg.solve(P[1], e[1]))
    assert np.isnan(out[2]) and np.isnan(out[3])                 # non-finite error; left out
    assert m.nees(np.zeros((0, 3)), np.zeros((0, 3, 3))).shape == (0,)
    with pytest.raises(ValueError, match="nees"):
        m.nees(e, P[:, :1, :1])


def test_nis_consistency_is_one_function_with_one_set_of_keys():
    from uwbwb.filters.ekf import nis_consistency
    assert nis_consistency is m.nis_consistency                  # the old import path still works
    rng = np.random.default_rng(0)
    dof = rng.integers(1, 4, 2000)
    c = m.nis_consistency(rng.chisquare(dof), dof)
    assert c["verdict"] == "consistent" and 0.93 < c["fraction_inside"] < 0.97 and c["n"] == 2000
    assert m.nis_consistency(3 * rng.chisquare(dof), dof)["verdict"] == "over-confident"
    assert m.nis_consistency(rng.chisquare(dof) / 3, dof)["verdict"] == "under-confident"
    none = m.nis_consistency([np.nan, 1.0], [2, 0])                  # nothing used: no updates
    assert none["verdict"] == "no updates" and set(none) == set(c)


@pytest.mark.parametrize("lo, hi, null, side", [(-2.0, -0.1, 0.0, "below"), (0.1, 2.0, 0.0, "above"),
                                                (-1.0, 1.0, 0.0, "contains"), (0.0, 1.0, 0.0, "contains"),
                                                (1.2, 1.5, 1.0, "above"), (0.4, 0.9, 1.0, "below"),
                                                (np.nan, 1.0, 0.0, "none"), (0.0, np.inf, 0.0, "none")])
def test_interval_side_rejects_the_null_only_when_the_interval_excludes_it(lo, hi, null, side):
    assert m.interval_side(lo, hi, null) == side


def test_tied_ranks_split_only_where_every_pair_across_is_decided():
    """Ranks walk up the given order; a cut needs every item before it decided better than every item after it,
    so a decided pair inside a tie (a ≈ b, a ≈ c, b better than c) ties all three, and nothing decided ties all."""
    assert m.tied_ranks("abc", {("a", "b"), ("a", "c"), ("b", "c")}) == {"a": 1, "b": 2, "c": 3}
    assert m.tied_ranks("abc", {("a", "c"), ("b", "c")}) == {"a": 1, "b": 1, "c": 3}
    assert m.tied_ranks("abc", {("b", "c")}) == {"a": 1, "b": 1, "c": 1}
    assert m.tied_ranks("abc", {("a", "b"), ("a", "c")}) == {"a": 1, "b": 2, "c": 2}
    assert m.tied_ranks("abc", set()) == {"a": 1, "b": 1, "c": 1}


def test_block_bootstrap_median_difference_sees_a_shift_and_not_a_tie():
    """``statistic="median"``: the interval of median(a) − median(b) lies above 0 for a shifted method, contains 0
    for the same errors relabelled, and is NaN with fewer than MIN_BLOCKS blocks; a bad statistic is an error."""
    import pytest

    from uwbwb.metrics import block_bootstrap_difference, interval_side

    rng = np.random.default_rng(3)
    base = [np.abs(rng.normal(0, 1, 60)) for _ in range(6)]
    shifted = block_bootstrap_difference([b + 0.4 + rng.normal(0, 0.05, b.size) for b in base], base,
                                         rng=np.random.default_rng(0), statistic="median")
    assert shifted["diff_m"] == pytest.approx(0.4, abs=0.05) and interval_side(shifted["lo_m"], shifted["hi_m"]) == "above"
    noisy = [b * np.exp(rng.normal(0, 0.3, b.size)) for b in base]
    tie = block_bootstrap_difference(noisy, base, rng=np.random.default_rng(0), statistic="median")
    assert interval_side(tie["lo_m"], tie["hi_m"]) == "contains"
    assert set(tie) >= {"median_a_m", "median_b_m", "n_blocks"} and "rmse_a_m" not in tie
    few = block_bootstrap_difference(base[0][:8], base[0][:8] + 1, rng=np.random.default_rng(0), statistic="median")
    assert np.isnan(few["lo_m"]) and few["diff_m"] == pytest.approx(-1.0)
    with pytest.raises(ValueError, match="statistic must be 'rmse' or 'median'"):
        block_bootstrap_difference(base, base, rng=np.random.default_rng(0), statistic="mean")


def test_segment_blocks_see_an_offset_shared_within_a_segment_that_acf_blocks_do_not():
    """Twelve 10-stop series whose differences share one offset per series (as stops of one simulated experiment
    share its range biases): the ACF of a mean-centred series cannot see the offset, so its blocks (about 5 a
    series) count each series several times as independent; resampling whole series widens the interval by
    about √5."""
    from uwbwb.metrics import block_bootstrap_difference

    rng = np.random.default_rng(3)
    b = [np.abs(rng.normal(1.0, 0.05, 10)) for _ in range(12)]
    a = [x + rng.normal(0.0, 0.3) + rng.normal(0.0, 0.01, 10) for x in b]      # one offset per series
    acf = block_bootstrap_difference(a, b, rng=np.random.default_rng(0), statistic="median")
    seg = block_bootstrap_difference(a, b, rng=np.random.default_rng(0), statistic="median", blocks="segment")
    assert seg["n_blocks"] == 12 and acf["n_blocks"] >= 4 * 12
    assert seg["diff_m"] == acf["diff_m"]
    assert (seg["hi_m"] - seg["lo_m"]) > 1.5 * (acf["hi_m"] - acf["lo_m"]), (seg, acf)
    r = block_bootstrap_difference(a, b, rng=np.random.default_rng(0), blocks="segment")
    assert r["n_blocks"] == 12 and np.isfinite(r["lo_m"])
    with pytest.raises(ValueError, match="blocks"):
        block_bootstrap_difference(a, b, rng=np.random.default_rng(0), blocks="time")
