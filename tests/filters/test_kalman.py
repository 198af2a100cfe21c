import numpy as np
import pytest

from uwbwb.filters import kalman
from uwbwb.filters.kalman import Gaussian, predict, update


def test_predict_is_FPFt_plus_Q():
    F = np.array([[1.0, 0.5], [0.0, 1.0]])
    Q = np.diag([0.01, 0.02])
    P = np.array([[2.0, 0.3], [0.3, 1.0]])
    out = predict(Gaussian([1.0, 2.0], P), F, Q)
    np.testing.assert_allclose(out.x, [2.0, 2.0])
    np.testing.assert_allclose(out.P, F @ P @ F.T + Q)


def test_linear_update_matches_hand_computation():
    P = np.array([[2.0, 0.3], [0.3, 1.0]])
    H = np.array([[1.0, 0.0]])
    R = np.array([[0.5]])
    post, inn = update(Gaussian([1.0, 2.0], P), [2.0], H, R)
    S = H @ P @ H.T + R
    K = P @ H.T / S
    np.testing.assert_allclose(post.x, np.array([1.0, 2.0]) + K[:, 0] * 1.0)
    IKH = np.eye(2) - K @ H
    np.testing.assert_allclose(post.P, IKH @ P @ IKH.T + K @ R @ K.T)
    assert inn.nis == pytest.approx(1.0 / S[0, 0])
    np.testing.assert_allclose(post.P, post.P.T)


def test_nonlinear_update_uses_h_of_x():
    # range measurement to an anchor at the origin from x = (3, 4): h = 5
    x = np.array([3.0, 4.0])
    H = (x / 5.0)[None]
    post, inn = update(Gaussian(x, np.eye(2)), [5.5], H, [[0.01]], h_x=[5.0])
    assert inn.y[0] == pytest.approx(0.5)
    assert np.linalg.norm(post.x) == pytest.approx(5.5, abs=0.01)


def test_shape_errors_are_clear():
    with pytest.raises(ValueError, match="do not fit"):
        update(Gaussian([0.0, 0.0], np.eye(2)), [1.0, 2.0], np.eye(2)[:1], [[1.0]])


@pytest.mark.parametrize("correlated", [False, True])
def test_sequential_update_equals_the_batch_update(correlated, rng):
    n, m = 7, 4
    A = rng.normal(size=(n, n))
    state = kalman.Gaussian(rng.normal(size=n), A @ A.T + np.eye(n))
    H = rng.normal(size=(m, n))
    R = np.diag(rng.uniform(0.1, 1.0, m))
    if correlated:
        R = R + 0.3
    z, h = rng.normal(size=m), rng.normal(size=m)
    batch, inn = kalman.update(state, z, H, R, h_x=h)
    seq, parts = kalman.update_sequential(state, z, H, R, h_x=h)
    np.testing.assert_allclose(seq.x, batch.x, atol=1e-10)
    np.testing.assert_allclose(seq.P, batch.P, atol=1e-10)
    assert parts.sum() == pytest.approx(inn.nis, rel=1e-10)
    with pytest.raises(ValueError, match="non-finite"):
        kalman.update_sequential(state, np.full(m, np.nan), H, R)
