"""Fixed inputs and outputs of the UWB/INS fusion filters, for the golden test.

``python -m tests.golden.eskf_cases`` (from the repository root) writes ``eskf_golden.npz``
beside this file: every array of every case's :class:`~uwbwb.filters.eskf.FusionRun` (each
multi-column array at every 32nd epoch) and the platform they were computed on. :mod:`tests.golden.test_eskf_golden` recomputes the cases and
compares them with the file.

The inputs are synthetic (fixed seeds): a short two-leg robot run with outliers, missing TDoAs
and magnetometer headings, a longer run with a UWB outage (one TDoA heard, then nothing at
all), and two-way ranges drawn from the same truth. The cases cover the tight filter's
configurations (closed and open loop, no gate, a tight gate with short lost-lock runs,
iterated updates, ranges, no height, uncorrelated TDoAs, INS only, a far start) on both the
compiled and the reference path, and the loose filter (2-D and 3-D, gated and not, open loop).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from tests.golden.ekf_cases import digest, fingerprint
from uwbwb.filters import eskf
from uwbwb.filters.tdoa_ls import tdoa_least_squares
from uwbwb.models.imu import GRADES
from uwbwb.models.ins import NavState
from uwbwb.models.tdoa import TdoaModel
from uwbwb.sim import robot
from uwbwb.types import EstimateStatus, Estimates, RangeLog, TdoaLog

GOLDEN = Path(__file__).with_name("eskf_golden.npz")
DIGEST = Path(__file__).with_name("eskf_golden.sha256")
FIELDS = ("pos_m", "vel_mps", "quat", "acc_bias_mps2", "gyro_bias_radps", "P", "pos_cov_m2", "nis", "dof",
          "n_outliers", "n_gated", "status")

STRIDE = 32

TIGHT_CASES = {
    "default": dict(),
    "open-loop": dict(feedback=False),
    "nogate-scaled": dict(gate_prob=None, q_scale=2.0, r_scale=0.5),
    "p0.6-max2": dict(gate_prob=0.6, max_gated=2),
    "iterated": dict(iterate_sigma_m=0.0, gate_prob=None),
    "ranges": dict(ranges=True),
    "ranges-iterated": dict(ranges=True, iterate_sigma_m=0.0),
    "no-height": dict(height_m=None),
    "uncorrelated": dict(correlated=False),
    "ins-only": dict(uwb=None),
    "far-start": dict(far=True),
}


def _tight(cfg, **kw):
    model = cfg.tdoa_model(sigma_m=max(cfg.sigma_toa_m, 0.01))
    return eskf.TightEskf(GRADES["consumer"], eskf.TdoaUpdate(model, 0.1), lever_arm_m=cfg.lever_arm_m,
                          height_m=cfg.tag_height_m, **kw)


def _range_log(run, cfg, rng) -> RangeLog:
    a = np.asarray(cfg.stations_m, float)
    k = np.searchsorted(run.truth.t_s, run.tdoa.t_s).clip(0, len(run.truth.t_s) - 1)
    tag = np.column_stack([run.truth.pos_m[k, :2], np.full(k.size, cfg.tag_height_m)])
    r = np.linalg.norm(tag[:, None, :] - a, axis=-1) + 0.1 * rng.standard_normal((k.size, len(a)))
    r[rng.random(r.shape) < 0.1] = np.nan
    return RangeLog(run.tdoa.t_s, r, tuple(str(i) for i in range(len(a))))


def _fixes(run, cfg, dim: int) -> Estimates:
    m = TdoaModel(np.asarray(cfg.stations_m), max(cfg.sigma_toa_m, 0.01), dim=dim,
                  **({"z_m": cfg.tag_height_m} if dim == 2 else {}))
    ls = tdoa_least_squares(run.tdoa, m)
    st = np.where(ls.ok, EstimateStatus.UPDATED, EstimateStatus.NO_ESTIMATE).astype(np.int8)
    return Estimates(ls.t_s, np.where(ls.ok[:, None], ls.pos_m, np.nan), st, "UWB")


def _short_run():
    cfg = robot.RobotConfig(outlier_rate=0.1, outlier_excess_m=(0.3, 3.0), p_missing=0.2)
    rng = np.random.default_rng(11)
    motion = robot.broken_line(((2.0, 1.0), (3.2, 1.0), (3.2, 1.9)), turn_s=1.5, pause_s=0.5)
    run = robot.simulate(motion, cfg, rng=rng)
    return cfg, run, _range_log(run, cfg, rng)


def _outage_run():
    """Broken line with a 5 s one-TDoA outage, then 4 s with no UWB at all (rows empty)."""
    cfg = robot.RobotConfig(outage_start_s=10.0, outage_s=5.0, outlier_rate=0.0, p_missing=0.0, uwb_rate_hz=10.0)
    run = robot.simulate(robot.broken_line(robot.PAPER_WAYPOINTS_M[:4]), cfg, rng=np.random.default_rng(4))
    d = run.tdoa.tdoa_m.copy()
    ref = run.tdoa.ref.copy()
    empty = (run.tdoa.t_s >= 16.0) & (run.tdoa.t_s < 20.0)
    d[empty], ref[empty] = np.nan, -1
    return cfg, run, TdoaLog(run.tdoa.t_s, d, ref, run.tdoa.anchor_ids)


def _absent(log: TdoaLog) -> TdoaLog:
    """The same log with its empty epochs left out altogether."""
    keep = np.isfinite(log.tdoa_m).any(axis=1)
    return TdoaLog(log.t_s[keep], log.tdoa_m[keep], log.ref[keep], log.anchor_ids)


def runs() -> dict[str, eskf.FusionRun]:
    """Every case, by name."""
    out = {}
    cfg, run, ranges = _short_run()
    ba0, bg0 = np.array([0.02, -0.01, 0.03]), np.array([1e-3, -2e-3, 5e-4])
    for label, kw in TIGHT_CASES.items():
        kw = dict(kw)
        uwb, x0 = run.tdoa, run.x0
        if kw.pop("ranges", False):
            uwb = ranges
            kw["uwb"] = eskf.RangeUpdate(np.asarray(cfg.stations_m, float), 0.1, bias_m=0.02)
        if kw.pop("correlated", True) is False:
            kw["uwb"] = eskf.TdoaUpdate(replace(cfg.tdoa_model(sigma_m=0.05), correlated=False), 0.1)
        if kw.pop("far", False):
            x0 = NavState(run.x0.pos_m + np.array([1.5, -1.0, 0.0]), run.x0.vel_mps, run.x0.quat)
        if "uwb" in kw and kw["uwb"] is None:
            kw.pop("uwb")
            uwb = None
        height = kw.pop("height_m", cfg.tag_height_m)
        filt = replace(_tight(cfg), height_m=height, **kw)
        for path, ref in (("compiled", False), ("reference", True)):
            out[f"tight-{label}-{path}"] = filt.run(run.imu, uwb, x0, heading=run.heading, acc_bias0=ba0,
                                                    gyro_bias0=bg0, reference_step=ref)
    cfg, orun, olog = _outage_run()
    filt = _tight(cfg)
    for path, ref in (("compiled", False), ("reference", True)):
        out[f"tight-outage-{path}"] = filt.run(orun.imu, olog, orun.x0, heading=orun.heading, reference_step=ref)
        out[f"tight-outage-absent-{path}"] = filt.run(orun.imu, _absent(olog), orun.x0, heading=orun.heading,
                                                     reference_step=ref)
    loose2 = eskf.LooseFilter(height_m=cfg.tag_height_m, lever_arm_m=cfg.lever_arm_m)
    for label, (r, filt) in {
        "loose2d-default": (run, eskf.LooseFilter(height_m=cfg.tag_height_m, lever_arm_m=cfg.lever_arm_m)),
        "loose2d-gated": (run, eskf.LooseFilter(height_m=cfg.tag_height_m, lever_arm_m=cfg.lever_arm_m,
                                                gate_prob=0.99, max_gated=3)),
        "loose2d-openloop": (run, eskf.LooseFilter(height_m=cfg.tag_height_m, lever_arm_m=cfg.lever_arm_m,
                                                   feedback=False, q_scale=2.0, r_scale=0.5)),
        "loose3d-gated": (run, eskf.LooseFilter(dim=3, lever_arm_m=cfg.lever_arm_m, gate_prob=0.999, vel_window=3)),
        "loose2d-outage": (orun, loose2),
        "loose2d-outage-gated": (orun, replace(loose2, gate_prob=0.999, max_gated=5)),
    }.items():
        dim = 3 if label.startswith("loose3d") else 2
        out[label] = filt.run(r.imu, _fixes(r, cfg, dim), r.x0, heading=r.heading)
    return out


def arrays(cases: dict[str, eskf.FusionRun]) -> dict[str, np.ndarray]:
    """The flat ``{"<case>/<field>": array}`` dictionary stored in the golden file."""
    out = {}
    for name, run in cases.items():
        for f in FIELDS:
            a = np.asarray(getattr(run, f))
            if a.ndim > 1:
                a = a[::STRIDE]          # a multi-column array at every STRIDE-th epoch: a small file
            out[f"{name}/{f}"] = a
    return out


def write(path: Path = GOLDEN) -> None:
    flat = arrays(runs())
    np.savez_compressed(path, __fingerprint__=np.array(fingerprint()), **flat)
    DIGEST.write_text(f"{digest(flat)}  {fingerprint()}\n")


if __name__ == "__main__":
    write()
    print(f"wrote {GOLDEN} ({fingerprint()})")
