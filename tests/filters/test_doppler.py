from dataclasses import replace

import numpy as np
import pytest

from uwbwb import ChirpFlag, EstimateStatus
from uwbwb.filters import doppler as fd
from uwbwb.filters.kalman import Gaussian
from uwbwb.filters.particle import effective_sample_size, tempering_exponent
from uwbwb.models import doppler as dm
from uwbwb.models.motion import ReceiverMotion
from uwbwb.sim import chirps as sc


@pytest.fixture(scope="module")
def lab():
    return dm.DopplerModel.for_layout(dm.lab_layout())


@pytest.fixture(scope="module")
def clean(lab):
    track, _ = sc.rectangle_track()
    return sc.simulate_chirps(lab, track, 20.0, rng=np.random.default_rng(0), jitter=False, p_miss=0.0,
                              spurious_rate_hz=0.0)


def test_front_end_assigns_a_clean_recording_correctly(lab, clean):
    log = fd.assign_chirps(clean.t_s, lab)
    assigned = log.beacon >= 0
    assert assigned.mean() > 0.97
    # chirps of two beacons that arrive together can be swapped; nothing else goes wrong
    assert np.mean(log.beacon[assigned] == clean.source[assigned]) > 0.98
    assert log.has(ChirpFlag.LOCK).sum() == 2 * lab.n_beacons
    ok = log.measured
    h = lab.delta_p(clean.truth.pos_m[ok], clean.truth.vel_mps[ok], log.beacon[ok], instantaneous=False)
    assert np.median(np.abs(log.dp_s[ok] - h)) < 5e-6


def test_front_end_bridges_misses_and_flags_spurious(lab):
    track, _ = sc.rectangle_track()
    rec = sc.simulate_chirps(lab, track, 60.0, rng=np.random.default_rng(1), p_miss=0.1, spurious_rate_hz=1.0)
    log = fd.assign_chirps(rec.t_s, lab)
    assert log.has(ChirpFlag.GAP).sum() > 10
    wrong = (log.beacon >= 0) & (log.beacon != rec.source)
    assert wrong.mean() < 0.05
    spurious = rec.source < 0
    assert np.mean(log.has(ChirpFlag.UNASSIGNED)[spurious]) > 0.8


def test_clock_pseudo_ranges_are_ranges(lab, clean):
    log = fd.assign_chirps(clean.t_s, lab)
    r = fd.clock_pseudo_ranges(log, lab, clean.phase_s)
    ok = (log.beacon >= 0) & (log.beacon == clean.source)
    truth = lab.pseudo_range_m(clean.truth.pos_m[ok], log.beacon[ok])
    np.testing.assert_allclose(r[ok], truth, atol=1e-6)
    assert np.all(np.isnan(r[log.beacon < 0]))


def test_pf_converges_on_a_noise_free_run():
    cubic = dm.DopplerModel.for_layout(dm.cubic_layout())
    track, _ = sc.rectangle_track()
    clean = sc.simulate_chirps(cubic, track, 20.0, rng=np.random.default_rng(0), jitter=False, p_miss=0.0,
                               spurious_rate_hz=0.0)
    log = fd.assign_chirps(clean.t_s, cubic)
    pf = fd.DopplerPf(cubic, n_particles=3000, room_lo_m=(-2, -2, -1.2), room_hi_m=(2, 2, 1.5))
    runs = pf.run(log, n_runs=4, rng=np.random.default_rng(2))
    idx = np.searchsorted(clean.truth.t_s, runs.t_s)
    err = np.linalg.norm(runs.pos_m - clean.truth.pos_m[idx], axis=-1)
    late = runs.t_s > 10.0
    assert np.median(err[:, late]) < 0.15
    assert np.median(err[:, :5]) > 2 * np.median(err[:, late])          # it started lost and converged
    est = runs.estimates(1)
    assert est.coverage == 1.0 and est.vel_mps.shape == (len(runs.t_s), 3)


def test_pf_same_seed_same_runs(lab, clean):
    log = fd.assign_chirps(clean.t_s, lab).between(0, 5)
    pf = fd.DopplerPf(lab, n_particles=200)
    a = pf.run(log, n_runs=2, rng=np.random.default_rng(7))
    b = pf.run(log, n_runs=2, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a.pos_m, b.pos_m)


def test_mh_ekf_converges_on_a_noise_free_run(lab):
    """Constant velocity (so eq 1 at mid-period is exact) and no noise: the error keeps shrinking."""
    track = sc.LineTrack((-1.2, -0.8, 0.0), (0.2, 0.1, 0.0))
    clean = sc.simulate_chirps(lab, track, 20.0, rng=np.random.default_rng(0), jitter=False, p_miss=0.0,
                               spurious_rate_hz=0.0)
    log = fd.assign_chirps(clean.t_s, lab)
    x0 = np.concatenate([clean.truth.pos_m[0] + [0.4, -0.3, 0.2], clean.truth.vel_mps[0] + [0.2, 0.2, 0.0]])
    ekf = fd.ScaatMhEkf(replace(lab, sigma_model_mps=0.01), motion=ReceiverMotion((0.2, 0.2, 0.02)))
    est = ekf.run(log, Gaussian(x0, np.diag([0.5 ** 2] * 3 + [0.5 ** 2] * 3)))
    err = np.linalg.norm(est.pos_m - clean.truth.pos_m, axis=1)
    late = est.t_s > 15.0
    assert err[0] > 0.5 and np.max(err[late]) < 0.1   # eq 1 at mid-period is exact to ~0.5 %, not 0
    assert np.linalg.norm(est.vel_mps[-1] - clean.truth.vel_mps[-1]) < 0.02
    assert np.mean(est.status[late] == EstimateStatus.UPDATED) > 0.9
    used = est.info["beacon"] >= 0
    assert np.mean(est.info["beacon"][used] == clean.source[used]) > 0.99


def test_mh_ekf_reads_spurious_chirps_as_noise(lab):
    track, _ = sc.rectangle_track()
    rec = sc.simulate_chirps(lab, track, 20.0, rng=np.random.default_rng(3), spurious_rate_hz=2.0, p_miss=0.0)
    log = fd.assign_chirps(rec.t_s, lab)
    x0 = np.concatenate([rec.truth.pos_m[0], rec.truth.vel_mps[0]])
    est = fd.ScaatMhEkf(lab, spurious_rate_hz=2.0).run(log, Gaussian(x0, np.diag([0.3 ** 2] * 3 + [0.3 ** 2] * 3)))
    spurious = rec.source < 0
    assert spurious.sum() > 20
    assert np.mean(est.info["beacon"][spurious] == -1) > 0.8
    assert est.info["n_hypotheses"].max() > 1


# ------------------------------------------------------------------ parameter checks (each names the parameter)

@pytest.mark.parametrize("kwargs, name", [
    ({"n_particles": 1}, "n_particles"), ({"n_particles": 2.5}, "n_particles"),
    ({"room_lo_m": (0, 0)}, "room_lo_m"), ({"room_hi_m": (1.0, np.nan, 1.0)}, "room_hi_m"),
    ({"init_speed_mps": 0.0}, "init_speed_mps"), ({"resample_threshold": 1.5}, "resample_threshold"),
    ({"roughening": -0.1}, "roughening"), ({"outlier_prob": -0.1}, "outlier_prob"),
    ({"outlier_prob": 1.0}, "outlier_prob"), ({"outlier_window_s": 0.0}, "outlier_window_s"),
    ({"temper_ess": 1.0}, "temper_ess"), ({"temper_ess": np.nan}, "temper_ess"),
    ({"use_ambiguous": "yes"}, "use_ambiguous"), ({"motion": None}, "motion"),
])
def test_pf_rejects_bad_parameters_by_name(lab, kwargs, name):
    with pytest.raises(ValueError, match=name):
        fd.DopplerPf(lab, **kwargs)


@pytest.mark.parametrize("kwargs, name", [
    ({"p_detect": 1.5}, "p_detect"), ({"p_detect": 0.0}, "p_detect"), ({"spurious_rate_hz": -1.0}, "spurious_rate_hz"),
    ({"window_s": -1.0}, "window_s"), ({"max_gap": 0}, "max_gap"), ({"max_gap": 2.0}, "max_gap"),
    ({"max_hypotheses": 0}, "max_hypotheses"), ({"prune_ratio": 2.0}, "prune_ratio"), ({"motion": None}, "motion"),
])
def test_mh_ekf_rejects_bad_parameters_by_name(lab, kwargs, name):
    with pytest.raises(ValueError, match=name):
        fd.ScaatMhEkf(lab, **kwargs)


def test_filters_reject_a_model_that_is_not_a_doppler_model():
    with pytest.raises(ValueError, match="model"):
        fd.DopplerPf(None)
    with pytest.raises(ValueError, match="model"):
        fd.ScaatMhEkf("lab")


def test_run_arguments_are_checked_by_name(lab, clean):
    log = fd.assign_chirps(clean.t_s, lab).between(0, 3)
    pf = fd.DopplerPf(lab, n_particles=50)
    for kwargs, name in (({"n_runs": 0}, "n_runs"), ({"block_runs": -1}, "block_runs"), ({"workers": 0}, "workers"),
                         ({"ranges_m": np.zeros(3)}, "ranges_m"), ({"ranges_m": np.full(len(log), -1.0)}, "ranges_m")):
        with pytest.raises(ValueError, match=name):
            pf.run(log, rng=np.random.default_rng(0), **kwargs)
    kf = fd.ScaatMhEkf(lab)
    with pytest.raises(ValueError, match="x0"):
        kf.run(log, Gaussian(np.zeros(3), np.eye(3)))
    with pytest.raises(ValueError, match="ranges_m"):
        kf.run(log, Gaussian(np.zeros(6), np.eye(6)), ranges_m=np.zeros(2))


def test_front_end_arguments_are_checked_by_name(lab, clean):
    for kwargs, name in (({"window_s": -1.0}, "window_s"), ({"window_s": 0.0}, "window_s"), ({"max_gap": 0}, "max_gap")):
        with pytest.raises(ValueError, match=name):
            fd.assign_chirps(clean.t_s, lab, **kwargs)
    with pytest.raises(ValueError, match="t_s"):
        fd.assign_chirps(clean.t_s[::-1], lab)
    log = fd.assign_chirps(clean.t_s, lab)
    with pytest.raises(ValueError, match="phase_s"):
        fd.clock_pseudo_ranges(log, lab, np.zeros(3))


# ------------------------------------------------------------------ measurement adapter and tempering

def test_measurement_adapter_gives_doppler_and_range_rows(lab):
    x = np.array([0.1, 0.2, 0.3, 0.5, -0.2, 0.0])
    meas = fd.DopplerMeasurement(lab)
    lin = meas.linearise(x, (2, 1e-4, np.nan))
    assert lin.z.shape == (1,) and lin.H.shape == (1, 6)
    np.testing.assert_allclose(lin.H[0], lab.jacobian(x[:3], x[3:], np.array(2), instantaneous=False))
    lin = meas.linearise(x, (2, 1e-4, 3.0))
    assert lin.z.shape == (2,) and lin.h[1] == pytest.approx(np.linalg.norm(x[:3] - lab.beacons.pos_m[2]))
    assert meas.linearise(x, (-1, np.nan, np.nan)) is None


def test_tempering_keeps_the_requested_effective_sample_size(lab):
    pf = fd.DopplerPf(lab, n_particles=400, temper_ess=0.1)
    rng = np.random.default_rng(0)
    logw = np.full((3, 400), -np.log(400))
    ll = np.stack([np.zeros(400), -0.5 * (rng.normal(size=400) / 0.01) ** 2, -0.5 * (rng.normal(size=400) / 0.1) ** 2])
    beta = tempering_exponent(logw, ll, pf.temper_ess)
    assert beta[0] == 1.0                                 # a flat likelihood is used in full
    assert 0 < beta[1] < 1 and effective_sample_size(logw[1] + beta[1] * ll[1]) == pytest.approx(40, rel=0.02)
    off = tempering_exponent(logw, ll, fd.DopplerPf(lab, n_particles=400, temper_ess=0.0).temper_ess)
    np.testing.assert_array_equal(off, 1.0)


def test_pf_with_pseudo_ranges_keeps_track_where_the_untempered_one_restarts():
    """The sharp pseudo-range likelihood collapses an untempered cloud onto wrong particles (restarts, lost runs);
    the tempered update keeps every run on track on the same log and seed."""
    lab = dm.DopplerModel.for_layout(dm.lab_layout())
    track, _ = sc.rectangle_track()
    rec = sc.simulate_chirps(lab, track, 12.0, rng=np.random.default_rng(101), p_miss=0.05, spurious_rate_hz=0.5)
    log = fd.assign_chirps(rec.t_s, lab)
    r = fd.clock_pseudo_ranges(log, lab, rec.phase_s)
    out = {}
    for temper in (0.0, 0.02):
        pf = fd.DopplerPf(lab, n_particles=800, temper_ess=temper)
        runs = pf.run(log, n_runs=8, rng=np.random.default_rng(1), ranges_m=r)
        late = runs.t_s > 6.0
        err = np.linalg.norm(runs.pos_m[:, late, :2] - track.pos_m(runs.t_s[late])[:, :2], axis=-1)
        out[temper] = (runs.restarts.sum(), np.quantile(err, 0.95), runs.meta["tempered"])
    assert out[0.0][1] > 0.5                                # lost runs without tempering
    assert out[0.02][1] < 0.2 and out[0.02][0] <= 1        # on track with it
    assert np.all(out[0.0][2] == 0) and np.all(out[0.02][2] > 0)


def test_pf_runs_are_estimates_batched_along_a_run_axis(lab, clean):
    log = fd.assign_chirps(clean.t_s, lab).between(0, 3)
    runs = fd.DopplerPf(lab, n_particles=60).run(log, n_runs=3, rng=np.random.default_rng(4))
    R, T = runs.pos_m.shape[:2]
    assert (R, T) == (3, runs.t_s.size) and runs.status.shape == (R, T) and runs.pos_cov_m2.shape == (R, T, 3, 3)
    assert np.all(runs.status == EstimateStatus.UPDATED) and runs.ess is runs.info["ess"]
    each = runs.to_estimates()
    assert len(each) == R
    for r, est in enumerate(each):
        np.testing.assert_array_equal(est.pos_m, runs.pos_m[r])
        np.testing.assert_array_equal(est.pos_cov_m2, runs.pos_cov_m2[r])
        np.testing.assert_array_equal(est.vel_mps, runs.vel_mps[r])
        np.testing.assert_array_equal(est.info["ess"], runs.ess[r])
    with pytest.raises(ValueError, match="status"):
        fd.PfRuns(runs.t_s, runs.pos_m, runs.status[:, :-1])
    with pytest.raises(ValueError, match="info"):
        fd.PfRuns(runs.t_s, runs.pos_m, runs.status, info={"ess": runs.ess[0]})
    with pytest.raises(ValueError, match="pos_m"):
        fd.PfRuns(runs.t_s, runs.pos_m[0], runs.status)
