"""Two-way-ranging models: the NLOS mixture's analytic distribution and its persistent NLOS episodes."""

import numpy as np
import pytest

from uwbwb.models.ranging import NlosRangeModel, TwrRangeModel

ANCHORS = np.array([[4.0, 3.0, 4.0], [14.0, 3.0, 4.2], [22.0, 4.0, 4.5], [4.0, 13.0, 4.0], [14.0, 13.0, 4.2],
                    [22.0, 12.0, 4.5]])


def _model(*, rng, sigma_m=0.5, resolution_m=0.0, **kw) -> NlosRangeModel:
    los = TwrRangeModel(bias_m=rng.uniform(0.0, 0.5, (2, 6)), scale=np.ones((2, 6)), sigma_m=sigma_m,
                        resolution_m=resolution_m)
    return NlosRangeModel(los, ANCHORS, np.full(6, 7.0), **kw)


def test_error_distribution_is_the_model_mixture():
    rng = np.random.default_rng(3)
    model = _model(rng=rng, p_err_in=0.0, p_err_out=0.0, nlos_dwell_s=0.0)
    pos = np.broadcast_to(np.array([2.0, 14.0, 1.3]), (20000, 2, 6, 3))
    r, nlos = model.sample(pos, rng=rng)
    err = r[:, 0, 0] - np.linalg.norm(pos[0, 0, 0] - model.anchor_pos_m[0]) - model.los.bias_m[0, 0]
    p = float(model.p_nlos(pos[0, 0, 0])[0])
    assert nlos[:, 0, 0].mean() == pytest.approx(p, abs=0.015)
    for e in (-0.5, 0.0, 0.5, 2.0, 3.5):
        assert np.mean(err <= e) == pytest.approx(model.error_cdf(e, p), abs=0.015)
    q = model.error_quantile(0.05, p)
    assert model.error_cdf(q, p) == pytest.approx(0.05)
    x = np.linspace(-3, 8, 2001)
    assert np.trapezoid(model.error_pdf(x, p), x) == pytest.approx(1.0, abs=1e-3)


def test_nlos_is_likelier_outside_coverage_and_failures_follow():
    model = _model(rng=np.random.default_rng(1))
    inside, outside = np.array([4.0, 3.0, 1.3]), np.array([40.0, 40.0, 1.3])
    assert model.p_nlos(inside)[0] == pytest.approx(model.p_nlos_in, abs=1e-6)          # under anchor 0
    assert model.p_nlos(inside)[2] == pytest.approx(model.p_nlos_out, abs=1e-6)         # 18 m from anchor 2
    np.testing.assert_allclose(model.p_nlos(outside), model.p_nlos_out, atol=1e-6)
    assert model.p_err(outside)[0] == pytest.approx(model.p_err_out)


def test_nlos_episodes_last_the_dwell_time():
    rng = np.random.default_rng(4)
    model = _model(rng=rng, nlos_dwell_s=2.0, p_nlos_in=0.3, p_nlos_out=0.3)
    pos = np.broadcast_to(np.array([12.0, 8.0, 1.3]), (6000, 2, 6, 3))
    _, nlos = model.sample(pos, rng=rng, dt_s=0.13)
    s = nlos.reshape(6000, -1)
    assert s.mean() == pytest.approx(0.3, abs=0.04)
    starts = np.sum(s[1:] & ~s[:-1])
    mean_episode_s = s[1:].sum() / starts * 0.13
    assert mean_episode_s == pytest.approx(2.0, rel=0.15)


def test_bad_shapes_are_rejected():
    rng = np.random.default_rng(0)
    los = TwrRangeModel(bias_m=np.zeros((2, 5)), scale=np.ones((2, 5)))
    with pytest.raises(ValueError, match="one column per anchor"):
        NlosRangeModel(los, ANCHORS, np.full(6, 7.0))
    with pytest.raises(ValueError, match="pos_m must have shape"):
        _model(rng=rng).sample(np.zeros((3, 2, 5, 3)), rng=rng)


def test_one_two_way_range_model_serves_geometry_the_tdoa_model_and_the_bounds():
    from uwbwb import bounds, geometry
    from uwbwb.models import ranging
    from uwbwb.models.tdoa import TdoaModel
    assert geometry.ranges is ranging.ranges and geometry.range_jacobian is ranging.range_jacobian
    rng = np.random.default_rng(3)
    A = rng.uniform(0.0, 10.0, (5, 3))
    p = rng.uniform(0.0, 10.0, (7, 2))
    model = TdoaModel(A, 0.1, dim=2, z_m=1.2)
    np.testing.assert_array_equal(model.ranges(p), ranging.ranges(p, A, z_m=1.2))
    np.testing.assert_array_equal(model.unit_vectors(p), ranging.range_jacobian(p, A, z_m=1.2))
    J = ranging.range_jacobian(p, A, z_m=1.2)
    np.testing.assert_allclose(bounds.range_information(p, A, 0.1, z_m=1.2),
                               np.einsum("tni,tnj->tij", J, J) / 0.1 ** 2, rtol=1e-12)
    # the Jacobian is the derivative of the prediction
    h = 1e-6
    fd = (ranging.ranges(p + [h, 0.0], A, z_m=1.2) - ranging.ranges(p - [h, 0.0], A, z_m=1.2)) / (2 * h)
    np.testing.assert_allclose(J[..., 0], fd, atol=1e-8)
