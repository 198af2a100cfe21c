import numpy as np
import pytest

from uwbwb.filters.tdoa_ls import STATUS, tdoa_least_squares
from uwbwb.models.tdoa import TdoaModel
from uwbwb.types import TdoaLog, pseudo_tdoa

ANCHORS = np.array([[0.0, 0.0, 2.0], [10.0, 0.0, 2.5], [10.0, 8.0, 2.0], [0.0, 8.0, 2.5],
                    [5.0, -1.0, 0.5], [5.0, 9.0, 1.0]])
IDS = tuple(f"a{i}" for i in range(6))


def _log(r, ref=0):
    d, refs = pseudo_tdoa(r, ref)
    return TdoaLog(np.arange(len(r)) * 0.1, d, refs, IDS)


@pytest.mark.parametrize("dim", [2, 3])
def test_noise_free_fixes_are_exact(dim, rng):
    model = TdoaModel(ANCHORS, 0.05, dim=dim, z_m=1.2)
    lo, hi = [0.5, 0.5, 0.3][:dim], [9.5, 7.5, 2.0][:dim]
    pos = rng.uniform(lo, hi, (300, dim))
    res = tdoa_least_squares(_log(model.ranges(pos)), model)
    assert res.ok.all()
    np.testing.assert_allclose(res.pos_m, pos, atol=1e-5)
    assert np.nanmax(res.residual_rms_m) < 1e-6


def test_covariance_is_consistent_with_errors(rng):
    model = TdoaModel(ANCHORS, 0.05, dim=2, z_m=1.0)
    pos = rng.uniform([1, 1], [9, 7], (3000, 2))
    r = model.ranges(pos) + 0.05 * rng.standard_normal((3000, 6))
    r[rng.random(r.shape) < 0.15] = np.nan
    res = tdoa_least_squares(_log(r), model)
    ok = res.ok
    assert ok.mean() > 0.95
    e = res.pos_m[ok] - pos[ok]
    nees = np.einsum("ti,tij,tj->t", e, np.linalg.inv(res.cov_m2[ok]), e)
    assert 1.8 < nees.mean() < 2.2                 # chi2(2) mean, standard error ~0.04


def test_result_independent_of_reference_with_correlated_covariance(rng):
    model = TdoaModel(ANCHORS, 0.05, dim=2, z_m=1.0)
    pos = rng.uniform([1, 1], [9, 7], (200, 2))
    r = model.ranges(pos) + 0.05 * rng.standard_normal((200, 6))
    a, b = tdoa_least_squares(_log(r, 0), model), tdoa_least_squares(_log(r, 4), model)
    np.testing.assert_allclose(a.pos_m, b.pos_m, atol=1e-5)
    np.testing.assert_allclose(a.cov_m2, b.cov_m2, atol=1e-10)


def test_status_too_few_and_degenerate():
    model = TdoaModel(ANCHORS, 0.05, dim=2, z_m=2.0)
    r = model.ranges(np.array([[4.0, 3.0], [4.0, 3.0]]))
    r[0, 2:] = np.nan                               # two anchors -> one TDoA < 2 unknowns
    # three anchors on the line y = 0 at the tag's height, tag on that line: H has rank 1
    line = TdoaModel(np.array([[0.0, 0, 2], [5.0, 0, 2], [10.0, 0, 2]]), 0.05, dim=2, z_m=2.0)
    r_line = line.ranges(np.array([[3.0, 0.0]]))
    res = tdoa_least_squares(_log(r), model)
    assert [STATUS[s] for s in res.status] == ["too few anchors", "ok"]
    assert np.isnan(res.pos_m[0]).all()
    d, refs = pseudo_tdoa(r_line, 0)
    deg = tdoa_least_squares(TdoaLog([0.0], d, refs, ("a", "b", "c")), line, x0_m=[3.0, 0.0])
    assert STATUS[int(deg.status[0])] == "degenerate geometry"
    assert deg.status_counts()["degenerate geometry"] == 1


def test_starting_point_and_outputs(rng):
    model = TdoaModel(ANCHORS, 0.05, dim=2, z_m=1.0)
    pos = rng.uniform([1, 1], [9, 7], (20, 2))
    log = _log(model.ranges(pos))
    res = tdoa_least_squares(log, model, x0_m=pos + 0.3)
    np.testing.assert_allclose(res.pos_m, pos, atol=1e-5)
    df = res.to_frame()
    assert list(df.columns) == ["t_s", "x_m", "y_m", "sd_x_m", "sd_y_m", "n_tdoa", "n_iter", "residual_rms_m",
                                "status"]
    assert (df.status == "ok").all() and (df.n_tdoa == 5).all()
    traj = res.to_trajectory()
    assert traj.name == "LS" and len(traj) == 20


def test_anchor_count_mismatch():
    model = TdoaModel(ANCHORS, 0.05)
    log = TdoaLog([0.0], [[0.0, 1.0, 2.0]], [0], ("a", "b", "c"))
    with pytest.raises(ValueError, match="anchors"):
        tdoa_least_squares(log, model)


def test_to_estimates_is_the_fixes_with_status(rng):
    model = TdoaModel(ANCHORS, 0.05, dim=2, z_m=1.0)
    pos = rng.uniform([1, 1], [9, 7], (20, 2))
    r = model.ranges(pos) + 0.05 * rng.standard_normal((20, 6))
    r[4, 2:] = np.nan                                   # two anchors: one TDoA, no 2-D fix
    res = tdoa_least_squares(_log(r), model)
    est = res.to_estimates("TDoA LS")
    assert est.name == "TDoA LS" and est.status[4] == 3 and (est.status[res.ok] == 0).all()
    np.testing.assert_array_equal(est.pos_m[res.ok], res.pos_m[res.ok])
    np.testing.assert_array_equal(est.pos_cov_m2[res.ok], res.cov_m2[res.ok])
    np.testing.assert_array_equal(est.info["n_tdoa"], res.n_tdoa)
