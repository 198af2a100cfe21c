import numpy as np
import pytest

from uwbwb.experiments import quickstart as qs


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    return qs.load(tmp_path_factory.mktemp("empty"), fast=True, seed=1)


def test_absent_data_gives_a_labelled_synthetic_stand_in(synthetic):
    assert synthetic.synthetic and synthetic.data_label == "synthetic"
    assert "SYNTHETIC" in synthetic.note
    assert len(synthetic.static) == 30


def test_calibration_fitted_on_static_improves_the_dynamic_run(synthetic):
    cal = qs.calibrate(synthetic)
    table, errors = qs.compare_calibration(synthetic.dynamic, cal, tag_height_m=synthetic.tag_height_m)
    raw = table[table.variant == "raw"].set_index("tag")
    calibrated = table[table.variant == "calibrated"].set_index("tag")
    # biases of 5-40 cm dominate raw fixes; calibration leaves centimetre-level noise
    assert (raw.cep95_m > 0.15).all()
    assert (calibrated.cep95_m < 0.5 * raw.cep95_m).all()
    assert (table.fixes == table.epochs).all()
    assert set(errors) == {"raw", "calibrated"}


def test_decimate_keeps_truth_and_thins_ranges(synthetic):
    rec = qs.decimate(synthetic.dynamic, 10)
    assert len(rec.ranges["t0"]) == int(np.ceil(len(synthetic.dynamic.ranges["t0"]) / 10))
    assert rec.truth is synthetic.dynamic.truth
