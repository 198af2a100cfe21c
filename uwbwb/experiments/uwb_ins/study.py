"""What notebook 05 runs: UWB-only, INS-only, the paper's loose filter and the tight filter,
on the synthetic robot re-creation and on the ``iasl-uwb-imu`` drone recordings.

Every method of a comparison gets the same information: the same IMU samples, the same
UWB epochs (TDoA from the same ranges, the same eq-4 test), the same initial state, the same
magnetometer headings where there are any, the same known tag height for the ground robot.
They are scored on the same epochs; coverage is reported beside accuracy.

The real-data pieces live in the core: the IMU calibration in :mod:`uwbwb.filters.imu_calibration`, the start-up
(eq-4 screen, levelling, heading alignment) and the filters run from it in :mod:`uwbwb.filters.alignment`, and the
board that tunes and scores them on a recording in :mod:`uwbwb.scoreboard` (notebook 05's real-data section).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...filters import eskf
from ...models.ins import NavState
from ...models.tdoa import TdoaModel
from ...sim import robot
from ...types import Estimates, ImuLog, TdoaLog, Trajectory
from ...filters.alignment import Comparison, FusionSettings, imu_after, initial_state, ls_estimates, screened_tdoa

__all__ = ["PAPER", "METHODS", "simulate", "Start", "start", "fusion_filters", "injected", "compare_synthetic",
           "error_ranges"]

#: Numbers quoted from paper 004 (kind "input"): error ranges (m) and the summary bounds.
PAPER = {"static_E_m": (-0.04, 0.07), "static_N_m": (-0.07, 0.09), "dynamic_m": (-0.21, 0.16),
         "static_bound_m": 0.1, "dynamic_bound_m": 0.25, "uwb_rate_hz": 50.0, "speed_mps": 0.3}
#: Method names, in display order (one colour each, see :mod:`uwbwb.plotting`).
METHODS = ("UWB-only", "INS-only", "loose", "tight")


# ====================================================================== synthetic
#: Where the degradations sit in the dynamic run (s): the outage starts on the second leg, the
#: NLOS-biased station episode covers the third turn and the fourth leg.
OUTAGE_START_S, NLOS_START_S, NLOS_S = 8.0, 18.0, 6.0


def simulate(scenario: str, world: robot.RobotConfig, *, rng: np.random.Generator, static_s: float = 60.0,
             legs: int = 5, outage_s: float = 0.0, nlos_bias_m: float = 0.0) -> robot.RobotRun:
    """One synthetic run in ``world``: ``"static"`` at (3.5, 2) m for ``static_s`` or ``"dynamic"`` along the
    first ``legs`` legs of the paper's broken line, drawn from ``rng``.

    ``outage_s`` > 0 silences every station but BS1 and BS2 from :data:`OUTAGE_START_S` on (one
    TDoA per epoch: no position fix); ``nlos_bias_m`` > 0 adds that excess to station BS3 for
    :data:`NLOS_S` seconds from :data:`NLOS_START_S`. Notebook 05's sections draw from their seed
    (``default_rng(seed)``), the ablation from ``default_rng([seed, 0 static / 1 dynamic])``
    (:func:`~.ablation.simulate`).
    """
    if scenario not in ("static", "dynamic"):
        raise ValueError(f"scenario must be 'static' or 'dynamic', got {scenario!r}")
    motion = robot.hold(duration_s=static_s) if scenario == "static" \
        else robot.broken_line(robot.PAPER_WAYPOINTS_M[: legs + 1])
    if outage_s > 0 and OUTAGE_START_S + outage_s > motion.duration_s:
        raise ValueError(f"outage_s = {outage_s:g} s cannot hold: the outage starts at {OUTAGE_START_S:g} s and "
                         f"this {scenario} run lasts {motion.duration_s:.1f} s")
    world = replace(world, outage_start_s=OUTAGE_START_S if outage_s > 0 else None, outage_s=outage_s)
    if nlos_bias_m > 0:
        world = replace(world, nlos_station=2, nlos_bias_m=nlos_bias_m, nlos_start_s=NLOS_START_S, nlos_s=NLOS_S)
    return robot.simulate(motion, world, rng=rng)


@dataclass(frozen=True)
class Start:
    """What every method of one synthetic run shares (:func:`start`): the TDoAs after the eq-4 test
    (``screened``) and the count it removed per epoch (``n_eq4``), the 2-D TDoA model at the known tag
    height (``tdoa2``), the UWB-only least-squares ``fixes``, the filters' initial state ``x0`` at epoch
    ``k0`` (the first scored one), the ``imu`` samples from there on, and the tight filter's ``snapshot`` fixes
    (:meth:`~uwbwb.filters.eskf.TdoaUpdate.snapshot` of the run's TDoAs after its eq-4 test, ``(T, 3)``: every
    tight filter of :func:`fusion_filters` on this run starts its iterated updates there, whatever its knobs)."""

    screened: TdoaLog
    n_eq4: np.ndarray
    tdoa2: TdoaModel
    fixes: Estimates
    x0: NavState
    k0: int
    imu: ImuLog
    snapshot: np.ndarray


def start(run: robot.RobotRun, model: robot.RobotConfig, outlier_c_m: float | None) -> Start:
    """Eq. 4 on the run's TDoAs, LS fixes at the tag height of ``model`` (the filters' model), and the filters'
    start at the first fix: zero velocity, level attitude (the robot stands on a flat floor), the magnetometer
    heading of that epoch, zero IMU biases."""
    anchors = np.asarray(model.stations_m, float)
    screened, n_eq4 = screened_tdoa(run.tdoa, anchors, outlier_c_m)
    tdoa2 = TdoaModel(anchors, model.sigma_toa_m, dim=2, z_m=model.tag_height_m)
    fixes = ls_estimates(screened, tdoa2)
    yaw0 = float(run.heading.yaw_rad[int(np.flatnonzero(fixes.has_estimate)[0])])
    x0, k0 = initial_state(fixes, height_m=model.tag_height_m, lever_m=model.lever_arm_m, yaw_rad=yaw0)
    uwb = fusion_filters(model, FusionSettings(outlier_c_m=outlier_c_m))[0].uwb   # the tight filter's update
    snapshot = uwb.snapshot(run.tdoa.t_s, uwb.screen(run.tdoa.tdoa_m, run.tdoa.ref)[0], run.tdoa.ref)
    return Start(screened, n_eq4, tdoa2, fixes, x0, k0, imu_after(run.imu, run.truth.t_s[k0]), snapshot)


def fusion_filters(model: robot.RobotConfig, settings: FusionSettings = FusionSettings(), *,
                   gate_loose: bool = True) -> tuple[eskf.TightEskf, eskf.LooseFilter]:
    """The tight filter and the paper's loose filter for the robot ``model``: the one builder of notebook 05's
    cell, its sections and its ablation.

    Tight: the 15-state error-state filter whose ``(F, Q)`` per IMU step come from the IMU grade's noise model
    (``model.imu``, the object that draws the simulated IMU errors) and which updates with each TDoA on its own
    (:class:`~uwbwb.filters.eskf.TdoaUpdate`: the TDoA model that draws them, eq. 4's ``C``), χ² gate
    ``settings.gate_prob``. Loose (eqs 5–7): the LS fixes with position σ twice the arrival-time σ and a velocity
    differenced over ``settings.loose_window`` of them; gated alike unless ``gate_loose`` is False (the paper's
    filter, as published). Both hold the known tag height and the lever arm, and take ``settings``' Q and R
    multipliers and feedback.
    """
    common = dict(lever_arm_m=model.lever_arm_m, height_m=model.tag_height_m, q_scale=settings.q_scale,
                  r_scale=settings.r_scale, feedback=settings.feedback)
    tight = eskf.TightEskf(model.imu, eskf.TdoaUpdate(model.tdoa_model(), settings.outlier_c_m),
                           gate_prob=settings.gate_prob, **common)
    loose = eskf.LooseFilter(vel_window=settings.loose_window, sigma_r_pos_m=2 * model.sigma_toa_m,
                             gate_prob=settings.gate_prob if gate_loose else None, **common)
    return tight, loose


def injected(run: robot.RobotRun) -> np.ndarray:
    """Where a measured TDoA carries the simulator's multipath excess (on its station or on the reference),
    ``(T, n)`` bool."""
    ref = run.tdoa.ref
    bad = run.outlier | run.outlier[np.arange(len(ref)), np.clip(ref, 0, None)][:, None]
    bad &= np.isfinite(run.tdoa.tdoa_m)
    bad[np.arange(len(ref)), ref] = False
    return bad


def compare_synthetic(run: robot.RobotRun, settings: FusionSettings = FusionSettings(), *,
                      label: str = "synthetic", methods=METHODS) -> Comparison:
    """UWB-only (TDoA LS at the known height), INS-only, the paper's loose filter (no gate) and the tight filter
    on one simulated run, all from :func:`start` with the filters of :func:`fusion_filters`.

    ``methods`` picks which of :data:`METHODS` to run (UWB-only always runs: the others start from its first fix).
    """
    unknown = set(methods) - set(METHODS)
    if unknown:
        raise ValueError(f"compare_synthetic: unknown methods {sorted(unknown)}; known: {METHODS}")
    cfg = run.config
    s = start(run, cfg, settings.outlier_c_m)
    tight, loose = fusion_filters(cfg, settings, gate_loose=False)
    todo = {"tight": lambda: tight.run(s.imu, run.tdoa, s.x0, heading=run.heading, fix_tag=s.snapshot),
            "loose": lambda: loose.run(s.imu, s.fixes, s.x0, heading=run.heading),
            "INS-only": lambda: eskf.dead_reckon(s.imu, s.x0, run.truth.t_s, lever_arm_m=cfg.lever_arm_m)}
    runs = {k: f() for k, f in todo.items() if k in methods}
    est = {"UWB-only": s.fixes}
    est.update({k: v.to_estimates(dim=2, name=k) for k, v in runs.items()})
    est = {m: est[m] for m in METHODS if m in est}
    masks = {"scored": np.arange(len(run.truth)) >= s.k0, "outage": run.outage, "nlos": run.nlos}
    gated = int(runs["tight"].n_gated.sum()) if "tight" in runs else 0
    rejected = {"eq4": int(s.n_eq4.sum()), "gated": gated, "injected": int(injected(run).sum()),
                "tdoas": int(run.tdoa.n_tdoa.sum())}
    truth = Trajectory(run.truth.t_s, run.truth.pos_m[:, :2], run.truth.vel_mps[:, :2], run.truth.rot, "truth")
    return Comparison(label, truth, est, runs, masks, rejected, 2, {"yaw_true_rad": run.yaw_true_rad})


def error_ranges(comp: Comparison, name: str = "tight") -> dict:
    """East and north error extremes of ``name``, m.

    The paper's "error range (a, b)" is read as the min and max of the signed error over the
    test; its "average residual rate" and "confidence" are not defined and are not reproduced.
    """
    est = comp.estimates[name]
    sel = comp.masks.get("scored", np.ones(len(est), bool)) & est.has_estimate
    e = est.pos_m[sel, :2] - comp.truth.pos_m[sel, :2]
    out = {}
    for k, ax in enumerate("EN"):
        out[f"{ax}_min"], out[f"{ax}_max"] = float(e[:, k].min()), float(e[:, k].max())
    # the dynamic test's single range: the signed error along the direction of travel's normal is
    # not defined in the paper; we take the signed error component of larger magnitude per epoch
    big = np.where(np.abs(e[:, 0]) >= np.abs(e[:, 1]), e[:, 0], e[:, 1])
    out["signed_min"], out["signed_max"] = float(big.min()), float(big.max())
    out["max_abs"] = float(np.linalg.norm(e, axis=1).max())
    return out
