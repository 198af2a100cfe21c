"""Loader of the Hanyang dynamic runs, on generated trees of the upstream layout (and the real ones if present)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.fixtures import hanyang as fx
from uwbwb.datasets import dataset_available
from uwbwb.datasets import hanyang_dynamic as hd
from uwbwb.errors import DataFormatError, DataNotFoundError


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    data = tmp_path_factory.mktemp("hy") / "data"
    cases = fx.write_dynamic_tree(data / "hanyang-outdoor-uwb", rng=np.random.default_rng(5))
    return data, cases


@pytest.fixture(scope="module")
def loaded(tree):
    data, cases = tree
    return {c.name: hd.load_dynamic_case(c.name, data) for c in cases}


def test_cases_are_found_by_globbing(tree):
    data, cases = tree
    assert hd.dynamic_cases(data) == sorted(c.name for c in cases)


def test_anchors_ranges_and_epochs(tree, loaded):
    _, cases = tree
    for c in cases:
        rec = loaded[c.name]
        assert rec.label == f"hanyang-outdoor-uwb/{c.name}"
        assert rec.anchors.ids == ("A3", "A5", "A9", "A12")
        np.testing.assert_allclose(rec.anchors.pos_m, np.array(list(fx.DYNAMIC_ANCHORS.values())))
        log = rec.ranges["tag"]
        # every written range lands in exactly one epoch, in its anchor's column
        assert {a: int(np.isfinite(log.range_m[:, k]).sum()) for k, a in enumerate(rec.anchors.ids)} == c.n_ranges
        assert rec.meta["epochs"]["max_spread_s"] < 0.01
        assert rec.meta["rssi_dbm"].shape == log.range_m.shape
        assert np.array_equal(np.isfinite(rec.meta["rssi_dbm"]), np.isfinite(log.range_m))
        assert (rec.meta["condition"], rec.meta["trajectory"]) == tuple(c.name.split("/")[:2]) \
            or rec.meta["trajectory"] == c.name.split("/")[1].split("_")[1]


def test_clock_offset_and_height_are_recovered_from_the_data(tree, loaded):
    _, cases = tree
    for c in cases:
        m = loaded[c.name].meta
        assert abs(m["reference_time_offset_s"] - c.clock_offset_s) < 0.02, c.name
        assert all(abs(lag + 0.05) < 0.03 for lag in m["authors_lag_s"].values()), m["authors_lag_s"]
        if c.name.startswith("LOS"):        # NLOS biases one anchor: the height fit is looser there
            assert abs(m["tag_height_fit_m"] - c.tag_height_m) < 0.05, c.name
        assert m["tag_height_m"] == m["tag_height_fit_m"] and "this case" in m["tag_height_source"]


def test_truth_is_the_reference_moved_to_the_range_clock_and_lifted_by_the_given_height(tree, loaded):
    data, cases = tree
    c = cases[0]
    raw = hd.load_dynamic_case(c.name, data, register=False)
    given = hd.load_dynamic_case(c.name, data, tag_height_m=0.7)
    dt = given.meta["reference_time_offset_s"]
    np.testing.assert_allclose(given.truth["tag"].t_s, raw.truth["tag"].t_s + dt)
    np.testing.assert_allclose(given.truth["tag"].pos_m[:, 2], raw.truth["tag"].pos_m[:, 2] + 0.7)
    assert given.meta["tag_height_source"] == "given (calibration)"
    # the true horizontal track at the range epochs is the generator's: check a mid-run epoch
    p, _ = fx._track(c.name.split("/")[1][-1], 2.5)
    rec = loaded[c.name]
    t = rec.ranges["tag"].t_s[len(rec.ranges["tag"]) // 2]
    np.testing.assert_allclose(rec.truth["tag"].interp([t])[0, :2], p([t])[0], atol=0.06)


def test_authors_estimates_and_their_cleaning(tree, loaded):
    data, cases = tree
    for c in cases:
        rec = loaded[c.name]
        est = rec.meta["authors_estimates"]
        assert set(est) == {"LS", "ESKF"}
        assert est["ESKF"].coverage == 1.0 and est["LS"].dim == 3
        steps = {s.name: s.n_affected for s in rec.cleaning}
        assert steps["repeated rows dropped"] == c.n_eskf_repeats
    name = cases[2].name                                           # written with a blank line in A5.csv
    assert {s.name: s.n_affected for s in loaded[name].cleaning}["empty lines"] == 1
    again = hd.load_dynamic_case(cases[0].name, data, register=False).meta["authors_estimates"]   # own stamps
    np.testing.assert_array_equal(again["LS"].pos_m, loaded[cases[0].name].meta["authors_estimates"]["LS"].pos_m)


def test_a_folder_path_loads_like_its_name(tree, loaded):
    _, cases = tree
    c = cases[1]
    rec = hd.load_dynamic_case(c.folder)
    assert rec.name == c.name
    np.testing.assert_array_equal(rec.ranges["tag"].range_m, loaded[c.name].ranges["tag"].range_m)


def test_unknown_case_lists_the_known_ones(tree):
    data, _ = tree
    with pytest.raises(DataNotFoundError, match="LOS/Trajectory_A/Case_2"):
        hd.load_dynamic_case("LOS/Trajectory_C/Case_9", data)


def _bad_case(tmp_path, edit):
    """A generated case whose A5.csv is changed by ``edit(lines) -> lines``."""
    c = fx.write_dynamic_case(tmp_path / "LOS" / "Trajectory_A" / "Case_7", rng=np.random.default_rng(3),
                              speed_mps=8.0)
    path = c.folder / "A5.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")
    return c.folder, path


@pytest.mark.parametrize("edit, line, match", [
    (lambda ls: ls[:4] + [ls[4] + ",1"] + ls[5:], 5, "10 comma-separated fields"),
    (lambda ls: ls[:3] + [ls[3].replace(ls[3].split(",")[6], "abc")] + ls[4:], 4, "field.distanceFromTag"),
    (lambda ls: ls[:3] + [ls[3].replace(",5,", ",9,", 1)] + ls[4:], 4, "this file is anchor 5"),
    (lambda ls: ls[:6] + [ls[6].replace(",-0.87,", ",-0.97,", 1)] + ls[7:], 7, "must not move"),
    (lambda ls: ls[:2] + [ls[2].replace(ls[2].split(",")[6], "-1.5")] + ls[3:], 3, "negative range"),
    (lambda ls: ["%time,stamp,id"] + ls[1:], 1, "not a anchor range header"),
    (lambda ls: ls[:3] + [ls[3].replace(ls[3].split(",")[1], ls[2].split(",")[1])] + ls[4:], 4, "share time"),
])
def test_bad_anchor_file_names_file_and_line(tmp_path, edit, line, match):
    folder, path = _bad_case(tmp_path, edit)
    with pytest.raises(DataFormatError, match=match) as err:
        hd.load_dynamic_case(folder)
    assert err.value.path == path and err.value.line == line


def test_bad_reference_and_estimate_files(tmp_path):
    c = fx.write_dynamic_case(tmp_path / "NLOS" / "Trajectory_B" / "Case_7", rng=np.random.default_rng(4),
                              shape="B", speed_mps=8.0)
    ls = (c.folder / "LS.csv").read_text().splitlines()
    (c.folder / "LS.csv").write_text("\n".join(ls[:5] + [ls[5] + ",0"] + ls[6:]) + "\n")
    with pytest.raises(DataFormatError, match="5 comma-separated fields") as err:
        hd.load_dynamic_case(c.folder)
    assert err.value.path.name == "LS.csv" and err.value.line == 6
    (c.folder / "LS.csv").write_text("\n".join(ls) + "\n")
    tr = (c.folder / "trajectory.csv").read_text().splitlines()
    (c.folder / "trajectory.csv").write_text("\n".join(tr[:8] + [tr[8].replace(tr[8].split(",")[2], "nan")] + tr[9:]))
    with pytest.raises(DataFormatError, match="y is not a finite number") as err:
        hd.load_dynamic_case(c.folder)
    assert err.value.path.name == "trajectory.csv" and err.value.line == 9


def test_epochs_split_when_an_anchor_repeats():
    t0 = 1_000_000_000
    a = np.array([0, 10_000_000, 20_000_000], np.int64) + t0     # 10 ms apart: within one gap
    b = np.array([5_000_000], np.int64) + t0
    t, epoch, anchor, info = hd.group_epochs([a, b], t0, gap_s=0.05)
    assert t.size == 3 and info["n_split"] == 2
    assert sorted(np.bincount(epoch).tolist()) == [1, 1, 2]


@pytest.mark.skipif(not dataset_available("hanyang-outdoor-uwb")
                    or not hd.dynamic_cases(), reason="hanyang-outdoor-uwb dynamic part not in the data directories")
def test_real_cases_load_with_a_consistent_clock_offset():
    for name in hd.dynamic_cases():
        rec = hd.load_dynamic_case(name)
        m = rec.meta
        assert 0.1 < m["reference_time_offset_s"] < 0.3, (name, m["reference_time_offset_s"])
        assert abs(np.diff(m["registration"].half_offsets_s)[0]) < 0.1
        assert 0.8 < m["tag_height_fit_m"] < 1.3
        assert set(m["authors_estimates"]) == {"LS", "ESKF"}


def test_the_registry_opens_a_case_by_name(tree, loaded):
    from uwbwb.datasets import registry

    data, cases = tree
    rec = registry.open(f"hanyang-outdoor-uwb/{cases[2].name}", data)
    assert rec.label == loaded[cases[2].name].label
    assert set(registry.names("hanyang-outdoor-uwb", data)) >= {f"hanyang-outdoor-uwb/{c.name}" for c in cases}


@pytest.mark.parametrize("kw, message", [({"tag_height_m": float("nan")}, "tag_height_m must be a finite height"),
                                         ({"tag_height_m": True}, "tag_height_m must be a finite height"),
                                         ({"epoch_gap_s": 0.0}, "epoch_gap_s must be a positive number"),
                                         ({"epoch_gap_s": -1.0}, "epoch_gap_s must be a positive number"),
                                         ({"epoch_gap_s": float("nan")}, "epoch_gap_s must be a positive number")])
def test_load_options_that_cannot_be_used_are_refused(tree, kw, message):
    data, cases = tree
    with pytest.raises(ValueError, match=message):
        hd.load_dynamic_case(cases[0].name, data, **kw)


def test_one_anchor_in_two_files_is_refused(tmp_path):
    data = tmp_path / "data"
    cases = fx.write_dynamic_tree(data / "hanyang-outdoor-uwb", rng=np.random.default_rng(5))
    folder, _ = hd.case_dir(cases[0].name, data)
    (folder / "A03.csv").write_text((folder / "A3.csv").read_text())
    with pytest.raises(DataFormatError, match=r"anchor 3 has two files here"):
        hd.load_dynamic_case(cases[0].name, data)


def _edit_reference(folder: Path, edit) -> Path:
    """Rewrite the case's trajectory.csv (timestamp,x,y,z,heading) with ``edit(t_ns, xyz)`` -> (t_ns, xyz)."""
    path = folder / "trajectory.csv"
    head, *rows = path.read_text().splitlines()
    data = np.array([[float(v) for v in r.split(",")] for r in rows])
    t_ns, xyz = edit(data[:, 0].copy(), data[:, 1:4].copy())
    path.write_text("\n".join([head] + [f"{t:.17g},{x!r},{y!r},{z!r},{h!r}" for t, (x, y, z), h
                                        in zip(t_ns, xyz.tolist(), data[:, 4].tolist())]) + "\n")
    return path


@pytest.mark.parametrize("what, edit, says", [
    ("in millimetres", lambda t, p: (t, 1000 * p), "robust range residual σ"),
    ("shifted 3 m", lambda t, p: (t, p + [3.0, 0.0, 0.0]), "horizontal translation"),
    ("with y mirrored", lambda t, p: (t, p * [1.0, -1.0, 1.0]), "horizontal translation"),
    ("30 s late", lambda t, p: (t + 30e9, p), "robust range residual σ"),
])
def test_a_reference_that_does_not_fit_the_ranges_is_refused_with_what_does_not_fit(tmp_path, what, edit, says):
    c = fx.write_dynamic_case(tmp_path / "LOS" / "Trajectory_A" / "Case_1", rng=np.random.default_rng(4), shape="A")
    assert hd.load_dynamic_case(c.folder).meta["registration"].robust_sigma_m < hd.MAX_REGISTRATION_SIGMA_M
    path = _edit_reference(c.folder, edit)
    with pytest.raises(DataFormatError, match=f"the reference does not fit the ranges — .*{says}") as err:
        hd.load_dynamic_case(c.folder)
    assert err.value.path == path, what
    assert hd.load_dynamic_case(c.folder, register=False).meta["registered"] is False   # unregistered: loaded as is


def test_the_authors_lag_is_nan_without_overlap_not_the_first_lag_searched(tmp_path):
    c = fx.write_dynamic_case(tmp_path / "LOS" / "Trajectory_A" / "Case_1", rng=np.random.default_rng(4), shape="A")
    rec = hd.load_dynamic_case(c.folder)
    assert all(np.isfinite(v) and abs(v) < 1.0 for v in rec.meta["authors_lag_s"].values())
    est = rec.meta["authors_estimates"]["LS"]
    ref = rec.truth["tag"]
    far = type(est)(est.t_s + 1000.0, est.pos_m, est.status, est.name)
    assert np.isnan(hd._best_lag(far, ref))                    # was -1.0 s: the first lag of the search
