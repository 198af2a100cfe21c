import dataclasses

import numpy as np
import pytest

from uwbwb.calibration import fit_range_calibration, tag_mount_height
from uwbwb.experiments import quickstart as qs
from uwbwb.metrics import MIN_BLOCKS
from uwbwb.widgets import data_banner
from uwbwb.types import Trajectory
from tests.test_teaching import assert_reads_predictions


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    return qs.load(tmp_path_factory.mktemp("empty"), fast=True, seed=1)


@pytest.fixture(scope="module")
def heights(synthetic):
    return tag_mount_height(synthetic.static).per_tag_m


@pytest.fixture(scope="module")
def compared(synthetic, heights):
    cal = fit_range_calibration(list(synthetic.static))
    return cal, *qs.compare_calibration(synthetic.dynamic, cal, tag_height_m=heights)


def test_absent_data_gives_a_labelled_synthetic_stand_in(synthetic):
    assert synthetic.synthetic and synthetic.data_label == "synthetic"
    assert "not found" in synthetic.reason
    assert "synthetic stand-in" in data_banner(**synthetic.banner_args()).data
    assert len(synthetic.static) == 30
    assert all(r.meta["decimated"] == 10 for r in synthetic.static)          # FAST thins the static poses


def test_tag_height_comes_from_the_static_poses(synthetic):
    height = tag_mount_height(synthetic.static)
    assert height.z_m == pytest.approx(0.97, abs=0.01)
    assert "static" in height.source


def test_calibration_fitted_on_static_improves_the_dynamic_run(compared):
    cal, table, errors = compared
    raw = table[table.variant == "raw"].set_index("tag")
    calibrated = table[table.variant == "calibrated"].set_index("tag")
    # biases of 5-40 cm dominate raw fixes; calibration leaves centimetre-level noise
    assert (raw.cep95_m > 0.15).all()
    assert (calibrated.cep95_m < 0.5 * raw.cep95_m).all()
    assert (table.fixes == table.epochs).all() and (table.coverage == 1).all()
    assert set(errors) == {"raw", "calibrated"}


def test_both_variants_are_scored_on_the_same_epochs(synthetic, compared):
    """An epoch only one variant fixes is left out of both variants' CEP, and coverage says so."""
    rec = synthetic.dynamic
    tag = rec.tags[0]
    log = rec.ranges[tag]
    r = np.array(log.range_m)
    r[:50, 2:] = np.nan                                   # two anchors left: no 2-D fix on raw or calibrated
    holed = dataclasses.replace(rec, ranges={**rec.ranges, tag: dataclasses.replace(log, range_m=r)})
    table, _ = qs.compare_calibration(holed, compared[0], tag_height_m=tag_mount_height(synthetic.static).z_m)
    row = table[table.tag == tag].set_index("variant")
    assert (row.fixes == len(log) - 50).all()
    assert row.coverage.iloc[0] == pytest.approx((len(log) - 50) / len(log))
    assert (row.compared == len(log) - 50).all()


def test_verdicts_say_whether_calibration_helps_on_both_sides_of_the_rule(compared):
    _, table, errors = compared
    t = qs.verdicts(errors, rng=np.random.default_rng(0))
    assert list(t.columns) == ["claim", "ours", "low", "high", "epochs", "blocks", "rule", "verdict"]
    raw = table[table.variant == "raw"].set_index("tag")
    cal = table[table.variant == "calibrated"].set_index("tag")
    for row, tag in zip(t.itertuples(), raw.index):
        assert row.ours == pytest.approx(raw.loc[tag, "rmse_m"] - cal.loc[tag, "rmse_m"])
        assert row.epochs == raw.loc[tag, "compared"]
        if row.blocks >= MIN_BLOCKS:
            assert row.low <= row.ours <= row.high and row.verdict in ("better", "worse", "not significant")
        else:                                     # too few independent stretches: no interval, no verdict
            assert np.isnan(row.low) and row.verdict == "no verdict"
    # white errors (short blocks), calibrated 10 cm better or worse than raw: the verdict turns with the sign
    rng = np.random.default_rng(1)

    def white(mean_m):
        return {k: dataclasses.replace(e, err_m=np.abs(rng.normal(mean_m, 0.05, e.err_m.size)))
                for k, e in errors["raw"].items()}

    raw_white = white(0.3)
    assert set(qs.verdicts({"raw": raw_white, "calibrated": white(0.4)}, rng=rng).verdict) == {"worse"}
    assert set(qs.verdicts({"raw": raw_white, "calibrated": white(0.2)}, rng=rng).verdict) == {"better"}
    same = {"raw": errors["raw"], "calibrated": errors["raw"]}
    assert set(qs.verdicts(same, rng=np.random.default_rng(0)).verdict) == {"not significant"}


def test_headline_rows_carry_kind_and_coverage(compared):
    _, table, _ = compared
    rows = qs.headline_rows(table)
    assert {r["kind"] for r in rows} == {"reproduced"}
    assert sum(r["quantity"].startswith("coverage") for r in rows) == len(table)


# --------------------------------------------------------------------------- exercises and the panel

def test_exercise_fewer_anchors(synthetic, heights):
    rec, tag = synthetic.dynamic, synthetic.dynamic.tags[0]
    z = heights[tag]
    check = qs.exercises.fewer_anchors(rec, tag, tag_height_m=z)
    n = check.numbers
    assert check.holds, check
    assert n["HDOP, 4 anchors"] > n["HDOP, all anchors"] > 0          # fewer rows in H: never a lower DOP
    assert n["CEP95 4 anchors (m)"] > n["CEP95 all (m)"]
    assert check.holds == (n["CEP95 4 anchors (m)"] > n["CEP95 all (m)"])    # the HDOP, which cannot fall, is no claim
    assert_reads_predictions(check)
    with pytest.raises(ValueError, match="keep"):
        qs.exercises.fewer_anchors(rec, tag, tag_height_m=z, keep=[0, 1])


class _LongDroppedAnchors:
    """A calibration that leaves the anchors the exercise drops (1, 3, 5, 7) reading 0.5 m long."""

    def apply(self, log):
        r = np.array(log.range_m)
        r[:, 1::2] += 0.5
        return dataclasses.replace(log, range_m=r)


def test_exercise_fewer_anchors_can_fail_when_the_dropped_anchors_are_the_bad_ones(synthetic, heights):
    rec, tag = synthetic.dynamic, synthetic.dynamic.tags[0]
    z = heights[tag]
    check = qs.exercises.fewer_anchors(rec, tag, tag_height_m=z, calibration=_LongDroppedAnchors())
    n = check.numbers
    assert n["HDOP, 4 anchors"] > n["HDOP, all anchors"]                 # the geometry is as weak as before ...
    assert not check.holds and n["CEP95 4 anchors (m)"] < n["CEP95 all (m)"]      # ... but the biased ranges go
    assert_reads_predictions(check)
    assert check.against("higher").right is False and check.against("not higher").right is True


def test_exercise_noisier_ranges_can_fail_when_the_noise_added_is_negligible(synthetic, heights):
    rec, tag = synthetic.dynamic, synthetic.dynamic.tags[0]
    z = heights[tag]
    checks = [qs.exercises.noisier_ranges(rec, tag, tag_height_m=z, sigma_m=1e-4, rng=np.random.default_rng(s))
              for s in range(4)]
    assert {c.holds for c in checks} == {True, False}                     # 0.1 mm: CEP50 moves either way
    for c in checks:
        assert c.holds == (c.numbers["CEP50 after (m)"] > c.numbers["CEP50 before (m)"])
        assert_reads_predictions(c)


def test_exercise_noisier_ranges_matches_the_first_order_prediction(synthetic, heights, compared):
    cal = compared[0]
    rec, tag = synthetic.dynamic, synthetic.dynamic.tags[0]
    check = qs.exercises.noisier_ranges(rec, tag, tag_height_m=heights[tag], calibration=cal,
                                        sigma_m=0.2, rng=np.random.default_rng(3))
    n = check.numbers
    assert check.holds, check
    assert n["RMSE after (m)"] == pytest.approx(n["RMSE after, predicted (m)"], rel=0.2)
    assert_reads_predictions(check)
    with pytest.raises(ValueError, match="sigma_m"):
        qs.exercises.noisier_ranges(rec, tag, tag_height_m=1.0, sigma_m=0.0, rng=np.random.default_rng(3))


def test_explorer_panel_draws_a_window_and_its_readout(synthetic, heights, compared):
    from uwbwb.classroom import axes_problems, axes_record

    cal = compared[0]
    ex = qs.panels.Explorer(synthetic.dynamic, heights, cal)
    tag = synthetic.dynamic.tags[0]
    fig, readout = ex.render(tag, "calibrated", 0.0, 20.0)
    est, err = ex.track(tag, "calibrated")
    inside = err.err_m[(err.t_s >= 0.0) & (err.t_s < 20.0)]
    assert readout["fixes in window"] == inside.size > 0
    assert readout["CEP95 (m)"] >= readout["CEP50 (m)"] > 0
    assert all(axes_problems(axes_record(ax)) == [] for ax in fig.axes)
    fig, readout = ex.render(tag, "raw", ex.span_s + 10.0, 5.0)         # a window past the end: a note says so
    assert readout == {"fixes in window": 0} and "no fix" in fig.axes[0].texts[-1].get_text()
    panel = qs.panels.explorer(synthetic.dynamic, heights, cal)
    assert set(panel.values) == {"tag", "variant", "start_s", "window_s"}
