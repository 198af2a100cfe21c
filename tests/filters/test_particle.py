import numpy as np
import pytest

from uwbwb.filters import particle as P

W = np.array([0.1, 0.2, 0.3, 0.4])


def test_normalise_log_weights_hand_case_and_stability():
    logw, lse = P.normalise_log_weights(np.log([1.0, 2.0, 3.0, 4.0]))
    np.testing.assert_allclose(np.exp(logw), W)
    assert lse == pytest.approx(np.log(10.0))
    logw, lse = P.normalise_log_weights(np.array([[1000.0, 1000.0 + np.log(3)], [-1e4, -np.inf]]))
    np.testing.assert_allclose(np.exp(logw), [[0.25, 0.75], [1.0, 0.0]])
    assert lse[0] == pytest.approx(1000 + np.log(4))
    with pytest.raises(ValueError, match="no finite"):
        P.normalise_log_weights(np.full((2, 3), -np.inf))


def test_eq12_cv_and_ess_hand_case():
    # K w - 1 = (-0.6, -0.2, 0.2, 0.6): CV = (0.36 + 0.04 + 0.04 + 0.36) / 4 = 0.2
    logw = np.log(W) + 7.0                      # unnormalised on purpose
    assert P.coefficient_of_variation(logw) == pytest.approx(0.2)
    assert P.effective_sample_size(logw) == pytest.approx(4 / 1.2)
    assert P.effective_sample_size(logw) == pytest.approx(1 / np.sum(W ** 2))


def test_ess_limits_and_batch_shape():
    logw = np.stack([np.zeros(5), np.r_[0.0, np.full(4, -np.inf)]])
    np.testing.assert_allclose(P.effective_sample_size(logw), [5.0, 1.0])
    np.testing.assert_allclose(P.coefficient_of_variation(logw), [0.0, 4.0])
    big = np.random.default_rng(0).normal(size=(3, 2, 50))
    assert P.effective_sample_size(big).shape == (3, 2)


def test_weighted_mean_eq11():
    particles = np.arange(8.0).reshape(4, 2)
    np.testing.assert_allclose(P.weighted_mean(particles, np.log(W)), W @ particles)


def test_systematic_indices_hand_case():
    # positions (j + 0.5)/4 = .125 .375 .625 .875 in the CDF (.1 .3 .6 1)
    assert P.systematic_indices(W, np.array(0.5)).tolist() == [1, 2, 3, 3]
    assert P.systematic_indices(W, np.array(0.0)).tolist() == [0, 1, 2, 3]


def test_multinomial_indices_hand_case():
    u = np.array([0.95, 0.05, 0.65, 0.25])
    assert P.multinomial_indices(W, u).tolist() == [0, 1, 3, 3]


@pytest.mark.parametrize("method", P.RESAMPLERS)
def test_batched_indices_equal_row_by_row(method):
    rng = np.random.default_rng(1)
    w = rng.random((3, 2, 40)) ** 4
    w /= w.sum(-1, keepdims=True)
    u = rng.random((3, 2) if method == "systematic" else (3, 2, 40))
    f = P.systematic_indices if method == "systematic" else P.multinomial_indices
    batched = f(w, u)
    assert batched.shape == (3, 2, 40)
    for i in range(3):
        for j in range(2):
            np.testing.assert_array_equal(batched[i, j], f(w[i, j], u[i, j]))


def test_systematic_copy_counts_are_floor_or_ceil_of_K_w():
    rng = np.random.default_rng(2)
    K = 200
    w = rng.random((50, K)) ** 3
    w /= w.sum(-1, keepdims=True)
    idx = P.systematic_indices(w, rng.random(50))
    counts = np.stack([np.bincount(r, minlength=K) for r in idx])
    assert np.all(counts >= np.floor(K * w) - 1e-9) and np.all(counts <= np.ceil(K * w) + 1e-9)


@pytest.mark.parametrize("method", P.RESAMPLERS)
def test_resampling_is_unbiased_and_skips_zero_weights(method):
    rng = np.random.default_rng(3)
    w = np.array([0.0, 0.5, 0.1, 0.0, 0.4])
    logw = np.log(np.where(w > 0, w, 1e-300)) + np.where(w > 0, 0, -np.inf)
    idx = P.resample_indices(np.tile(logw, (4000, 1)), rng=rng, method=method)
    counts = np.bincount(idx.ravel(), minlength=5) / idx.size
    np.testing.assert_allclose(counts, w, atol=0.01)
    assert counts[0] == 0 and counts[3] == 0


def test_resample_only_rows_below_threshold():
    rng = np.random.default_rng(4)
    particles = np.arange(2 * 4 * 1.0).reshape(2, 4, 1)
    logw = np.log(np.stack([np.full(4, 0.25), [0.97, 0.01, 0.01, 0.01]]))
    p2, lw2, done = P.resample(particles, logw, rng=rng, threshold=0.5)
    assert done.tolist() == [False, True]
    np.testing.assert_array_equal(p2[0], particles[0])
    np.testing.assert_allclose(lw2[0], logw[0])
    np.testing.assert_allclose(lw2[1], -np.log(4))
    assert set(p2[1, :, 0]) <= set(particles[1, :, 0])
    # same seed, same result; inputs untouched
    p3, _, _ = P.resample(particles, logw, rng=np.random.default_rng(4), threshold=0.5)
    np.testing.assert_array_equal(p2, p3)
    assert particles[1, 1, 0] == 5.0


def test_bad_arguments():
    with pytest.raises(ValueError, match="method must be one of"):
        P.resample_indices(np.zeros(3), rng=np.random.default_rng(0), method="stratified-ish")
    with pytest.raises(ValueError, match="one uniform per row"):
        P.systematic_indices(np.full((2, 3), 1 / 3), np.zeros(3))
    with pytest.raises(ValueError, match="K uniforms"):
        P.multinomial_indices(np.full((2, 3), 1 / 3), np.zeros(2))
    with pytest.raises(ValueError, match="do not match"):
        P.resample(np.zeros((2, 3, 1)), np.zeros((2, 4)), rng=np.random.default_rng(0))


def test_roughen_scales_with_the_spread_and_respects_rows():
    from uwbwb.filters.particle import roughen

    rng = np.random.default_rng(0)
    x = np.stack([rng.uniform(0, 1, (2, 4000)), rng.uniform(0, 10, (2, 4000))], axis=-1)   # (2, K, 2)
    y = roughen(x, rng=np.random.default_rng(1), k=0.2, rows=np.array([True, False]))
    np.testing.assert_array_equal(y[1], x[1])
    d = (y[0] - x[0]).std(axis=0)
    np.testing.assert_allclose(d, 0.2 * np.ptp(x[0], axis=0) * 4000 ** -0.5, rtol=0.05)
