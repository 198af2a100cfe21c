"""``uwbwb score`` puts a recording's outside estimates on the board as *external* rows: a tidy folder's
``external/*.csv``, a Hanyang case's ``LS.csv`` / ``ESKF.csv`` (generated, and the real case when present); on a
Hanyang case the TDoA methods say why they do not run and the range EKFs do."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from tests.conftest import real_dataset
from tests.fixtures import hanyang as fx
from uwbwb import cli
from uwbwb.datasets import tidy
from uwbwb.errors import DataFormatError
from uwbwb.scoreboard import synthetic as syn
from uwbwb.scoreboard.sources import external_estimators, load_target
from uwbwb.types import Trajectory

RANGE_EKFS = ("EKF-RW ranges", "EKF-RF ranges", "EKF-RJ ranges")
TDOA = ("TDoA LS", "EKF-RW", "EKF-RF", "EKF-RJ")
AUTHORS = ("authors LS (external)", "authors ESKF (external, +IMU)")


def _tidy_with_external(folder, offset_m=0.3):
    rec = syn.simulate(syn.SyntheticConfig(duration_s=30.0), rng=np.random.default_rng(11))
    tr = rec.truth["tag"]
    rec = replace(rec, truth={"tag": Trajectory(tr.t_s, tr.pos_m, name="truth")})
    tidy.write_recording(rec, folder)
    (folder / "external").mkdir()
    vendor = Trajectory(tr.t_s[::2], tr.pos_m[::2] + np.array([offset_m, 0.0, 0.0]))
    tidy.write_truth_csv(folder / "external" / "vendor RTLS.csv", vendor)
    return rec


def test_a_tidy_folder_reads_its_external_estimates(tmp_path):
    _tidy_with_external(tmp_path / "run")
    rec = load_target(str(tmp_path / "run"))
    assert list(rec.meta["external_estimates"]) == ["vendor RTLS"]
    assert rec.meta["source"]["external"]["vendor RTLS"].endswith("external/vendor RTLS.csv")
    (est,) = external_estimators(rec)
    assert est.name == "vendor RTLS (external)" and est.external and set(est.tracks) == {"tag"}
    (tmp_path / "run" / "external" / "other.csv").write_text("t_s,x_m,y_m,tag_id\n0.0,1.0,2.0,ghost\n")
    with pytest.raises(DataFormatError, match="other.csv.*no ranges"):
        load_target(str(tmp_path / "run"))


def test_the_score_command_puts_a_tidy_folders_external_estimates_on_the_board(tmp_path, capsys):
    _tidy_with_external(tmp_path / "run", offset_m=0.3)
    out = tmp_path / "out"
    rc = cli.main(["score", str(tmp_path / "run"), "--out", str(out), "--quiet", "--rate-hz", "5",
                   "--methods", "LS"])
    assert rc == 0, capsys.readouterr().err
    table = pd.read_csv(out / "scoreboard.csv").set_index("method")
    assert list(table.index) == ["LS", "vendor RTLS (external)"]
    row = table.loc["vendor RTLS (external)"]
    assert row.kind == "input" and row.rmse_m == pytest.approx(0.3, abs=1e-9) and row.coverage > 0.9


def test_the_score_command_on_a_generated_hanyang_case(tmp_path, capsys):
    cases = fx.write_dynamic_tree(tmp_path / "hanyang-outdoor-uwb", rng=np.random.default_rng(6),
                                  cases=fx.DYNAMIC_CASES[:1], speed_mps=4.0)
    out = tmp_path / "out"
    rc = cli.main(["score", str(cases[0].folder), "--out", str(out), "--fast", "--quiet",
                   "--methods", "raw LS", "TDoA LS", "EKF-RF", "EKF-RF ranges"])
    printed = capsys.readouterr()
    assert rc == 0, printed.err
    assert ": 2-D," in printed.out          # a ground robot: 2-D at the tag height, as notebook 06's Hanyang boards
    table = pd.read_csv(out / "scoreboard.csv").set_index("method")
    assert list(table.index) == ["raw LS", "TDoA LS", "EKF-RF", "EKF-RF ranges", *AUTHORS]
    assert table.loc["EKF-RF ranges", "coverage"] > 0.9
    for m in ("TDoA LS", "EKF-RF"):
        assert table.loc[m, "note"].startswith("not run: TDoAs uninformative here")
    assert (table.loc[list(AUTHORS), "kind"] == "input").all() and (table.loc[list(AUTHORS), "n_scored"] > 0).all()


def test_the_score_command_on_a_real_hanyang_case(tmp_path, capsys):
    """The first dynamic case of the real dataset (FAST settings): the authors' rows, the range EKFs, and a
    "not run" note on each TDoA method and each UWB/INS filter."""
    from uwbwb.datasets import hanyang_dynamic

    root = real_dataset("hanyang-outdoor-uwb")
    case = hanyang_dynamic.dynamic_cases(root.parent)[0]
    out = tmp_path / "out"
    rc = cli.main(["score", str(root / "Dynamic_measurements" / case), "--out", str(out), "--fast", "--quiet"])
    printed = capsys.readouterr()
    assert rc == 0, printed.err
    assert ": 2-D," in printed.out          # the reference's z wanders, yet the ground robot's board is 2-D (as in 06)
    table = pd.read_csv(out / "scoreboard.csv").set_index("method")
    assert set(AUTHORS + RANGE_EKFS + TDOA) <= set(table.index)
    assert (table.loc[list(AUTHORS), "kind"] == "input").all() and (table.loc[list(AUTHORS), "coverage"] > 0.5).all()
    assert (table.loc[list(RANGE_EKFS), "coverage"] > 0.9).all()
    assert table.loc[list(TDOA), "note"].str.startswith("not run: TDoAs uninformative here").all()
    assert table.loc[["loose", "tight"], "note"].str.startswith("not run: needs an IMU").all()
    # the range EKFs are the board's working filters here: each within a factor 2 of the authors' LS
    assert (table.loc[list(RANGE_EKFS), "rmse_m"] < 2 * table.loc["authors LS (external)", "rmse_m"]).all()


def test_a_recording_that_declares_its_dimension_gets_it():
    """A truth whose height wanders by 0.5 m is 3-D by the planar rule, 2-D where the loader declares a ground robot
    (``meta["board_dim"]``, as the Hanyang loader does)."""
    from dataclasses import replace

    from uwbwb.scoreboard.protocol import fit_calibration

    rec = syn.simulate(syn.SyntheticConfig(duration_s=10.0), rng=np.random.default_rng(1))
    tr = rec.truth["tag"]
    wavy = replace(tr, pos_m=tr.pos_m + np.c_[0 * tr.pos_m[:, :2], 0.25 * np.sin(tr.t_s)])
    rec = replace(rec, truth={"tag": wavy})
    assert fit_calibration(rec).dim == 3
    assert fit_calibration(replace(rec, meta={**rec.meta, "board_dim": 2})).dim == 2
