from dataclasses import replace

import matplotlib
import numpy as np
import pandas as pd
import pytest

from uwbwb.experiments import motion_models as mm
from uwbwb.sim import walk
from uwbwb.types import Anchors, RangeLog, TagRun, Trajectory

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def office_runs():
    cal, _ = mm.synthetic_acquisition("office", seed=1, duration_s=25.0, role="calibration")
    test, _ = mm.synthetic_acquisition("office", seed=1, duration_s=25.0)
    return cal, test


@pytest.fixture(scope="module")
def los_run():
    """An office walk with no obstacles and no body shadowing: pure DWM1000 LOS noise."""
    cfg = walk.office(duration_s=30.0, obstacles=(), tags=(walk.TagMount("tag1", 0, 0, 1.8),), p_missing_los=0.0)
    rec, _ = walk.simulate_walk(cfg, rng=np.random.default_rng(9))
    return mm.tag_runs(rec, z_m={"tag1": 1.8})[0]


def test_synthetic_acquisitions(office_runs):
    cal, test = office_runs
    assert [r.tag for r in test] == ["tag1", "tag2"] and all(r.raw is not None for r in test)
    assert test[0].name == "office" and cal[0].name == "office (calibration)"
    assert test[0].data == "synthetic" and test[0].dim == 2 and test[0].z_m == pytest.approx(1.8)
    assert test[0].dt_s == pytest.approx(0.1)
    assert not np.allclose(np.nan_to_num(cal[0].ranges.range_m), np.nan_to_num(test[0].ranges.range_m))
    again, _ = mm.synthetic_acquisition("office", seed=1, duration_s=25.0)
    np.testing.assert_array_equal(again[1].ranges.range_m, test[1].ranges.range_m)


def test_tag_run_decimation_window_and_validation(office_runs):
    run = office_runs[1][0]
    slow = run.decimated(2.0)
    assert slow.dt_s == pytest.approx(0.5) and len(slow.ranges) == int(np.ceil(len(run.ranges) / 5))
    assert set(slow.raw.t_s) <= set(slow.ranges.t_s)
    assert run.decimated(None) is run and run.decimated(50.0) is run
    part = run.between(5.0, 10.0, name="part")
    assert part.name == "part" and part.ranges.t_s.min() >= 5.0 and part.ranges.t_s.max() < 10.0
    assert part.truth.t_s[0] <= 5.0 and part.truth.t_s[-1] >= 10.0
    other = Anchors(tuple("BCDEFG"), run.anchors.pos_m)
    with pytest.raises(ValueError, match="differ"):
        replace(run, anchors=other)


def test_true_ranges_and_sigma_fit_on_los_data(los_run):
    r = los_run.ranges.range_m - los_run.true_range_m()
    assert abs(np.nanmean(r)) < 0.01
    sig = mm.fit_range_sigma(los_run)
    np.testing.assert_allclose(sig, 0.05, rtol=0.15)
    empirical, model = mm.tdoa_noise_check(los_run, sig, ref=2)
    assert empirical.shape == model.shape == (5, 5)
    np.testing.assert_allclose(empirical, model, atol=0.0015)          # σ²(I + 11ᵀ) with σ ≈ 5 cm
    assert np.all(np.diag(empirical) > 1.5 * empirical[0, 1])


def test_raw_multilateration_is_exact_on_exact_ranges():
    anchors = Anchors(tuple("ABCD"), np.array([[0, 0, 2.5], [10, 0, 2.5], [10, 8, 2.4], [0, 8, 2.6]]))
    t = np.arange(20) * 0.1
    pos = np.column_stack([2 + 0.5 * t, 3 + 0.2 * t, np.full(t.size, 1.2)])
    r = np.linalg.norm(pos[:, None] - anchors.pos_m, axis=-1)
    run = TagRun("synthetic", "x", "t", RangeLog(t, r, anchors.ids, "t"), Trajectory(t, pos), anchors, 2, 1.2)
    raw = mm.raw_multilateration(run)
    np.testing.assert_allclose(raw.pos_m, pos[:, :2], atol=1e-6)


def test_estimate_calibrate_and_tables(office_runs):
    cal, test = office_runs
    sig = {r.key: mm.fit_range_sigma(r) for r in cal}
    grids = {"RW": [0.1, 1.0], "RF": [1.0], "RJ": [1.0, 10.0]}
    curves = mm.calibration_curves(cal, sig, grids=grids, progress=False)
    assert len(curves) == 2 * 5
    assert list(curves.columns) == ["run", "tag", "model", "sigma", "sigma_unit", "psd", "psd_unit", "cep95_m",
                                    "rmse_m"]
    np.testing.assert_allclose(curves.psd, curves.sigma ** 2 * 0.1)
    assert set(curves.psd_unit) == {"m²/s", "m²/s³", "m²/s⁵"}
    best = mm.best_sigmas(curves)
    assert set(best) == {"RW", "RF", "RJ"} and best["RF"] == 1.0
    # a random walk driven by 0.1 m/s cannot follow a 0.8 m/s walker
    rw = curves[curves.model == "RW"].groupby("sigma").cep95_m.mean()
    assert rw[0.1] > rw[1.0] and best["RW"] == 1.0

    est = mm.estimate(test[0], sig[cal[0].key], best)
    assert set(est.trajectories) == {"raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ"}
    c = est.cep95()
    assert all(0 < v < 3 for v in c.values())
    assert c["EKF-RW"] < c["raw"]
    assert min(est.coverage().values()) > 0.95
    nis = est.nis()
    assert list(nis.index) == ["RW", "RF", "RJ"] and (nis["n"] > 200).all()
    table = mm.cep95_table([est], ["raw", "LS", "EKF-RW"])
    assert table.loc[("office", "tag1"), "LS"] == pytest.approx(c["LS"])


def test_best_sigmas_minimises_the_mean_over_runs():
    curves = pd.DataFrame({"run": ["a"] * 3 + ["b"] * 3, "tag": ["t"] * 6, "model": ["RW"] * 6,
                           "sigma": [0.1, 1.0, 10.0] * 2, "cep95_m": [0.5, 0.4, 0.9, 0.3, 0.6, 0.2]})
    # means: 0.1 -> 0.40, 1.0 -> 0.50, 10 -> 0.55
    assert mm.best_sigmas(curves) == {"RW": 0.1}


def test_ranking_and_paper_table():
    table = pd.DataFrame({"EKF-RW": [0.4, 0.5], "EKF-RF": [0.7, 0.3], "EKF-RJ": [1.0, 0.45]},
                         index=pd.MultiIndex.from_tuples([("office", "tag1"), ("agv1", "tag1")], names=["run", "tag"]))
    assert list(mm.ranking(table)) == ["RW < RF < RJ", "RF < RJ < RW"]
    paper = mm.paper_table(mm.PAPER_MODELS_CEP95, [("office", "tag2"), ("lab", "t0")], ["EKF-RW", "EKF-RJ"])
    assert paper.loc[("office", "tag2"), "EKF-RJ"] == 1.14 and np.isnan(paper.loc[("lab", "t0"), "EKF-RW"])
    assert mm.PAPER_METHODS_CEP95[("office", "tag2")]["raw"] == 2.03


def test_figures(office_runs):
    import matplotlib.pyplot as plt

    cal, test = office_runs
    curves = pd.DataFrame({"run": "x", "tag": "t", "model": np.repeat(["RW", "RF", "RJ"], 2),
                           "sigma": [0.1, 1.0] * 3, "cep95_m": [0.5, 0.4, 0.6, 0.5, 0.7, 0.6]})
    fig = mm.calibration_figure(curves, best={"RW": 1.0, "RF": 1.0, "RJ": 1.0}, paper=mm.PAPER_SIGMA["office"])
    assert len(fig.axes) == 3 and fig.axes[0].get_xscale() == "log"
    plt.close(fig)
    est = mm.estimate(test[1], 0.3, {"RW": 1.0, "RF": 1.0, "RJ": 1.0})
    ax = mm.paths_figure(est, t_range_s=(0.0, 10.0))
    assert ax.get_title() == "office, tag2"
    ax = mm.cdf_figure(est)
    assert len(ax.get_legend().get_texts()) == 5
    ax = mm.scenario_figure(walk.office(), truth=test[0].truth)
    assert "6 anchors" in ax.get_title()
    plt.close("all")


def test_sigma_fit_methods_and_common_mode(los_run):
    # a range error common to all anchors cancels in every TDoA: the 'tdoa' fit ignores it, 'rms' does not
    shifted = replace(los_run, ranges=RangeLog(los_run.ranges.t_s, los_run.ranges.range_m + 0.4,
                                               los_run.ranges.anchor_ids, los_run.tag))
    np.testing.assert_allclose(mm.fit_range_sigma(shifted), mm.fit_range_sigma(los_run), atol=1e-9)
    assert np.all(mm.fit_range_sigma(shifted, method="rms") > 0.35)
    np.testing.assert_allclose(mm.fit_range_sigma(shifted, method="robust"), 0.05, rtol=0.15)
    assert np.all(mm.fit_range_sigma(los_run, floor_m=0.2) == 0.2)
    with pytest.raises(ValueError, match="method"):
        mm.fit_range_sigma(los_run, method="mad")


def test_split_runs_and_study(office_runs):
    cal, test = office_runs
    first, second = mm.split_runs(test, 0.5)
    assert first[0].name.startswith("office 0–") and second[0].ranges.t_s[0] >= first[0].ranges.t_s[-1]
    assert len(first[0].ranges) + len(second[0].ranges) == len(test[0].ranges)
    with pytest.raises(ValueError, match="fraction"):
        mm.split_runs(test, 1.0)
    grids = {"RW": [1.0], "RF": [1.0, 3.0], "RJ": [3.0]}
    study = mm.run_study(cal, test, grids=grids, progress=False)
    assert study.best == {"RW": 1.0, "RF": study.best["RF"], "RJ": 3.0}
    assert set(study.sigma_m) == {"tag1", "tag2"} and study.sigma_m["tag1"].shape == (6,)
    table = study.table()
    assert list(table.columns) == ["raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ"] and len(table) == 2
    assert study.estimate_for("office", "tag2").run.tag == "tag2"
    with pytest.raises(KeyError, match="no test result"):
        study.estimate_for("office", "tag9")
    with pytest.raises(ValueError, match="no calibration run"):
        mm.run_study(cal[:1], test, grids=grids, progress=False)


def test_ranging_summary_and_covariance_figure(los_run):
    import matplotlib.pyplot as plt

    cfg = walk.office(duration_s=10.0)
    rec, truth = walk.simulate_walk(cfg, rng=np.random.default_rng(2))
    runs = mm.tag_runs(rec, z_m={"tag1": 1.8, "tag2": 1.3})
    table = mm.ranging_summary(runs, truth)
    assert table.loc[("office", "tag2"), "NLOS links (%)"] > table.loc[("office", "tag1"), "NLOS links (%)"]
    assert abs(table.loc[("office", "tag1"), "LOS error mean (cm)"]) < 2
    emp, mod = mm.tdoa_noise_check(los_run, mm.fit_range_sigma(los_run))
    fig = mm.covariance_figure(emp, mod, list("BCDEF"), title="x")
    assert len(fig.axes) == 3
    plt.close(fig)


def test_banner_escapes_its_message():
    html = mm.banner("data <absent> & skipped")._repr_html_()
    assert "data &lt;absent&gt; &amp; skipped" in html and "background" in html


# --------------------------------------------------------------------------- discussion text

def _cep_table(rows: dict) -> pd.DataFrame:
    """(run, tag) → (raw, LS, RW, RF, RJ) CEP95 in metres, as :meth:`mm.Study.table` lays it out."""
    return pd.DataFrame([{"run": k[0], "tag": k[1], **dict(zip(["raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ"], v))}
                         for k, v in rows.items()]).set_index(["run", "tag"])


def _curves(cep_at_one: dict) -> pd.DataFrame:
    """Calibration curves whose mean is ``cep_at_one[model]`` at σ = 1 and 0.1 m higher at σ = 0.1 and 10."""
    return pd.DataFrame([{"run": "cal", "tag": "tag1", "model": m, "sigma": s,
                          "cep95_m": v + (0.0 if s == 1.0 else 0.1)}
                         for m, v in cep_at_one.items() for s in (0.1, 1.0, 10.0)])


SYNTHETIC = _cep_table({("office", "tag1"): (0.58, 0.45, 0.41, 0.40, 0.41),
                        ("office", "tag2"): (0.76, 0.59, 0.41, 0.49, 0.51),
                        ("agv1", "tag1"): (0.70, 0.48, 0.45, 0.44, 0.45),
                        ("agv1", "tag2"): (0.77, 0.52, 0.47, 0.48, 0.48),
                        ("agv2", "tag1"): (0.70, 0.55, 0.49, 0.53, 0.54),
                        ("agv2", "tag2"): (0.78, 0.64, 0.58, 0.61, 0.61)})


def test_discussion_reads_the_tables():
    ablation = pd.DataFrame({"EKF-RW": [0.412, 0.428], "EKF-RF": [0.492, 0.430], "EKF-RJ": [0.510, 0.429]})
    lias = {"calibrated ranges": _cep_table({("fast", "t0"): (0.103, 0.109, 0.091, 0.101, 0.101),
                                             ("fast", "t1"): (0.085, 0.089, 0.089, 0.088, 0.085)}),
            "raw ranges": _cep_table({("fast", "t0"): (0.281, 0.160, 0.137, 0.155, 0.155),
                                      ("fast", "t1"): (0.223, 0.143, 0.155, 0.148, 0.144)})}
    text = mm.discussion_markdown(SYNTHETIC, ablation=ablation,
                                  curves={"office": _curves({"RW": 0.40, "RF": 0.45, "RJ": 0.46}),
                                          "agv": _curves({"RW": 0.45, "RF": 0.47, "RJ": 0.50})},
                                  best={"office": {"RW": 1.6, "RF": 4.5, "RJ": 15.0},
                                        "agv": {"RW": 1.6, "RF": 4.5, "RJ": 0.5}},
                                  lias=lias, lias_label="lias-planar-uwb/fast")
    assert "RW 0.41/0.48 m against RF 0.77/1.13 m and RJ 1.03/1.14 m" in text           # the thesis, quoted
    assert "ranking holds, but only for the body-shadowed tag" in text
    assert "unshadowed tag (tag1) the three models are within 1.0 cm (RF ahead)" in text
    assert "body-shadowed tag (tag2) the random walk is 0.08 m better than the next model (RF)" in text
    assert "The ablation above shows why" in text and "(0.08 m) shrinks to 0.00 m" in text
    assert "RW is usually best (3 of 4 tag-runs)" in text and "from −1.0 cm to 4.0 cm" in text
    assert "is not reproduced" in text and "factor of at most 1.24" in text and "up to 2.54" in text
    assert "they are 2.0 cm to 6.0 cm worse than the best random walk" in text
    assert "within a factor of two of the thesis' 0.83 m/s, 1 m/s" in text
    assert "RF prefers larger values" in text and "RJ prefers other values" in text
    assert "Real data: no ranking" in text and "the winner changes from tag to tag (RJ, RW)" in text
    assert "improve only a little on LS (11 % lower CEP95 on average, at most 17 %)" in text
    assert "TDoA LS beats range multilateration (0.15 m against 0.25 m" in text
    assert "range multilateration is as good or better (0.09 m against 0.10 m)" in text
    assert "worse than LS, as in the thesis, but by less (+15 cm on average; thesis +61 cm)" in text
    assert "within 0.18 m of the random-walk EKF" in text and "6 well-spread anchors, 5 cm LOS noise" in text


def test_discussion_follows_other_outcomes():
    worse_rw = SYNTHETIC.copy()
    worse_rw["EKF-RW"] += 0.2                                                 # RW now last everywhere
    ablation = pd.DataFrame({"EKF-RW": [0.61, 0.60], "EKF-RF": [0.49, 0.43], "EKF-RJ": [0.51, 0.43]})
    iasl = _cep_table({("scenario2", "tag"): (0.30, 0.30, 0.20, 0.25, 0.26)})
    text = mm.discussion_markdown(worse_rw, ablation=ablation,
                                  curves={"office": _curves({"RW": 0.40, "RF": 0.38, "RJ": 0.45})},
                                  best={"office": {"RW": 0.1, "RF": 1.0, "RJ": 0.5}}, iasl=iasl,
                                  iasl_label="iasl-uwb-imu/scenario2")
    assert "the ranking does not hold" in text and "does not single out body shadowing" in text
    assert "RW is best on only 0 of 4 tag-runs" in text and "never lose to the random walk" in text
    assert "they are from 2.0 cm better to 5.0 cm worse than the best random walk" in text
    assert "more than a factor of two from" in text and "RF prefers the same values as" in text
    assert "RJ prefers smaller values" in text
    assert "Real data: small differences" in text and "RW is best;" not in text and "RW is best." in text
    assert "The best filter improves on LS (33 % lower CEP95 on average" in text
    assert "TDoA vs raw ranges" not in text                                   # no LIAS variants
    nothing = mm.discussion_markdown(SYNTHETIC, curves={}, best={})
    assert "Neither real dataset was found" in nothing and "ablation" not in nothing
