import dataclasses

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from tests.conftest import real_dataset  # noqa: E402
from uwbwb.experiments import setnoise as E  # noqa: E402
from uwbwb.types import set_mask  # noqa: E402
from uwbwb.widgets import data_banner  # noqa: E402
from uwbwb.sim import setnoise as S  # noqa: E402
from tests.test_teaching import assert_reads_predictions

SMALL = dataclasses.replace(S.FacilityConfig(), n_calibration=300, n_legs=2, speeds_mps=(0.35, 1.0))
TINY_SWEEP = E.SweepConfig(sigma_d_mps=(0.1, 0.3, 0.5), n_trials=3, n_particles=100)


@pytest.fixture(scope="module")
def study():
    return E.synthetic_study(SMALL, rng=np.random.default_rng(0))


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def test_sweep_config_validation():
    with pytest.raises(ValueError, match="increasing"):
        E.SweepConfig(sigma_d_mps=(0.3, 0.1))
    with pytest.raises(ValueError, match=">= 1"):
        E.SweepConfig(n_trials=0)
    fast = E.SweepConfig.fast()
    assert fast.n_trials < E.SweepConfig().n_trials and len(E.SweepConfig().sigma_d_mps) >= 15


def test_synthetic_study_and_table1(study):
    assert len(study.calibration) == 6 and len(study.recordings) == 2
    assert np.allclose(study.fig3.truth_m[0], SMALL.fig3_xy_m)
    assert study.pooled.set_id.tolist() == study.model.set_id.tolist()
    assert np.all(study.pooled.sigma_m >= study.model.sigma_m - 1e-12)      # pooled adds between-location spread
    t1 = E.table1(study.recordings)
    assert t1["recording"].tolist() == ["rec1", "rec2"]
    np.testing.assert_allclose(t1["speed_cmps"], [35, 100], rtol=0.03)   # path length / time span of the fixes
    assert t1["paper_raw_error_cm"].tolist() == [18, 19]                       # paper values ride along by position
    sh = E.set_shares(study.fig3)
    assert 0 < sh["top1_share"] <= sh["top5_share"] <= 1 and len(sh["top_labels"]) == 5
    with pytest.raises(KeyError, match="rec9"):
        study.recording("rec9")


def test_sweep_table_and_reproducibility(study):
    df = E.sweep(study.recordings, study.model, TINY_SWEEP, rng=np.random.default_rng(1), pooled=study.pooled,
                 progress=False)
    assert set(df["filter"]) == set(E.FILTERS)
    assert len(df) == 2 * 3 * len(E.FILTERS)
    raw = df[df["filter"] == E.RAW].groupby("recording")["mean_error_m"].nunique()
    assert (raw == 1).all()                                                   # raw does not depend on σ_d
    pf = df[df["filter"] == E.SET_PF]
    assert (pf["n_trials"] == 3).all() and (pf["sem_error_m"] > 0).all()
    again = E.sweep(study.recordings, study.model, TINY_SWEEP, rng=np.random.default_rng(1), pooled=study.pooled,
                    progress=False)
    pd.testing.assert_frame_equal(df, again)
    # in the paper's band the filters beat the raw fixes
    band = E.band_summary(df).set_index(["recording", "filter"])
    assert band.loc[("mean", E.SET_KF), "improvement_pct"] > 0
    assert band.loc[("mean", E.SET_PF), "improvement_pct"] > 0


def test_band_summary_hand_case():
    rows = []
    for rec, raw in (("a", 0.20), ("b", 0.10)):
        for s, e in ((0.2, 0.5), (0.3, 0.16), (0.5, 0.12), (0.6, 0.5)):
            rows += [(rec, E.RAW, s, raw, 0.0, 1), (rec, E.SET_PF, s, e if rec == "a" else e / 2, 0.01, 5)]
    df = pd.DataFrame(rows, columns=["recording", "filter", "sigma_d_mps", "mean_error_m", "sem_error_m", "n_trials"])
    b = E.band_summary(df).set_index(["recording", "filter"])
    # band 0.3-0.5: a → mean(0.16, 0.12) = 0.14 (raw 0.20); b → 0.07 (raw 0.10)
    assert b.loc[("a", E.SET_PF), "error_cm"] == pytest.approx(14.0)
    assert b.loc[("a", E.SET_PF), "improvement_pct"] == pytest.approx(30.0)
    assert b.loc[("mean", E.SET_PF), "error_cm"] == pytest.approx(10.5)
    assert b.loc[("mean", E.SET_PF), "improvement_cm"] == pytest.approx(4.5)
    # standard errors: the RMS over σ_d per recording (1 cm), over two independent recordings 1/√2 cm; raw has none
    assert b.loc[("a", E.SET_PF), "se_cm"] == pytest.approx(1.0)
    assert b.loc[("mean", E.SET_PF), "se_cm"] == pytest.approx(np.sqrt(2) / 2)
    assert b.loc[("mean", E.RAW), "se_cm"] == 0
    m = E.mean_over_recordings(df)
    assert m.loc[(m["filter"] == E.SET_PF) & (m["sigma_d_mps"] == 0.3), "mean_error_m"].item() == pytest.approx(0.12)
    assert m.loc[(m["filter"] == E.SET_PF) & (m["sigma_d_mps"] == 0.3), "sem_error_m"].item() == pytest.approx(
        np.sqrt(2 * 0.01 ** 2) / 2)
    with pytest.raises(ValueError, match="band"):
        E.band_summary(df, band=(2.0, 3.0))


def test_residual_table_hand_case():
    from uwbwb.models.setnoise import SetNoiseModel
    from uwbwb.types import SetFixLog

    log = SetFixLog([0.0, 1.0], [[0.3, 0.0], [0.1, 0.0]], [1, 1], tuple("01234567"), np.zeros((2, 2)))
    model = SetNoiseModel([1], [[0.2, 0.0]], [[0.1, 0.1]], [40], [0.0, 0.0], [0.2, 0.2])
    # set model: residuals (±0.1)/0.1 in x, 0 in y -> mean of (1, 0, 1, 0) = 0.5
    # default: (0.3/0.2)² = 2.25, (0.1/0.2)² = 0.25 in x, 0 in y -> 0.625
    got = E.residual_table([log], model, model)["fixes"]
    assert got.to_dict() == pytest.approx({E.FACILITY_WIDE: 0.625, E.PAPER_SIGMA_RULE: 0.5, E.POOLED_SIGMA_RULE: 0.5})


def test_trace_and_pf_kf_gap(study):
    rec = study.recordings[0]
    est = E.trace(rec, study.model, 0.3, rng=np.random.default_rng(2), n_particles=300)
    assert set(est) == {"truth", E.RAW, E.BASE_PF, E.SET_PF, E.BASE_KF, E.SET_KF}
    assert all(v.shape == (len(rec), 2) for v in est.values())
    gap = E.pf_kf_gap(rec, study.model, 0.3, (30, 1000), n_trials=3, rng=np.random.default_rng(3))
    assert gap["rms_gap_m"].iloc[1] < 0.5 * gap["rms_gap_m"].iloc[0]
    assert gap["kf_error_m"].nunique() == 1


def test_figures_draw_what_they_say(study):
    fig, axes = plt.subplots(2, 4)
    ax = E.plot_facility(study.facility, ax=axes[0, 0])
    assert "test track" in [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(E.plot_fixes(study.fig3, ax=axes[0, 1]).get_legend().get_texts()) == 7   # other, 5 sets, truth
    assert len(E.plot_set_frequency(study.fig3, ax=axes[0, 2], n_bars=6).patches) == 6
    assert len(E.plot_set_ellipses(study.fig3, ax=axes[0, 3], n_sets=4).patches) == 4
    est = E.trace(study.recordings[0], study.model, 0.3, rng=np.random.default_rng(2), n_particles=100)
    assert len(E.plot_trace(est, ax=axes[1, 0], index=slice(0, 50)).lines) == 4
    df = E.sweep(study.recordings[:1], study.model, TINY_SWEEP, rng=np.random.default_rng(1), progress=False)
    assert len(E.plot_sweep(df, "rec1", ax=axes[1, 1]).lines) == 5
    gap = pd.DataFrame({"n_particles": [10, 100], "rms_gap_m": [0.1, 0.03]})
    assert len(E.plot_pf_kf_gap(gap, ax=axes[1, 2]).lines) == 2


# --------------------------------------------------------------------------- real-data pipeline

@pytest.fixture(scope="module")
def rig_inputs(tmp_path_factory):
    return E.real_inputs(tmp_path_factory.mktemp("no_data"), seed=1, fast=True)


def test_real_inputs_fall_back_to_the_rig(rig_inputs):
    assert rig_inputs.synthetic and rig_inputs.data_label == "synthetic"
    assert "not found" in rig_inputs.reason and "synthetic rig" in rig_inputs.note
    assert "synthetic stand-in" in data_banner(**rig_inputs.banner_args()).data


def test_emulated_sets(rig_inputs):
    rec = rig_inputs.static[0]
    emu = S.SetEmulation(set_size=5, fading_db=0.0)
    z = float(rec.truth["t0"].pos_m[0, 2])
    fixes, rep = E.emulate_fixes(rec, "t0", emu, tag_height_m=z, rng=np.random.default_rng(0), decimate=4)
    assert rep["kept_after_decimation"] == -(-rep["epochs"] // 4)
    assert rep["coverage"] == pytest.approx(rep["fixes"] / (rep["kept_after_decimation"] - rep["no_truth"]))
    assert rep["fixes"] == len(fixes) == rep["kept_after_decimation"] - rep["no_truth"] - rep["too_few_ranges"] \
        - rep["fix_failed"]
    used = set_mask(fixes.set_id, 8)
    assert np.all(used.sum(1) == 5)
    # without fading the set is the five shortest ranges of the epoch
    r = rec.ranges["t0"].range_m[::4][: len(fixes)]
    shortest = np.argsort(r, axis=1)[:, :5]
    np.testing.assert_array_equal(np.sort(np.flatnonzero(used[0])), np.sort(shortest[0]))
    assert fixes.name == f"{rec.name}/t0"
    # fading makes a static tag switch sets
    faded, _ = E.emulate_fixes(rec, "t0", tag_height_m=z, rng=np.random.default_rng(0), decimate=4)
    assert len(np.unique(faded.set_id)) > 3
    with pytest.raises(ValueError, match="decimate"):
        E.emulate_fixes(rec, "t0", tag_height_m=z, rng=np.random.default_rng(0), decimate=0)


def test_real_study_on_the_rig(rig_inputs):
    st = E.real_study(rig_inputs, decimate=4, rng=np.random.default_rng(0))
    assert st.range_calibration is not None
    assert len(st.tests) == len(rig_inputs.dynamic.tags)
    assert len(st.calibration) == len(rig_inputs.static) * len(rig_inputs.dynamic.tags)
    assert set(st.reports["role"]) == {"calibration", "test"}
    assert len(st.model) > 0 and all(E.modelled_share(t, st.model) > 0.3 for t in st.tests)
    raw = [E.raw_error_m(t) for t in st.tests]
    assert all(0 < e < 0.3 for e in raw)
    uncal = E.real_study(rig_inputs, decimate=4, range_calibration=False, rng=np.random.default_rng(0))
    assert uncal.range_calibration is None
    assert np.mean([E.raw_error_m(t) for t in uncal.tests]) > np.mean(raw)      # the rig has per-pair biases
    # the mount height comes from the static poses, the coverage is reported per role
    assert st.tag_height.z_m == pytest.approx(0.97, abs=0.01) and "static" in st.tag_height.source
    cov = st.coverage()
    assert list(cov.index) == ["calibration", "test"] and (cov["coverage"] <= 1).all()


def test_the_test_run_truth_height_does_not_reach_the_fixes(rig_inputs):
    """Moving the dynamic run's truth up by 30 cm changes no fix: the height comes from the static poses."""
    import dataclasses as dc

    from uwbwb.types import Trajectory

    lifted = {t: Trajectory(tr.t_s, tr.pos_m + [0.0, 0.0, 0.3], name=tr.name)
              for t, tr in rig_inputs.dynamic.truth.items()}
    moved = dc.replace(rig_inputs, dynamic=dc.replace(rig_inputs.dynamic, truth=lifted))
    a = E.real_study(rig_inputs, decimate=8, rng=np.random.default_rng(2))
    b = E.real_study(moved, decimate=8, rng=np.random.default_rng(2))
    for x, y in zip(a.tests, b.tests):
        np.testing.assert_array_equal(x.pos_m, y.pos_m)


@pytest.mark.realdata
def test_real_study_on_lias():
    root = real_dataset("lias-planar-uwb")
    inputs = E.real_inputs(root.parent, "fast", "8.14", fast=True)
    assert not inputs.synthetic and inputs.data_label == "lias-planar-uwb/fast"
    st = E.real_study(inputs, decimate=20, rng=np.random.default_rng(0))
    raw = [E.raw_error_m(t) for t in st.tests]
    assert all(0.01 < e < 0.2 for e in raw), raw
    assert all(E.modelled_share(t, st.model) > 0.5 for t in st.tests)
    assert (st.reports.query("role == 'test'")["fixes"] > 500).all()


# --------------------------------------------------------------------------- section 10: the verdict table

def _sweep_frame(errors_cm: dict, sem_cm: float = 0.1, sigmas=(0.02, 0.3, 0.5), recordings=("a", "b")) -> pd.DataFrame:
    """A sweep table: filter → (error at the smallest σ_d, error at the others), cm, same for every recording; the
    particle filters get ``sem_cm`` as their standard error, the others none."""
    rows = [(rec, name, s, (small if s == sigmas[0] else band) / 100, sem_cm / 100 if "PF" in name else 0.0, 3)
            for rec in recordings for name, (small, band) in errors_cm.items() for s in sigmas]
    return pd.DataFrame(rows, columns=["recording", "filter", "sigma_d_mps", "mean_error_m", "sem_error_m",
                                       "n_trials"])


def _resampler(systematic_cm: float, multinomial_cm: float, sem_cm: float = 0.1) -> dict:
    """Band tables of the set-noise PF on one recording under the two resamplers (errors in the band, cm)."""
    return {r: E.band_summary(_sweep_frame({E.RAW: (20, 20), E.SET_PF: (90, e)}, sem_cm, recordings=("rec2",)))
            for r, e in (("systematic", systematic_cm), ("multinomial", multinomial_cm))}


RESAMPLER = _resampler(17.0, 17.05)


def _verdict(table: pd.DataFrame, start: str) -> pd.Series:
    return table[table["claim"].str.startswith(start)].iloc[0]


def test_residual_table_labels(study):
    t = E.residual_table(study.recordings, study.model, study.pooled)
    assert list(t.index) == [E.FACILITY_WIDE, E.PAPER_SIGMA_RULE, E.POOLED_SIGMA_RULE]
    assert list(t.columns) == ["rec1", "rec2"] and (t.to_numpy() > 0).all()


def test_verdicts_follow_the_intervals_on_both_sides_of_each_rule():
    on = _sweep_frame({E.RAW: (20, 20), E.BASE_PF: (60, 17), E.SET_PF: (90, 17.0), E.BASE_KF: (25, 16.5),
                       E.SET_KF: (24, 15.8)}, sem_cm=0.1)
    off = _sweep_frame({E.RAW: (20, 20), E.BASE_PF: (60, 17), E.SET_PF: (90, 17.05), E.BASE_KF: (25, 16.5),
                        E.SET_KF: (24, 17.0)}, sem_cm=0.1)
    t = E.headlines.verdicts(E.band_summary(on), E.band_summary(off), RESAMPLER)
    assert list(t.columns) == ["claim", "paper", "ours", "low", "high", "rule", "verdict"]
    pct = _verdict(t, "set-noise PF improvement over raw")
    assert pct["ours"] == pytest.approx(15.0) and pct["verdict"] == "agrees"       # 3 cm of 20: the paper's 15 %
    cm = _verdict(t, "set-noise PF improvement over raw, σ_d 30-50 cm/s, mean of recordings (cm)")
    assert cm["ours"] == pytest.approx(3.0) and cm["verdict"] == "differs: ours smaller"       # paper: 5 cm
    se = 0.1 / np.sqrt(2)                                                           # two independent recordings
    assert cm["high"] - cm["ours"] == pytest.approx(2 * se)
    kf = _verdict(t, f"{E.SET_KF} vs {E.BASE_KF}: error reduction, σ_d 30-50 cm/s, paper's")
    assert kf["ours"] == pytest.approx(0.7) and kf.verdict == "exact filters: no Monte Carlo interval"
    # 0 and 0.05 cm apart with se √2·0.07: not significant either way
    assert _verdict(t, f"{E.SET_PF} vs {E.BASE_PF}: error reduction, σ_d 30-50 cm/s, paper's").verdict == "not significant"
    assert _verdict(t, f"{E.SET_PF} vs {E.BASE_PF}: error reduction, σ_d 30-50 cm/s, track").verdict == "not significant"
    kf = _verdict(t, f"{E.SET_KF} vs {E.SET_PF}")
    assert kf["ours"] == pytest.approx(1.2) and kf["verdict"] == "better"
    res = _verdict(t, "systematic vs multinomial resampling: set-noise PF error reduction, rec2")
    assert res["ours"] == pytest.approx(0.05) and res["verdict"] == "not significant"
    assert res["high"] - res["ours"] == pytest.approx(2 * np.hypot(0.1, 0.1))        # one recording each
    # the same table with a clear resampler difference and a set-noise PF beating its baseline
    better = _sweep_frame({E.RAW: (20, 20), E.BASE_PF: (60, 17), E.SET_PF: (90, 16.0), E.BASE_KF: (25, 16.5),
                           E.SET_KF: (24, 15.8)}, sem_cm=0.1)
    t2 = E.headlines.verdicts(E.band_summary(better), E.band_summary(off), _resampler(17.5, 17.0))
    assert _verdict(t2, f"{E.SET_PF} vs {E.BASE_PF}: error reduction, σ_d 30-50 cm/s, paper's").verdict == "better"
    assert _verdict(t2, "systematic vs multinomial").verdict == "worse"
    assert _verdict(t2, "set-noise PF improvement over raw, σ_d 30-50 cm/s, mean of recordings (%)").verdict == \
        "differs: ours larger"


def test_one_trial_gives_no_interval_and_no_verdict():
    one = _sweep_frame({E.RAW: (20, 20), E.BASE_PF: (60, 17), E.SET_PF: (90, 16.0), E.BASE_KF: (25, 16.5),
                        E.SET_KF: (24, 15.8)}, sem_cm=np.nan)
    t = E.headlines.verdicts(E.band_summary(one), E.band_summary(one), RESAMPLER)
    pf_rows = t[t["claim"].str.contains("PF") & ~t["claim"].str.startswith("systematic")]   # the sweep's rows
    assert (pf_rows["verdict"] == "no interval (fewer than two trials)").all()
    assert pf_rows["low"].isna().all()


# --------------------------------------------------------------------------- kinds, the second track, the resampler

def test_simulator_rate_is_the_mean_fix_rate_table1_implies():
    # the paper states no rate: fixes ÷ (1750 cm at the stated speed) per recording, averaged, to one decimal
    rates = [n / (1750 / v) for n, v in zip(E.PAPER["n_fixes"], E.PAPER["speed_cmps"])]
    assert rates[0] == pytest.approx(9.56, abs=0.01)                            # 9.56 Hz, not 9.4
    assert round(float(np.mean(rates)), 1) == S.FacilityConfig().rate_hz


def test_headline_rows_say_their_kind(study):
    t1 = E.table1(study.recordings)
    imp = pd.DataFrame({"improvement_pct": 1.0, "improvement_cm": 0.1},
                       index=[E.SET_PF, E.BASE_PF, E.SET_KF, E.BASE_KF, E.SET_KF_POOLED])
    rows = E.headline_rows(shares=E.set_shares(study.fig3), table1=t1, improvement=imp, off_improvement=imp)
    kind = {r["quantity"]: r["kind"] for r in rows}
    assert all(kind[q] == "target" for q in kind if q.startswith(("raw error", "top")))
    assert all(kind[q] == "input" for q in kind if q.startswith("fixes"))
    assert all(kind[q] == "reproduced" for q in kind if "improvement" in q)
    assert sum("away from calibration" in q for q in kind) == 4
    targets = E.headline_rows(shares=E.set_shares(study.fig3), table1=t1)      # no improvement: no reproduction
    assert {r["kind"] for r in targets} == {"target", "input"} and len(targets) == len(rows) - 14


def test_second_track_keeps_away_from_the_calibration_locations(study):
    assert len(study.off_recordings) == len(study.recordings)
    assert all(r.name.startswith("off-") for r in study.off_recordings)
    prox = E.calibration_proximity(study.recordings + study.off_recordings, SMALL).set_index("recording")
    assert (prox.loc[["rec1", "rec2"], "within_corr_share"] > 0.3).all()      # through the Fig. 3 location
    assert (prox.loc[["off-rec1", "off-rec2"], "within_corr_share"] == 0).all()
    assert (prox.loc[["off-rec1", "off-rec2"], "median_distance_m"] > 1.9).all()
    # the paper's recordings are the same with or without the second track
    alone = E.synthetic_study(SMALL, rng=np.random.default_rng(0), off_track_xy_m=None)
    assert alone.off_recordings == ()
    np.testing.assert_array_equal(alone.recordings[1].pos_m, study.recordings[1].pos_m)


# --------------------------------------------------------------------------- exercises and notes

def test_exercise_few_particles_at_small_sigma_d(study):
    rec = study.recording("rec1")                                   # 0.35 m/s, as the notebook's recording 2
    check = E.exercises.few_particles(rec, study.model, rng=np.random.default_rng(5))
    n = check.numbers
    assert check.holds, check
    assert n["PF at 2 cm/s (cm)"] > 1.5 * n["KF at 2 cm/s (cm)"]
    # the verdict follows the numbers: an impossible factor turns it
    strict = E.exercises.few_particles(rec, study.model, factor=1000.0, rng=np.random.default_rng(5))
    assert not strict.holds and strict.numbers == check.numbers
    # at the paper's slowest speed (0.11 m/s) the turns of the track are slow enough for the small σ_d to follow:
    # the cloud stays on the set's moves, the PF stays within the default 1.5× of the KF and the claim fails
    slow = E.synthetic_study(dataclasses.replace(SMALL, speeds_mps=(0.11,)), rng=np.random.default_rng(0),
                             off_track_xy_m=None)
    crawl = E.exercises.few_particles(slow.recording("rec1"), slow.model, rng=np.random.default_rng(5))
    m = crawl.numbers
    assert crawl.holds is False, crawl
    assert m["PF at 2 cm/s (cm)"] <= 1.5 * m["KF at 2 cm/s (cm)"]
    assert m["PF at 2 cm/s (cm)"] < 0.5 * n["PF at 2 cm/s (cm)"]      # far below the PF's error at 0.35 m/s
    for c in (check, strict, crawl):
        assert_reads_predictions(c)
    with pytest.raises(ValueError, match="factor"):
        E.exercises.few_particles(rec, study.model, factor=0.5, rng=np.random.default_rng(5))


def test_exercise_no_resampling(study):
    rec = study.recording("rec1")
    check = E.exercises.no_resampling(rec, study.model, rng=np.random.default_rng(6))
    n = check.numbers
    assert check.holds, check
    assert n["never resample (cm)"] > n["resample when ESS < 0.5 K (cm)"]
    assert n["raw fixes (cm)"] == pytest.approx(100 * E.raw_error_m(rec))
    assert 1 <= n["ESS at the last fix, never resample"] < 0.1 * 200       # the weights have degenerated
    again = E.exercises.no_resampling(rec, study.model, rng=np.random.default_rng(6))
    assert again.numbers == check.numbers                           # same seed, same numbers
    # one particle: its ESS is always 1, above the threshold 0.5 K, so both settings never resample and the same
    # draws give the same error: the claim does not hold
    single = E.exercises.no_resampling(rec, study.model, n_particles=1, rng=np.random.default_rng(6))
    n = single.numbers
    assert single.holds is False, single
    assert n["never resample (cm)"] == n["resample when ESS < 0.5 K (cm)"] and n["median ESS, never resample"] == 1
    for c in (check, single):
        assert_reads_predictions(c)


def test_plot_sweep_marks_points_above_the_axes():
    df = _sweep_frame({E.RAW: (25, 25), E.SET_PF: (300, 20), E.SET_KF: (40, 19)})
    fig, ax = plt.subplots()
    E.plot_sweep(df, "a", ax=ax, names=(E.RAW, E.SET_PF, E.SET_KF), y_max=100)
    assert ax.get_ylim() == (0, 100)
    marks = [ln for ln in ax.lines if ln.get_marker() == "^"]
    assert len(marks) == 1 and marks[0].get_xdata()[0] == pytest.approx(2)
    assert [t.get_text() for t in ax.texts] == ["off the axes:\n▲ set-noise PF: up to 300 cm (σ_d ≤ 2 cm/s)"]
    colours = {ln.get_label(): ln.get_color() for ln in ax.lines if not ln.get_label().startswith("_")}
    assert len(set(colours.values())) == 3                          # each estimator its own colour


# --------------------------------------------------------------------------- panel, summary rows, checks

def test_explorer_offers_every_recording_and_reads_out_its_errors(study, rig_inputs):
    from uwbwb.classroom import axes_problems, axes_record

    real = E.real_study(rig_inputs, decimate=8, tags=("t0",), rng=np.random.default_rng(0))
    speeds = 2 * tuple(study.facility.config.speeds_mps)                  # as the notebook builds them
    logs = {f"{r.name} ({100 * v:.0f} cm/s, synthetic)": (r, study.model)
            for r, v in zip(study.recordings + study.off_recordings, speeds)}
    logs.update({f"{t.name} (synthetic, calibrated ranges)": (t, real.model) for t in real.tests})
    assert len(logs) == len(study.recordings) + len(study.off_recordings) + 1
    assert list(logs)[0] == "rec1 (35 cm/s, synthetic)" and logs[list(logs)[-1]][1] is real.model
    ex = E.panels.Explorer(logs)
    panel = ex.panel(n_particles=100, seed=3)
    assert panel.values["recording"] == list(logs)[1] and panel.values["n_particles"] == 100
    values = dict(panel.values, recording=list(logs)[0])
    errors = ex.readout(values)
    log = logs[list(logs)[0]][0]
    assert errors[f"{E.RAW} mean error (cm)"] == pytest.approx(100 * E.raw_error_m(log))
    assert ex.readout(values) is errors                                   # cached per setting
    fig, shown = ex.render(**values)
    assert shown is errors and all(axes_problems(axes_record(ax)) == [] for ax in fig.axes)


def test_real_rows_and_checks():
    bands = {}
    for variant, raw in (("calibrated", 10.0), ("raw", 14.0)):
        bands[variant] = pd.DataFrame({"error_cm": [raw, 9.0, 9.5, 9.2, 9.1, 9.0],
                                       "improvement_pct": [0.0, 10.0, 5.0, 8.0, 9.0, 10.0]},
                                      index=pd.Index(E.FILTERS, name="filter"))
    real_band = pd.concat(bands)

    class Cov:
        def coverage(self):
            return pd.DataFrame({"coverage": [0.9, 0.8]}, index=["calibration", "test"])

    studies = {"calibrated": Cov(), "raw": Cov()}
    rows = E.headlines.real_rows(real_band, studies, "lias-planar-uwb/fast")
    assert len(rows) == 2 * 6 and {r["kind"] for r in rows} == {"reproduced"}
    assert rows[0]["value"] == 10.0 and rows[1]["value"] == pytest.approx(80.0) and rows[6]["value"] == 14.0
    imp = pd.DataFrame({"improvement_pct": [5.0, 6.0, 4.0]}, index=[E.SET_PF, E.SET_KF, E.BASE_KF])
    band_table = pd.DataFrame({E.SET_PF: [12.0], E.SET_KF: [11.0]}, index=["mean"])
    gap = pd.DataFrame({"rms_gap_m": [0.10, 0.02]})
    kw = dict(shares={"n_sets": 5, "top1_share": 0.4}, improvement=imp, off_improvement=imp, band_table=band_table,
              gap=gap, resampler=_resampler(17.1, 17.0), real_band=real_band, studies=studies)
    E.headlines.checks(**kw, fast=True)
    with pytest.raises(AssertionError, match="differ by 1.00 cm"):          # 1 cm apart: fine in FAST only
        E.headlines.checks(**kw, fast=False)
    with pytest.raises(AssertionError, match="approach the KF"):
        E.headlines.checks(**dict(kw, gap=pd.DataFrame({"rms_gap_m": [0.10, 0.09]})), fast=True)
    with pytest.raises(AssertionError, match="resamplers differ"):          # 1 cm apart, standard error 0.1 cm
        E.headlines.checks(**dict(kw, resampler=_resampler(18.0, 17.0)), fast=True)
