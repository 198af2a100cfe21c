"""Class mode: a lecturer's run of the notebooks, and the audits that keep them teachable.

``make class`` (``python -m uwbwb.classroom``) writes two folders into the git-ignored ``class/``
(:func:`run_class`):

* ``class/student/`` — what students get: every notebook **unexecuted** (no outputs, so no answer
  printed under a question), its ``parameters`` cell rewritten to ``FAST = True`` and ``CLASS = True``
  (each where the notebook declares it; :func:`set_parameters`), cells tagged ``research`` *folded*
  (cell metadata ``jupyter: {source_hidden: true, outputs_hidden: true}``; one click unfolds them),
  with ``GLOSSARY.md`` and every other file the notebooks link to copied beside them (links rewritten
  where a copy moved: :func:`unresolved_links` finds none), and the lab sheets (:func:`lab_sheets`). Students
  open it with ``make lab LAB_DIR=class/student``; the package finds the datasets wherever the notebook runs from
  (:mod:`uwbwb.datasets.discovery` searches relative to the package, not the working directory).
* ``class/answers/`` — what the lecturer keeps: each student notebook executed *as handed out*
  (a Run All in ``class/student/``, no injected parameters) except that its coding exercise is answered and
  each prediction written (:func:`answer_key`, from the claims in the source's cell metadata; a check that then does not say "right" fails the notebook:
  :func:`wrong_predictions`), its HTML handout (one that does not show all the notebook holds offline fails the
  notebook: :func:`handout_problems`), ``TEACHING.md`` (from the folder above the notebooks) and the
  glossary as ``GLOSSARY.md`` and ``GLOSSARY.html``.

A handout (:func:`handout_html`) is the executed notebook without its ``research`` cells, readable
offline in one file with no script: formulas drawn server-side as inline SVG by Matplotlib's mathtext
(:func:`math_svg`; a formula it cannot draw is shown as TeX code and reported), each widget panel as
static HTML of its saved state — its controls' values, its readout and its figure as a PNG
(:func:`static_panels`) — and glossary links pointing at ``GLOSSARY.html``.

The command prints each notebook's wall time and its :func:`class_limits` violations. It exits
non-zero when a notebook fails to execute (violations are reported, not fatal).

Class limits (:func:`class_limits`), among the cells *not* tagged ``research``:

* a Markdown cell over :data:`MAX_MARKDOWN_WORDS` words of prose (cell 0, the teaching front, over
  :data:`MAX_FRONT_WORDS`); math (``$...$``, ``$$...$$``), HTML tags, link targets and tokens without a
  letter or digit (``|``, ``—``) are not words;
* a table over :data:`MAX_TABLE_ROWS` rows: ``<tr>`` rows of an HTML output (those in ``<tbody>``
  when it has one), or the lines after the header of a plain-text-only result;
* printed output over :data:`MAX_OUTPUT_WORDS` words in one cell: stdout, Markdown outputs and
  plain-text results that are not tables.

Code rules (:func:`code_rules`, issue 19): every code cell at most :data:`MAX_CODE_LINES` lines and
without a ``def``, except the final widget cell (the last cell that builds a panel) and a coding exercise's
stub (tagged :data:`uwbwb.coding.EXERCISE_TAG`); no private package name (``module._name``) in any cell.

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
import ast
import copy
import json
import math
import os
import re
import shutil
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from . import reproduce
from .reproduce import INJECTED_TAG
from .coding import EXERCISE_TAG, Verdict, answer_cell
from .widgets.notes import RIGHT

__all__ = ["ANSWERS_DIR", "AUDIT_HOOK_TAG", "DIMENSIONLESS", "GLOSSARY_NAME", "MATH_SCALE", "MAX_CODE_LINES",
           "MAX_FRONT_WORDS", "MAX_MARKDOWN_WORDS", "MAX_OUTPUT_WORDS", "MAX_TABLE_ROWS", "RESEARCH_TAG",
           "PREDICTION_TAG", "CLAIM_KEY", "STATIC_PANEL_NOTE", "STUDENT_DIR", "TEACHING_NAME", "TEX_LEFT",
           "TEX_LEFT_OUTPUT", "LAB_SHEETS_NAME", "ANSWERS_HEADING", "ROUTES_HEADING", "lab_sheets", "answer_key",
           "prediction_claims", "axes_problems", "axes_record", "class_limits", "class_values",
           "code_rules", "cut_tables", "figure_audit", "fold_research", "handout_html", "handout_problems",
           "hook_cell", "image_count", "install_figure_recorder", "main", "markdown_formulas", "markdown_page_html",
           "math_svg", "mathtext_source", "notebook_links", "notebook_panels", "record_figure", "relative_links",
           "run_class", "set_parameters", "source_indices", "static_panels", "static_widget_html",
           "student_notebook", "unresolved_links", "write_student_folder", "wrong_predictions"]

#: Tag of the research-bookkeeping cells: folded in class notebooks, dropped from handouts.
RESEARCH_TAG = "research"
#: Tag of the cell :func:`hook_cell` adds to a copy of a notebook (not a cell of the notebook).
AUDIT_HOOK_TAG = "audit-hook"
MAX_MARKDOWN_WORDS = 200
MAX_FRONT_WORDS = 150
MAX_TABLE_ROWS = 25
MAX_OUTPUT_WORDS = 200
#: Words that mark a dimensionless axis label (besides a bracketed unit such as ``[-]``).
DIMENSIONLESS = ("count", "number", "index", "fraction", "ratio", "probability", "share", "unitless",
                 "dimensionless")
#: Default output folder of ``make class`` (git-ignored), in the working directory: never inside the package.
CLASS_DIR = Path("class")
#: Sub-folders of the output folder: unexecuted copies for students, and the executed run for the lecturer.
STUDENT_DIR, ANSWERS_DIR = "student", "answers"
#: The glossary beside the notebooks (copied beside each class copy) and the lecturer's notes above them.
GLOSSARY_NAME, TEACHING_NAME = "GLOSSARY.md", "TEACHING.md"
#: The students' lab sheets in the student folder: the routes of ``TEACHING.md`` without its answers
#: (:func:`lab_sheets`).
LAB_SHEETS_NAME = "LAB_SHEETS.md"
#: Where the routes start and where the answers start in ``TEACHING.md``.
ROUTES_HEADING, ANSWERS_HEADING = "## Two two-hour routes", "## Answers"

_UNIT = re.compile(r"[\[(][^\[\]()]{1,20}[\])]")
_DIMLESS = re.compile(r"\b(" + "|".join(DIMENSIONLESS) + r")s?\b", re.IGNORECASE)
_PANEL = re.compile(r"^\s*\(?[a-zA-Z]\)\s*")
_WIDGET_MIME = "application/vnd.jupyter.widget-view+json"
_WIDGET_STATE = "application/vnd.jupyter.widget-state+json"


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


_CUT_TABLE = re.compile(r"\[?(\d+) rows [x×] (\d+) columns\]?")
_CUT_HEADER = re.compile(r"<thead>.*?<th>\.\.\.</th>.*?</thead>", flags=re.S)


def cut_tables(nb) -> list[str]:
    """Tables pandas printed with columns hidden (the ``...`` column of its header; a long table cut to its head
    and tail rows is fine), one sentence each naming the cell, research cells included: a table a notebook
    discusses must show every column (``pd.set_option("display.max_columns", None)``) or select those it shows."""
    problems = []
    for i, k in source_indices(nb).items():
        for out in nb.cells[i].get("outputs", []) if nb.cells[i].cell_type == "code" else ():
            data = out.get("data", {})
            html, plain = _text(data.get("text/html", "")), _text(data.get("text/plain", ""))
            header = plain.strip("\n").splitlines()[0].split() if plain.strip() else []
            if (html and _CUT_HEADER.search(html)) or (not html and "..." in header):
                m = _CUT_TABLE.search(html or plain)
                size = f" ({m.group(1)} rows × {m.group(2)} columns)" if m else ""
                problems.append(f"cell {k}: a table printed with columns hidden{size}")
    return problems


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
    return problems + _class_gaps(nb)


_HEADING = re.compile(r"^\s*#{1,3} ")
_NEXT_CELL = re.compile(r"\b(next cell|cell below|the cell after)\b", flags=re.I)


def _class_gaps(nb) -> list[str]:
    """What a handout (no ``research`` cells) loses around them: a Markdown cell that sends the reader to the next
    cell when that cell is a research cell, and a section whose heading cell is followed, once research cells are
    left out, by the next heading (an empty section)."""
    cells = [(k, nb.cells[i]) for i, k in source_indices(nb).items()]
    problems = []
    for n, (k, cell) in enumerate(cells):
        if cell.cell_type != "markdown" or RESEARCH_TAG in _tags(cell):
            continue
        if _NEXT_CELL.search(cell.source) and n + 1 < len(cells) and RESEARCH_TAG in _tags(cells[n + 1][1]):
            problems.append(f"cell {k}: refers to the next cell, a research cell left out in class")
        if _HEADING.match(cell.source) and len(cell.source.strip().splitlines()) == 1:
            rest = [c for _, c in cells[n + 1:] if RESEARCH_TAG not in _tags(c)]
            if not rest or (rest[0].cell_type == "markdown" and _HEADING.match(rest[0].source)):
                problems.append(f"cell {k}: section {cell.source.strip()!r} is empty without its research cells")
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
        if k != widget and EXERCISE_TAG not in _tags(cell) and re.search(r"^\s*(async\s+)?def\s", cell.source,
                                                                      flags=re.M):
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


# ---------------------------------------------------------------- student copies

def fold_research(nb):
    """Fold every ``research`` cell (source and outputs hidden in JupyterLab); returns ``nb``."""
    for cell in nb.cells:
        if RESEARCH_TAG in _tags(cell):
            cell.metadata["jupyter"] = {**cell.metadata.get("jupyter", {}),
                                        "source_hidden": True, "outputs_hidden": True}
    return nb


def set_parameters(source: str, values: Mapping[str, object]) -> str:
    """``source`` (a parameters cell) with the top-level assignment of each name in ``values`` set to
    ``repr(value)``; the rest of each line (its comment, in the same column where it fits) is kept.

    Raises
    ------
    ValueError
        A name is not assigned at the top level of the cell, or its value spans several lines.
    """
    lines = source.splitlines(keepends=True)
    found = {}
    for node in ast.parse(source).body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                and node.targets[0].id in values):
            found[node.targets[0].id] = node.value
    missing = [name for name in values if name not in found]
    if missing:
        raise ValueError(f"the parameters cell assigns no {', '.join(missing)}")
    for name, node in found.items():
        if node.lineno != node.end_lineno:
            raise ValueError(f"the value of {name} spans several lines")
        raw = lines[node.lineno - 1].encode("utf-8")        # ast offsets count UTF-8 bytes
        new = repr(values[name]).encode("utf-8")
        rest = raw[node.end_col_offset:]
        spare = len(rest) - len(rest.lstrip(b" ")) - 1       # keep the comment's column where it can be kept
        if len(new) < node.end_col_offset - node.col_offset and rest.strip() and spare >= 0:
            new += b" " * (node.end_col_offset - node.col_offset - len(new))
        elif len(new) > node.end_col_offset - node.col_offset and spare > 0:
            rest = rest[min(spare, len(new) - (node.end_col_offset - node.col_offset)):]
        lines[node.lineno - 1] = (raw[:node.col_offset] + new + rest).decode("utf-8")
    return "".join(lines)


def class_values(declared: Iterable[str]) -> dict[str, bool]:
    """The parameters a class copy sets: ``FAST`` and ``CLASS``, each where the notebook declares it."""
    declared = set(declared)
    return {name: True for name in ("FAST", "CLASS") if name in declared}


def student_notebook(nb, values: Mapping[str, object]):
    """A student's copy of ``nb``: no outputs or execution counts, ``values`` written into its
    ``parameters`` cell (:func:`set_parameters`), ``research`` cells folded, no papermill or widget
    metadata, no injected or audit cells. ``nb`` itself is not changed."""
    nb = copy.deepcopy(nb)
    nb.cells = [c for c in nb.cells if not ({INJECTED_TAG, AUDIT_HOOK_TAG} & set(_tags(c)))]
    params = [c for c in nb.cells if c.cell_type == "code" and "parameters" in _tags(c)]
    if values and len(params) != 1:
        raise ValueError(f"expected one code cell tagged 'parameters', found {len(params)}")
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
        for key in ("execution", "papermill", "ExecuteTime", CLAIM_KEY):
            cell.metadata.pop(key, None)
    if values:
        params[0].source = set_parameters(params[0].source, values)
    for key in ("widgets", "papermill"):
        nb.metadata.pop(key, None)
    return fold_research(nb)


#: Tag of the cell where a student writes an exercise's prediction (``PREDICTION_1 = None  # write "a" or "b": ...``).
PREDICTION_TAG = "prediction"
#: The student's line, ``PREDICTION_k = None  # write "a" or "b": ...``, its two choices in either order.
_PREDICTION = re.compile(r'^(PREDICTION_\w+)(\s*=\s*)None(\s*#\s*write\s+"([^"\n]+)"\s+or\s+"([^"\n]+)")', flags=re.M)
#: Key of a prediction cell's metadata naming its claim: the choice its check cell asserts, which the answer key
#: writes. Student copies drop it (:func:`student_notebook`), so nothing in a student's file says which choice it is.
CLAIM_KEY = "claim"
_PREDICTION_NAME = re.compile(r"^(PREDICTION_\w+)\s*=\s*(.+?)\s*(#|$)", flags=re.M)


def prediction_claims(nb) -> dict[str, str]:
    """``{"PREDICTION_k": claim}`` of ``nb``'s prediction cells (tagged :data:`PREDICTION_TAG`), each claim read from
    the cell's metadata (:data:`CLAIM_KEY`) and one of the two choices its line offers.

    Raises
    ------
    ValueError
        A prediction cell without one ``PREDICTION_k = None  # write "a" or "b"`` line, or whose claim is missing or
        not one of its choices (the message shows the cell).
    """
    claims = {}
    for cell in nb.cells:
        if cell.cell_type != "code" or PREDICTION_TAG not in _tags(cell):
            continue
        found, claim = _PREDICTION.findall(cell.source), cell.metadata.get(CLAIM_KEY)
        if len(found) != 1 or claim not in found[0][3:5]:
            raise ValueError(f"a cell tagged {PREDICTION_TAG!r} must set one "
                             f'PREDICTION_… = None  # write "…" or "…", and its metadata {CLAIM_KEY!r} one of the two '
                             f"choices; got {claim!r} and:\n{cell.source}")
        claims[found[0][0]] = claim
    return claims


def answer_key(nb, claims: Mapping[str, str] | None = None):
    """``nb`` with the stub of each coding exercise (cells tagged :data:`uwbwb.coding.EXERCISE_TAG`) replaced by
    its answer (:func:`uwbwb.coding.answer_cell`), and each prediction (cells tagged :data:`PREDICTION_TAG`,
    ``PREDICTION_k = None  # write "a" or "b": ...``) set to its claim, the choice its check cell asserts:
    ``claims`` (from :func:`prediction_claims` of the notebook a student copy was made from; default: ``nb``'s
    own). ``nb`` itself is not changed."""
    claims = prediction_claims(nb) if claims is None else claims
    nb = copy.deepcopy(nb)
    for cell in nb.cells:
        if cell.cell_type == "code" and EXERCISE_TAG in _tags(cell):
            cell.source = answer_cell(cell.source)
        elif cell.cell_type == "code" and PREDICTION_TAG in _tags(cell):
            m = _PREDICTION.search(cell.source)
            if m is None or claims.get(m.group(1)) not in (m.group(4), m.group(5)):
                raise ValueError(f"no claim among the choices of {m.group(1) if m else 'this cell'} "
                                 f"(PREDICTION_… = None  # write \"…\" or \"…\"):\n{cell.source}")
            cell.source = (cell.source[:m.start()] + f'{m.group(1)}{m.group(2)}"{claims[m.group(1)]}"{m.group(3)}'
                           + cell.source[m.end():])
    return nb


def wrong_predictions(nb) -> list[str]:
    """What the checks of an executed answer key (:func:`answer_key`) do not say right, one sentence each; empty when
    every check agrees with its answer: a prediction whose check cell (the next code cell that reads it) does not say
    :data:`uwbwb.widgets.notes.RIGHT`, and a coding exercise (its cell tagged :data:`uwbwb.coding.EXERCISE_TAG`)
    whose check cell (the next code cell with ``check(name)``) does not report its function right
    (:class:`uwbwb.coding.Verdict`)."""
    problems = []
    for i, cell in enumerate(nb.cells):
        tags = _tags(cell)
        if PREDICTION_TAG in tags and (m := _PREDICTION_NAME.match(cell.source)):
            name, reads, right = m.group(1), re.compile(rf"\({m.group(1)}\b"), RIGHT
            wrong = f"{name} = {m.group(2)} is not what its check shows"
        elif EXERCISE_TAG in tags and (m := re.search(r"^def\s+(\w+)\s*\(", cell.source, flags=re.M)):
            name, reads = m.group(1), re.compile(rf"\bcheck\(\s*{m.group(1)}\s*\)")
            right = Verdict(name, "right", "")._repr_markdown_().strip()
            wrong = f"the answer of {name} is not right by its check"
        else:
            continue
        check = next((c for c in nb.cells[i + 1:] if c.cell_type == "code" and reads.search(c.source)), None)
        shown = "" if check is None else " ".join(_text(o.get("data", {}).get("text/markdown", ""))
                                                  for o in check.get("outputs", []))
        if right not in shown:
            problems.append(f"cell {i}: {wrong}" if check is not None else f"cell {i}: no check cell reads {name}")
    return problems


# ---------------------------------------------------------------- relative links

_FENCE = re.compile(r"^(```|~~~).*?^\1[^\n]*$|`[^`\n]*`", flags=re.S | re.M)
_MD_LINK = re.compile(r"(\]\(\s*<?)([^)\s>]+)(>?(?:\s+\"[^\"]*\")?\s*\))")
_HTML_LINK = re.compile(r"""(\b(?:href|src)\s*=\s*["'])([^"']+)(["'])""", flags=re.I)
_SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def _is_relative(target: str) -> bool:
    return bool(target) and not (target.startswith(("#", "/")) or _SCHEME.match(target))


def _map_links(markdown: str, fn) -> str:
    """``markdown`` with every relative link target ``t`` (Markdown and HTML links, outside code) replaced by
    ``fn(t)``."""
    def sub(text):
        for pattern in (_MD_LINK, _HTML_LINK):
            text = pattern.sub(lambda m: m.group(1) + (fn(m.group(2)) if _is_relative(m.group(2)) else m.group(2))
                               + m.group(3), text)
        return text

    out, pos = [], 0
    for m in _FENCE.finditer(markdown):
        out += [sub(markdown[pos:m.start()]), m.group(0)]
        pos = m.end()
    return "".join(out + [sub(markdown[pos:])])


def relative_links(markdown: str) -> list[str]:
    """The relative link targets of a Markdown text (Markdown and HTML links outside code, fragment kept):
    no URL with a scheme, no bare ``#anchor``, no absolute path."""
    found = []
    _map_links(markdown, lambda t: found.append(t) or t)
    return found


def _split_target(target: str) -> tuple[str, str]:
    path, sep, frag = target.partition("#")
    return path.partition("?")[0], sep + frag


def notebook_links(nb) -> list[str]:
    """Relative link targets of the Markdown cells of ``nb``."""
    return [t for c in nb.cells if c.cell_type == "markdown" for t in relative_links(c.source)]


def unresolved_links(folder: Path) -> list[str]:
    """Relative links of the notebooks and Markdown files in ``folder`` (and below) whose file is missing,
    as ``"file: target"``."""
    folder = Path(folder)
    problems = []
    for path in sorted(folder.rglob("*")):
        if path.suffix == ".ipynb":
            targets = notebook_links(_read_notebook(path))
        elif path.suffix == ".md":
            targets = relative_links(path.read_text(encoding="utf-8"))
        else:
            continue
        for t in targets:
            file = _split_target(t)[0]
            if file and not (path.parent / file).exists():
                problems.append(f"{path.relative_to(folder).as_posix()}: {t}")
    return problems


def _read_notebook(path):
    import nbformat

    return nbformat.read(path, as_version=4)


class _Companions:
    """The files a set of notebooks (and Markdown files) link to, transitively through linked Markdown
    files, each with its place in an output folder: its path relative to the notebooks' folder, or,
    for a file outside it, relative to the folder above (``../docs/X.md`` → ``docs/X.md``)."""

    def __init__(self, notebooks_dir: Path):
        self.root = Path(notebooks_dir).resolve()
        self.placed: dict[Path, Path] = {}       # source file -> place relative to an output folder

    def place(self, file: Path) -> Path | None:
        for base in (self.root, self.root.parent):
            rel = Path(os.path.relpath(file, base))
            if not rel.parts or rel.parts[0] != "..":
                return rel
        return None

    def add(self, file: Path, place: Path | None = None) -> None:
        file = Path(file).resolve()
        if file in self.placed or not file.is_file():
            return
        place = place or self.place(file)
        if place is None:
            return
        self.placed[file] = place
        if file.suffix == ".md":
            self.add_links(relative_links(file.read_text(encoding="utf-8")), file.parent)

    def add_links(self, targets: Iterable[str], base: Path) -> None:
        for t in targets:
            path = _split_target(t)[0]
            if path:
                self.add(Path(base) / path)

    def relink(self, markdown: str, source_dir: Path, out_root: Path, out_dir: Path) -> str:
        """``markdown`` (from ``source_dir``, written to ``out_dir`` under ``out_root``) with each relative
        link to a placed file pointing at its copy, and every other link to an existing file pointing back
        at the original."""
        def fix(target):
            path, frag = _split_target(target)
            if not path:
                return target
            file = (Path(source_dir) / path).resolve()
            if file in self.placed:
                new = os.path.relpath(out_root / self.placed[file], out_dir)
            elif file.exists():
                new = os.path.relpath(file, out_dir)
            else:
                return target
            return Path(new).as_posix() + frag

        return _map_links(markdown, fix)

    def write(self, out_root: Path) -> list[Path]:
        """Copy every placed file under ``out_root`` (Markdown files relinked); returns the copies."""
        out_root = Path(out_root)
        written = []
        for file, place in self.placed.items():
            dest = out_root / place
            dest.parent.mkdir(parents=True, exist_ok=True)
            if file.suffix == ".md":
                dest.write_text(self.relink(file.read_text(encoding="utf-8"), file.parent, out_root.resolve(),
                                            dest.parent.resolve()), encoding="utf-8")
            else:
                shutil.copy2(file, dest)
            written.append(dest)
        return written


# ---------------------------------------------------------------- handouts: math and panels

_SIMPLE_TEX = [(r"\\[bB]igg?[lrm]?(?![A-Za-z])", ""), (r"\\[lr]Vert(?![A-Za-z])", r"\\Vert "),
               (r"\\[lr]vert(?![A-Za-z])", "|"), (r"\\[td]frac(?![A-Za-z])", r"\\frac"),
               (r"\\le(?![A-Za-z])", r"\\leq "), (r"\\ge(?![A-Za-z])", r"\\geq "), (r"\\ne(?![A-Za-z])", r"\\neq "),
               (r"\\operatorname(?![A-Za-z])", r"\\mathrm"), (r"\\lbrace(?![A-Za-z])", r"\\{"),
               (r"\\rbrace(?![A-Za-z])", r"\\}")]
_TEX_ARGS = re.compile(r"\\(frac|mathcal|mathbf|mathrm|mathit|mathbb|mathsf|mathtt|text|hat|tilde|bar|dot|ddot|vec"
                       r"|sqrt|overline|widehat|widetilde)(?![A-Za-z])")


def _tex_argument(s: str, i: int) -> tuple[str, int]:
    """``(argument, end)`` of the TeX argument at ``s[i]`` (spaces skipped): a ``{group}``, a ``\\command``
    or one character."""
    while i < len(s) and s[i] == " ":
        i += 1
    if i >= len(s):
        return "", i
    if s[i] == "{":
        depth = 0
        for j in range(i, len(s)):
            depth += {"{": 1, "}": -1}.get(s[j], 0)
            if depth == 0:
                return s[i + 1:j], j + 1
        return s[i + 1:], len(s)
    if s[i] == "\\":
        m = re.match(r"\\([A-Za-z]+|.)", s[i:])
        return m.group(0), i + len(m.group(0))
    return s[i], i + 1


def _brace_arguments(s: str) -> str:
    out, i = [], 0
    while True:
        m = _TEX_ARGS.search(s, i)
        if not m:
            return "".join(out + [s[i:]])
        out.append(s[i:m.end()])
        i = m.end()
        for _ in range(2 if m.group(1) == "frac" else 1):
            arg, i = _tex_argument(s, i)
            out.append("{" + _brace_arguments(arg) + "}")


def _two_row_matrix(m) -> str:
    rows = [r.strip() for r in re.split(r"\\\\", m.group(2)) if r.strip()]
    if len(rows) != 2:
        return m.group(0)                   # left as it is: mathtext refuses it and the TeX is shown
    cells = [r" \quad ".join(c.strip() for c in r.split("&")) for r in rows]
    left, right = {"bmatrix": ("[", "]"), "pmatrix": ("(", ")"), "vmatrix": ("|", "|")}.get(m.group(1), (".", "."))
    return rf"\left{left}\genfrac{{}}{{}}{{0}}{{}}{{{cells[0]}}}{{{cells[1]}}}\right{right}"


def mathtext_source(tex: str) -> str:
    """``tex`` (a formula of the notebooks, LaTeX as MathJax reads it) in the dialect of Matplotlib's
    mathtext: ``\\big`` sizes dropped, ``\\lVert``/``\\lvert`` as ``\\Vert``/``|``, ``\\tfrac`` as ``\\frac``,
    ``\\le`` as ``\\leq``, one-token arguments braced (``\\mathcal N`` → ``\\mathcal{N}``, ``\\frac1K`` →
    ``\\frac{1}{K}``) and a two-row matrix as a ``\\genfrac`` stack."""
    s = " ".join(tex.split())
    s = re.sub(r"\\begin\{([bpv]?matrix)\}(.*?)\\end\{\1\}", _two_row_matrix, s)
    for pattern, repl in _SIMPLE_TEX:
        s = re.sub(pattern, repl, s)
    return _brace_arguments(s)


#: Formula glyphs per glyph of the surrounding text (Computer Modern looks smaller than the page's sans serif).
MATH_SCALE = 1.15


def _svg_number(v: float) -> str:
    text = f"{v:.2f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def math_svg(tex: str, *, display: bool = False) -> str:
    """An inline SVG of formula ``tex``, drawn by Matplotlib's mathtext (Computer Modern glyphs as
    outlines: no font, script or network needed to show it), sized in ``em`` of the surrounding text and
    sitting on its baseline; its TeX is the SVG's title and ARIA label.

    Raises
    ------
    ValueError
        mathtext cannot parse the formula (:func:`mathtext_source`'s translation included).
    """
    import html as html_mod

    from matplotlib.font_manager import FontProperties
    from matplotlib.path import Path as MplPath
    from matplotlib.textpath import TextPath

    size = 10.0                             # outline units per em of the formula
    try:
        path = TextPath((0, 0), f"${mathtext_source(tex)}$", size=size,
                        prop=FontProperties(family="DejaVu Serif", math_fontfamily="cm"))
    except Exception as exc:  # pyparsing's exceptions differ between versions
        raise ValueError(f"mathtext cannot draw {tex!r}: {str(exc).splitlines()[0] if str(exc) else exc!r}") from None
    verts = path.vertices
    (x0, y0), (x1, y1) = (verts.min(axis=0), verts.max(axis=0)) if len(verts) else ((0, 0), (0, 0))
    pad = 0.08 * size
    x0, x1, y0, y1 = x0 - pad, x1 + pad, min(y0, -0.2 * size) - pad, max(y1, 0.7 * size) + pad
    em = MATH_SCALE / size                  # ems of the surrounding text per outline unit
    letters = {MplPath.MOVETO: "M", MplPath.LINETO: "L", MplPath.CURVE3: "Q", MplPath.CURVE4: "C"}
    d = "".join("Z" if code == MplPath.CLOSEPOLY else letters[code] + " ".join(map(_svg_number, pts))
                for pts, code in path.iter_segments(simplify=False, curves=True))
    label = html_mod.escape(tex, quote=True)
    svg = (f'<svg class="uwbwb-math" role="img" aria-label="{label}" '
           f'width="{(x1 - x0) * em:.3f}em" height="{(y1 - y0) * em:.3f}em" '
           f'viewBox="{_svg_number(x0)} {_svg_number(-y1)} {_svg_number(x1 - x0)} {_svg_number(y1 - y0)}" '
           f'style="vertical-align: {y0 * em:.3f}em"><title>{label}</title>'
           f'<path transform="scale(1,-1)" fill="currentColor" d="{d}"/></svg>')
    return f'<div class="uwbwb-math-display">{svg}</div>' if display else svg


def _tex_fallback(tex: str, display: bool) -> str:
    import html as html_mod

    code = f'<code class="uwbwb-tex">{html_mod.escape(tex)}</code>'
    return f'<div class="uwbwb-math-display">{code}</div>' if display else code


def _format_value(value, fmt: str | None) -> str:
    if fmt:
        try:
            return format(value, fmt)
        except (TypeError, ValueError):
            pass
    return str(value)


def static_widget_html(model_id: str, state: Mapping[str, dict]) -> str:
    """Static HTML of the widget ``model_id`` from a saved widget state (``nb.metadata.widgets``): boxes
    as boxes, HTML widgets as their HTML, each control as ``label: value`` (no control), an ``Output`` as
    its saved outputs (a figure as its embedded PNG). What a panel showed when the run ended, with no
    script."""
    import html as html_mod

    model = state.get(model_id.removeprefix("IPY_MODEL_"))
    if model is None:
        return ""
    name, s = model.get("model_name", ""), model.get("state", {})
    classes = " ".join(s.get("_dom_classes", []))
    if "children" in s:
        inner = "".join(static_widget_html(c, state) for c in s["children"])
        return f'<div class="uwbwb-static-box {html_mod.escape(classes)}">{inner}</div>'
    if name in ("HTMLModel", "HTMLMathModel"):
        return f'<div class="{html_mod.escape(classes)}">{s.get("value", "")}</div>'
    if name == "OutputModel":
        return "".join(_static_output(o) for o in s.get("outputs", []))
    if name in ("FloatProgressModel", "IntProgressModel"):       # e.g. a tqdm bar, at its end
        return (f'<progress value="{_format_value(s.get("value", 0), None)}" '
                f'max="{_format_value(s.get("max", 100), None)}"></progress>')
    label = s.get("description", "")
    if "_options_labels" in s:
        index = s.get("index")
        labels = s["_options_labels"]
        value = labels[index] if isinstance(index, int) and 0 <= index < len(labels) else "—"
    elif "value" in s:
        value = _format_value(s["value"], s.get("readout_format"))
    else:
        return ""
    label = f'<span class="uwbwb-static-label">{html_mod.escape(str(label))}:</span> ' if label else ""
    return (f'<div class="uwbwb-static-control">{label}<span class="uwbwb-static-value">'
            f'{html_mod.escape(str(value))}</span></div>')


def _static_output(out: Mapping) -> str:
    import html as html_mod

    if out.get("output_type") == "stream":
        return f"<pre>{html_mod.escape(_text(out.get('text', '')))}</pre>"
    data = out.get("data", {})
    for mime in ("image/png", "image/jpeg"):
        if mime in data:
            return f'<img src="data:{mime};base64,{_text(data[mime]).strip()}" alt="panel figure">'
    if "image/svg+xml" in data:
        return _text(data["image/svg+xml"])
    if "text/html" in data:
        return _text(data["text/html"])
    if "text/plain" in data:
        return f"<pre>{html_mod.escape(_text(data['text/plain']))}</pre>"
    return ""


#: Shown above each static panel of a handout.
STATIC_PANEL_NOTE = ("Static copy of an interactive panel: its controls and figure at the settings the run "
                     "left it in (its defaults). Open the notebook to move the controls.")


#: CSS class of a :class:`uwbwb.widgets.Panel`'s box (its static copy carries :data:`STATIC_PANEL_NOTE`).
_PANEL_CLASS = "uwbwb-panel"


def _widget_state(nb) -> dict:
    """The saved widget models of an executed notebook, ``{model_id: model}``."""
    return nb.metadata.get("widgets", {}).get(_WIDGET_STATE, {}).get("state", {})


def _is_panel(state: Mapping[str, dict], model_id: str) -> bool:
    """Whether the widget ``model_id`` of ``state`` is a :class:`uwbwb.widgets.Panel`."""
    return _PANEL_CLASS in state.get(model_id, {}).get("state", {}).get("_dom_classes", [])


def static_panels(nb) -> int:
    """Replace every widget output of ``nb`` (in place) by static HTML (:func:`static_widget_html`; a
    :class:`uwbwb.widgets.Panel` under :data:`STATIC_PANEL_NOTE`) and drop the saved widget state, so that an
    HTML export needs no widget script; returns the number of widget outputs made static."""
    import html as html_mod

    state = _widget_state(nb)
    count = 0
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            data = out.get("data", {})
            if _WIDGET_MIME not in data:
                continue
            model_id = data[_WIDGET_MIME].get("model_id", "")
            body = static_widget_html(model_id, state)
            del data[_WIDGET_MIME]
            if not body:
                data.setdefault("text/plain", "(a widget: open the notebook)")
                continue
            count += 1
            if _is_panel(state, model_id):
                body = (f'<div class="uwbwb-static-panel"><p class="uwbwb-static-note">'
                        f'{html_mod.escape(STATIC_PANEL_NOTE)}</p>{body}</div>')
            data["text/html"] = body
    nb.metadata.pop("widgets", None)
    return count


_HANDOUT_TEMPLATE = """{%- extends 'index.html.j2' -%}
{%- block html_head_js_requirejs -%}{%- endblock html_head_js_requirejs -%}
{%- block jupyter_widgets -%}{%- endblock jupyter_widgets -%}
{%- block html_head_js_mathjax -%}{%- endblock html_head_js_mathjax -%}
{%- block html_head_js_mermaidjs -%}{%- endblock html_head_js_mermaidjs -%}
{%- block extra_css -%}
<style type="text/css">
.uwbwb-math-display { text-align: center; margin: 0.6em 0; overflow-x: auto; }
svg.uwbwb-math { overflow: visible; }
.uwbwb-static-panel { border: 1px solid #ccc; padding: 0.5em; }
.uwbwb-static-note { font-style: italic; color: #555; margin: 0 0 0.4em 0; }
.uwbwb-static-control { display: inline-block; margin-right: 1.2em; }
.uwbwb-static-label { color: #555; }
.uwbwb-static-value { font-weight: bold; }
.uwbwb-static-panel img { max-width: 100%; }
</style>
{%- endblock extra_css -%}
"""


def _handout_exporter(link_map: Mapping[str, str], fallbacks: list[str]):
    from jinja2 import DictLoader, pass_context
    from nbconvert import HTMLExporter
    from nbconvert.filters.markdown_mistune import IPythonRenderer, MarkdownWithMath
    from nbconvert.preprocessors import TagRemovePreprocessor
    from traitlets.config import Config

    class Renderer(IPythonRenderer):
        def _math(self, body, display):
            try:
                return math_svg(body, display=display)
            except ValueError:
                fallbacks.append(body)
                return _tex_fallback(body, display)

        def inline_math(self, body):
            return self._math(body, False)

        def block_math(self, body):
            return self._math(body, True)

        def latex_environment(self, name, body):
            return self._math(f"\\begin{{{name}}}{body}\\end{{{name}}}", True)

        def link(self, text, url, title=None):
            path, frag = _split_target(url)
            return super().link(text, link_map.get(path, path) + frag if _is_relative(url) else url, title)

    class Exporter(HTMLExporter):
        @pass_context                       # a context filter, as nbconvert's own
        def markdown2html(self, context, source):
            cell = context.get("cell", {})
            renderer = Renderer(escape=False, attachments=cell.get("attachments", {}),
                                embed_images=self.embed_images,
                                path=context.get("resources", {}).get("metadata", {}).get("path", ""),
                                anchor_link_text=self.anchor_link_text,
                                exclude_anchor_links=self.exclude_anchor_links)
            return MarkdownWithMath(renderer=renderer).render(source)

    config = Config()
    config.TagRemovePreprocessor.remove_cell_tags = {RESEARCH_TAG, INJECTED_TAG, AUDIT_HOOK_TAG}
    config.TagRemovePreprocessor.enabled = True
    exporter = Exporter(config=config, extra_loaders=[DictLoader({"uwbwb_handout.html.j2": _HANDOUT_TEMPLATE})],
                        template_file="uwbwb_handout.html.j2", embed_images=True)
    exporter.register_preprocessor(TagRemovePreprocessor(config=config), enabled=True)
    return exporter


def handout_html(nb, *, name: str = "", path: str | os.PathLike = "", link_map: Mapping[str, str] | None = None,
                 tex_left: list[str] | None = None) -> str:
    """HTML of ``nb`` without its ``research`` cells and its injected-parameters cell, that shows all it
    holds offline: one file, no script (no MathJax, RequireJS or widget manager from a CDN), formulas as
    inline SVG (:func:`math_svg`), panels static (:func:`static_panels`), figures embedded.

    Parameters
    ----------
    name
        Page title.
    path
        Folder relative Markdown images are embedded from.
    link_map
        Relative link paths to replace (``{"GLOSSARY.md": "GLOSSARY.html"}``); fragments are kept.
    tex_left
        If given, each formula mathtext could not draw is appended to it (shown as TeX code).
    """
    nb = copy.deepcopy(nb)
    static_panels(nb)
    fallbacks = [] if tex_left is None else tex_left
    exporter = _handout_exporter(dict(link_map or {}), fallbacks)
    body, _ = exporter.from_notebook_node(nb, resources={"metadata": {"name": name or "handout",
                                                                      "path": str(path)}})
    return body


def markdown_page_html(markdown: str, *, name: str, link_map: Mapping[str, str] | None = None,
                       tex_left: list[str] | None = None) -> str:
    """A Markdown text (the glossary) as a standalone HTML page made like a handout (:func:`handout_html`)."""
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_markdown_cell(markdown)]
    return handout_html(nb, name=name, link_map=link_map, tex_left=tex_left)


#: TeX a reader would see as code: a ``$...$`` formula or a ``\\command`` (in a handout's visible text, a formula
#: mathtext could not draw, or one the renderer did not take as math).
TEX_LEFT = re.compile(r"\$[^$]+\$|\\[A-Za-z]+")
#: The same in printed outputs, narrower: only a ``$...$`` holding TeX (``\\``, ``^``, ``_`` or ``{``) with no space
#: inside its dollars, so that prices ("$5 and $6") or a Windows path in a printed line are not taken for formulas.
TEX_LEFT_OUTPUT = re.compile(r"\$(?!\s)[^$\n]*[\\^_{][^$\n]*(?<!\s)\$")


def markdown_formulas(nb) -> int:
    """The formulas of a notebook's Markdown cells that a handout shows (``research`` cells left out): ``$$...$$``,
    ``\\begin{env}...\\end{env}`` and ``$...$``, code spans and fenced code not counted."""
    count = 0
    for cell in nb.cells:
        if cell.cell_type != "markdown" or RESEARCH_TAG in _tags(cell):
            continue
        s = re.sub(r"^(```|~~~).*?^\1", " ", cell.source, flags=re.S | re.M)
        s = re.sub(r"(`+).*?\1", " ", s, flags=re.S)
        for pattern in (r"\$\$.+?\$\$", r"(?<!\\)\$[^$]+?(?<!\\)\$", r"\\begin\{([a-z]+\*?)\}.*?\\end\{\1\}"):
            count += len(re.findall(pattern, s, flags=re.S))
            s = re.sub(pattern, " ", s, flags=re.S)
    return count


def notebook_panels(nb) -> int:
    """The :class:`uwbwb.widgets.Panel` views among the outputs of an executed notebook's non-``research`` cells."""
    state = _widget_state(nb)
    return sum(_is_panel(state, out["data"][_WIDGET_MIME].get("model_id", ""))
               for cell in nb.cells if RESEARCH_TAG not in _tags(cell)
               for out in cell.get("outputs", []) if _WIDGET_MIME in out.get("data", {}))


def _plain(html: str) -> str:
    """The text of an HTML fragment: style and SVG elements (a formula's TeX is its SVG's title) and tags dropped,
    entities decoded."""
    import html as html_mod

    html = re.sub(r"<(style|svg)\b.*?</\1>", " ", html, flags=re.S | re.I)
    return html_mod.unescape(re.sub(r"<[^>]*>", "", html))


def _static_panel_html(html: str) -> list[str]:
    """The HTML of each static panel of a handout (its whole ``<div class="uwbwb-static-panel">``)."""
    panels = []
    for m in re.finditer(r'<div class="uwbwb-static-panel">', html):
        depth = 0
        for tag in re.finditer(r"<(/?)div\b[^>]*>", html[m.start():]):
            depth += -1 if tag.group(1) else 1
            if depth == 0:
                panels.append(html[m.start():m.start() + tag.end()])
                break
    return panels


def handout_problems(html: str, nb, values: Mapping[str, object]) -> list[str]:
    """What the handout ``html`` of the executed notebook ``nb`` (:func:`handout_html`) would not show offline, read
    without a browser, one sentence each; empty when it shows everything:

    * a script loaded from a file, a stylesheet or CSS import loaded from the web, MathJax or widget views;
    * TeX (:data:`TEX_LEFT`) in the visible text of its Markdown cells or of its outputs;
    * a number of math SVGs in its Markdown cells other than the formulas of ``nb``'s Markdown
      (:func:`markdown_formulas`);
    * a number of static panels with an embedded image other than the panels of ``nb`` (:func:`notebook_panels`);
    * a parameter of ``values`` (:func:`class_values`) not shown as ``NAME = value``.
    """
    found = [f"script loaded from {m}" for m in re.findall(r"<script\b[^>]*\bsrc\s*=\s*[\"']([^\"']*)", html, re.I)]
    found += [f"stylesheet from {m}" for m in re.findall(r"<link\b[^>]*\bhref\s*=\s*[\"'](https?:[^\"']*)", html, re.I)]
    found += [f"CSS loads {m}" for m in re.findall(r"(?:@import\s*|url\(\s*[\"']?)(https?:[^\"')\s;]*)", html, re.I)]
    found += ["mentions MathJax"] * ("mathjax" in html.lower())
    found += ["holds widget views"] * (_WIDGET_MIME in html or _WIDGET_STATE in html)
    cells = re.split(r'(?=<div class="jp-Cell )', html)[1:]
    markdown = [c for c in cells if c.startswith('<div class="jp-Cell jp-MarkdownCell')]
    outputs = [c[c.find("jp-Cell-outputWrapper"):] for c in cells if "jp-Cell-outputWrapper" in c]
    for where, parts, tex_left in (("Markdown", markdown, TEX_LEFT), ("output", outputs, TEX_LEFT_OUTPUT)):
        found += [f"TeX left in the {where} text: {tex}" for part in parts for tex in tex_left.findall(_plain(part))]
    drawn = sum(len(re.findall(r'<svg\b[^>]*\bclass="uwbwb-math"', c)) for c in markdown)
    if drawn != (formulas := markdown_formulas(nb)):
        found.append(f"{drawn} formulas drawn for the {formulas} of the notebook's Markdown")
    shown = sum(bool(re.search(r'<img\b[^>]*\bsrc="data:image/', p)) for p in _static_panel_html(html))
    if shown != (panels := notebook_panels(nb)):
        found.append(f"{shown} static panels with their figure for the notebook's {panels} panels")
    text = _plain(html)
    found += [f"{name} = {value!r} not shown" for name, value in values.items()
              if not re.search(rf"\b{name}\s*=\s*{value!r}(?!\w)", text)]
    return found


# ---------------------------------------------------------------- class run

def _one_folder(notebooks: Sequence[Path]) -> Path:
    folders = {n.resolve().parent for n in notebooks}
    if len(folders) != 1:
        raise ValueError("the notebooks of a class run come from one folder, got "
                         f"{sorted(map(str, folders)) or 'none'}")
    return folders.pop()


def lab_sheets(teaching: str) -> str:
    """The students' lab sheets from the text of ``TEACHING.md``: its section :data:`ROUTES_HEADING` (each route's
    objectives, steps, questions and timing) up to the first :data:`ANSWERS_HEADING` heading, under a title."""
    lines = teaching.splitlines()
    start = next((i for i, ln in enumerate(lines) if ln.strip() == ROUTES_HEADING), None)
    if start is None:
        raise ValueError(f"{TEACHING_NAME} has no {ROUTES_HEADING!r} heading: no lab sheets to hand out")
    end = next((i for i, ln in enumerate(lines) if i > start and ln.startswith(ANSWERS_HEADING)), len(lines))
    return "# Lab sheets\n\n" + "\n".join(lines[start:end]).rstrip() + "\n"


def write_student_folder(notebooks: Iterable[Path], student_dir: Path) -> tuple[_Companions, dict[Path, Path]]:
    """The student folder (module docstring): each notebook's :func:`student_notebook` with the class values of
    its parameters (:func:`class_values`), the glossary and every file they link to beside them, and the lab sheets
    (:func:`lab_sheets`, when ``TEACHING.md`` is in the folder above the notebooks').

    Returns
    -------
    (companions, copies)
        The linked files and their places; ``{source notebook: its student copy}``.
    """
    import nbformat

    notebooks = [Path(n) for n in notebooks]
    source_dir = _one_folder(notebooks)
    student_dir = Path(student_dir)
    student_dir.mkdir(parents=True, exist_ok=True)
    sources = {n: _read_notebook(n) for n in notebooks}
    companions = _Companions(source_dir)
    companions.add(source_dir / GLOSSARY_NAME)
    for nb in sources.values():
        companions.add_links(notebook_links(nb), source_dir)
    teaching = source_dir.parent / TEACHING_NAME
    sheets = lab_sheets(teaching.read_text(encoding="utf-8")) if teaching.is_file() else None
    if sheets is not None:
        companions.add_links(relative_links(sheets), teaching.parent)
    companions.write(student_dir)
    if sheets is not None:
        (student_dir / LAB_SHEETS_NAME).write_text(companions.relink(
            sheets, teaching.parent, student_dir.resolve(), student_dir.resolve()), encoding="utf-8")
    copies = {}
    for source, nb in sources.items():
        copies[source] = student_dir / source.name
        student = student_notebook(nb, class_values(reproduce.notebook_parameters(source)))
        for cell in student.cells:           # links follow the copies (see _Companions)
            if cell.cell_type == "markdown":
                cell.source = companions.relink(cell.source, source_dir, student_dir.resolve(), student_dir.resolve())
        nbformat.write(student, copies[source])
    return companions, copies


def _answer_companions(companions: _Companions, answers_dir: Path, teaching: Path, log) -> dict[str, str]:
    """Write the student folder's companions, ``teaching`` and the glossary's HTML page into ``answers_dir``;
    returns the link map of the handouts (``{"GLOSSARY.md": "GLOSSARY.html"}``)."""
    answers = _Companions(companions.root)
    answers.placed.update(companions.placed)
    if teaching.is_file():
        answers.add(teaching, Path(TEACHING_NAME))
    else:
        log(f"no {teaching}: the answers folder has no lecturer's notes")
    answers.write(answers_dir)
    glossary = (companions.root / GLOSSARY_NAME).resolve()
    if glossary not in companions.placed:
        return {}
    place = companions.placed[glossary]
    text = companions.relink(glossary.read_text(encoding="utf-8"), glossary.parent, answers_dir.resolve(),
                             (answers_dir / place).parent.resolve())
    tex_left: list[str] = []
    (answers_dir / place.with_suffix(".html")).write_text(
        markdown_page_html(text, name="Glossary", link_map={place.name: place.with_suffix(".html").name},
                           tex_left=tex_left), encoding="utf-8")
    if tex_left:
        log(f"{GLOSSARY_NAME}: {len(tex_left)} formulas shown as TeX in its HTML page: " + "; ".join(tex_left[:3]))
    return {place.as_posix(): place.with_suffix(".html").as_posix()}


def run_class(notebooks: Iterable[Path], out_dir: Path, *, kernel_name: str = reproduce.KERNEL_NAME,
              timeout_s: float | None = 600, log=print) -> list[dict]:
    """Write the class folders of ``notebooks`` under ``out_dir`` (see the module docstring): the
    student folder first (:func:`write_student_folder`), then each student copy executed in that folder
    into the answers folder, with its handout. The lecturer's notes are ``TEACHING.md`` in the folder above
    the notebooks' (skipped, with a note, when there is none).

    Returns
    -------
    list of dict
        Per notebook: ``notebook``, ``seconds`` (wall time, kernel start included), ``error`` (None when it
        ran; what its answer key's checks or its handout (:func:`handout_problems`) got wrong, when it ran), ``limits``
        (:func:`class_limits`), ``student``, ``executed`` and ``html`` paths, ``tex_left``
        (formulas the handout shows as TeX) and ``class_parameter``.
    """
    import nbformat
    import papermill as pm

    notebooks = [Path(n) for n in notebooks]
    out_dir = Path(out_dir)
    student_dir, answers_dir = out_dir / STUDENT_DIR, out_dir / ANSWERS_DIR
    answers_dir.mkdir(parents=True, exist_ok=True)
    for source in notebooks:     # this run's earlier output
        for stale in (answers_dir / f"{source.stem}.ipynb", answers_dir / f"{source.stem}.html"):
            stale.unlink(missing_ok=True)
    companions, copies = write_student_folder(notebooks, student_dir)
    link_map = _answer_companions(companions, answers_dir, companions.root.parent / TEACHING_NAME, log)

    runs = []
    for source in notebooks:
        values = class_values(reproduce.notebook_parameters(source))
        student = copies[source]
        executed, html = answers_dir / f"{source.stem}.ipynb", answers_dir / f"{source.stem}.html"
        error = None
        t0 = time.perf_counter()
        try:            # a student's Run All of the copy as handed out, answered, run in the student folder
            nbformat.write(answer_key(nbformat.read(student, as_version=4),
                                      prediction_claims(nbformat.read(source, as_version=4))), executed)
            pm.execute_notebook(str(executed), str(executed), kernel_name=kernel_name, cwd=str(student_dir),
                                progress_bar=False, log_output=False, execution_timeout=timeout_s,
                                kernel_manager_class=reproduce.ipc_kernel_manager())
        except Exception as exc:  # reported per notebook; the others still run
            error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''}"
        seconds = time.perf_counter() - t0
        limits, tex_left = [], []
        if executed.is_file():
            nb = nbformat.read(executed, as_version=4)
            limits = class_limits(nb)
            wrong = wrong_predictions(nb) if error is None else []
            nbformat.write(fold_research(nb), executed)
            page = handout_html(nb, name=source.stem, path=answers_dir, link_map=link_map, tex_left=tex_left)
            html.write_text(page, encoding="utf-8")
            lacks = handout_problems(page, nb, values) if error is None else []
            error = "; ".join([f"answer key: {'; '.join(wrong)}"] * bool(wrong)
                              + [f"handout {html.name}: {'; '.join(lacks)}"] * bool(lacks)) or error
        run = {"notebook": source.stem, "seconds": seconds, "error": error, "limits": limits, "student": student,
               "executed": executed if executed.is_file() else None, "html": html if html.is_file() else None,
               "tex_left": tex_left, "class_parameter": "CLASS" in values}
        runs.append(run)
        note = "" if run["class_parameter"] else " (no CLASS parameter: FAST only)"
        log(f"{source.stem}: {'ok' if error is None else 'FAILED'} in {seconds:.1f} s{note}")
        if error:
            log(f"  error: {error}")
        for p in limits:
            log(f"  class limit: {p}")
        if tex_left:
            log(f"  handout: {len(tex_left)} formulas shown as TeX (mathtext cannot draw them): "
                + "; ".join(tex_left[:3]))
    return runs


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m uwbwb.classroom [--only NB ...] [--kernel NAME] [--out DIR] [--notebooks-dir DIR]``."""
    parser = argparse.ArgumentParser(prog="python -m uwbwb.classroom",
                                     description="Class mode (CLASS=True, FAST=True): unexecuted student notebooks "
                                                 "in OUT/student, the same run into OUT/answers with offline HTML "
                                                 "handouts, TEACHING.md and the glossary.")
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
          f"{n_limits} class-limit violations; for students: {args.out / STUDENT_DIR} (make lab "
          f"LAB_DIR={args.out / STUDENT_DIR}); executed notebooks, handouts and notes: {args.out / ANSWERS_DIR}")
    return 0 if all(r["error"] is None for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
