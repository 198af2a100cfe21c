"""The board EKFs' one ``update`` option: each value maps to its gate policy, the default keeps the rows' names and
behaviour, and the variants are distinct rows of one board."""

import numpy as np
import pytest

from uwbwb.filters.gating import AnchorDropping, NoGate, Robust
from uwbwb.scoreboard import score, split_in_time
from uwbwb.scoreboard import synthetic as syn
from uwbwb.scoreboard.estimators import (UPDATES, RangeEkfEstimator, TdoaEkfEstimator, default_estimators,
                                        update_variants)
from uwbwb.scoreboard.verdicts import difference_table
from uwbwb.scoreboard.protocol import fit_calibration
from uwbwb.types import RangeLog, Recording, Trajectory


def _hall(seed: int = 3, duration_s: float = 30.0, p_nlos: float = 0.0) -> Recording:
    """The synthetic hall's random-force track, 5 cm range noise, a share ``p_nlos`` of the ranges 1–5 m long."""
    rng = np.random.default_rng(seed)
    cfg = syn.SyntheticConfig(duration_s=duration_s)
    tr = syn.simulate(cfg, rng=rng).truth["tag"]
    anchors = cfg.anchors()
    r = np.linalg.norm(tr.pos_m[:, None, :] - anchors.pos_m[None], axis=-1) + 0.05 * rng.standard_normal(
        (len(tr), len(anchors)))
    out = rng.random(r.shape) < p_nlos
    r[out] += rng.uniform(1.0, 5.0, out.sum())
    return Recording("synthetic", f"nlos-{p_nlos:g}", anchors, {"tag": RangeLog(tr.t_s, r, anchors.ids, "tag")},
                     {"tag": Trajectory(tr.t_s, tr.pos_m, name="truth")})


@pytest.mark.parametrize("kind", [RangeEkfEstimator, TdoaEkfEstimator])
def test_each_update_maps_to_its_policy(kind):
    rec = _hall(duration_s=5.0)
    cal = fit_calibration(rec, dim=2)
    gates = {u: kind("RF", update=u)._filter(rec, "tag", cal, 1.0).gate for u in UPDATES}
    assert isinstance(gates["gate"], AnchorDropping) and gates["gate"].prob == 0.9999
    assert isinstance(gates["none"], NoGate)
    assert isinstance(gates["robust"], Robust) and gates["robust"].kind == "huber"
    assert isinstance(gates["robust"].gate, NoGate)
    assert isinstance(gates["cauchy"], Robust) and gates["cauchy"].kind == "cauchy"
    assert isinstance(gates["both"], Robust) and gates["both"].kind == "huber" and gates["both"].gate == gates["gate"]
    assert gates["gate"] == kind("RF")._filter(rec, "tag", cal, 1.0).gate          # the default is the gate


def test_default_names_unchanged_and_variants_distinct():
    names = [e.name for e in default_estimators(fast=True)]
    assert [n for n in names if n.startswith("EKF")] == ["EKF-RW", "EKF-RF", "EKF-RJ", "EKF-RW ranges",
                                                         "EKF-RF ranges", "EKF-RJ ranges"]
    variants = [RangeEkfEstimator("RF", update=u).name for u in UPDATES]
    assert len(set(variants)) == len(UPDATES) and variants[0] == "EKF-RF ranges"
    assert RangeEkfEstimator("RF", update="robust").name == "EKF-RF ranges (Huber)"
    assert TdoaEkfEstimator("RW", update="both").name == "EKF-RW (gate + Huber)"


def test_unknown_update_is_refused():
    with pytest.raises(ValueError, match="update must be one of"):
        RangeEkfEstimator("RF", update="huber")


def test_variants_run_side_by_side_and_the_gate_matters_with_nlos_ranges():
    """Every variant is a row of one board; with 10 % of ranges 1–5 m long the ungated filter is far worse than the
    gated one and than the robust ones (a policy that is not applied would tie them)."""
    cal_rec, test = split_in_time(_hall(p_nlos=0.1), 0.5)
    est = [RangeEkfEstimator("RF", grid=(0.3, 1.0), update=u) for u in UPDATES]
    board = score(test, cal_rec, estimators=est, rate_hz=None, dim=2)
    rmse = board.table().set_index("method")["rmse_m"]
    assert len(rmse) == len(UPDATES) and np.isfinite(rmse).all()
    none = rmse["EKF-RF ranges (no gate)"]
    for name in ("EKF-RF ranges", "EKF-RF ranges (Huber)", "EKF-RF ranges (Cauchy)", "EKF-RF ranges (gate + Huber)"):
        assert rmse[name] < 0.7 * none, (name, rmse.to_dict())
    # the ablation's table: each variant against the gate, coverage beside the interval's verdict
    diff = difference_table({"hall": board}, [(e.name, est[0].name) for e in est[1:]], seed=0).set_index("A")
    assert (diff["coverage A"] > 0.9).all() and (diff["coverage B"] > 0.9).all()
    # a two-value grid puts every pick on its edge: the verdict says so and names both picks
    verdict = diff.loc["EKF-RF ranges (no gate)", "verdict"]
    assert verdict.startswith("edge-bound: EKF-RF ranges more accurate at the picks (EKF-RF ranges (no gate): σ_w ")
    assert verdict.count("on the grid's edge") == 2


def test_update_variants_are_the_ablation_rows_tuned_alike():
    rows = update_variants("RW", fast=True)
    assert [e.update for e in rows] == list(UPDATES) and rows[0].name == "EKF-RW ranges"
    assert {e.grid for e in rows} == {tuple(default_estimators(fast=True)[6].grid)}
    assert all(e.grid is None for e in update_variants("RW"))
