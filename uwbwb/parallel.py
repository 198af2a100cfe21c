"""Monte Carlo sweeps as independent tasks, run serially, in local threads or on a Dask cluster.

A sweep is a list of :class:`Task` s. Each task carries the keyword arguments of
one call of the sweep's task function (``params``: small values such as a chunk
index, a trial range or a model name), its own :class:`numpy.random.SeedSequence`
child(ren) (``seed``) and its share of the work (``size``, for the progress bar).
Everything large that every task needs (recordings, models, arrays) is passed
once as ``shared``. A task's numbers depend only on its params, its seed and the
shared inputs, so a sweep gives **bit-identical** results whichever way it runs:

``scheduler=None``
    In this process, as a plain loop (``workers=1``) or in ``workers`` threads
    (NumPy and numba kernels release the GIL). Dask is not imported.
``scheduler="local"``
    A :class:`distributed.LocalCluster` sized to the machine, started on first use
    and kept for the rest of the session.
``scheduler="tcp://host:8786"`` (any scheduler address) or a :class:`distributed.Client`
    That cluster: a plain ``dask scheduler``, dask-jobqueue (SLURM, PBS, …),
    Kubernetes — anything a ``Client`` connects to.

Results come back **in task order** through :func:`imap`, at most ``max_pending``
tasks ahead of the consumer (submitted or finished but not yet consumed), so the
memory held on the client is bounded whatever the number of tasks: reduce on the
worker (return counts, sums or kept samples, not raw draws) and fold the results
as they arrive. A task that raises stops the sweep with a :class:`TaskError`
naming the task and its params; the tasks not yet finished are cancelled, and no
partial result is returned. A worker lost mid-sweep is not an error of the task:
Dask runs its tasks again elsewhere (up to ``distributed.scheduler.allowed-failures``
times, then the task fails with ``KilledWorker``, reported like any other error).
Shared inputs up to :data:`EMBED_BYTES` travel with every task, so any task can be
rerun; larger ones are copied once to every worker.

Size tasks so that the scheduler's overhead (about 1 ms a task) stays negligible:
:math:`10^5` draws or more, or a whole block of trials, per task.
"""

from __future__ import annotations

import queue
import re
import reprlib
import threading
import uuid
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["LOCAL", "WORKER_ENVIRON", "Task", "TaskError", "spawn", "imap", "connect", "describe", "local_cluster",
           "plan_summary", "shutdown"]

#: The ``scheduler`` value that starts a :class:`distributed.LocalCluster` sized to the machine.
LOCAL = "local"

_short = reprlib.Repr()
_short.maxstring, _short.maxother, _short.maxlist, _short.maxtuple, _short.maxdict = 60, 60, 6, 6, 6


@dataclass(frozen=True)
class Task:
    """One independent unit of a sweep.

    Attributes
    ----------
    params
        Keyword arguments of the task function for this task. Keep them small: they
        are sent with every task and shown in error messages and dry runs.
    seed
        A :class:`numpy.random.SeedSequence` (or a tuple of them, e.g. one per trial
        of a block), passed to the task function as ``seed=``; None for a
        deterministic task (no ``seed`` argument).
    size
        Units of work (draws, trials, runs) for the progress bar.
    """

    params: Mapping[str, Any] = field(default_factory=dict)
    seed: Any = None
    size: int = 1

    def __post_init__(self):
        if not all(isinstance(k, str) and k.isidentifier() for k in self.params):
            raise ValueError(f"task params must be keyword names, got {list(self.params)}")
        if "seed" in self.params:
            raise ValueError("'seed' is the task's seed, not a param: pass it as Task(seed=...)")
        if int(self.size) < 0:
            raise ValueError(f"task size must be >= 0, got {self.size}")

    def label(self) -> str:
        """The params as ``name=value, …`` (long values shortened)."""
        return ", ".join(f"{k}={_short.repr(v)}" for k, v in self.params.items()) or "no params"


class TaskError(RuntimeError):
    """A task of a sweep raised: the message names the sweep, the task and its params."""


def spawn(seed, n: int) -> list[np.random.SeedSequence]:
    """``n`` independent :class:`~numpy.random.SeedSequence` children of ``seed``.

    ``seed`` is an integer (or anything :class:`~numpy.random.SeedSequence` takes),
    a ``SeedSequence``, or a :class:`~numpy.random.Generator` — whose own seed
    sequence is spawned, exactly as :meth:`numpy.random.Generator.spawn` does, so
    ``numpy.random.default_rng(spawn(rng, n)[i])`` is ``rng.spawn(n)[i]`` for the
    default bit generator. Spawning advances the parent: a second call gives new
    children.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if isinstance(seed, np.random.Generator):
        root = seed.bit_generator.seed_seq
        if not isinstance(root, np.random.SeedSequence):
            raise ValueError("the generator was not created from a SeedSequence; pass an integer seed instead")
    elif isinstance(seed, np.random.SeedSequence):
        root = seed
    else:
        root = np.random.SeedSequence(seed)
    return root.spawn(int(n))


def plan_summary(tasks: Iterable[Task], *, unit: str = "task") -> str:
    """A dry run: how many tasks a sweep has and how the work is split (nothing is computed)."""
    tasks = list(tasks)
    sizes = np.array([t.size for t in tasks], float)
    if not tasks:
        return "0 tasks"
    return (f"{len(tasks)} tasks, {sizes.sum():.3g} {unit} in all, {sizes.min():.3g}–{sizes.max():.3g} "
            f"{unit} per task")


# --------------------------------------------------------------------------- clusters

_CLIENTS: dict[str, Any] = {}
_LOCK = threading.Lock()


def _distributed():
    try:
        import distributed
    except ImportError:  # the optional extra is not installed
        raise ImportError("running on a Dask cluster needs dask.distributed: pip install 'uwbwb[dask]' "
                          "(or pass scheduler=None to run in this process)") from None
    return distributed


#: Dask starts worker processes with ``MALLOC_TRIM_THRESHOLD_=65536``, which also turns off glibc's
#: adaptive mmap threshold: every array above 128 KiB is then mapped and zero-filled anew, and the
#: particle-filter blocks run about 2× slower than in this process (benchmarks/bench_parallel.py).
#: Local clusters started here leave glibc's defaults in place; see the README for other clusters.
WORKER_ENVIRON = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


def local_cluster(**kwargs):
    """A :class:`distributed.LocalCluster` (``kwargs`` as there; default: sized to the machine)
    whose worker processes allocate memory like this process does (:data:`WORKER_ENVIRON`)."""
    distributed = _distributed()
    import dask

    with dask.config.set(WORKER_ENVIRON):
        return distributed.LocalCluster(**kwargs)


def connect(scheduler, *, announce: bool = True):
    """The :class:`distributed.Client` for ``scheduler`` (None for ``None``: run in this process).

    ``"local"`` starts a :func:`local_cluster` with Dask's defaults for this
    machine (one worker process per few cores); an address connects to that
    scheduler; a ``Client`` is used as given. Clients made here are kept and reused
    for the same value; the first connection prints the cluster and its dashboard
    link (unless ``announce`` is False).
    """
    if scheduler is None:
        return None
    distributed = _distributed()
    if isinstance(scheduler, distributed.Client):
        return scheduler
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise ValueError(f"scheduler must be None, {LOCAL!r}, a scheduler address such as "
                         f"'tcp://10.0.0.5:8786', or a distributed.Client; got {scheduler!r}")
    key = scheduler.strip()
    with _LOCK:
        client = _CLIENTS.get(key)
        if client is None or client.status not in ("running", "connecting", "newly-created"):
            if key == LOCAL:
                client = distributed.Client(local_cluster(), set_as_default=False)
            else:
                client = distributed.Client(key, set_as_default=False)
            _CLIENTS[key] = client
            if announce:
                print(describe(client), flush=True)
    return client


def describe(scheduler) -> str:
    """One line on where sweeps run: this process, or the cluster with its workers and dashboard link."""
    if scheduler is None:
        return "Sweeps run in this process (no Dask scheduler given)."
    client = connect(scheduler, announce=False)
    threads = client.nthreads()
    link = client.dashboard_link if getattr(client, "dashboard_link", None) else "none (install bokeh)"
    return (f"Sweeps run on the Dask cluster at {client.scheduler.address}: {len(threads)} workers, "
            f"{sum(threads.values())} threads; dashboard: {link}")


def shutdown(scheduler: str | None = None) -> None:
    """Close the clients (and local clusters) this module started: all, or the one for ``scheduler``."""
    with _LOCK:
        keys = list(_CLIENTS) if scheduler is None else [k for k in _CLIENTS if k == scheduler.strip()]
        clients = [_CLIENTS.pop(k) for k in keys]
    for client in clients:
        cluster = client.cluster
        client.close()
        if cluster is not None:
            cluster.close()


# --------------------------------------------------------------------------- running a sweep

def _call(fn: Callable, task: Task, shared: Mapping[str, Any]):
    kwargs = {**task.params, **shared}
    if task.seed is not None:
        kwargs["seed"] = task.seed
    return fn(**kwargs)


#: Shared inputs up to this size (pickled) travel inside every task, so that Dask can rerun any task
#: on another worker when one is lost; larger ones are sent once to every worker (``scatter``), which
#: survives the loss of some workers but not of all that hold them.
EMBED_BYTES = 1 << 20


def _pickled_size(obj) -> int:
    import cloudpickle

    return len(cloudpickle.dumps(obj))


def _error(desc: str, index: int, n: int, task: Task, exc: BaseException) -> TaskError:
    text = str(exc).strip().splitlines()
    return TaskError(f"{desc}: task {index + 1} of {n} ({task.label()}) failed: {type(exc).__name__}"
                     + (f": {text[0]}" if text else ""))


def imap(fn: Callable, tasks: Iterable[Task], *, shared: Mapping[str, Any] | None = None, scheduler=None,
         workers: int = 1, progress: bool | None = None, desc: str = "sweep", unit: str = "task",
         max_pending: int | None = None) -> Iterator[tuple[Task, Any]]:
    """Run ``fn`` for every task; yield ``(task, result)`` in task order as results arrive.

    Parameters
    ----------
    fn
        Called as ``fn(**task.params, **shared, seed=task.seed)`` (no ``seed`` when
        the task has none). On a cluster it must be importable there (a module-level
        function of an installed package) or picklable by cloudpickle.
    tasks
        The sweep.
    shared
        Inputs every task needs, passed by keyword; on a cluster they are sent to
        the workers once, not with every task.
    scheduler
        None (this process), ``"local"``, a scheduler address or a ``Client`` (see
        the module docstring and :func:`connect`).
    workers
        Threads used in this process when ``scheduler`` is None (1: a plain loop).
    progress
        Show a ``tqdm`` bar over the tasks' sizes; None shows it when a cluster is used.
    desc, unit
        Label of the sweep (bar and error messages) and unit of the task sizes.
    max_pending
        Most tasks submitted or finished but not yet consumed (default: twice the
        number of worker threads, plus one): this bounds the client's memory.

    Raises
    ------
    TaskError
        The first task found to have raised, with its params; the other tasks are
        cancelled.
    """
    tasks = list(tasks)
    shared = dict(shared or {})
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    clash = sorted({k for t in tasks for k in t.params} & set(shared))
    if clash:
        raise ValueError(f"{desc}: {', '.join(clash)} given both as task params and as shared inputs")
    client = connect(scheduler)
    from tqdm.auto import tqdm

    show = (client is not None) if progress is None else bool(progress)
    bar = tqdm(total=sum(t.size for t in tasks), desc=desc, unit=unit, unit_scale=True, disable=not show,
               mininterval=0.5)
    try:
        if client is None and (workers == 1 or len(tasks) <= 1):
            for i, task in enumerate(tasks):
                try:
                    result = _call(fn, task, shared)
                except Exception as exc:
                    raise _error(desc, i, len(tasks), task, exc) from exc
                bar.update(task.size)
                yield task, result
            return
        yield from _pipelined(fn, tasks, shared, client, workers, desc, bar, max_pending)
    finally:
        bar.close()


def _pipelined(fn, tasks, shared, client, workers, desc, bar, max_pending):
    n = len(tasks)
    scattered: dict[str, Any] = {}
    if client is None:
        pool = ThreadPoolExecutor(max_workers=workers)
        slots = workers

        def submit(i):
            return pool.submit(_call, fn, tasks[i], shared)
    else:
        pool = None
        slots = max(sum(client.nthreads().values()), 1)
        names = list(shared)
        inputs = shared
        if names and _pickled_size(shared) > EMBED_BYTES:
            scattered = dict(zip(names, client.scatter([shared[k] for k in names], hash=False, broadcast=True)))
            inputs = scattered
        prefix = re.sub(r"[^0-9A-Za-z_]+", "_", desc).strip("_") or "task"
        token = uuid.uuid4().hex[:8]

        def submit(i):
            return client.submit(_call, fn, tasks[i], inputs, key=f"{prefix}-{token}-{i}", pure=False)

    window = max(int(max_pending or 2 * slots + 1), 1)
    done: queue.SimpleQueue = queue.SimpleQueue()       # indices of finished tasks, in completion order
    pending: dict[int, Any] = {}
    finished: dict[int, Any] = {}
    next_submit = next_yield = 0
    try:
        while next_yield < n:
            while next_submit < n and len(pending) + len(finished) < window:
                fut = submit(next_submit)
                pending[next_submit] = fut
                fut.add_done_callback(lambda _, i=next_submit: done.put(i))
                next_submit += 1
            while next_yield not in finished:
                i = done.get()
                fut = pending.pop(i)
                try:
                    finished[i] = fut.result()
                except Exception as exc:
                    raise _error(desc, i, n, tasks[i], exc) from exc
                bar.update(tasks[i].size)
            while next_yield in finished:
                yield tasks[next_yield], finished.pop(next_yield)
                next_yield += 1
    finally:
        for fut in pending.values():
            fut.cancel()
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        for fut in scattered.values():
            fut.release()
