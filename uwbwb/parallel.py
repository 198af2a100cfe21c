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
partial result is returned. This holds for ``SystemExit`` and ``KeyboardInterrupt``
raised by a task too (a ``sys.exit()`` deep in a task must not end a script with
status 0 mid-sweep): they surface as a :class:`TaskError` (a
:class:`TaskInterrupted`, also a ``KeyboardInterrupt``, for the latter). A worker lost mid-sweep is not an error of the task:
Dask runs its tasks again elsewhere (up to ``distributed.scheduler.allowed-failures``
times, then the task fails with ``KilledWorker``, reported like any other error).
Shared inputs up to :data:`EMBED_BYTES` travel with every task, so any task can be
rerun; larger ones are copied once to every worker.

A scheduler address is checked before any client is made: within
:func:`connect_timeout_s` seconds (default :data:`CONNECT_TIMEOUT_S`, or the
``UWBWB_SCHEDULER_TIMEOUT_S`` environment variable) it must answer as a Dask
scheduler, else :func:`connect` raises :class:`SchedulerUnreachable` naming the
address and what was found there (nothing listening, no answer, something that is
not a Dask scheduler, a malformed address). No thread is left behind.

Size tasks so that the scheduler's overhead (about 1 ms a task) stays negligible:
:math:`10^5` draws or more, or a whole block of trials, per task.
"""

from __future__ import annotations

import asyncio
import os
import queue
import re
import reprlib
import socket
import threading
import uuid
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["LOCAL", "WORKER_ENVIRON", "CONNECT_TIMEOUT_S", "Task", "TaskError", "TaskInterrupted",
           "SchedulerUnreachable", "spawn", "imap", "connect", "probe", "connect_timeout_s", "check_scheduler_address",
           "describe", "local_cluster", "shutdown"]

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


class TaskInterrupted(TaskError, KeyboardInterrupt):
    """A task of a sweep raised ``KeyboardInterrupt``: a :class:`TaskError` naming the task that is
    also a ``KeyboardInterrupt`` (Ctrl-C during a sweep in this process still reads as one)."""


class _TaskExit(RuntimeError):
    """``SystemExit`` / ``KeyboardInterrupt`` of a task, carried back as an ordinary exception.

    Raised where the task runs (a worker thread or a Dask worker, which would otherwise let
    them through and stop the worker); its args are ``(type name, text)``.
    """

    def __str__(self) -> str:
        kind, text = self.args
        return text


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


#: Seconds a scheduler address has to answer as a Dask scheduler (see :func:`connect_timeout_s`).
CONNECT_TIMEOUT_S = 5.0
#: Environment variable that overrides :data:`CONNECT_TIMEOUT_S` (e.g. in notebooks run by ``reproduce``).
TIMEOUT_ENV = "UWBWB_SCHEDULER_TIMEOUT_S"


class SchedulerUnreachable(ConnectionError):
    """No Dask scheduler answered at the given address: the message names it and what was found there."""


def connect_timeout_s(timeout_s: float | None = None) -> float:
    """The connection timeout: ``timeout_s``, else ``$UWBWB_SCHEDULER_TIMEOUT_S``, else :data:`CONNECT_TIMEOUT_S`.

    Raises
    ------
    ValueError
        A timeout (given or from the environment) that is not a positive finite number of seconds.
    """
    source = "timeout_s"
    if timeout_s is None:
        text = os.environ.get(TIMEOUT_ENV, "").strip()
        if not text:
            return CONNECT_TIMEOUT_S
        source = f"${TIMEOUT_ENV}"
        try:
            timeout_s = float(text)
        except ValueError:
            raise ValueError(f"{source} must be seconds, got {text!r}") from None
    if isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) or not 0 < timeout_s < float("inf"):
        raise ValueError(f"{source} must be positive seconds, got {timeout_s!r}")
    return float(timeout_s)


def check_scheduler_address(address: str) -> str:
    """``address`` as ``scheme://host:port`` (``tcp://`` added when no scheme is given).

    Raises
    ------
    SchedulerUnreachable
        Not a scheduler address: an unknown scheme, no host, or no valid port.
    """
    _distributed()
    from distributed.comm import parse_address, parse_host_port
    from distributed.comm.registry import backends

    text = address.strip()
    full = text if "://" in text else f"tcp://{text}"
    expected = f"expected {LOCAL!r} or a scheduler address such as tcp://10.0.0.5:8786"
    try:
        scheme, loc = parse_address(full, strict=True)
    except ValueError:
        raise SchedulerUnreachable(f"scheduler {address!r} is not an address: {expected}") from None
    if scheme not in backends:
        raise SchedulerUnreachable(f"scheduler {address!r}: unknown protocol {scheme!r} "
                                   f"(known: {', '.join(sorted(backends))}); {expected}")
    if scheme in ("tcp", "tls", "ws", "wss"):
        try:
            host, port = parse_host_port(loc)
        except (ValueError, TypeError):
            raise SchedulerUnreachable(f"scheduler {address!r} is not an address (no valid port): {expected}") from None
        if not host or not 0 < int(port) < 65536:
            raise SchedulerUnreachable(f"scheduler {address!r} is not an address: {expected}")
    return full


def _probe(address: str, timeout_s: float) -> None:
    """Check within ``timeout_s`` that a Dask scheduler answers at ``address``; raise
    :class:`SchedulerUnreachable` saying what was found there otherwise.

    The probe runs its own event loop in a short-lived daemon thread (this thread may already
    run one, as in a Jupyter kernel), and every step is bounded, so nothing outlives the call.
    """
    from distributed.comm import parse_address, parse_host_port

    scheme, loc = parse_address(address, strict=True)
    if scheme in ("tcp", "ws"):                 # plain sockets: tell "nothing listens" from "no answer"
        host, port = parse_host_port(loc)
        try:
            with socket.create_connection((host, port), timeout=timeout_s):
                pass
        except socket.gaierror as exc:
            raise SchedulerUnreachable(f"no Dask scheduler at {address}: host {host!r} not found ({exc.strerror})") \
                from None
        except ConnectionRefusedError:
            raise SchedulerUnreachable(f"no Dask scheduler at {address}: connection refused "
                                       f"(nothing listens on port {port})") from None
        except (TimeoutError, socket.timeout):
            raise SchedulerUnreachable(f"no Dask scheduler at {address}: no answer within {timeout_s:g} s "
                                       f"(host down or port filtered?)") from None
        except OSError as exc:
            raise SchedulerUnreachable(f"no Dask scheduler at {address}: {exc.strerror or exc}") from None

    outcome: dict[str, Any] = {}

    async def identify():
        from distributed.comm import connect as comm_connect
        from distributed.security import Security

        # the connection arguments a Client would use (TLS settings from the Dask configuration)
        comm = await comm_connect(address, timeout=timeout_s, **Security().get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    def run():
        try:
            outcome["reply"] = asyncio.run(asyncio.wait_for(identify(), timeout_s))
        except BaseException as exc:  # reported by the caller's thread
            outcome["error"] = exc

    thread = threading.Thread(target=run, name="uwbwb-scheduler-probe", daemon=True)
    thread.start()
    thread.join(timeout_s + 2.0)
    # only a plain socket was checked to accept connections above; other protocols (tls, wss, ucx) were not
    there = ("something accepts connections there but" if scheme in ("tcp", "ws") else
             f"the {scheme}:// connection was not checked on its own and")
    if thread.is_alive() or isinstance(outcome.get("error"), (asyncio.TimeoutError, TimeoutError)):
        raise SchedulerUnreachable(f"no Dask scheduler at {address}: {there} did not answer as a Dask scheduler "
                                   f"within {timeout_s:g} s") from None
    if "error" in outcome:
        exc = outcome["error"]
        text = _short.repr((str(exc).strip().splitlines() or [""])[0]).strip("'\"")
        raise SchedulerUnreachable(f"no Dask scheduler at {address}: {there} the Dask handshake failed "
                                   f"({type(exc).__name__}: {text})") from None
    reply = outcome.get("reply")
    kind = reply.get("type") if isinstance(reply, dict) else None
    if kind != "Scheduler":
        found = f"a Dask {kind}" if kind else f"a reply that is not a Dask identity ({_short.repr(reply)})"
        raise SchedulerUnreachable(f"no Dask scheduler at {address}: found {found}, not a scheduler")


def probe(scheduler: str, *, timeout_s: float | None = None) -> str:
    """Check that a Dask scheduler answers at address ``scheduler`` within the connection timeout,
    without keeping a connection; returns the address as ``scheme://host:port``.

    Raises
    ------
    SchedulerUnreachable
        As :func:`connect`.
    """
    address = check_scheduler_address(scheduler)
    _probe(address, connect_timeout_s(timeout_s))
    return address


def connect(scheduler, *, timeout_s: float | None = None):
    """The :class:`distributed.Client` for ``scheduler`` (None for ``None``: run in this process).

    ``"local"`` starts a :func:`local_cluster` with Dask's defaults for this
    machine (one worker process per few cores); an address connects to that
    scheduler; a ``Client`` is used as given. Clients made here are kept and reused
    for the same value; :func:`describe` says where they run.

    Parameters
    ----------
    timeout_s
        Seconds the address has to answer as a Dask scheduler; None: :func:`connect_timeout_s`.

    Raises
    ------
    ValueError
        ``scheduler`` of the wrong type, or a bad timeout.
    SchedulerUnreachable
        (a ``ConnectionError``) A malformed address, or no Dask scheduler answering there in time;
        the message names the address and what was found there.
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
    timeout_s = connect_timeout_s(timeout_s)
    with _LOCK:
        client = _CLIENTS.get(key)
        if client is None or client.status not in ("running", "connecting", "newly-created"):
            if key == LOCAL:
                client = distributed.Client(local_cluster(), set_as_default=False)
            else:
                client = distributed.Client(probe(key, timeout_s=timeout_s), set_as_default=False, timeout=timeout_s)
            _CLIENTS[key] = client
    return client


def describe(scheduler) -> str:
    """One line on where sweeps run: this process, or the cluster with its workers and dashboard link."""
    if scheduler is None:
        return "Sweeps run in this process (no Dask scheduler given)."
    client = connect(scheduler)
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


def _guarded_call(fn: Callable, task: Task, shared: Mapping[str, Any]):
    """:func:`_call` where the task runs off this thread: ``SystemExit`` and ``KeyboardInterrupt``
    come back as :class:`_TaskExit`, an ordinary error (a Dask worker would let them through and die)."""
    try:
        return _call(fn, task, shared)
    except (SystemExit, KeyboardInterrupt) as exc:
        raise _TaskExit(type(exc).__name__, _exit_text(exc)) from None


def _exit_text(exc: BaseException) -> str:
    if isinstance(exc, SystemExit):
        return f"exit status {exc.code!r}" if not isinstance(exc.code, str) else exc.code
    return (str(exc).strip().splitlines() or ["interrupted"])[0]


#: Shared inputs up to this size (pickled) travel inside every task, so that Dask can rerun any task
#: on another worker when one is lost; larger ones are sent once to every worker (``scatter``), which
#: survives the loss of some workers but not of all that hold them.
EMBED_BYTES = 1 << 20


def _error(desc: str, index: int, n: int, task: Task, exc: BaseException) -> TaskError:
    if isinstance(exc, _TaskExit):
        name, text = exc.args
    elif isinstance(exc, (SystemExit, KeyboardInterrupt)):
        name, text = type(exc).__name__, _exit_text(exc)
    else:
        name, text = type(exc).__name__, (str(exc).strip().splitlines() or [""])[0]
    kind = TaskInterrupted if name == "KeyboardInterrupt" else TaskError
    return kind(f"{desc}: task {index + 1} of {n} ({task.label()}) failed: {name}" + (f": {text}" if text else ""))


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
                except (Exception, SystemExit, KeyboardInterrupt) as exc:   # a task's exit is its error
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
            return pool.submit(_guarded_call, fn, tasks[i], shared)
    else:
        pool = None
        slots = max(sum(client.nthreads().values()), 1)
        names = list(shared)
        inputs = shared
        import cloudpickle                      # comes with dask.distributed

        if names and len(cloudpickle.dumps(shared)) > EMBED_BYTES:
            scattered = dict(zip(names, client.scatter([shared[k] for k in names], hash=False, broadcast=True)))
            inputs = scattered
        prefix = re.sub(r"[^0-9A-Za-z_]+", "_", desc).strip("_") or "task"
        token = uuid.uuid4().hex[:8]

        def submit(i):
            return client.submit(_guarded_call, fn, tasks[i], inputs, key=f"{prefix}-{token}-{i}", pure=False)

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
                    finished[i] = (fut.result(), None)
                    bar.update(tasks[i].size)
                except (Exception, SystemExit, KeyboardInterrupt) as exc:   # the task's own, raised in its turn
                    finished[i] = (None, exc)
            while next_yield in finished:
                result, exc = finished.pop(next_yield)
                if exc is not None:     # every result before the failed task has been yielded, none after
                    raise _error(desc, next_yield, n, tasks[next_yield], exc) from exc
                yield tasks[next_yield], result
                next_yield += 1
    finally:
        for fut in pending.values():
            fut.cancel()
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        for fut in scattered.values():
            fut.release()
