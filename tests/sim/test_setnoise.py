import dataclasses

import numpy as np
import pytest

from uwbwb.calibration import fit_set_noise_from_fixes
from uwbwb.types import set_mask
from uwbwb.sim import setnoise as S

CFG = S.FacilityConfig()
QUIET = dataclasses.replace(CFG, fading_db=0.0, sensor_bias_sigma_m=0.0, wall_excess_m=0.0,
                            multipath_sigma_m=0.0, range_sigma_m=0.0)


def test_config_validation():
    with pytest.raises(ValueError, match="set_size"):
        S.FacilityConfig(set_size=9)
    with pytest.raises(ValueError, match="range_sigma_m"):
        S.FacilityConfig(range_sigma_m=-0.1)
    with pytest.raises(ValueError, match="positive"):
        S.FacilityConfig(speeds_mps=(0.1, 0.0))
    assert CFG.track_length_m == pytest.approx(2.5)


def test_wall_crossings_hand_case():
    fac = S.make_facility(CFG, rng=np.random.default_rng(0))
    n_walls, factor = fac.wall_crossings(np.array([[4.5, 5.9]]))
    # hallway sensors 1, 2 behind the north wall; sensor 3 behind the east wall
    assert n_walls[0].tolist() == [0, 1, 1, 1, 0, 0, 0, 0]
    d = np.array([2.0 - 4.5, 9.6 - 5.9])
    assert factor[0, 1] == pytest.approx(np.linalg.norm(d) / abs(d[1]))  # 1 / cos(incidence)
    assert factor[0, 0] == 0.0


def test_select_sets_takes_the_strongest():
    power = np.array([[-10.0, -20, -5, np.nan, -30, -1, -15, -12]])
    used = S.select_sets(power, 5, 0.0, rng=np.random.default_rng(0))
    assert np.flatnonzero(used[0]).tolist() == [0, 2, 5, 6, 7]
    few = S.select_sets(np.array([[-1.0, np.nan, -2.0]]), 3, 0.0, rng=np.random.default_rng(0))
    assert few[0].tolist() == [True, False, True]                  # unavailable sensors never used
    faded = S.select_sets(np.tile(power, (2000, 1)), 5, 3.0, rng=np.random.default_rng(1))
    assert np.all(faded.sum(1) == 5) and not faded[:, 3].any()
    assert 0.3 < np.mean(np.all(faded == used, axis=1)) < 0.9        # fading switches sets, the strongest dominate


def test_noise_free_fixes_are_exact():
    fac = S.make_facility(QUIET, rng=np.random.default_rng(0))
    xy = np.array([[1.0, 1.0], [4.5, 5.9], [7.5, 2.0]])
    fix, sets = fac.measure(xy, rng=np.random.default_rng(1))
    np.testing.assert_allclose(fix, xy, atol=1e-6)
    assert np.all(set_mask(sets, 8).sum(1) == 5)


def test_multipath_field_statistics():
    fac = S.make_facility(CFG, rng=np.random.default_rng(2))
    xy = np.random.default_rng(3).uniform(0, 40, (4000, 2))
    m = fac.multipath_m(xy)
    assert m.std() == pytest.approx(CFG.multipath_sigma_m, rel=0.15)
    near = fac.multipath_m(xy + [0.05, 0.0])
    far = fac.multipath_m(xy + [3.0, 0.0])
    corr = lambda a, b: np.corrcoef(a.ravel(), b.ravel())[0, 1]    # noqa: E731
    assert corr(m, near) > 0.95 and abs(corr(m, far)) < 0.15


def test_set_noise_emerges_from_sensor_errors():
    """With white noise off, each set has its own nearly constant error at a location."""
    cfg = dataclasses.replace(CFG, range_sigma_m=0.0)
    fac = S.make_facility(cfg, rng=np.random.default_rng(4))
    log = S.static_fixes(fac, cfg.fig3_xy_m, 600, rng=np.random.default_rng(5))
    model = fit_set_noise_from_fixes([log])
    assert len(model) >= 4
    assert np.all(model.sigma_m < 0.005)                           # set → error is deterministic here
    assert np.ptp(model.mu_m, axis=0).max() > 0.05                # ... and differs between sets


def test_track_truth_follows_table1():
    for v, paper_count in zip(S.TABLE1_SPEEDS_MPS, (1521, 467, 250, 164, 135)):
        t, truth = S.track_truth(CFG, v)
        assert abs(t.size - 7 * 2.5 / v * CFG.rate_hz) <= 1
        assert abs(t.size - paper_count) / paper_count < 0.03
        assert np.all(truth[:, 0] >= 3.25 - 1e-9) and np.all(truth[:, 0] <= 5.75 + 1e-9)
        np.testing.assert_allclose(truth[:, 1], 5.9)
        step = np.abs(np.diff(truth[:, 0]))
        assert step.max() <= v / CFG.rate_hz + 1e-9
    t, truth = S.track_truth(CFG, 0.5)
    np.testing.assert_allclose(truth[0], CFG.track_start_xy_m)
    turns = np.sum(np.diff(np.sign(np.diff(truth[:, 0]))) != 0)
    assert turns == 6                                              # seven legs


def test_recordings_calibration_and_reproducibility():
    fac = S.make_facility(CFG, rng=np.random.default_rng(6))
    recs = S.table1_recordings(fac, rng=np.random.default_rng(7))
    assert [r.name for r in recs] == ["rec1", "rec2", "rec3", "rec4", "rec5"]
    again = S.table1_recordings(fac, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(recs[1].pos_m, again[1].pos_m)
    raw_cm = [100 * np.linalg.norm(r.error_m, axis=1).mean() for r in recs]
    assert all(10 < e < 35 for e in raw_cm)                       # the paper's order (18-23 cm)
    cal = S.calibration_campaign(fac, rng=np.random.default_rng(8))
    assert len(cal) == 6 and all(len(c) == 1000 for c in cal)
    fig3 = [c for c in cal if np.allclose(c.truth_m[0], CFG.fig3_xy_m)][0]
    freq = fig3.set_frequency()
    assert freq["share"].iloc[0] < 0.5 and freq["cum_share"].iloc[4] > 0.75   # cf. Fig. 4: < 45 %, 85.8 %


def _emulation_log(n=40):
    from uwbwb.types import RangeLog
    anchors = np.array([[0, 0, 3], [8, 0, 3], [8, 6, 3], [0, 6, 3], [4, -2, 3], [10, 3, 3]], float)
    t = np.arange(n) * 0.1
    xy = np.column_stack([1 + 0.1 * t, 2 + 0.05 * t])
    r = np.linalg.norm(np.column_stack([xy, np.full(n, 1.0)])[:, None] - anchors, axis=-1)
    r[3, :3] = np.nan                                   # 3 ranges left: fewer than a set
    return RangeLog(t, r, tuple("ABCDEF")), anchors, xy


def test_emulated_sets_pick_the_nearest_anchors_and_solve_exactly_without_fading():
    log, anchors, xy = _emulation_log()
    em = S.emulate_set_fixes(log, anchors, 1.0, S.SetEmulation(set_size=4, fading_db=0.0),
                             rng=np.random.default_rng(0), truth_m=xy)
    assert em.too_few_ranges == 1 and em.fix_failed == 0 and 3 not in em.row
    np.testing.assert_allclose(em.fixes.pos_m, xy[em.row], atol=1e-6)
    nearest = np.argsort(log.range_m[0])[:4]
    assert set(np.flatnonzero(set_mask(em.fixes.set_id[:1], 6)[0])) == set(nearest)


def test_emulated_sets_missing_truth_drops_fixes_not_the_random_stream():
    log, anchors, xy = _emulation_log()
    emu = S.SetEmulation(set_size=4, fading_db=3.0)
    full = S.emulate_set_fixes(log, anchors, 1.0, emu, rng=np.random.default_rng(1), truth_m=xy)
    gap = xy.copy()
    gap[10:15] = np.nan
    part = S.emulate_set_fixes(log, anchors, 1.0, emu, rng=np.random.default_rng(1), truth_m=gap)
    keep = ~np.isin(full.row, np.arange(10, 15))
    np.testing.assert_array_equal(part.row, full.row[keep])
    np.testing.assert_array_equal(part.fixes.set_id, full.fixes.set_id[keep])
    with pytest.raises(ValueError, match="set_size"):
        S.SetEmulation(set_size=2)
