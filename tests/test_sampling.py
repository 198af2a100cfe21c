import numpy as np
import pytest

from uwbwb import Anchors
from uwbwb import sampling as smp
from uwbwb.models import doppler as dm

REF = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)


@pytest.fixture(scope="module")
def cubic():
    return dm.DopplerModel.for_layout(dm.cubic_layout())


def test_kernel_counts_equal_numpy_on_the_same_stream(cubic):
    """The compiled kernel draws X then V from the chunk's generator, exactly as numpy would."""
    n, thresholds = 100_000, (0.5, 1.0, 3.0)
    res = smp.brute_force(cubic, *REF, n, seed=5, chunk_size=40_000, thresholds_m=thresholds,
                          keep_below_m=1.0, workers=1)
    counts = np.zeros(3, int)
    kept = []
    for ss, m in smp.chunk_seeds(5, n, 40_000):
        u = np.random.default_rng(ss).random((m, 6))
        X, V = -5 + 10 * u[:, :3], -3 + 6 * u[:, 3:]
        d = cubic.distance_m(cubic.delta_p(X, V), cubic.delta_p(*REF))
        counts += [np.count_nonzero(d < t) for t in thresholds]
        kept.append(d[d < 1.0])
    assert [e.n_hits for e in res.estimates] == counts.tolist()
    np.testing.assert_allclose(res.samples.delta_m, np.concatenate(kept), rtol=1e-9)
    d_again = cubic.distance_m(cubic.delta_p(res.samples.pos_m, res.samples.vel_mps), cubic.delta_p(*REF))
    np.testing.assert_allclose(res.samples.delta_m, d_again, rtol=1e-9)


def test_fraction_of_a_layout_with_beacons_at_infinity_is_known_in_closed_form():
    """All beacons far below: u = (0, 0, 1) everywhere, so δ depends on V_z alone and
    δ < τ ⟺ |f(V_z/v_s) − f(r_ref)| < τ / (v_s ‖P‖) with f(r) = r / (1 − r)."""
    far = Anchors(tuple(f"b{i}" for i in range(8)), np.tile([0.0, 0.0, -1e7], (8, 1)))
    m = dm.DopplerModel.for_layout(far)
    tau = 0.15
    res = smp.brute_force(m, *REF, 400_000, seed=1, thresholds_m=(tau,), keep_below_m=None, confidence=0.999)
    f_ref = (REF[1][2] / m.v_s_mps) / (1 - REF[1][2] / m.v_s_mps)
    c = tau / (m.v_s_mps * np.linalg.norm(m.period_s))
    lo, hi = (m.v_s_mps * f / (1 + f) for f in (f_ref - c, f_ref + c))
    exact = (min(hi, 3.0) - max(lo, -3.0)) / 6.0
    est = res.estimate(tau)
    assert est.ci_low < exact < est.ci_high, (exact, est)


def test_conditional_agrees_with_brute_force_within_intervals(cubic):
    thresholds = (0.3, 0.6)
    brute = smp.brute_force(cubic, *REF, 3_000_000, seed=2, thresholds_m=thresholds, keep_below_m=None,
                            confidence=0.999)
    cond = smp.conditional(cubic, *REF, 100_000, seed=3, thresholds_m=thresholds, confidence=0.999)
    for t in thresholds:
        b, c = brute.estimate(t), cond.estimate(t)
        assert b.n_hits > 50 and c.n_hits > 50
        assert c.ci_low < b.ci_high and b.ci_low < c.ci_high, (b, c)
        # the conditional estimate is tighter for fewer exact evaluations
        assert c.ci_high - c.ci_low < 0.5 * (b.ci_high - b.ci_low) and c.n_draws < b.n_draws
    # weights of the kept draws add up to the estimate
    assert cond.samples.below(0.3).weight.sum() == pytest.approx(cond.estimate(0.3).fraction)


def test_same_seed_same_fraction_whatever_the_workers(cubic):
    a = smp.brute_force(cubic, *REF, 300_000, seed=9, chunk_size=50_000, thresholds_m=(1.0,), workers=1)
    b = smp.brute_force(cubic, *REF, 300_000, seed=9, chunk_size=50_000, thresholds_m=(1.0,), workers=2)
    c = smp.brute_force(cubic, *REF, 300_000, seed=10, chunk_size=50_000, thresholds_m=(1.0,), workers=2)
    assert a.estimates == b.estimates and a.estimates != c.estimates
    ca = smp.conditional(cubic, *REF, 20_000, seed=4, chunk_size=5_000, workers=1)
    cb = smp.conditional(cubic, *REF, 20_000, seed=4, chunk_size=5_000, workers=2)
    np.testing.assert_equal([vars(e) for e in ca.estimates], [vars(e) for e in cb.estimates])


def test_ranging_term_shrinks_the_ghost_set(cubic):
    without = smp.conditional(cubic, *REF, 50_000, seed=6, thresholds_m=(0.5,))
    with_r = smp.conditional(cubic, *REF, 50_000, seed=6, thresholds_m=(0.5,), ranges=True)
    assert with_r.estimate(0.5).fraction < 0.2 * without.estimate(0.5).fraction
    # every kept sample with ranges lies close to the reference position
    assert np.all(np.linalg.norm(with_r.samples.pos_m - REF[0], axis=1) < 0.5 + 1e-9)


def test_kept_samples_overflow_is_counted_not_lost(cubic):
    res = smp.brute_force(cubic, *REF, 20_000, seed=1, thresholds_m=(100.0,), keep_below_m=100.0,
                          max_kept_per_chunk=1000, chunk_size=10_000, workers=1)
    assert len(res.samples) == 2000 and res.overflow == 18_000


def test_clopper_pearson_edges():
    lo, hi = smp.clopper_pearson(0, 1000)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / 1000))
    with pytest.raises(ValueError):
        smp.clopper_pearson(5, 3)


@pytest.mark.parametrize("layout", ["cubic", "lab"])
def test_ranging_region_holds_every_position_under_the_threshold(layout):
    model = dm.DopplerModel.for_layout(getattr(dm, f"{layout}_layout")())
    M, half, volume = smp.ranging_region(model, REF[0], 0.15)
    rng = np.random.default_rng(0)
    X = REF[0] + rng.uniform(-1.5, 1.5, (400_000, 3))
    resid = np.linalg.norm(model.pseudo_range_m(X) - model.pseudo_range_m(REF[0]), axis=1)
    inside = resid < 0.15
    assert inside.sum() > 20
    assert np.all(np.abs((X[inside] - REF[0]) @ M.T) < half)
    assert volume < 27.0


def test_conditional_with_ranges_matches_brute_force_at_a_large_threshold(cubic):
    b = smp.brute_force(cubic, *REF, 2_000_000, seed=3, thresholds_m=(2.0,), keep_below_m=None, ranges=True,
                        confidence=0.999)
    c = smp.conditional(cubic, *REF, 50_000, seed=4, thresholds_m=(2.0,), ranges=True, confidence=0.999)
    eb, ec = b.estimate(2.0), c.estimate(2.0)
    assert eb.n_hits > 30 and ec.ci_low < eb.ci_high and eb.ci_low < ec.ci_high, (eb, ec)


@pytest.mark.parametrize("kwargs, name", [({"n_draws": 0}, "n_draws"), ({"chunk_size": 0}, "chunk_size"),
                                          ({"workers": 0}, "workers"), ({"confidence": 1.0}, "confidence"),
                                          ({"thresholds_m": (0.1, np.nan)}, "thresholds_m"),
                                          ({"keep_below_m": -1.0}, "keep_below_m"),
                                          ({"max_kept_per_chunk": -1}, "max_kept_per_chunk")])
def test_brute_force_names_a_bad_parameter(cubic, kwargs, name):
    args = {"n_draws": 1000, **kwargs}
    n = args.pop("n_draws")
    with pytest.raises(ValueError, match=name):
        smp.brute_force(cubic, *REF, n, seed=0, **args)


@pytest.mark.parametrize("kwargs, name", [({"n_positions": 0}, "n_positions"), ({"draws_per_position": 0},
                                          "draws_per_position"), ({"thresholds_m": ()}, "thresholds_m"),
                                          ({"workers": 1.5}, "workers")])
def test_conditional_names_a_bad_parameter(cubic, kwargs, name):
    args = {"n_positions": 1000, **kwargs}
    n = args.pop("n_positions")
    with pytest.raises(ValueError, match=name):
        smp.conditional(cubic, *REF, n, seed=0, **args)


def test_a_run_sized_for_a_small_threshold_finds_samples_a_large_one_misses(cubic):
    """The conditional sampler draws velocities in the largest threshold's ellipsoid: sized for 15 cm it holds
    (almost) nothing under 3 cm, sized for 3 cm it holds many, and both estimate the same fraction."""
    wide = smp.conditional(cubic, *REF, 100_000, seed=1, thresholds_m=(0.03, 0.15))
    narrow = smp.conditional(cubic, *REF, 100_000, seed=1, thresholds_m=(0.03,))
    assert len(narrow.samples) > 5 * max(len(wide.samples.below(0.03)), 1)
    assert narrow.estimate(0.03).fraction > 0 and narrow.estimate(0.03).n_hits == len(narrow.samples)
