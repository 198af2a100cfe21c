"""Memory of the tidy ranges reader: peak memory while reading, against the parsed arrays.

Writes a ranges file of ``--rows`` rows (``t_s,anchor_id,range_m,status,tag_id``,
8 anchors, 2 tags, 1 % ``ERR`` rows) and reads it in fresh processes with

* **typed** — :func:`uwbwb.datasets.tidy.read_ranges_csv` (pandas' C parser into
  typed columns, the path every well-formed file takes);
* **field by field** — the same reader forced onto its field-by-field fallback (a
  Python string per field, the way every file was read before; today only files
  the typed parser cannot read exactly go this way, to find the offending line).

For each: the increase of the peak resident memory over the process's memory
before the call (imports done, file in the page cache), divided by the file size
and by the size of the parsed arrays (``t_s``, ``range_m``, one code per row for
anchor, status and tag, ``line_no``: 8 + 8 + 3 x 8 + 8 bytes per row). The ratios
are measured in the same run; the wall time of each read is printed for context.

Usage::

    .venv/bin/python benchmarks/bench_tidy_memory.py [--rows 400000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

_CHILD = r"""
import json, resource, sys, time
from pathlib import Path
sys.path.insert(0, sys.argv[3])
from uwbwb.datasets import tidy

def rss_kib():
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])

path, mode = sys.argv[1], sys.argv[2]
if mode == "fields":
    tidy._fast_table = lambda *a, **k: None      # force the field-by-field reader
Path(path).read_bytes()                           # file into the page cache, not counted below
before = rss_kib()
t0 = time.perf_counter()
logs = tidy.read_ranges_csv(path)
seconds = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"delta_peak_bytes": (peak - before) * 1024, "seconds": seconds,
                  "epochs": sum(len(v) for v in logs.values())}))
"""


def write_file(path: Path, n_rows: int) -> None:
    import numpy as np

    rng = np.random.default_rng(0)
    n_anchors, tags = 8, ("front", "back")
    n_epochs = n_rows // (n_anchors * len(tags))
    t = np.repeat(np.arange(n_epochs) * 0.01, n_anchors * len(tags))
    anchor = np.tile(np.repeat([f"A{k + 1}" for k in range(n_anchors)], 1), n_epochs * len(tags))
    tag = np.tile(np.repeat(tags, n_anchors), n_epochs)
    r = rng.uniform(0.5, 12.0, t.size)
    err = rng.random(t.size) < 0.01
    with path.open("w") as fh:
        fh.write("t_s,anchor_id,range_m,status,tag_id\n")
        for ti, ai, ri, ei, gi in zip(t, anchor, r, err, tag):
            fh.write(f"{float(ti)!r},{ai},{'' if ei else repr(float(ri))},{'ERR' if ei else 'OK'},{gi}\n")


def measure(path: Path, mode: str) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(path), mode, str(ROOT)], check=True,
                         capture_output=True, text=True)
    return json.loads(out.stdout)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=400_000)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "ranges.csv"
        write_file(path, args.rows)
        size = path.stat().st_size
        arrays = args.rows * (8 + 8 + 3 * 8 + 8)
        print(f"ranges file: {args.rows} rows, {size / 1e6:.1f} MB; parsed arrays {arrays / 1e6:.1f} MB")
        results = {mode: measure(path, mode) for mode in ("typed", "fields")}
    for mode, r in results.items():
        d = r["delta_peak_bytes"]
        print(f"  {mode:>6}: peak +{d / 1e6:7.1f} MB = {d / size:5.1f} x file, {d / arrays:5.1f} x arrays "
              f"({r['seconds']:.2f} s)")
    ratio = results["fields"]["delta_peak_bytes"] / max(results["typed"]["delta_peak_bytes"], 1)
    speed = results["fields"]["seconds"] / results["typed"]["seconds"]
    print(f"field-by-field / typed: {ratio:.1f} x the memory, {speed:.1f} x the time")


if __name__ == "__main__":
    main()
