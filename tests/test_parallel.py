"""uwbwb.parallel: same numbers serially, in threads and on a Dask cluster; clear task errors; bounded memory."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import threading

import cloudpickle
import numpy as np
import pandas as pd
import pytest

from uwbwb import parallel as par

distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed (pip install 'uwbwb[dask]')")


@pytest.fixture(scope="module")
def client():
    """Two small in-process workers: the Dask path (scheduler, scatter, futures) without process start-up."""
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None)
    c = distributed.Client(cluster, set_as_default=False)
    yield c
    c.close()
    cluster.close()


@pytest.fixture
def pickled(monkeypatch):
    """Every task (function, params, seed, shared inputs) goes through cloudpickle, as between processes."""
    call = par._call

    def through_pickle(fn, task, shared):
        return call(*cloudpickle.loads(cloudpickle.dumps((fn, task, shared))))

    monkeypatch.setattr(par, "_call", through_pickle)


def _draw(i, seed, scale):
    return scale * np.random.default_rng(seed).standard_normal(3) + i


def _tasks(n=12, seed=5):
    return [par.Task({"i": i}, seed=s) for i, s in enumerate(par.spawn(seed, n))]


def _results(**kw):
    return np.array([r for _, r in par.imap(_draw, _tasks(), shared={"scale": 2.0}, **kw)])


# --------------------------------------------------------------------------- the layer

def test_spawn_gives_the_generators_children():
    a = [np.random.default_rng(s).random() for s in par.spawn(np.random.default_rng(3), 4)]
    b = [g.random() for g in np.random.default_rng(3).spawn(4)]
    assert a == b
    assert [s.spawn_key for s in par.spawn(7, 3)] == [(0,), (1,), (2,)]
    ss = np.random.SeedSequence(7)
    assert par.spawn(ss, 2)[0].spawn_key == (0,) and par.spawn(ss, 2)[0].spawn_key == (2,)   # advances


def test_serial_threads_and_cluster_give_identical_numbers(client, monkeypatch):
    serial = _results()
    np.testing.assert_array_equal(serial, _results(workers=3))
    np.testing.assert_array_equal(serial, _results(scheduler=client, progress=False))
    np.testing.assert_array_equal(serial, _results(scheduler=client, max_pending=1, progress=False))
    monkeypatch.setattr(par, "EMBED_BYTES", 0)          # shared inputs sent once to every worker instead
    np.testing.assert_array_equal(serial, _results(scheduler=client, progress=False))
    np.testing.assert_array_equal(serial, _results(scheduler=client, progress=False))


@pytest.mark.parametrize("where", ["serial", "threads", "cluster"])
def test_a_task_that_raises_fails_the_sweep_naming_its_params(where, client):
    def fragile(i, seed, scale):
        if i == 7:
            raise ValueError(f"no solution for i={i}\nsecond line")
        return i

    kw = {"serial": {}, "threads": {"workers": 2}, "cluster": {"scheduler": client, "progress": False}}[where]
    got = []
    with pytest.raises(par.TaskError, match=r"fragile sweep: task 8 of 12 \(i=7\) failed: ValueError: "
                                            r"no solution for i=7$") as info:
        for task, r in par.imap(fragile, _tasks(), shared={"scale": 1.0}, desc="fragile sweep", **kw):
            got.append(r)
    assert isinstance(info.value.__cause__, ValueError)
    assert got == list(range(7))          # everything before the failure, in order; nothing after it


@pytest.mark.parametrize("where", ["serial", "threads", "cluster"])
@pytest.mark.parametrize("escape", [SystemExit, KeyboardInterrupt])
def test_a_task_that_exits_fails_the_sweep_naming_its_params(where, escape, client):
    """``sys.exit()`` or a KeyboardInterrupt inside a task is the task's error, never the sweep's quiet end."""
    def quitter(i, seed, scale):
        if i == 4:
            raise escape(3) if escape is SystemExit else escape("stop at 4")
        return i

    kw = {"serial": {}, "threads": {"workers": 2}, "cluster": {"scheduler": client, "progress": False}}[where]
    expected = par.TaskInterrupted if escape is KeyboardInterrupt else par.TaskError
    text = "SystemExit: exit status 3" if escape is SystemExit else "KeyboardInterrupt: stop at 4"
    got = []
    with pytest.raises(expected, match=rf"quitting sweep: task 5 of 12 \(i=4\) failed: {text}$"):
        for task, r in par.imap(quitter, _tasks(), shared={"scale": 1.0}, desc="quitting sweep", **kw):
            got.append(r)
    assert got == [0, 1, 2, 3]
    if where == "cluster":   # the workers survived: the same cluster still runs a sweep
        assert [r[0] for _, r in par.imap(_draw, _tasks(3), shared={"scale": 0.0}, scheduler=client,
                                          progress=False)] == [0.0, 1.0, 2.0]


@pytest.mark.parametrize("escape", [ValueError, SystemExit])
def test_a_failure_is_raised_in_its_turn_after_every_earlier_result(escape):
    """A task that fails before an earlier, slower one has finished: the earlier result still comes
    first, then the error (never a sweep cut short by a race between workers)."""
    release = threading.Event()

    def uneven(i, seed):
        if i == 3:
            release.wait(5.0)            # still running when task 4 fails
        if i == 4:
            release.set()
            raise escape(1)
        return i

    got = []
    with pytest.raises(par.TaskError, match=r"task 5 of 12 \(i=4\) failed"):
        for _, r in par.imap(uneven, _tasks(), workers=2, desc="uneven sweep"):
            got.append(r)
    assert got == [0, 1, 2, 3]


def test_a_task_exit_status_is_not_the_script_exit_status(tmp_path):
    """A script whose sweep task calls sys.exit(0) exits non-zero with the task named (it used to exit 0)."""
    script = tmp_path / "sweep.py"
    script.write_text("import sys\nfrom uwbwb import parallel as p\n"
                      "def f(i):\n    if i == 2:\n        sys.exit(0)\n    return i\n"
                      "for _ in p.imap(f, [p.Task({'i': i}) for i in range(5)], workers=2, desc='demo'):\n    pass\n"
                      "print('finished')\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert done.returncode != 0 and "finished" not in done.stdout
    assert "TaskError: demo: task 3 of 5 (i=2) failed: SystemExit: exit status 0" in done.stderr


def test_results_are_consumed_in_order_with_a_bounded_number_pending():
    lock, state = threading.Lock(), {"started": 0, "consumed": 0, "most": 0}

    def slow_first(i, seed, scale):
        with lock:
            state["started"] += 1
            state["most"] = max(state["most"], state["started"] - state["consumed"])
        if i == 0:
            threading.Event().wait(0.2)           # the head finishes last: the others must wait for it
        return i

    order = []
    for task, r in par.imap(slow_first, _tasks(40), shared={"scale": 1.0}, workers=3, max_pending=5):
        order.append(r)
        with lock:
            state["consumed"] += 1
    assert order == list(range(40))
    assert state["most"] <= 5


def _dies_once(i, marker):
    """Kills its worker process the first time it runs (the marker file remembers)."""
    import os
    from pathlib import Path

    if i == 1 and not Path(marker).exists():
        Path(marker).touch()
        os._exit(1)
    return i


def test_a_lost_worker_is_retried_not_reported(tmp_path):
    """A worker process that dies mid-sweep: Dask reruns its task on a fresh worker; the sweep completes."""
    cluster = par.local_cluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None)
    client = distributed.Client(cluster, set_as_default=False)
    try:
        marker = tmp_path / "died"
        tasks = [par.Task({"i": i}) for i in range(3)]
        got = [r for _, r in par.imap(_dies_once, tasks, shared={"marker": str(marker)}, scheduler=client,
                                      progress=False)]
    finally:
        client.close()
        cluster.close()
    assert marker.exists() and got == [0, 1, 2]


def test_bad_arguments_are_reported():
    with pytest.raises(ValueError, match="keyword names"):
        par.Task({"not a name": 1})
    with pytest.raises(ValueError, match="seed"):
        par.Task({"seed": 1})
    with pytest.raises(ValueError, match="both as task params and as shared"):
        list(par.imap(_draw, _tasks(), shared={"i": 1, "scale": 1.0}))
    with pytest.raises(ValueError, match="scheduler must be"):
        par.connect(42)


# --------------------------------------------------------------------------- connecting to a scheduler

class _Server:
    """A TCP server on 127.0.0.1 that is not Dask: it greets like HTTP, or (``silent``) accepts and says nothing."""

    def __init__(self, silent=False):
        import socket

        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.silent, self.conns = silent, []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            if not self.silent:
                conn.sendall(b"HTTP/1.0 200 OK\r\nContent-Type: text/plain\r\n\r\nhello\n")

    def close(self):
        for c in self.conns:
            c.close()
        self.sock.close()


def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("case, message", [
    ("http", r"no Dask scheduler at tcp://127\.0\.0\.1:\d+: something accepts connections there but the Dask "
             r"handshake failed"),
    ("silent", r"no Dask scheduler at tcp://127\.0\.0\.1:\d+: something accepts connections there but did not "
               r"answer as a Dask scheduler within 1 s"),
    ("refused", r"no Dask scheduler at tcp://127\.0\.0\.1:\d+: connection refused \(nothing listens on port \d+\)"),
    ("notanaddress", r"scheduler 'notanaddress' is not an address.*expected 'local' or a scheduler address"),
    ("tcp://127.0.0.1:99999", r"is not an address"),
    ("foo://host:1", r"unknown protocol 'foo'"),
])
def test_an_address_without_a_scheduler_fails_promptly_naming_it(case, message):
    server = _Server(silent=case == "silent") if case in ("http", "silent") else None
    address = {"http": f"tcp://127.0.0.1:{server.port if server else 0}",
               "silent": f"tcp://127.0.0.1:{server.port if server else 0}",
               "refused": f"tcp://127.0.0.1:{_free_port()}"}.get(case, case)
    before = set(threading.enumerate())
    try:
        with pytest.raises(par.SchedulerUnreachable, match=message):
            par.connect(address, timeout_s=1.0)
    finally:
        if server is not None:
            server.close()
    assert address not in par._CLIENTS
    assert not [t for t in set(threading.enumerate()) - before if t.is_alive() and t.name.startswith("uwbwb")]


def test_the_connection_timeout_comes_from_the_argument_the_environment_or_the_default(monkeypatch):
    monkeypatch.delenv(par.TIMEOUT_ENV, raising=False)
    assert par.connect_timeout_s() == par.CONNECT_TIMEOUT_S == 5.0
    assert par.connect_timeout_s(1.5) == 1.5
    monkeypatch.setenv(par.TIMEOUT_ENV, "0.25")
    assert par.connect_timeout_s() == 0.25
    server = _Server(silent=True)
    try:   # a notebook's DASK_SCHEDULER goes through connect(): the environment bounds the wait
        with pytest.raises(par.SchedulerUnreachable, match="within 0.25 s"):
            par.describe(f"tcp://127.0.0.1:{server.port}")
    finally:
        server.close()
    for bad in ("soon", "0", "-1", "inf"):
        monkeypatch.setenv(par.TIMEOUT_ENV, bad)
        with pytest.raises(ValueError, match=par.TIMEOUT_ENV):
            par.connect_timeout_s()
    with pytest.raises(ValueError, match="timeout_s must be positive"):
        par.connect_timeout_s(0)


def test_a_live_scheduler_passes_the_probe(client):
    address = client.scheduler.address
    assert par.probe(address, timeout_s=2.0) == address


def test_the_default_path_does_not_import_dask():
    code = ("import sys, numpy as np; from uwbwb import parallel as p; "
            "t = [p.Task({'i': i}, seed=s) for i, s in enumerate(p.spawn(1, 4))]; "
            "f = lambda i, seed: i; assert [r for _, r in p.imap(f, t)] == [0, 1, 2, 3]; "
            "assert [r for _, r in p.imap(f, t, workers=2)] == [0, 1, 2, 3]; "
            "assert 'distributed' not in sys.modules and 'dask' not in sys.modules, 'dask imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


# --------------------------------------------------------------------------- the heavy paths

def test_setnoise_sweep_table_identical_on_a_cluster(client, pickled):
    from uwbwb.experiments import setnoise as E
    from uwbwb.sim import setnoise as S

    small = dataclasses.replace(S.FacilityConfig(), n_calibration=300, n_legs=2, speeds_mps=(0.35, 1.0))
    study = E.synthetic_study(small, rng=np.random.default_rng(0), off_track_xy_m=None)
    cfg = E.SweepConfig(sigma_d_mps=(0.1, 0.3), n_trials=3, n_particles=60)
    tables = [E.sweep(study.recordings, study.model, dataclasses.replace(cfg, **kw), rng=np.random.default_rng(4),
                      progress=False) for kw in ({}, {"n_threads": 2}, {"scheduler": client})]
    for t in tables[1:]:
        pd.testing.assert_frame_equal(tables[0], t, check_exact=True)


def test_pf_sweep_blocks_identical_on_a_cluster(client, pickled):
    from uwbwb.filters import setnoise as F

    rng = np.random.default_rng(0)
    t = np.arange(30) * 0.1
    z = np.c_[t, 0.5 * t] + rng.normal(0, 0.1, (30, 2))
    mu, sd = np.zeros((2, 30, 2)), np.full((2, 30, 2), 0.1)
    kw = dict(n_trials=5, n_particles=50, block_particles=2 * 2 * 50)          # 5 trials in 3 blocks
    a = F.pf_sweep(t, z, mu, sd, z[0], (0.1, 0.3), rng=np.random.default_rng(1), **kw)
    b = F.pf_sweep(t, z, mu, sd, z[0], (0.1, 0.3), rng=np.random.default_rng(1), scheduler=client,
                   truth_m=z, **kw)
    np.testing.assert_array_equal(a.pos_m, b.pos_m)
    np.testing.assert_array_equal(a.n_resampled, b.n_resampled)
    np.testing.assert_array_equal(a.mean_error_m(z), b.error_m)
    c = F.pf_sweep(t, z, mu, sd, z[0], (0.1, 0.3), rng=np.random.default_rng(1), truth_m=z, keep_positions=False,
                   **kw)
    assert c.pos_m is None
    np.testing.assert_array_equal(c.error_m, b.error_m)
    with pytest.raises(ValueError, match="kept no positions"):
        c.mean_error_m(z)


def test_doppler_sampler_identical_on_a_cluster(client, pickled):
    from uwbwb import sampling as smp
    from uwbwb.models import doppler as dm

    model = dm.DopplerModel.for_layout(dm.cubic_layout())
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    kw = dict(seed=3, chunk_size=40_000, thresholds_m=(0.5, 2.0), keep_below_m=1.0)
    a = smp.brute_force(model, *ref, 200_000, workers=1, **kw)
    b = smp.brute_force(model, *ref, 200_000, scheduler=client, **kw)
    np.testing.assert_equal([vars(e) for e in a.estimates], [vars(e) for e in b.estimates])
    np.testing.assert_array_equal(a.samples.delta_m, b.samples.delta_m)
    assert len(b.samples) > 0
    c = smp.conditional(model, *ref, 6_000, seed=4, chunk_size=2_000, workers=1)
    d = smp.conditional(model, *ref, 6_000, seed=4, chunk_size=2_000, scheduler=client)
    np.testing.assert_equal([vars(e) for e in c.estimates], [vars(e) for e in d.estimates])
    np.testing.assert_array_equal(c.samples.weight, d.samples.weight)


def test_doppler_pf_cloud_identical_on_a_cluster(client, pickled):
    from uwbwb.filters import doppler as fd
    from uwbwb.models import doppler as dm
    from uwbwb.sim import chirps as sc

    lab = dm.DopplerModel.for_layout(dm.lab_layout())
    track, _ = sc.rectangle_track()
    rec = sc.simulate_chirps(lab, track, 4.0, rng=np.random.default_rng(0), jitter=False, p_miss=0.0,
                             spurious_rate_hz=0.0)
    log = fd.assign_chirps(rec.t_s, lab)
    pf = fd.DopplerPf(lab, n_particles=100)
    a = pf.run(log, n_runs=5, block_runs=2, rng=np.random.default_rng(7))
    b = pf.run(log, n_runs=5, block_runs=2, rng=np.random.default_rng(7), scheduler=client)
    c = pf.run(log, n_runs=5, block_runs=2, rng=np.random.default_rng(7), workers=2)
    for other in (b, c):
        np.testing.assert_array_equal(a.pos_m, other.pos_m)
        np.testing.assert_array_equal(a.meta["restarts"], other.meta["restarts"])


def test_calibration_curves_identical_on_a_cluster(client, pickled):
    from uwbwb.experiments import motion_models as mm

    cal, _ = mm.synthetic_acquisition("office", seed=1, duration_s=15.0, role="calibration")
    grids = {"RW": [0.1, 1.0], "RF": [1.0], "RJ": [1.0, 10.0]}
    a = mm.run_study(cal, cal[:1], grids=grids, gate_prob=None, progress=False)
    b = mm.run_study(cal, cal[:1], grids=grids, gate_prob=None, scheduler=client, progress=False)
    pd.testing.assert_frame_equal(a.curves, b.curves, check_exact=True)
    assert a.best == b.best


def test_a_protocol_whose_listener_is_not_checked_is_not_said_to_accept_connections():
    """ucx:// (or tls://) is not probed with a plain socket first: the message must not claim a listener."""
    try:
        par.connect(f"tls://127.0.0.1:{_free_port()}", timeout_s=1.0)
    except par.SchedulerUnreachable as exc:
        assert "something accepts connections" not in str(exc) and "tls:// connection was not checked" in str(exc)
    else:
        raise AssertionError("a closed tls:// port gave a scheduler")
