"""Execute the notebooks headless and collect their headline numbers.

``python -m uwbwb reproduce`` (or :func:`reproduce`) runs every notebook in
``notebooks/`` (sorted by name) with papermill on the ``python3`` kernel and
writes, for each notebook ``<stem>``, into the output folder (default
``reports/``):

* ``<stem>.ipynb`` — the executed notebook (also when it failed: the failing
  cell holds the traceback);
* ``<stem>.html`` — the same, rendered with nbconvert;
* ``<stem>.summary.json`` — the headline numbers the notebook published to its
  ``SUMMARY_PATH`` parameter (``uw.metrics.Summary.publish``): a JSON list of
  rows with keys ``notebook, quantity, value, unit, paper_value, data``.

Then it aggregates all summaries into ``summary.json`` (one list of rows) and
``summary.md`` (a table of the numbers next to the paper's values, and a status
table: notebook, ok/failed, seconds, first line of the error).

Parameters passed to every notebook: ``SUMMARY_PATH`` always, ``FAST=True``
under ``quick``, plus any given explicitly. All notebooks run even if one
fails; the run is unsuccessful if a notebook failed or wrote no valid summary.
"""

from __future__ import annotations

import ast
import datetime as _dt
import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

from .datasets.discovery import PROJECT_ROOT

#: Notebooks run by default.
NOTEBOOKS_DIR = PROJECT_ROOT / "notebooks"
#: Default output folder.
REPORTS_DIR = PROJECT_ROOT / "reports"
#: Kernel the notebooks are executed with.
KERNEL_NAME = "python3"
#: Keys of every summary row, in display order.
SUMMARY_KEYS = ("notebook", "quantity", "value", "unit", "paper_value", "data")
#: Parameters set by the runner itself; they cannot be overridden.
RESERVED_PARAMETERS = ("SUMMARY_PATH",)


@dataclass(frozen=True)
class NotebookRun:
    """Outcome of one notebook.

    Attributes
    ----------
    notebook
        Notebook stem, e.g. ``"00_quickstart"``.
    source
        The input notebook.
    executed
        The executed notebook written to the output folder.
    html
        Its HTML rendering (None when rendering failed).
    summary
        Where the notebook was asked to write its summary.
    seconds
        Execution time in seconds (kernel start included).
    error
        None when the notebook ran and wrote a valid summary; else the reason
        (first line of the exception, or the summary problem).
    rows
        The summary rows it published (empty when none).
    """

    notebook: str
    source: Path
    executed: Path
    html: Path | None
    summary: Path
    seconds: float
    error: str | None
    rows: tuple[dict, ...] = ()

    @property
    def ok(self) -> bool:
        return self.error is None

    @property
    def status(self) -> str:
        return "ok" if self.ok else "failed"


@dataclass(frozen=True)
class ReproduceResult:
    """All runs of one :func:`reproduce` call.

    Attributes
    ----------
    runs
        One :class:`NotebookRun` per notebook, in execution order.
    out_dir
        The output folder.
    summary_json, summary_md
        The aggregated summary files.
    """

    runs: tuple[NotebookRun, ...]
    out_dir: Path
    summary_json: Path
    summary_md: Path

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.runs)

    @property
    def failed(self) -> tuple[NotebookRun, ...]:
        return tuple(r for r in self.runs if not r.ok)

    @property
    def rows(self) -> list[dict]:
        return [row for run in self.runs for row in run.rows]

    @property
    def exit_code(self) -> int:
        return 0 if self.ok else 1


def parse_parameter_value(text: str) -> Any:
    """A ``-p KEY VALUE`` value: a Python literal when it parses as one, else the string.

    ``"3"`` → 3, ``"0.5"`` → 0.5, ``"True"`` → True, ``"None"`` → None,
    ``"[1, 2]"`` → [1, 2], ``"'x'"`` → ``"x"``, ``"lias"`` → ``"lias"``.
    """
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        return text


def select_notebooks(notebooks_dir: str | os.PathLike | None = None,
                     only: Iterable[str] | None = None) -> list[Path]:
    """Notebooks to run, sorted by file name.

    Parameters
    ----------
    notebooks_dir
        Folder of ``*.ipynb`` files; default ``notebooks/`` in the project.
    only
        Keep notebooks whose file name or stem equals, or whose stem starts
        with, one of these (``"00"``, ``"00_quickstart"``, ``"00_quickstart.ipynb"``).

    Raises
    ------
    ValueError
        No notebooks in the folder, or an ``only`` pattern that matches none.
    """
    notebooks_dir = Path(NOTEBOOKS_DIR if notebooks_dir is None else notebooks_dir)
    found = sorted(notebooks_dir.glob("*.ipynb"))
    if not found:
        raise ValueError(f"no notebooks (*.ipynb) in {notebooks_dir}")
    if only is None:
        return found
    patterns = list(only)
    unmatched = [p for p in patterns if not any(_matches(nb, p) for nb in found)]
    if unmatched:
        raise ValueError(f"no notebook matches {', '.join(map(repr, unmatched))}; "
                         f"available: {', '.join(nb.stem for nb in found)}")
    return [nb for nb in found if any(_matches(nb, p) for p in patterns)]


def _matches(notebook: Path, pattern: str) -> bool:
    pattern = pattern.removesuffix(".ipynb")
    return bool(pattern) and notebook.stem.startswith(pattern)


def _first_line(exc: BaseException) -> str:
    ename, evalue = getattr(exc, "ename", None), getattr(exc, "evalue", None)
    text = f"{ename}: {evalue}" if ename else f"{type(exc).__name__}: {exc}"
    where = getattr(exc, "exec_count", None)
    line = (text.strip().splitlines() or [type(exc).__name__])[0]
    return f"{line} (cell [{where}])" if where is not None else line


def read_summary(path: Path, notebook: str) -> tuple[list[dict], str | None]:
    """Rows of a notebook's summary file and the problem with it (None when valid)."""
    if not path.is_file():
        return [], f"no summary file: the notebook wrote nothing to SUMMARY_PATH ({path})"
    try:
        rows = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        return [], f"summary file {path.name} is not valid JSON ({exc})"
    if not isinstance(rows, list) or not rows:
        return [], f"summary file {path.name} must hold a non-empty JSON list of rows"
    for i, row in enumerate(rows):
        if not isinstance(row, dict) or set(row) != set(SUMMARY_KEYS):
            keys = sorted(row) if isinstance(row, dict) else type(row).__name__
            return [], f"summary file {path.name}, row {i}: keys must be {', '.join(SUMMARY_KEYS)}, got {keys}"
        if row["notebook"] != notebook:
            return [], f"summary file {path.name}, row {i}: names notebook {row['notebook']!r}, not {notebook!r}"
    return [{k: row[k] for k in SUMMARY_KEYS} for row in rows], None


def _export_html(executed: Path, html: Path) -> None:
    import nbformat
    from nbconvert import HTMLExporter

    body, _ = HTMLExporter().from_notebook_node(nbformat.read(executed, as_version=4))
    html.write_text(body, encoding="utf-8")


def run_notebook(source: Path, out_dir: Path, parameters: Mapping[str, Any], *,
                 timeout_s: float | None = None, kernel_name: str = KERNEL_NAME) -> NotebookRun:
    """Execute one notebook into ``out_dir`` and read its summary (see :func:`reproduce`)."""
    import papermill as pm

    stem = source.stem
    executed, html, summary = (out_dir / f"{stem}.ipynb", out_dir / f"{stem}.html",
                               out_dir / f"{stem}.summary.json")
    for stale in (executed, html, summary):
        stale.unlink(missing_ok=True)  # a failed run must not show an older run's results
    params = {**parameters, "SUMMARY_PATH": str(summary)}
    error = None
    t0 = time.perf_counter()
    try:
        pm.execute_notebook(str(source), str(executed), parameters=params, kernel_name=kernel_name,
                            cwd=str(source.parent), progress_bar=False, log_output=False,
                            execution_timeout=timeout_s)
    except Exception as exc:  # any failure of one notebook is reported; the others still run
        error = _first_line(exc)
    seconds = time.perf_counter() - t0

    if executed.is_file():
        try:
            _export_html(executed, html)
        except Exception as exc:  # rendering problems are reported like execution problems
            html = None
            error = error or f"HTML export failed: {_first_line(exc)}"
    else:
        html = None
    rows, problem = read_summary(summary, stem)
    if error is None:
        error = problem
    return NotebookRun(notebook=stem, source=source, executed=executed, html=html, summary=summary,
                       seconds=seconds, error=error, rows=tuple(rows))


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        text = "nan" if math.isnan(value) else f"{value:.4g}"
    else:
        text = str(value)
    return text.replace("|", r"\|").replace("\n", " ")


def _table(header: list[str], rows: list[list[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return lines


def summary_markdown(runs: Iterable[NotebookRun], parameters: Mapping[str, Any] | None = None) -> str:
    """The ``summary.md`` text: headline numbers, then the run status of every notebook."""
    runs = list(runs)
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    out = ["# Reproduction summary", "",
           f"Generated by `python -m uwbwb reproduce` on {stamp}."]
    if parameters:
        out.append("Parameters: " + ", ".join(f"`{k}={v!r}`" for k, v in parameters.items()) + ".")
    out += ["", "## Headline numbers", ""]
    rows = [[row[k] for k in SUMMARY_KEYS] for run in runs for row in run.rows]
    if rows:
        out += _table(["notebook", "quantity", "value", "unit", "paper value", "data"], rows)
    else:
        out.append("No notebook published a summary.")
    out += ["", "## Notebook runs", ""]
    out += _table(["notebook", "status", "seconds", "error"],
                  [[r.notebook, r.status, f"{r.seconds:.1f}", r.error] for r in runs])
    n_failed = sum(not r.ok for r in runs)
    out += ["", f"{len(runs) - n_failed} of {len(runs)} notebooks ok." if n_failed else
            f"All {len(runs)} notebooks ok.", ""]
    return "\n".join(out)


def reproduce(*, quick: bool = False, only: Iterable[str] | None = None,
              out: str | os.PathLike | None = None, parameters: Mapping[str, Any] | None = None,
              timeout_s: float | None = None, notebooks_dir: str | os.PathLike | None = None,
              kernel_name: str = KERNEL_NAME,
              log: Callable[[str], None] | None = None) -> ReproduceResult:
    """Execute the notebooks and aggregate their summaries.

    Parameters
    ----------
    quick
        Pass ``FAST=True`` (the CI setting: smaller experiments, looser checks).
    only
        Notebook selection, see :func:`select_notebooks`.
    out
        Output folder; default ``reports/`` in the project.
    parameters
        Extra papermill parameters for every notebook (they override ``FAST``).
    timeout_s
        Execution timeout per cell, in seconds (None: no limit).
    notebooks_dir
        Folder of notebooks; default ``notebooks/`` in the project.
    kernel_name
        Jupyter kernel to execute with.
    log
        Called with one progress line per notebook (e.g. ``print``).

    Returns
    -------
    ReproduceResult
        ``exit_code`` is non-zero when a notebook failed or wrote no valid summary.

    Raises
    ------
    ValueError
        Bad selection, a reserved parameter name, or a non-positive timeout.
    """
    parameters = dict(parameters or {})
    reserved = sorted(set(parameters) & set(RESERVED_PARAMETERS))
    if reserved:
        raise ValueError(f"parameter(s) {', '.join(reserved)} are set by the runner and cannot be passed")
    if timeout_s is not None and not timeout_s > 0:
        raise ValueError(f"timeout must be positive seconds, got {timeout_s!r}")
    notebooks = select_notebooks(notebooks_dir, only)
    out_dir = Path(REPORTS_DIR if out is None else out).expanduser().resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    params = ({"FAST": True} if quick else {}) | parameters

    runs = []
    for i, source in enumerate(notebooks, 1):
        if log:
            log(f"[{i}/{len(notebooks)}] {source.stem} ...")
        run = run_notebook(source, out_dir, params, timeout_s=timeout_s, kernel_name=kernel_name)
        runs.append(run)
        if log:
            log(f"[{i}/{len(notebooks)}] {run.notebook}: {run.status} ({run.seconds:.1f} s)"
                + (f" — {run.error}" if run.error else ""))

    summary_json, summary_md = out_dir / "summary.json", out_dir / "summary.md"
    result = ReproduceResult(runs=tuple(runs), out_dir=out_dir, summary_json=summary_json,
                             summary_md=summary_md)
    summary_json.write_text(json.dumps(result.rows, indent=2, allow_nan=True) + "\n", encoding="utf-8")
    summary_md.write_text(summary_markdown(runs, params), encoding="utf-8")
    return result
