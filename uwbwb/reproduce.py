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
under ``quick``, plus any given explicitly. Each value is checked against the
notebook's parameter specification (:mod:`uwbwb.notebook_params`: type, range,
what None means) before any notebook runs, and reaches the notebook with the
type the specification gives it: the runner writes the injected parameters cell
itself, as Python literals (papermill would write a tuple as a string). An
explicit value that the notebook's FAST mode would replace or lower is refused
under ``FAST=True``, as is ``FAST=False`` given with ``quick``. All notebooks
run even if one fails; the run is unsuccessful if a notebook failed or wrote no
valid summary.

Kernels are started on IPC transport (local sockets, no TCP ports), so that
jupyter_client's warning about unencrypted TCP never reaches the output.

With ``--scheduler ADDRESS`` (or ``local``) the notebooks run concurrently as
tasks on that Dask cluster, each receiving the cluster as its
``DASK_SCHEDULER`` parameter so that its sweeps run there too
(:mod:`uwbwb.parallel`); the outputs and the summary are the same files.
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

from . import notebook_params
from .datasets.discovery import PROJECT_ROOT
from .metrics import Summary
from .notebook_params import Spec

#: Notebooks run by default.
NOTEBOOKS_DIR = PROJECT_ROOT / "notebooks"
#: Default output folder.
REPORTS_DIR = PROJECT_ROOT / "reports"
#: Kernel the notebooks are executed with.
KERNEL_NAME = "python3"
#: Keys of every summary row, in display order.
SUMMARY_KEYS = Summary.COLUMNS
#: The notebook parameter that receives the Dask scheduler (``reproduce --scheduler``).
SCHEDULER_PARAMETER = "DASK_SCHEDULER"
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


_MISSING = object()


def notebook_parameters(notebook: str | os.PathLike) -> dict[str, Any]:
    """The parameters a notebook declares and their defaults.

    Read from its one code cell tagged ``parameters``: every top-level
    ``NAME = <literal>`` assignment. A default that is not a literal (an
    expression) is returned as None, i.e. it takes any literal.

    The notebook is read as plain JSON (nbformat's import costs seconds, and every
    problem with the parameters must be reported before any of that).

    Raises
    ------
    ValueError
        The notebook is not notebook JSON, has no such cell, several, or a cell that is not valid Python.
    """
    path = Path(notebook)
    try:
        nb = json.loads(path.read_text(encoding="utf-8"))
        cells = [c for c in nb["cells"] if c.get("cell_type") == "code"
                 and "parameters" in (c.get("metadata") or {}).get("tags", [])]
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path.name}: not a Jupyter notebook ({type(exc).__name__}: {exc})") from None
    if len(cells) != 1:
        raise ValueError(f"{path.name}: expected exactly one code cell tagged 'parameters', found {len(cells)}")
    source = cells[0].get("source", "")
    source = "".join(source) if isinstance(source, list) else str(source)
    try:
        tree = ast.parse(source)
    except SyntaxError as exc:
        raise ValueError(f"{path.name}: parameters cell, line {exc.lineno}: {exc.msg}") from None
    declared = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            name, value = node.targets[0].id, node.value
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
            name, value = node.target.id, node.value
        else:
            continue
        try:
            declared[name] = ast.literal_eval(value)
        except (ValueError, SyntaxError, TypeError):
            declared[name] = None
    return declared


def parameter_specs(notebook: str | os.PathLike) -> dict[str, Spec]:
    """The :class:`~uwbwb.notebook_params.Spec` of every parameter a notebook declares.

    From :data:`uwbwb.notebook_params.SPECS` for the project's notebooks (by stem); inferred
    from each default for other notebooks (:func:`uwbwb.notebook_params.infer`).
    """
    path = Path(notebook)
    return notebook_params.specs_for(path.stem, notebook_parameters(path))


def parse_parameter_value(text: str, default: Any = None, *, name: str = "value", spec: Spec | None = None) -> Any:
    """A ``-p NAME VALUE`` value, checked and typed by the parameter's spec.

    ``spec`` defaults to the one inferred from ``default``
    (:func:`uwbwb.notebook_params.infer`): a string default keeps the text exactly as
    typed (``"8.20"`` stays ``"8.20"``); a bool takes ``True``/``False`` (also lower
    case); an int, float or tuple reads the text as a Python literal of that type (an
    int is accepted for a float, an integral float such as ``1e9`` for an int; a tuple's
    elements must fit the default's elements when those share one type); None: any
    Python literal, else the text. See :meth:`uwbwb.notebook_params.Spec.parse`.

    Raises
    ------
    ValueError
        A value that does not fit, naming the parameter, what was expected and the default.
    """
    spec = notebook_params.infer(default) if spec is None else spec
    try:
        return spec.parse(text, name)
    except ValueError as exc:
        raise ValueError(f"{exc} (the default of {name} is {default!r})") from None


def resolve_parameters(notebooks: Iterable[str | os.PathLike], parameters: Mapping[str, Any] | None = None,
                       *, text: Mapping[str, str] | None = None, quick: bool = False) -> dict[Path, dict[str, Any]]:
    """The parameters each notebook will receive, checked against what it declares.

    Parameters
    ----------
    notebooks
        The selected notebooks.
    parameters
        Python values (e.g. ``{"FAST": True, "N_TRIALS": 5}``): each must satisfy the
        notebook's spec (see :func:`parameter_specs`).
    text
        Values as typed on the command line (``-p NAME VALUE``): parsed by each
        notebook's spec (see :func:`parse_parameter_value`). A name in both wins from ``text``.
    quick
        Every notebook runs with ``FAST=True`` (``--quick``); an explicit ``FAST=False`` is refused.

    Returns
    -------
    dict
        Notebook path → ``{name: value}`` for the names that notebook declares, each
        value of the type its spec gives.

    Raises
    ------
    ValueError
        A reserved name, a name that no selected notebook declares (the message lists
        the valid names), a value that does not satisfy its spec, ``FAST=False`` with
        ``quick``, or (when the notebook will run with ``FAST=True``) an explicit value
        that its FAST mode replaces or lowers (see :func:`uwbwb.notebook_params.fast_conflict`).
    """
    notebooks = [Path(nb) for nb in notebooks]
    parameters, text = dict(parameters or {}), dict(text or {})
    given = parameters | text
    reserved = sorted(set(given) & set(RESERVED_PARAMETERS))
    if reserved:
        raise ValueError(f"parameter(s) {', '.join(reserved)} are set by the runner and cannot be passed")
    declared = {nb: notebook_parameters(nb) for nb in notebooks}
    valid = sorted({name for d in declared.values() for name in d} - set(RESERVED_PARAMETERS))
    unknown = [name for name in given if not any(name in d for d in declared.values())]
    if unknown:
        stems = ", ".join(nb.stem for nb in notebooks)
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}: not declared by {stems}; "
                         f"valid names: {', '.join(valid)}")
    resolved = {}
    for nb, defaults in declared.items():
        specs = notebook_params.specs_for(nb.stem, defaults)
        params = {}
        for name in given:
            if name not in defaults:
                continue
            try:
                if name in text:
                    params[name] = parse_parameter_value(text[name], defaults[name], name=name, spec=specs[name])
                else:
                    try:
                        params[name] = specs[name].validate(parameters[name], name)
                    except ValueError as exc:
                        raise ValueError(f"parameter {exc} (the default of {name} is {defaults[name]!r})") from None
            except ValueError as exc:
                raise ValueError(f"{nb.stem}: {exc}") from None
        if quick and "FAST" in defaults:
            if params.get("FAST", True) is not True:
                raise ValueError(f"--quick sets FAST=True, but FAST={params['FAST']!r} was given too: "
                                 f"drop --quick or the FAST value")
            params = {"FAST": True} | params
        if params.get("FAST", defaults.get("FAST")) is True:
            for name, value in params.items():
                problem = notebook_params.fast_conflict(nb.stem, name, value, specs[name])
                if problem is not None:
                    raise ValueError(problem)
        resolved[nb] = params
    return resolved


#: Tag papermill gives the cell of injected parameters (kept, so that tools reading executed notebooks find it).
INJECTED_TAG = "injected-parameters"


def injected_source(parameters: Mapping[str, Any]) -> str:
    """The injected parameters cell: one ``NAME = <Python literal>`` line per parameter.

    Every value is written as its ``repr``, which must read back as the same value of
    the same type (papermill itself would turn a tuple into a string).

    Raises
    ------
    ValueError
        A value whose ``repr`` is not a Python literal giving it back (a non-finite
        float, an object), naming the parameter.
    """
    lines = ["# Parameters (injected by python -m uwbwb reproduce)"]
    for name, value in parameters.items():
        if not name.isidentifier():
            raise ValueError(f"parameter name {name!r} is not a Python identifier")
        literal = repr(value)
        try:
            back = ast.literal_eval(literal)
        except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
            back = _MISSING
        if back is _MISSING or type(back) is not type(value) or back != value:
            raise ValueError(f"parameter {name}={literal[:60]}: not a Python literal that reads back as itself")
        lines.append(f"{name} = {literal}")
    return "\n".join(lines) + "\n"


def parameterized(nb, parameters: Mapping[str, Any]):
    """``nb`` (a notebook node, changed in place and returned) with the injected parameters cell
    right after its ``parameters`` cell (replacing an injected cell already there)."""
    import nbformat

    cells = [c for c in nb.cells if INJECTED_TAG not in c.metadata.get("tags", [])]
    where = next((i + 1 for i, c in enumerate(cells) if "parameters" in c.metadata.get("tags", [])), 0)
    cell = nbformat.v4.new_code_cell(injected_source(parameters))
    cell.metadata["tags"] = [INJECTED_TAG]
    nb.cells = cells[:where] + [cell] + cells[where:]
    meta = nb.metadata.setdefault("papermill", {})
    meta["parameters"] = json.loads(json.dumps(dict(parameters), default=repr))   # JSON record (tuples as lists)
    return nb


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


def read_summary(path: Path, notebook: str, mode: str | None = None) -> tuple[list[dict], str | None]:
    """Rows of a notebook's summary file and the problem with it (None when valid).

    ``mode`` (``"FAST"`` / ``"full"``), when given, is the mode the notebook ran
    in: every row must say so.
    """
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
        if row["kind"] not in Summary.KINDS:
            return [], f"summary file {path.name}, row {i}: kind must be one of {', '.join(Summary.KINDS)}, got {row['kind']!r}"
        if row["mode"] not in Summary.MODES:
            return [], f"summary file {path.name}, row {i}: mode must be one of {', '.join(Summary.MODES)}, got {row['mode']!r}"
        if mode is not None and row["mode"] != mode:
            return [], (f"summary file {path.name}, row {i}: mode {row['mode']!r}, but the notebook ran with "
                        f"FAST={mode == 'FAST'} (pass fast=FAST to uw.metrics.Summary)")
    return [{k: row[k] for k in SUMMARY_KEYS} for row in rows], None


def _export_html(executed: Path, html: Path) -> None:
    import nbformat
    from nbconvert import HTMLExporter

    body, _ = HTMLExporter().from_notebook_node(nbformat.read(executed, as_version=4))
    html.write_text(body, encoding="utf-8")


def run_notebook(source: Path, out_dir: Path, parameters: Mapping[str, Any], *,
                 timeout_s: float | None = None, kernel_name: str = KERNEL_NAME,
                 kernel_env: Mapping[str, str] | None = None) -> NotebookRun:
    """Execute one notebook into ``out_dir`` and read its summary (see :func:`reproduce`).

    ``parameters`` go to the notebook's injected cell as given (see
    :func:`resolve_parameters` for checking them first); ``kernel_env`` is added to
    the kernel's environment.
    """
    executed, html, summary = _outputs(source, out_dir)
    params = {**parameters, "SUMMARY_PATH": str(summary)}
    error = None
    t0 = time.perf_counter()
    try:
        _papermill(source, executed, params, source.parent, timeout_s, kernel_name, kernel_env)
    except Exception as exc:  # any failure of one notebook is reported; the others still run
        error = _first_line(exc)
    return _finish(source, out_dir, parameters, error, time.perf_counter() - t0)


def _outputs(source: Path, out_dir: Path) -> tuple[Path, Path, Path]:
    """The executed notebook, HTML and summary paths of ``source``, with stale copies removed."""
    stem = source.stem
    paths = (out_dir / f"{stem}.ipynb", out_dir / f"{stem}.html", out_dir / f"{stem}.summary.json")
    for stale in paths:
        stale.unlink(missing_ok=True)  # a failed run must not show an older run's results
    return paths


def _papermill(source, executed, params, cwd, timeout_s, kernel_name, kernel_env=None) -> None:
    """Execute ``source`` into ``executed`` with ``params`` in an injected cell (:func:`parameterized`),
    on a kernel over IPC transport (:func:`_kernel_manager_class`) with ``kernel_env`` added to its environment."""
    import tempfile

    import nbformat
    import papermill as pm

    nb = parameterized(nbformat.read(str(source), as_version=4), params)
    with tempfile.TemporaryDirectory(prefix="uwbwb-nb-") as tmp:
        prepared = Path(tmp, Path(source).name)
        nbformat.write(nb, str(prepared))
        try:
            pm.execute_notebook(str(prepared), str(executed), parameters=None, kernel_name=kernel_name,
                                cwd=str(cwd), progress_bar=False, log_output=False, execution_timeout=timeout_s,
                                kernel_manager_class=_kernel_manager_class(kernel_env))
        finally:
            if Path(executed).is_file():   # the record names the notebook, not the scratch copy
                out = nbformat.read(str(executed), as_version=4)
                out.metadata.setdefault("papermill", {})["input_path"] = str(source)
                nbformat.write(out, str(executed))


def _kernel_manager_class(env: Mapping[str, str] | None = None):
    """A jupyter_client kernel manager on IPC transport (Unix sockets in Jupyter's private runtime
    folder, removed at shutdown): no TCP port is opened, so ipykernel has no unencrypted-TCP warning
    to print. ``env`` is added to the kernel's environment."""
    import uuid

    from jupyter_client.connect import jupyter_runtime_dir
    from jupyter_client.manager import AsyncKernelManager
    from traitlets import CaselessStrEnum, default

    extra = dict(env or {})

    class IpcKernelManager(AsyncKernelManager):
        transport = CaselessStrEnum(["tcp", "ipc"], default_value="ipc", config=True)

        @default("ip")
        def _ipc_path(self):
            runtime = Path(jupyter_runtime_dir())
            runtime.mkdir(mode=0o700, parents=True, exist_ok=True)
            return str(runtime / f"uwbwb-{uuid.uuid4().hex[:12]}-ipc")

        async def start_kernel(self, **kw):
            if extra:
                kw["env"] = {**kw.get("env", os.environ), **extra}
            return await super().start_kernel(**kw)

    return IpcKernelManager


def _finish(source: Path, out_dir: Path, parameters: Mapping[str, Any], error: str | None,
            seconds: float) -> NotebookRun:
    """Render the executed notebook and read its summary into a :class:`NotebookRun`."""
    stem = source.stem
    executed, html, summary = (out_dir / f"{stem}.ipynb", out_dir / f"{stem}.html",
                               out_dir / f"{stem}.summary.json")
    if executed.is_file():
        try:
            _export_html(executed, html)
        except Exception as exc:  # rendering problems are reported like execution problems
            html = None
            error = error or f"HTML export failed: {_first_line(exc)}"
    else:
        html = None
    fast = parameters.get("FAST", notebook_parameters(source).get("FAST"))
    rows, problem = read_summary(summary, stem, ("FAST" if fast else "full") if isinstance(fast, bool) else None)
    if error is None:
        error = problem
    return NotebookRun(notebook=stem, source=source, executed=executed, html=html, summary=summary,
                       seconds=seconds, error=error, rows=tuple(rows))


def _notebook_task(name: str, text: str, cwd: str, parameters: Mapping[str, Any], timeout_s: float | None,
                   kernel_name: str, kernel_env: Mapping[str, str] | None = None
                   ) -> tuple[str | None, str | None, str | None, float]:
    """Execute one notebook where this task runs (a Dask worker) in a scratch folder.

    The notebook's text travels with the task and the executed notebook and its
    summary travel back, so the worker needs the package and the data, not the
    output folder. While the kernel runs, the task leaves its worker thread
    (``distributed.secede``), so the sweeps the notebook itself sends to the same
    cluster find free threads.

    Returns
    -------
    tuple
        ``(executed notebook text or None, summary text or None, error or None, seconds)``.
    """
    import tempfile

    try:
        from distributed import rejoin, secede
        secede()
        seceded = True
    except (ImportError, ValueError):  # not on a Dask worker
        seceded = False
    try:
        with tempfile.TemporaryDirectory(prefix=f"uwbwb-{name}-") as tmp:
            source, executed, summary = Path(tmp, f"{name}.ipynb"), Path(tmp, "executed.ipynb"), Path(tmp, "summary.json")
            source.write_text(text, encoding="utf-8")
            t0 = time.perf_counter()
            error = _papermill_in_subprocess(source, executed, {**parameters, "SUMMARY_PATH": str(summary)},
                                             cwd if os.path.isdir(cwd) else tmp, timeout_s, kernel_name, kernel_env)
            seconds = time.perf_counter() - t0
            read = (lambda p: p.read_text(encoding="utf-8") if p.is_file() else None)
            return read(executed), read(summary), error, seconds
    finally:
        if seceded:
            rejoin()


def _papermill_in_subprocess(source, executed, params, cwd, timeout_s, kernel_name, kernel_env=None) -> str | None:
    """:func:`_papermill` in a child Python process; the first line of its error, or None.

    Each notebook gets its own process (and event loop): several notebooks run at
    once in the threads of one worker, which papermill's client cannot share.
    """
    import pickle
    import subprocess
    import sys

    job = Path(executed).with_suffix(".job")
    job.write_bytes(pickle.dumps((str(source), str(executed), dict(params), str(cwd), timeout_s, kernel_name,
                                  dict(kernel_env or {}))))
    code = "import sys; from uwbwb.reproduce import _papermill_job; _papermill_job(sys.argv[1])"
    done = subprocess.run([sys.executable, "-c", code, str(job)], capture_output=True, text=True)
    failure = job.with_suffix(".error")
    if failure.is_file():
        return failure.read_text(encoding="utf-8")
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines() or [f"exit status {done.returncode}"]
        return f"notebook process failed: {lines[-1]}"
    return None


def _papermill_job(job: str) -> None:
    """Entry point of :func:`_papermill_in_subprocess`'s child: run the pickled job, write the error line if any."""
    import pickle

    source, executed, params, cwd, timeout_s, kernel_name, kernel_env = pickle.loads(Path(job).read_bytes())
    try:
        _papermill(source, executed, params, cwd, timeout_s, kernel_name, kernel_env)
    except Exception as exc:  # reported by the parent as the run's status
        Path(job).with_suffix(".error").write_text(_first_line(exc), encoding="utf-8")


def _run_on_cluster(notebooks, out_dir, resolved, client, timeout_s, kernel_name, log,
                    kernel_env=None) -> list[NotebookRun]:
    """Every notebook a task on the cluster, as many at once as it has threads; runs in notebook order."""
    from . import parallel

    tasks = [parallel.Task({"name": nb.stem, "text": nb.read_text(encoding="utf-8"), "cwd": str(nb.parent),
                            "parameters": resolved[nb]}) for nb in notebooks]
    by_name = {nb.stem: nb for nb in notebooks}
    runs = []
    slots = max(sum(client.nthreads().values()), 1)
    if log:
        log(f"running {len(notebooks)} notebooks on the Dask cluster at {client.scheduler.address}, "
            f"up to {slots} at once")
    for i, (task, out) in enumerate(parallel.imap(
            _notebook_task, tasks, shared={"timeout_s": timeout_s, "kernel_name": kernel_name,
                                           "kernel_env": kernel_env}, scheduler=client,
            progress=False, desc="notebooks", unit="notebook", max_pending=slots), 1):
        source = by_name[task.params["name"]]
        executed, _, summary = _outputs(source, out_dir)
        text, summary_text, error, seconds = out
        if text is not None:
            executed.write_text(text, encoding="utf-8")
        if summary_text is not None:
            summary.write_text(summary_text, encoding="utf-8")
        run = _finish(source, out_dir, resolved[source], error, seconds)
        runs.append(run)
        if log:
            log(f"[{i}/{len(notebooks)}] {run.notebook}: {run.status} ({run.seconds:.1f} s)"
                + (f" — {run.error}" if run.error else ""))
    return runs


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


#: Mark beside a FAST row's value in ``summary.md``.
FAST_MARK = "(FAST)"


def summary_markdown(runs: Iterable[NotebookRun], parameters: Mapping[str, Any] | None = None) -> str:
    """The ``summary.md`` text: headline numbers, then the run status of every notebook.

    When any row comes from a FAST run, a note at the top says so, and each FAST
    row's value is followed by :data:`FAST_MARK` (smoke-test numbers: they must
    not be read as a reproduction of the paper's value beside them).
    """
    runs = list(runs)
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    out = ["# Reproduction summary", "",
           f"Generated by `python -m uwbwb reproduce` on {stamp}."]
    if parameters:
        out.append("Parameters: " + ", ".join(f"`{k}={v!r}`" for k, v in parameters.items()) + ".")
    all_rows = [row for run in runs for row in run.rows]
    fast_notebooks = list(dict.fromkeys(row["notebook"] for row in all_rows if row["mode"] == "FAST"))
    if fast_notebooks:
        n_fast = sum(row["mode"] == "FAST" for row in all_rows)
        scope = "All rows" if n_fast == len(all_rows) else f"{n_fast} of {len(all_rows)} rows"
        out += ["", f"**FAST mode.** {scope} come from FAST runs ({', '.join(fast_notebooks)}): small, "
                    f"CI-sized experiments whose numbers are smoke tests, not reproductions. "
                    f"Their values are marked {FAST_MARK}; do not compare them with the paper's values."]
    out += ["", "## Headline numbers", "",
            "Kind: *reproduced* came out of the method; *target* is a number a simulator parameter "
            "was chosen to hit; *input* is taken from the paper.", ""]
    rows = [[row["notebook"], row["quantity"],
             _cell(row["value"]) + (f" {FAST_MARK}" if row["mode"] == "FAST" else ""),
             row["unit"], row["paper_value"], row["kind"], row["mode"], row["data"]] for row in all_rows]
    if rows:
        out += _table(["notebook", "quantity", "value", "unit", "paper value", "kind", "mode", "data"], rows)
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
              text_parameters: Mapping[str, str] | None = None,
              timeout_s: float | None = None, notebooks_dir: str | os.PathLike | None = None,
              kernel_name: str = KERNEL_NAME, scheduler=None, scheduler_timeout_s: float | None = None,
              log: Callable[[str], None] | None = None) -> ReproduceResult:
    """Execute the notebooks and aggregate their summaries.

    Parameters
    ----------
    quick
        Pass ``FAST=True`` (the CI setting: smaller experiments, looser checks). An
        explicit ``FAST=False``, or an explicit value that a notebook's FAST mode would
        replace or lower, is refused (see :func:`resolve_parameters`).
    only
        Notebook selection, see :func:`select_notebooks`.
    out
        Output folder; default ``reports/`` in the project.
    parameters
        Extra notebook parameters as Python values, checked by each notebook's spec
        (:func:`parameter_specs`); each goes to the selected notebooks that declare it.
    text_parameters
        Extra notebook parameters as typed on the command line, typed by each
        notebook's declared default (see :func:`resolve_parameters`).
    timeout_s
        Execution timeout per cell, in seconds (None: no limit).
    notebooks_dir
        Folder of notebooks; default ``notebooks/`` in the project.
    kernel_name
        Jupyter kernel to execute with.
    scheduler
        None: the notebooks run one after the other in this process's machine.
        ``"local"`` (a :class:`distributed.LocalCluster` sized to the machine), a
        Dask scheduler address or a ``distributed.Client``: every notebook is a task
        on that cluster, as many at once as it has worker threads, and receives the
        cluster's address as :data:`SCHEDULER_PARAMETER`, so its sweeps run there
        too. The workers need the package and the data (not the output folder:
        executed notebooks and summaries come back to this process).
    scheduler_timeout_s
        Seconds a scheduler address (``scheduler``, or a ``DASK_SCHEDULER`` value given
        as a parameter) has to answer as a Dask scheduler, checked before any notebook
        runs; also passed to the kernels (``$UWBWB_SCHEDULER_TIMEOUT_S``) for the
        notebooks' own connections. None: :func:`uwbwb.parallel.connect_timeout_s`.
    log
        Called with one progress line per notebook (e.g. ``print``).

    Returns
    -------
    ReproduceResult
        ``exit_code`` is non-zero when a notebook failed or wrote no valid summary.

    Raises
    ------
    ValueError
        Before any notebook runs: bad selection, a reserved or unknown parameter
        name, a value its spec refuses, an explicit value that ``FAST=True`` would
        replace or lower, a notebook without ``FAST`` under ``quick`` or without
        :data:`SCHEDULER_PARAMETER` under ``scheduler``, the scheduler parameter given
        as well as ``scheduler``, or a non-positive timeout.
    uwbwb.parallel.SchedulerUnreachable
        (a ``ConnectionError``) Before any notebook runs: no Dask scheduler answered
        in time at the address given (the message names it and what was found there).
    """
    if timeout_s is not None and not timeout_s > 0:
        raise ValueError(f"timeout must be positive seconds, got {timeout_s!r}")
    notebooks = select_notebooks(notebooks_dir, only)
    if quick:
        lacking = [nb.stem for nb in notebooks if "FAST" not in notebook_parameters(nb)]
        if lacking:
            raise ValueError(f"--quick sets FAST, which {', '.join(lacking)} does not declare in its parameters cell")
    given = dict(parameters or {})
    kernel_env = {}
    if scheduler_timeout_s is not None:
        from .parallel import TIMEOUT_ENV, connect_timeout_s

        kernel_env[TIMEOUT_ENV] = repr(connect_timeout_s(scheduler_timeout_s))
    client = None
    if scheduler is not None:
        if SCHEDULER_PARAMETER in given or SCHEDULER_PARAMETER in (text_parameters or {}):
            raise ValueError(f"give the cluster once: scheduler={scheduler!r} sets {SCHEDULER_PARAMETER} itself")
        lacking = [nb.stem for nb in notebooks if SCHEDULER_PARAMETER not in notebook_parameters(nb)]
        if lacking:
            raise ValueError(f"--scheduler sets {SCHEDULER_PARAMETER}, which {', '.join(lacking)} does not declare "
                             f"in its parameters cell")
        from . import parallel

        resolve_parameters(notebooks, given, text=text_parameters, quick=quick)   # bad values first
        client = parallel.connect(scheduler, timeout_s=scheduler_timeout_s)
        given[SCHEDULER_PARAMETER] = client.scheduler.address
    resolved = resolve_parameters(notebooks, given, text=text_parameters, quick=quick)
    addresses = {params[SCHEDULER_PARAMETER] for params in resolved.values()
                 if params.get(SCHEDULER_PARAMETER) not in (None, "local")}
    if client is None and addresses:      # a cluster given as a parameter: check it answers before any notebook runs
        from . import parallel

        for address in sorted(addresses):
            parallel.probe(address, timeout_s=scheduler_timeout_s)
    if log:
        for name in ({"FAST": True} if quick else {}) | dict(given) | dict(text_parameters or {}):
            receivers = [nb.stem for nb in notebooks if name in resolved[nb]]
            if len(receivers) < len(notebooks):
                log(f"parameter {name} goes to {', '.join(receivers)} only (the others do not declare it)")
    out_dir = Path(REPORTS_DIR if out is None else out).expanduser().resolve()
    out_dir.mkdir(parents=True, exist_ok=True)

    runs = []
    if client is not None:
        try:
            runs = _run_on_cluster(notebooks, out_dir, resolved, client, timeout_s, kernel_name, log, kernel_env)
        finally:
            if isinstance(scheduler, str) and scheduler.strip() == "local":   # the cluster started for this run
                from . import parallel

                parallel.shutdown(scheduler)
    for i, source in enumerate(notebooks if client is None else (), 1):
        if log:
            log(f"[{i}/{len(notebooks)}] {source.stem} ...")
        run = run_notebook(source, out_dir, resolved[source], timeout_s=timeout_s, kernel_name=kernel_name,
                           kernel_env=kernel_env)
        runs.append(run)
        if log:
            log(f"[{i}/{len(notebooks)}] {run.notebook}: {run.status} ({run.seconds:.1f} s)"
                + (f" — {run.error}" if run.error else ""))

    summary_json, summary_md = out_dir / "summary.json", out_dir / "summary.md"
    result = ReproduceResult(runs=tuple(runs), out_dir=out_dir, summary_json=summary_json,
                             summary_md=summary_md)
    summary_json.write_text(json.dumps(result.rows, indent=2, allow_nan=True) + "\n", encoding="utf-8")
    shown = {name: value for params in resolved.values() for name, value in params.items()}
    summary_md.write_text(summary_markdown(runs, shown), encoding="utf-8")
    return result
