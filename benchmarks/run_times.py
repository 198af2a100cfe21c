"""The notebooks' run times: measured by one command, written into one table (``docs/run_times.md``).

Each selected notebook runs once per mode, one notebook at a time, in a fresh kernel (kernel start included):

* ``class``: a student's Run All of the copy ``make class`` hands out (``uwbwb.classroom.run_class``:
  ``FAST = True``, ``CLASS = True``, the answer key's predictions written; the handout is made after the clock stops);
* ``fast``: ``reproduce --quick --only NN`` (``FAST = True``);
* ``full``: ``reproduce --only NN`` (full fidelity), only with ``--full`` (tens of minutes per notebook).

``--from-reproduce DIR`` instead takes the full-mode times of a finished ``reproduce --force`` into ``DIR`` (each
notebook's own wall time, from ``DIR/<notebook>.cache.json``): the notebooks ran as ``reproduce`` runs them, as many
at once as ``--jobs`` allowed, each in one process; ``--load`` says what else the machine was doing.

The numba kernels are compiled into their cache first (``python -m uwbwb.filters.twins``, as ``make env`` does at
install time), so no notebook's time includes compiling them. Every (notebook, mode) row of the table carries its wall time, the date, the machine (CPU and cores) and the
load average when that notebook started (it includes this command's previous notebook). A run of some notebooks
or modes replaces those rows and keeps the others. It then writes the table's times into the notebook fronts'
*Run time* lines, README.md's and TEACHING.md's quoted lists and the routes' timing tables (:func:`write_quotes`);
``tests/test_classroom_times.py`` fails when one of them disagrees with it.

A script beside the benchmarks rather than a ``uwbwb`` command: it measures the workbench, it is not part of
what a lecturer or a student runs, and the package does not grow for it.

Run:  python benchmarks/run_times.py [--only 00 03] [--modes class fast] [--full] [--table docs/run_times.md]
      python benchmarks/run_times.py --from-reproduce reports --jobs 2 --load "idle machine" [--commit 33b1571]
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
        out.setdefault(e.notebook, {m: NOT_MEASURED for m in MODES})[e.mode] = format_time(round(e.seconds, 1))  # as written
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


TIME = r"\d+ min(?: \d+ s)?|\d+ s"
#: A quoted list in README.md / TEACHING.md: ``class mode: 00 28 s, 01 34 s, ...`` (also ``FAST:`` and ``full:``).
QUOTED_LIST = re.compile(rf"\b(class mode|FAST|full):(\s*)((?:0\d (?:{TIME}|not measured)(?:,\s*)?)+)", re.I)
QUOTED_ITEM = re.compile(rf"\b(0\d) ({TIME}|not measured)")
#: A front's *Run time* line: ``class mode 41 s, [FAST](GLOSSARY.md#fast) 1 min 2 s, [full](...) 34 min``.
FRONT_ITEM = re.compile(rf"(\bclass mode |\[FAST\]\([^)]*\) |\[full\]\([^)]*\) )({TIME}|not measured)")
_MODE_OF = {"class mode": "class", "fast": "fast", "full": "full"}


def _minutes(time: str) -> int:
    m = re.fullmatch(r"(?:(\d+) min)?(?: ?(\d+) s)?", time)
    return math.ceil((60 * int(m.group(1) or 0) + int(m.group(2) or 0)) / 60)


def quote(text: str, by_nb: dict[str, dict[str, str]]) -> str:
    """``text`` (README.md, TEACHING.md) with every quoted list's times set to the table's, and each route's timing
    table (TEACHING.md) re-added: a block's minutes are its Run All (rounded up) plus its assumed minutes."""
    def one_list(m):
        mode = _MODE_OF[m.group(1).lower()]
        items = QUOTED_ITEM.sub(lambda i: f"{i.group(1)} {by_nb[i.group(1)][mode]}", m.group(3))
        return f"{m.group(1)}:{m.group(2)}{items}"

    text = QUOTED_LIST.sub(one_list, text)
    out, clock = [], None
    for line in text.split("\n"):
        cells = _cells(line) if line.startswith("| ") else []
        if len(cells) == 6 and cells[0] in ("1", "") and cells[1] in ("introduction", "total"):
            clock = 0 if cells[1] == "introduction" else clock
        if len(cells) == 6 and clock is not None and line.startswith("| "):
            block, what, run, assumed, minutes, span = cells
            if what == "total":
                line, clock = f"| | total | | | {clock} | |", None
            else:
                nb = re.match(r"\*?\*?(0\d)\b", what)
                run = by_nb[nb.group(1)]["class"] if nb else run
                minutes = (_minutes(run) if nb else 0) + int(re.match(r"(\d+) min", assumed).group(1))
                start, clock = clock, clock + minutes
                line = (f"| {block} | {what} | {run} | {assumed} | {minutes} | "
                        f"{start // 60}:{start % 60:02d}–{clock // 60}:{clock % 60:02d} |")
        out.append(line)
    return "\n".join(out)


def quote_front(front: str, times_of_nb: dict[str, str]) -> str:
    """A notebook front with its *Run time* line set to the table's times."""
    mode = {"class mode ": "class"}
    return "\n".join(FRONT_ITEM.sub(lambda m: m.group(1) + times_of_nb[mode.get(m.group(1)) or
                                                                      ("fast" if "FAST" in m.group(1) else "full")],
                                     ln) if "Run time" in ln else ln for ln in front.split("\n"))


def write_quotes(entries: list[Entry]) -> list[Path]:
    """Write the table's times into the notebook fronts, README.md and TEACHING.md; the files changed."""
    import json

    by_nb = {nb[:2]: row for nb, row in times(entries).items()}
    changed = []
    for path in (ROOT / "README.md", ROOT / "TEACHING.md"):
        old = path.read_text(encoding="utf-8")
        if (new := quote(old, by_nb)) != old:
            path.write_text(new, encoding="utf-8")
            changed.append(path)
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        nb = json.loads(path.read_text(encoding="utf-8"))
        front = "".join(nb["cells"][0]["source"])
        if (new := quote_front(front, by_nb[path.stem[:2]])) != front:
            nb["cells"][0]["source"] = new.splitlines(keepends=True)
            path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
            changed.append(path)
    return changed


def from_reproduce(out: Path, *, jobs: int, load: str, commit: str = "") -> list[Entry]:
    """The full-mode rows of a ``reproduce --force`` run into ``out``: each notebook's wall time from its cache entry
    (written when it succeeded), dated by that file; a notebook without one is an error, naming the file."""
    import json

    entries = []
    for path in sorted(out.glob("*.cache.json")):
        seconds = json.loads(path.read_text(encoding="utf-8")).get("seconds")
        if not isinstance(seconds, (int, float)) or not math.isfinite(seconds):
            raise ValueError(f"{path}: no 'seconds' of a finished run")
        date = dt.datetime.fromtimestamp(path.stat().st_mtime, dt.timezone.utc).strftime("%Y-%m-%d %H:%M")
        at = f" at {commit}" if commit else ""
        entries.append(Entry(path.name.removesuffix(".cache.json"), "full", float(seconds), date, machine(), load,
                             f"`reproduce --force` of all notebooks, {jobs} at once{at}"))
    if not entries:
        raise ValueError(f"{out}: no <notebook>.cache.json (run `reproduce --force --out {out}` first)")
    return entries


def main(argv: list[str] | None = None) -> int:
    from uwbwb import reproduce

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="+", metavar="NB", help="notebooks whose stem starts with NB (default all)")
    ap.add_argument("--modes", nargs="+", choices=MODES[:2], default=list(MODES[:2]), help="modes (class fast)")
    ap.add_argument("--full", action="store_true", help="measure full fidelity too (tens of minutes per notebook)")
    ap.add_argument("--table", type=Path, default=TABLE, help="the table file (default docs/run_times.md)")
    ap.add_argument("--from-reproduce", type=Path, metavar="DIR",
                    help="take the full times of a finished `reproduce --force --out DIR` instead of measuring")
    ap.add_argument("--jobs", type=int, default=os.cpu_count(), help="with --from-reproduce: notebooks it ran at once")
    ap.add_argument("--load", default="not recorded", help="with --from-reproduce: what else the machine was doing")
    ap.add_argument("--commit", default="", help="with --from-reproduce: the commit it ran")
    args = ap.parse_args(argv)
    if args.from_reproduce is not None:
        entries = parse(args.table.read_text(encoding="utf-8")) if args.table.is_file() else []
        entries = merge(entries, from_reproduce(args.from_reproduce, jobs=args.jobs, load=args.load, commit=args.commit))
        args.table.write_text(render(entries), encoding="utf-8")
        changed = write_quotes(entries)
        print(f"written: {args.table}; the times quoted in {', '.join(p.name for p in changed) or 'no file (all agree)'}")
        return 0
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
    changed = write_quotes(entries)
    print(f"written: {args.table}; the times quoted in {', '.join(p.name for p in changed) or 'no file (all agree)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
