import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from uwbwb.calibration import RangeCalibration, fit_range_calibration, range_residuals
from uwbwb.sim import rig
from uwbwb.types import RangeLog


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
