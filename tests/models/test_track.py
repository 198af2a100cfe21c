"""The eq. (1) range model of a straight constant-velocity track: analytic derivatives and parameters."""

import numpy as np
import pytest

from uwbwb.models.track import LinearTrackRanges
from uwbwb.types import RangeLog, RangeSamples

XY = np.array([[1.0, 1.0], [12.0, 0.5], [18.0, 6.0], [14.0, 11.0], [3.0, 10.0], [8.0, 5.0]])
CEILING = np.column_stack([XY, 3.9 + 0.6 * XY[:, 0] / 18.0])


def _samples(rng, P0=(4.0, 3.0, 1.3), v=(0.7, 0.4, 0.0), sigma_m=0.2):
    t = np.arange(0.0, 10.0, 0.13)
    pos = np.asarray(P0) + np.outer(t, v)
    r = np.linalg.norm(pos[:, None] - CEILING, axis=-1) + sigma_m * rng.standard_normal((t.size, len(CEILING)))
    return RangeSamples.from_ranges(RangeLog(t, r, tuple(str(i + 1) for i in range(len(CEILING)))))


def _fd_grad(f, x, h=1e-6):
    g = np.zeros_like(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        g[i] = (f(x + e) - f(x - e)) / (2 * h)
    return g


@pytest.mark.parametrize("dim, static", [(3, False), (3, True), (2, False), (2, True)])
def test_gradient_and_jacobian_match_finite_differences(rng, dim, static):
    s = _samples(rng)
    model = LinearTrackRanges(CEILING, dim, static, 1.3 if dim == 2 else None)
    n = model.n_params
    assert n == dim * (1 if static else 2)
    theta = rng.normal(0, 1, n) + np.r_[[5.0, 4.0, 1.0][:dim], [0.5, 0.2, 0.1][:dim]][:n]
    f, g = model.objective(theta, s)
    np.testing.assert_allclose(g, _fd_grad(lambda x: model.objective(x, s)[0], theta), rtol=1e-6, atol=1e-5)
    J = model.jacobian(theta, s)
    J_fd = np.column_stack([_fd_grad(lambda x, m=m: model.residuals(x, s)[m], theta) for m in range(len(s))]).T
    np.testing.assert_allclose(J, J_fd, rtol=1e-6, atol=1e-7)
    r = model.residuals(theta, s)
    assert f == pytest.approx(r @ r)


def test_exact_track_has_zero_residuals_and_time_origin_moves_p():
    s = _samples(np.random.default_rng(0), sigma_m=0.0)
    model = LinearTrackRanges(CEILING)
    theta = model.pack([4.0, 3.0, 1.3], [0.7, 0.4, 0.0])
    np.testing.assert_allclose(model.residuals(theta, s), 0.0, atol=1e-12)
    moved = model.pack(np.array([4.0, 3.0, 1.3]) + 2.0 * np.array([0.7, 0.4, 0.0]), [0.7, 0.4, 0.0])
    np.testing.assert_allclose(model.residuals(moved, s, t0_s=2.0), 0.0, atol=1e-12)
    P, v = LinearTrackRanges(CEILING, dim=2, z_m=1.3).unpack([4.0, 3.0, 0.7, 0.4])
    np.testing.assert_array_equal(P, [4.0, 3.0, 1.3])
    np.testing.assert_array_equal(v, [0.7, 0.4, 0.0])


def test_bad_parameters():
    s = _samples(np.random.default_rng(1))
    with pytest.raises(ValueError, match="theta"):
        LinearTrackRanges(CEILING).objective(np.zeros(4), s)
    with pytest.raises(ValueError, match="z_m"):
        LinearTrackRanges(CEILING, dim=2)
    with pytest.raises(ValueError, match="dim"):
        LinearTrackRanges(CEILING, dim=4)
    with pytest.raises(ValueError, match="anchors"):
        LinearTrackRanges(CEILING[:, :2])
    with pytest.raises(ValueError, match="anchors"):
        LinearTrackRanges(CEILING[:5]).residuals(np.zeros(6), s)
