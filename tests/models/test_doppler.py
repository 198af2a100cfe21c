import numpy as np
import pytest

from uwbwb.models import doppler as dm
from uwbwb.models.motion import ReceiverMotion


@pytest.fixture
def model():
    return dm.DopplerModel.for_layout(dm.cubic_layout())


def test_speed_of_sound_default_is_dry_air_at_20c():
    assert dm.speed_of_sound_mps(20.0) == pytest.approx(343.2, abs=0.05)
    assert dm.speed_of_sound_mps(0.0) == pytest.approx(331.3)
    with pytest.raises(ValueError):
        dm.speed_of_sound_mps(-300.0)


def test_cubic_layout_order_matches_the_paper():
    b = dm.cubic_layout().pos_m
    assert b[0].tolist() == [-2, -2, -2] and b[1].tolist() == [-2, -2, 2] and b[7].tolist() == [2, 2, 2]


def test_eq1_holds_for_the_returned_period_shift(model):
    rng = np.random.default_rng(0)
    X, V = rng.uniform(-5, 5, (100, 3)), rng.uniform(-3, 3, (100, 3))
    dp = model.delta_p(X, V)
    u = (X[:, None] - model.beacons.pos_m) / np.linalg.norm(X[:, None] - model.beacons.pos_m, axis=-1)[..., None]
    lhs = dp / (model.period_s + dp) * model.v_s_mps
    np.testing.assert_allclose(lhs, np.einsum("nbk,nk->nb", u, V), rtol=1e-12, atol=1e-12)


def test_moving_away_lengthens_the_period(model):
    X = np.array([0.0, 0.0, 0.0])
    away = X - model.beacons.pos_m[0]
    assert model.delta_p(X, away / np.linalg.norm(away), beacon=np.array(0)) > 0
    assert model.delta_p(X, -away / np.linalg.norm(away), beacon=np.array(0)) < 0


def test_reference_pair_at_half_second_period():
    m = dm.DopplerModel(dm.cubic_layout(), 0.5 + 1e-6 * np.arange(8), v_s_mps=343.0)
    dp = m.delta_p(dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    # paper: 1.1 ms (beacon 0) and -1.2 ms (beacon 7); eq 1 gives about 1.06 and -1.08 ms
    assert dp[0] == pytest.approx(1.06e-3, abs=0.01e-3) and dp[7] == pytest.approx(-1.08e-3, abs=0.01e-3)


@pytest.mark.parametrize("instantaneous", [True, False])
def test_jacobian_matches_finite_differences(model, instantaneous):
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)])
    J = model.jacobian(x[:3], x[3:], instantaneous=instantaneous)
    num = np.empty_like(J)
    for k in range(6):
        e = np.zeros(6)
        e[k] = 1e-6
        f = lambda y: model.delta_p(y[:3], y[3:], instantaneous=instantaneous)
        num[:, k] = (f(x + e) - f(x - e)) / 2e-6
    np.testing.assert_allclose(J, num, rtol=1e-6, atol=1e-12)
    one = model.jacobian(x[:3], x[3:], beacon=np.array(3), instantaneous=instantaneous)
    np.testing.assert_allclose(one, J[3])


def test_measurement_rows_give_doppler_and_range_rows(model):
    x = np.array([0.1, 0.2, 0.3, 0.5, -0.2, 0.0])
    z, h, H, R = model.measurement_rows(x, (2, 1e-4, np.nan))
    assert z.shape == (1,) and H.shape == (1, 6) and R.shape == (1, 1)
    assert h[0] == pytest.approx(model.delta_p(x[:3], x[3:], np.array(2), instantaneous=False))
    assert R[0, 0] == pytest.approx(model.sigma_dp_s(np.array(2)) ** 2)
    z, h, H, R = model.measurement_rows(x, (2, 1e-4, 3.0))
    assert z.shape == (2,) and H.shape == (2, 6)
    assert h[1] == pytest.approx(np.linalg.norm(x[:3] - model.beacons.pos_m[2]))
    assert R[1, 1] == pytest.approx(model.sigma_m ** 2)
    assert model.measurement_rows(x, (-1, np.nan, np.nan)) is None
    assert model.measurement_rows(x, (2, np.nan, np.nan)) is None
    with pytest.raises(ValueError, match="beacon"):
        model.measurement_rows(x, (8, 1e-4, np.nan))


def test_the_model_module_imports_nothing_from_the_filters():
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(dm))
    names = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    names += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert not [n for n in names if "filters" in n], names


def test_distance_multiplies_by_the_speed_of_sound(model):
    assert model.distance_m(np.array([1e-4, 0.0]), np.zeros(2)) == pytest.approx(1e-4 * model.v_s_mps)


def test_invalid_models_are_rejected():
    with pytest.raises(ValueError, match="distinct"):
        dm.DopplerModel(dm.cubic_layout(), np.full(8, 0.5))
    with pytest.raises(ValueError, match="shape"):
        dm.DopplerModel(dm.cubic_layout(), np.ones(3))
    with pytest.raises(ValueError, match="lag"):
        dm.DopplerModel.for_layout(dm.cubic_layout(), lag=2.0)
    for name, value in (("v_s_mps", 0.0), ("sigma_t_s", -1e-5), ("sigma_model_mps", np.nan), ("lag", np.inf)):
        with pytest.raises(ValueError, match=name):
            dm.DopplerModel.for_layout(dm.cubic_layout(), **{name: value})
    with pytest.raises(ValueError, match="beacons"):
        dm.DopplerModel(np.zeros((8, 3)), dm.beacon_periods_s(8))
    with pytest.raises(ValueError, match="step_s"):
        dm.beacon_periods_s(8, step_s=-0.001)
    with pytest.raises(ValueError, match="sigma_acc_mps2"):
        ReceiverMotion(None)
    with pytest.raises(ValueError, match="sigma_acc_mps2"):
        ReceiverMotion((1.0, -1.0, 0.0))


def test_receiver_motion_matches_its_covariance():
    mot = ReceiverMotion()
    rng = np.random.default_rng(2)
    x0 = np.zeros((200_000, 6))
    x1 = mot.propagate(x0, 0.1, rng=rng)
    np.testing.assert_allclose(np.cov(x1.T), mot.Q(0.1), atol=5e-3 * np.abs(mot.Q(0.1)).max() + 1e-12, rtol=0.03)
    x = np.array([0, 0, 0, 1.0, 2.0, 0.5])
    np.testing.assert_allclose(mot.propagate(x, 0.5, rng=None), mot.F(0.5) @ x)
    # the one-step path equals the broadcast one, bit for bit
    for dt in (0.0, 0.07, 0.5):
        np.testing.assert_array_equal(mot.F(dt), mot.F(np.array([dt]))[0])
        np.testing.assert_array_equal(mot.Q(dt), mot.Q(np.array([dt]))[0])
