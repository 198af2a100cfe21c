"""The notebooks' run times: measured by one command, written into one table (``docs/run_times.md``).

Each selected notebook runs once per mode, one notebook at a time, in a fresh kernel (kernel start included):

* ``class``: a student's Run All of the copy ``make class`` hands out (``uwbwb.classroom.run_class``:
  ``FAST = True``, ``CLASS = True``, the answer key's predictions written; the handout is made after the clock stops);
* ``fast``: ``reproduce --quick --only NN`` (``FAST = True``);
* ``full``: ``reproduce --only NN`` (full fidelity), only with ``--full`` (tens of minutes per notebook).

The numba kernels are compiled into their cache first (``python -m uwbwb.filters.twins``, as ``make env`` does at
install time), so no notebook's time includes compiling them. Every (notebook, mode) row of the table carries its wall time, the date, the machine (CPU and cores) and the
load average when that notebook started (it includes this command's previous notebook). A run of some notebooks
or modes replaces those rows and keeps the others. The notebook fronts, README.md and TEACHING.md quote the table;
``tests/test_classroom_times.py`` fails when one of them disagrees with it.

A script beside the benchmarks rather than a ``uwbwb`` command: it measures the workbench, it is not part of
what a lecturer or a student runs, and the package does not grow for it.

Run:  python benchmarks/run_times.py [--only 00 03] [--modes class fast] [--full] [--table docs/run_times.md]
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "docs" / "run_times.md"
MODES = ("class", "fast", "full")
#: Column titles of the modes in the table of times.
TITLES = {"class": "class mode", "fast": "FAST", "full": "full"}
NOT_MEASURED = "not measured"
COMMAND = "`benchmarks/run_times.py`"

HEADER = """# Notebook run times

The one table of the notebooks' run times: the notebook fronts, `README.md` and `TEACHING.md` quote it, and
`tests/test_classroom_times.py` fails when one of them disagrees with it. Written by `python
benchmarks/run_times.py` (`make times`), which runs each notebook alone, one after the other, in a fresh kernel
(kernel start included; the numba kernels compiled into their cache beforehand, as at install): **class mode** is
a student's Run All of the copy `make class` hands out (`FAST = True`, `CLASS = True`), **FAST** is `reproduce
--quick --only NN`, **full** is `reproduce --only NN` (measured only with `--full`). Rows the command did not
measure are kept as they are, with their own date and source. Every time is a wall time on the machine named in its
row; the load average is the machine's when the notebook started (on a shared machine other work slows a run:
compare rows under similar load).

| notebook | class mode | FAST | full |
|---|---|---|---|
"""

MEASUREMENTS = """
## Measurements

| notebook | mode | seconds | date (UTC) | machine | load average at start (1, 5, 15 min) | source |
|---|---|---|---|---|---|---|
"""


@dataclass(frozen=True)
class Entry:
    """One measured (notebook, mode): the wall time and where it comes from."""

    notebook: str
    mode: str
    seconds: float
    date: str
    machine: str
    load: str
    source: str


def format_time(seconds: float) -> str:
    """``"42 s"``, ``"3 min 5 s"`` (under 10 min) or ``"34 min"`` (rounded to the minute)."""
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 600:
        m, r = divmod(s, 60)
        return f"{m} min {r} s" if r else f"{m} min"
    return f"{round(seconds / 60)} min"


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def parse(text: str) -> list[Entry]:
    """The rows of the *Measurements* table of a table file."""
    body = text.split("## Measurements", 1)[1]
    entries = []
    for line in body.splitlines():
        cells = _cells(line) if line.startswith("|") else []
        if len(cells) == 7 and cells[1] in MODES:
            entries.append(Entry(cells[0], cells[1], float(cells[2]), *cells[3:]))
    return entries


def times(entries: list[Entry]) -> dict[str, dict[str, str]]:
    """``{notebook: {mode: "1 min 5 s" or "not measured"}}``, as the table of times shows them."""
    out: dict[str, dict[str, str]] = {}
    for e in entries:
        out.setdefault(e.notebook, {m: NOT_MEASURED for m in MODES})[e.mode] = format_time(e.seconds)
    return out


def render(entries: list[Entry]) -> str:
    """The table file of ``entries``: the table of times, then the measurements they come from."""
    order = sorted(entries, key=lambda e: (e.notebook, MODES.index(e.mode)))
    grid = "".join(f"| {nb} | " + " | ".join(row[m] for m in MODES) + " |\n" for nb, row in times(order).items())
    rows = "".join(f"| {e.notebook} | {e.mode} | {e.seconds:.1f} | {e.date} | {e.machine} | {e.load} | {e.source} |\n"
                   for e in order)
    return HEADER + grid + MEASUREMENTS + rows


def merge(old: list[Entry], new: list[Entry]) -> list[Entry]:
    """``old`` with the (notebook, mode) rows of ``new`` replaced or added."""
    fresh = {(e.notebook, e.mode) for e in new}
    return [e for e in old if (e.notebook, e.mode) not in fresh] + list(new)


def machine() -> str:
    """CPU model and the cores this process may use."""
    model = ""
    try:
        model = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                      if ln.startswith("model name")), "")
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return f"{re.sub(r'[|]', '/', model) or 'unknown CPU'}, {cores} cores"


def _load() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def measure(notebook: Path, mode: str, out: Path) -> float:
    """Wall seconds of one run of ``notebook`` in ``mode``; raises when the run fails."""
    from uwbwb import classroom, reproduce

    if mode == "class":
        runs = classroom.run_class([notebook], out / "class", log=lambda _: None)
        if runs[0]["error"]:
            raise RuntimeError(f"{notebook.stem} in class mode: {runs[0]['error']}")
        return runs[0]["seconds"]
    result = reproduce.reproduce(quick=mode == "fast", only=[notebook.stem], out=out / mode,
                                 notebooks_dir=notebook.parent, force=True, jobs=1)
    if not result.ok:
        raise RuntimeError(f"{notebook.stem} in {mode} mode: {result.runs[0].error}")
    return result.runs[0].seconds


def main(argv: list[str] | None = None) -> int:
    from uwbwb import reproduce

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="+", metavar="NB", help="notebooks whose stem starts with NB (default all)")
    ap.add_argument("--modes", nargs="+", choices=MODES[:2], default=list(MODES[:2]), help="modes (class fast)")
    ap.add_argument("--full", action="store_true", help="measure full fidelity too (tens of minutes per notebook)")
    ap.add_argument("--table", type=Path, default=TABLE, help="the table file (default docs/run_times.md)")
    args = ap.parse_args(argv)
    notebooks = reproduce.select_notebooks(ROOT / "notebooks", args.only)
    modes = [m for m in MODES if m in args.modes or (m == "full" and args.full)]
    entries = parse(args.table.read_text(encoding="utf-8")) if args.table.is_file() else []
    where = machine()
    subprocess.run([sys.executable, "-m", "uwbwb.filters.twins"], check=True)     # as at install: no compile timed
    print(f"# run times of {len(notebooks)} notebook(s), modes {', '.join(modes)}, on {where}; load {_load()}")
    with tempfile.TemporaryDirectory(prefix="uwbwb-times-") as tmp:
        for mode in modes:
            for nb in notebooks:
                date, load = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M"), _load()
                seconds = measure(nb, mode, Path(tmp))
                if not math.isfinite(seconds):
                    raise RuntimeError(f"{nb.stem} {mode}: no time")
                entry = Entry(nb.stem, mode, seconds, date, where, load, COMMAND)
                print(f"{nb.stem:24s} {mode:6s} {format_time(seconds):>10s}  (load at start {load})", flush=True)
                entries = merge(entries, [entry])
                args.table.write_text(render(entries), encoding="utf-8")     # each row as soon as it is measured
    print(f"written: {args.table}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
