"""Class mode: a lecturer's run of the notebooks, and the audits that keep them teachable.

``make class`` (``python -m uwbwb.classroom``) executes every notebook with ``FAST=True`` and
``CLASS=True`` (``CLASS`` only where the notebook's ``parameters`` cell declares it) into the
git-ignored folder ``class/`` and writes, per notebook:

* ``<stem>.ipynb`` — the executed notebook; cells tagged ``research`` open *folded* in JupyterLab
  (cell metadata ``jupyter: {source_hidden: true, outputs_hidden: true}``), one click unfolds them;
* ``<stem>.html`` — the handout: the same run without the ``research`` cells and without the
  injected-parameters cell (nbconvert's ``TagRemovePreprocessor``);

and prints each notebook's wall time and its :func:`class_limits` violations. It exits non-zero
when a notebook fails to execute (violations are reported, not fatal).

Class limits (:func:`class_limits`), among the cells *not* tagged ``research``:

* a Markdown cell over :data:`MAX_MARKDOWN_WORDS` words of prose (cell 0, the teaching front, over
  :data:`MAX_FRONT_WORDS`); math (``$...$``, ``$$...$$``), HTML tags, link targets and tokens without a
  letter or digit (``|``, ``—``) are not words;
* a table over :data:`MAX_TABLE_ROWS` rows: ``<tr>`` rows of an HTML output (those in ``<tbody>``
  when it has one), or the lines after the header of a plain-text-only result;
* printed output over :data:`MAX_OUTPUT_WORDS` words in one cell: stdout, Markdown outputs and
  plain-text results that are not tables.

Code rules (:func:`code_rules`, issue 19): every code cell at most :data:`MAX_CODE_LINES` lines and
without a ``def``, except the final widget cell (the last cell that builds a panel); no private package
name (``module._name``) in any cell.

Figure audit (:func:`axes_problems`, :func:`figure_audit`). Every Axes a notebook draws through
pyplot is recorded while it runs (:func:`install_figure_recorder`, a ``figure.hooks`` entry plus a
``post_run_cell`` callback, so the audit rides on an execution that happens anyway) and must have

* a **title or a panel label** (any of its three titles, or a text such as ``(a)`` in the Axes);
* an **x and a y label with a unit**: a bracketed group — ``[m]``, ``(s)``, ``(cm/s)``, ``[-]`` —
  anywhere in the label, or one of the words of :data:`DIMENSIONLESS` (``count``, ``fraction``,
  ``index``, ...) for a dimensionless axis. A label may come from an Axes sharing that axis or from
  the figure's ``supxlabel``/``supylabel``. A categorical axis (string categories or fixed tick
  labels, e.g. set names under bars) needs a label but no unit. Polar Axes need a unit on the radial
  axis (y label or title) only;
* **data or a note**: an Axes with no artist must carry a text saying why it is empty.

Exempt: invisible Axes, Axes whose axis is switched off (``ax.axis("off")``: images, tables, text
panels) and colorbars. Each executed notebook must also hold at least one image output
(``image/png``), i.e. its HTML report has a figure whatever the backend.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

from . import reproduce

__all__ = ["AUDIT_HOOK_TAG", "DIMENSIONLESS", "MAX_CODE_LINES", "MAX_FRONT_WORDS", "MAX_MARKDOWN_WORDS",
           "MAX_OUTPUT_WORDS", "MAX_TABLE_ROWS", "RESEARCH_TAG", "axes_problems", "axes_record", "class_limits",
           "code_rules", "figure_audit",
           "fold_research", "handout_html", "hook_cell", "image_count", "install_figure_recorder", "main",
           "record_figure", "run_class", "source_indices"]

#: Tag of the research-bookkeeping cells: folded in class notebooks, dropped from handouts.
RESEARCH_TAG = "research"
#: Tag of the cell :func:`hook_cell` adds to a copy of a notebook (not a cell of the notebook).
AUDIT_HOOK_TAG = "audit-hook"
#: papermill's tag of the cell holding the parameters it injected.
INJECTED_TAG = "injected-parameters"
MAX_MARKDOWN_WORDS = 200
MAX_FRONT_WORDS = 150
MAX_TABLE_ROWS = 25
MAX_OUTPUT_WORDS = 200
#: Words that mark a dimensionless axis label (besides a bracketed unit such as ``[-]``).
DIMENSIONLESS = ("count", "number", "index", "fraction", "ratio", "probability", "share", "unitless",
                 "dimensionless")
#: Default output folder of ``make class`` (git-ignored), in the working directory: never inside the package.
CLASS_DIR = Path("class")

_UNIT = re.compile(r"[\[(][^\[\]()]{1,20}[\])]")
_DIMLESS = re.compile(r"\b(" + "|".join(DIMENSIONLESS) + r")s?\b", re.IGNORECASE)
_PANEL = re.compile(r"^\s*\(?[a-zA-Z]\)\s*")
_WIDGET_MIME = "application/vnd.jupyter.widget-view+json"


# ---------------------------------------------------------------- class limits

def _tags(cell) -> list[str]:
    return list(cell.get("metadata", {}).get("tags", []))


def source_indices(nb) -> dict[int, int]:
    """``{index in nb: index in the source notebook}`` of the cells that are the notebook's own
    (the injected-parameters cell of papermill and the audit hook cell are left out)."""
    out, k = {}, 0
    for i, cell in enumerate(nb.cells):
        if INJECTED_TAG in _tags(cell) or AUDIT_HOOK_TAG in _tags(cell):
            continue
        out[i] = k
        k += 1
    return out


def _text(value) -> str:
    return "".join(value) if isinstance(value, list) else str(value)


def _words(text: str) -> int:
    return len(text.split())


def _prose_words(markdown: str) -> int:
    """Words of a Markdown text without its math, HTML tags and link targets (a formula is not prose)."""
    s = re.sub(r"\$\$.*?\$\$", " ", markdown, flags=re.S)
    s = re.sub(r"\$[^$\n]*\$", " ", s)
    s = re.sub(r"<[^>\n]*>", " ", s)
    s = re.sub(r"\]\([^)\s]*\)", "]", s)
    return sum(1 for w in s.split() if re.search(r"\w", w))


def _html_rows(html: str) -> int:
    bodies = re.findall(r"<tbody.*?</tbody>", html, flags=re.S | re.I)
    return sum(len(re.findall(r"<tr[\s>]", b, flags=re.I)) for b in (bodies or [html]))


def class_limits(nb) -> list[str]:
    """Class-mode violations of an executed notebook, one sentence each naming the cell.

    Parameters
    ----------
    nb
        An executed notebook (``nbformat`` node). Cells tagged ``research`` are skipped; cell
        indices are those of the source notebook (:func:`source_indices`).

    Returns
    -------
    list of str
        Empty when every visible cell keeps to the limits of the module docstring.
    """
    problems = []
    for i, k in source_indices(nb).items():
        cell = nb.cells[i]
        if RESEARCH_TAG in _tags(cell):
            continue
        if cell.cell_type == "markdown":
            limit = MAX_FRONT_WORDS if k == 0 else MAX_MARKDOWN_WORDS
            n = _prose_words(cell.source)
            if n > limit:
                problems.append(f"cell {k}: markdown of {n} words (limit {limit}"
                                f"{', teaching front' if k == 0 else ''})")
            continue
        if cell.cell_type != "code":
            continue
        words = 0
        for out in cell.get("outputs", []):
            if out.get("output_type") == "stream":
                if out.get("name") == "stdout":
                    words += _words(_text(out.get("text", "")))
                continue
            data = out.get("data", {})
            if _WIDGET_MIME in data:
                continue
            if "text/html" in data:
                rows = _html_rows(_text(data["text/html"]))
                if rows > MAX_TABLE_ROWS:
                    problems.append(f"cell {k}: table of {rows} rows (limit {MAX_TABLE_ROWS})")
            elif "text/markdown" in data:
                words += _words(_text(data["text/markdown"]))
            elif "text/plain" in data and not any(m.startswith("image/") for m in data):
                lines = _text(data["text/plain"]).strip("\n").splitlines()
                if len(lines) > 1 and _looks_tabular(lines):
                    if len(lines) - 1 > MAX_TABLE_ROWS:
                        problems.append(f"cell {k}: text table of {len(lines) - 1} rows (limit {MAX_TABLE_ROWS})")
                else:
                    words += _words("\n".join(lines))
        if words > MAX_OUTPUT_WORDS:
            problems.append(f"cell {k}: {words} words of printed output (limit {MAX_OUTPUT_WORDS})")
    return problems


def _looks_tabular(lines: list[str]) -> bool:
    """A pandas-like text table: every line has at least two columns separated by two spaces."""
    return all(len(re.split(r"\s{2,}", ln.strip())) >= 2 for ln in lines if ln.strip())


# ---------------------------------------------------------------- code rules

#: Most lines of a notebook code cell (the final widget cell excepted).
MAX_CODE_LINES = 20
_PRIVATE = re.compile(r"(?<![\w.])(?:uw|[a-z]\w*)\.(_[a-z]\w*)")


def code_rules(nb) -> list[str]:
    """Code-rule violations of a notebook (issue 19), one sentence each naming the cell: a code cell over
    :data:`MAX_CODE_LINES` lines or with a ``def`` (both allowed in the last cell that builds a panel, the
    final widget cell), and a private package name (``module._name``) anywhere."""
    code = [(k, nb.cells[i]) for i, k in source_indices(nb).items() if nb.cells[i].cell_type == "code"]
    widget = max((k for k, c in code if "Panel(" in c.source or ".panel(" in c.source
                  or "explorer(" in c.source), default=None)
    problems = []
    for k, cell in code:
        lines = [ln for ln in cell.source.splitlines()]
        if k != widget and len(lines) > MAX_CODE_LINES:
            problems.append(f"cell {k}: {len(lines)} lines of code (limit {MAX_CODE_LINES})")
        if k != widget and re.search(r"^\s*(async\s+)?def\s", cell.source, flags=re.M):
            problems.append(f"cell {k}: defines a function (move it into the experiment package)")
        for name in sorted(set(_PRIVATE.findall(cell.source))):
            if not name.startswith("__"):
                problems.append(f"cell {k}: private name {name!r}")
    return problems


# ---------------------------------------------------------------- figure audit

def _has_unit(label: str) -> bool:
    return bool(_UNIT.search(label) or _DIMLESS.search(label))


def _categorical(axis) -> bool:
    import matplotlib.category as mcat
    import matplotlib.ticker as mticker

    if isinstance(axis.get_units(), mcat.UnitData) or isinstance(axis.get_major_formatter(),
                                                                  (mticker.FixedFormatter, mcat.StrCategoryFormatter)):
        return True
    if not isinstance(axis.get_major_locator(), mticker.FixedLocator):
        return False
    # fixed ticks whose labels are not their positions (set names, "54321" for sensors 5, 4, 3, 2, 1)
    labels = [(t.get_text().strip().replace("\u2212", "-"), t.get_position()[0 if axis.axis_name == "x" else 1])
              for t in axis.get_ticklabels()]
    return any(text and not _same_number(text, loc) for text, loc in labels)


def _same_number(text: str, value: float) -> bool:
    try:
        return abs(float(text.rstrip("%").strip()) - float(value)) <= 1e-9 * max(1.0, abs(float(value)))
    except ValueError:
        return False


def _shared_label(ax, which: str) -> str:
    """The axis label of ``ax``, else of an Axes sharing that axis, else the figure's sup-label."""
    own = (ax.get_xlabel() if which == "x" else ax.get_ylabel()).strip()
    if own:
        return own
    group = ax.get_shared_x_axes() if which == "x" else ax.get_shared_y_axes()
    for other in group.get_siblings(ax):
        label = (other.get_xlabel() if which == "x" else other.get_ylabel()).strip()
        if label:
            return label
    fig = ax.get_figure(root=True)
    sup = fig.get_supxlabel() if which == "x" else fig.get_supylabel()
    return (sup or "").strip()


def axes_record(ax) -> dict:
    """What the figure audit needs of one Axes (JSON-ready)."""
    titles = [ax.get_title(loc=loc).strip() for loc in ("left", "center", "right")]
    notes = [t.get_text().strip() for t in ax.texts if t.get_visible() and t.get_text().strip()]
    exempt = None
    if not ax.get_visible():
        exempt = "invisible"
    elif ax.get_label() == "<colorbar>":
        exempt = "colorbar"
    elif not ax.axison:
        exempt = "axis off"
    return {
        "kind": ax.name,
        "title": " | ".join(t for t in titles if t),
        "panel_label": next((n for n in notes if _PANEL.match(n)), ""),
        "xlabel": _shared_label(ax, "x"),
        "ylabel": _shared_label(ax, "y"),
        "x_categorical": _categorical(ax.xaxis),
        "y_categorical": _categorical(ax.yaxis),
        "has_data": bool(ax.has_data()),
        "notes": notes,
        "exempt": exempt,
    }


def axes_problems(rec: dict) -> list[str]:
    """What one Axes record (:func:`axes_record`) lacks under the rule of the module docstring."""
    if rec.get("exempt"):
        return []
    out = []
    if not (rec["title"] or rec["panel_label"]):
        out.append("no title or panel label")
    if rec["kind"] == "polar":
        if not (_has_unit(rec["ylabel"]) or _has_unit(rec["title"])):
            out.append("no radial unit (y label or title)")
    else:
        for axis in ("x", "y"):
            label = rec[f"{axis}label"]
            if not label:
                out.append(f"no {axis} label")
            elif not rec[f"{axis}_categorical"] and not _has_unit(label):
                out.append(f"{axis} label {label!r} has no unit")
    if not rec["has_data"] and not rec["notes"]:
        out.append("empty panel without a note")
    return out


# The recorder runs inside the kernel: figures created through pyplot are kept (by reference, so the
# inline backend closing them does not matter) until the cell ends, then audited and appended to a file.
_PENDING: list = []
_RECORD_PATH: list[Path] = []


def record_figure(fig) -> None:
    """``figure.hooks`` entry: remember a new pyplot figure for the end of the cell."""
    _PENDING.append(fig)


def _flush(result) -> None:
    if not _RECORD_PATH:
        return
    path = _RECORD_PATH[0]
    records = json.loads(path.read_text()) if path.is_file() else []
    for n, fig in enumerate(_PENDING):
        records.append({"execution_count": result.execution_count, "figure": n,
                        "title": (fig.get_suptitle() or "").strip(),
                        "axes": [axes_record(ax) for ax in fig.axes]})
    _PENDING.clear()
    path.write_text(json.dumps(records, indent=1))


def install_figure_recorder(path) -> None:
    """Record every pyplot figure of the running IPython session into the JSON file ``path``.

    One entry per figure: the execution count of the cell that drew it and :func:`axes_record` of
    each Axes, taken when the cell has finished (so a figure's later titles and labels count).
    Figures made without pyplot (``matplotlib.figure.Figure(...)``, e.g. a widget's
    :class:`uwbwb.widgets.PanelFigure`) are not seen.
    """
    import matplotlib as mpl
    from IPython import get_ipython

    if _RECORD_PATH:
        raise RuntimeError(f"the figure recorder is already installed (writing {_RECORD_PATH[0]})")
    _RECORD_PATH[:] = [Path(path)]
    Path(path).write_text("[]")
    hook = f"{__name__}:record_figure"
    if hook not in mpl.rcParams["figure.hooks"]:
        mpl.rcParams["figure.hooks"] = [*mpl.rcParams["figure.hooks"], hook]
    get_ipython().events.register("post_run_cell", _flush)


def hook_cell(record_path) -> "nbformat.NotebookNode":  # noqa: F821
    """A code cell (tagged :data:`AUDIT_HOOK_TAG`) that installs the recorder; put it first in a copy."""
    import nbformat

    cell = nbformat.v4.new_code_cell(f"import uwbwb.classroom\nuwbwb.classroom.install_figure_recorder({str(record_path)!r})")
    cell.metadata["tags"] = [AUDIT_HOOK_TAG]
    return cell


def image_count(nb) -> int:
    """Number of ``image/png`` outputs of an executed notebook."""
    return sum("image/png" in out.get("data", {}) for c in nb.cells if c.cell_type == "code"
               for out in c.get("outputs", []))


def figure_audit(records: Sequence[dict], nb) -> list[str]:
    """Figure-audit violations of one executed notebook, one sentence each naming cell and Axes.

    Parameters
    ----------
    records
        What :func:`install_figure_recorder` wrote for this execution.
    nb
        The executed notebook (to map execution counts to cells and count the images).
    """
    where = {c.get("execution_count"): k for i, k in source_indices(nb).items()
             for c in [nb.cells[i]] if c.cell_type == "code"}
    problems = []
    for fig in records:
        cell = where.get(fig["execution_count"], f"[{fig['execution_count']}]")
        for j, rec in enumerate(fig["axes"]):
            for p in axes_problems(rec):
                name = rec["title"] or rec["panel_label"] or "untitled"
                problems.append(f"cell {cell}, figure {fig['figure']}, axes {j} ({name!r}): {p}")
    if image_count(nb) == 0:
        problems.append("no image output: the HTML report would hold no figure")
    elif not records:
        problems.append("the recorder saw none of the figures (was rcParams['figure.hooks'] reset?): nothing audited")
    return problems


# ---------------------------------------------------------------- class run

def fold_research(nb):
    """Fold every ``research`` cell (source and outputs hidden in JupyterLab); returns ``nb``."""
    for cell in nb.cells:
        if RESEARCH_TAG in _tags(cell):
            cell.metadata["jupyter"] = {**cell.metadata.get("jupyter", {}),
                                        "source_hidden": True, "outputs_hidden": True}
    return nb


def handout_html(nb) -> str:
    """HTML of ``nb`` without its ``research`` cells and its injected-parameters cell."""
    from nbconvert import HTMLExporter
    from nbconvert.preprocessors import TagRemovePreprocessor
    from traitlets.config import Config

    config = Config()
    config.TagRemovePreprocessor.remove_cell_tags = {RESEARCH_TAG, INJECTED_TAG, AUDIT_HOOK_TAG}
    config.TagRemovePreprocessor.enabled = True
    exporter = HTMLExporter(config=config)
    exporter.register_preprocessor(TagRemovePreprocessor(config=config), enabled=True)
    body, _ = exporter.from_notebook_node(nb)
    return body


def run_class(notebooks: Iterable[Path], out_dir: Path, *, kernel_name: str = reproduce.KERNEL_NAME,
              timeout_s: float | None = 600, log=print) -> list[dict]:
    """Execute ``notebooks`` in class mode into ``out_dir`` (see the module docstring).

    Returns
    -------
    list of dict
        Per notebook: ``notebook``, ``seconds`` (wall time, kernel start included), ``error``
        (None when it ran), ``limits`` (:func:`class_limits`), ``executed`` and ``html`` paths.
    """
    import nbformat
    import papermill as pm

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    runs = []
    for source in notebooks:
        source = Path(source)
        declared = reproduce.notebook_parameters(source)
        params = {"FAST": True, **({"CLASS": True} if "CLASS" in declared else {})}
        executed, html = out_dir / f"{source.stem}.ipynb", out_dir / f"{source.stem}.html"
        for stale in (executed, html):
            stale.unlink(missing_ok=True)
        error = None
        t0 = time.perf_counter()
        try:
            pm.execute_notebook(str(source), str(executed), parameters=params, kernel_name=kernel_name,
                                cwd=str(source.parent), progress_bar=False, log_output=False,
                                execution_timeout=timeout_s, kernel_manager_class=reproduce.ipc_kernel_manager())
        except Exception as exc:  # reported per notebook; the others still run
            error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''}"
        seconds = time.perf_counter() - t0
        limits = []
        if executed.is_file():
            nb = nbformat.read(executed, as_version=4)
            limits = class_limits(nb)
            nbformat.write(fold_research(nb), executed)
            html.write_text(handout_html(nb), encoding="utf-8")
        run = {"notebook": source.stem, "seconds": seconds, "error": error, "limits": limits,
               "executed": executed if executed.is_file() else None, "html": html if html.is_file() else None,
               "class_parameter": "CLASS" in declared}
        runs.append(run)
        note = "" if run["class_parameter"] else " (no CLASS parameter: FAST only)"
        log(f"{source.stem}: {'ok' if error is None else 'FAILED'} in {seconds:.1f} s{note}")
        if error:
            log(f"  error: {error}")
        for p in limits:
            log(f"  class limit: {p}")
    return runs


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m uwbwb.classroom [--only NB ...] [--kernel NAME] [--out DIR] [--notebooks-dir DIR]``."""
    parser = argparse.ArgumentParser(prog="python -m uwbwb.classroom",
                                     description="Run the notebooks in class mode (CLASS=True, FAST=True): "
                                                 "folded notebooks and HTML handouts without research cells.")
    parser.add_argument("--only", nargs="+", metavar="NB", help="notebooks to run: stems or prefixes (00 01)")
    parser.add_argument("--kernel", default=reproduce.KERNEL_NAME, help="Jupyter kernel name (default %(default)s)")
    parser.add_argument("--out", type=Path, default=CLASS_DIR, help="output folder (default class/ in the working "
                                                                   "directory)")
    parser.add_argument("--notebooks-dir", type=Path, default=None, help="folder of the notebooks")
    parser.add_argument("--timeout", type=float, default=600, help="seconds per cell, > 0 (default %(default)s)")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        parser.error(f"--timeout must be a positive number of seconds, got {args.timeout}")
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"--out {args.out}: exists and is not a folder")
    try:
        notebooks = reproduce.select_notebooks(args.notebooks_dir, args.only)
    except ValueError as exc:
        parser.error(str(exc))
    runs = run_class(notebooks, args.out, kernel_name=args.kernel, timeout_s=args.timeout)
    total = sum(r["seconds"] for r in runs)
    n_limits = sum(len(r["limits"]) for r in runs)
    print(f"class mode: {len(runs)} notebooks in {total:.0f} s, {sum(r['error'] is not None for r in runs)} failed, "
          f"{n_limits} class-limit violations; notebooks and handouts in {args.out}")
    return 0 if all(r["error"] is None for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
