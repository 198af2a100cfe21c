"""Synthetic cafeteria tours (Zupanec et al., sec. 3)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from uwbwb.datasets import packets
from uwbwb.sim import tours

QUIET = dict(sigma_m=0.0, bias_range_m=(0.0, 0.0), resolution_m=0.0, p_nlos_in=0.0, p_nlos_out=0.0,
             p_err_in=0.0, p_err_out=0.0)


def test_anchors_on_the_inclined_ceiling_and_coverage():
    cfg = tours.TourConfig()
    a = tours.cafeteria_anchors(cfg)
    assert a.ids == ("1", "2", "3", "4", "5", "6")
    assert np.all((a.pos_m[:, 2] >= 3.9) & (a.pos_m[:, 2] <= 4.5))
    # heights grow linearly with x: coplanar on the inclined ceiling
    np.testing.assert_allclose(a.pos_m[:, 2], 3.9 + 0.6 * a.pos_m[:, 0] / 24.0)
    R = tours.coverage_radius_m(cfg, a)
    np.testing.assert_allclose(R, a.pos_m[:, 2] * np.sqrt(3.0))
    # the layout leaves corners poorly covered and the middle well covered
    assert tours.coverage_count(np.array([1.0, 15.0]), cfg) == 0
    assert tours.coverage_count(np.array([12.0, 8.0]), cfg) >= 4


@pytest.mark.parametrize("pace", ["slow", "fast"])
def test_tour_timing_stops_and_walks(pace):
    cfg = tours.TourConfig(tour=3, pace=pace)
    segs = tours.tour_path(cfg)
    kp = np.asarray(tours.TOURS[3])
    assert [s.kind for s in segs] == ["stop", "move"] * (len(kp) - 1) + ["stop"]
    for s in segs:
        dur = s.t_end_s - s.t_start_s
        if s.kind == "stop":
            assert dur == pytest.approx(10.0)
        else:
            assert np.linalg.norm(s.vel_xy_mps) == pytest.approx(cfg.speed)
            np.testing.assert_allclose(np.add(s.start_xy_m, s.vel_xy_mps * dur), s.end_xy_m)
    assert all(a.t_end_s == pytest.approx(b.t_start_s) for a, b in zip(segs, segs[1:]))


def test_noise_free_ranges_follow_the_round_robin_slots():
    cfg = dataclasses.replace(tours.TourConfig(tour=1, pace="fast"), **QUIET)
    rec, truth = tours.simulate_tour(cfg, rng=np.random.default_rng(1))
    assert rec.tags == ("L", "H") and rec.label == "synthetic/tour1-fast"
    for tag, z in (("L", 1.3), ("H", 2.0)):
        log = rec.ranges[tag]
        np.testing.assert_allclose(np.diff(log.t_s), 0.130)
        assert np.isfinite(log.range_m).all() and not truth.nlos[tag].any()
        assert np.all(rec.truth[tag].pos_m[:, 2] == z)
        # anchor j was ranged in slot j of the 130 ms before the packet time stamp
        slot = 0.130 / 6
        for j in range(6):
            t_meas = log.t_s - 0.130 + (j + 0.5) * slot
            xy, _ = tours.tour_xy(truth.segments, t_meas)
            d = np.linalg.norm(np.column_stack([xy, np.full(len(xy), z)]) - rec.anchors.pos_m[j], axis=1)
            np.testing.assert_allclose(log.range_m[:, j], d, atol=1e-9)
        np.testing.assert_allclose(rec.truth[tag].pos_m[:, :2], tours.tour_xy(truth.segments, log.t_s)[0])
    assert rec.ranges["H"].t_s[0] - rec.ranges["L"].t_s[0] == pytest.approx(0.065)
    # truth sits on the keypoints during stops and moves at the pace in between
    tr = rec.truth["L"]
    for s in truth.segments:
        inside = (tr.t_s > s.t_start_s + 0.01) & (tr.t_s < s.t_end_s - 0.01)
        np.testing.assert_allclose(tr.vel_mps[inside, :2], np.broadcast_to(s.vel_xy_mps, (inside.sum(), 2)))


def test_nlos_is_more_likely_where_coverage_is_poor():
    cfg = dataclasses.replace(tours.TourConfig(tour=2, pace="slow"), nlos_dwell_s=0.0)
    rec, truth = tours.simulate_tour(cfg, rng=np.random.default_rng(2))
    tr = rec.truth["H"]
    frac = []
    for s in truth.segments:
        if s.kind == "stop":
            inside = (tr.t_s > s.t_start_s + 0.2) & (tr.t_s < s.t_end_s)
            frac.append((truth.coverage[s.keypoint], truth.nlos["H"][inside].mean()))
    cov, f = np.array(frac).T
    assert f[cov == cov.min()].mean() > f[cov == cov.max()].mean() + 0.1
    m = truth.model
    assert np.all(m.p_nlos(np.array([1.0, 15.0, 2.0])) > m.p_nlos(np.array([12.0, 8.0, 2.0])).min())


def test_same_seed_same_numbers_and_packets_round_trip(tmp_path):
    cfg = tours.TourConfig(tour=1, pace="fast")
    a, _ = tours.simulate_tour(cfg, rng=np.random.default_rng(7))
    b, _ = tours.simulate_tour(cfg, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a.ranges["L"].range_m, b.ranges["L"].range_m)
    path = packets.write_packets(tmp_path / "L.tsv", a.ranges["L"])
    back = packets.read_packets(path, anchor_ids=a.anchors.ids)
    r = a.ranges["L"].range_m
    np.testing.assert_allclose(back.ranges.range_m, r, atol=1e-9)
    assert back.t0_ms == tours.T0_MS + 130
    assert sum(back.n_err.values()) == int(np.isnan(r).sum()) > 0


def test_config_validates():
    with pytest.raises(ValueError, match="tour"):
        tours.TourConfig(tour=4)
    with pytest.raises(ValueError, match="pace"):
        tours.TourConfig(pace="run")
    with pytest.raises(ValueError, match="probabilities"):
        tours.TourConfig(p_nlos_out=1.5)
