"""What each ingredient of notebook 05's fusion adds: an ablation on equal terms, over seeds,
with model mismatch as a second axis.

Rows (:data:`ROWS`): UWB-only LS, UWB-only EKF (notebook 03's :class:`~uwbwb.filters.ekf.TdoaEkf`,
random-force motion, no IMU), the paper's loose filter (eqs 5–7) and the tight filter, each with
and without a χ² gate of the same probability:

* **LS + gate**: the weighted residual sum of squares of each fix is tested against the
  ``gate_prob`` quantile of χ²(m − 2) (``m`` TDoAs, 2 coordinates) and a failing epoch is
  rejected (no fix). With four stations an epoch has one redundant TDoA: the test can detect
  a bad TDoA but not say which one, so it rejects the epoch; an epoch without redundancy
  (m = 2) cannot be tested and is kept.
* **EKF + gate**: the filter's own per-epoch gate (drops the anchor that lowers the NIS most;
  released after 10 gated epochs).
* **EKF (per-TDoA) + gate**: the same EKF with the tight filter's kind of gate — a χ²(1) test on
  each TDoA, released after 5 gated epochs (:class:`~uwbwb.filters.gating.ChiSquarePerMeasurement`)
  — so that the step EKF → tight changes the IMU only (:data:`LADDER`).
* **loose + gate**: its χ² gate on each epoch's UWB fix (position + velocity).
* **tight + gate**: its χ² gate on each TDoA.

Every row gets the same TDoAs (after the same eq-4 test), the same known tag height, the same
start (state, epoch) and is scored on the same epochs with coverage beside accuracy. The IMU rows
also get the magnetometer heading. **Tuning**: each filter has two knobs, tuned together — a
process-noise multiplier ``Q ×`` (the variance multiplier ``q_scale`` of the loose and the tight filter,
the random-force spectral density ``EKF_Q0 · Q ×`` of the EKF) and a measurement-noise multiplier ``R ×``
(``r_scale`` of the loose filter's position and velocity fixes and of the tight filter's TDoAs; the EKF's
TDoA variance) — chosen from the same grid of pairs (:attr:`AblationConfig.grid` × :attr:`AblationConfig.r_grid`)
by the lowest RMSE on a *tuning seed* that is never scored (static run + dynamic run outside the
outage and recovery); RMSEs within :data:`TIE_REL` of the lowest count as a tie, broken towards the
model's own noise ``(1, 1)`` (the pair nearest it in log scale), then the larger ``Q ×`` and ``R ×``. A pick on
the grid's edge
is flagged (:func:`choose_knobs`): its optimum may lie outside the grid. LS has no knob (no grid). The filters are tuned once on the matched world
and keep their knob in every mismatch case: a mismatch row tests the design on a world it was
not built for.

Scenarios per seed: a static run and a dynamic run (the paper's broken line) with a UWB outage
from :data:`~.study.OUTAGE_START_S`: only BS1 and BS2 heard, one TDoA per epoch. The dynamic
score leaves out the outage and the ``recovery_s`` after it; the outage is scored on its own
(max and RMSE), the recovery by its max error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
from scipy import stats

from ... import parallel
from ...filters.alignment import FusionSettings
from ...filters.ekf import TdoaEkf
from ...filters.gating import ChiSquarePerMeasurement
from ...models.imu import GRADES
from ...models.ins import quat_to_dcm
from ...models.motion import RandomForce
from ...models.tdoa import TdoaModel, triangle_outliers
from ...metrics import nis_consistency, pool_scores, rmse, score_epochs, seeds_interval
from ...sim import mismatch as mm
from ...sim import robot
from ...types import EstimateStatus, Estimates
from ...validate import integer, number, probability
from . import study
from .study import OUTAGE_START_S, fusion_filters, injected, start

__all__ = ["R_GRID", "FAST_R_GRID", "BASES", "ROWS", "EKF_TDOA_GATE", "EKF_TDOA_MAX_GATED", "gate_table", "METRICS", "COVERAGE", "LADDER", "EKF_Q0",
           "RECOVERY_S", "RECOVERY_MAX_M", "HOLD_S", "reacquisition_s", "AblationConfig", "AblationResult", "check_outage", "notebook_config",
           "legs_for_outage", "simulate", "ls_gate", "run_methods", "score_seed", "tune", "run_ablation", "ratio_ci",
           "choose_knobs", "TIE_REL", "FULL_GRID", "FAST_GRID"]

#: The four estimators, without and with the gate; the EKF also with the tight filter's per-TDoA gate.
BASES = ("LS", "EKF", "loose", "tight")
EKF_TDOA_GATE = "EKF (per-TDoA) + gate"
ROWS = tuple(x for b in BASES for x in (b, f"{b} + gate") + ((EKF_TDOA_GATE,) if b == "EKF" else ()))
#: Release rule of the EKF's per-TDoA gate: the tight filter's ``max_gated``.
EKF_TDOA_MAX_GATED = 5
#: Nominal random-force spectral density of the IMU-free EKF, m²/s³ (an assumption: ~0.3 m/s²
#: acceleration over ~1 s ramps); the tuning grid multiplies it.
EKF_Q0 = 0.1
#: Tuning RMSEs within this fraction of the lowest are a tie (broken towards the larger knob).
TIE_REL = 0.02
#: Process-noise multipliers of the full run: 0.01–100 in half-decade steps.
FULL_GRID = tuple(float(round(10 ** (k / 2), 4)) for k in range(-4, 5))
#: FAST grid: three decades only (a smoke test; edge knobs are flagged, not resolved).
FAST_GRID = (0.1, 1.0, 10.0)
#: Measurement-noise multipliers of the full run, tried with every process-noise multiplier: 0.3–100 (the
#: ungated filters' picks reached 10, the top of the earlier 0.3–10; their outliers inflate the best R well above the
#: model's, so the grid reaches a decade past it).
R_GRID = (0.3, 1.0, 3.0, 10.0, 30.0, 100.0)
#: FAST measurement-noise multipliers (those of :data:`uwbwb.scoreboard.estimators.INS_GRID_FAST`).
FAST_R_GRID = (1.0, 3.0)
#: Seconds after an outage scored as "recovery" (not as "dynamic"); also the re-acquisition deadline
#: (error below :data:`RECOVERY_MAX_M` within this, then held for :data:`HOLD_S`).
RECOVERY_S = 5.0
#: Error (m) a filter must get below, and stay below for :data:`HOLD_S` seconds, within :data:`RECOVERY_S` of UWB's
#: return after the outage to count as re-acquired (:func:`reacquisition_s`; matched world, every seed).
RECOVERY_MAX_M, HOLD_S = 0.5, 5.0
#: Scores per row and seed (m; coverage as a fraction of the scored epochs).
METRICS = ("static_rmse", "static_cov", "dyn_rmse", "dyn_cov", "outage_max", "outage_rmse", "outage_cov",
           "recovery_max", "recovery_cov", "reacq_s", "nis")
#: The coverage each accuracy metric is scored on (a row's own epochs: the share of the window's scored epochs it has).
COVERAGE = {"static_rmse": "static_cov", "dyn_rmse": "dyn_cov", "outage_max": "outage_cov", "recovery_max": "recovery_cov"}
_TUNED = tuple(r for r in ROWS if not r.startswith("LS"))


#: The outage of the notebook's default run, s (its parameter OUTAGE_S may ask for up to 18.7 s).
DEFAULT_OUTAGE_S = 5.0


@dataclass(frozen=True)
class AblationConfig:
    """Sizes and settings of the ablation (FAST: :meth:`fast`).

    Attributes
    ----------
    seeds
        Scoring seeds (``base_seed + 1 … + seeds``); the tuning seed is ``base_seed + 1000``.
    grid
        Process-noise multipliers (``Q ×``) tried for every tuned filter (same grid, same effort).
    r_grid
        Measurement-noise multipliers (``R ×``), each tried with every value of ``grid``.
    gate_prob
        χ² probability of every gate.
    outlier_c_m
        ``C`` of eq. 4 (every row gets the same screened TDoAs); None: no eq-4 test.
    static_s
        Length of the static run, s.
    legs
        Legs of the broken line driven in the dynamic run (1–5).
    outage_s
        Outage length in the dynamic run, s (from :data:`~.study.OUTAGE_START_S`).
    recovery_s
        Epochs this long after the outage are scored as "recovery", not as "dynamic".
    grade
        IMU grade of the filters' model (:data:`uwbwb.models.imu.GRADES`).
    cases
        Mismatch cases (names of :data:`uwbwb.sim.mismatch.CASES`); the first must be "matched".
    mismatch_seeds
        Scoring seeds per mismatch case (the first ``mismatch_seeds`` of ``seeds``).
    mismatch_static
        Whether mismatch cases also run the static scenario.
    loose_window
        Epochs of the loose filter's UWB velocity difference.
    outlier_rate
        Base multipath rate of the matched world (per station and epoch).
    """

    seeds: int = 10
    grid: tuple = FULL_GRID
    r_grid: tuple = R_GRID
    gate_prob: float = 0.999
    outlier_c_m: float | None = 0.1
    static_s: float = 60.0
    legs: int = 5
    outage_s: float = DEFAULT_OUTAGE_S
    recovery_s: float = RECOVERY_S
    grade: str = "consumer"
    cases: tuple = tuple(c.name for c in mm.CASES)
    mismatch_seeds: int = 10
    mismatch_static: bool = True
    loose_window: int = 5
    outlier_rate: float = 0.02

    def __post_init__(self):
        integer("seeds", self.seeds, minimum=1)
        integer("mismatch_seeds", self.mismatch_seeds, minimum=1)
        integer("legs", self.legs, minimum=1, maximum=len(robot.PAPER_WAYPOINTS_M) - 1)
        probability("gate_prob", self.gate_prob)
        number("static_s", self.static_s, minimum=1.0)
        number("recovery_s", self.recovery_s, minimum=0.0)
        number("outlier_rate", self.outlier_rate, minimum=0.0, maximum=1.0)
        for name, grid in (("grid", self.grid), ("r_grid", self.r_grid)):
            if len(grid) < 1 or not all(np.isfinite(g) and g > 0 for g in grid) or len(set(grid)) != len(grid):
                raise ValueError(f"{name} must hold distinct positive multipliers, got {grid!r}")
            if 1.0 not in grid:
                raise ValueError(f"{name} must hold 1.0 (the model's own noise, where the NIS check reads the "
                                 f"filters), got {grid!r}")
        if self.grade not in GRADES:
            raise ValueError(f"grade must be one of {list(GRADES)}, got {self.grade!r}")
        for c in self.cases:
            mm.case(c)
        if not self.cases or self.cases[0] != "matched":
            raise ValueError(f"cases must start with 'matched', got {self.cases!r}")
        check_outage(self.outage_s, self.recovery_s, robot.broken_line(robot.PAPER_WAYPOINTS_M[: self.legs + 1]),
                     name="outage_s")

    @classmethod
    def fast(cls, **kw) -> "AblationConfig":
        """FAST (smoke-test) sizes: 2 seeds, a 3 × 2 grid (:data:`FAST_GRID` × :data:`FAST_R_GRID`, not the full 9 × 6), a 10 s static run, 3 legs, and three
        mismatch cases (those the checks read: IMU 10×, UWB σ 2×, multipath up to 12 m) on 1 seed and
        the dynamic run only."""
        base = dict(seeds=2, grid=FAST_GRID, r_grid=FAST_R_GRID, static_s=10.0, legs=3, mismatch_seeds=1, mismatch_static=False,
                    cases=("matched", "IMU 10× worse", "UWB σ 2×", "multipath up to 12 m"))
        base.update(kw)
        return cls(**base)

    @property
    def model(self) -> robot.RobotConfig:
        """The filters' model (the matched world)."""
        return robot.RobotConfig(imu=GRADES[self.grade], outlier_rate=self.outlier_rate)


def check_outage(outage_s: float, recovery_s: float, motion: robot.RobotMotion, *, name: str = "OUTAGE_S") -> None:
    """Refuse an outage that cannot hold in ``motion``: it must start after the filters start and
    end, with ``recovery_s`` after it, before the run ends.

    Raises ``ValueError`` naming the parameter ``name``.
    """
    number(name, outage_s, minimum=0.0, strict_minimum=True)
    end = OUTAGE_START_S + outage_s + recovery_s
    if end > motion.duration_s:
        raise ValueError(f"{name} = {outage_s:g} s cannot hold: the outage starts at {OUTAGE_START_S:g} s and the "
                         f"run lasts {motion.duration_s:.1f} s, so with {recovery_s:g} s of recovery scored after it "
                         f"{name} must be at most {motion.duration_s - OUTAGE_START_S - recovery_s:.1f} s")


def notebook_config(*, fast: bool, seeds: int, outage_s: float, gate_prob: float, outlier_c_m: float | None,
                    grade: str, outlier_rate: float, loose_window: int, static_s: float) -> AblationConfig:
    """The ablation of notebook 05 for its parameters: full sizes, or :meth:`AblationConfig.fast`
    (whose dynamic run drives at least three legs, more if ``outage_s`` needs them)."""
    common = dict(outage_s=outage_s, gate_prob=gate_prob, outlier_c_m=outlier_c_m, grade=grade,
                  outlier_rate=outlier_rate, loose_window=loose_window)
    if fast:
        return AblationConfig.fast(legs=max(3, legs_for_outage(outage_s, after_s=RECOVERY_S)),
                                   static_s=min(static_s, 10.0), **common)
    return AblationConfig(seeds=seeds, mismatch_seeds=seeds, static_s=static_s, **common)


def legs_for_outage(outage_s: float, *, after_s: float = 1.0) -> int:
    """Fewest legs of the broken line whose run holds an outage of ``outage_s`` from
    :data:`~.study.OUTAGE_START_S` and ``after_s`` after it (ValueError naming ``OUTAGE_S`` if none)."""
    n = len(robot.PAPER_WAYPOINTS_M) - 1
    for legs in range(1, n + 1):
        if OUTAGE_START_S + outage_s + after_s <= robot.broken_line(robot.PAPER_WAYPOINTS_M[: legs + 1]).duration_s:
            return legs
    check_outage(outage_s, after_s, robot.broken_line(), name="OUTAGE_S")
    return n


def gate_table(cfg: AblationConfig) -> pd.DataFrame:
    """Kind and release rule (``max_gated``: consecutive gated epochs before the next is used
    ungated) of every gated row, read off the filters as :func:`run_methods` builds them."""
    m = cfg.model
    m2 = TdoaModel(np.asarray(m.stations_m, float), m.sigma_toa_m, dim=2, z_m=m.tag_height_m)
    ekf = TdoaEkf(RandomForce(EKF_Q0, dim=2), m2, gate_prob=cfg.gate_prob)
    ekf_t = TdoaEkf(RandomForce(EKF_Q0, dim=2), m2,
                    gate=ChiSquarePerMeasurement(cfg.gate_prob, max_gated=EKF_TDOA_MAX_GATED))
    tight, loose = fusion_filters(m, FusionSettings(cfg.outlier_c_m, cfg.gate_prob, loose_window=cfg.loose_window))
    rows = {"LS + gate": ("χ²(m − 2) on the fix's weighted residuals; the epoch is dropped", pd.NA),
            "EKF + gate": ("anchor dropping, χ²(m) per epoch", ekf.max_gated),
            EKF_TDOA_GATE: ("χ²(1) per TDoA", ekf_t.max_gated),
            "loose + gate": ("χ²(4) on the fix (position + velocity)", loose.max_gated),
            "tight + gate": ("χ²(1) per TDoA, engaged after heading alignment", tight.max_gated)}
    return pd.DataFrame({"gate": {r: v[0] for r, v in rows.items()},
                         "max_gated": pd.Series({r: v[1] for r, v in rows.items()}, dtype="Int64")})


def _masks(run: robot.RobotRun, k0: int, recovery_s: float) -> dict:
    T = len(run.truth)
    scored = np.arange(T) >= k0
    if not run.outage.any():
        return {"all": scored}
    t = run.truth.t_s
    t_end = t[run.outage][-1]
    rec = (t > t_end) & (t <= t_end + recovery_s)
    return {"all": scored & ~run.outage & ~rec, "outage": scored & run.outage, "recovery": scored & rec}


def reacquisition_s(t_s: np.ndarray, err_m: np.ndarray, t_end_s: float, limit_m: float = RECOVERY_MAX_M,
                    hold_s: float = HOLD_S) -> float:
    """Seconds from UWB's return after an outage until the error gets below ``limit_m`` and holds.

    UWB returns at the first epoch after ``t_end_s`` (the outage's last epoch); the filter has
    re-acquired at the first epoch from which the error stays below ``limit_m`` for ``hold_s``
    seconds, or to the end of the run if that comes first (a missing, non-finite error counts as
    not below). Returns 0 when it holds from the return, ``inf`` when no such stretch starts
    (never re-acquired), NaN when no epoch follows the outage. The drift UWB finds on its return
    is the outage's own score (``outage_max``) and a later excursion the dynamic score's: this is
    the time to re-acquire, neither the error at return nor what happens long after.

    Parameters
    ----------
    t_s, err_m
        Epoch times (s) and errors (m), shape ``(T,)``, scored epochs only.
    """
    t_s, err_m = np.asarray(t_s, float), np.asarray(err_m, float)
    after = t_s > t_end_s
    if not after.any():
        return np.nan
    t, e = t_s[after], err_m[after]
    ok = e < limit_m
    # stretches of consecutive epochs below the limit: [starts[i], ends[i]) in epoch indices
    edge = np.diff(np.r_[0, ok.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1)
    held = (t[ends - 1] - t[starts] >= hold_s) | (ends == t.size)
    if not held.any():
        return math.inf
    return float(t[starts[np.argmax(held)]] - t[0])


def simulate(scenario: str, world: robot.RobotConfig, cfg: AblationConfig, seed: int) -> robot.RobotRun:
    """The ``"static"`` or ``"dynamic"`` (with outage) run of scoring/tuning seed ``seed`` in ``world``
    (:func:`~.study.simulate` at ``cfg``'s sizes).

    The random stream depends on the seed and the scenario only, so the mismatch cases of one seed
    share their draws (paired comparisons across cases).
    """
    return study.simulate(scenario, world, rng=np.random.default_rng([seed, 0 if scenario == "static" else 1]),
                          static_s=cfg.static_s, legs=cfg.legs, outage_s=cfg.outage_s if scenario == "dynamic" else 0.0)


def ls_gate(fixes: Estimates, tdoa, model: TdoaModel, gate_prob: float) -> tuple[Estimates, int]:
    """LS fixes whose weighted residuals fail the χ²(m − dim) test at ``gate_prob`` removed.

    The residual sum ``eᵀΣ⁻¹e`` uses the model's reference-correlated covariance
    ``Σ = diag(σ_j²) + σ_ref² 11ᵀ`` (inverted by Sherman–Morrison). Epochs with ``m <= dim``
    TDoAs have no redundancy and are kept untested. Returns the gated fixes (status
    ``NO_ESTIMATE`` where rejected) and the number of rejected epochs.
    """
    ok = fixes.has_estimate
    T, n = tdoa.tdoa_m.shape
    pos = np.where(ok[:, None], fixes.pos_m, 0.0)
    ref = np.clip(tdoa.ref, 0, None)
    e = tdoa.tdoa_m - model.h(pos, ref)
    meas = np.isfinite(e)
    meas[np.arange(T), ref] = False
    e = np.where(meas, e, 0.0)
    w = np.where(meas, 1.0 / model.sigma_m ** 2, 0.0)
    s1, s2 = (w * e * e).sum(axis=1), (w * e).sum(axis=1)
    wssr = s1 - s2 ** 2 / (1.0 / model.sigma_m[ref] ** 2 + w.sum(axis=1))
    dof = meas.sum(axis=1) - model.dim
    thr = np.full(T, np.inf)
    thr[dof >= 1] = stats.chi2.ppf(gate_prob, dof[dof >= 1])
    bad = ok & (tdoa.ref >= 0) & (wssr > thr)
    status = np.where(bad, EstimateStatus.NO_ESTIMATE, fixes.status).astype(np.int8)
    p = np.where(bad[:, None], np.nan, fixes.pos_m)
    cov = None if fixes.pos_cov_m2 is None else np.where(bad[:, None, None], np.nan, fixes.pos_cov_m2)
    return Estimates(fixes.t_s, p, status, fixes.name + " + gate", cov), int(bad.sum())


def run_methods(run: robot.RobotRun, model: robot.RobotConfig, knobs: Mapping[str, tuple[float, float]],
                cfg: AblationConfig, rows: Sequence[str] = ROWS, *,
                started: study.Start | None = None) -> tuple[dict, int, dict]:
    """Every row of ``rows`` on one run, with the filters' ``model`` (not the run's world) and each tuned row's
    ``knobs[row] = (Q ×, R ×)``, all from :func:`~.study.start`; the loose and tight rows are the filters of
    :func:`~.study.fusion_filters` (notebook 05's cell) at that pair and gate.

    Returns ``(positions, k0, counts)``: row → horizontal tag position ``(T, 2)`` (NaN where the
    row has no estimate), the first scored epoch, and counts (``eq4`` TDoAs removed by eq. 4,
    ``injected`` multipath TDoAs, ``gated`` per row, ``nis``: the filters' mean NIS per degree of
    freedom over the scored epochs before the outage — the filters' noise model in normal operation, which the
    NIS check reads; whether a filter re-acquires after the outage is the re-acquisition check's (a filter
    that never does would otherwise fail the NIS check too, naming no parameter) —, NaN for LS).
    ``started``: :func:`~.study.start` of ``run`` and ``model`` at ``cfg.outlier_c_m`` when the caller already has it
    (the tuning runs every row and pair on the same two runs).
    """
    s = start(run, model, cfg.outlier_c_m) if started is None else started
    k0 = s.k0
    tag0 = s.x0.pos_m + quat_to_dcm(s.x0.quat) @ np.asarray(model.lever_arm_m, float)
    keep = _masks(run, k0, cfg.recovery_s)["all"]              # scored epochs, and only those before an outage:
    if run.outage.any():                                       # after it, re-acquisition is check 6's to judge
        keep &= run.truth.t_s < run.truth.t_s[run.outage][0]
    gate = cfg.gate_prob
    out, gated, nis = {}, {}, {}
    for row in rows:
        g = gate if row.endswith("+ gate") else None
        base = row.split(" ")[0]
        q, r = knobs[row] if base != "LS" else (1.0, 1.0)
        if base == "LS":
            est, gated[row] = ls_gate(s.fixes, s.screened, s.tdoa2, gate) if g else (s.fixes, 0)
            pos = est.pos_m
        elif base == "EKF":
            m2r = replace(s.tdoa2, sigma_m=s.tdoa2.sigma_m * math.sqrt(r))
            if row == EKF_TDOA_GATE:
                ekf = TdoaEkf(RandomForce(EKF_Q0 * q, dim=2), m2r,
                              gate=ChiSquarePerMeasurement(g, max_gated=EKF_TDOA_MAX_GATED))
            else:
                ekf = TdoaEkf(RandomForce(EKF_Q0 * q, dim=2), m2r, gate_prob=g)
            kr = ekf.run(s.screened.select(slice(k0, None)), x0=ekf.init(tag0[:2]))
            pos = np.full((len(run.truth), 2), np.nan)
            pos[k0:] = np.where(kr.started[:, None], kr.pos_m, np.nan)
            gated[row] = 0 if kr.n_rejected is None else int(kr.n_rejected.sum())
            up = (kr.status == EstimateStatus.UPDATED) & keep[k0:]
            nis[row] = nis_consistency(kr.nis[up], kr.dof[up])["mean_nis_over_dof"]
        elif base in ("loose", "tight"):
            tight, loose = fusion_filters(model, FusionSettings(cfg.outlier_c_m, g, q, r, loose_window=cfg.loose_window))
            fr = (tight.run(s.imu, run.tdoa, s.x0, heading=run.heading, fix_tag=s.snapshot) if base == "tight"
                  else loose.run(s.imu, s.fixes, s.x0, heading=run.heading))
            pos = fr.to_estimates(dim=2).pos_m
            gated[row] = int(fr.n_gated.sum())
            nis[row] = nis_consistency(fr.nis[keep], fr.dof[keep])["mean_nis_over_dof"]
        else:
            raise ValueError(f"unknown row {row!r}; known: {ROWS}")
        pos = np.array(pos, float)
        pos[:k0] = np.nan
        out[row] = pos
    bad = injected(run)
    counts = {"eq4": int(s.n_eq4.sum()), "injected": int(bad.sum()), "gated": gated, "nis": nis,
              "eq4_on_injected": int((triangle_outliers(run.tdoa.tdoa_m, run.tdoa.ref, s.tdoa2.anchor_pos_m,
                                                        cfg.outlier_c_m) & bad).sum())
              if cfg.outlier_c_m is not None else 0}
    return out, k0, counts


def score_seed(case: str, seed: int, knobs: Mapping[str, tuple[float, float]], cfg: AblationConfig,
               rows: Sequence[str] = ROWS, scenarios: Sequence[str] = ("static", "dynamic")) -> dict:
    """Scores (:data:`METRICS`) of every row on the runs of one (mismatch case, seed).

    Returns ``{"scores": {row: {metric: value}}, "counts": {scenario: counts}}``.
    """
    model = cfg.model
    world = mm.case(case).world(model)
    scores = {r: {m: np.nan for m in METRICS} for r in rows}
    counts, pairs = {}, {}
    for scen in scenarios:
        run = simulate(scen, world, cfg, seed)
        pos, k0, counts[scen] = run_methods(run, model, knobs, cfg, rows)
        masks = _masks(run, k0, cfg.recovery_s)
        truth = run.truth.pos_m[:, :2]
        err = {r: np.linalg.norm(pos[r] - truth, axis=1) for r in pos}      # NaN where the row has no estimate
        for what, a, b in LADDER:
            if a in pos and b in pos:
                p = pairs.setdefault(what, {})
                for key, sel, stat in (("static_rmse" if scen == "static" else "dyn_rmse", masks["all"], rmse),
                                       ("outage_max", masks.get("outage"), np.max)):
                    if sel is None:
                        continue
                    both = score_epochs({a: err[a], b: err[b]}, sel).table(common={key: stat})
                    p[key] = (both.loc[a, key], both.loc[b, key], float(both.loc[a, "n_common"] / max(sel.sum(), 1)))
        for r in rows:
            own = {k: score_epochs({r: err[r]}, m)[r] for k, m in masks.items()}
            rmse_m, cov = own["all"].stats(own={"": rmse})[""], own["all"].coverage
            s = scores[r]
            if scen == "static":
                s["static_rmse"], s["static_cov"] = rmse_m, cov
            else:
                s["dyn_rmse"], s["dyn_cov"] = rmse_m, cov
                o = own["outage"].stats(own={"rmse": rmse, "max": np.max})
                s["outage_rmse"], s["outage_max"], s["outage_cov"] = o["rmse"], o["max"], own["outage"].coverage
                s["recovery_max"] = own["recovery"].stats(own={"max": np.max})["max"]
                s["recovery_cov"] = own["recovery"].coverage
                if run.outage.any():
                    s["reacq_s"] = reacquisition_s(run.truth.t_s[k0:], err[r][k0:], float(run.truth.t_s[run.outage][-1]))
                s["nis"] = counts[scen]["nis"].get(r, np.nan)
    return {"scores": scores, "counts": counts, "pairs": pairs}


def _tune_task(*, row: str, knob: tuple[float, float], cfg: AblationConfig,
               runs: Mapping[str, tuple[robot.RobotRun, study.Start]]) -> tuple[float, float]:
    """RMSE over the tuning seed's scored epochs (no outage, no recovery), and the row's mean NIS per dof on its
    dynamic run (NaN for rows without one); ``runs``: scenario → (run, its start), the same for every task."""
    parts, nis = [], np.nan
    for scen, (run, s) in runs.items():
        pos, k0, counts = run_methods(run, cfg.model, {row: knob}, cfg, (row,), started=s)
        parts.append(score_epochs({row: np.linalg.norm(pos[row] - run.truth.pos_m[:, :2], axis=1)},
                                  _masks(run, k0, cfg.recovery_s)["all"]))
        if scen == "dynamic":
            nis = float(counts["nis"].get(row, np.nan))
    pooled = pool_scores(parts)[row]
    return (rmse(pooled.own_m) if pooled.n_scored else np.inf), nis


def tune(cfg: AblationConfig, *, tuning_seed: int, scheduler=None,
         workers: int = 1) -> tuple[pd.DataFrame, pd.DataFrame]:
    """RMSE on the tuning seed for every tuned row × ``(Q ×, R ×)`` pair (rows: rows; columns: the pairs, a
    two-level index ``Q ×``, ``R ×``), and the mean NIS per dof of the same runs' dynamic part (same shape).

    The tuning seed's static and dynamic runs and their start (eq. 4, LS fixes) are computed once and shared by
    every task. The pair of each row is chosen by :func:`choose_knobs`.
    """
    runs = {}
    for scen in ("static", "dynamic"):
        run = simulate(scen, cfg.model, cfg, tuning_seed)
        runs[scen] = (run, start(run, cfg.model, cfg.outlier_c_m))
    pairs = [(float(q), float(r)) for q in cfg.grid for r in cfg.r_grid]
    tasks = [parallel.Task({"row": row, "knob": pair}) for row in _TUNED for pair in pairs]
    res = {(t.params["row"], t.params["knob"]): v for t, v in parallel.imap(
        _tune_task, tasks, shared={"cfg": cfg, "runs": runs}, scheduler=scheduler,
        workers=workers, desc="ablation tuning", unit="run")}
    tables = []
    for i in (0, 1):
        t = pd.DataFrame({pair: {row: res[(row, pair)][i] for row in _TUNED} for pair in pairs})
        t.columns = pd.MultiIndex.from_tuples(pairs, names=["Q ×", "R ×"])
        tables.append(t)
    return tables[0], tables[1]


def choose_knobs(tuning: pd.DataFrame, *, tie_rel: float = TIE_REL) -> pd.DataFrame:
    """The ``(Q ×, R ×)`` pair per tuned row from its tuning RMSEs (:func:`tune`'s table).

    The pick is, among the pairs whose RMSE is within ``tie_rel`` of the row's lowest, the one nearest the model's
    own noise ``(1, 1)`` (sum of ``|log10 Q ×| + |log10 R ×|``), then the one with the larger ``Q ×``, then ``R ×``
    (a near-tie goes to the model as built, not to a filter made pessimistic by the grid). Returns per row
    ``Q ×``, ``R ×``, ``rmse`` (m), ``edge`` ("Q", "R", "Q, R" where the pick lies on that knob's grid edge —
    the optimum may lie outside —, "—" otherwise) and ``blowups``: the pairs whose RMSE exceeds 10× the row's
    lowest (a filter that fails there, not a tuning trade-off).
    """
    pairs = [tuple(float(x) for x in c) for c in tuning.columns]
    qs, rs = sorted({q for q, _ in pairs}), sorted({r for _, r in pairs})
    out = {}
    for row in tuning.index:
        v = tuning.loc[row].to_numpy(float)
        best = np.nanmin(v)
        ok = np.flatnonzero(v <= best * (1 + tie_rel))
        q, r = min((pairs[k] for k in ok), key=lambda p: (abs(np.log10(p[0])) + abs(np.log10(p[1])), -p[0], -p[1]))
        edges = [name for name, x, xs in (("Q", q, qs), ("R", r, rs)) if len(xs) > 1 and x in (xs[0], xs[-1])]
        out[row] = {"Q ×": q, "R ×": r, "rmse": float(v[pairs.index((q, r))]), "edge": ", ".join(edges) or "—",
                    "blowups": tuple(p for p, x in zip(pairs, v) if not x <= 10 * best)}
    return pd.DataFrame(out).T


def _score_task(*, case, run_seed, knobs, cfg, rows, scenarios):
    return score_seed(case, run_seed, knobs, cfg, rows, scenarios)


@dataclass(frozen=True)
class AblationResult:
    """Scores of the ablation.

    Attributes
    ----------
    config
        The :class:`AblationConfig` used.
    fast
        True for a FAST (smoke-test) run.
    tuning
        RMSE on the tuning seed per tuned row × ``(Q ×, R ×)`` pair (m; :func:`tune`).
    knobs
        Row → chosen ``(Q ×, R ×)`` (:func:`choose_knobs`).
    scores
        Long table: one row per (case, seed, method) with the :data:`METRICS`.
    counts
        ``{case: {"eq4": .., "injected": .., "eq4_on_injected": ..}}`` summed over seeds and scenarios.
    pairs
        Long table of the :data:`LADDER` steps scored on the epochs *both* rows cover: one row per
        (case, seed, step, metric) with ``num``, ``den`` (the without / with row's score there) and
        ``both_cov`` (share of the scored epochs both rows cover). Empty: ratios fall back to the
        per-row scores.
    tuning_nis
        Mean NIS per dof of the tuning runs (dynamic part), same shape as ``tuning``: at ``(1, 1)`` it is the
        filter's consistency with the model's own noise, which the NIS check reads (a tuned ``R ×`` above 1
        makes a filter deliberately pessimistic, and its NIS small, by design).
    """

    config: AblationConfig
    fast: bool
    tuning: pd.DataFrame
    knobs: dict
    scores: pd.DataFrame
    counts: dict = field(default_factory=dict)
    pairs: pd.DataFrame = field(default_factory=pd.DataFrame)
    tuning_nis: pd.DataFrame = field(default_factory=pd.DataFrame)

    def case(self, name: str = "matched") -> pd.DataFrame:
        """Scores of one case, indexed by (seed, method)."""
        return self.scores[self.scores["case"] == name].set_index(["seed", "method"]).drop(columns="case")

    def table(self, name: str = "matched") -> pd.DataFrame:
        """Mean over seeds of every metric per method (rows in :data:`ROWS` order), with the seed count."""
        c = self.case(name)
        t = c.groupby(level="method").mean()
        order = [r for r in ROWS if r in t.index]
        t = t.loc[order]
        t["seeds"] = c.groupby(level="method").size().loc[order]
        return t

    def ratio(self, num: str, den: str, metric: str, case: str = "matched", prob: float = 0.95,
              seeds=None) -> dict:
        """:func:`ratio_ci` of ``num / den`` on ``metric`` over the case's seeds (paired; only
        ``seeds`` if given)."""
        c = self.case(case)[metric].unstack("method")
        if seeds is not None:
            c = c.loc[c.index.intersection(pd.Index(seeds))]
        return ratio_ci(c[num].to_numpy(), c[den].to_numpy(), prob=prob)


#: The ingredient ladder: (what it measures, without, with).
LADDER = (
    ("outlier handling (gate), LS", "LS", "LS + gate"),
    ("outlier handling (gate), EKF", "EKF", "EKF + gate"),
    ("outlier handling (gate), loose", "loose", "loose + gate"),
    ("outlier handling (gate), tight", "tight", "tight + gate"),
    ("temporal filtering (LS → EKF, gated)", "LS + gate", "EKF + gate"),
    ("gate kind, EKF (anchor dropping, release 10 → per-TDoA χ², release 5)", "EKF + gate", EKF_TDOA_GATE),
    ("IMU, loosely (EKF → loose, gated; gates differ)", "EKF + gate", "loose + gate"),
    ("IMU, tightly (EKF → tight, both per-TDoA χ², release 5)", EKF_TDOA_GATE, "tight + gate"),
    ("tight vs loose (gated)", "loose + gate", "tight + gate"),
)


def ratio_ci(a, b, *, prob: float = 0.95) -> dict:
    """Geometric-mean ratio ``a / b`` over paired seeds with a Student-t interval on the log ratios.

    Returns ``{"ratio", "lo", "hi", "n"}``; with fewer than two finite pairs the interval is NaN.
    A ratio > 1 means ``b`` has the smaller error (the ingredient helps).
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b) & (a > 0) & (b > 0)
    t = seeds_interval(np.log(a[ok] / b[ok]), prob=prob)          # on the log ratios
    return {"ratio": math.exp(t["mean"]) if t["n"] else np.nan, "lo": math.exp(t["lo"]), "hi": math.exp(t["hi"]),
            "n": t["n"]}


def run_ablation(cfg: AblationConfig, *, base_seed: int = 0, fast: bool = False, scheduler=None,
                 workers: int = 1) -> AblationResult:
    """Tune every filter on the tuning seed, then score every row on every seed and mismatch case.

    Cases other than "matched" run the gated rows and LS (``mismatch_seeds`` seeds; the static run
    only if ``mismatch_static``). Work is sent through :func:`uwbwb.parallel.imap` (``scheduler``,
    ``workers``); results do not depend on how it runs.
    """
    tuning, tuning_nis = tune(cfg, tuning_seed=base_seed + 1000, scheduler=scheduler, workers=workers)
    picked = choose_knobs(tuning)
    knobs = {row: (float(p["Q ×"]), float(p["R ×"])) for row, p in picked.iterrows()}
    mis_rows = ("LS",) + tuple(r for r in ROWS if r.endswith("+ gate"))
    tasks = []
    for case in cfg.cases:
        matched = case == "matched"
        n = cfg.seeds if matched else min(cfg.mismatch_seeds, cfg.seeds)
        scen = ("static", "dynamic") if matched or cfg.mismatch_static else ("dynamic",)
        for k in range(n):
            tasks.append(parallel.Task({"case": case, "run_seed": base_seed + 1 + k,
                                        "rows": ROWS if matched else mis_rows, "scenarios": scen}))
    recs, counts, prs = [], {}, []
    for task, out in parallel.imap(_score_task, tasks, shared={"knobs": knobs, "cfg": cfg},
                                   scheduler=scheduler, workers=workers, desc="ablation", unit="seed"):
        case, seed = task.params["case"], task.params["run_seed"]
        for r, s in out["scores"].items():
            recs.append({"case": case, "seed": seed, "method": r, **s})
        for step, p in out["pairs"].items():
            for metric, (num, den, both) in p.items():
                prs.append({"case": case, "seed": seed, "step": step, "metric": metric, "num": num, "den": den,
                            "both_cov": both})
        c = counts.setdefault(case, {"eq4": 0, "injected": 0, "eq4_on_injected": 0})
        for sc in out["counts"].values():
            for k in c:
                c[k] += sc[k]
    return AblationResult(cfg, fast, tuning, knobs, pd.DataFrame(recs), counts, pd.DataFrame(prs), tuning_nis)

