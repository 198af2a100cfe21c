"""Notebook 05's study code: comparisons on the same epochs, error ranges, the eq-4 screening,
and the real-data path on any scenario folder by name."""

import numpy as np
import pytest

from tests.conftest import real_dataset
from tests.filters.test_eskf_recovery import fusion_errors, rmse_and_coverage
from tests.fixtures import iasl as fx
from uwbwb.experiments.uwb_ins import ablation as ab
from uwbwb.experiments.uwb_ins import headlines, study
from uwbwb.filters import alignment, imu_calibration
from uwbwb.models.tdoa import TdoaModel
from uwbwb.sim import robot
from uwbwb.types import TdoaLog


@pytest.fixture(scope="module")
def short_dynamic():
    run = study.simulate("dynamic", robot.RobotConfig(), rng=np.random.default_rng(3), legs=2, outage_s=3.0)
    return run, study.compare_synthetic(run)


def test_synthetic_comparison_scores_every_method_on_the_same_epochs(short_dynamic):
    run, comp = short_dynamic
    assert list(comp.estimates) == list(study.METHODS)
    assert all(len(e) == len(run.truth) for e in comp.estimates.values())
    t = comp.table()
    assert t.loc["tight", "RMSE (m)"] < t.loc["UWB-only", "RMSE (m)"]
    assert t.loc["INS-only", "RMSE (m)"] > 5 * t.loc["tight", "RMSE (m)"]
    out = comp.table("outage")
    assert out.loc["UWB-only", "coverage"] == 0.0 and out.loc["tight", "coverage"] == 1.0
    assert (t["epochs"] == t["epochs"].iloc[0]).all()


def test_methods_subset_and_unknown_method(short_dynamic):
    run, _ = short_dynamic
    comp = study.compare_synthetic(run, methods=("UWB-only", "loose"))
    assert list(comp.estimates) == ["UWB-only", "loose"]
    with pytest.raises(ValueError, match="unknown methods"):
        study.compare_synthetic(run, methods=("EKF",))


def test_the_cell_the_sections_and_the_ablation_run_one_builders_filters():
    """``study.fusion_filters`` from ``study.start`` is what notebook 05's cell runs; the ablation's loose and tight
    rows and the sections' comparison are the same filters (the paper's loose one ungated there)."""
    cfg = ab.AblationConfig.fast(seeds=1)
    run = ab.simulate("dynamic", cfg.model, cfg, 5)
    s = study.start(run, cfg.model, cfg.outlier_c_m)
    settings = alignment.FusionSettings(cfg.outlier_c_m, cfg.gate_prob, loose_window=cfg.loose_window)
    tight, loose = study.fusion_filters(cfg.model, settings)
    cell = {"tight + gate": tight.run(s.imu, run.tdoa, s.x0, heading=run.heading),
            "loose + gate": loose.run(s.imu, s.fixes, s.x0, heading=run.heading)}
    rows = tuple(cell)
    pos, k0, _ = ab.run_methods(run, cfg.model, dict.fromkeys(rows, (1.0, 1.0)), cfg, rows=rows)
    assert k0 == s.k0
    for r in rows:
        np.testing.assert_array_equal(pos[r][k0:], cell[r].to_estimates(dim=2).pos_m[k0:])
    shared, _, _ = ab.run_methods(run, cfg.model, dict.fromkeys(rows, (1.0, 1.0)), cfg, rows=rows, started=s)
    for r in rows:                                     # the tuning's path: the start computed once, passed in
        np.testing.assert_array_equal(shared[r], pos[r])
    with pytest.raises(ValueError, match="fix_tag must have shape"):
        tight.run(s.imu, run.tdoa, s.x0, heading=run.heading, fix_tag=s.snapshot[1:])
    comp = study.compare_synthetic(run, settings)
    np.testing.assert_array_equal(comp.estimates["tight"].pos_m, cell["tight + gate"].to_estimates(dim=2).pos_m)
    ungated = study.fusion_filters(cfg.model, settings, gate_loose=False)[1]
    assert loose.gate_prob == cfg.gate_prob and ungated.gate_prob is None
    np.testing.assert_array_equal(comp.estimates["loose"].pos_m,
                                  ungated.run(s.imu, s.fixes, s.x0, heading=run.heading).to_estimates(dim=2).pos_m)


def test_the_paper_comparisons_rows_say_they_are_its_pairing_and_are_the_cells_of_its_tables(short_dynamic):
    """Sections 2–4 pair the paper's ungated loose filter with the gated tight one on one seed: a summary row from
    there says so (summary.md must not read as the ablation's like-for-like comparison) and is its table's cell."""
    run, comp = short_dynamic
    ranges = {n: study.error_ranges(comp, n) for n in ("loose", "tight")}
    rows = headlines.comparison_rows((comp,), ranges, ranges, outage_s=3.0, paper=study.PAPER, world=run.config)
    method_rows = {r["quantity"]: r["value"] for r in rows if r["kind"] == "reproduced" and "TDoAs" not in r["quantity"]}
    assert method_rows and all(headlines.PAPERS_PAIRING in q for q in method_rows)
    assert headlines.PAPERS_PAIRING == "paper's pairing: loose ungated vs tight gated, 1 seed"
    for m, v in comp.table()["RMSE (m)"].items():
        assert method_rows[f"RMSE {m} ({comp.label}; {headlines.PAPERS_PAIRING})"] == v
    assert method_rows[f"max error in the 3 s outage, loose ({comp.label}; {headlines.PAPERS_PAIRING})"] == \
        comp.table("outage").loc["loose", "max (m)"]


def test_the_error_range_rows_say_the_assumed_noise_they_follow_from(short_dynamic):
    from uwbwb.models.imu import GRADES

    run, comp = short_dynamic
    ranges = {"tight": study.error_ranges(comp, "tight")}
    for world, said in ((robot.RobotConfig(), "3 cm arrival-time σ, 2 % multipath of 0.3–4 m, consumer IMU"),
                        (robot.RobotConfig(imu=GRADES["tactical"], outlier_rate=0.05, sigma_toa_m=0.05),
                         "5 cm arrival-time σ, 5 % multipath of 0.3–4 m, tactical IMU")):
        rows = headlines.comparison_rows((comp,), ranges, ranges, outage_s=3.0, paper=study.PAPER, world=world)
        q = [r["quantity"] for r in rows if r["quantity"].startswith("static max |error|, tight")]
        assert q == [f"static max |error|, tight ({headlines.PAPERS_PAIRING}; follows from assumed noise: {said})"]


def test_error_ranges_are_min_and_max_of_the_signed_errors(short_dynamic):
    _, comp = short_dynamic
    r = study.error_ranges(comp, "tight")
    e = comp.estimates["tight"].pos_m[:, :2] - comp.truth.pos_m[:, :2]
    e = e[comp.masks["scored"]]
    assert r["E_min"] == pytest.approx(e[:, 0].min()) and r["N_max"] == pytest.approx(e[:, 1].max())
    assert r["max_abs"] >= max(abs(r["signed_min"]), abs(r["signed_max"])) - 1e-12


def test_screened_tdoa_removes_what_eq4_rejects():
    anchors = np.array([[0, 0, 2.4], [7, 0, 2.2], [7, 5, 2.4], [0, 5, 2.2]], float)
    d = np.array([[0.0, 1.0, 30.0, np.nan], [0.0, 20.0, np.nan, np.nan]])
    log = TdoaLog(np.array([0.0, 0.02]), d, np.array([0, 0]), ("a", "b", "c", "d"))
    out, n = alignment.screened_tdoa(log, anchors, 0.1)
    np.testing.assert_array_equal(n, [1, 1])
    assert np.isnan(out.tdoa_m[0, 2]) and out.ref[1] == -1
    same, none = alignment.screened_tdoa(log, anchors, None)
    assert same is log and not none.any()


def _fixture_tree(tmp_path, names):
    root = tmp_path / "iasl-uwb-imu"
    root.mkdir(parents=True)
    (root / "uwb.yaml").write_text(fx.YAML_TEXT)
    rng = np.random.default_rng(8)
    for name in names:
        fx.write_scenario(root / name, rng=rng, duration_s=45.0)
    return tmp_path


@pytest.mark.parametrize("names", [("flight_a", "flight_b")])
def test_real_data_path_runs_on_any_scenario_by_name(tmp_path, names):
    from uwbwb.datasets import iasl

    data = _fixture_tree(tmp_path, names)
    cal = imu_calibration.calibrate_iasl(iasl.load_scenario(names[0], data))
    assert cal.source.endswith(names[0])
    # the fixture's accelerometer reads 1.056 × the specific force, z down (as upstream)
    assert cal.notes["accelerometer scale (flight fit, cross-check)"] == pytest.approx(1 / 1.056, rel=0.03)
    np.testing.assert_allclose(np.diag(cal.convention.R_body_sensor), [1, -1, -1])
    rec = iasl.load_scenario(names[1], data)
    assert rec.label.endswith(names[1])
    _, err, have = fusion_errors(rec, cal, ("UWB-only", "tight"), still_s=1.0, align_s=15.0)
    (uwb, _), (tight, tight_cov) = (rmse_and_coverage(err[n], have) for n in err)
    assert tight_cov > 0.99 and np.isfinite(tight)
    assert tight < 2 * uwb + 0.05


@pytest.mark.realdata
def test_real_iasl_calibration_transfers():
    from uwbwb.datasets import iasl

    real_dataset("iasl-uwb-imu")
    cal = imu_calibration.calibrate_iasl(iasl.load_scenario("scenario1"))
    assert 0.93 < cal.convention.acc_scale < 0.96              # ≈ 9.81 / 10.3
    _, err, have = fusion_errors(iasl.load_scenario("scenario2"), cal, ("UWB-only", "tight"), duration_s=20.0,
                                 align_s=15.0)
    (uwb, _), (tight, _) = (rmse_and_coverage(err[n], have) for n in err)
    assert tight < 1.2 * uwb
