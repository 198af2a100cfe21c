from dataclasses import replace

import numpy as np
import pytest

from uwbwb.models.motion import RandomForce, VelocityKick
from uwbwb.sim import walk
from uwbwb.sim.walk import Obstacle, TagMount
from uwbwb.types import Anchors, RangeLog


def _short(name="office", **kw):
    return walk.scenario(name, duration_s=30.0, **kw)


def test_path_is_a_closed_loop_with_rounded_corners():
    xy, kappa = walk.path_points(((0, 0), (10, 0), (10, 6), (0, 6)), corner_radius_m=1.0, step_m=0.02)
    step = np.linalg.norm(np.diff(np.vstack([xy, xy[:1]]), axis=0), axis=1)
    assert np.all(step < 0.021) and np.median(step) == pytest.approx(0.02, rel=0.01)
    length = 2 * (8 + 4) + 2 * np.pi * 1.0          # straights + four quarter circles of radius 1
    assert step.sum() == pytest.approx(length, rel=0.01)
    assert np.median(kappa[kappa > 0.5]) == pytest.approx(1.0, rel=0.05)
    assert np.mean(kappa < 1e-6) > 0.6                # mostly straight


def test_steering_follows_the_path_at_the_scenario_speed():
    cfg = _short("office")
    t, x = walk.steer(cfg, rng=np.random.default_rng(1))
    xy, _ = walk.path_points(cfg.waypoints_m, cfg.corner_radius_m)
    dist = np.min(np.linalg.norm(x[::20, None, :2] - xy[None], axis=-1), axis=1)
    assert dist.max() < 0.5
    speed = np.linalg.norm(x[200:, 2:], axis=1)        # after the start-up second
    assert 0.65 < speed.mean() < 0.95
    agv_t, agv_x = walk.steer(_short("agv2"), rng=np.random.default_rng(1))
    assert 0.7 < np.linalg.norm(agv_x[200:, 2:], axis=1).mean() < 1.05


def test_steering_noise_comes_from_the_shared_random_force_model():
    cfg = _short("agv1")
    assert cfg.motion == RandomForce(cfg.psd_acc_m2ps3, dim=2)
    quiet = replace(cfg, psd_acc_m2ps3=0.0)
    _, a = walk.steer(quiet, rng=np.random.default_rng(1))
    _, b = walk.steer(quiet, rng=np.random.default_rng(2))
    np.testing.assert_allclose(a, b)                   # no process noise: rng does not matter
    _, c = walk.steer(cfg, rng=np.random.default_rng(1))
    _, d = walk.steer(cfg, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(c, d)
    assert np.abs(c - a).max() > 1e-3


def test_obstacle_crossing_respects_height():
    wall = (Obstacle(5, -5, 5, 5, 2.0, 0.4),)
    anchor = np.array([[10.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    tag = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 3.5], [6.0, 0.0, 1.0]])
    bias = walk._crossings(tag, anchor, wall)
    # low link crosses the wall; high link passes over it; link on the same side does not cross
    np.testing.assert_allclose(bias, [[0.4, 0.0], [0.0, 0.0], [0.0, 0.4]])


def test_simulated_ranges_follow_the_documented_error_model():
    cfg = walk.scenario("office", duration_s=120.0)
    rec, truth = walk.simulate_walk(cfg, rng=np.random.default_rng(5))
    assert rec.tags == ("tag1", "tag2") and len(rec.anchors) == 6
    t1, t2 = rec.ranges["tag1"].t_s, rec.ranges["tag2"].t_s
    assert np.allclose(np.diff(t1), 0.1) and np.allclose(t2 - t1[: t2.size], 0.05)    # TDMA interleave
    e, nlos = truth.range_error_m["tag1"], truth.nlos["tag1"]
    los = ~nlos & np.isfinite(e)
    assert np.std(e[los]) == pytest.approx(cfg.sigma_los_m, rel=0.1)
    assert abs(np.mean(e[los])) < 0.01
    assert np.nanmean(e[nlos]) > 0.2                  # positive NLOS bias
    miss = np.isnan(rec.ranges["tag1"].range_m)
    assert miss[~nlos].mean() == pytest.approx(cfg.p_missing_los, abs=0.01)
    assert miss[nlos].mean() == pytest.approx(cfg.p_missing_nlos, abs=0.03)
    # tag 2 is worn on the chest: the body blocks anchors behind the walker
    assert truth.nlos["tag2"].mean() > truth.nlos["tag1"].mean() + 0.1
    tr = rec.truth["tag1"]
    assert tr.pos_m.shape[1] == 3 and np.allclose(tr.pos_m[:, 2], 1.8)
    np.testing.assert_allclose(truth.true_range_m["tag1"],
                               np.linalg.norm(tr.interp(t1)[:, None] - rec.anchors.pos_m, axis=-1), atol=0.01)


def test_same_seed_same_recording():
    a, _ = walk.simulate_walk(_short("agv1"), rng=np.random.default_rng(3))
    b, _ = walk.simulate_walk(_short("agv1"), rng=np.random.default_rng(3))
    c, _ = walk.simulate_walk(_short("agv1"), rng=np.random.default_rng(4))
    np.testing.assert_array_equal(a.ranges["tag2"].range_m, b.ranges["tag2"].range_m)
    assert not np.array_equal(np.nan_to_num(a.ranges["tag2"].range_m), np.nan_to_num(c.ranges["tag2"].range_m))


def test_device_output_uses_the_nearest_anchors_and_linear_least_squares():
    anchors = Anchors(("A", "B", "C", "D", "E"),
                      np.array([[0, 0, 2.5], [10, 0, 2.5], [10, 8, 2.4], [0, 8, 2.6], [30, 30, 2.5]]))
    pos = np.array([[2.0, 3.0], [6.0, 5.0], [4.0, 1.0]])
    r = np.linalg.norm(np.column_stack([pos, np.full(3, 1.2)])[:, None] - anchors.pos_m, axis=-1)
    r[:, 4] += 5.0                                   # the far anchor is wildly wrong...
    r[1, 2] = np.nan
    out = walk.device_output(RangeLog(np.arange(3.0), r, anchors.ids), anchors, z_m=1.2)
    # ...but it is never among the four nearest, so it is not used; epoch 1 uses the 3 left + E
    np.testing.assert_allclose(out.pos_m[[0, 2]], pos[[0, 2]], atol=1e-9)
    assert np.linalg.norm(out.pos_m[1] - pos[1]) > 0.1
    three = walk.device_output(RangeLog(np.arange(3.0), np.where(np.arange(5) == 4, np.nan, r), anchors.ids),
                               anchors, z_m=1.2)
    np.testing.assert_allclose(three.pos_m, pos, atol=1e-9)
    with pytest.raises(ValueError, match="n_nearest"):
        walk.device_output(RangeLog(np.arange(3.0), r, anchors.ids), anchors, z_m=1.2, n_nearest=2)


def test_scenario_validation():
    with pytest.raises(ValueError, match="unknown scenario"):
        walk.scenario("warehouse")
    with pytest.raises(ValueError, match="acquisition"):
        walk.agv(3)
    with pytest.raises(ValueError, match="positive"):
        walk.office(speed_mps=0.0)
    with pytest.raises(ValueError, match="unique tag ids"):
        walk.office(tags=(TagMount("t", 0, 0, 1), TagMount("t", 0, 0, 1)))
    with pytest.raises(ValueError, match="anchor_pos_m"):
        walk.office(anchor_pos_m=((0, 0, 1),))
    with pytest.raises(ValueError, match="consecutive waypoints"):
        walk.office(waypoints_m=((0, 0), (5, 0), (5, 0), (0, 4)))


def test_a_motion_object_drives_the_walk_like_its_psd_bit_for_bit():
    cfg = _short("agv1")
    model = RandomForce(0.3, dim=2)
    a, ta = walk.simulate_walk(cfg, rng=np.random.default_rng(3), motion=model)
    b, tb = walk.simulate_walk(replace(cfg, psd_acc_m2ps3=0.3), rng=np.random.default_rng(3))
    assert ta.config == tb.config and ta.config.motion == model
    for tag in cfg.tag_ids:
        np.testing.assert_array_equal(a.ranges[tag].range_m, b.ranges[tag].range_m)
        np.testing.assert_array_equal(a.truth[tag].pos_m, b.truth[tag].pos_m)
    np.testing.assert_array_equal(ta.reference.pos_m, tb.reference.pos_m)
    np.testing.assert_array_equal(walk.steer(cfg, rng=np.random.default_rng(4), motion=model)[1],
                                  walk.steer(cfg.with_motion(model), rng=np.random.default_rng(4))[1])
    own, _ = walk.simulate_walk(cfg, rng=np.random.default_rng(3), motion=cfg.motion)
    plain, _ = walk.simulate_walk(cfg, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(own.ranges["tag1"].range_m, plain.ranges["tag1"].range_m)
    assert not np.array_equal(np.nan_to_num(a.ranges["tag1"].range_m), np.nan_to_num(plain.ranges["tag1"].range_m))
    for bad in (RandomForce(0.3, dim=3), VelocityKick(0.3)):
        with pytest.raises(ValueError, match="2-D RandomForce"):
            walk.simulate_walk(cfg, rng=np.random.default_rng(3), motion=bad)
