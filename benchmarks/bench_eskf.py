"""Throughput of the tight UWB/INS error-state filter and of the paper's loose filter against their
straightforward per-step forms.

Both forms of the tight filter run the same 15-state filter (:class:`uwbwb.filters.eskf.TightEskf`)
on the same simulated dynamic run of notebook 05 (100 Hz IMU, 50 Hz TDoA, four stations):

* **per step** — ``reference_step=True``: the Python reference (``TightEskf.run_reference``); the
  covariance goes through :func:`uwbwb.filters.kalman.predict` (filterpy) at every IMU step with the
  (F, Q) of the INS error transition model, and every epoch's rows through the Gaussian engine's
  sequential update (:func:`uwbwb.filters.gating.ungated_update`, :func:`kalman.update_sequential`);
* **compiled** — the default: one compiled loop over the epochs (the transition of the IMU steps
  between two UWB epochs accumulated and applied once, then the same sequential updates).

The loose filter (:class:`uwbwb.filters.eskf.LooseFilter`, notebook 05's gated one, on the LS fixes of the
same run) likewise: ``LooseFilter.run_reference`` (the mechanization step by step in Python, filterpy's
predict and the gate policy's update per epoch) against the compiled loop (the same steps).

Printed: seconds per 10 000 IMU steps of each (wall clock and CPU time in this process, on
whatever load the machine has), their ratio, and the largest position difference between the
two (they are the same filter).

Run:  python benchmarks/bench_eskf.py [--repeat N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uwbwb.experiments.uwb_ins import study
from uwbwb.filters import eskf
from uwbwb.sim import robot


def _setup(seed: int):
    run = study.simulate("dynamic", robot.RobotConfig(), rng=np.random.default_rng(seed), legs=3)
    cfg = run.config
    filt = eskf.TightEskf(cfg.imu, eskf.TdoaUpdate(cfg.tdoa_model(), 0.1), lever_arm_m=cfg.lever_arm_m,
                          height_m=cfg.tag_height_m)
    return run, filt


def _report(label: str, ref, acc, n_steps: int, repeat: int) -> None:
    (t_ref, c_ref, a), (t_acc, c_acc, b) = ref, acc
    per = 1e4 / n_steps
    print(f"{label}, per step : {t_ref * per:6.3f} s wall, {c_ref * per:6.3f} s CPU per 10 000 IMU steps")
    print(f"{label}, compiled : {t_acc * per:6.3f} s wall, {c_acc * per:6.3f} s CPU per 10 000 IMU steps")
    print(f"{label}, speed-up : {t_ref / t_acc:5.2f} x wall, {c_ref / c_acc:5.2f} x CPU (same process, best of {repeat})")
    print(f"{label}, max |Δpos|: {np.nanmax(np.abs(a.pos_m - b.pos_m)):.2e} m (same filter)")


def _time(fn, repeat: int):
    """Best wall and CPU time of ``repeat`` calls (CPU time is less sensitive to a loaded machine)."""
    best, cpu, out = np.inf, np.inf, None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        best, cpu = min(best, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    return best, cpu, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs each")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    run, filt = _setup(args.seed)
    n_steps = len(run.imu)
    filt.run(run.imu.__class__(run.imu.t_s[:50], run.imu.acc_mps2[:50], run.imu.gyro_radps[:50]), run.tdoa,
             run.x0)                                           # compile the kernels outside the timing
    ref = _time(lambda: filt.run(run.imu, run.tdoa, run.x0, heading=run.heading, reference_step=True), args.repeat)
    acc = _time(lambda: filt.run(run.imu, run.tdoa, run.x0, heading=run.heading), args.repeat)
    print(f"run: {n_steps} IMU steps, {len(run.tdoa)} UWB epochs ({run.motion.duration_s:.1f} s)")
    _report("tight", ref, acc, n_steps, args.repeat)
    s = study.start(run, run.config, 0.1)
    _, loose = study.fusion_filters(run.config, study.FusionSettings(gate_prob=0.999))
    loose.run(s.imu, s.fixes, s.x0, heading=run.heading)                 # compile outside the timing
    ref = _time(lambda: loose.run_reference(s.imu, s.fixes, s.x0, heading=run.heading), args.repeat)
    acc = _time(lambda: loose.run(s.imu, s.fixes, s.x0, heading=run.heading), args.repeat)
    _report("loose", ref, acc, len(s.imu), args.repeat)

if __name__ == "__main__":
    main()
