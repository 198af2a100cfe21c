"""Time of notebook 04's filters on one recording, this checkout against a reference revision.

Notebook 04 spends most of its full-mode time in two places (``benchmarks/profile_notebooks.py``):

* **PF block** — one block of :meth:`uwbwb.filters.doppler.DopplerPf.run` (``block_runs=25`` runs ×
  1000 particles × 6 states on the particle engine, :class:`uwbwb.filters.particle.ParticleFilter`),
  over the chirps of a :func:`uwbwb.experiments.doppler.study.track_study` recording, Doppler only
  and Doppler + pseudo-ranges;
* **MH-EKF** — :meth:`uwbwb.filters.doppler.ScaatMhEkf.run` over the same recording, both variants.

Each is timed (CPU time of its process, best of ``--repeat``: the machine may be shared) in a
process that imports this checkout and, with ``--reference REV`` (default ``HEAD``), in one that
imports the package as it was at ``REV`` (``git archive``), on the same recording with the same
seeds. Printed: both times, the ratio reference / this checkout, and whether the outputs are
bit-equal (positions, velocities, covariances, ESS, restarts and tempered shares of the PF runs;
positions and covariances of the MH-EKF).

Run:  python benchmarks/bench_doppler_pf.py [--reference REV] [--chirps N] [--repeat N]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def measure(chirps: int, repeat: int, out: str) -> dict:
    """Time the PF block and the MH-EKF in this process; their outputs go to ``out`` (npz)."""
    from uwbwb.experiments.doppler import study
    from uwbwb.filters.doppler.pf import _rows

    cfg = study.StudyConfig.for_mode(False)
    st = study.track_study("lab", cfg, pf_runs=1, n_particles=2, kf=False, variants=("Doppler",))
    log = st.log.select(slice(0, chirps)) if chirps else st.log
    pf, mh = study.make_filters("lab", cfg, st.model)
    ranges = study.fd.clock_pseudo_ranges(log, st.model, st.recording.phase_s)
    times, arrays = {}, {}
    for variant, r in (("Doppler", None), ("Doppler + ranges", ranges)):
        rows = _rows(log, pf.use_ambiguous)
        meas = (log.t_s[rows], log.beacon[rows], log.dp_s[rows], None if r is None else r[rows])
        best = np.inf
        for _ in range(repeat):
            t0 = time.process_time()
            res = pf._run_block(meas, 25, np.random.default_rng(7))
            best = min(best, time.process_time() - t0)
        times[f"PF block ({variant})"] = best
        for name, a in zip(("pos", "vel", "ess", "restarts", "tempered", "cov"), res):
            arrays[f"pf {variant} {name}"] = np.asarray(a)
        best = np.inf
        for _ in range(repeat):
            t0 = time.process_time()
            est = mh.run(log, study.kf_prior("lab"), ranges_m=r)
            best = min(best, time.process_time() - t0)
        times[f"MH-EKF ({variant})"] = best
        arrays[f"mh {variant} pos"], arrays[f"mh {variant} cov"] = est.pos_m, est.pos_cov_m2
    np.savez(out, **arrays)
    return {"times": times, "epochs": int(rows.size), "chirps": len(log)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", default="HEAD", help="git revision to compare with ('' = none)")
    ap.add_argument("--chirps", type=int, default=300, help="first chirps of the recording (0 = all)")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(measure(args.chirps, args.repeat, args.worker)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        runs = {"this checkout": ROOT}
        if args.reference:
            ref = Path(tmp) / "ref"
            ref.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.reference, "uwbwb"], capture_output=True)
            if archive.returncode == 0:
                subprocess.run(["tar", "-x", "-C", str(ref)], input=archive.stdout, check=True)
                runs = {f"reference {args.reference}": ref, **runs}
            else:                                   # e.g. a copy without its git history: this checkout only
                print(f"no reference: git archive {args.reference} failed ({archive.stderr.decode().strip()})")
        res = {}
        for label, path in runs.items():
            out = str(Path(tmp) / f"{len(res)}.npz")
            env = {**os.environ, "PYTHONPATH": str(path)}
            proc = subprocess.run([sys.executable, __file__, "--worker", out, "--chirps", str(args.chirps),
                                   "--repeat", str(args.repeat)], env=env, check=True, capture_output=True, text=True)
            res[label] = (json.loads(proc.stdout.strip().splitlines()[-1]), dict(np.load(out)))
        first = next(iter(res.values()))[0]
        print(f"lab recording, first {first['chirps']} chirps ({first['epochs']} PF epochs); PF block: 25 runs x "
              f"1000 particles; CPU s, best of {args.repeat}; load average {os.getloadavg()[0]:.1f}")
        labels = list(res)
        print(f"{'':28s}" + "".join(f"{lab:>22s}" for lab in labels) + ("      ratio" if len(labels) == 2 else ""))
        for key in first["times"]:
            t = [res[lab][0]["times"][key] for lab in labels]
            print(f"{key:28s}" + "".join(f"{v:21.2f}s" for v in t) + (f"{t[0] / t[1]:10.2f}x" if len(t) == 2 else ""))
        if len(labels) == 2:
            a, b = (res[lab][1] for lab in labels)
            same = [k for k in a if np.array_equal(a[k], b[k], equal_nan=True)]
            print(f"bit-equal outputs: {len(same)} of {len(a)}"
                  + "".join(f"\n  differs: {k}" for k in a if k not in same))


if __name__ == "__main__":
    main()
