import numpy as np
import pytest

from uwbwb.calibration import empirical_tdoa_covariance
from uwbwb.models.tdoa import TdoaModel
from uwbwb.types import pseudo_tdoa

ANCHORS = np.array([[0.0, 0.0, 2.0], [10.0, 0.0, 2.5], [10.0, 8.0, 2.0], [0.0, 8.0, 2.5],
                    [5.0, -1.0, 0.5], [5.0, 9.0, 1.0]])


def _fd_jacobian(model, pos, ref, eps=1e-6):
    J = np.empty((model.n_anchors, model.dim))
    for k in range(model.dim):
        e = np.zeros(model.dim)
        e[k] = eps
        J[:, k] = (model.h(pos + e, ref) - model.h(pos - e, ref)) / (2 * eps)
    return J


@pytest.mark.parametrize("dim,pos", [(2, [3.1, 4.7]), (2, [9.5, -0.5]), (3, [3.1, 4.7, 1.2]), (3, [7.0, 2.0, 0.1])])
@pytest.mark.parametrize("ref", [0, 3])
def test_jacobian_matches_finite_differences(dim, pos, ref):
    model = TdoaModel(ANCHORS, 0.1, dim=dim, z_m=1.3)
    pos = np.array(pos)
    np.testing.assert_allclose(model.jacobian(pos, ref), _fd_jacobian(model, pos, ref), atol=1e-8)


def test_h_and_jacobian_batched_with_per_epoch_reference():
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    pos = np.array([[1.0, 2.0], [5.0, 5.0], [8.0, 1.0]])
    ref = np.array([0, 2, 5])
    H = model.h(pos, ref)
    J = model.jacobian(pos, ref)
    assert H.shape == (3, 6) and J.shape == (3, 6, 2)
    for t in range(3):
        np.testing.assert_allclose(H[t], model.h(pos[t], ref[t]))
        np.testing.assert_allclose(J[t], model.jacobian(pos[t], ref[t]))
        assert H[t, ref[t]] == 0.0 and np.all(J[t, ref[t]] == 0.0)


def test_h_is_range_difference_including_height():
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    p = np.array([4.0, 3.0])
    r = np.linalg.norm(np.append(p, 1.0) - ANCHORS, axis=1)
    np.testing.assert_allclose(model.ranges(p), r)
    np.testing.assert_allclose(model.h(p, 1), r - r[1])


def test_covariance_equal_sigma_is_sigma2_I_plus_ones():
    model = TdoaModel(ANCHORS, 0.1)
    others = np.array([1, 2, 3, 4, 5])
    np.testing.assert_allclose(model.covariance(others, 0), 0.01 * (np.eye(5) + np.ones((5, 5))))
    uncorr = TdoaModel(ANCHORS, 0.1, correlated=False)
    np.testing.assert_allclose(uncorr.covariance(others, 0), 0.02 * np.eye(5))


def test_covariance_unequal_sigma_and_errors():
    sig = np.array([0.1, 0.2, 0.3, 0.1, 0.1, 0.5])
    model = TdoaModel(ANCHORS, sig)
    C = model.covariance([1, 5], 2)
    np.testing.assert_allclose(C, [[0.04 + 0.09, 0.09], [0.09, 0.25 + 0.09]])
    with pytest.raises(ValueError, match="reference"):
        model.covariance([1, 2], 2)
    with pytest.raises(ValueError, match="sigma_m"):
        TdoaModel(ANCHORS, 0.0)
    with pytest.raises(ValueError, match="anchor_pos_m"):
        TdoaModel(ANCHORS[:, :2])
    with pytest.raises(ValueError, match="coordinates"):
        TdoaModel(ANCHORS, dim=3).h(np.zeros(2), 0)


def test_pseudo_tdoa_covariance_matches_model(rng):
    # equal-sigma ranges -> TDoA errors have covariance sigma^2 (I + 11^T)
    model = TdoaModel(ANCHORS, 0.07, dim=2, z_m=1.0)
    T = 20000
    pos = np.array([4.0, 3.0])
    true_r = np.tile(model.ranges(pos), (T, 1))
    d, ref = pseudo_tdoa(true_r + 0.07 * rng.standard_normal(true_r.shape), 2)
    C = empirical_tdoa_covariance(d, np.tile(model.h(pos, 2), (T, 1)), 2)
    np.testing.assert_allclose(C, model.covariance([0, 1, 3, 4, 5], 2), atol=0.07 ** 2 * 0.06)


def test_epoch_terms_any_reference():
    model = TdoaModel(ANCHORS, 0.1, dim=2, z_m=1.0)
    p = np.array([4.0, 3.0])
    row = model.h(p, 0)
    row[4] = np.nan
    z, h, H, R, others = model.epoch(row, p, 3)
    np.testing.assert_array_equal(others, [0, 1, 2, 5])
    np.testing.assert_allclose(z, h, atol=1e-12)                      # exact data re-referenced to anchor 3
    np.testing.assert_allclose(H, model.jacobian(p, 3)[others])
    np.testing.assert_allclose(R, model.covariance(others, 3))
    with pytest.raises(ValueError, match="not among"):
        model.epoch(row, p, 4)


def test_triangle_outliers_rejects_injected_outliers_and_keeps_clean_ones(rng):
    from uwbwb.models.tdoa import triangle_outliers

    model = TdoaModel(ANCHORS[:4], 0.05, dim=2, z_m=0.3)
    pos = rng.uniform([1, 1], [9, 7], (500, 2))
    clean = model.h(pos, 0) + np.where(np.arange(4) == 0, 0.0, rng.normal(0, 0.05, (500, 4)))
    assert not triangle_outliers(clean, 0, model.anchor_pos_m, 0.2).any()
    dirty = clean.copy()
    bad = rng.random((500, 4)) < 0.1
    bad[:, 0] = False
    dirty[bad] += np.sign(rng.normal(size=bad.sum())) * 25.0   # gross multipath excess: beyond any baseline
    flagged = triangle_outliers(dirty, 0, model.anchor_pos_m, 0.2)
    np.testing.assert_array_equal(flagged, bad)
    # where it cannot help: a 0.5 m NLOS excess on a TDoA far from its bound passes
    mild = clean.copy()
    mild[:, 1] += 0.5
    centre = np.linalg.norm(pos - [5, 4], axis=1) < 1.5
    assert not triangle_outliers(mild[centre], 0, model.anchor_pos_m, 0.2).any()
    # NaN (missing) and the reference never flagged; per-row references respected
    row = np.array([[np.nan, 0.0, 30.0, 0.1]])
    np.testing.assert_array_equal(triangle_outliers(row, [1], model.anchor_pos_m, 0.0), [[False, False, True, False]])
    with pytest.raises(ValueError, match="anchor_pos_m"):
        triangle_outliers(row, 1, model.anchor_pos_m[:3], 0.0)
