import numpy as np
import pytest

from uwbwb import ChirpFlag, ChirpLog, DataFormatError
from uwbwb.datasets.chirps import read_chirps_csv, write_chirps_csv

IDS = ("b0", "b1", "b2")


def _log():
    return ChirpLog(np.array([0.031, 0.1874, 0.532, 1.0601, 1.5]), np.array([1, -1, 1, 1, 0]),
                    np.array([np.nan, np.nan, 1.23456789e-4, -4.2e-4, np.nan]),
                    np.array([ChirpFlag.LOCK, ChirpFlag.UNASSIGNED, 0, ChirpFlag.GAP | ChirpFlag.AMBIGUOUS,
                              ChirpFlag.LOCK], np.int8), IDS)


def test_round_trip_is_exact(tmp_path):
    log = _log()
    path = write_chirps_csv(tmp_path / "chirps.csv", log)
    back = read_chirps_csv(path, IDS)
    for name in ("t_s", "beacon", "dp_s", "flags"):
        np.testing.assert_array_equal(getattr(back, name), getattr(log, name))
    assert "gap+ambiguous" in path.read_text()
    assert log.counts()["with ΔP"] == 2 and log.counts()["lock"] == 2


def test_arrival_times_only_is_a_valid_log(tmp_path):
    p = tmp_path / "c.csv"
    p.write_text("# raw receiver output\nt_s,beacon_id,dp_s,flags\n0.1,,,\n0.6,,,\n")
    log = read_chirps_csv(p, IDS)
    assert len(log) == 2 and np.all(log.beacon == -1)


@pytest.mark.parametrize("body, line, column, what", [
    ("0.1,b0,,\n0.1,b1,,\n", 3, "t_s", "strictly increasing"),
    ("0.1,b9,,\n", 2, "beacon_id", "not a beacon"),
    ("0.1,,1e-4,\n", 2, "dp_s", "needs a beacon_id"),
    ("0.1,b0,abc,\n", 2, "dp_s", "not a finite number"),
    ("0.1,b0,,weird\n", 2, "flags", "unknown flag"),
    ("0.1,b0,\n", 2, None, "fields"),
])
def test_bad_input_names_file_line_and_column(tmp_path, body, line, column, what):
    p = tmp_path / "bad.csv"
    p.write_text("t_s,beacon_id,dp_s,flags\n" + body)
    with pytest.raises(DataFormatError, match=what) as exc:
        read_chirps_csv(p, IDS)
    assert exc.value.line == line and exc.value.column == column and exc.value.path == p


def test_container_checks():
    with pytest.raises(ValueError, match="assigned"):
        ChirpLog([0.0], [-1], [1e-3], [0], IDS)
    with pytest.raises(ValueError, match="increasing"):
        ChirpLog([1.0, 0.5], [0, 0], [np.nan, np.nan], [0, 0], IDS)
    with pytest.raises(ValueError, match="beacon"):
        ChirpLog([0.0], [3], [np.nan], [0], IDS)


# --------------------------------------------------------------------------- plausibility and consistency

@pytest.mark.parametrize("dp", ["-10", "1e6", "0.91", "-0.1000001"])
def test_an_implausible_period_shift_is_an_error_naming_the_line(tmp_path, dp):
    from uwbwb.datasets.chirps import MAX_ABS_DP_S

    p = tmp_path / "bad.csv"
    p.write_text(f"t_s,beacon_id,dp_s,flags\n0.1,b0,,lock\n0.6,b0,{dp},\n1.1,b0,-20,\n")
    with pytest.raises(DataFormatError, match=r"not a plausible period shift.*at most 0\.1 s.*2 row\(s\)") as exc:
        read_chirps_csv(p, IDS)
    assert exc.value.line == 3 and exc.value.column == "dp_s" and exc.value.path == p
    assert MAX_ABS_DP_S == 0.1


def test_shifts_at_the_bound_are_kept(tmp_path):
    p = tmp_path / "edge.csv"
    p.write_text("t_s,beacon_id,dp_s,flags\n0.1,b0,,lock\n0.6,b0,0.1,\n1.1,b0,-0.1,gap\n")
    np.testing.assert_array_equal(read_chirps_csv(p, IDS).dp_s, [np.nan, 0.1, -0.1])


@pytest.mark.parametrize("row, what", [
    ("b1,0.0004,unassigned", "'unassigned' on a row with a beacon_id"),
    ("b1,,unassigned", "'unassigned' on a row with a beacon_id"),
    (",,unassigned+gap", "cannot be combined"),
    (",,lock", "'lock' needs a beacon_id"),
    ("b1,0.0004,lock", "'lock' on a row with a dp_s"),
    ("b1,,gap", "'gap' needs a beacon_id and a dp_s"),
    (",,ambiguous", "'ambiguous' needs a beacon_id"),
])
def test_contradictory_rows_are_rejected_with_file_and_line(tmp_path, row, what):
    p = tmp_path / "contradictory.csv"
    p.write_text(f"t_s,beacon_id,dp_s,flags\n0.1,b1,,lock\n0.3,,,unassigned\n0.6,{row}\n")
    with pytest.raises(DataFormatError, match=what) as exc:
        read_chirps_csv(p, IDS)
    assert exc.value.line == 4 and exc.value.column == "flags" and exc.value.path == p


def test_counts_of_a_read_log_match_its_rows(tmp_path):
    p = tmp_path / "c.csv"
    p.write_text("t_s,beacon_id,dp_s,flags\n0.1,b1,,lock\n0.2,,,unassigned\n0.61,b1,0.0004,ambiguous\n"
                 "1.7,b1,-0.0003,gap\n1.9,,,\n2.2,b2,,\n")
    c = read_chirps_csv(p, IDS).counts()
    assert c == {"detections": 6, "with ΔP": 2, "lock": 1, "gap": 1, "ambiguous": 1, "unassigned": 1}


def test_simulated_and_assigned_logs_pass_the_rules(tmp_path):
    """The workbench's own chirp logs (simulated, then assigned by periodicity) round-trip through the file."""
    from uwbwb.filters.doppler import assign_chirps
    from uwbwb.models import doppler as dm
    from uwbwb.sim import chirps as sc

    model = dm.DopplerModel.for_layout(dm.cubic_layout())
    track, _ = sc.rectangle_track()
    rec = sc.simulate_chirps(model, track, 60.0, rng=np.random.default_rng(1), p_miss=0.2, spurious_rate_hz=2.0)
    log = assign_chirps(rec.t_s, model)
    assert log.counts()["gap"] > 0 and log.counts()["unassigned"] > 0 and log.counts()["lock"] > 0
    back = read_chirps_csv(write_chirps_csv(tmp_path / "sim.csv", log), log.beacon_ids)
    assert back.counts() == log.counts()


@pytest.mark.parametrize("ids, error, message", [(None, TypeError, "beacon_ids must be the layout's beacon identifiers"),
                                                 ("b0", TypeError, "beacon_ids must be"),
                                                 ((), ValueError, "no beacon identifiers")])
def test_beacon_ids_that_are_not_a_layout_are_refused(tmp_path, ids, error, message):
    path = write_chirps_csv(tmp_path / "chirps.csv", _log())
    with pytest.raises(error, match=message):
        read_chirps_csv(path, ids)
