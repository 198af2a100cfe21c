"""Property tests: mutated upstream files only ever raise DataFormatError.

Valid synthetic files (tests/fixtures) are damaged by a few random edits —
delete, duplicate or swap lines, truncate, replace a character, add or remove
a field, set a field to an out-of-range number — and fed to every reader and
loader of the iasl, hanyang, packets and tidy modules. The only exception allowed
is :class:`uwbwb.DataFormatError`; no warning may escape; when reading succeeds the
result is self-consistent, and every range is either within [0, max_range_m] or
missing with its removal counted (the range rule of uwbwb.datasets.cleaning).

Examples are derandomised so that a run is reproducible; set
``UWBWB_FUZZ_EXAMPLES`` to explore with more (random) examples.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.fixtures import hanyang as hanyang_fx
from tests.fixtures import iasl as iasl_fx
from uwbwb import DataFormatError, RangeLog, Recording
from uwbwb.datasets import hanyang, iasl, iasl_files, packets, tidy
from uwbwb.datasets.cleaning import MAX_RANGE_M

_EXPLORE = int(os.environ.get("UWBWB_FUZZ_EXAMPLES", "0"))


def fuzz_settings(n: int):
    return settings(max_examples=_EXPLORE or n, deadline=None, derandomize=not _EXPLORE,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


CHARS = [b"0", b"7", b".", b"-", b"e", b"E", b"\t", b",", b"\n", b"\r", b" ", b"x", b"#", b"\0", b"\xc3\xa9",
         b"\xff", b"[", b":"]
TOKENS = [b"1", b"-2.5", b"", b"nan", b"inf", b"OK", b"ERR", b"a1", b"1e308", b"99999999999999999999"]
#: Numbers outside what a range may be: negative (an error) or beyond MAX_RANGE_M (a counted drop).
OUT_OF_RANGE = [b"-1", b"-0.5", b"1e9", b"652.8", b"1e308", b"300.5"]

MUTATION = st.one_of(
    st.tuples(st.just("delete"), st.integers(0, 10**6)),
    st.tuples(st.just("duplicate"), st.integers(0, 10**6)),
    st.tuples(st.just("swap"), st.integers(0, 10**6), st.integers(0, 10**6)),
    st.tuples(st.just("truncate"), st.integers(0, 10**7)),
    st.tuples(st.just("replace"), st.integers(0, 10**7), st.sampled_from(CHARS)),
    st.tuples(st.just("add_field"), st.integers(0, 10**6), st.sampled_from(TOKENS)),
    st.tuples(st.just("remove_field"), st.integers(0, 10**6), st.integers(0, 100)),
    st.tuples(st.just("set_field"), st.integers(0, 10**6), st.integers(0, 100), st.sampled_from(OUT_OF_RANGE)),
)
MUTATIONS = st.lists(MUTATION, min_size=1, max_size=3)


def mutate(data: bytes, mutations, sep: bytes) -> bytes:
    """Apply the edits in order; indices wrap around the current content."""
    for m in mutations:
        kind = m[0]
        lines = data.split(b"\n")
        if kind == "delete":
            del lines[m[1] % len(lines)]
        elif kind == "duplicate":
            i = m[1] % len(lines)
            lines.insert(i, lines[i])
        elif kind == "swap":
            i, j = m[1] % len(lines), m[2] % len(lines)
            lines[i], lines[j] = lines[j], lines[i]
        elif kind == "truncate":
            data = data[: m[1] % (len(data) + 1)]
            continue
        elif kind == "replace":
            if data:
                k = m[1] % len(data)
                data = data[:k] + m[2] + data[k + 1:]
            continue
        elif kind == "add_field":
            i = m[1] % len(lines)
            lines[i] = lines[i] + sep + m[2]
        elif kind == "remove_field":
            i = m[1] % len(lines)
            fields = lines[i].split(sep)
            del fields[m[2] % len(fields)]
            lines[i] = sep.join(fields)
        elif kind == "set_field":
            i = m[1] % len(lines)
            fields = lines[i].split(sep)
            fields[m[2] % len(fields)] = m[3]
            lines[i] = sep.join(fields)
        data = b"\n".join(lines)
    return data


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """Valid files of every format, small."""
    root = tmp_path_factory.mktemp("fuzz")
    iasl_dir = root / "iasl"
    iasl_fx.write_dataset(iasl_dir / iasl.NAME, rng=np.random.default_rng(5), duration_s=8.0)
    han_dir = root / "hanyang"
    hanyang_fx.write_dataset(han_dir / hanyang.NAME, rng=np.random.default_rng(6), heights_cm=(50.0,),
                             distances_m=(2, 10), n=8)
    tidy_paths = iasl_fx.write_tidy_sample(root / "tidy")
    return {"iasl": iasl_dir, "hanyang": han_dir, "tidy": tidy_paths}


def _mutated_copy(src: Path, rel: str, mutations, sep: bytes, tmp: Path) -> Path:
    """Copy the tree ``src`` into ``tmp`` with file ``rel`` mutated; returns the mutated file."""
    dst = tmp / src.name
    shutil.copytree(src, dst)
    target = dst / rel
    target.write_bytes(mutate(target.read_bytes(), mutations, sep))
    return target


def _only_format_errors(call):
    """Run ``call``; a DataFormatError is an accepted outcome (returns None)."""
    try:
        return call()
    except DataFormatError as exc:
        assert exc.path.name and str(exc.path) in str(exc)
        return None


# --- iasl ------------------------------------------------------------------------------------

IASL_FILES = ["scenario1/uwb.csv", "scenario2/uwb.csv", "scenario1/imu.csv", "scenario2/gt.csv", "uwb.yaml"]


def _check_iasl_file(parsed) -> None:
    if isinstance(parsed, iasl_files.UwbFile):
        log = parsed.ranges
        assert log.range_m.shape == (len(log.t_s), len(log.anchor_ids))
        assert len(parsed.device) == len(log) == parsed.system_time_ms.size
        assert not np.any(log.range_m <= 0) and not np.any(log.range_m > MAX_RANGE_M)
    elif isinstance(parsed, iasl_files.ImuFile):
        assert parsed.imu.acc_mps2.shape == parsed.imu.gyro_radps.shape == (len(parsed.imu), 3)
    elif isinstance(parsed, iasl_files.GtFile):
        assert parsed.truth.rot.shape == (len(parsed.truth), 3, 3)
    else:
        assert parsed.pos_m.shape == (len(parsed.ids), 3)
    for step in getattr(parsed, "cleaning", ()):
        assert step.n_affected > 0


@pytest.mark.filterwarnings("error")
@fuzz_settings(50)
@given(which=st.sampled_from(IASL_FILES), mutations=MUTATIONS)
def test_iasl_readers(base, which, mutations):
    reader = {"uwb.csv": iasl.read_uwb, "imu.csv": iasl.read_imu, "gt.csv": iasl.read_gt,
              "uwb.yaml": iasl.read_anchors}[Path(which).name]
    with tempfile.TemporaryDirectory() as tmp:
        path = _mutated_copy(base["iasl"] / iasl.NAME, which, mutations,
                             b"," if which.endswith("yaml") else b"\t", Path(tmp))
        parsed = _only_format_errors(lambda: reader(path))
        if parsed is not None:
            _check_iasl_file(parsed)


@pytest.mark.filterwarnings("error")
@fuzz_settings(12)
@given(which=st.sampled_from(IASL_FILES[:4]), mutations=MUTATIONS)
def test_iasl_load_scenario(base, which, mutations):
    scenario = which.split("/")[0]
    with tempfile.TemporaryDirectory() as tmp:
        _mutated_copy(base["iasl"] / iasl.NAME, which, mutations, b"\t", Path(tmp))
        rec = _only_format_errors(lambda: iasl.load_scenario(scenario, data_dir=tmp))
        if rec is not None:
            assert isinstance(rec, Recording) and rec.tags == ("tag",)
            assert rec.ranges["tag"].anchor_ids == rec.anchors.ids
            assert np.isfinite(rec.meta["truth_time_offset_s"])
            assert np.all(np.isfinite(rec.meta["truth_translation_m"]))
            assert rec.imu is None or np.all(np.diff(rec.imu.t_s) > 0)


# --- hanyang ---------------------------------------------------------------------------------

HANYANG_FILES = ["Static_measurements/LOS/height_50.0cm/2m.csv", "Static_measurements/LOS/height_50.0cm/10m.csv",
                 "Static_measurements/NLOS/height_50.0cm/2m.csv", "Static_measurements/NLOS/height_50.0cm/10m.csv"]


def _check_samples(df, cleaning) -> None:
    for col in ("t_s", "range_m", "rssi_dbm", "rssi_fp_dbm", "t_unix_s", "line"):
        assert col in df.columns
    assert df["t_unix_s"].notna().all()
    r = df["range_m"]
    assert ((r >= 0) & (r <= MAX_RANGE_M)).sum() + r.isna().sum() == len(df)
    dropped = sum(s.n_affected for s in cleaning if s.name == "implausible ranges -> missing")
    assert r.isna().sum() == dropped           # a missing range is one the range rule removed, counted


@pytest.mark.filterwarnings("error")
@fuzz_settings(50)
@given(which=st.sampled_from(HANYANG_FILES), mutations=MUTATIONS)
def test_hanyang_read_static_file(base, which, mutations):
    with tempfile.TemporaryDirectory() as tmp:
        path = _mutated_copy(base["hanyang"] / hanyang.NAME, which, mutations, b",", Path(tmp))
        sf = _only_format_errors(lambda: hanyang.read_static_file(path))
        if sf is not None:
            _check_samples(sf.samples, sf.cleaning)
            assert np.all(np.diff(sf.samples["t_unix_s"]) > 0)
            assert sf.header_only == sf.samples.empty


@pytest.mark.filterwarnings("error")
@fuzz_settings(20)
@given(which=st.sampled_from(HANYANG_FILES), mutations=MUTATIONS)
def test_hanyang_load_static(base, which, mutations):
    with tempfile.TemporaryDirectory() as tmp:
        _mutated_copy(base["hanyang"] / hanyang.NAME, which, mutations, b",", Path(tmp))
        df = _only_format_errors(lambda: hanyang.load_static(tmp))
        if df is not None:
            _check_samples(df, df.attrs["cleaning"])
            assert list(df.columns[: len(hanyang.SAMPLE_COLUMNS)]) == list(hanyang.SAMPLE_COLUMNS)
            assert all(s.n_affected > 0 for s in df.attrs["cleaning"])
        listing = _only_format_errors(lambda: hanyang.list_recordings(tmp))
        if listing is not None and df is not None:
            assert listing["n_samples"].sum() == len(df)


# --- tidy ------------------------------------------------------------------------------------

@pytest.mark.filterwarnings("error")
@fuzz_settings(50)
@given(which=st.sampled_from(["ranges", "anchors", "truth"]), mutations=MUTATIONS)
def test_tidy_readers_and_loader(base, which, mutations):
    paths = base["tidy"]
    with tempfile.TemporaryDirectory() as tmp:
        target = _mutated_copy(paths[which].parent, paths[which].name, mutations, b",", Path(tmp))
        files = {k: target.parent / p.name for k, p in paths.items()}
        reader = {"ranges": tidy.read_ranges_csv, "anchors": tidy.read_anchors_csv,
                  "truth": tidy.read_truth_csv}[which]
        parsed = _only_format_errors(lambda: reader(target))
        if which == "anchors" and parsed is not None:
            assert parsed.pos_m.shape == (len(parsed.ids), 3)
        elif parsed is not None:
            for tag, item in parsed.items():
                assert len(item) > 0 and (item.tag_id == tag if which == "ranges" else item.dim in (2, 3))
                if which == "ranges":
                    r = item.range_m[np.isfinite(item.range_m)]
                    assert np.all((r >= 0) & (r <= MAX_RANGE_M))
        rec = _only_format_errors(lambda: tidy.load_recording(files["ranges"], files["anchors"], files["truth"]))
        if rec is not None:
            assert all(log.anchor_ids == rec.anchors.ids for log in rec.ranges.values())
            assert set(rec.truth) <= set(rec.ranges)


# --- packets ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def packet_file(tmp_path_factory):
    rng = np.random.default_rng(7)
    r = rng.uniform(0.5, 40.0, (12, 5))
    r[rng.random(r.shape) < 0.1] = np.nan
    log = RangeLog(np.arange(12) * 0.13, r, tuple(str(k) for k in range(1, 6)), "node")
    return packets.write_packets(tmp_path_factory.mktemp("packets") / "node.tsv", log, t0_ms=1452967702506)


@pytest.mark.filterwarnings("error")
@fuzz_settings(60)
@given(mutations=MUTATIONS)
def test_packets_reader(packet_file, mutations):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / packet_file.name
        path.write_bytes(mutate(packet_file.read_bytes(), mutations, b"\t"))
        pk = _only_format_errors(lambda: packets.read_packets(path))
        if pk is not None:
            r = pk.ranges.range_m
            finite = r[np.isfinite(r)]
            assert np.all((finite >= 0) & (finite <= MAX_RANGE_M))
            assert np.all(np.diff(pk.ranges.t_s) > 0)
            text = path.read_text(encoding="utf-8", errors="replace").splitlines()[1:]
            ok_values = [float(f[2]) for f in (ln.split("\t") for ln in text) if len(f) == 4 and f[3].strip() == "OK"]
            n_huge = sum(v > MAX_RANGE_M for v in ok_values)
            dropped = sum(s.n_affected for s in pk.cleaning if s.name == "implausible ranges -> missing")
            assert dropped == n_huge    # every out-of-range OK value is counted, none silently
