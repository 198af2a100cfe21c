"""Verdict sentences follow from the facts: each flips when a value crosses its threshold."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from uwbwb.scoreboard import calibrate, score
from uwbwb.scoreboard import synthetic as syn
from uwbwb.scoreboard.estimators import CalibratedLs, ExternalEstimates
from uwbwb.scoreboard.verdicts import (difference_facts, difference_sentence, placement_facts,
                                       placement_sentence)
from uwbwb.types import Trajectory


def _facts(lo, hi):
    return {"a": "A", "b": "B", "mode": "FAST", "n_epochs": 100, "rmse_a_m": 0.05, "rmse_b_m": 0.06,
            "diff_m": (lo + hi) / 2, "lo_m": lo, "hi_m": hi,
            "verdict": "a" if hi < 0 else ("b" if lo > 0 else "none")}


@pytest.mark.parametrize("lo, hi, expected", [(-0.010, -0.001, "A is more accurate"),
                                              (-0.010, 0.001, "no significant difference"),
                                              (0.001, 0.010, "B is more accurate")])
def test_difference_sentence_flips_with_the_interval(lo, hi, expected):
    s = difference_sentence(_facts(lo, hi))
    assert s.endswith(expected + ".") or expected in s
    assert "FAST" in s


@pytest.mark.parametrize("ratio, se, expected", [(1.30, 0.10, "above"), (1.15, 0.10, "on"), (0.85, 0.10, "on"),
                                                 (0.70, 0.10, "below"), (float("nan"), 0.1, "no common bound")])
def test_placement_flips_at_two_standard_errors(ratio, se, expected):
    f = placement_facts(SimpleNamespace(method="M", rmse_over_common=ratio, rmse_over_common_se=se))
    assert expected in placement_sentence(f)


def _board(offset_m):
    """LS against an outside method whose estimates are the truth plus a known constant offset."""
    cfg = syn.SyntheticConfig(duration_s=20.0)
    rec = syn.simulate(cfg, rng=np.random.default_rng(4))
    tr = rec.truth["tag"]
    ext = ExternalEstimates("shifted truth", {"tag": Trajectory(tr.t_s, tr.pos_m + [offset_m, 0.0, 0.0])})
    ests = [CalibratedLs(), ext]
    return score(rec, rec, estimators=ests, rate_hz=None,
                 calibration=syn.exact_calibration(cfg, calibrate(rec, ests, rate_hz=None, dim=2)))


@pytest.mark.parametrize("offset_m, verdict", [(0.005, "b"), (0.2, "a")])
def test_difference_facts_on_a_board_follow_the_errors(offset_m, verdict):
    """An outside method 5 mm off beats LS (σ 5 cm); 20 cm off it loses — and the interval says so."""
    b = _board(offset_m)
    f = difference_facts(b, "LS", "shifted truth (external)", rng=np.random.default_rng(0))
    assert f["n_epochs"] == len(b.entry("LS", "tag").estimates)
    assert f["verdict"] == verdict and f["lo_m"] <= f["diff_m"] <= f["hi_m"]
    assert f["diff_m"] == pytest.approx(f["rmse_a_m"] - f["rmse_b_m"])
