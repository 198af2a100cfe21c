import numpy as np
import pytest

from uwbwb.models import doppler as dm
from uwbwb.models import motion as mm
from uwbwb.models.layout import KinematicModel, StateLayout

FAMILY = [mm.RandomWalk(0.07, dim=2), mm.RandomForce(0.1, dim=3), mm.RandomJerk(0.1, dim=2),
          mm.VelocityKick(0.3, dim=2), mm.ReceiverMotion((2.0, 1.0, 0.2))]
DT = np.array([0.1, 0.05, 0.3])


def test_layouts_name_every_component_with_its_unit():
    assert mm.RandomWalk(dim=3).layout.labels == ("x_m", "y_m", "z_m")
    assert mm.RandomForce().layout.labels == ("x_m", "y_m", "vx_mps", "vy_mps")
    assert mm.RandomJerk().layout.labels == ("x_m", "y_m", "vx_mps", "vy_mps", "ax_mps2", "ay_mps2")
    assert mm.VelocityKick(dim=3).layout.labels == ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
    assert mm.ReceiverMotion().layout == StateLayout(("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps"), 3)
    assert mm.RandomWalk().layout.vel_index is None
    assert mm.RandomJerk().layout.pos_index == (0, 1) and mm.RandomJerk().layout.vel_index == (2, 3)
    assert mm.ReceiverMotion().layout.vel_index == (3, 4, 5)
    for m in FAMILY:
        assert m.state_labels == m.layout.labels and m.layout.n_x == m.n_x
        np.testing.assert_array_equal(m.layout.pos_index, np.arange(m.layout.dim))   # derivative-major


def test_layout_rejects_what_is_not_a_kinematic_state():
    with pytest.raises(ValueError, match="not kinematic labels"):
        StateLayout(("x_m", "y_m", "speed"), 2)
    with pytest.raises(ValueError, match="missing"):
        StateLayout(("x_m", "vx_mps", "vy_mps"), 2)
    with pytest.raises(ValueError, match="distinct"):
        StateLayout(("x_m", "x_m"), 1)
    with pytest.raises(ValueError, match="not kinematic labels"):
        StateLayout(("x_m", "y_m", "z_m"), 2)


@pytest.mark.parametrize("model", FAMILY, ids=lambda m: type(m).__name__)
def test_every_member_follows_the_family_protocol(model):
    assert isinstance(model, KinematicModel)
    F, Q = model.F(DT), model.Q(DT)
    assert F.shape == Q.shape == (3, model.n_x, model.n_x)
    for k, dt in enumerate(DT):
        np.testing.assert_allclose(model.F(float(dt)), F[k], rtol=1e-15, atol=0)
        np.testing.assert_allclose(model.Q(float(dt)), Q[k], rtol=1e-15, atol=0)
    np.testing.assert_allclose(Q, np.swapaxes(Q, -1, -2), rtol=0, atol=0)
    x0 = np.arange(model.n_x, dtype=float)
    t = np.array([0.0, 0.1, 0.25, 0.3])
    a = model.sample_path(x0, t, rng=np.random.default_rng(5))
    b = model.sample_path(x0, t, rng=np.random.default_rng(5))
    assert a.shape == (4, model.n_x)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a[0], x0)
    with pytest.raises(ValueError, match="increasing"):
        model.sample_path(x0, t[::-1], rng=np.random.default_rng(5))


@pytest.mark.parametrize("model", FAMILY, ids=lambda m: type(m).__name__)
def test_a_step_has_mean_F_x_and_covariance_Q(model):
    x0 = np.linspace(-1.0, 1.0, model.n_x)
    x = model.step(np.broadcast_to(x0, (100_000, model.n_x)), 0.2, rng=np.random.default_rng(2))
    np.testing.assert_allclose(x.mean(axis=0), model.F(0.2) @ x0, atol=0.01)
    Q = model.Q(0.2)
    se = np.sqrt(np.outer(np.diag(Q), np.diag(Q)) + Q ** 2) / np.sqrt(len(x))   # standard error of each entry
    assert np.all(np.abs(np.cov(x.T) - Q) <= 5 * se + 1e-15)


def test_receiver_motion_is_one_class_and_its_step_is_propagate():
    mot = mm.ReceiverMotion()
    x = np.random.default_rng(1).standard_normal((7, 6))
    dt = np.linspace(0.4, 0.6, 7)
    np.testing.assert_array_equal(mot.step(x, dt, rng=np.random.default_rng(9)),
                                  mot.propagate(x, dt, rng=np.random.default_rng(9)))
    t = np.cumsum(np.r_[0.0, dt])
    path, rng, want = mot.sample_path(x[0], t, rng=np.random.default_rng(3)), np.random.default_rng(3), [x[0]]
    for d in np.diff(t):
        want.append(mot.propagate(want[-1], d, rng=rng))
    np.testing.assert_array_equal(path, np.array(want))


def test_motion_model_step_without_noise_is_the_transition():
    rf = mm.RandomForce(0.5, dim=2)
    x = np.random.default_rng(0).standard_normal((3, 4))
    np.testing.assert_array_equal(rf.step(x, DT, rng=None), np.einsum("tij,tj->ti", rf.F(DT), x))


def test_layout_sizes_must_be_the_integers_one_two_three():
    for args in ((4, 2), (2, 4), (2.0, 2), (2, True)):
        with pytest.raises(ValueError, match="must be 1, 2 or 3"):
            StateLayout.kinematic(*args)
    for dim in (2.0, True, 0):
        with pytest.raises(ValueError, match="StateLayout.dim"):
            StateLayout(("x_m", "y_m"), dim)
    assert StateLayout.kinematic(1, 2).labels == ("x_m", "vx_mps")


def test_velocity_kick_without_rng_moves_without_a_kick():
    kick = mm.VelocityKick(0.5)
    x = np.array([[1.0, 2.0, 0.3, -0.4]])
    np.testing.assert_array_equal(kick.step(x, 2.0, rng=None), [[1.6, 1.2, 0.3, -0.4]])
