"""Execute the notebooks headless and collect their headline numbers.

``python -m uwbwb reproduce`` (or :func:`reproduce`) runs every notebook in
``notebooks/`` of the working directory (sorted by name) with papermill on the ``python3`` kernel and
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

One run at a time per output folder: a run holds ``<out>/.reproduce.lock`` (a second run into the folder is
refused while the first one's process lives). At its start a run removes the folder's old ``summary.json``
and writes a ``summary.md`` saying it is in progress; the summaries are written at the end, each through a
temporary file, so a run stopped half-way (Ctrl-C, SIGTERM) leaves a ``summary.md`` saying so and no
``summary.json`` — never an old "ok" beside new notebooks.

A notebook whose source, parameters, package source, environment, data locations and data files (by
checksum) are those of its last successful run into the same output folder is not executed again: its
outputs are reused and the report says so (:mod:`.cache`; ``force=True`` / ``--force`` executes everything).

Kernels are started on IPC transport (local sockets, no TCP ports), so that
jupyter_client's warning about unencrypted TCP never reaches the output.

With ``--scheduler ADDRESS`` (or ``local``) the notebooks run concurrently as
tasks on that Dask cluster, each receiving the cluster as its
``DASK_SCHEDULER`` parameter so that its sweeps run there too
(:mod:`uwbwb.parallel`); the outputs and the summary are the same files.

Where things are
----------------
The notebook folder, the output folder and the data folder are arguments, never computed from
where the package is installed (it also works installed as a wheel): ``notebooks_dir`` (default
:data:`NOTEBOOKS_DIR`, ``notebooks/`` in the working directory), ``out`` (default
:data:`REPORTS_DIR`, ``reports/`` in the working directory) and the notebooks' own ``DATA_DIR``
parameter (``-p DATA_DIR DIR``; default: the search order of :mod:`uwbwb.datasets.discovery`).

Modules: :mod:`.params` (what a notebook declares; checking and typing values), :mod:`.running`
(papermill, the kernel, the cluster, reading summaries), :mod:`.report` (``summary.md``).
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import signal
import subprocess
import threading
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

from .. import notebook_params, parallel
from ..datasets.text import READ_LOG_ENV
from . import cache
from .params import (INJECTED_TAG, RESERVED_PARAMETERS, SCHEDULER_PARAMETER, injected_source, notebook_parameters,
                     parameterized, resolve_parameters)
from .report import summary_markdown
from .running import (KERNEL_NAME, NotebookRun, ReproduceResult, _published, _run_on_cluster, ipc_kernel_manager,
                      read_summary, run_notebook)

__all__ = ["INJECTED_TAG", "KERNEL_NAME", "NOTEBOOKS_DIR", "NotebookRun", "REPORTS_DIR", "RESERVED_PARAMETERS",
           "ReproduceResult", "SCHEDULER_PARAMETER", "injected_source", "ipc_kernel_manager", "notebook_parameters",
           "parameterized", "read_summary", "reproduce", "resolve_parameters", "run_notebook", "select_notebooks",
           "summary_markdown"]

#: Notebooks run by default: ``notebooks/`` in the working directory (the project root, where
#: ``make reproduce`` and ``python -m uwbwb reproduce`` are run).
NOTEBOOKS_DIR = Path("notebooks")
#: Default output folder: ``reports/`` in the working directory.
REPORTS_DIR = Path("reports")


def select_notebooks(notebooks_dir: str | os.PathLike | None = None,
                     only: Iterable[str] | None = None) -> list[Path]:
    """Notebooks to run, sorted by file name.

    Parameters
    ----------
    notebooks_dir
        Folder of ``*.ipynb`` files; default :data:`NOTEBOOKS_DIR` (``notebooks/`` in the working directory).
    only
        Keep notebooks whose file name or stem equals, or whose stem starts
        with, one of these (``"00"``, ``"00_quickstart"``, ``"00_quickstart.ipynb"``).

    Raises
    ------
    ValueError
        No notebooks in the folder, or an ``only`` pattern that matches none.
    """
    notebooks_dir = Path(NOTEBOOKS_DIR if notebooks_dir is None else notebooks_dir)
    found = sorted(notebooks_dir.expanduser().resolve().glob("*.ipynb"))
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


def reproduce(*, quick: bool = False, only: Iterable[str] | None = None,
              out: str | os.PathLike | None = None, parameters: Mapping[str, Any] | None = None,
              text_parameters: Mapping[str, str] | None = None,
              timeout_s: float | None = None, notebooks_dir: str | os.PathLike | None = None,
              scheduler=None, scheduler_timeout_s: float | None = None,
              log: Callable[[str], None] | None = None, force: bool = False,
              jobs: int | None = None) -> ReproduceResult:
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
        Output folder; default :data:`REPORTS_DIR` (``reports/`` in the working directory).
    parameters
        Extra notebook parameters as Python values, checked by each notebook's spec
        (:func:`uwbwb.notebook_params.specs_for`); each goes to the selected notebooks that declare it.
    text_parameters
        Extra notebook parameters as typed on the command line, typed by each
        notebook's declared default (see :func:`resolve_parameters`).
    timeout_s
        Execution timeout per cell, in seconds (None: no limit).
    notebooks_dir
        Folder of notebooks; default :data:`NOTEBOOKS_DIR` (``notebooks/`` in the working directory).
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
    force
        Execute every notebook, even one whose last successful run into ``out`` can be reused (:mod:`.cache`).
    jobs
        Notebooks executed at once on this machine, each in its own process (None: one per core,
        ``os.cpu_count()``; 1: one after the other). Each notebook is seeded by its parameters, so
        the numbers do not depend on it. Ignored with ``scheduler`` (the cluster decides).

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
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ValueError(f"jobs must be a whole number ≥ 1 (notebooks at once), got {jobs!r}")
    notebooks = select_notebooks(notebooks_dir, only)
    for option, name, on in (("--quick", "FAST", quick), ("--scheduler", SCHEDULER_PARAMETER, scheduler is not None)):
        lacking = [nb.stem for nb in notebooks if on and name not in notebook_parameters(nb)]
        if lacking:
            raise ValueError(f"{option} sets {name}, which {', '.join(lacking)} does not declare in its "
                             "parameters cell")
    given = dict(parameters or {})
    kernel_env = {}
    if scheduler_timeout_s is not None:
        kernel_env[parallel.TIMEOUT_ENV] = repr(parallel.connect_timeout_s(scheduler_timeout_s))
    if scheduler is not None:
        if SCHEDULER_PARAMETER in given or SCHEDULER_PARAMETER in (text_parameters or {}):
            raise ValueError(f"give the cluster once: scheduler={scheduler!r} sets {SCHEDULER_PARAMETER} itself")
        if isinstance(scheduler, str):      # checked as the notebooks' DASK_SCHEDULER is (no inproc:// address)
            notebook_params.COMMON[SCHEDULER_PARAMETER].validate(scheduler, "scheduler")
    resolved = resolve_parameters(notebooks, given, text=text_parameters, quick=quick)   # bad values first
    client = None if scheduler is None else parallel.connect(scheduler, timeout_s=scheduler_timeout_s)
    for params in resolved.values():
        if client is not None:
            params[SCHEDULER_PARAMETER] = client.scheduler.address
        elif params.get(SCHEDULER_PARAMETER) not in (None, "local"):   # a cluster given as a parameter answers
            parallel.probe(params[SCHEDULER_PARAMETER], timeout_s=scheduler_timeout_s)
    if log:
        for name in ({"FAST": True} if quick else {}) | dict(given) | dict(text_parameters or {}):
            receivers = [nb.stem for nb in notebooks if name in resolved[nb]]
            if len(receivers) < len(notebooks):
                log(f"parameter {name} goes to {', '.join(receivers)} only (the others do not declare it)")
    out_dir = Path(REPORTS_DIR if out is None else out).expanduser().resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    summary_json, summary_md = out_dir / "summary.json", out_dir / "summary.md"
    with _OutLock(out_dir), _sigterm_interrupts():
        summary_json.unlink(missing_ok=True)            # no earlier "ok" may stand beside a run that stops half-way
        _write_atomic(summary_md, f"# Reproduction in progress\n\nStarted with {len(notebooks)} notebook(s); a run "
                                  "that stopped leaves this text and no summary.json.\n")
        runs: list = []
        try:
            _execute(notebooks, out_dir, resolved, client, scheduler, timeout_s, log, kernel_env, runs, force,
                     jobs or os.cpu_count() or 1)
        except KeyboardInterrupt:
            done = ", ".join(f"{r.notebook} ({r.status})" for r in runs) or "none"
            _write_atomic(summary_md, f"# Reproduction INTERRUPTED\n\nStopped by the user or a signal; notebooks "
                                      f"finished before it: {done}. No summary.json was written: rerun.\n")
            raise
        result = ReproduceResult(runs=tuple(runs), out_dir=out_dir, summary_json=summary_json,
                                 summary_md=summary_md)
        shown = {name: value for params in resolved.values() for name, value in params.items()}
        _write_atomic(summary_md, summary_markdown(runs, shown))
        _write_atomic(summary_json, json.dumps(result.rows, indent=2, allow_nan=True) + "\n")
    return result


def _execute(notebooks, out_dir, resolved, client, scheduler, timeout_s, log, kernel_env, runs: list,
             force: bool = False, jobs: int = 1) -> None:
    """Run the notebooks (on the cluster when ``client`` is given, else up to ``jobs`` at once), appending each
    run to ``runs`` as it ends, then putting ``runs`` in notebook order; without a cluster, a notebook whose last
    run can be reused (:mod:`.cache`) is not executed unless ``force``."""
    if client is not None:
        try:
            for run in _run_on_cluster(notebooks, out_dir, resolved, client, timeout_s, log, kernel_env):
                runs.append(run)
                _log_end(log, len(runs), len(notebooks), run)
            return
        finally:
            if isinstance(scheduler, str) and scheduler.strip() == "local":   # the cluster started for this run
                parallel.shutdown(scheduler)
    digest, order = cache.package_digest(), {nb: i for i, nb in enumerate(notebooks, 1)}
    todo = []
    for source in notebooks:
        key = cache.notebook_key(source, resolved[source], package_digest=digest)
        run = None if force else _reused(source, out_dir, resolved[source], key)
        if run is None:
            todo.append((source, key))
        else:
            runs.append(run)
            _log_end(log, order[source], len(notebooks), run)
    todo.sort(key=lambda item: -_expected_seconds(item[0], quick=bool(resolved[item[0]].get("FAST"))))
    processes, stopping, finished = set(), threading.Event(), []

    def one(source: Path, key: str) -> NotebookRun:
        if log:
            log(f"[{order[source]}/{len(notebooks)}] {source.stem} ...")
        cache.forget(out_dir, source.stem)
        env = {**kernel_env, READ_LOG_ENV: str(cache.read_log_path(out_dir, source.stem))}
        run = run_notebook(source, out_dir, resolved[source], timeout_s=timeout_s, kernel_env=env,
                           processes=processes)
        if run.ok and run.executed.is_file():
            cache.write_entry(out_dir, source.stem, key, run.seconds)
        _log_end(log, order[source], len(notebooks), run)
        if not stopping.is_set():
            finished.append(run)
        return run

    pool = ThreadPoolExecutor(max_workers=max(min(jobs, len(todo)), 1), thread_name_prefix="notebook")
    try:
        for future in as_completed([pool.submit(one, source, key) for source, key in todo]):
            future.result()
    except BaseException:                  # Ctrl-C or SIGTERM: stop the notebooks still running, then report
        stopping.set()                     # the ones that finished before it
        pool.shutdown(wait=False, cancel_futures=True)
        _stop(processes)
        runs.extend(finished)
        raise
    pool.shutdown()
    runs.extend(finished)
    runs.sort(key=lambda r: order[r.source])


#: A notebook front's *Run time* line (written from docs/run_times.md by benchmarks/run_times.py):
#: ``… [FAST](GLOSSARY.md#fast) 42 s, [full](GLOSSARY.md#full-mode) 11 min.``
_FRONT_TIME = re.compile(r"\[(FAST|full)\]\([^)]*\) (?:(\d+) min)? ?(?:(\d+) s)?")


def _expected_seconds(source: Path, *, quick: bool) -> float:
    """How long ``source`` runs in its mode, as its front quotes it; ``inf`` when it quotes none (a notebook of
    unknown length starts first). Notebooks start longest first, so that a long one does not start last on a
    machine whose other cores are idle by then; the numbers do not depend on the order."""
    try:
        front = "".join(json.loads(source.read_text(encoding="utf-8"))["cells"][0]["source"])
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        return float("inf")
    for line in front.splitlines():
        if "Run time" in line:
            for mode, minutes, seconds in _FRONT_TIME.findall(line):
                if (mode == "FAST") == quick and (minutes or seconds):
                    return 60.0 * int(minutes or 0) + int(seconds or 0)
    return float("inf")


def _log_end(log, i: int, n: int, run: NotebookRun) -> None:
    if log:
        how = f"from the cache, ran {run.seconds:.1f} s before" if run.cached else f"{run.seconds:.1f} s"
        log(f"[{i}/{n}] {run.notebook}: {run.status} ({how})" + (f" — {run.error}" if run.error else ""))


def _stop(processes: set, grace_s: float = 10.0) -> None:
    """Interrupt the notebook processes still running (their kernels shut down with them), then kill the rest."""
    for child in list(processes):
        child.send_signal(signal.SIGINT)
    deadline = time.monotonic() + grace_s
    for child in list(processes):
        try:
            child.wait(max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            child.kill()


def _reused(source: Path, out_dir: Path, parameters: Mapping[str, Any], key: str) -> NotebookRun | None:
    """The earlier run of ``source`` into ``out_dir`` as a :class:`NotebookRun` if it can be reused, else None."""
    entry = cache.valid_entry(out_dir, source.stem, key)
    if entry is None:
        return None
    summary = out_dir / f"{source.stem}.summary.json"
    rows, problem = _published(source, summary, parameters)
    if problem:
        return None
    return NotebookRun(notebook=source.stem, source=source, executed=out_dir / f"{source.stem}.ipynb",
                       html=out_dir / f"{source.stem}.html", summary=summary, seconds=float(entry.get("seconds", 0.0)),
                       error=None, rows=tuple(rows), cached=True)


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder: a reader sees the old or the new file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


class _OutLock:
    """``<out>/.reproduce.lock`` held (``flock``) for one run: a second run into the same folder is refused while the
    first one's process lives (the system releases the lock when that process ends, however it ends)."""

    def __init__(self, out_dir: Path):
        self.path = out_dir / ".reproduce.lock"

    def __enter__(self):
        self.file = open(self.path, "a+")
        try:
            fcntl.flock(self.file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self.file.seek(0)
            pid = self.file.read().strip()
            self.file.close()
            raise ValueError(f"{self.path.parent}: another reproduce (process {pid}) is writing into this folder; "
                             "wait for it to finish or give another --out") from None
        self.file.truncate(0)
        self.file.write(str(os.getpid()))
        self.file.flush()
        return self

    def __exit__(self, *exc):
        self.path.unlink(missing_ok=True)
        self.file.close()
        return False


class _sigterm_interrupts:
    """While a run lasts, SIGTERM stops it like Ctrl-C (so the summary says it was interrupted and temporary files
    go); only in the main thread, where Python can install the handler."""

    def __enter__(self):
        self.previous = None
        if threading.current_thread() is threading.main_thread():
            def stop(signum, frame):
                raise KeyboardInterrupt(f"signal {signum}")

            self.previous = signal.signal(signal.SIGTERM, stop)
        return self

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGTERM, self.previous)
        return False
