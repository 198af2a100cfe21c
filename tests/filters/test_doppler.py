from dataclasses import replace

import numpy as np
import pytest

from uwbwb import ChirpFlag, EstimateStatus
from uwbwb.filters import doppler as fd
from uwbwb.filters.kalman import Gaussian
from uwbwb.models import doppler as dm
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
    ekf = fd.ScaatMhEkf(replace(lab, sigma_model_mps=0.01), motion=dm.ReceiverMotion((0.2, 0.2, 0.02)))
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
