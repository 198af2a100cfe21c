import numpy as np
import pandas as pd
import pytest

from uwbwb.models.setnoise import SetNoiseModel, log_likelihood


# --------------------------------------------------------------------------- eq. 9

def test_eq9_hand_computed():
    # x: (1 + 0.2 - 1.5) / 0.5 = -0.6 ; y: (2 - 0.1 - 2.0) / 0.2 = -0.5
    ll = log_likelihood([1.0, 2.0], [1.5, 2.0], [0.2, -0.1], [0.5, 0.2])
    assert ll == pytest.approx(-0.5 * (0.36 + 0.25))
    lln = log_likelihood([1.0, 2.0], [1.5, 2.0], [0.2, -0.1], [0.5, 0.2], normalised=True)
    assert lln == pytest.approx(-0.305 - np.log(2 * np.pi * 0.1))


def test_eq9_is_the_gaussian_of_eq6_up_to_a_constant():
    from scipy.stats import norm

    rng = np.random.default_rng(0)
    pos = rng.normal(size=(50, 2))
    z, mu, sd = np.array([0.3, -0.2]), np.array([0.05, 0.1]), np.array([0.2, 0.4])
    expect = norm.logpdf(z[0], pos[:, 0] + mu[0], sd[0]) + norm.logpdf(z[1], pos[:, 1] + mu[1], sd[1])
    np.testing.assert_allclose(log_likelihood(pos, z, mu, sd, normalised=True), expect)
    diff = log_likelihood(pos, z, mu, sd) - expect
    np.testing.assert_allclose(diff, diff[0])                      # constant across particles


def test_model_validation_and_facility_only():
    with pytest.raises(ValueError, match="positive"):
        SetNoiseModel([1], [[0, 0]], [[0.1, 0.0]], [40], [0, 0], [0.1, 0.1])
    with pytest.raises(ValueError, match="sorted"):
        SetNoiseModel([3, 1], [[0, 0]] * 2, [[0.1, 0.1]] * 2, [40, 40], [0, 0], [0.1, 0.1])
    model = SetNoiseModel([1, 3], [[0.1, 0.0], [0.0, 0.2]], [[0.1, 0.1], [0.2, 0.2]], [40, 50], [0.05, 0.05], [0.3, 0.3], 90)
    base = model.facility_only()
    assert len(base) == 0
    mu, sd, modelled = base.lookup(np.array([[1, 3], [2, 1]]))
    assert mu.shape == (2, 2, 2) and not modelled.any()
    np.testing.assert_allclose(sd, 0.3)


def test_model_table_round_trip():
    model = SetNoiseModel([1, 3], [[0.1, 0.0], [0.0, 0.2]], [[0.1, 0.1], [0.2, 0.2]], [40, 50], [0.05, 0.05],
                          [0.3, 0.3], 90)
    df = model.to_frame()
    assert df["label"].tolist() == ["10", "0", "default"]
    back = SetNoiseModel.from_frame(df)
    for name in ("set_id", "mu_m", "sigma_m", "n", "default_mu_m", "default_sigma_m"):
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name))
    assert back.default_n == 90
    with pytest.raises(ValueError, match="facility-wide"):
        SetNoiseModel.from_frame(df[df["set_id"] != 0])


def test_sample_follows_the_model():
    model = SetNoiseModel([1, 2], [[0.1, -0.2], [0.0, 0.3]], [[0.05, 0.1], [0.2, 0.02]], [40, 40], [0, 0], [1, 1])
    n = 20000
    sets = np.r_[np.ones(n, int), np.full(n, 2)]
    z = model.sample(np.zeros((2 * n, 2)), sets, rng=np.random.default_rng(3))
    np.testing.assert_allclose(z[:n].mean(0), [0.1, -0.2], atol=0.005)
    np.testing.assert_allclose(z[n:].std(0), [0.2, 0.02], rtol=0.03)
    z2 = model.sample(np.zeros((2 * n, 2)), sets, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(z, z2)
