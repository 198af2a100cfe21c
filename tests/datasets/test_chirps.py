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
