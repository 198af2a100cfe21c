"""The scoreboard's UWB/INS tuning against the form it replaced: one start-up per recording and only the
adapter's own filter per grid point, against notebook 05's whole comparison at every grid point.

Both tune the tight filter's ``(Q ×, R ×)`` on the same calibration recording with the same grid and the same
criterion (horizontal RMSE on the calibration part):

* **whole comparison** — at every grid point :func:`uwbwb.filters.alignment.compare_iasl`: the start-up (rest
  levelling, 20 s heading alignment) and all six methods, of which one is kept (the adapter's former way);
* **adapter** — :class:`uwbwb.scoreboard.estimators.UwbInsFilter`: the start-up once, then
  :func:`~uwbwb.filters.alignment.run_fusion_filter` for its own filter at every grid point.

Printed: seconds (wall and CPU in this process, best of ``--repeat``) of each, their ratio, and the largest
difference between the two grids' RMSEs (the same filter: 0).

Data: ``iasl-uwb-imu`` scenario 1 when present (thinned to ``--rate-hz``), else a generated flight of the same
format (the test fixture).

Run:  python benchmarks/bench_board_ins.py [--repeat N] [--rate-hz R] [--grid-points N]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

import uwbwb as uw
from uwbwb.datasets import iasl
from uwbwb.filters import alignment
from uwbwb.scoreboard import calibrate
from uwbwb.scoreboard.estimators import INS_GRID, INS_REST_S, INS_ALIGN_S, UwbInsFilter
from uwbwb.scoreboard.interface import _errors_rmse, calibrated_log
from uwbwb.types import Trajectory

from bench_eskf import _time                                   # best wall and CPU time of N calls (same folder)


def _recording(rate_hz: float):
    if uw.datasets.dataset_available("iasl-uwb-imu"):
        return iasl.load_scenario("scenario1").decimate(rate_hz=rate_hz), "iasl-uwb-imu/scenario1"
    from tests.fixtures import iasl as fx                      # the generated flight of the tests

    root = Path(tempfile.mkdtemp()) / "iasl-uwb-imu"
    fx.write_dataset(root, rng=np.random.default_rng(0), duration_s=60.0)
    return iasl.load_scenario("scenario1", root.parent).decimate(rate_hz=rate_hz), "generated flight (60 s)"


def _whole(rec, cal, est, grid):
    """The former adapter: compare_iasl (start-up + every method) per grid point, keep the tight filter."""
    imu_cal = cal.params("tight")["calibration"]
    real = replace(imu_cal, range_sigma_m=cal.sigma("tag"), range_bias_m=0.0)
    log = calibrated_log(rec, "tag", cal)
    hidden = Trajectory(log.t_s[[0, -1]], np.full((2, 3), np.nan), name="truth (hidden)")
    one = replace(rec, ranges={"tag": log}, truth={"tag": hidden})
    out = []
    for q, r in grid:
        comp = alignment.compare_iasl(one, real, alignment.FusionSettings(), still_s=INS_REST_S, align_s=INS_ALIGN_S,
                                      scales={k: (q, r) for k in ("loose", "tight", "tight (ranges)")})
        out.append(_errors_rmse(est._placed(comp.estimates["tight"], rec, "tag"), rec, "tag", cal.dim))
    return np.array(out)


def _adapter(rec, cal, grid):
    est = UwbInsFilter("tight", {}, grid)
    return np.array(est.tune(rec, ["tag"], cal)["grid_rmse_m"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="best of N runs each")
    ap.add_argument("--rate-hz", type=float, default=10.0)
    ap.add_argument("--grid-points", type=int, default=6, help="the first N pairs of the board's grid")
    args = ap.parse_args()
    rec, what = _recording(args.rate_hz)
    grid = INS_GRID[:args.grid_points]
    est = UwbInsFilter("tight", {}, grid)
    cal = calibrate(rec, [est], rate_hz=None)                  # the IMU calibration both use, fitted once
    t_w, c_w, rmse_w = _time(lambda: _whole(rec, cal, est, grid), args.repeat)
    t_a, c_a, rmse_a = _time(lambda: _adapter(rec, cal, grid), args.repeat)
    print(f"{what} at {args.rate_hz:g} Hz, {len(grid)} grid points, tight filter")
    print(f"whole comparison per point : {t_w:7.2f} s wall, {c_w:7.2f} s CPU")
    print(f"adapter (one start-up)     : {t_a:7.2f} s wall, {c_a:7.2f} s CPU")
    print(f"speed-up                   : {t_w / t_a:5.2f} x wall, {c_w / c_a:5.2f} x CPU (same process, best of "
          f"{args.repeat})")
    print(f"max |Δ grid RMSE|          : {np.abs(rmse_w - rmse_a).max():.2e} m (same filter)")


if __name__ == "__main__":
    main()
