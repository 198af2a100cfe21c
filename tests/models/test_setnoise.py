import numpy as np
import pandas as pd
import pytest

from uwbwb.models.setnoise import SetNoiseModel, location_statistics, log_likelihood
from uwbwb.types import SetFixLog



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


# --------------------------------------------------------------------------- calibration

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
    model = SetNoiseModel.fit(err, sets, loc)
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
    model = SetNoiseModel.fit(err, sets, loc, sigma_rule="pooled")
    paper = SetNoiseModel.fit(err, sets, loc)
    np.testing.assert_allclose(model.mu_m, paper.mu_m)
    mx = (30 * 0.1 + 40 * 0.3) / 70
    var_x = (30 * (_sample_std(0.02, 30) ** 2 + (0.1 - mx) ** 2) + 40 * (_sample_std(0.06, 40) ** 2 + (0.3 - mx) ** 2)) / 70
    assert model.sigma_m[0, 0] == pytest.approx(np.sqrt(var_x))
    np.testing.assert_allclose(model.sigma_m[1], paper.sigma_m[1])       # one location: the rules agree
    np.testing.assert_allclose(model.default_sigma_m, paper.default_sigma_m)
    with pytest.raises(ValueError, match="sigma_rule"):
        SetNoiseModel.fit(err, sets, loc, sigma_rule="median")


def test_gate_is_at_least_30(calib):
    err, sets, loc = calib
    table = SetNoiseModel.fit(err, sets, loc).meta["per_location"]
    gate = dict(zip(zip(table["location"], table["set_id"]), table["gated_in"]))
    assert gate[("A", 1)] and not gate[("A", 2)] and gate[("B", 2)]
    # moving the gate to 28 admits set 2 at A; 31 drops set 1 at A
    assert SetNoiseModel.fit(err, sets, loc, min_count=28).n.tolist() == [70, 62]
    assert SetNoiseModel.fit(err, sets, loc, min_count=31).n.tolist() == [40, 34]
    with pytest.raises(ValueError, match="min_count"):
        SetNoiseModel.fit(err, sets, loc, min_count=1)


def test_location_statistics_table():
    err = np.array([[0.0, 1.0], [2.0, 3.0], [4.0, 5.0]])
    t = location_statistics(err, [5, 5, 6], ["a", "a", "a"])
    assert t["set_id"].tolist() == [5, 6] and t["n"].tolist() == [2, 1]
    np.testing.assert_allclose(t.loc[0, ["mu_x_m", "mu_y_m", "sigma_x_m"]].to_numpy(float), [1.0, 2.0, np.sqrt(2)])
    assert np.isnan(t.loc[1, "sigma_x_m"])
    with pytest.raises(ValueError, match="non-finite"):
        location_statistics([[np.nan, 0.0]], [1], ["a"])


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


# --------------------------------------------------------------------------- calibration from fix logs

def _log(n=6, name="loc"):
    t = np.arange(n) * 0.1
    sets = np.array([0b11111, 0b11111, 0b101111, 0b11111, 0b101111, 0b1110011])[:n]
    return SetFixLog(t, np.zeros((n, 2)) + 0.1, sets, tuple(str(i) for i in range(8)), np.zeros((n, 2)), name)


def test_from_fixes_labels_locations_by_name():
    a, b = _log(name="A"), _log(name="B")
    model = SetNoiseModel.from_fixes([a, b], min_count=2)
    assert set(model.meta["per_location"]["location"]) == {"A", "B"}
    assert model.n.tolist() == [6, 4]
    # identical fixes give σ = 0, which the fit floors (eq. 9 would be infinite)
    np.testing.assert_allclose(model.sigma_m, 1e-3)
    assert model.meta["n_sigma_floored"] == 6
    with pytest.raises(ValueError, match="distinct names"):
        SetNoiseModel.from_fixes([a, _log(name="A")])
