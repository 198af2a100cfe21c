"""Invalid parameters and hostile values at the boundary of the filters: a clear ValueError, never
quiet nonsense (a count of -1, a negative NIS, a NaN state) or a raw numpy/LinAlg error."""

from __future__ import annotations

import numpy as np
import pytest

from uwbwb.filters import kalman, particle
from uwbwb.filters import setnoise as sn
from uwbwb.filters.ekf import TdoaEkf
from uwbwb.models.motion import RandomForce, VelocityKick
from uwbwb.models.tdoa import TdoaModel
from uwbwb.types import TdoaLog, pseudo_tdoa

ANCHORS = np.array([[0.0, 0.0, 3.0], [30.0, 0.0, 0.5], [30.0, 30.0, 3.0], [0.0, 30.0, 0.5],
                    [15.0, -2.0, 2.0], [15.0, 32.0, 1.0]])
IDS = tuple(f"a{i}" for i in range(6))


# --- the EKF gate is on by default -------------------------------------------------------------------

def _one_absurd_tdoa():
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    t = np.arange(0, 10, 0.1)
    pos = np.column_stack([10 + 0.3 * t, 12 + 0.1 * t])
    d, refs = pseudo_tdoa(model.ranges(pos), 0)
    d[50, 2] = 1e6                                   # one TDoA of 1000 km
    return model, TdoaLog(t, d, refs, IDS), pos


def test_ekf_default_gate_rejects_one_absurd_tdoa():
    model, log, pos = _one_absurd_tdoa()
    res = TdoaEkf(RandomForce(0.3), model).run(log)              # default settings
    err = np.linalg.norm(res.pos_m - pos, axis=1)
    assert err.max() < 0.5 and res.n_rejected[50] >= 1            # flagged and counted, estimate kept
    assert TdoaEkf(RandomForce(0.3), model).gate_prob == 0.9999


def test_ekf_without_gate_follows_the_absurd_tdoa():
    model, log, pos = _one_absurd_tdoa()
    res = TdoaEkf(RandomForce(0.3), model, gate_prob=None).run(log)   # None: no gate, as documented
    assert np.linalg.norm(res.pos_m[50] - pos[50]) > 1e3


# --- Kalman edge ---------------------------------------------------------------------------------------

def test_kalman_update_rejects_negative_r_nan_measurement_and_singular_innovation():
    g = kalman.Gaussian(np.zeros(2), np.eye(2))
    H = np.array([[1.0, 0.0]])
    with pytest.raises(ValueError, match="R must be symmetric with positive variances"):
        kalman.update(g, np.array([1.0]), H, np.array([[-1.0]]))        # would give NIS -0.25
    with pytest.raises(ValueError, match="z contains non-finite values"):
        kalman.update(g, np.array([np.nan]), H, np.array([[1.0]]))        # would turn the state NaN
    with pytest.raises(ValueError, match="not positive definite"):
        kalman.update(kalman.Gaussian(np.zeros(2), np.zeros((2, 2))), np.array([1.0, 1.0]),
                      np.eye(2), np.ones((2, 2)))                          # singular innovation covariance


def test_tdoa_model_sigma_whose_variance_underflows():
    with pytest.raises(ValueError, match="sigma_m"):
        TdoaModel(ANCHORS, 1e-300, dim=2, z_m=1.0)
    with pytest.raises(ValueError, match="sigma_m"):
        TdoaModel(ANCHORS, -0.1)


# --- particle filter -----------------------------------------------------------------------------------

def test_systematic_resampling_rejects_a_negative_weight():
    with pytest.raises(ValueError, match="non-negative"):
        particle.systematic_counts(np.array([0.5, -0.2, 0.7]), np.array(0.3))   # was a count of -1
    with pytest.raises(ValueError, match="non-negative"):
        particle.multinomial_indices(np.array([0.5, np.nan, 0.5]), np.array([0.1, 0.5, 0.9]))


@pytest.mark.parametrize("call", [
    lambda: particle.normalise_log_weights(np.zeros(0)),
    lambda: particle.effective_sample_size(np.zeros((3, 0))),
    lambda: particle.weighted_mean(np.zeros((0, 2)), np.zeros(0)),
    lambda: particle.systematic_counts(np.zeros(0), np.array(0.3)),
    lambda: particle.multinomial_indices(np.zeros(0), np.zeros(0)),
    lambda: particle.resample_indices(np.zeros(0), rng=np.random.default_rng(0)),
])
def test_zero_particles_is_a_clear_error(call):
    with pytest.raises(ValueError, match="K >= 1"):
        call()


@pytest.mark.parametrize("n", [2.5, 0, -3, True, "100"])
def test_n_particles_must_be_a_positive_integer(n):
    t = np.arange(5.0)
    z, mu, sd = np.zeros((5, 2)), np.zeros((5, 2)), np.ones((5, 2))
    with pytest.raises(ValueError, match="n_particles"):
        sn.reference_pf(t, z, mu, sd, np.zeros(2), 0.3, rng=np.random.default_rng(0), n_particles=n)
    with pytest.raises(ValueError, match="n_particles"):
        sn.pf_init(np.zeros(2), n)


def test_negative_driving_noise_is_an_error():
    with pytest.raises(ValueError, match="sigma_d_mps"):
        VelocityKick(-0.3, dim=2)
    t = np.arange(5.0)
    z, mu, sd = np.zeros((5, 2)), np.zeros((5, 2)), np.ones((5, 2))
    with pytest.raises(ValueError, match="sigma_d_mps"):
        sn.reference_pf(t, z, mu, sd, np.zeros(2), -0.3, rng=np.random.default_rng(0), n_particles=10)


# --- every public filter parameter is checked where it enters ------------------------------------------

@pytest.mark.parametrize("call, name", [
    (lambda: particle.resample(np.zeros((2, 4, 2)), np.zeros((2, 4)), rng=np.random.default_rng(0),
                               threshold=float("nan")), "threshold"),
    (lambda: particle.resample(np.zeros((2, 4, 2)), np.zeros((2, 4)), rng=np.random.default_rng(0),
                               method="stratified"), "method"),
    (lambda: particle.roughen(np.zeros((2, 4, 2)), rng=np.random.default_rng(0), k=-1.0), "k"),
    (lambda: sn.pf_sweep(np.arange(5.0), np.zeros((5, 2)), np.zeros((5, 2)), np.ones((5, 2)), np.zeros(2), [0.3],
                         rng=np.random.default_rng(0), n_trials=2.5, n_particles=10), "n_trials"),
    (lambda: sn.kf_sweep(np.arange(5.0), np.zeros((5, 2)), np.zeros((5, 2)), np.ones((5, 2)), np.zeros(2),
                         [-0.3]), "sigma_d_mps"),
    (lambda: sn.reference_pf(np.arange(5.0), np.zeros((5, 2)), np.zeros((5, 2)), np.ones((5, 2)), np.zeros(2), 0.3,
                             rng=np.random.default_rng(0), n_particles=10, ess_fraction="half"), "ess_fraction"),
])
def test_filter_parameters_are_checked(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_pruning_and_tdoa_ls_parameters_are_checked():
    from uwbwb.filters import pruning, tdoa_ls
    with pytest.raises(ValueError, match="retention"):
        pruning.drop_schedule(100, 1.5, 0.01)
    with pytest.raises(ValueError, match="n0"):
        pruning.drop_schedule(-1, 0.5, 0.01)
    with pytest.raises(ValueError, match="q"):
        pruning.percentile_ranges(np.ones((5, 3)), q=200)
    with pytest.raises(ValueError, match="retention"):
        pruning.robust_mean(np.zeros((10, 2)), retention=0.0)
    model, log, _ = _one_absurd_tdoa()
    with pytest.raises(ValueError, match="max_iter"):
        tdoa_ls.tdoa_least_squares(log, model, max_iter=2.5)


def test_ekf_parameters_are_checked():
    from uwbwb.filters.ekf import nis_consistency
    model, _, _ = _one_absurd_tdoa()
    with pytest.raises(ValueError, match="init_pos_sigma_m"):
        TdoaEkf(RandomForce(0.3), model, init_pos_sigma_m=-1.0)
    with pytest.raises(ValueError, match="gate_prob"):
        TdoaEkf(RandomForce(0.3), model, gate_prob="high")
    with pytest.raises(ValueError, match="prob"):
        nis_consistency(np.ones(5), np.ones(5), prob=2.0)
