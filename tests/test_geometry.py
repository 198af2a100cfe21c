import numpy as np
import pandas as pd
import pytest

import uwbwb as uw
from uwbwb import geometry as geo
from uwbwb.geometry import Status

# A 10 m x 8 m room with anchors at mixed heights (not coplanar, so 3-D works too).
ANCHORS = np.array([[0.0, 0.0, 2.5], [10.0, 0.0, 2.4], [10.0, 8.0, 2.6], [0.0, 8.0, 2.5],
                    [5.0, -1.0, 1.0], [11.0, 4.0, 0.5], [5.0, 9.0, 2.0], [-1.0, 4.0, 1.5]])


def _tags(rng, T):
    xy = np.column_stack([rng.uniform(1, 9, T), rng.uniform(1, 7, T)])
    return xy, rng.uniform(0.5, 1.5, T)


def _drop(rng, r, p, keep):
    """Set a fraction p of ranges to NaN, keeping at least `keep` per epoch."""
    r = r.copy()
    drop = rng.random(r.shape) < p
    drop[:, :keep] = False
    r[drop] = np.nan
    return r


# --------------------------------------------------------------------------- ranges / TDoA


def test_ranges_hand_values():
    A = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    assert geo.ranges([3.0, 4.0, 0.0], A) == pytest.approx([5.0, 4.0, np.sqrt(29.0)])
    assert geo.ranges([3.0, 4.0], A, z_m=12.0) == pytest.approx([13.0, np.hypot(4, 12), np.hypot(5, 10)])
    planar = geo.ranges([[3.0, 4.0], [0.0, 0.0]], A[:, :2])
    np.testing.assert_allclose(planar, [[5.0, 4.0, 5.0], [0.0, 3.0, 0.0]])


def test_ranges_batch_shapes_and_per_epoch_height(rng):
    pos = rng.normal(size=(2, 5, 2))
    z = rng.normal(size=(2, 5))
    r = geo.ranges(pos, ANCHORS, z_m=z)
    assert r.shape == (2, 5, len(ANCHORS))
    full = np.concatenate([pos, z[..., None]], axis=-1)
    np.testing.assert_allclose(r, geo.ranges(full, uw.Anchors(tuple("abcdefgh"), ANCHORS)))


@pytest.mark.parametrize("pos, kw", [([1.0, 2.0], {}), ([1.0, 2.0, 3.0], {"z_m": 1.0}),
                                     ([1.0], {}), ([1.0, 2.0], {"z_m": [1.0, 2.0, 3.0]})])
def test_ranges_bad_input(pos, kw):
    with pytest.raises(ValueError):
        geo.ranges(pos, ANCHORS, **kw)


def test_yaw_rotation_turns_about_z_and_broadcasts():
    R = geo.yaw_rotation(np.pi / 2)
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.5], [0.0, 1.0, 0.5], atol=1e-12)
    Rs = geo.yaw_rotation(np.array([[0.0, 0.3], [1.0, -2.0]]))
    assert Rs.shape == (2, 2, 3, 3)
    np.testing.assert_allclose(Rs @ np.swapaxes(Rs, -1, -2), np.broadcast_to(np.eye(3), Rs.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(Rs), 1.0)


# --------------------------------------------------------------------------- Jacobian / GDOP


@pytest.mark.parametrize("dim", [2, 3])
def test_range_jacobian_matches_finite_differences(rng, dim):
    pos = rng.uniform(0, 8, size=(6, dim))
    kw = {"z_m": rng.uniform(0, 2, 6)} if dim == 2 else {}
    J = geo.range_jacobian(pos, ANCHORS, **kw)
    assert J.shape == (6, len(ANCHORS), dim)
    h = 1e-6
    for k in range(dim):
        dp = np.zeros(dim)
        dp[k] = h
        fd = (geo.ranges(pos + dp, ANCHORS, **kw) - geo.ranges(pos - dp, ANCHORS, **kw)) / (2 * h)
        np.testing.assert_allclose(J[..., k], fd, atol=1e-8)


def test_gdop_hand_cases():
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    # Unit vectors (+-1, +-1)/sqrt(2): H^T H = 2 I, GDOP = sqrt(1/2 + 1/2) = 1.
    assert geo.gdop([5.0, 5.0], square) == pytest.approx(1.0)
    # Same square at the tag's height, 3-D anchors, 2-D solve with known height.
    square3 = np.column_stack([square, np.full(4, 1.2)])
    assert geo.gdop([5.0, 5.0], square3, z_m=1.2) == pytest.approx(1.0)
    assert geo.gdop([5.0, 5.0, 1.2], square3, dim=2) == pytest.approx(1.0)
    # Octahedron around the tag: H^T H = 2 I (3-D), GDOP = sqrt(3/2).
    octa = np.vstack([np.eye(3), -np.eye(3)]) * 4.0
    assert geo.gdop(np.zeros(3), octa) == pytest.approx(np.sqrt(1.5))
    # Only two anchors of the square (mask), tag on their line: singular.
    assert geo.gdop([5.0, 0.0], square, mask=np.array([True, True, False, False])) == np.inf
    assert geo.gdop([3.0, 0.0], square[:2]) == np.inf


def test_gdop_batch_shape(rng):
    pos = rng.uniform(1, 9, size=(3, 4, 3))
    assert geo.gdop(pos, ANCHORS).shape == (3, 4)
    assert geo.gdop(pos, ANCHORS, dim=2).shape == (3, 4)
    assert np.all(geo.gdop(pos, ANCHORS, dim=2) < geo.gdop(pos, ANCHORS))   # knowing z helps


# --------------------------------------------------------------------------- multilateration


def test_noise_free_2d_exact_with_missing_ranges(rng):
    xy, z = _tags(rng, 500)
    r = _drop(rng, geo.ranges(xy, ANCHORS, z_m=z), 0.3, keep=3)
    res = geo.multilaterate(r, ANCHORS, dim=2, z_m=z)
    assert res.ok.all()
    np.testing.assert_allclose(res.pos_m, xy, atol=1e-7)
    np.testing.assert_array_equal(res.n_used, np.isfinite(r).sum(axis=1))
    assert np.max(res.residual_rms_m) < 1e-7
    np.testing.assert_allclose(geo.linear_multilaterate(r, ANCHORS, dim=2, z_m=z), xy, atol=1e-7)


def test_noise_free_3d_exact_with_missing_ranges(rng):
    xy, z = _tags(rng, 500)
    p = np.column_stack([xy, z])
    r = _drop(rng, geo.ranges(p, ANCHORS), 0.3, keep=4)
    res = geo.multilaterate(r, ANCHORS, dim=3)
    assert res.ok.all()
    np.testing.assert_allclose(res.pos_m, p, atol=1e-7)
    np.testing.assert_allclose(geo.linear_multilaterate(r, ANCHORS, dim=3), p, atol=1e-7)


def test_planar_anchors_without_height():
    A = np.array([[0.0, 0.0], [6.0, 0.0], [0.0, 5.0]])
    r = geo.ranges(np.array([[2.0, 1.0], [4.0, 3.0]]), A)
    res = geo.multilaterate(r, A, dim=2)
    np.testing.assert_allclose(res.pos_m, [[2.0, 1.0], [4.0, 3.0]], atol=1e-9)


@pytest.mark.parametrize("dim, sigma", [(2, 0.05), (2, np.array([0.02, 0.05, 0.1, 0.03, 0.08, 0.05, 0.04, 0.06])),
                                        (3, 0.03)])
def test_covariance_consistent_with_scatter(dim, sigma):
    rng = np.random.default_rng(2024)
    T = 4000
    xy, z = _tags(rng, T)
    p = xy if dim == 2 else np.column_stack([xy, z])
    kw = {"z_m": z} if dim == 2 else {}
    r_true = geo.ranges(p, ANCHORS, **kw)
    r = _drop(rng, r_true + np.broadcast_to(sigma, r_true.shape[1:]) * rng.standard_normal(r_true.shape),
              0.2, keep=dim + 2)
    res = geo.multilaterate(r, ANCHORS, dim=dim, sigma_m=sigma, **kw)
    assert res.ok.all()
    err = res.pos_m - p
    nees = np.einsum("ti,tij,tj->t", err, np.linalg.inv(res.cov_m2), err)
    # Mean NEES ~ dim; its sampling s.d. is sqrt(2 dim / T) ~ 0.03.
    assert nees.mean() == pytest.approx(dim, rel=0.08)
    # ~95 % of a chi2(dim) sample lies below the 95 % point.
    q95 = {2: 5.991, 3: 7.815}[dim]
    assert np.mean(nees < q95) == pytest.approx(0.95, abs=0.015)


def test_estimated_sigma_is_pooled_residual_sigma():
    rng = np.random.default_rng(11)
    xy, z = _tags(rng, 3000)
    r_true = geo.ranges(xy, ANCHORS, z_m=z)
    r = r_true + 0.04 * rng.standard_normal(r_true.shape)
    res = geo.multilaterate(r, ANCHORS, dim=2, z_m=z)
    assert res.sigma_estimated
    assert res.sigma_m == pytest.approx(0.04, rel=0.03)
    given = geo.multilaterate(r, ANCHORS, dim=2, z_m=z, sigma_m=res.sigma_m)
    np.testing.assert_allclose(given.cov_m2, res.cov_m2, rtol=1e-9)
    np.testing.assert_allclose(given.pos_m, res.pos_m, atol=1e-9)
    # With equal sigma, cov = sigma^2 (J^T J)^-1, so GDOP = sqrt(trace(cov)) / sigma.
    np.testing.assert_allclose(res.gdop, np.sqrt(np.trace(res.cov_m2, axis1=1, axis2=2)) / res.sigma_m)
    np.testing.assert_allclose(res.gdop, geo.gdop(res.pos_m, ANCHORS, z_m=z), rtol=1e-9)


def test_gauss_newton_and_least_squares_agree(rng):
    xy, z = _tags(rng, 60)
    p = np.column_stack([xy, z])
    for dim, kw, truth in ((2, {"z_m": z}, xy), (3, {}, p)):
        r_true = geo.ranges(truth, ANCHORS, **kw)
        r = _drop(rng, r_true + 0.1 * rng.standard_normal(r_true.shape), 0.2, keep=dim + 1)
        gn = geo.multilaterate(r, ANCHORS, dim=dim, **kw)
        ls = geo.multilaterate(r, ANCHORS, dim=dim, method="least_squares", **kw)
        assert gn.ok.all() and ls.ok.all()
        np.testing.assert_allclose(gn.pos_m, ls.pos_m, atol=1e-6)
        np.testing.assert_allclose(gn.cov_m2, ls.cov_m2, rtol=1e-4, atol=1e-12)
        assert ls.method == "least_squares"
    # Per-anchor sigma: both minimise the same weighted cost.
    sigma = np.linspace(0.02, 0.2, len(ANCHORS))
    r = geo.ranges(xy, ANCHORS, z_m=z) + sigma * rng.standard_normal((60, len(ANCHORS)))
    gn = geo.multilaterate(r, ANCHORS, z_m=z, sigma_m=sigma)
    ls = geo.multilaterate(r, ANCHORS, z_m=z, sigma_m=sigma, method="least_squares")
    np.testing.assert_allclose(gn.pos_m, ls.pos_m, atol=1e-6)
    unweighted = geo.multilaterate(r, ANCHORS, z_m=z)
    assert np.max(np.abs(unweighted.pos_m - gn.pos_m)) > 1e-3   # the weights matter
    assert geo.multilaterate(r, ANCHORS, z_m=z, sigma_m=0.1).sigma_m == 0.1


def test_robust_loss_resists_an_outlier(rng):
    xy, z = _tags(rng, 30)
    r = geo.ranges(xy, ANCHORS, z_m=z) + 0.02 * rng.standard_normal((30, len(ANCHORS)))
    r[:, 2] += 3.0   # one anchor in NLOS: +3 m
    plain = geo.multilaterate(r, ANCHORS, z_m=z, method="least_squares")
    robust = geo.multilaterate(r, ANCHORS, z_m=z, method="least_squares", loss="soft_l1", f_scale=0.1)
    e_plain = np.linalg.norm(plain.pos_m - xy, axis=1)
    e_robust = np.linalg.norm(robust.pos_m - xy, axis=1)
    assert np.median(e_robust) < 0.3 * np.median(e_plain)
    with pytest.raises(ValueError, match="least_squares"):
        geo.multilaterate(r, ANCHORS, z_m=z, loss="soft_l1")


def test_degenerate_and_too_few_are_reported_not_raised():
    line = np.array([[0.0, 0.0, 2.0], [5.0, 0.0, 2.5], [10.0, 0.0, 1.0], [15.0, 0.0, 2.0]])
    xy = np.array([[3.0, 4.0], [7.0, -2.0]])
    r = geo.ranges(xy, line, z_m=1.0)
    res = geo.multilaterate(r, line, dim=2, z_m=1.0)
    assert list(res.status_labels) == ["degenerate", "degenerate"]
    assert np.all(np.isnan(res.pos_m)) and np.all(np.isnan(res.cov_m2)) and np.all(np.isnan(res.gdop))
    # A start point picks the mirror side of the line.
    res = geo.multilaterate(r, line, dim=2, z_m=1.0, x0=[5.0, 1.0])
    np.testing.assert_allclose(res.pos_m, [[3.0, 4.0], [7.0, 2.0]], atol=1e-7)

    # Mixed batch: all ranges / two ranges / three ranges from anchors on the line y = 0.
    A = np.vstack([ANCHORS, [5.0, 0.0, 1.8]])
    r = np.tile(geo.ranges([4.0, 3.0], A, z_m=1.0), (3, 1))
    r[1, 2:] = np.nan
    r[2, 2:8] = np.nan
    res = geo.multilaterate(r, A, dim=2, z_m=1.0)
    assert list(res.status_labels) == ["ok", "too_few", "degenerate"]
    assert res.counts() == {"ok": 1, "too_few": 1, "degenerate": 1, "not_converged": 0}
    np.testing.assert_array_equal(res.n_used, [9, 2, 3])
    assert np.isfinite(res.pos_m[0]).all() and np.isnan(res.pos_m[1:]).all()
    assert geo.multilaterate(r[:1], A, dim=2, z_m=1.0, min_anchors=9).status[0] == Status.OK
    r8 = r[:1].copy()
    r8[0, 3] = np.nan
    assert geo.multilaterate(r8, A, dim=2, z_m=1.0, min_anchors=9).status[0] == Status.TOO_FEW


def test_coplanar_anchors_in_3d():
    flat = np.array([[0.0, 0.0, 2.5], [10.0, 0.0, 2.5], [10.0, 8.0, 2.5], [0.0, 8.0, 2.5], [5.0, 4.0, 2.5]])
    p = np.array([[3.0, 4.0, 1.0], [7.0, 2.0, 0.5], [5.0, 5.0, 2.5]])   # the last one in the plane
    r = geo.ranges(p, flat)
    assert list(geo.multilaterate(r, flat, dim=3).status_labels) == ["degenerate"] * 3
    res = geo.multilaterate(r, flat, dim=3, x0=[5.0, 4.0, 0.0])
    assert list(res.status_labels[:2]) == ["ok", "ok"]
    np.testing.assert_allclose(res.pos_m[:2], p[:2], atol=1e-7)
    res = geo.multilaterate(r[2:], flat, dim=3, x0=[5.0, 4.0, 2.5])
    assert res.status[0] == Status.DEGENERATE
    assert np.all(np.isnan(geo.linear_multilaterate(r, flat, dim=3)))


def test_multilaterate_one():
    xy = np.array([4.0, 3.0])
    r = geo.ranges(xy, ANCHORS, z_m=1.0)
    np.testing.assert_allclose(geo.multilaterate_one(r, ANCHORS, z_m=1.0), xy, atol=1e-9)
    few = np.where(np.arange(8) < 2, r, np.nan)
    with pytest.raises(uw.GeometryError, match="only 2 of 8 ranges.*at least 3"):
        geo.multilaterate_one(few, ANCHORS, z_m=1.0)
    line = np.array([[0.0, 0.0, 2.0], [5.0, 0.0, 2.5], [10.0, 0.0, 1.0]])
    with pytest.raises(uw.GeometryError, match="collinear.*mirror"):
        geo.multilaterate_one(geo.ranges(xy, line, z_m=1.0), line, z_m=1.0)
    flat = np.column_stack([ANCHORS[:, :2], np.full(8, 2.0)])
    with pytest.raises(uw.GeometryError, match="coplanar.*plane"):
        geo.multilaterate_one(geo.ranges([4.0, 3.0, 2.0], flat), flat, dim=3, x0=[5.0, 4.0, 2.0])
    with pytest.raises(ValueError):
        geo.multilaterate_one(r[None], ANCHORS, z_m=1.0)


def test_not_converged_is_reported(rng):
    xy, z = _tags(rng, 20)
    r = geo.ranges(xy, ANCHORS, z_m=z) + 0.1 * rng.standard_normal((20, 8))
    res = geo.multilaterate(r, ANCHORS, z_m=z, x0=[50.0, 50.0], max_iter=1)
    assert np.all(res.status == Status.NOT_CONVERGED)
    assert np.all(np.isnan(res.pos_m))
    assert geo.multilaterate(r, ANCHORS, z_m=z, x0=[50.0, 50.0]).ok.all()
    with pytest.raises(uw.GeometryError, match="did not converge"):
        geo.multilaterate_one(r[0], ANCHORS, z_m=z[0], x0=[50.0, 50.0], max_iter=1)


def test_scalar_and_per_epoch_height_agree(rng):
    xy, _ = _tags(rng, 50)
    r = geo.ranges(xy, ANCHORS, z_m=1.1) + 0.02 * rng.standard_normal((50, 8))
    a = geo.multilaterate(r, ANCHORS, z_m=1.1)
    b = geo.multilaterate(r, ANCHORS, z_m=np.full(50, 1.1))
    np.testing.assert_allclose(a.pos_m, b.pos_m)


def test_result_containers(rng):
    xy, z = _tags(rng, 5)
    r = geo.ranges(xy, ANCHORS, z_m=z)
    r[2, 1:] = np.nan
    res = geo.multilaterate(r, ANCHORS, z_m=z)
    t = np.arange(5) * 0.1
    tr = res.to_trajectory(t, name="LS")
    assert isinstance(tr, uw.Trajectory) and len(tr) == 4 and tr.name == "LS"
    np.testing.assert_allclose(tr.t_s, t[[0, 1, 3, 4]])
    df = res.to_frame(t)
    assert isinstance(df, pd.DataFrame) and len(df) == 5
    assert list(df.columns) == ["t_s", "x_m", "y_m", "var_x_m2", "var_y_m2", "cov_xy_m2", "gdop", "n_used",
                                "residual_rms_m", "status"]
    assert df["status"].tolist() == ["ok", "ok", "too_few", "ok", "ok"]
    with pytest.raises(ValueError):
        res.pos_m[0, 0] = 1.0
    with pytest.raises(ValueError):
        res.to_frame(t[:3])
    assert res.dim == 2 and len(res) == 5


@pytest.mark.parametrize("kwargs", [
    {"dim": 4}, {"dim": 2},                     # dim=2 with 3-D anchors needs z_m
    {"dim": 3, "z_m": 1.0}, {"dim": 2, "z_m": 1.0, "min_anchors": 2},
    {"dim": 2, "z_m": 1.0, "method": "newton"}, {"dim": 2, "z_m": 1.0, "sigma_m": -1.0},
    {"dim": 2, "z_m": 1.0, "x0": [1.0, 2.0, 3.0]}, {"dim": 2, "z_m": [1.0, 2.0]},
    {"dim": 2, "z_m": 1.0, "max_iter": 0},
])
def test_bad_parameters(kwargs):
    r = geo.ranges(np.array([[4.0, 3.0, 1.0]] * 3), ANCHORS)
    with pytest.raises(ValueError):
        geo.multilaterate(r, ANCHORS, **kwargs)


def test_bad_ranges():
    r = geo.ranges(np.array([[4.0, 3.0, 1.0]] * 3), ANCHORS)
    for bad in (r[:, :5], r[0], np.where(r > 5, -1.0, r), np.where(r > 5, np.inf, r)):
        with pytest.raises(ValueError):
            geo.multilaterate(bad, ANCHORS, dim=3)


def test_to_estimates_marks_failed_epochs_and_keeps_covariances(rng):
    A = ANCHORS
    pos = rng.uniform(1, 7, size=(5, 2))
    r = geo.ranges(pos, A, z_m=1.0)
    r[2, 1:] = np.nan                                   # too few ranges at epoch 2
    res = geo.multilaterate(r, A, dim=2, z_m=1.0, sigma_m=0.1)
    est = res.to_estimates(np.arange(5) * 0.1, name="LS")
    assert est.status.tolist() == [0, 0, 3, 0, 0] and est.name == "LS"
    np.testing.assert_allclose(est.pos_m[res.ok], res.pos_m[res.ok])
    assert np.isnan(est.pos_m[2]).all() and est.coverage == pytest.approx(0.8)
    np.testing.assert_allclose(est.pos_cov_m2[0], res.cov_m2[0])
    np.testing.assert_array_equal(est.info["n_used"], res.n_used)


# --------------------------------------------------------------------------- point fixes, straight pieces

def test_point_fixes_exact_without_noise_and_nan_where_no_fix():
    rng = np.random.default_rng(4)
    xy, z = _tags(rng, 20)
    z[:] = 1.2
    truth = np.column_stack([xy, z])
    r = geo.ranges(truth, ANCHORS)
    r[5, :6] = np.nan                                          # two ranges: no 2-D fix... nor 3-D
    P2 = geo.point_fixes(r, ANCHORS, dim=2, z_m=1.2)
    P3 = geo.point_fixes(r, uw.Anchors(tuple("abcdefgh"), ANCHORS), dim=3)
    ok = np.arange(20) != 5
    np.testing.assert_allclose(P2[ok], truth[ok], atol=1e-6)
    np.testing.assert_allclose(P3[ok], truth[ok], atol=1e-5)
    assert np.isnan(P2[5]).all() and np.isnan(P3[5]).all()
    with pytest.raises(ValueError, match="z_m"):
        geo.point_fixes(r, ANCHORS, dim=2)
    with pytest.raises(ValueError, match="dim"):
        geo.point_fixes(r, ANCHORS, dim=1)


def _polyline_truth(corners, speed=0.5, rate=50.0, pause_s=3.0):
    """Walk through corners at constant speed, pausing at each corner."""
    t, pts, now = [], [], 0.0
    c = np.asarray(corners, float)
    for a, b in zip(c[:-1], c[1:]):
        tt = np.arange(0, pause_s, 1 / rate)
        t.append(now + tt)
        pts.append(np.tile(a, (tt.size, 1)))
        now += pause_s
        dur = np.linalg.norm(b - a) / speed
        tt = np.arange(0, dur, 1 / rate)
        t.append(now + tt)
        pts.append(a + np.outer(tt / dur, b - a))
        now += dur
    t = np.concatenate(t)
    P = np.vstack(pts)
    return uw.Trajectory(t, np.column_stack([P, np.full(len(P), 0.97)]), name="truth")


def test_straight_segments_find_the_legs_and_skip_the_pauses():
    corners = [(0, 0), (4, 0), (4, 3), (0, 3)]
    segs = geo.straight_segments(_polyline_truth(corners), tol_m=0.05)
    assert len(segs) == 3
    np.testing.assert_allclose(segs.speed_mps, 0.5, atol=0.02)
    np.testing.assert_allclose(segs.heading_deg, [0, 90, 180], atol=2)
    np.testing.assert_allclose(segs.length_m, [4, 3, 4], atol=0.3)
    assert (segs.max_dev_m <= 0.05).all() and list(segs.segment) == [0, 1, 2]


def test_line_fit_recovers_a_constant_velocity_line():
    t = np.linspace(2.0, 4.0, 21)
    P = np.column_stack([1.0 + 0.5 * (t - 2.0), -2.0 * (t - 2.0)])
    c, v, dev = geo.line_fit(t, P)
    np.testing.assert_allclose(c, [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(v, [0.5, -2.0], atol=1e-12)
    assert dev < 1e-12
