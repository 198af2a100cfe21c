import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from uwbwb.calibration import (RangeCalibration, fit_range_calibration, fit_range_sigma, fit_set_noise,
                               fit_set_noise_from_fixes, location_statistics, percentile_by_file, range_residuals,
                               range_sigma_from_truth)
from uwbwb.sim import rig
from uwbwb.types import Anchors, RangeLog, SetFixLog, TagRun, Trajectory


@pytest.fixture(scope="module")
def campaign():
    rng = np.random.default_rng(3)
    cfg = rig.RigConfig(sigma_m=0.03, outlier_prob=0.05, outlier_mean_m=0.6, scale_sigma=0.01)
    static, model = rig.simulate_static(cfg, duration_s=4.0, rng=rng)
    return cfg, static, model


def test_recovers_known_bias_and_scale_despite_outliers(campaign):
    _, static, model = campaign
    cal = fit_range_calibration(static)
    assert cal.scale_fitted.all()
    np.testing.assert_allclose(cal.bias_m, model.bias_m, atol=0.02)
    np.testing.assert_allclose(cal.scale, model.scale, atol=0.006)
    # the robust sigma of residuals estimates the white noise, not the outliers
    np.testing.assert_allclose(cal.resid_sigma_m, 0.03, atol=0.01)
    assert (cal.n_samples == 30 * 400).all()


def test_plain_least_squares_would_be_pulled_by_outliers(campaign):
    """Guards the robust loss: an unweighted fit is biased by the positive outliers."""
    _, static, model = campaign
    cal = fit_range_calibration(static, n_iter=1)            # first IRLS pass = ordinary LS
    robust = fit_range_calibration(static)
    err_ls = np.abs(cal.bias_m + (cal.scale - 1) * 4 - (model.bias_m + (model.scale - 1) * 4)).mean()
    err_rob = np.abs(robust.bias_m + (robust.scale - 1) * 4 - (model.bias_m + (model.scale - 1) * 4)).mean()
    assert err_rob < 0.5 * err_ls


def test_calibration_removes_bias_on_an_independent_dynamic_run(campaign):
    cfg, static, model = campaign
    cal = fit_range_calibration(static)
    dyn, _ = rig.simulate_dynamic(dataclasses.replace(cfg, duration_s=20.0), rng=np.random.default_rng(9),
                                  range_model=model)
    before = range_residuals(dyn)
    after = range_residuals(dyn, cal)
    assert before["median_m"].abs().mean() > 0.15
    assert after["median_m"].abs().max() < 0.03


def test_short_span_gets_bias_only_fit(rng):
    cfg = rig.RigConfig(outlier_prob=0.0)
    static, model = rig.simulate_static(cfg, poses_xy_yaw=[(0.5, 0.3, 0.0)], duration_s=2.0, rng=rng)
    cal = fit_range_calibration(static)
    assert not cal.scale_fitted.any() and np.all(cal.scale == 1.0)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_file_round_trip(campaign, tmp_path, suffix):
    _, static, _ = campaign
    cal = fit_range_calibration(static[:6])
    back = RangeCalibration.load(cal.save(tmp_path / f"cal{suffix}"))
    for name in ("bias_m", "scale", "scale_fitted", "n_samples", "resid_sigma_m"):
        np.testing.assert_allclose(getattr(back, name), getattr(cal, name), rtol=1e-5)
    assert back.anchor_ids == cal.anchor_ids and back.tag_ids == cal.tag_ids
    if suffix == ".json":
        assert back.source == cal.source


def test_refuses_mismatched_logs_and_units(campaign, tmp_path):
    _, static, _ = campaign
    cal = fit_range_calibration(static[:6])
    log = static[0].ranges["t0"]
    with pytest.raises(ValueError, match="anchors"):
        cal.apply(RangeLog(log.t_s, log.range_m[:, :7], log.anchor_ids[:7], "t0"))
    with pytest.raises(ValueError, match="no tag 'tX'"):
        cal.apply(dataclasses.replace(log, tag_id="tX"))
    df = cal.to_frame().rename(columns={"bias_m": "bias_cm"})
    df.to_csv(tmp_path / "cm.csv", index=False)
    with pytest.raises(ValueError, match="not in metres"):
        RangeCalibration.load(tmp_path / "cm.csv")
    doc = json.loads(cal.save(tmp_path / "c.json").read_text())
    doc["units"]["bias"] = "cm"
    (tmp_path / "c.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="expected metres"):
        RangeCalibration.load(tmp_path / "c.json")


def test_apply_recording_counts_ranges_set_missing(campaign):
    _, static, _ = campaign
    cal = fit_range_calibration(static)
    rec = static[0]
    log = rec.ranges["t0"]
    r = log.range_m.copy()
    r[:5, 2] = 0.0                                       # below any positive bias
    rec = dataclasses.replace(rec, ranges={**rec.ranges, "t0": dataclasses.replace(log, range_m=r)})
    out = cal.apply_recording(rec)
    assert out.cleaning[-1].n_affected == 5
    assert np.isnan(out.ranges["t0"].range_m[:5, 2]).all()
    np.testing.assert_array_equal(rec.ranges_of("t0", cal).range_m, out.ranges["t0"].range_m)   # one tag alike
    assert rec.ranges_of("t0") is rec.ranges["t0"]                                          # no calibration: as logged


def test_too_few_samples_is_an_error(rng):
    static, _ = rig.simulate_static(rig.RigConfig(), poses_xy_yaw=[(0, 0, 0)], duration_s=0.1, rng=rng)
    with pytest.raises(ValueError, match="samples"):
        fit_range_calibration(static)


# ----------------------------------------------------------------------------- with the LIAS loader

def test_calibrates_another_rooms_static_poses_with_its_own_anchor_table(tmp_path):
    """The 8.20 room has its own anchor/tag/pose tables: same code, no changes."""
    from tests.fixtures import lias as fx
    from uwbwb.datasets import lias

    rng = np.random.default_rng(4)
    fx.make_tree(tmp_path, rng=rng, sessions=[fx.session_814(rng), fx.session_820(rng)])
    static = lias.load_static("8.20", tmp_path)
    np.testing.assert_allclose(static[0].anchors.pos_m, fx.ROOM_B.anchors_m, atol=1e-4)
    cal = fit_range_calibration(static)
    assert cal.source == tuple(r.label for r in static)
    resid = range_residuals(static[0], cal)
    assert resid["median_m"].abs().max() < 0.5      # fixture biases are redrawn per file: loose bound


@pytest.mark.realdata
def test_lias_static_calibration_improves_the_fast_run():
    """Calibrate on the 8.14 static poses, evaluate on the dynamic run of the same room."""
    from tests.conftest import real_dataset
    from uwbwb.datasets import lias

    real_dataset(lias.NAME)
    static = [r for r in lias.load_static("8.14")]
    cal = fit_range_calibration(static)
    fast = lias.load_dynamic("fast")
    before = range_residuals(fast)
    after = range_residuals(fast, cal)
    # per-pair biases of ~0.1-0.3 m on the moving trolley shrink to a few centimetres
    assert before["median_m"].abs().median() > 0.08
    assert after["median_m"].abs().median() < 0.04
    assert cal.scale_fitted.all() and np.all(np.abs(cal.scale - 1) < 0.05)


@pytest.mark.parametrize("kwargs, name", [
    (dict(n_iter=0), "n_iter"), (dict(n_iter=2.5), "n_iter"), (dict(min_samples=1), "min_samples"),
    (dict(min_span_m=-1.0), "min_span_m"), (dict(min_span_m=float("nan")), "min_span_m"),
])
def test_fit_parameters_are_checked(campaign, kwargs, name):
    # n_iter=0 used to return an identity calibration marked as fitted
    with pytest.raises(ValueError, match=name):
        fit_range_calibration(campaign[1], **kwargs)


# --------------------------------------------------------------------------- range noise per anchor (paper 002)

def test_range_sigma_from_truth(rng):
    T = 5000
    true = np.full((T, 2), 5.0)
    meas = true + np.array([0.05, 0.10]) * rng.standard_normal((T, 2)) + np.array([0.3, 0.0])
    meas[rng.random(T) < 0.05, 1] += 3.0                              # NLOS outliers on anchor 1
    robust = range_sigma_from_truth(meas, true)
    np.testing.assert_allclose(robust, [0.05, 0.10], rtol=0.08)
    rms = range_sigma_from_truth(meas, true, robust=False)
    assert rms[0] == pytest.approx(np.hypot(0.3, 0.05), rel=0.05) and rms[1] > 0.5
    with pytest.raises(ValueError, match="fewer than two"):
        range_sigma_from_truth(np.full((3, 2), np.nan), true[:3])


def test_fit_range_sigma_readings():
    anchors = Anchors(tuple("ABCD"), np.array([[0, 0, 2.5], [10, 0, 2.5], [10, 8, 2.4], [0, 8, 2.6]]))
    rng = np.random.default_rng(11)
    t = np.arange(4000) * 0.1
    pos = np.column_stack([5 + 2 * np.sin(0.05 * t), 4 + 2 * np.cos(0.05 * t), np.full(t.size, 1.2)])
    true = np.linalg.norm(pos[:, None] - anchors.pos_m, axis=-1)
    common = 0.4 * rng.standard_normal((t.size, 1))                        # cancels in every TDoA
    meas = true + common + 0.05 * rng.standard_normal(true.shape)
    run = TagRun("synthetic", "x", "t", RangeLog(t, meas, anchors.ids, "t"), Trajectory(t, pos), anchors, 2, 1.2)
    np.testing.assert_allclose(fit_range_sigma(run), 0.05, rtol=0.08)               # the part TDoAs see
    assert np.all(fit_range_sigma(run, method="rms") > 0.35)                         # common part included
    assert np.all(fit_range_sigma(run, floor_m=0.5) == 0.5)
    with pytest.raises(ValueError, match="method"):
        fit_range_sigma(run, method="mad")


# --------------------------------------------------------------------------- NLOS percentile per file

def test_percentile_by_file():
    df = pd.DataFrame({"condition": ["LOS"] * 100 + ["NLOS"] * 100 + ["LOS"] * 5,
                       "height_m": 1.0, "true_range_m": [10.0] * 200 + [20.0] * 5,
                       "range_m": np.r_[10.0 + np.linspace(0, 0.99, 100), 12.0 + np.linspace(0, 0.99, 100),
                                        np.full(5, 20.0)],
                       "file": ["a"] * 100 + ["b"] * 100 + ["c"] * 5})
    out = percentile_by_file(df, q=5)
    assert list(out.file) == ["a", "b"] and out.attrs["n_skipped"] == 1
    np.testing.assert_allclose(out.pq_err_m, [np.percentile(np.linspace(0, .99, 100), 5),
                                              2.0 + np.percentile(np.linspace(0, .99, 100), 5)])
    assert out.loc[1, "frac_over_1m"] == 1.0 and out.loc[0, "frac_over_1m"] == 0.0
    with pytest.raises(ValueError, match="lack"):
        percentile_by_file(df.drop(columns="file"))
    # short files only: an empty table, and no condition to look up
    short = percentile_by_file(df[df.file == "c"])
    assert short.empty and short.attrs["n_skipped"] == 1


# --------------------------------------------------------------------------- set-noise model (paper 000)

def _two_valued(mean, spread, n):
    """n values (n even) with the given mean, half at mean+spread and half at mean-spread."""
    return np.r_[np.full(n // 2, mean + spread), np.full(n // 2, mean - spread)]


def _sample_std(spread, n):
    return spread * np.sqrt(n / (n - 1))


@pytest.fixture
def calib():
    """Hand-built calibration data at two locations.

    set 1: 30 fixes at A (ex mean 0.1 ± 0.02, ey mean -0.1 ± 0.04) and 40 at B (0.3 ± 0.06, 0.1 ± 0.02)
    set 2: 28 at A (below the gate) and 34 at B (0.0 ± 0.1, 0.2 ± 0.1)
    set 3: 10 at A and 10 at B (below the gate everywhere)
    """
    rows = []

    def add(loc, s, n, mx, sx, my, sy):
        rows.append(pd.DataFrame({"loc": loc, "set": s, "ex": _two_valued(mx, sx, n), "ey": _two_valued(my, sy, n)}))

    add("A", 1, 30, 0.1, 0.02, -0.1, 0.04)
    add("B", 1, 40, 0.3, 0.06, 0.1, 0.02)
    add("A", 2, 28, -0.5, 0.3, 0.5, 0.3)
    add("B", 2, 34, 0.0, 0.1, 0.2, 0.1)
    add("A", 3, 10, 1.0, 0.1, 1.0, 0.1)
    add("B", 3, 10, -1.0, 0.1, -1.0, 0.1)
    df = pd.concat(rows, ignore_index=True)
    return df[["ex", "ey"]].to_numpy(), df["set"].to_numpy(), df["loc"].to_numpy()


def test_calibration_rules_on_hand_computed_case(calib):
    err, sets, loc = calib
    model = fit_set_noise(err, sets, loc)
    assert model.set_id.tolist() == [1, 2]                         # set 3 never reaches 30 at one location
    # set 1: count-weighted average of the per-location parameters (30 at A, 40 at B)
    np.testing.assert_allclose(model.mu_m[0], [(30 * 0.1 + 40 * 0.3) / 70, (30 * -0.1 + 40 * 0.1) / 70])
    np.testing.assert_allclose(model.sigma_m[0], [(30 * _sample_std(0.02, 30) + 40 * _sample_std(0.06, 40)) / 70,
                                                  (30 * _sample_std(0.04, 30) + 40 * _sample_std(0.02, 40)) / 70])
    assert model.n.tolist() == [70, 34]
    # set 2: the 28 fixes at A are below the gate, so only B counts
    np.testing.assert_allclose(model.mu_m[1], [0.0, 0.2], atol=1e-15)
    np.testing.assert_allclose(model.sigma_m[1], [_sample_std(0.1, 34)] * 2)
    # facility-wide default: mean and sample std of all 152 errors
    np.testing.assert_allclose(model.default_mu_m, err.mean(axis=0))
    np.testing.assert_allclose(model.default_sigma_m, err.std(axis=0, ddof=1))
    assert model.default_n == 152
    # set 3 (and any unseen set) falls back to the default
    mu, sd, modelled = model.lookup([1, 3, 99])
    assert modelled.tolist() == [True, False, False]
    np.testing.assert_allclose(mu[1:], np.tile(model.default_mu_m, (2, 1)))
    np.testing.assert_allclose(sd[0], model.sigma_m[0])


def test_pooled_sigma_rule_adds_the_spread_between_locations(calib):
    err, sets, loc = calib
    model = fit_set_noise(err, sets, loc, sigma_rule="pooled")
    paper = fit_set_noise(err, sets, loc)
    np.testing.assert_allclose(model.mu_m, paper.mu_m)
    mx = (30 * 0.1 + 40 * 0.3) / 70
    var_x = (30 * (_sample_std(0.02, 30) ** 2 + (0.1 - mx) ** 2) + 40 * (_sample_std(0.06, 40) ** 2 + (0.3 - mx) ** 2)) / 70
    assert model.sigma_m[0, 0] == pytest.approx(np.sqrt(var_x))
    np.testing.assert_allclose(model.sigma_m[1], paper.sigma_m[1])       # one location: the rules agree
    np.testing.assert_allclose(model.default_sigma_m, paper.default_sigma_m)
    with pytest.raises(ValueError, match="sigma_rule"):
        fit_set_noise(err, sets, loc, sigma_rule="median")


def test_gate_is_at_least_30(calib):
    err, sets, loc = calib
    table = fit_set_noise(err, sets, loc).meta["per_location"]
    gate = dict(zip(zip(table["location"], table["set_id"]), table["gated_in"]))
    assert gate[("A", 1)] and not gate[("A", 2)] and gate[("B", 2)]
    # moving the gate to 28 admits set 2 at A; 31 drops set 1 at A
    assert fit_set_noise(err, sets, loc, min_count=28).n.tolist() == [70, 62]
    assert fit_set_noise(err, sets, loc, min_count=31).n.tolist() == [40, 34]
    with pytest.raises(ValueError, match="min_count"):
        fit_set_noise(err, sets, loc, min_count=1)


def test_location_statistics_table():
    err = np.array([[0.0, 1.0], [2.0, 3.0], [4.0, 5.0]])
    t = location_statistics(err, [5, 5, 6], ["a", "a", "a"])
    assert t["set_id"].tolist() == [5, 6] and t["n"].tolist() == [2, 1]
    np.testing.assert_allclose(t.loc[0, ["mu_x_m", "mu_y_m", "sigma_x_m"]].to_numpy(float), [1.0, 2.0, np.sqrt(2)])
    assert np.isnan(t.loc[1, "sigma_x_m"])
    with pytest.raises(ValueError, match="non-finite"):
        location_statistics([[np.nan, 0.0]], [1], ["a"])


def _fix_log(n=6, name="loc"):
    t = np.arange(n) * 0.1
    sets = np.array([0b11111, 0b11111, 0b101111, 0b11111, 0b101111, 0b1110011])[:n]
    return SetFixLog(t, np.zeros((n, 2)) + 0.1, sets, tuple(str(i) for i in range(8)), np.zeros((n, 2)), name)


def test_from_fixes_labels_locations_by_name():
    a, b = _fix_log(name="A"), _fix_log(name="B")
    model = fit_set_noise_from_fixes([a, b], min_count=2)
    assert set(model.meta["per_location"]["location"]) == {"A", "B"}
    assert model.n.tolist() == [6, 4]
    # identical fixes give σ = 0, which the fit floors (eq. 9 would be infinite)
    np.testing.assert_allclose(model.sigma_m, 1e-3)
    assert model.meta["n_sigma_floored"] == 6
    with pytest.raises(ValueError, match="distinct names"):
        fit_set_noise_from_fixes([a, _fix_log(name="A")])
