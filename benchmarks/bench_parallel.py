"""Where a sweep runs: one process, local threads, or a Dask LocalCluster — same numbers, how fast.

Two heavy paths of the workbench, each run three ways on the same machine in the
same process, interleaved over a few rounds in rotating order, so that the ratios
(median over rounds of the ratio within a round) hold even on a machine shared
with other work:

* **Fig. 9 sweep** — :func:`uwbwb.experiments.setnoise.sweep` (baseline and set-noise
  PF, every σ_d of the paper's grid, K = 1000) on two Table I recordings;
* **Doppler sampler** — :func:`uwbwb.sampling.brute_force` (numba kernel, chunks of
  2²³ draws, its default).

Paths: ``serial`` (``scheduler=None``, one thread: the default), ``threads``
(``scheduler=None``, 2 threads), ``cluster`` (``scheduler=`` a
``LocalCluster(n_workers=2, threads_per_worker=1)`` of worker processes, started
and warmed up before timing). Every path is checked to give identical numbers.

It also times the default path against the loop it replaced (the blocks of
:func:`uwbwb.filters.setnoise.pf_sweep` called directly, no task layer) — the
cost of the layer when no cluster is given — and prints the dry-run task count
and per-task cost of the full-size sweeps, for scaling to more workers.

Run:  python benchmarks/bench_parallel.py [--rounds 6]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

import numpy as np
import pandas as pd

from uwbwb import parallel
from uwbwb import sampling as smp
from uwbwb.experiments import setnoise as ex
from uwbwb.filters import setnoise as sf
from uwbwb.models import doppler as dm


def _time(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def _direct_blocks(rec, mu, sd, sig, cfg, seed):
    """The sweep's blocks called in a plain loop (how pf_sweep ran them before the task layer)."""
    t, dt = sf._times(rec.t_s)
    x0 = rec.truth_m[0]
    dtype = np.dtype(np.float32)
    centre = (rec.pos_m[None] - mu - x0).astype(dtype)
    half_prec = (0.5 / sd ** 2).astype(dtype)
    children = np.random.default_rng(seed).spawn(cfg.n_trials)
    b = sf._block_trials(2 * sig.size, cfg.n_particles, 1 << 17, cfg.n_trials)
    err = np.empty((2, cfg.n_trials, sig.size))
    for first in range(0, cfg.n_trials, b):
        sl = slice(first, min(first + b, cfg.n_trials))
        pos, _, _ = sf._sweep_block(children[sl], centre, half_prec, dt.astype(dtype), sig, cfg.n_particles, 2,
                                    cfg.ess_fraction, cfg.resampler, True, dtype)
        err[:, sl] = np.linalg.norm(np.moveaxis(pos, 0, 1) + x0 - rec.truth_m, axis=-1).mean(axis=-1)
    return err


def _via_layer(rec, mu, sd, sig, cfg, seed):
    res = sf.pf_sweep(rec.t_s, rec.pos_m, mu, sd, rec.truth_m[0], sig, rng=np.random.default_rng(seed),
                      n_trials=cfg.n_trials, n_particles=cfg.n_particles, truth_m=rec.truth_m, keep_positions=False)
    return res.error_m


def main(argv=None):
    import distributed

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=6, help="interleaved rounds (each path takes each place in turn)")
    p.add_argument("--trials", type=int, default=8, help="PF trials per σ_d in the timed Fig. 9 sweep")
    p.add_argument("--draws", type=float, default=3.2e7, help="draws of the timed Doppler sampler run")
    args = p.parse_args(argv)

    study = ex.synthetic_study(rng=np.random.default_rng(0))
    recs = [study.recording("rec4"), study.recording("rec5")]
    cfg = ex.SweepConfig(n_trials=args.trials)
    model = dm.DopplerModel.for_layout(dm.cubic_layout())
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    chunk = 1 << 23                   # brute_force's default chunk size
    n_draws = int(args.draws)

    cluster = parallel.local_cluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = distributed.Client(cluster, set_as_default=False)
    where = {"serial": dict(n_threads=1), "threads": dict(n_threads=2), "cluster": dict(scheduler=client)}
    sampler_kw = {"serial": dict(workers=1), "threads": dict(workers=2), "cluster": dict(scheduler=client)}
    try:
        # warm-up: imports, numba kernels and the recordings' first transfer on every worker
        small = dataclasses.replace(cfg, n_trials=2, n_particles=50, sigma_d_mps=(0.1, 0.3))
        for kw in where.values():
            ex.sweep(recs, study.model, dataclasses.replace(small, **kw), rng=np.random.default_rng(0), progress=False)
        for kw in sampler_kw.values():
            smp.brute_force(model, *ref, 2 * chunk, seed=0, chunk_size=chunk, **kw)

        runs = {(job, w): [] for job in ("fig9", "sampler") for w in where}
        runs.update({("layer", "direct"): [], ("layer", "pf_sweep"): []})
        tables, fracs = {}, {}
        rec = recs[0]
        mu = np.stack([study.model.facility_only().lookup(rec.set_id)[0], study.model.lookup(rec.set_id)[0]])
        sd = np.stack([study.model.facility_only().lookup(rec.set_id)[1], study.model.lookup(rec.set_id)[1]])
        sig = np.asarray(cfg.sigma_d_mps)
        names = list(where)
        for r in range(args.rounds):
            order = names[r % 3:] + names[:r % 3]          # each path takes each place in turn
            for w in order:
                s, tables[w] = _time(lambda: ex.sweep(recs, study.model, dataclasses.replace(cfg, **where[w]),
                                                      rng=np.random.default_rng(1), progress=False))
                runs["fig9", w].append(s)
            for w in order:
                s, fracs[w] = _time(lambda: smp.brute_force(model, *ref, n_draws, seed=2, chunk_size=chunk,
                                                            **sampler_kw[w]))
                runs["sampler", w].append(s)
            for w in (("direct", "pf_sweep") if r % 2 == 0 else ("pf_sweep", "direct")):
                fn = _direct_blocks if w == "direct" else _via_layer
                s, errs = _time(lambda: fn(rec, mu, sd, sig, cfg, 3))
                runs["layer", w].append(s)
                if w == "direct":
                    e_direct = errs
                else:
                    e_layer = errs
        for w in where:
            pd.testing.assert_frame_equal(tables["serial"], tables[w], check_exact=True)
            np.testing.assert_equal([vars(e) for e in fracs["serial"].estimates], [vars(e) for e in fracs[w].estimates])
        assert np.array_equal(e_direct, e_layer), "the task layer changed the numbers"
    finally:
        client.close()
        cluster.close()

    best = {k: min(v) for k, v in runs.items()}

    def ratio(a, b):   # median over rounds of the ratio within a round: robust to the load changing between rounds
        return float(np.median(np.asarray(runs[a]) / np.asarray(runs[b])))

    n_fixes = sum(map(len, recs))
    print(f"{os.cpu_count()} CPUs (load average {os.getloadavg()[0]:.1f}); {args.rounds} interleaved rounds "
          f"(times: best round; ratios: median over rounds of the ratio within a round); "
          f"identical numbers on every path: yes")
    for job, label in (("fig9", f"Fig. 9 sweep: 2 recordings ({n_fixes} fixes) x {cfg.n_trials} trials x "
                                f"{len(cfg.sigma_d_mps)} sigma_d x K = {cfg.n_particles}, both PFs"),
                       ("sampler", f"Doppler sampler: brute force, {n_draws:.3g} draws in chunks of {chunk}")):
        local = min(("serial", "threads"), key=lambda w: best[job, w])
        print(label)
        for w in where:
            print(f"  {w:8s} {best[job, w]:7.2f} s   {1 / ratio((job, w), (job, 'serial')):5.2f} x serial")
        print(f"  cluster / best local path ({local}) = {ratio((job, 'cluster'), (job, local)):.3f}")
    print(f"default path (pf_sweep, scheduler=None, 1 thread) / its blocks called directly: "
          f"{ratio(('layer', 'pf_sweep'), ('layer', 'direct')):.3f}  (recording {rec.name}, {cfg.n_trials} trials)")

    # dry run of the full-size sweeps: task counts and per-task cost, nothing computed beyond one timed task
    full = ex.SweepConfig()
    b = sf._block_trials(2 * len(full.sigma_d_mps), full.n_particles, 1 << 17, full.n_trials)
    per_rec = -(-full.n_trials // b)
    per_block_s = best["fig9", "serial"] / sum(-(-cfg.n_trials // b) for _ in recs) * (
        np.mean([len(r) for r in study.recordings]) / np.mean([len(r) for r in recs]))
    plan = smp.chunk_seeds(0, 10 ** 9, 1 << 23)
    per_chunk_s = best["sampler", "serial"] / n_draws * (1 << 23)
    print("dry run of the full sizes (for scaling to more workers):")
    print(f"  Fig. 9 sweep, 5 recordings x 100 trials: {len(study.recordings) * per_rec} tasks of {b} trials "
          f"({per_rec} per recording), ~{per_block_s:.2g} s each on one core here")
    sizes = [n for _, n in plan]
    print(f"  Doppler sampler, 1e9 draws: {len(plan)} tasks of {min(sizes):.3g}–{max(sizes):.3g} draws"
          f", ~{per_chunk_s:.2g} s per task on one core here")


if __name__ == "__main__":
    main()
