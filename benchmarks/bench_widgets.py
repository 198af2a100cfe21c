"""Panel latency: time from a control change to the updated readout/figure, per notebook.

For every notebook (``notebooks/*.ipynb`` by default) and every ``uw.widgets.Panel``
in it, the first control (slider, else dropdown, else number box) is changed
``--repeats`` times, one step at a time, starting from the panel's default values:

* **browser** — JupyterLab in headless Chromium (the harness of
  ``tests/test_browser.py``): arrow key / selection to the first DOM change of the
  panel's readout or figure, so kernel round trip, PNG transfer and rendering count;
* **headless** — the same notebook executed in a separate Python process with
  IPython, the same changes made with ``panel.set``: the render alone (wall clock, and
  the process's CPU time, which a loaded machine disturbs less).

Prints the medians, their ratio (browser / headless, the reference measured in
the same run) and flags panels whose median exceeds 0.5 s. The notebooks run
with their own default parameters; ``--fast`` injects ``FAST=True`` as CI does.

Usage::

    .venv/bin/python benchmarks/bench_widgets.py [--fast] [--repeats 5] [--no-browser] [NOTEBOOK ...]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: A panel whose median update takes longer than this is flagged.
SLOW_S = 0.5


# --------------------------------------------------------------------------- headless

def _next_value(control, direction: int):
    """``(value, direction)`` one step from the control's value, like the browser change."""
    import ipywidgets as widgets

    if isinstance(control, (widgets.FloatSlider, widgets.IntSlider, widgets.FloatLogSlider)):
        log = isinstance(control, widgets.FloatLogSlider)
        pos = math.log(control.value, control.base) if log else control.value
        if not control.min <= pos + direction * control.step <= control.max:
            direction = -direction
        pos = pos + direction * control.step
        if log:
            return control.base ** pos, direction
        return (round(pos, 12) if isinstance(control, widgets.FloatSlider) else pos), direction
    if isinstance(control, widgets.Dropdown):
        values = control._options_values
        return values[(control.index + 1) % len(values)], direction
    return control.value + 1, direction


def _pick_control(panel):
    """Name of the control the browser harness changes: first slider, dropdown, number box."""
    import ipywidgets as widgets

    kinds = [(widgets.FloatSlider, widgets.IntSlider, widgets.FloatLogSlider), (widgets.Dropdown,),
             (widgets.IntText, widgets.BoundedIntText, widgets.FloatText, widgets.BoundedFloatText)]
    for kind in kinds:
        for name, control in panel.controls.items():
            if isinstance(control, kind):
                return name
    return None


def headless_worker(notebook: Path, repeats: int) -> list[dict]:
    """Execute ``notebook`` in this process (IPython), time ``panel.set`` for each panel."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    import gc

    import nbformat
    from IPython.core.interactiveshell import InteractiveShell

    from uwbwb.widgets import Panel

    class Shell(InteractiveShell):
        def enable_gui(self, gui=None):  # `%matplotlib inline` needs no event loop here
            pass

    os.chdir(notebook.parent)
    shell = Shell.instance()
    nb = nbformat.read(notebook, as_version=4)
    with contextlib.redirect_stdout(sys.stderr):  # stdout carries the result only
        for i, cell in enumerate(c for c in nb.cells if c.cell_type == "code"):
            result = shell.run_cell(cell.source, store_history=True)
            if not result.success:
                err = result.error_in_exec or result.error_before_exec
                raise RuntimeError(f"{notebook.name}: code cell {i + 1} failed: {err!r}")
    # Every panel stays alive through its controls' observers, bound to a name or not.
    panels = [o for o in gc.get_objects() if isinstance(o, Panel)]
    rows = []
    for panel in panels:
        name = _pick_control(panel)
        row = {"title": panel.title, "control": name, "times_s": [], "cpu_s": [], "error": None}
        direction = +1
        for _ in range(repeats if name else 0):
            value, direction = _next_value(panel.controls[name], direction)
            t0, c0 = time.perf_counter(), time.process_time()
            panel.set(**{name: value})
            row["times_s"].append(time.perf_counter() - t0)
            row["cpu_s"].append(time.process_time() - c0)
            if panel.last_error is not None:
                row["error"] = repr(panel.last_error)
                break
        rows.append(row)
    return rows


def run_headless(notebook: Path, repeats: int) -> list[dict]:
    """:func:`headless_worker` in a fresh interpreter (clean state for each notebook)."""
    proc = subprocess.run([sys.executable, __file__, "--headless-worker", str(notebook),
                           "--repeats", str(repeats)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{notebook.name}: headless run failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------- browser

def run_browser(server, page, notebook: Path, repeats: int) -> list[dict]:
    """Open ``notebook`` in JupyterLab in ``page``, change each panel's first control ``repeats`` times."""
    from tests.browser_support import change_control, close_notebook, open_and_run

    rows = []
    try:
        open_and_run(page, server, notebook.name)
        panels = page.locator(".uwbwb-panel")
        for i in range(panels.count()):
            panel = panels.nth(i)
            panel.scroll_into_view_if_needed()
            title = panel.locator(".uwbwb-title").first.inner_text().strip()
            row = {"title": title, "control": None, "times_s": [], "error": None}
            direction = +1
            for _ in range(repeats):
                try:
                    change = change_control(page, panel, name=notebook.name, index=i, direction=direction)
                except AssertionError as exc:
                    row["error"] = " ".join(str(exc).split())
                    break
                direction = change.direction
                row["control"] = change.control
                row["times_s"].append(change.latency_s)
            rows.append(row)
    finally:
        close_notebook(page, server, notebook.name)
    return rows


# --------------------------------------------------------------------------- table

def _median(times):
    return statistics.median(times) if times else float("nan")


def _match(browser_rows, headless_rows):
    """Pair panels by title (and order among equal titles)."""
    pairs, pool = [], list(headless_rows)
    for b in browser_rows:
        h = next((r for r in pool if r["title"] == b["title"]), None)
        if h is not None:
            pool.remove(h)
        pairs.append((b, h))
    pairs += [(None, h) for h in pool]
    return pairs


def print_table(results: dict[str, list[tuple[dict | None, dict | None]]], repeats: int) -> int:
    header = (f"{'notebook':<24} {'panel':<34} {'control':<18} {'browser s':>10} {'headless s':>11} "
              f"{'CPU s':>6} {'ratio':>6}  flag")
    print(f"\nmedian of {repeats} control changes, from the panel's default values")
    print(header)
    print("-" * len(header))
    n_slow = 0
    for nb, pairs in results.items():
        if not pairs:
            print(f"{nb:<24} (no panel)")
        for b, h in pairs:
            title = (b or h)["title"]
            control = (b and b["control"]) or (h and h["control"]) or "-"
            tb = _median(b["times_s"]) if b else float("nan")
            th = _median(h["times_s"]) if h else float("nan")
            ch = _median(h.get("cpu_s", [])) if h else float("nan")
            ratio = tb / th if b and h and th > 0 else float("nan")
            worst = max((t for t in (tb, th) if t == t), default=float("nan"))
            flags = []
            if worst > SLOW_S:
                flags.append(f"SLOW (> {SLOW_S} s)")
                n_slow += 1
            for side, row in (("browser", b), ("headless", h)):
                if row and row["error"]:
                    flags.append(f"{side} error: {row['error'][:160]}")
            print(f"{nb[:24]:<24} {title[:34]:<34} {str(control)[:18]:<18} {tb:>10.3f} {th:>11.3f} "
                  f"{ch:>6.3f} {ratio:>6.1f}  {'; '.join(flags)}")
    print(f"\n{n_slow} panel(s) slower than {SLOW_S} s")
    return n_slow


# --------------------------------------------------------------------------- main

def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("notebooks", nargs="*", type=Path, help="notebooks (default: notebooks/*.ipynb)")
    parser.add_argument("--fast", action="store_true", help="inject FAST=True (as CI does)")
    parser.add_argument("--repeats", type=int, default=5, help="control changes per panel (default 5)")
    parser.add_argument("--no-browser", action="store_true", help="headless timings only")
    parser.add_argument("--headless-worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    if args.headless_worker:
        print(json.dumps(headless_worker(args.headless_worker, args.repeats)))
        return 0

    from tests.browser_support import CHROMIUM, lab_session, prepare_notebook, project_notebooks

    notebooks = args.notebooks or project_notebooks()
    if not notebooks:
        print("no notebooks to benchmark")
        return 0
    use_browser = not args.no_browser
    if use_browser and not CHROMIUM.exists():
        print(f"{CHROMIUM} not found: headless timings only")
        use_browser = False

    with tempfile.TemporaryDirectory(prefix="uwbwb-bench-") as tmp:
        root = Path(tmp)
        prepared = []
        for nb in notebooks:
            parameters = {"FAST": True} if args.fast else {}
            parameters["SUMMARY_PATH"] = str(root / f"{nb.stem}.summary.json")
            prepared.append(prepare_notebook(nb, root, parameters))
        headless = {}
        for nb in prepared:
            t0 = time.perf_counter()
            headless[nb.name] = run_headless(nb, args.repeats)
            print(f"headless  {nb.name}: {time.perf_counter() - t0:.1f} s", flush=True)
        in_browser = {nb.name: [] for nb in prepared}
        if use_browser:
            with lab_session(root) as (server, page):
                for nb in prepared:
                    t0 = time.perf_counter()
                    in_browser[nb.name] = run_browser(server, page, nb, args.repeats)
                    print(f"browser   {nb.name}: {time.perf_counter() - t0:.1f} s", flush=True)
    results = {nb.stem: _match(in_browser[nb.name], headless[nb.name]) for nb in prepared}
    print_table(results, args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
