import numpy as np
import pandas as pd
import pytest

from uwbwb import sampling as smp
from uwbwb.experiments.doppler import discussion, study
from uwbwb.models import doppler as dm


@pytest.fixture(scope="module")
def cfg():
    return study.StudyConfig.for_mode(True, 0, n_brute=200_000, n_positions=20_000, pf_runs=3, n_particles=300)


def test_fast_mode_only_shrinks_sizes():
    full, fast = study.StudyConfig.for_mode(False), study.StudyConfig.for_mode(True)
    assert full.n_brute >= 1_000_000_000 and full.pf_runs == 1000
    assert fast.n_brute < full.n_brute and fast.sigma_range_m == full.sigma_range_m
    assert fast.p_miss == full.p_miss and fast.temperature_c == full.temperature_c


def test_reference_table_reports_eq1_beside_the_paper(cfg):
    t = study.reference_table(study.make_model("cubic", cfg))
    assert t["ΔP_ref (ms), P = 500 ms"].iloc[0] == pytest.approx(1.06, abs=0.01)
    assert t["paper (ms)"].iloc[7] == -1.2 and np.isnan(t["paper (ms)"].iloc[3])


def test_cut_with_the_reference_velocity_reaches_zero_at_the_reference(cfg):
    model = study.make_model("cubic", cfg)
    s = np.linspace(-1, 1, 201)
    df = study.cuts(model, np.array([1.0, 0, 0]), {"ref": dm.REFERENCE_VEL_MPS, "fast": 2 * dm.REFERENCE_VEL_MPS}, s)
    assert df["ref"].iloc[100] == pytest.approx(0.0, abs=1e-9) and df["ref"].min() == df["ref"].iloc[100]
    assert df["fast"].min() > 0.5


def test_ghost_geometry_finds_a_plane_and_an_axis():
    rng = np.random.default_rng(0)
    v = dm.REFERENCE_VEL_MPS / np.linalg.norm(dm.REFERENCE_VEL_MPS)
    a = np.cross(v, [0, 0, 1.0])
    a /= np.linalg.norm(a)
    b = np.cross(v, a)
    pos = rng.normal(size=(3000, 1)) * a + rng.normal(size=(3000, 1)) * b + 0.01 * rng.normal(size=(3000, 1)) * v
    vel = rng.normal(size=(3000, 1)) * v + 0.05 * rng.normal(size=(3000, 3))
    g = study.ghost_geometry(smp.GhostSamples(pos, vel, np.zeros(3000), np.ones(3000)))
    assert g["angle(position plane normal, V) (°)"] < 2 and g["angle(velocity main axis, V) (°)"] < 5


def test_fisher_weakest_direction_is_a_unit_vector(cfg):
    f = study.fisher_analysis(study.make_model("cubic", cfg))
    assert f["J"].shape == (8, 6) and np.all(np.diff(f["singular_values"]) <= 0)
    w = f["weak"][0]
    assert np.linalg.norm(np.concatenate([w["position part"], w["velocity part"]])) == pytest.approx(1.0)


def test_small_study_end_to_end(cfg):
    maps = {k: study.map_space(k, cfg, workers=1) for k in ("cubic", "lab")}
    table = study.fraction_table(maps)
    assert set(table["estimator"]) == {"brute force", "conditional", "conditional + ranges"}
    assert table.loc[(table["δ < (cm)"] == 15) & (table["estimator"] == "conditional"), "paper (%)"].notna().all()
    track = study.track_study("lab", cfg)
    t_a, t_b = track.snapshots_s
    assert t_b - t_a == pytest.approx(3.0, abs=1e-3)
    assert track.cloud("Doppler", 0).shape == (3, 3)
    scores = study.filter_scores([track])
    assert list(scores["variant"]) == ["Doppler", "Doppler + ranges"] and (scores["epochs"] > 50).all()
    heads = {v: track.headline(v) for v in track.pf}
    at15 = {k: {"conditional": m.conditional.estimate(0.15), "brute force": m.brute.estimate(0.15),
                "ranges": m.ranging.estimate(0.15)} for k, m in maps.items()}
    text = discussion.discussion_markdown(
        fast=True, dp_ref_ms={"model": (1.06, -1.17), "P=0.5": (1.06, -1.08), "P7_ms": 543.0}, fractions=at15,
        geometry=study.ghost_geometry(maps["cubic"].conditional.samples),
        fisher=study.fisher_analysis(maps["cubic"].model), headline=heads, scores=scores,
        brute_small={"n": 200_000, "hits_4cm": 0, "hits_6cm": 0})
    assert text.startswith("> **FAST mode") and "0.0186 %" in text
