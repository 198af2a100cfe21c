"""Measurement-packet files (Zupanec et al., Table 1): loader, writer, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from uwbwb import Anchors, DataFormatError, RangeLog
from uwbwb.datasets import packets

# Table 1 of the paper, verbatim (one packet of six anchors), then a second packet.
TABLE_1 = """timestamp\tanchor ID\tranging\tstatus
1452967702506\t1\t21.49\tOK
1452967702506\t2\t12.64\tOK
1452967702506\t3\t0.00\tERR
1452967702506\t4\t2.80\tOK
1452967702506\t5\t13.51\tOK
1452967702506\t6\t11.29\tOK
1452967702636\t1\t21.40\tOK
1452967702636\t2\t12.70\tOK
1452967702636\t3\t7.31\tOK
1452967702636\t4\t0.00\tERR
1452967702636\t5\t13.44\tOK
1452967702636\t6\t11.35\tOK
"""


def _write(tmp_path, text, name="node.tsv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_table_1_loads(tmp_path):
    pk = packets.read_packets(_write(tmp_path, TABLE_1))
    log = pk.ranges
    assert log.anchor_ids == ("1", "2", "3", "4", "5", "6")
    np.testing.assert_allclose(log.t_s, [0.0, 0.130])
    assert pk.t0_ms == 1452967702506 and log.t0 == 1452967702506
    np.testing.assert_allclose(log.range_m[0], [21.49, 12.64, np.nan, 2.80, 13.51, 11.29])
    assert np.isnan(log.range_m[1, 3]) and log.range_m[1, 2] == 7.31
    assert pk.n_err == {"1": 0, "2": 0, "3": 1, "4": 1, "5": 0, "6": 0}
    assert sum(pk.n_absent.values()) == 0
    steps = {s.name: s.n_affected for s in pk.cleaning}
    assert steps == {"ERR status -> missing": 2}
    assert log.tag_id == "node"


def test_err_is_missing_whatever_the_number(tmp_path):
    text = TABLE_1.replace("1452967702506\t3\t0.00\tERR", "1452967702506\t3\t99.00\tERR")
    log = packets.read_packets(_write(tmp_path, text)).ranges
    assert np.isnan(log.range_m[0, 2])


def test_round_trip_exact_on_cm_grid(tmp_path, rng):
    T, n = 50, 6
    t_s = np.arange(T) * 0.130 + rng.integers(0, 3, T) * 0.001
    r = np.round(rng.uniform(0.5, 25.0, (T, n)), 2)
    r[rng.random((T, n)) < 0.1] = np.nan
    log = RangeLog(t_s, r, tuple(str(i) for i in range(1, n + 1)), "H", 1452967702506)
    path = packets.write_packets(tmp_path / "h.tsv", log)
    back = packets.read_packets(path, tag_id="H")
    # the reader puts t_s = 0 at the first packet; t0_ms carries the offset
    shift_s = (back.t0_ms - 1452967702506) / 1000
    np.testing.assert_allclose(back.ranges.t_s + shift_s, log.t_s, atol=5e-7)
    np.testing.assert_array_equal(np.isnan(back.ranges.range_m), np.isnan(r))
    np.testing.assert_allclose(back.ranges.range_m, r, atol=1e-12)
    assert back.t0_ms == 1452967702506 + round(1000 * t_s[0])
    assert sum(back.n_err.values()) == int(np.isnan(r).sum())
    first = path.read_text().splitlines()[:2]
    assert first[0] == "timestamp\tanchor ID\tranging\tstatus"
    assert int(first[1].split("\t")[0]) == back.t0_ms


def test_writer_refuses_epochs_in_one_millisecond(tmp_path):
    log = RangeLog([0.0, 0.0004], np.ones((2, 2)), ("1", "2"))
    with pytest.raises(ValueError, match="same millisecond"):
        packets.write_packets(tmp_path / "x.tsv", log)


def test_anchor_ids_fix_order_and_absent_anchors_are_counted(tmp_path):
    # anchor 5 is missing from the second packet; anchor 7 never reports
    lines = [ln for ln in TABLE_1.splitlines() if not ln.startswith("1452967702636\t5\t")]
    pk = packets.read_packets(_write(tmp_path, "\n".join(lines) + "\n"),
                              anchor_ids=["6", "5", "4", "3", "2", "1", "7"])
    assert pk.anchor_ids == ("6", "5", "4", "3", "2", "1", "7")
    assert pk.n_absent["5"] == 1 and pk.n_absent["7"] == 2
    assert np.isnan(pk.ranges.range_m[1, 1]) and pk.ranges.range_m[0, 1] == 13.51
    assert any(s.name.startswith("anchor absent") and s.n_affected == 3 for s in pk.cleaning)


def test_unsorted_packets_are_sorted_and_counted(tmp_path):
    lines = TABLE_1.splitlines()
    text = "\n".join([lines[0]] + lines[7:] + lines[1:7]) + "\n"
    pk = packets.read_packets(_write(tmp_path, text))
    np.testing.assert_allclose(pk.ranges.t_s, [0.0, 0.130])
    assert pk.ranges.range_m[0, 0] == 21.49
    assert {s.name: s.n_affected for s in pk.cleaning}["rows sorted by time"] == len(lines) - 1   # every row moved


def test_exact_duplicates_dropped_conflicts_rejected(tmp_path):
    lines = TABLE_1.splitlines()
    pk = packets.read_packets(_write(tmp_path, "\n".join(lines + [lines[3]]) + "\n"))
    assert {s.name: s.n_affected for s in pk.cleaning}["repeated rows dropped"] == 1
    conflict = lines + ["1452967702506\t2\t12.99\tOK"]
    with pytest.raises(DataFormatError, match="two different .timestamp, anchor ID. rows") as exc:
        packets.read_packets(_write(tmp_path, "\n".join(conflict) + "\n", "c.tsv"))
    assert exc.value.line == 14


def test_blank_lines_are_counted(tmp_path):
    text = TABLE_1.replace("OK\n1452967702636\t1", "OK\n\n1452967702636\t1")
    pk = packets.read_packets(_write(tmp_path, text))
    assert {s.name: s.n_affected for s in pk.cleaning}["blank lines skipped"] == 1
    assert len(pk.ranges) == 2


@pytest.mark.parametrize("line, problem, column", [
    ("1452967702506.5\t1\t2.00\tOK", "integer number of milliseconds", "timestamp"),
    ("-5\t1\t2.00\tOK", "integer number of milliseconds", "timestamp"),
    ("99999999999999999999999\t1\t2.00\tOK", "out of range", "timestamp"),
    ("1452967702506\t1\tabc\tOK", "not a finite number", "ranging"),
    ("1452967702506\t1\tnan\tOK", "not a finite number", "ranging"),
    ("1452967702506\t1\t-2.00\tOK", "negative range", "ranging"),
    ("1452967702506\t1\t2.00\tok", "neither 'OK' nor 'ERR'", "status"),
    ("1452967702506\t1\t2.00", "3 tab-separated fields, expected 4", None),
    ("1452967702506\t1\t2.00\tOK\textra", "5 tab-separated fields, expected 4", None),
    ("1452967702506 1 2.00 OK", "1 tab-separated fields, expected 4", None),
    ("1452967702506\t\t2.00\tOK", "empty or contains white space", "anchor ID"),
])
def test_bad_rows_name_file_line_and_problem(tmp_path, line, problem, column):
    lines = TABLE_1.splitlines()
    lines.insert(4, line)
    path = _write(tmp_path, "\n".join(lines) + "\n")
    with pytest.raises(DataFormatError, match=problem) as exc:
        packets.read_packets(path)
    assert exc.value.line == 5 and exc.value.path == path and exc.value.column == column
    assert str(path) in str(exc.value) and "line 5" in str(exc.value)


def test_unknown_anchor_is_an_error(tmp_path):
    with pytest.raises(DataFormatError, match="not one of the expected") as exc:
        packets.read_packets(_write(tmp_path, TABLE_1), anchor_ids=["1", "2", "3", "4", "5"])
    assert exc.value.line == 7


@pytest.mark.parametrize("text, problem", [
    ("", "empty file"),
    ("time\tanchor\trange\tstatus\n1\t1\t1.0\tOK\n", "header"),
    ("timestamp,anchor ID,ranging,status\n", "header"),
    ("timestamp\tanchor ID\tranging\tstatus\n", "no packets"),
    ("timestamp\tanchor ID\tranging\tstatus\n\n\n", "no packets"),
])
def test_bad_files(tmp_path, text, problem):
    with pytest.raises(DataFormatError, match=problem):
        packets.read_packets(_write(tmp_path, text))


def test_not_utf8(tmp_path):
    p = tmp_path / "bin.tsv"
    p.write_bytes(b"timestamp\tanchor ID\tranging\tstatus\n\xff\xfe\x00\n")
    with pytest.raises(DataFormatError, match="UTF-8"):
        packets.read_packets(p)


def test_load_recording_combines_nodes(tmp_path):
    anchors = Anchors(tuple("123456"), np.column_stack([np.arange(6.0), np.zeros(6), np.full(6, 4.0)]))
    a = _write(tmp_path, TABLE_1, "L.tsv")
    b = _write(tmp_path, TABLE_1.replace("0.00\tERR", "5.00\tOK"), "H.tsv")
    rec = packets.load_recording({"L": a, "H": b}, anchors, name="tour1-fast")
    assert rec.tags == ("L", "H") and rec.label == "packets/tour1-fast"
    assert np.isfinite(rec.ranges["H"].range_m).all()
    assert [s.name for s in rec.cleaning] == ["L: ERR status -> missing"]
    assert rec.meta["t0_ms"] == {"L": 1452967702506, "H": 1452967702506}


# ------------------------------------------------------------------ mutation tests

def _mutate(text: str, data) -> str:
    lines = text.split("\n")
    i = data.draw(st.integers(0, len(lines) - 1))
    kind = data.draw(st.sampled_from(["char", "delete_line", "dup_line", "field", "truncate", "insert"]))
    line = lines[i]
    if kind == "char" and line:
        j = data.draw(st.integers(0, len(line) - 1))
        c = data.draw(st.sampled_from(list("\t ,.-x0E9\r") + ["", "\x00", "é"]))
        lines[i] = line[:j] + c + line[j + 1:]
    elif kind == "delete_line":
        del lines[i]
    elif kind == "dup_line":
        lines.insert(i, line)
    elif kind == "field":
        fields = line.split("\t")
        k = data.draw(st.integers(0, len(fields) - 1))
        fields[k] = data.draw(st.sampled_from(["", "NaN", "inf", "1e400", "-0.0", "ERR", "OK", "1.2.3",
                                               "99999999999999999999999", " 7 ", "0x10"]))
        lines[i] = "\t".join(fields)
    elif kind == "truncate":
        lines[i] = line[: data.draw(st.integers(0, max(len(line) - 1, 0)))]
    else:
        lines.insert(i, data.draw(st.text(alphabet="0123456789\tOKER.- ab", max_size=30)))
    return "\n".join(lines)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_mutated_files_load_or_raise_data_format_error(tmp_path, data):
    text = TABLE_1
    for _ in range(data.draw(st.integers(1, 3))):
        text = _mutate(text, data)
    path = tmp_path / "mut.tsv"
    path.write_text(text, encoding="utf-8")
    # the loader's line rule: lines end at \n only (a stray \r stays inside its line), so count the same way
    n_lines = max(len(text.split("\n")), 1)
    try:
        pk = packets.read_packets(path)
    except DataFormatError as exc:
        assert exc.path == path
        assert exc.line is None or 1 <= exc.line <= n_lines
        return
    # whatever loaded is a consistent log: finite non-negative or NaN, increasing time
    r = pk.ranges.range_m
    assert np.all(np.isnan(r) | (r >= 0))
    assert np.all(np.diff(pk.ranges.t_s) > 0)
    n_rows = sum(1 for ln in text.split("\n")[1:] if ln.strip())
    n_dup = sum(s.n_affected for s in pk.cleaning if s.name == "repeated rows dropped")
    n_absent = sum(pk.n_absent.values())
    assert r.size == n_rows - n_dup + n_absent          # every row is accounted for
