"""One source of run times: ``docs/run_times.md`` (written by ``benchmarks/run_times.py``) and every time the notebook
fronts, README.md and TEACHING.md quote from it, including the two routes' lab-sheet timings."""

from __future__ import annotations

import importlib.util
import math
import re
import sys
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
_spec = importlib.util.spec_from_file_location("run_times", ROOT / "benchmarks" / "run_times.py")
rt = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("run_times", rt)
_spec.loader.exec_module(rt)

TIME = r"\d+ min(?: \d+ s)?|\d+ s"
_LINK = re.compile(r"\[([^\]]*)\]\([^)\s]*\)")
#: A quoted list: ``class mode: 00 28 s, 01 34 s, ...`` (also ``FAST:`` and ``full:``).
_LIST = re.compile(rf"\b(class mode|FAST|full):\s*((?:0\d (?:{TIME}|not measured)(?:,\s*)?)+)", re.I)
_ITEM = re.compile(rf"\b(0\d) ({TIME}|not measured)")
_MODE = {"class mode": "class", "fast": "fast", "full": "full"}


def table() -> dict[str, dict[str, str]]:
    """``{"00": {mode: time}}`` of docs/run_times.md."""
    return {nb[:2]: row for nb, row in rt.times(rt.parse((ROOT / "docs" / "run_times.md").read_text("utf-8"))).items()}


def _plain(markdown: str) -> str:
    return " ".join(_LINK.sub(r"\1", markdown).replace("**", "").split())


def front_problems(stem: str, front: str, times: dict) -> list[str]:
    """How a teaching front's *Run time* line disagrees with the table (each mode quoted once, as the table has it)."""
    line = _plain(next((ln for ln in front.splitlines() if "Run time" in ln), ""))
    problems = []
    for mode, label in (("class", "class mode"), ("fast", "FAST"), ("full", "full")):
        found = re.findall(rf"\b{label} ({TIME}|not measured)", line)
        want = times[stem[:2]][mode]
        if found != [want]:
            problems.append(f"{stem}: {label} {found or 'not quoted'} in its front, {want!r} in the table")
    return problems


def quote_problems(name: str, text: str, times: dict) -> list[str]:
    """How the per-notebook times of a Markdown text disagree with the table: every ``NN <time>`` must sit in a
    quoted list (``class mode: 00 28 s, ...``) and equal the table's time of that notebook and mode."""
    text = _plain(text)
    problems, listed = [], set()
    for m in _LIST.finditer(text):
        mode = _MODE[m.group(1).lower()]
        for item in _ITEM.finditer(m.group(2)):
            listed.add(m.start(2) + item.start())
            want = times.get(item.group(1), {}).get(mode)
            if item.group(2) != want:
                problems.append(f"{name}: {m.group(1)} {item.group(1)} {item.group(2)}, the table has {want!r}")
    for item in _ITEM.finditer(text):
        if item.start() not in listed:
            problems.append(f"{name}: '{item.group(0)}' is not in a quoted list (class mode: / FAST: / full:)")
    return problems


def route_tables(teaching: str) -> dict[str, list[list[str]]]:
    """The timing table of each route of TEACHING.md: ``{route heading: rows of cells}``."""
    out = {}
    for part in re.split(r"^### ", teaching, flags=re.M)[1:]:
        heading, body = part.split("\n", 1)
        if heading.startswith("Route"):
            out[heading.strip()] = [[c.strip() for c in ln.strip().strip("|").split("|")]
                                    for ln in body.split("**Timing")[1].splitlines()
                                    if ln.startswith("|") and not ln.startswith("|---")][1:]
    return out


def route_problems(route: str, rows: list[list[str]], times: dict) -> list[str]:
    """A route's timing table: each run time is the table's class time of its notebook, each block its run time
    (rounded up to the minute) plus the assumed minutes, the clock adds up, and the route ends by 2:00."""
    problems, clock = [], 0
    *blocks, total = rows
    for block, what, run, assumed, minutes, span in blocks:
        nb = re.match(r"\*?\*?(0\d)\b", what)
        run_min = 0
        if nb:
            want = times[nb.group(1)]["class"]
            if run != want:
                problems.append(f"{route}: {what}: Run All {run!r}, the table's class mode {want!r}")
            m = re.fullmatch(rf"(?:(\d+) min)?(?: ?(\d+) s)?", run)
            run_min = math.ceil((60 * int(m.group(1) or 0) + int(m.group(2) or 0)) / 60) if m else 0
        elif run != "—":
            problems.append(f"{route}: {what}: a run time without a notebook")
        expect = run_min + int(re.match(r"(\d+) min", assumed).group(1))
        if int(minutes) != expect:
            problems.append(f"{route}: {what}: {minutes} min, but {run} + {assumed} make {expect}")
        start, end = clock, clock + int(minutes)
        if span != f"{start // 60}:{start % 60:02d}–{end // 60}:{end % 60:02d}":
            problems.append(f"{route}: {what}: clock {span}, want {start // 60}:{start % 60:02d}–{end // 60}:{end % 60:02d}")
        clock = end
    if int(total[4]) != clock:
        problems.append(f"{route}: total {total[4]} min, the blocks add up to {clock}")
    if clock > 120:
        problems.append(f"{route}: {clock} min, over the two hours")
    return problems


# ------------------------------------------------------------------ the table

def test_the_table_is_as_the_command_writes_it_and_has_every_notebook():
    text = (ROOT / "docs" / "run_times.md").read_text("utf-8")
    entries = rt.parse(text)
    assert rt.render(entries) == text                       # the table of times is made from the measurements
    assert {e.notebook for e in entries} == {p.stem for p in NOTEBOOKS}
    for e in entries:
        assert re.fullmatch(r"20\d\d-\d\d-\d\d( \d\d:\d\d)?", e.date) and e.machine and e.load and e.source, e
    measured = {(e.notebook, e.mode) for e in entries}
    assert {(p.stem, m) for p in NOTEBOOKS for m in ("class", "fast")} <= measured    # class and FAST measured


def test_time_format_and_a_partial_run_keeps_the_other_rows():
    assert [rt.format_time(s) for s in (4.4, 59.4, 59.6, 125, 180, 599.4, 1161)] == \
        ["4 s", "59 s", "1 min", "2 min 5 s", "3 min", "9 min 59 s", "19 min"]
    a = rt.Entry("00_x", "class", 10.0, "2026-01-01 00:00", "cpu, 2 cores", "1.00, 1.00, 1.00", "`x`")
    b = rt.Entry("00_x", "full", 900.0, "2025-12-01", "2 cores", "4–11", "README at abc")
    new = rt.Entry("00_x", "class", 20.0, "2026-01-02 00:00", "cpu, 2 cores", "2.00, 1.00, 1.00", "`x`")
    merged = rt.merge([a, b], [new])
    assert sorted(merged, key=lambda e: e.mode) == [new, b]
    assert rt.parse(rt.render(merged)) == sorted(merged, key=lambda e: rt.MODES.index(e.mode))
    assert rt.times(merged) == {"00_x": {"class": "20 s", "fast": "not measured", "full": "15 min"}}
    odd = rt.Entry("00_x", "fast", 46.52, "2026-01-02 00:00", "cpu, 2 cores", "1.00, 1.00, 1.00", "`x`")
    assert rt.times(rt.parse(rt.render([odd]))) == rt.times([odd])     # the grid is what the written row gives


# ------------------------------------------------------------------ the quotes

@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_each_front_quotes_the_table(path):
    front = nbformat.read(path, as_version=4).cells[0].source
    assert front_problems(path.stem, front, table()) == []
    assert "../docs/run_times.md" in front


def test_readme_and_teaching_quote_the_table():
    times = table()
    readme = (ROOT / "README.md").read_text("utf-8")
    teaching = (ROOT / "TEACHING.md").read_text("utf-8")
    assert quote_problems("README.md", readme, times) == []
    assert quote_problems("TEACHING.md", teaching, times) == []
    quoted = {_MODE[m.group(1).lower()] for m in _LIST.finditer(_plain(readme))}
    assert quoted == {"class", "fast", "full"}                  # README quotes every mode


def test_two_routes_of_at_most_two_hours_from_the_measured_run_times_and_the_assumed_minutes():
    routes = route_tables((ROOT / "TEACHING.md").read_text("utf-8"))
    assert [re.findall(r"0\d", name) for name in routes] == [["00", "03", "01"], ["00", "03", "05"]]
    for name, rows in routes.items():
        assert route_problems(name, rows, table()) == []
        assert [re.match(r"\*?\*?(0\d)", r[1]).group(1) for r in rows[:-1] if re.match(r"\*?\*?0\d", r[1])] == \
            re.findall(r"0\d", name)


def test_the_checks_see_a_time_that_disagrees():
    times = {"00": {"class": "28 s", "fast": "40 s", "full": "1 min 54 s"}}
    good = "**Run time** ([table](../docs/run_times.md)): class mode 28 s, [FAST](G.md#fast) 40 s, full 1 min 54 s."
    assert front_problems("00_q", good, times) == []
    assert len(front_problems("00_q", good.replace("40 s", "41 s"), times)) == 1
    assert len(front_problems("00_q", good.replace("class mode 28 s, ", ""), times)) == 1
    assert quote_problems("R", "class mode: 00 28 s. FAST: 00 40 s", times) == []
    assert len(quote_problems("R", "class mode: 00 29 s", times)) == 1
    assert len(quote_problems("R", "notebook 00 30 s alone", times)) == 1          # a time outside a list
    rows = [["1", "intro", "—", "5 min", "5", "0:00–0:05"], ["2", "**00** x", "28 s", "20 min", "21", "0:05–0:26"],
            ["", "total", "", "", "26", ""]]
    assert route_problems("R", rows, times) == []
    late = [rows[0], ["2", "**00** x", "28 s", "120 min", "121", "0:05–2:06"], ["", "total", "", "", "126", ""]]
    assert route_problems("R", late, times) == ["R: 126 min, over the two hours"]
    wrong = [rows[0], ["2", "**00** x", "28 s", "20 min", "20", "0:05–0:25"], ["", "total", "", "", "25", ""]]
    assert len(route_problems("R", wrong, times)) == 1


def test_the_command_writes_the_quotes_the_checks_read():
    """``run_times.quote`` / ``quote_front`` put another table's times into README, TEACHING and a front so that
    every check agrees with that table (and the texts as committed already agree with this one)."""
    entries = rt.parse((ROOT / "docs" / "run_times.md").read_text("utf-8"))
    other = [rt.Entry(e.notebook, e.mode, e.seconds / 3 + 7, e.date, e.machine, e.load, e.source) for e in entries]
    here = {nb[:2]: row for nb, row in rt.times(entries).items()}
    there = {nb[:2]: row for nb, row in rt.times(other).items()}
    teaching = (ROOT / "TEACHING.md").read_text("utf-8")
    for name in ("README.md", "TEACHING.md"):
        text = (ROOT / name).read_text("utf-8")
        assert rt.quote(text, here) == text
        assert quote_problems(name, rt.quote(text, there), there) == []
        assert quote_problems(name, rt.quote(text, there), here) != []
    for route, rows in route_tables(rt.quote(teaching, there)).items():
        assert route_problems(route, rows, there) == []
    front = nbformat.read(NOTEBOOKS[1], as_version=4).cells[0].source
    assert front_problems(NOTEBOOKS[1].stem, rt.quote_front(front, there["01"]), there) == []


def test_full_times_taken_from_a_reproduce_run_are_each_notebooks_own(tmp_path):
    """``--from-reproduce``: one full row per notebook, its seconds the run's cache entry; a run without a finished
    notebook, or an entry without seconds, is an error naming the folder or file."""
    (tmp_path / "00_quickstart.cache.json").write_text('{"key": "k", "inputs": {}, "seconds": 63.3}')
    (tmp_path / "05_uwb_ins_fusion.cache.json").write_text('{"key": "k", "inputs": {}, "seconds": 776.2}')
    entries = rt.from_reproduce(tmp_path, jobs=2, load="idle", commit="abc1234")
    assert [(e.notebook, e.mode, e.seconds) for e in entries] == [("00_quickstart", "full", 63.3),
                                                                  ("05_uwb_ins_fusion", "full", 776.2)]
    assert all("2 at once at abc1234" in e.source and e.load == "idle" for e in entries)
    assert rt.times(entries)["05_uwb_ins_fusion"]["full"] == "13 min"
    (tmp_path / "06_scoreboard.cache.json").write_text('{"key": "k", "inputs": {}}')
    with pytest.raises(ValueError, match="06_scoreboard.cache.json"):
        rt.from_reproduce(tmp_path, jobs=2, load="idle")
    with pytest.raises(ValueError, match="no <notebook>.cache.json"):
        rt.from_reproduce(tmp_path / "empty", jobs=2, load="idle")
