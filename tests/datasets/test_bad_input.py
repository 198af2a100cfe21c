"""Hostile and careless input to the loaders: one rule per kind of bad value, the same in every format.

Each test feeds exactly one bad input and asserts the clear error (DataFormatError naming
file, line and column; ValueError naming a parameter) or the counted drop.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.fixtures import iasl as iasl_fx
from uwbwb import DataFormatError, DataNotFoundError, RangeLog
from uwbwb.datasets import cleaning, hanyang, iasl, lias, packets, tidy

HANYANG_HEADER = "timestamp,Distance,RSSI(dBm),RSSI_fp(dBm)"


def _hanyang_tree(tmp_path, distance: str):
    """A Hanyang static tree with one file whose second sample has ``Distance = distance``."""
    folder = tmp_path / hanyang.NAME / hanyang.STATIC_DIR / "LOS" / "height_50cm"
    folder.mkdir(parents=True)
    rows = [f"{1600000000 + k * 0.1:.1f},{d},-80.5,-82.0" for k, d in enumerate(["2.05", distance, "1.98"])]
    path = folder / "2m.csv"
    path.write_text("\n".join([HANYANG_HEADER, *rows]) + "\n")
    return path


def _steps(steps) -> dict[str, int]:
    return {s.name: s.n_affected for s in steps}


# --- one range rule: negative is an error, beyond MAX_RANGE_M a counted drop, in every loader --------

def test_hanyang_negative_range_is_an_error(tmp_path):
    path = _hanyang_tree(tmp_path, "-1")
    with pytest.raises(DataFormatError, match="negative range") as exc:
        hanyang.read_static_file(path)
    assert exc.value.line == 3 and exc.value.column == "Distance" and exc.value.path == path
    with pytest.raises(DataFormatError, match="negative range"):
        hanyang.load_static(tmp_path)


def test_hanyang_absurd_range_is_dropped_and_counted(tmp_path):
    path = _hanyang_tree(tmp_path, "1e9")
    sf = hanyang.read_static_file(path)
    assert _steps(sf.cleaning) == {"implausible ranges -> missing": 1}
    assert np.isnan(sf.samples["range_m"].iloc[1]) and sf.samples["range_m"].notna().sum() == 2
    df = hanyang.load_static(tmp_path)
    assert _steps(df.attrs["cleaning"])["implausible ranges -> missing"] == 1
    assert df["range_m"].isna().sum() == 1                     # never reaches range_m as 1e9
    assert hanyang.load_static(tmp_path, max_range_m=2e9)["range_m"].max() == 1e9   # the maximum is stated


def _tidy_ranges(tmp_path, value: str):
    path = tmp_path / "ranges.csv"
    path.write_text(f"t_s,anchor_id,range_m\n0,A1,2.5\n0,A2,{value}\n0.1,A1,2.6\n")
    return path


def test_tidy_absurd_range_is_dropped_and_counted(tmp_path):
    logs, steps = tidy.read_ranges_csv(_tidy_ranges(tmp_path, "1e9"), with_cleaning=True)
    assert _steps(steps) == {"implausible ranges -> missing": 1}
    assert np.isnan(logs["tag"].range_m[0, 1]) and logs["tag"].range_m[0, 0] == 2.5


def test_tidy_negative_range_is_an_error(tmp_path):
    with pytest.raises(DataFormatError, match="negative range") as exc:
        tidy.read_ranges_csv(_tidy_ranges(tmp_path, "-1"))
    assert exc.value.line == 3 and exc.value.column == "range_m"


def _packet_file(tmp_path, value: str, status: str = "OK", prefix: bytes = b""):
    path = tmp_path / "node.tsv"
    text = "timestamp\tanchor ID\tranging\tstatus\n" + "\n".join([
        "1000\t1\t2.50\tOK", f"1000\t2\t{value}\t{status}", "1130\t1\t2.60\tOK", "1130\t2\t3.10\tOK"]) + "\n"
    path.write_bytes(prefix + text.encode())
    return path


def test_packets_absurd_range_is_dropped_and_counted(tmp_path):
    pk = packets.read_packets(_packet_file(tmp_path, "1e9"))
    assert _steps(pk.cleaning)["implausible ranges -> missing"] == 1
    assert np.isnan(pk.ranges.range_m[0, 1]) and pk.ranges.range_m[1, 1] == 3.1


def test_packets_negative_range_is_an_error_unless_err(tmp_path):
    with pytest.raises(DataFormatError, match="negative range") as exc:
        packets.read_packets(_packet_file(tmp_path, "-1"))
    assert exc.value.line == 3 and exc.value.column == "ranging"
    pk = packets.read_packets(_packet_file(tmp_path, "-1", status="ERR"))   # an ERR number means nothing
    assert np.isnan(pk.ranges.range_m[0, 1]) and "implausible ranges -> missing" not in _steps(pk.cleaning)


def test_iasl_absurd_range_is_dropped_and_counted(tmp_path):
    iasl_fx.write_dataset(tmp_path / iasl.NAME, rng=np.random.default_rng(0), duration_s=4.0)
    path = tmp_path / iasl.NAME / "scenario1" / "uwb.csv"
    lines = path.read_text().split("\n")
    k = next(i for i, ln in enumerate(lines) if ln.strip() and ln.split("\t")[0].strip()[0].isdigit())
    fields = lines[k + 3].split("\t")
    fields[-1] = "1e9"
    lines[k + 3] = "\t".join(fields)
    path.write_text("\n".join(lines))
    uwb = iasl.read_uwb(path)
    assert _steps(uwb.cleaning)["implausible ranges -> missing"] == 1
    assert np.isnan(uwb.ranges.range_m[:, -1]).sum() >= 1 and np.nanmax(uwb.ranges.range_m) < cleaning.MAX_RANGE_M


def _lias_file(tmp_path, value: str):
    path = tmp_path / "UWB_dynamic_exp_x.csv"
    rows = []
    for k in range(3):
        r = [f"{2.0 + 0.01 * j:.2f}" for j in range(24)]
        if k == 1:
            r[5] = value
        rows.append(f"2022-08-15 9:59:48.{214 + 10 * k:03d}," + ",".join(r))
    path.write_text("\n".join(rows) + "\n")
    return path


def test_lias_absurd_range_is_dropped_and_counted(tmp_path):
    t, r, _, steps = lias.read_uwb_csv(_lias_file(tmp_path, "1e9"), return_cleaning=True)
    assert _steps(steps) == {"implausible ranges -> missing": 1} and np.isnan(r[1, 1, 2])


def test_one_maximum_for_every_loader():
    import inspect
    for f in (lias.read_uwb_csv, iasl.read_uwb, iasl.load_scenario, hanyang.read_static_file, hanyang.load_static,
              packets.read_packets, tidy.read_ranges_csv, tidy.load_recording):
        assert inspect.signature(f).parameters["max_range_m"].default == cleaning.MAX_RANGE_M, f.__qualname__


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), "100", True])
def test_max_range_must_be_a_positive_number(tmp_path, bad):
    with pytest.raises(ValueError, match="max_range_m"):
        tidy.read_ranges_csv(_tidy_ranges(tmp_path, "2.0"), max_range_m=bad)


# --- the package's own exceptions, never a raw library one ------------------------------------------

@pytest.mark.parametrize("reader", [lias.read_uwb_csv, lias.read_mocap_csv, packets.read_packets])
def test_missing_file_and_directory(tmp_path, reader):
    with pytest.raises(DataNotFoundError, match="no such file"):
        reader(tmp_path / "absent.csv")
    with pytest.raises(DataFormatError, match="is a directory"):
        reader(tmp_path)


@pytest.mark.parametrize("n_anchors, n_tags", [(8, 0), (0, 3), (8, -1), (8, 1.5), (True, 3)])
def test_lias_counts_must_be_positive_integers(tmp_path, n_anchors, n_tags):
    with pytest.raises(ValueError, match="n_anchors|n_tags"):
        lias.read_uwb_csv(_lias_file(tmp_path, "2.0"), n_anchors=n_anchors, n_tags=n_tags)


# --- consistency and resources -----------------------------------------------------------------------

def test_packets_accept_a_byte_order_mark_like_every_loader(tmp_path):
    pk = packets.read_packets(_packet_file(tmp_path, "3.00", prefix=b"\xef\xbb\xbf"))
    assert len(pk.ranges) == 2 and pk.ranges.range_m[0, 1] == 3.0


@pytest.mark.parametrize("reader", [packets.read_packets, tidy.read_ranges_csv, lias.read_mocap_csv])
def test_cr_only_file_gives_a_bounded_message(tmp_path, reader):
    path = tmp_path / "cr.csv"
    body = "\r".join(f"1{k:06d}\t1\t2.50\tOK" for k in range(20000))
    path.write_text("timestamp\tanchor ID\tranging\tstatus\r" + body)
    with pytest.raises(DataFormatError) as exc:
        reader(path)
    assert len(str(exc.value)) < 800 and "message cut" in str(exc.value)


def test_cleaning_rules_directly():
    t = np.array([0.0, 0.2, 0.1, 0.2, 0.3])
    lines = np.arange(2, 7)
    idx, steps = cleaning.order_rows("f.csv", t, lines, what="UWB", values=np.zeros((5, 1)))
    assert t[idx].tolist() == [0.0, 0.1, 0.2, 0.3]
    assert _steps(steps) == {"rows sorted by time": 2, "repeated rows dropped": 1}
    with pytest.raises(DataFormatError, match="two different UWB rows share time 0.2") as exc:
        cleaning.order_rows("f.csv", t, lines, what="UWB", values=np.arange(5.0))
    assert exc.value.line == 5
    with pytest.raises(DataFormatError, match="goes back") as exc:
        cleaning.order_rows("f.csv", t, lines, what="UWB", backwards="error")
    assert exc.value.line == 4
    with pytest.raises(DataFormatError, match="not a finite number"):
        cleaning.order_rows("f.csv", np.array([0.0, np.nan]), lines[:2], what="UWB")
    r, steps = cleaning.check_ranges("f.csv", np.array([[1.0, 0.0], [np.nan, 400.0]]), lines[:2],
                                     zero_is_missing=True)
    assert np.isnan(r).tolist() == [[False, True], [True, True]]
    assert _steps(steps) == {"zero ranges -> missing": 1, "implausible ranges -> missing": 1}
    with pytest.raises(ValueError, match="backwards"):
        cleaning.order_rows("f.csv", t, lines, what="UWB", backwards="ignore")


def test_range_log_from_every_loader_never_holds_out_of_range_values(tmp_path):
    log = RangeLog(np.arange(3) * 0.1, np.array([[1.0, 500.0], [2.0, 3.0], [4.0, 5.0]]), ("A1", "A2"), "tag")
    paths = tidy.write_ranges_csv(tmp_path / "r.csv", log)
    back, steps = tidy.read_ranges_csv(paths, with_cleaning=True)
    assert np.isnan(back["tag"].range_m[0, 1]) and _steps(steps)["implausible ranges -> missing"] == 1
