import numpy as np
import pytest

from uwbwb.models.motion import (MOTION_MODELS, RandomForce, RandomJerk, RandomWalk, VelocityKick, make_motion_model,
                                 noise_1d, transition_1d)

DT = 0.5


def _hand_F(order, dt):
    return {1: np.array([[1.0]]),
            2: np.array([[1.0, dt], [0.0, 1.0]]),
            3: np.array([[1.0, dt, dt ** 2 / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])}[order]


def _hand_Q(order, dt):
    return {1: np.array([[dt]]),
            2: np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]]),
            3: np.array([[dt ** 5 / 20, dt ** 4 / 8, dt ** 3 / 6],
                         [dt ** 4 / 8, dt ** 3 / 3, dt ** 2 / 2],
                         [dt ** 3 / 6, dt ** 2 / 2, dt]])}[order]


@pytest.mark.parametrize("cls", [RandomWalk, RandomForce, RandomJerk])
@pytest.mark.parametrize("dim", [2, 3])
def test_F_and_Q_match_hand_derived_matrices(cls, dim):
    q = 0.7
    m = cls(q, dim=dim)
    n = cls.order
    # derivative-major layout: [p (dim), v (dim), a (dim)] -> F = F1 ⊗ I, Q = q Q1 ⊗ I
    np.testing.assert_allclose(m.F(DT), np.kron(_hand_F(n, DT), np.eye(dim)), rtol=1e-14)
    np.testing.assert_allclose(m.Q(DT), q * np.kron(_hand_Q(n, DT), np.eye(dim)), rtol=1e-14)
    assert m.F(DT).shape == (n * dim, n * dim) == (m.n_x, m.n_x)


def test_rj_transition_is_thesis_eq_17_per_axis():
    m = RandomJerk(1.0, dim=2)
    F = m.F(0.2)
    np.testing.assert_allclose(F[np.ix_([0, 2, 4], [0, 2, 4])], [[1, 0.2, 0.02], [0, 1, 0.2], [0, 0, 1]])
    np.testing.assert_allclose(F[np.ix_([0, 2, 4], [1, 3, 5])], 0.0)   # axes do not couple


@pytest.mark.parametrize("cls", [RandomWalk, RandomForce, RandomJerk])
def test_discretisation_is_consistent_over_split_steps(cls):
    # exact discretisation: F(a+b) = F(b)F(a) and Q(a+b) = F(b) Q(a) F(b)^T + Q(b)
    m = cls(1.3, dim=3)
    a, b = 0.13, 0.41
    np.testing.assert_allclose(m.F(a + b), m.F(b) @ m.F(a), atol=1e-14)
    np.testing.assert_allclose(m.Q(a + b), m.F(b) @ m.Q(a) @ m.F(b).T + m.Q(b), atol=1e-14)


@pytest.mark.parametrize("cls", [RandomWalk, RandomForce, RandomJerk])
def test_Q_symmetric_positive_definite_and_its_square_root(cls):
    m = cls(2.0, dim=2)
    for dt in (1e-3, 0.1, 2.0):
        Q = m.Q(dt)
        np.testing.assert_allclose(Q, Q.T)
        assert np.all(np.linalg.eigvalsh(Q) > 0)
        L = m.Q_sqrt(dt)
        np.testing.assert_allclose(L @ L.T, Q, rtol=1e-10, atol=1e-30)


def test_batched_step_lengths():
    m = RandomForce(0.5, dim=2)
    dt = np.array([0.1, 0.2, 0.3])
    assert m.F(dt).shape == (3, 4, 4) and m.Q(dt).shape == (3, 4, 4) and m.G(dt).shape == (3, 4, 2)
    for k in range(3):
        np.testing.assert_allclose(m.Q(dt)[k], m.Q(dt[k]))
        np.testing.assert_allclose(m.F(dt)[k], m.F(dt[k]))


def test_input_matrix():
    np.testing.assert_allclose(RandomWalk(dim=2).G(0.5), 0.5 * np.eye(2))
    np.testing.assert_allclose(RandomForce(dim=2).G(0.5), [[0.125, 0], [0, 0.125], [0.5, 0], [0, 0.5]])
    np.testing.assert_allclose(RandomJerk(dim=2).G(0.5)[::2, 0], [0.5 ** 3 / 6, 0.125, 0.5])


def test_low_level_blocks():
    np.testing.assert_allclose(transition_1d(2, 3.0), [[1, 3], [0, 1]])
    np.testing.assert_allclose(noise_1d(2, 3.0), [[9, 4.5], [4.5, 3]])


def test_sigma_convention_reproduces_thesis_random_walk():
    # thesis eq. 12: u_t = u_{t-1} + T w_v with std(w_v) = sigma -> Q = sigma^2 T^2 I
    m = RandomWalk.from_sigma(0.83, 0.1, dim=2)
    np.testing.assert_allclose(m.Q(0.1), 0.83 ** 2 * 0.1 ** 2 * np.eye(2))
    assert m.sigma(0.1) == pytest.approx(0.83)
    assert m.psd_m2ps == pytest.approx(0.83 ** 2 * 0.1)
    rf = make_motion_model("rf", sigma=1.0, dt_s=0.2, dim=3)
    assert isinstance(rf, RandomForce) and rf.dim == 3 and rf.psd == pytest.approx(0.2)


def test_units_and_labels():
    assert [MOTION_MODELS[k].psd_unit for k in ("RW", "RF", "RJ")] == ["m²/s", "m²/s³", "m²/s⁵"]
    assert RandomForce(dim=2).state_labels == ("x_m", "y_m", "vx_mps", "vy_mps")
    assert RandomJerk(dim=3).state_labels[-1] == "az_mps2"
    assert RandomWalk(dim=3).state_labels == ("x_m", "y_m", "z_m")
    assert "m²/s³" in str(RandomForce(0.25))
    assert RandomForce(0.25).with_psd(1.5).psd_m2ps3 == 1.5


def test_state_helpers():
    m = RandomJerk(dim=2)
    x = m.initial_state([1.0, 2.0], [3.0, 4.0])
    np.testing.assert_allclose(x, [1, 2, 3, 4, 0, 0])
    np.testing.assert_allclose(m.position(x), [1, 2])
    np.testing.assert_allclose(m.velocity(x), [3, 4])
    assert RandomWalk(dim=2).velocity(np.zeros(2)) is None
    np.testing.assert_allclose(np.diag(m.initial_covariance(2.0, 0.5, 0.1)), [4, 4, 0.25, 0.25, 0.01, 0.01])
    np.testing.assert_allclose(m.H_pos @ x, [1, 2])
    with pytest.raises(ValueError, match="expected"):
        m.initial_state([1.0, 2.0, 3.0])


@pytest.mark.parametrize("cls", [RandomWalk, RandomForce, RandomJerk])
def test_sample_path_noise_has_covariance_Q(cls):
    m = cls(0.8, dim=2)
    t = np.arange(4001) * 0.25
    x = m.sample_path(m.initial_state(np.zeros(2)), t, rng=np.random.default_rng(7))
    w = x[1:] - x[:-1] @ m.F(0.25).T
    C = np.cov(w, rowvar=False)
    Q = m.Q(0.25)
    # 4000 samples: relative standard error of a variance ~ 2.2 %; allow 10 %
    np.testing.assert_allclose(np.diag(C), np.diag(Q), rtol=0.10)
    corr = C / np.sqrt(np.outer(np.diag(C), np.diag(C)))
    corr_q = Q / np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    np.testing.assert_allclose(corr, corr_q, atol=0.06)


def test_sample_path_with_input_and_reproducibility():
    m = RandomForce(0.0, dim=2)
    t = np.arange(11) * 0.1
    u = np.tile([1.0, 0.0], (10, 1))                 # constant 1 m/s² along x, no noise
    x = m.sample_path(m.initial_state([0, 0]), t, rng=np.random.default_rng(0), u=u)
    np.testing.assert_allclose(x[-1], [0.5, 0.0, 1.0, 0.0], atol=1e-12)
    m2 = RandomForce(0.3, dim=2)
    a = m2.sample_path(m2.initial_state([0, 0]), t, rng=np.random.default_rng(3))
    b = m2.sample_path(m2.initial_state([0, 0]), t, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)


def test_bad_parameters():
    with pytest.raises(ValueError, match="dim"):
        RandomWalk(0.1, dim=4)
    with pytest.raises(ValueError, match="psd_m2ps3"):
        RandomForce(-1.0)
    with pytest.raises(ValueError, match="unknown motion model"):
        make_motion_model("CV", sigma=1.0, dt_s=0.1)
    with pytest.raises(ValueError, match="dt_s"):
        RandomJerk.from_sigma(1.0, 0.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        RandomWalk().sample_path(np.zeros(2), np.array([0.0, 0.0]), rng=np.random.default_rng(0))


# --------------------------------------------------------------------------- velocity kick (paper 000, eq. 3)

def test_velocity_kick_matrices_are_eq3():
    m = VelocityKick(0.3)
    assert m.state_labels == ("x_m", "y_m", "vx_mps", "vy_mps")
    F = m.F(0.5)
    np.testing.assert_array_equal(F, [[1, 0, 0.5, 0], [0, 1, 0, 0.5], [0, 0, 1, 0], [0, 0, 0, 1]])
    np.testing.assert_array_equal(m.Q(0.5), np.diag([0.0, 0.0, 0.09, 0.09]))
    np.testing.assert_array_equal(m.Q(np.array([0.1, 2.0])), np.broadcast_to(np.diag([0, 0, 0.09, 0.09]), (2, 4, 4)))
    assert m.F(np.array([0.1, 0.2])).shape == (2, 4, 4)
    np.testing.assert_array_equal(m.H_pos @ m.initial_state([1.0, 2.0], [3.0, 4.0]), [1.0, 2.0])
    with pytest.raises(ValueError):
        VelocityKick(-0.1)


def test_velocity_kick_step_moves_with_old_velocity_then_kicks():
    m = VelocityKick(0.3)
    x = np.tile(m.initial_state([1.0, 2.0], [0.5, -0.25]), (20000, 1))
    y = m.step(x, 0.2, rng=np.random.default_rng(0))
    np.testing.assert_allclose(y[:, :2], [[1.1, 1.95]] * 20000)
    np.testing.assert_allclose(y[:, 2:].mean(0), [0.5, -0.25], atol=0.01)
    np.testing.assert_allclose(y[:, 2:].std(0), 0.3, rtol=0.03)
    # the sample covariance of one step is F P F' + Q with P = 0
    np.testing.assert_allclose(np.cov((y - m.F(0.2) @ x[0]).T), m.Q(0.2), atol=0.005)
    np.testing.assert_array_equal(m.step(x, 0.2, rng=np.random.default_rng(0)), y)
