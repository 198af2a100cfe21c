"""Running notebooks for ``reproduce``: one notebook with papermill on an IPC kernel, or every notebook as a
task on a Dask cluster, and reading back what each published.

Each run writes ``<stem>.ipynb`` (executed, also when it failed), ``<stem>.html`` and
``<stem>.summary.json`` into the output folder it is given; nothing here knows where the
project's notebooks or reports are (the caller passes the paths).
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from .. import parallel
from ..metrics import Summary
from .params import notebook_parameters, parameterized

__all__ = ["KERNEL_NAME", "NotebookRun", "ReproduceResult", "ipc_kernel_manager", "read_summary",
           "run_notebook"]


#: Kernel the notebooks are executed with.
KERNEL_NAME = "python3"


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
    cached
        True when the outputs of an earlier run were reused (:mod:`.cache`); ``seconds`` is then that run's.
    """

    notebook: str
    source: Path
    executed: Path
    html: Path | None
    summary: Path
    seconds: float
    error: str | None
    rows: tuple[dict, ...] = ()
    cached: bool = False

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
        if not isinstance(row, dict) or set(row) != set(Summary.COLUMNS):
            keys = sorted(row) if isinstance(row, dict) else type(row).__name__
            return [], f"summary file {path.name}, row {i}: keys must be {', '.join(Summary.COLUMNS)}, got {keys}"
        if row["notebook"] != notebook:
            return [], f"summary file {path.name}, row {i}: names notebook {row['notebook']!r}, not {notebook!r}"
        if row["kind"] not in Summary.KINDS:
            return [], f"summary file {path.name}, row {i}: kind must be one of {', '.join(Summary.KINDS)}, got {row['kind']!r}"
        if row["mode"] not in Summary.MODES:
            return [], f"summary file {path.name}, row {i}: mode must be one of {', '.join(Summary.MODES)}, got {row['mode']!r}"
        if mode is not None and row["mode"] != mode:
            return [], (f"summary file {path.name}, row {i}: mode {row['mode']!r}, but the notebook ran with "
                        f"FAST={mode == 'FAST'} (pass fast=FAST to uw.metrics.Summary)")
    return [{k: row[k] for k in Summary.COLUMNS} for row in rows], None


def _export_html(executed: Path, html: Path) -> None:
    import nbformat
    from nbconvert import HTMLExporter

    body, _ = HTMLExporter().from_notebook_node(nbformat.read(executed, as_version=4))
    html.write_text(body, encoding="utf-8")


def run_notebook(source: Path, out_dir: Path, parameters: Mapping[str, Any], *,
                 timeout_s: float | None = None, kernel_env: Mapping[str, str] | None = None,
                 processes: set | None = None) -> NotebookRun:
    """Execute one notebook into ``out_dir`` and read its summary (see :func:`reproduce`).

    ``parameters`` go to the notebook's injected cell as given (see
    :func:`resolve_parameters` for checking them first); ``kernel_env`` is added to
    the kernel's environment. Papermill runs in a child process, which is in ``processes`` (a set the caller
    watches) while it lives, so that several notebooks can run at once from threads and a caller that is
    interrupted can stop them.
    """
    outputs = executed, _, summary = _outputs(source, out_dir)
    t0 = time.perf_counter()
    error = _papermill_in_subprocess(source, executed, {**parameters, "SUMMARY_PATH": str(summary)}, source.parent,
                                     timeout_s, kernel_env, processes=processes)
    return _finish(source, outputs, parameters, error, time.perf_counter() - t0)


def _outputs(source: Path, out_dir: Path) -> tuple[Path, Path, Path]:
    """The executed notebook, HTML and summary paths of ``source``, with stale copies removed."""
    stem = source.stem
    paths = (out_dir / f"{stem}.ipynb", out_dir / f"{stem}.html", out_dir / f"{stem}.summary.json")
    for stale in paths:
        stale.unlink(missing_ok=True)  # a failed run must not show an older run's results
    return paths


def _papermill(source, executed, params, cwd, timeout_s, kernel_env=None) -> None:
    """Execute ``source`` into ``executed`` with ``params`` in an injected cell (:func:`parameterized`),
    on a kernel over IPC transport (:func:`ipc_kernel_manager`) with ``kernel_env`` added to its environment."""
    import tempfile

    import nbformat
    import papermill as pm

    nb = parameterized(nbformat.read(str(source), as_version=4), params)
    with tempfile.TemporaryDirectory(prefix="uwbwb-nb-") as tmp:
        prepared = Path(tmp, Path(source).name)
        nbformat.write(nb, str(prepared))
        try:
            pm.execute_notebook(str(prepared), str(executed), parameters=None, kernel_name=KERNEL_NAME,
                                cwd=str(cwd), progress_bar=False, log_output=False, execution_timeout=timeout_s,
                                kernel_manager_class=ipc_kernel_manager(kernel_env))
        finally:
            if Path(executed).is_file():   # the record names the notebook, not the scratch copy
                out = nbformat.read(str(executed), as_version=4)
                out.metadata.setdefault("papermill", {})["input_path"] = str(source)
                nbformat.write(out, str(executed))


def ipc_kernel_manager(env: Mapping[str, str] | None = None):
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


def _finish(source: Path, outputs: tuple[Path, Path, Path], parameters: Mapping[str, Any], error: str | None,
            seconds: float) -> NotebookRun:
    """Render the executed notebook and read its summary (``outputs`` from :func:`_outputs`) into a
    :class:`NotebookRun`."""
    executed, html, summary = outputs
    if executed.is_file():
        try:
            _export_html(executed, html)
        except Exception as exc:  # rendering problems are reported like execution problems
            html = None
            error = error or f"HTML export failed: {_first_line(exc)}"
    else:
        html = None
    rows, problem = _published(source, summary, parameters)
    if error is None:
        error = problem
    return NotebookRun(notebook=source.stem, source=source, executed=executed, html=html, summary=summary,
                       seconds=seconds, error=error, rows=tuple(rows))


def _published(source: Path, summary: Path, parameters: Mapping[str, Any]) -> tuple[list[dict], str | None]:
    """:func:`read_summary` of ``source``'s summary file, its mode read from the ``FAST`` it ran with."""
    fast = parameters.get("FAST", notebook_parameters(source).get("FAST"))
    return read_summary(summary, source.stem, ("FAST" if fast else "full") if isinstance(fast, bool) else None)


def _notebook_task(name: str, text: str, cwd: str, parameters: Mapping[str, Any], timeout_s: float | None,
                   kernel_env: Mapping[str, str] | None = None) -> tuple[str | None, str | None, str | None, float]:
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
                                             cwd if os.path.isdir(cwd) else tmp, timeout_s, kernel_env)
            seconds = time.perf_counter() - t0
            read = (lambda p: p.read_text(encoding="utf-8") if p.is_file() else None)
            return read(executed), read(summary), error, seconds
    finally:
        if seceded:
            rejoin()


def _papermill_in_subprocess(source, executed, params, cwd, timeout_s, kernel_env=None, *,
                             processes: set | None = None) -> str | None:
    """:func:`_papermill` in a child Python process; the first line of its error, or None.

    Each notebook gets its own process (and event loop): several notebooks run at
    once in the threads of one worker, which papermill's client cannot share. The child is in ``processes``
    while it runs (when given), for a caller that must stop it.
    """
    import pickle
    import subprocess
    import sys

    job = Path(executed).with_suffix(".job")
    failure = job.with_suffix(".error")
    failure.unlink(missing_ok=True)
    job.write_bytes(pickle.dumps((str(source), str(executed), dict(params), str(cwd), timeout_s,
                                  dict(kernel_env or {}))))
    code = "import sys; from uwbwb.reproduce.running import _papermill_job; _papermill_job(sys.argv[1])"
    child = subprocess.Popen([sys.executable, "-c", code, str(job)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    if processes is not None:
        processes.add(child)
    try:
        _, stderr = child.communicate()
    finally:
        if processes is not None:
            processes.discard(child)
        job.unlink(missing_ok=True)
    if failure.is_file():
        error = failure.read_text(encoding="utf-8")
        failure.unlink()
        return error
    if child.returncode != 0:
        lines = stderr.strip().splitlines() or [f"exit status {child.returncode}"]
        return f"notebook process failed: {lines[-1]}"
    return None


def _papermill_job(job: str) -> None:
    """Entry point of :func:`_papermill_in_subprocess`'s child: run the pickled job, write the error line if any."""
    import pickle
    import sys

    # Where rfc3987-syntax is installed (jsonschema[format-nongpl], under nbformat), importing jsonschema builds its
    # Earley parsers for the "iri" formats: ~3.5 s of CPU in every notebook's process, for formats no notebook
    # schema names (python-jsonschema/jsonschema#1428). Without the module jsonschema leaves those formats unchecked.
    sys.modules.setdefault("rfc3987_syntax", None)
    source, executed, params, cwd, timeout_s, kernel_env = pickle.loads(Path(job).read_bytes())
    try:
        _papermill(source, executed, params, cwd, timeout_s, kernel_env)
    except Exception as exc:  # reported by the parent as the run's status
        Path(job).with_suffix(".error").write_text(_first_line(exc), encoding="utf-8")


def _run_on_cluster(notebooks, out_dir, resolved, client, timeout_s, log, kernel_env=None):
    """Every notebook a task on the cluster, as many at once as it has threads; yields the runs in notebook order."""
    tasks = [parallel.Task({"name": nb.stem, "text": nb.read_text(encoding="utf-8"), "cwd": str(nb.parent),
                            "parameters": resolved[nb]}) for nb in notebooks]
    by_name = {nb.stem: nb for nb in notebooks}
    slots = max(sum(client.nthreads().values()), 1)
    if log:
        log(f"{parallel.describe(client)}; {len(notebooks)} notebooks, up to {slots} at once")
    for task, out in parallel.imap(
            _notebook_task, tasks, shared={"timeout_s": timeout_s, "kernel_env": kernel_env}, scheduler=client,
            progress=False, desc="notebooks", unit="notebook", max_pending=slots):
        source = by_name[task.params["name"]]
        outputs = executed, _, summary = _outputs(source, out_dir)
        text, summary_text, error, seconds = out
        if text is not None:
            executed.write_text(text, encoding="utf-8")
        if summary_text is not None:
            summary.write_text(summary_text, encoding="utf-8")
        yield _finish(source, outputs, resolved[source], error, seconds)
