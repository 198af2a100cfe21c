"""Throughput of the EKF's compiled epoch loop against its Python definition, on TDoAs and on ranges.

Both run the same filter on the same recording: notebook 03's simulated office walk (its "test"
acquisition, 10 Hz, the range noise σ the notebook calibrates), as the TDoA EKF
(:class:`uwbwb.filters.ekf.TdoaEkf`, pseudo-TDoAs to anchor 0) and as the range EKF of the board
(:class:`~uwbwb.filters.ekf.Ekf` with :class:`~uwbwb.filters.ekf.RangeMeasurement`, the tag at its known
height), with each motion model (RW, RF, RJ at the thesis' Table 1 σ) and the two gates the notebooks run
(none: notebook 03's ``GATE_PROB = None``; anchor dropping at 0.9999: the board's default in notebook 06),
the range EKF also with the :class:`~uwbwb.filters.gating.Robust` (Huber) update screened by that gate (notebook
06's update-variant rows "robust" and "both"), from the same start and prior:

* **Python** — :meth:`uwbwb.filters.ekf.Ekf.run`: filterpy's predict and update per epoch, the gate
  policy's own decision (the twin's definition, ``uwbwb/filters/twins.py``);
* **compiled** — :meth:`TdoaEkf.run` and :func:`~uwbwb.filters.ekf.ranges.run_ranges`, which take
  :mod:`uwbwb.filters.ekf.kernels` for these gates.

Printed per configuration: milliseconds per 1000 epochs of each (best wall and CPU time of ``--repeat``
runs in this process, on whatever load the machine has) of the loop from the start on, their ratio, the time of a
whole :meth:`TdoaEkf.run` (which also finds that start with a least-squares fix), and the largest position
difference (the same filter: rounding only).

Run:  python benchmarks/bench_ekf.py [--repeat N] [--duration S]
"""

from __future__ import annotations

import argparse

import numpy as np

from uwbwb import calibration
from uwbwb.experiments import motion_models as mm
from uwbwb.filters.ekf import Ekf, RangeMeasurement, TdoaEkf, TdoaMeasurement
from uwbwb.filters.ekf.ranges import run_ranges
from uwbwb.filters.gating import AnchorDropping, NoGate, Robust
from uwbwb.filters.kalman import Gaussian
from uwbwb.models import motion
from uwbwb.models.tdoa import TdoaModel

from bench_eskf import _time as _best     # best wall and CPU time of N calls: one timer for the benchmarks (run from benchmarks/)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs each")
    ap.add_argument("--duration", type=float, default=120.0, help="length of the simulated walk (s)")
    args = ap.parse_args()
    runs, _ = mm.synthetic_acquisition("office", seed=0, duration_s=args.duration, rate_hz=10.0, role="test")
    head = runs[0]
    log = head.tdoa(0)
    sigma = calibration.fit_range_sigma(head, method="tdoa")
    model = TdoaModel.for_tag(head, sigma)
    epochs, rows = TdoaMeasurement.epochs(log), RangeMeasurement.epochs(head.ranges)
    print(f"recording: {head.key}, {len(log)} epochs ({args.duration:g} s at 10 Hz), {log.n_anchors} anchors")
    ratios = {"TDoA": [], "ranges": [], "robust ranges": []}
    for name in mm.MODELS:
        for gate_prob in (None, 0.9999):
            m = motion.make_motion_model(name, sigma=mm.PAPER_SIGMA["office"][name], dt_s=head.dt_s, dim=head.dim)
            ekf = TdoaEkf(m, model, gate_prob=gate_prob)
            first = ekf.run(log)                            # compile (or load) the kernel outside the timing
            start = int(np.flatnonzero(first.started)[0])   # the start TdoaEkf.run finds (first LS fix)
            x0 = Gaussian(first.x_prior[start], first.P_prior[start])
            t_fast, c_fast, fast = _best(lambda: ekf.run(log.select(slice(start, None)), x0=x0), args.repeat)
            t_py, c_py, py = _best(lambda: Ekf.run(ekf, log.t_s[start:], epochs[start:], x0), args.repeat)
            t_whole, _, _ = _best(lambda: ekf.run(log), args.repeat)
            _report(f"EKF-{name:2s} TDoA   {type(ekf.gate).__name__:14s}", len(log) - start, t_py, c_py, t_fast,
                    c_fast, py, fast, ratios["TDoA"], f" (TdoaEkf.run with its LS start: {t_whole * 1e3:5.1f} ms)")
            gate = NoGate() if gate_prob is None else AnchorDropping(gate_prob, min_rows=2)   # the board's range gate
            for policy, kind, label in ((gate, "ranges", type(gate).__name__),
                                        (Robust(gate=gate), "robust ranges", f"Robust+{type(gate).__name__}")):
                rng_ekf = Ekf(m, RangeMeasurement(head.anchors.pos_m, sigma, m, head.z_m), gate=policy)
                run_ranges(rng_ekf, head.ranges, x0, start=start)                           # compile (or load)
                t_fast, c_fast, fast = _best(lambda: run_ranges(rng_ekf, head.ranges, x0, start=start), args.repeat)
                t_py, c_py, py = _best(lambda: rng_ekf.run(head.ranges.t_s, rows, x0, start=start), args.repeat)
                _report(f"EKF-{name:2s} ranges {label:21s}", len(log) - start, t_py, c_py, t_fast, c_fast, py, fast,
                        ratios[kind])
    for meas, rs in ratios.items():
        for k, kind in enumerate(("wall", "CPU")):
            r = [q[k] for q in rs]
            print(f"{meas}: ratio Python / compiled, {kind} time: {min(r):.1f} to {max(r):.1f} (geometric mean "
                  f"{np.exp(np.mean(np.log(r))):.1f}); same process, best of {args.repeat}")


def _report(label, epochs, t_py, c_py, t_fast, c_fast, py, fast, ratios, note=""):
    per = 1e6 / epochs
    ratios.append((t_py / t_fast, c_py / c_fast))
    print(f"{label}: Python {t_py * per:7.2f} ms, compiled {t_fast * per:5.2f} ms wall per 1000 epochs, ratio "
          f"{t_py / t_fast:5.1f} wall, {c_py / c_fast:5.1f} CPU{note}; max |Δpos| "
          f"{np.nanmax(np.abs(py.pos_m - fast.pos_m)):.1e} m, status equal: {np.array_equal(py.status, fast.status)}")


if __name__ == "__main__":
    main()
