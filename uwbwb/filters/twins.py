"""The declared twins: every compiled (numba) or hand-vectorised kernel of the package beside the
readable Python definition it must equal.

A fast kernel is only as trustworthy as the comparison that holds it to its definition. Each
:class:`Twin` names the kernel, says how to run the fast implementation and the definition on the
same input, builds that input (small, deterministic: fixed seeds, no files), and gives the
tolerance per output: :data:`BIT` (bit for bit) where the two compute the same floating-point
operations in the same order on every machine, otherwise a stated tolerance: the one the kernel's own
exactness test has always used (``held_by`` names that test; nothing here is looser), or a few units in
the last place of the output's largest element where the two sum the same products in another order
(a BLAS kernel against the compiled loop: which order the BLAS takes depends on the CPU). ``covers`` lists the compiled
functions the comparison runs, so a test can say which compiled kernel has no twin yet.

``tests/test_kernel_twins.py`` runs every entry of :data:`TWINS`. To add a kernel: write its
definition (the plain loop or the model functions it must equal), add one ``Twin(...)`` to
:func:`_registry`, and run that test.

The registry sits in ``filters/`` because it is the lowest layer that sees every kernel's unit
(the rotation primitives and block-written transition of ``models/ins.py``, the batched
multilateration of ``geometry/``, the Doppler sampler of ``sampling.py`` and the filters' own
kernels); it is imported by the tests and by :func:`compile_kernels` (which ``make`` runs once at install
time), never by ``import uwbwb``.
"""

from __future__ import annotations

import copy
import itertools
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, NamedTuple

import numpy as np

from .. import geometry, metrics, sampling
from ..calibration import twr
from ..models import doppler as doppler_model
from ..models import ins
from ..models.imu import GRADES
from ..models.motion import RandomForce, RandomJerk, RandomWalk, ReceiverMotion, VelocityKick
from ..models.setnoise import SetNoiseModel
from ..models.tdoa import TdoaModel
from ..models.track import LinearTrackRanges
from ..sim import chirps, robot, walk
from ..types import Estimates, EstimateStatus, RangeLog, TdoaLog, pseudo_tdoa
from . import kalman, particle, pruning
from .doppler import DopplerPf, ScaatMhEkf, assign_chirps, clock_pseudo_ranges
from .doppler.pf import _moments
from .ekf import Ekf, Linearisation, RangeMeasurement, TdoaEkf, TdoaMeasurement
from .ekf import kernels as ekf_kernels
from .eskf import LooseFilter, TdoaUpdate, TightEskf, _tag_jacobian
from .eskf import kernels as eskf_kernels
from .gating import AnchorDropping, ChiSquareEpoch, ChiSquarePerMeasurement, NoGate, Robust
from .setnoise import kf_sweep, pf_sweep, reference_pf
from .setnoise.pf import _sweep_block, _sweep_block_compiled
from .tdoa_ls import tdoa_least_squares

__all__ = ["BIT", "Tol", "Twin", "TWINS", "compile_kernels", "setnoise_case"]


class Tol(NamedTuple):
    """``|fast − definition| <= atol + rtol·|definition| + ulps·ε·max|definition|`` elementwise (NaN
    only where the other is NaN; ε the spacing at 1 of the definition's float type: 2⁻⁵² for float64,
    2⁻²³ for float32). ``ulps`` is the normwise part: units in the last place of the output's largest
    element, the scale of a rounding difference in a sum of products taken in another order."""

    rtol: float = 0.0
    atol: float = 0.0
    ulps: int = 0

    @property
    def bit_identical(self) -> bool:
        return self.rtol == 0.0 and self.atol == 0.0 and self.ulps == 0

    def atol_for(self, definition: np.ndarray) -> float:
        """The absolute part of the bound for this output: ``atol + ulps·ε·max|definition|``."""
        finite = np.abs(definition[np.isfinite(definition)]) if definition.size else np.zeros(0)
        scale = float(finite.max()) if finite.size else 0.0
        eps = np.finfo(definition.dtype if definition.dtype.kind == "f" else float).eps
        return self.atol + self.ulps * eps * scale


#: Bit for bit: same values, same NaN positions.
BIT = Tol()


@dataclass(frozen=True)
class Twin:
    """A fast kernel and the Python definition it must equal.

    Attributes
    ----------
    name
        ``<where>.<kernel>`` with the case in brackets when one kernel has several entries.
    fast, definition
        ``f(inputs) -> {output: array}``; both return the same outputs.
    inputs
        ``() -> inputs``: small and deterministic. Each side gets its own deep copy (kernels that
        work in place or draw from a generator cannot disturb the other side).
    tolerance
        ``{output: Tol}``, one per output.
    held_by
        The existing test that holds this kernel (directly, or as a step of the loop it belongs to);
        an output that is not bit for bit today keeps that test's tolerance.
    covers
        Qualified names of the compiled functions the fast side runs.
    exercised
        ``f(definition outputs) -> str | None``: why the comparison would be vacuous (e.g. no
        resampling happened), or None when it exercises what it is meant to.
    """

    name: str
    fast: Callable[[Any], Mapping[str, np.ndarray]]
    definition: Callable[[Any], Mapping[str, np.ndarray]]
    inputs: Callable[[], Any]
    tolerance: Mapping[str, Tol]
    held_by: str
    covers: tuple[str, ...] = ()
    exercised: Callable[[Mapping[str, np.ndarray]], str | None] = field(default=lambda out: None)

    def outputs(self) -> tuple[dict, dict]:
        """``(fast outputs, definition outputs)`` on one build of the inputs."""
        args = self.inputs()
        return dict(self.fast(copy.deepcopy(args))), dict(self.definition(copy.deepcopy(args)))

    def mismatches(self, fast: Mapping | None = None, definition: Mapping | None = None) -> list[str]:
        """What differs beyond the tolerance (empty: the twins agree); runs both sides unless given."""
        if fast is None or definition is None:
            fast, definition = self.outputs()
        out = []
        if set(fast) != set(definition) or set(fast) != set(self.tolerance):
            return [f"{self.name}: outputs {sorted(fast)} (fast), {sorted(definition)} (definition), "
                    f"tolerances for {sorted(self.tolerance)}"]
        for key, tol in self.tolerance.items():
            a, b = np.asarray(fast[key]), np.asarray(definition[key])
            if a.shape != b.shape:
                out.append(f"{self.name}: {key} has shape {a.shape} (fast), {b.shape} (definition)")
                continue
            try:
                if tol.bit_identical:
                    np.testing.assert_array_equal(a, b, strict=True)
                else:
                    np.testing.assert_allclose(a, b, rtol=tol.rtol, atol=tol.atol_for(b))
            except AssertionError as exc:
                out.append(f"{self.name}: {key} differs beyond {tol}:{exc}")
        why = self.exercised(definition)
        if why:
            out.append(f"{self.name}: the comparison is vacuous: {why}")
        return out


# ============================================================================ definitions

def _run_outputs(res, floats, ints) -> dict:
    return {**{f: getattr(res, f) for f in floats}, **{f: getattr(res, f) for f in ints}}


# ---------------------------------------------------------------- the tight ESKF
_FUSION_FLOATS = ("pos_m", "vel_mps", "quat", "acc_bias_mps2", "gyro_bias_radps", "P", "pos_cov_m2", "nis")
_FUSION_INTS = ("dof", "n_outliers", "n_gated", "status")


def _tight_inputs():
    """The closed-loop TDoA case of tests/filters/test_eskf.py: two legs with a turn, 10 % multipath,
    20 % missing TDoAs, heading, non-zero initial biases."""
    cfg = robot.RobotConfig(outlier_rate=0.1, outlier_excess_m=(0.3, 3.0), p_missing=0.2)
    run = robot.simulate(robot.broken_line(((2.0, 1.0), (3.2, 1.0), (3.2, 1.9)), turn_s=1.5, pause_s=0.5), cfg,
                         rng=np.random.default_rng(11))
    filt = TightEskf(uwb=TdoaUpdate(cfg.tdoa_model(sigma_m=max(cfg.sigma_toa_m, 0.01)), 0.1),
                     lever_arm_m=cfg.lever_arm_m, height_m=cfg.tag_height_m, imu_model=GRADES["consumer"])
    kw = dict(heading=run.heading, acc_bias0=np.array([0.02, -0.01, 0.03]), gyro_bias0=np.array([1e-3, -2e-3, 5e-4]))
    return filt, run.imu, run.tdoa, run.x0, kw


def _fusion_fast(a):
    filt, imu, uwb, x0, kw = a
    return _run_outputs(filt.run(imu, uwb, x0, **kw), _FUSION_FLOATS, _FUSION_INTS)


def _fusion_definition(a):
    filt, imu, uwb, x0, kw = a
    return _run_outputs(filt.run_reference(imu, uwb, x0, **kw), _FUSION_FLOATS, _FUSION_INTS)


def _tight_exercised(out):
    if not np.any(out["status"] == 1) or not np.any(out["n_outliers"] + out["n_gated"] > 0):
        return "no epoch updated, or none screened or gated"
    return None


# ---------------------------------------------------------------- the loose filter
def _loose_inputs():
    """A case of tests/filters/test_eskf.py's loose twin test: the short run with 10 % multipath and a 2 s UWB
    outage after which the epoch gate shuts and the lock is admitted lost, a 1 s IMU gap (coasting), heading."""
    cfg = robot.RobotConfig(outlier_rate=0.1, outlier_excess_m=(0.3, 3.0), outage_start_s=4.0, outage_s=2.0)
    run = robot.simulate(robot.broken_line(((2.0, 1.0), (3.2, 1.0), (3.2, 1.9)), turn_s=1.5, pause_s=0.5), cfg,
                         rng=np.random.default_rng(4))
    ls = tdoa_least_squares(run.tdoa, TdoaModel(np.asarray(cfg.stations_m), 0.01, dim=2, z_m=cfg.tag_height_m))
    fixes = Estimates(ls.t_s, np.where(ls.ok[:, None], ls.pos_m, np.nan),
                      np.where(ls.ok, EstimateStatus.UPDATED, EstimateStatus.NO_ESTIMATE).astype(np.int8), "UWB")
    filt = LooseFilter(height_m=cfg.tag_height_m, lever_arm_m=cfg.lever_arm_m, gate=ChiSquareEpoch(0.99, max_gated=3))
    imu = run.imu.select((run.imu.t_s <= 7.0) | (run.imu.t_s >= 8.0))
    return filt, imu, fixes, run.x0, dict(heading=run.heading)


def _loose_exercised(out):
    st = out["status"]
    if not np.any(st == EstimateStatus.GATED) or not np.any(out["dof"] == 4):
        return "no gated epoch, or no update with the differenced velocity"
    return None


# ---------------------------------------------------------------- rotation and reset primitives
def _rotation_inputs():
    """Rotation vectors of three sizes (series branch, small, large), unit quaternions, covariances."""
    rng = np.random.default_rng(3)
    cases = []
    for scale in (1e-9, 1e-3, 0.5):
        q = rng.standard_normal(4)
        cases.append((scale * rng.standard_normal(3), q / np.linalg.norm(q), np.cov(rng.standard_normal((15, 40)))))
    return cases


def _per_case(fn):
    def run(cases):
        outs = [fn(*c) for c in cases]
        return {k: np.stack([o[k] for o in outs]) for k in outs[0]}
    return run


def _exp_left_fast(rv, q, P):
    q2 = q.copy()
    ins._exp_left_nb(rv, q2)
    return {"quat": q2}


def _reset_block_fast(rv, q, P):
    return {"G_theta": eskf_kernels._reset_block(rv)}


def _reset_cov_fast(rv, q, P):
    P2 = P.copy()
    eskf_kernels._reset_covariance(P2, ins.reset_jacobian(rv)[6:9, 6:9])
    return {"P": P2}


def _reset_cov_definition(rv, q, P):
    G = ins.reset_jacobian(rv)
    return {"P": G @ P @ G.T}


def _skew_fast(rv, q, P):
    S = np.empty((3, 3))
    eskf_kernels._skew_into(rv, S)
    return {"S": S}


def _dcm_fast(rv, q, P):
    C = np.empty((3, 3))
    ins._dcm_nb(q, C)
    return {"C": C}


def _rows_inputs():
    """A TDoA epoch with one missing anchor, lever arm and attitude (tests/filters/test_eskf.py)."""
    anchors = np.array([[0, 0, 2.4], [7, 0, 2.2], [7, 5, 2.4], [0, 5, 2.2]], float)
    lever, C = np.array([0.1, -0.05, 0.2]), ins.dcm_from_euler(0.05, -0.1, 0.8)
    upd = TdoaUpdate(TdoaModel(anchors, [0.05, 0.1, 0.07, 0.2], dim=3), None)
    return upd, np.array([3.0, 2.0, 0.3]), lever, C, np.array([0.5, 0.0, np.nan, -0.3]), 1


def _rows_fast(a):
    upd, p, lever, C, row, ref = a
    tag = p + C @ lever
    S = np.empty((3, 3))
    eskf_kernels._skew_into(C @ lever, S)
    u = upd.model.unit_vectors(tag)
    used = [j for j in range(row.size) if j != ref and np.isfinite(row[j])]
    H = np.empty((len(used), 15))
    for i, j in enumerate(used):
        eskf_kernels._fill_row(H, i, u[j] - u[ref], S)
    return {"H": H}


def _rows_definition(a):
    upd, p, lever, C, row, ref = a
    return {"H": upd.linearise(p + C @ lever, _tag_jacobian(C, lever), row, ref).H}


# ---------------------------------------------------------------- strapdown propagation
def _imu_inputs():
    """50 IMU samples at ~100 Hz (jittered) of a turning, accelerating body, with biases."""
    rng = np.random.default_rng(5)
    n = 50
    t = np.cumsum(np.r_[0.0, rng.uniform(0.009, 0.011, n - 1)])
    acc = np.array([0.3, -0.2, 9.81]) + 0.2 * rng.standard_normal((n, 3))
    gyro = np.array([0.01, -0.02, 0.4]) + 0.05 * rng.standard_normal((n, 3))
    q = ins.dcm_to_quat(ins.dcm_from_euler(0.02, -0.03, 0.7))
    qrate = np.r_[np.zeros(3), np.full(3, 1e-3), np.full(3, 1e-5), np.full(3, 1e-6), np.full(3, 1e-8)]
    return dict(pos=np.array([1.0, 2.0, 0.3]), vel=np.array([0.4, -0.1, 0.0]), quat=q,
                b_a=np.array([0.02, -0.01, 0.03]), b_g=np.array([1e-3, -2e-3, 5e-4]), t=t, acc=acc, gyro=gyro,
                qrate=qrate, Phi=np.eye(15), Qacc=np.diag(np.full(15, 1e-4)), acc_var=0.25, rate_var=0.01)


def _propagate_fast(a):
    g_n = ins.Mechanization().g_n
    ins.propagate(a["pos"], a["vel"], a["quat"], a["b_a"], a["b_g"], a["t"], a["acc"], a["gyro"], 0, a["t"].size - 1,
                  g_n, a["qrate"], a["Phi"], a["Qacc"])
    return {k: a[k] for k in ("pos", "vel", "quat", "Phi", "Qacc")}


def _propagate_definition(a):
    """:meth:`Mechanization.step` and :func:`error_transition` per IMU step, ``Phi ← F Phi``,
    ``Qacc ← F Qacc Fᵀ + diag(qrate) Δt``."""
    mech = ins.Mechanization()
    p, v, q, Phi, Qacc = a["pos"], a["vel"], a["quat"], a["Phi"], a["Qacc"]
    f, w = a["acc"] - a["b_a"], a["gyro"] - a["b_g"]
    for i in range(1, a["t"].size):
        dt = a["t"][i] - a["t"][i - 1]
        p, v, q, C0, _ = mech.step(p, v, q, f[i - 1], f[i], w[i - 1], w[i], dt)
        F = ins.error_transition(C0, f[i - 1], dt)
        Phi = F @ Phi
        Qacc = F @ Qacc @ F.T + np.diag(a["qrate"] * dt)
    return {"pos": p, "vel": v, "quat": q, "Phi": Phi, "Qacc": Qacc}


def _coast_fast(a):
    ins.coast(a["pos"], a["vel"], a["t"], 0, a["t"].size - 1, a["qrate"], a["acc_var"], a["rate_var"], a["Phi"],
              a["Qacc"])
    return {k: a[k] for k in ("pos", "Phi", "Qacc")}


def _coast_definition(a):
    """:func:`coast_transition` per step: ``p += v Δt``, ``Phi ← F Phi``, ``Qacc ← F Qacc Fᵀ + Q``."""
    p, Phi, Qacc = a["pos"], a["Phi"], a["Qacc"]
    for i in range(1, a["t"].size):
        dt = a["t"][i] - a["t"][i - 1]
        F, Q = ins.coast_transition(dt, a["qrate"], np.sqrt(a["acc_var"]), np.sqrt(a["rate_var"]))
        p = p + a["vel"] * dt
        Phi = F @ Phi
        Qacc = F @ Qacc @ F.T + Q
    return {"pos": p, "Phi": Phi, "Qacc": Qacc}


# ---------------------------------------------------------------- sequential Kalman update
def _sequential_inputs(correlated: bool):
    def build():
        rng = np.random.default_rng(4)
        n, m = 7, 4
        A = rng.normal(size=(n, n))
        state = kalman.Gaussian(rng.normal(size=n), A @ A.T + np.eye(n))
        H = rng.normal(size=(m, n))
        R = np.diag(rng.uniform(0.1, 1.0, m)) + (0.3 if correlated else 0.0)
        return state, rng.normal(size=m), H, R, rng.normal(size=m)
    return build


def _sequential_fast(a):
    state, z, H, R, h = a
    post, parts = kalman.update_sequential(state, z, H, R, h_x=h)
    return {"x": post.x, "P": post.P, "nis": parts.sum()}


def _sequential_definition(a):
    state, z, H, R, h = a
    post, inn = kalman.update(state, z, H, R, h_x=h)
    return {"x": post.x, "P": post.P, "nis": inn.nis}


# ---------------------------------------------------------------- set-noise KF and PF
def setnoise_case(T: int = 60, speed_mps: float = 0.35, seed: int = 1):
    """A straight-line run observed through a two-set model (also the cases of
    tests/filters/test_setnoise.py): ``(t, z, mu, sd, truth)``."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.09, 0.12, T))
    truth = np.column_stack([1.0 + speed_mps * (t - t[0]), np.full(T, 2.0)])
    model = SetNoiseModel([3, 5], [[0.08, -0.03], [-0.05, 0.06]], [[0.10, 0.08], [0.15, 0.12]], [50, 50],
                          [0.0, 0.0], [0.2, 0.2], 100)
    sets = rng.choice([3, 5], T)
    z = model.sample(truth, sets, rng=rng)
    mu, sd, _ = model.lookup(sets)
    return t, z, mu, sd, truth


def _kf_inputs():
    return (*setnoise_case(25), np.array([0.05, 0.3]))


def _kf_fast(a):
    t, z, mu, sd, truth, sig = a
    res = kf_sweep(t, z, mu, sd, truth[0], sig)
    return {"state": res.state, "cov": res.cov, "nis": res.nis}


@dataclass(frozen=True)
class _BiasedFix:
    """A set-noise position fix as an :class:`~uwbwb.filters.ekf.Ekf` measurement model: per epoch
    ``(z − μ, H_pos x, H_pos, diag σ²)`` (paper 000, eq. 4 with the set's bias removed)."""

    H: np.ndarray

    def linearise(self, x, meas):
        z, mu, sd = meas
        return Linearisation(z - mu, self.H @ x, self.H, np.diag(sd ** 2))


def _kf_definition(a):
    """The generic EKF (:class:`~uwbwb.filters.ekf.Ekf`, no gate: ``kalman.predict`` / ``kalman.update``
    step by step) from the known start (``P₀ = 0``), once per σ_d."""
    t, z, mu, sd, truth, sig = a
    state, cov, nis = [], [], []
    for s in sig:
        motion = VelocityKick(float(s))
        ekf = Ekf(motion, _BiasedFix(motion.H_pos), pos_index=(0, 1), vel_index=(2, 3), gate=NoGate())
        run = ekf.run(t, list(zip(z, mu, sd)), kalman.Gaussian(motion.initial_state(truth[0]), np.zeros((4, 4))))
        state.append(run.x_post)
        cov.append(run.P_post)
        nis.append(run.nis)
    return {"state": np.stack(state), "cov": np.stack(cov), "nis": np.stack(nis)}


def _pf_inputs(resampler: str):
    def build():
        return (*setnoise_case(40), resampler)
    return build


def _pf_fast(a):
    t, z, mu, sd, truth, resampler = a
    sw = pf_sweep(t, z, mu, sd, truth[0], 0.2, rng=np.random.default_rng(7), n_particles=300, resampler=resampler,
                  dtype=np.float64, compiled=True)
    return {"pos_m": sw.pos_m[0, 0, 0], "n_resampled": sw.n_resampled[0, 0, 0], "ess_mean": sw.ess_mean[0, 0, 0]}


def _pf_definition(a):
    t, z, mu, sd, truth, resampler = a
    ref = reference_pf(t, z, mu, sd, truth[0], 0.2, rng=np.random.default_rng(7).spawn(1)[0], n_particles=300,
                       resampler=resampler)
    return {"pos_m": ref.pos_m, "n_resampled": ref.resampled.sum(), "ess_mean": ref.ess.mean()}


def _block_inputs(dtype, crn: bool):
    """Three trials of :func:`setnoise_case` for two noise models (the second with half the bias and 1.3 times
    the spread) and three σ_d, K = 200, systematic resampling: the arguments of one block of :func:`pf_sweep`."""
    def build():
        t, z, mu, sd, truth = setnoise_case(60)
        mu2, sd2 = np.stack([mu, 0.5 * mu]), np.stack([sd, 1.3 * sd])
        rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(3).spawn(3)]
        return (rngs, (z[None] - mu2 - truth[0]).astype(dtype), (0.5 / sd2 ** 2).astype(dtype),
                np.diff(t, prepend=t[0]).astype(dtype), np.array([0.05, 0.2, 0.5]), 200, 2, 0.5, "systematic", crn,
                np.dtype(dtype))
    return build


def _block(fn):
    def run(a):
        pos, n_res, ess_sum = fn(*a)
        return {"pos_m": pos, "n_resampled": n_res, "ess_sum": ess_sum}
    return run


def _block_exercised(out):
    return None if out["n_resampled"].min() > 3 else "a run with fewer than 4 resampling steps"


def _pf_exercised(out):
    return None if out["n_resampled"] > 3 else "fewer than 4 resampling steps"


# ---------------------------------------------------------------- particle resampling, batched
def _indices_inputs(method: str):
    def build():
        rng = np.random.default_rng(1)
        w = rng.random((3, 2, 40)) ** 4
        w /= w.sum(-1, keepdims=True)
        u = rng.random((3, 2) if method == "systematic" else (3, 2, 40))
        return (particle.systematic_indices if method == "systematic" else particle.multinomial_indices), w, u
    return build


def _indices_fast(a):
    f, w, u = a
    return {"indices": f(w, u)}


def _indices_definition(a):
    """One row at a time."""
    f, w, u = a
    return {"indices": np.stack([np.stack([f(w[i, j], u[i, j]) for j in range(w.shape[1])])
                                 for i in range(w.shape[0])])}


# ---------------------------------------------------------------- Doppler particle filter: one epoch's loops
def _doppler_pf_inputs():
    rng = np.random.default_rng(11)
    x = np.concatenate([rng.uniform(-4.0, 4.0, (3, 60, 3)), rng.uniform(-1.5, 1.5, (3, 60, 3))], axis=-1)
    x[1, :, 0] += 10.0                                       # every particle of row 1 outside the room: a restart
    pf = DopplerPf(doppler_model.DopplerModel.for_layout(doppler_model.lab_layout()), ReceiverMotion((2.0, 1.0, 0.2)),
                   n_particles=60)
    return pf, x, np.full((3, 60), -np.log(60)), np.array([True, False, True])


def _doppler_pf_fast(a):
    pf, x, logw, rows = a
    rng = np.random.default_rng(3)
    kept, kept_logw, lost = pf._keep_in_room(x, logw, rng=rng)
    return {"propagated": pf.motion.propagate(x, 0.07, rng=rng), "coasted": pf.motion.propagate(x, np.arange(60) / 50,
                                                                                                   rng=None),
            "roughened": particle.roughen(x, rng=rng, k=0.2, rows=rows), "roughened all": particle.roughen(x, rng=rng),
            "kept": kept, "kept logw": kept_logw, "lost": lost}


def _doppler_pf_definition(a):
    """NumPy, one axis at a time: the room test, the random-acceleration step ``p + v dt + a dt²/2``, ``v + a dt``
    (``a = σ · N(0, 1)``), and roughening ``x + σ_j N(0, 1)`` with ``σ_j = k · (max − min) · K^(−1/n_x)`` per row
    (times the row's mask); the draws in the filter's order (restart, prediction, roughening)."""
    pf, x, logw, rows = a
    rng = np.random.default_rng(3)
    lo, hi = np.asarray(pf.room_lo_m), np.asarray(pf.room_hi_m)
    inside = (x[..., 0] >= lo[0]) & (x[..., 0] <= hi[0])
    for c in (1, 2):
        inside &= (x[..., c] >= lo[c]) & (x[..., c] <= hi[c])
    lost = ~np.any(inside, axis=-1)
    kept, kept_logw = x.copy(), logw.copy()
    kept[lost] = pf._draw(rng, int(lost.sum()), lo, hi)
    kept_logw[lost] = -np.log(pf.n_particles)
    inside[lost] = True
    out = {"kept": kept, "kept logw": np.where(inside, kept_logw, -np.inf), "lost": lost}

    def propagate(x, dt, noise):
        y = np.empty_like(x)
        for c in range(3):
            acc = 0.0 if noise is None else noise[..., c] * pf.motion.sigma_acc_mps2[c]
            y[..., c] = x[..., c] + x[..., 3 + c] * dt + 0.5 * acc * dt * dt
            y[..., 3 + c] = x[..., 3 + c] + acc * dt
        return y

    def roughen(x, k, rows):
        K, n_x = x.shape[-2:]
        sigma = k * np.ptp(x, axis=-2)[..., None, :] * K ** (-1.0 / n_x)
        if rows is not None:
            sigma = sigma * rows[..., None, None]
        return x + sigma * rng.standard_normal(x.shape)

    out["propagated"] = propagate(x, 0.07, rng.standard_normal(x.shape[:-1] + (3,)))
    out["coasted"] = propagate(x, np.arange(60) / 50, None)
    out["roughened"], out["roughened all"] = roughen(x, 0.2, rows), roughen(x, 0.2, None)
    return out


def _doppler_pf_exercised(out):
    return None if out["lost"].sum() == 1 and np.isinf(out["kept logw"]).any() else "no restart or no particle out"



def _pf_pieces_fast(a):
    pf, x, logw, rows = a
    lw = particle.normalise_log_weights(logw + np.random.default_rng(4).normal(0.0, 2.0, logw.shape))[0]
    pos, vel, cov = _moments(x, lw)
    moved, moved_logw = particle._resample_rows(x, lw, np.exp(lw), rows, rng=np.random.default_rng(5),
                                                method="systematic")
    return {"log-likelihood": pf._log_likelihood(x, (2, 1e-3, None)),
            "log-likelihood, range": pf._log_likelihood(x, (5, -2e-3, 2.5)), "pos_m": pos, "vel_mps": vel,
            "pos_cov_m2": cov, "resampled": moved, "resampled logw": moved_logw}


def _pf_pieces_definition(a):
    """The model's log-likelihood (:meth:`DopplerModel.log_likelihood`) with the outlier mixture; the moments as
    einsum and matmul; the resampled rows by fancy indexing with the ancestors of :func:`particle.systematic_indices`
    (the uniforms drawn as the engine draws them)."""
    pf, x, logw, rows = a
    lw = particle.normalise_log_weights(logw + np.random.default_rng(4).normal(0.0, 2.0, logw.shape))[0]

    def ll(beacon, dp_s, range_m):
        out = pf.model.log_likelihood(x[..., :3], x[..., 3:], np.int64(beacon), dp_s, range_m=range_m)
        return np.logaddexp(np.log1p(-pf.outlier_prob) + out, np.log(pf.outlier_prob / (2 * pf.outlier_window_s)))

    w = np.exp(lw)
    pos, vel = np.einsum("rk,rkn->rn", w, x[..., :3]), np.einsum("rk,rkn->rn", w, x[..., 3:])
    d = x[..., :3] - pos[:, None, :]
    idx = particle.systematic_indices(w[rows], np.random.default_rng(5).random(int(rows.sum())))
    moved, moved_logw = x.copy(), lw.copy()
    moved[rows] = np.take_along_axis(x[rows], idx[..., None], axis=-2)
    moved_logw[rows] = -np.log(x.shape[-2])
    return {"log-likelihood": ll(2, 1e-3, None), "log-likelihood, range": ll(5, -2e-3, 2.5), "pos_m": pos,
            "vel_mps": vel, "pos_cov_m2": np.swapaxes(d * w[..., None], 1, 2) @ d, "resampled": moved,
            "resampled logw": moved_logw}


def _mh_inputs(ranges: bool, **settings):
    """The lab walked for 9 s (timing jitter, 5 % missed chirps, one spurious detection a second), assigned by the
    front end, with exact clock pseudo-ranges or none; the MH-EKF with ``settings`` and a room-sized prior."""
    def build():
        lab = doppler_model.DopplerModel.for_layout(doppler_model.lab_layout())
        track, _ = chirps.rectangle_track()
        rec = chirps.simulate_chirps(lab, track, 9.0, rng=np.random.default_rng(3), p_miss=0.05, spurious_rate_hz=1.0)
        log = assign_chirps(rec.t_s, lab)
        rr = clock_pseudo_ranges(log, lab, rec.phase_s) if ranges else np.full(len(log), np.nan)
        x0 = kalman.Gaussian(np.zeros(6), np.diag([3.0, 2.1, 0.6, 0.75, 0.75, 0.75]))
        return ScaatMhEkf(lab, **settings), log, rr, x0
    return build


def _mh_outputs(est):
    return {"pos_m": est.pos_m, "vel_mps": est.vel_mps, "pos_cov_m2": est.pos_cov_m2, "status": est.status,
            "n_hypotheses": est.info["n_hypotheses"], "beacon": est.info["beacon"]}


def _mh_exercised(out):
    return None if out["n_hypotheses"].max() > 1 and (out["beacon"] == -1).any() else "one hypothesis, no noise"


# ---------------------------------------------------------------- Doppler space sampling (eq. 1)
def _brute_inputs():
    model = doppler_model.DopplerModel.for_layout(doppler_model.cubic_layout())
    return dict(model=model, ref=(doppler_model.REFERENCE_POS_M, doppler_model.REFERENCE_VEL_MPS), n=100_000, seed=5,
                chunk_size=40_000, thresholds_m=(0.5, 1.0, 3.0), keep_below_m=1.0)


def _brute_fast(a):
    res = sampling.brute_force(a["model"], *a["ref"], a["n"], seed=a["seed"], chunk_size=a["chunk_size"],
                               thresholds_m=a["thresholds_m"], keep_below_m=a["keep_below_m"], workers=1)
    return {"counts": np.array([e.n_hits for e in res.estimates]), "delta_m": res.samples.delta_m}


def _brute_definition(a):
    """Chunk by chunk with NumPy: the chunk's generator draws X then V (six uniforms a row), δ by
    :meth:`DopplerModel.distance_m` of eq. 1, counted under each threshold and kept under ``keep_below_m``."""
    m = a["model"]
    box = sampling.SearchBox()
    counts, kept = np.zeros(len(a["thresholds_m"]), np.int64), []
    for ss, n in sampling.chunk_seeds(a["seed"], a["n"], a["chunk_size"]):
        u = np.random.default_rng(ss).random((n, 6))
        X = box.pos_lo_m + (box.pos_hi_m - box.pos_lo_m) * u[:, :3]
        V = box.vel_lo_mps + (box.vel_hi_mps - box.vel_lo_mps) * u[:, 3:]
        d = m.distance_m(m.delta_p(X, V), m.delta_p(*a["ref"]))
        counts += [np.count_nonzero(d < t) for t in a["thresholds_m"]]
        kept.append(d[d < a["keep_below_m"]])
    return {"counts": counts, "delta_m": np.concatenate(kept)}


def _brute_exercised(out):
    return None if out["counts"].min() > 0 else "a threshold with no hit"



def _ellipsoid_inputs(ranges: bool):
    """Positions of the conditional sampler for the cubic layout at the reference pair: 4000 uniform in the
    position box (a few of them outside it) or, with ``ranges``, in the ranging region of a 15 cm threshold."""
    def build():
        model = doppler_model.DopplerModel.for_layout(doppler_model.cubic_layout())
        ref = (doppler_model.REFERENCE_POS_M, doppler_model.REFERENCE_VEL_MPS)
        b, rho_ref = sampling._reference(model, *ref, ranges)
        rng = np.random.default_rng(11)
        if ranges:
            M, half, _ = sampling.ranging_region(model, ref[0], 0.15)
            X = ref[0] + np.linalg.solve(M, (rng.uniform(-1.0, 1.0, (4000, 3)) * half).T).T
        else:
            X = rng.uniform(-5.2, 5.2, (4000, 3))
        return dict(model=model, X=X, b=b, rho_ref=rho_ref, ranges=ranges, tau_max=0.15, box=sampling.SearchBox())
    return build


def _ellipsoid_e_norm(a):
    m, b, t = a["model"], a["b"], a["tau_max"]
    return float(np.linalg.norm((np.abs(b) + t) ** 2 / (m.v_s_mps * m.period_s - np.abs(b) - t)))


def _ellipsoid_fast(a):
    n = a["X"].shape[0]
    out = dict(L=np.empty((n, 3, 3)), v_star=np.empty((n, 3)), r2=np.empty(n), rr2=np.empty(n),
               active=np.empty(n, np.bool_))
    sampling._ellipsoids(a["X"], a["model"].beacons.pos_m, a["model"].period_s, a["b"], a["rho_ref"], a["ranges"],
                         a["tau_max"], _ellipsoid_e_norm(a), a["box"].pos_lo_m, a["box"].pos_hi_m, *out.values())
    return out


def _ellipsoid_definition(a):
    """The velocity ellipsoid per position in NumPy (the module docstring of :mod:`uwbwb.sampling`): rows
    ``A = P d / ρ``, ``M = AᵀA`` (its Cholesky factor), ``v* = M⁻¹ Aᵀb`` by LAPACK, the squared radius left
    after the residual at ``v*``, and whether the position takes draws."""
    X, T, P, b, tau_max, box = a["X"], a["model"].beacons.pos_m, a["model"].period_s, a["b"], a["tau_max"], a["box"]
    d = X[:, None, :] - T
    rho = np.linalg.norm(d, axis=-1)                                     # (n, nb)
    A = P[:, None] * d / rho[..., None]                                  # (n, nb, 3): eq 1's linear part A V
    rr2 = np.sum((rho - a["rho_ref"]) ** 2, axis=-1) if a["ranges"] else np.zeros(X.shape[0])
    tau_v = np.sqrt(np.clip(tau_max ** 2 - rr2, 0.0, None))              # what the Doppler part may use
    radius = tau_v + _ellipsoid_e_norm(a)
    M = np.einsum("nbi,nbj->nij", A, A)
    v_star = np.linalg.solve(M, np.einsum("nbi,b->ni", A, b)[..., None])[..., 0]
    res2 = np.sum((np.einsum("nbi,ni->nb", A, v_star) - b) ** 2, axis=-1)
    r2 = radius ** 2 - res2
    in_box = np.all((X >= box.pos_lo_m) & (X <= box.pos_hi_m), axis=1)
    return dict(L=np.linalg.cholesky(M), v_star=v_star, r2=r2, rr2=rr2, active=(rr2 < tau_max ** 2) & (r2 > 0) & in_box)


def _ellipsoid_exercised(out):
    return None if 0 < out["active"].sum() < out["active"].size else "every position or none takes draws"


# ---------------------------------------------------------------- error transition, written out by blocks
def _transition_inputs():
    return ins.dcm_from_euler(0.2, -0.3, 1.0), np.array([0.5, -0.2, 9.6]), 0.05


def _transition_definition(a):
    """``F = I + A Δt + ½ (A Δt)²`` with ``A`` = :func:`~uwbwb.models.ins.error_dynamics`."""
    C, f, dt = a
    Adt = ins.error_dynamics(C, f) * dt
    return {"F": np.eye(ins.N_ERR) + Adt + 0.5 * Adt @ Adt}


# ---------------------------------------------------------------- multilateration, batched Gauss-Newton
def _multilateration_inputs(dim: int):
    """60 tags in a 10 m × 8 m room with eight anchors at mixed heights, 10 cm range noise and 20 %
    of the ranges missing (tests/test_geometry.py)."""
    def build():
        rng = np.random.default_rng(2)
        anchors = np.array([[0.0, 0.0, 2.5], [10.0, 0.0, 2.4], [10.0, 8.0, 2.6], [0.0, 8.0, 2.5],
                            [5.0, -1.0, 1.0], [11.0, 4.0, 0.5], [5.0, 9.0, 2.0], [-1.0, 4.0, 1.5]])
        T = 60
        xy, z = np.column_stack([rng.uniform(1, 9, T), rng.uniform(1, 7, T)]), rng.uniform(0.5, 1.5, T)
        kw = {"z_m": z} if dim == 2 else {}
        truth = xy if dim == 2 else np.column_stack([xy, z])
        r = geometry.ranges(truth, anchors, **kw)
        r = r + 0.1 * rng.standard_normal(r.shape)
        drop = rng.random(r.shape) < 0.2
        drop[:, :dim + 1] = False
        r[drop] = np.nan
        return r, anchors, dim, kw
    return build


def _multilaterate(method: str):
    def run(a):
        r, anchors, dim, kw = a
        res = geometry.multilaterate(r, anchors, dim=dim, method=method, **kw)
        return {"pos_m": res.pos_m, "cov_m2": res.cov_m2, "ok": res.ok}
    return run


# ---------------------------------------------------------------- eq. (1)'s residuals and Jacobian
def _track_inputs(dim: int, static: bool):
    def build():
        """A 20 s walk (or a stop) past eight anchors, one range every 25 ms from a random anchor with 5 cm noise and
        a positive NLOS excess on 10 %; the unknowns 30 cm and 5 cm/s off the truth (as inside a solver)."""
        rng = np.random.default_rng(7)
        A = np.array([[0.0, 0.0, 2.5], [10.0, 0.0, 2.4], [10.0, 8.0, 2.6], [0.0, 8.0, 2.5],
                      [5.0, -1.0, 1.0], [11.0, 4.0, 0.5], [5.0, 9.0, 2.0], [-1.0, 4.0, 1.5]])
        t = np.arange(800) * 0.025
        k = rng.integers(0, 8, t.size)
        v = np.zeros(3) if static else np.array([0.4, 0.25, 0.0])
        P = np.array([2.0, 1.5, 1.3])
        r = np.linalg.norm(P + np.multiply.outer(t, v) - A[k], axis=1) + 0.05 * rng.standard_normal(t.size)
        r += np.where(rng.random(t.size) < 0.1, rng.exponential(0.8, t.size), 0.0)
        model = LinearTrackRanges(A, dim, static, 1.3 if dim == 2 else None)
        theta = model.pack(P + 0.3 * rng.standard_normal(3), v + 0.05 * rng.standard_normal(3))
        return model, theta, t, k, r
    return build


def _track_terms(compiled: bool):
    def run(a):
        model, theta, t, k, r = a
        res, J = model.residuals_jacobian(theta, t, k, r, compiled=compiled)
        return {"res_m": res, "J": J, "res_only_m": model.residuals_jacobian(theta, t, k, r, jacobian=False,
                                                                           compiled=compiled)[0]}
    return run


# ---------------------------------------------------------------- the robust mean's tuple fixes
def _tuple_inputs():
    """300 epochs of a tag 1.3 m up in a 12 m × 9 m room with eight anchors near one plane (LIAS-like), ranges with
    5 cm noise, a positive NLOS excess on 10 % of them and 5 % missing: every anchor triplet at every epoch."""
    rng = np.random.default_rng(5)
    A = np.array([[0.0, 0.0, 1.6], [12.0, 0.0, 1.5], [12.0, 9.0, 1.7], [0.0, 9.0, 1.6],
                  [6.0, -0.5, 1.4], [12.5, 4.5, 1.8], [6.0, 9.5, 1.5], [-0.5, 4.5, 1.3]])
    r = np.linalg.norm(np.array([4.0, 3.0, 1.3]) - A, axis=1) + 0.05 * rng.standard_normal((300, 8))
    r += np.where(rng.random(r.shape) < 0.1, rng.exponential(0.8, r.shape), 0.0)
    r[rng.random(r.shape) < 0.05] = np.nan
    return r, A, 1.3


def _tuple_fast(a):
    cloud = pruning.tuple_fixes(a[0], a[1], z_m=a[2])
    return {"pos_m": cloud.pos_m, "tuple_index": cloud.tuple_index, "n_failed": np.array(cloud.n_failed)}


def _tuple_definition(a):
    """Every complete (epoch, tuple) row through :func:`uwbwb.geometry.multilaterate` at once, the other anchors'
    ranges masked, its OK rows kept."""
    R, A, z_m = a
    combos = np.array(list(itertools.combinations(range(A.shape[0]), 3)))
    sv = np.linalg.svd(A[combos, :2] - A[combos, :2].mean(axis=1, keepdims=True), compute_uv=False)
    used = combos[sv[:, 1] > 0.02 * sv[:, 0]]
    C = used.shape[0]
    mask = np.zeros((C, A.shape[0]), bool)
    mask[np.arange(C)[:, None], used] = True
    Rt = np.where(mask[None], R[:, None, :], np.nan).reshape(-1, A.shape[0])
    complete = np.isfinite(Rt).sum(axis=1) == 3
    res = geometry.multilaterate(Rt[complete], A, dim=2, z_m=z_m, min_anchors=3)
    ok = res.ok
    rows = np.flatnonzero(complete)[ok]
    return {"pos_m": res.pos_m[ok], "tuple_index": rows % C, "n_failed": np.array(Rt.shape[0] - ok.sum())}


def _robust_mean_inputs():
    """The triplet cloud of :func:`_tuple_inputs` (about 14 000 fixes, the NLOS ones far out)."""
    r, A, z_m = _tuple_inputs()
    return pruning.tuple_fixes(r, A, z_m=z_m).pos_m, 0.5, 0.01


def _robust_mean_fast(a):
    res = pruning.robust_mean(a[0], retention=a[1], dropout=a[2])
    return {"kept": res.kept, "history_m": res.history_m}


def _robust_mean_definition(a):
    """The iterated centroid in NumPy: distances of the kept points, ``argpartition`` of the furthest, the mean."""
    P, retention, dropout = a
    kept, c = np.ones(len(P), bool), P.mean(axis=0)
    history = [c]
    for n_drop in pruning.drop_schedule(len(P), retention, dropout):
        idx = np.flatnonzero(kept)
        dist = np.linalg.norm(P[idx] - c, axis=1)
        kept[idx[np.argpartition(dist, dist.size - n_drop)[dist.size - n_drop:]]] = False
        c = P[kept].mean(axis=0)
        history.append(c)
    return {"kept": kept, "history_m": np.array(history)}


def _steer_inputs():
    """Arguments of :func:`uwbwb.sim.walk._steer_loop`: 20 s at 100 Hz around a rounded 6 m × 4 m loop (path points
    every 2 cm, slower in turns), random-force kicks, started at rest so the command is clipped at first."""
    xy, kappa = walk.path_points(((0.0, 0.0), (6.0, 0.0), (6.0, 4.0), (0.0, 4.0)), 1.0)
    rf, dt = RandomForce(0.05, dim=2), 0.01
    noise = np.random.default_rng(7).standard_normal((2001, 4)) @ rf.Q_sqrt(dt).T
    x = np.zeros((2001, 4))
    x[0, :2] = xy[0]
    return x, xy, 0.8 / (1.0 + 0.5 * kappa), noise, rf.F(dt), rf.G(dt), 50, 100, 0.5, 1.5


def _steer_fast(a):
    walk._steer_loop(*a)
    return {"x": a[0]}


def _steer_definition(a):
    """The pursuit loop in NumPy: nearest of the next ``window`` path points, command towards the point ``look``
    further on, clipped, then ``x_{k+1} = F x_k + G u + w_k``."""
    x, xy, v_path, noise, F, G, look, window, tau_s, max_acc_mps2 = a
    N, i = len(xy), 0
    for k in range(len(x) - 1):
        p, v = x[k, :2], x[k, 2:]
        cand = (i + np.arange(window)) % N
        i = int(cand[np.argmin(np.sum((xy[cand] - p) ** 2, axis=1))])
        d = xy[(i + look) % N] - p
        u = (v_path[i] * d / max(np.linalg.norm(d), 1e-9) - v) / tau_s
        a_norm = np.linalg.norm(u)
        if a_norm > max_acc_mps2:
            u = u * (max_acc_mps2 / a_norm)
        x[k + 1] = F @ x[k] + G @ u + noise[k]
    return {"x": x}


# ---------------------------------------------------------------- the median block bootstrap's replicates
def _irls_inputs():
    """12 000 rows, 2 tags × 3 anchors: ranges 1–9 m with a bias and scale per pair, 0.05 m noise, 5 % outliers
    (+1 to +3 m), rows with no sample in each pair (odd and even counts, over the 5 000 from which the medians
    take their bracket from a sample), one bias-only pair."""
    rng = np.random.default_rng(17)
    x = rng.uniform(1.0, 9.0, (12_000, 2, 3))
    y = 1.01 * x + 0.2 + rng.normal(0.0, 0.05, x.shape) + (rng.random(x.shape) < 0.05) * rng.uniform(1, 3, x.shape)
    mask = rng.random(x.shape) > 0.1
    x[~mask & (rng.random(x.shape) < 0.5)] = np.nan
    with_scale = np.ones((2, 3), bool)
    with_scale[1, 2] = False
    return x, y, mask, with_scale, 30


def _irls_fast(a):
    return dict(zip(("bias", "scale", "median", "sigma", "rms"), twr._irls(*a)))


def _irls_definition(a):
    """The IRLS in NumPy on every pair at once: weighted normal equations over the rows, residuals, robust σ
    (1.4826·MAD per pair, at least 0.1 mm) and Huber weights; the final residuals' median, robust σ and RMS."""
    x, y, mask, with_scale, n_iter = a
    x0, y0, w = np.where(mask, x, 0.0), np.where(mask, y, 0.0), mask.astype(float)

    def robust_sigma(resid):
        r = np.where(mask, resid, np.nan)
        return twr.MAD_TO_SIGMA * np.nanmedian(np.abs(r - np.nanmedian(r, axis=0)), axis=0)

    for _ in range(n_iter):
        wx = w * x0
        sw, sx, sy = w.sum(0), wx.sum(0), (w * y0).sum(0)
        sxx, sxy = (wx * x0).sum(0), (wx * y0).sum(0)
        with np.errstate(invalid="ignore", divide="ignore"):
            s_full = (sw * sxy - sx * sy) / (sw * sxx - sx * sx)
            scale = np.where(with_scale, s_full, 1.0)
            bias = np.where(with_scale, (sy - s_full * sx) / sw, (sy - sx) / sw)
        resid = y0 - (scale * x0 + bias)
        thr = twr._HUBER_K * np.maximum(robust_sigma(resid), 1e-4)
        d = np.abs(resid)
        w = np.where(mask, np.where(d <= thr, 1.0, thr / np.maximum(d, 1e-12)), 0.0)
    resid = np.where(mask, y0 - (scale * x0 + bias), np.nan)
    return {"bias": bias, "scale": scale, "median": np.nanmedian(resid, axis=0), "sigma": robust_sigma(resid),
            "rms": np.sqrt(np.nanmean(resid ** 2, axis=0))}


def _median_inputs():
    """40 blocks of 1–30 epochs (odd and even replicate sizes), the b side zero in 21 of them (so some replicates
    have a zero median: NaN ratio), 500 replicates."""
    rng = np.random.default_rng(11)
    counts = rng.integers(1, 31, 40)
    xa, xb = rng.lognormal(0.0, 0.5, counts.sum()), rng.lognormal(0.1, 0.5, counts.sum())
    starts = np.cumsum(counts) - counts
    xb[:starts[21]] = 0.0
    return xa, xb, starts, counts, rng.integers(0, 40, (500, 40))


def _median_fast(a):
    d, ratio = metrics.errors._median_replicates(*a)
    return {"d": d, "ratio": ratio}


def _median_definition(a):
    """One ``np.median`` per replicate on the epochs of its blocks gathered by index."""
    xa, xb, starts, counts, pick = a
    d, ratio = np.empty(len(pick)), np.empty(len(pick))
    for r in range(len(pick)):
        c = counts[pick[r]]
        idx = np.repeat(starts[pick[r]] - (np.cumsum(c) - c), c) + np.arange(c.sum())
        ma, mb = np.median(xa[idx]), np.median(xb[idx])
        d[r] = ma - mb
        ratio[r] = ma / mb if mb > 0 else np.nan
    return {"d": d, "ratio": ratio}


# ---------------------------------------------------------------- the EKF's epoch loop (TDoAs or ranges)
def _tdoa_ekf_inputs(motion, gate, correlated: bool = True, ranges: bool = False):
    """A 40 s walk at about 10 Hz (a Lissajous figure at walking speed, 1 m ± 0.3 m high) in a 30 m square
    of eight anchors: 10 cm range noise per anchor, 15 % of the ranges missing, 5 % with a 0.5–4 m excess,
    3 s with fewer than two anchors and a 2 s burst of 5–10 m outliers: every branch of the gates (updated,
    gated, released, predicted, anchors dropped, the reference among them). ``(filter, log, prior)``; ``ranges``:
    the range EKF (:class:`Ekf` with :class:`RangeMeasurement`) on the ranges themselves, prior σ 1 m (m/s, m/s²)."""
    def build():
        rng = np.random.default_rng(8)
        anchors = np.array([[0.0, 0.0, 3.0], [30.0, 0.0, 0.5], [30.0, 30.0, 3.0], [0.0, 30.0, 0.5],
                            [15.0, -2.0, 2.0], [15.0, 32.0, 1.0], [-2.0, 15.0, 2.0], [32.0, 15.0, 1.5]])
        model = TdoaModel(anchors, rng.uniform(0.05, 0.15, 8), dim=motion.dim, z_m=1.0, correlated=correlated)
        t = np.cumsum(rng.uniform(0.08, 0.12, 400))
        w = 2 * np.pi * t / 40.0
        pos = np.column_stack([15 + 8 * np.sin(w), 15 + 6 * np.sin(2 * w), 1 + 0.3 * np.sin(3 * w)])[:, :motion.dim]
        r = model.ranges(pos) + 0.1 * rng.standard_normal((t.size, 8))
        out = rng.random(r.shape) < 0.05
        r[out] += rng.uniform(0.5, 4.0, out.sum())
        r[rng.random(r.shape) < 0.15] = np.nan
        r[150:180, 2:] = np.nan
        r[250:270] += rng.uniform(5.0, 10.0, (20, 8)) * (rng.random((20, 8)) < 0.6)
        if ranges:
            ekf = Ekf(motion, RangeMeasurement(anchors, model.sigma_m, motion, 1.0), gate=gate)
            prior = kalman.Gaussian(motion.initial_state(pos[0] + 0.5), motion.initial_covariance(1.0, 1.0, 1.0))
            return ekf, RangeLog(t, r, tuple(f"a{i}" for i in range(8)), "tag"), prior
        d, ref = pseudo_tdoa(r, 0)
        ekf = TdoaEkf(motion, model, gate=gate)
        return ekf, TdoaLog(t, d, ref, tuple(f"a{i}" for i in range(8))), ekf.init(pos[0] + 0.5)
    return build


_EKF_FLOATS = ("x_prior", "P_prior", "x_post", "P_post", "nis")
_EKF_INTS = ("F", "dof", "status", "n_rejected")


def _tdoa_ekf_fast(a):
    ekf, log, x0 = a
    if isinstance(log, RangeLog):
        run = ekf_kernels.run(ekf, log.t_s, log.range_m, None, x0, 0, "EKF")
        if run is None:
            raise AssertionError(f"{ekf.gate!r}: the range EKF takes its Python loop")
        return _run_outputs(run, _EKF_FLOATS, _EKF_INTS)
    if not ekf.compiled:
        raise AssertionError(f"{ekf.gate!r}: the TDoA EKF takes its Python loop")
    return _run_outputs(ekf.run(log, x0=x0), _EKF_FLOATS, _EKF_INTS)


def _tdoa_ekf_definition(a):
    """:meth:`Ekf.run`, the Python loop (filterpy's predict and update, the gate policy's own decision)."""
    ekf, log, x0 = a
    epochs = RangeMeasurement.epochs(log) if isinstance(log, RangeLog) else TdoaMeasurement.epochs(log)
    return _run_outputs(Ekf.run(ekf, log.t_s, epochs, x0), _EKF_FLOATS, _EKF_INTS)


def _tdoa_ekf_exercised(gated: bool, dropped: bool):
    def check(out):
        st = out["status"]
        if not np.any(st == EstimateStatus.PREDICTED) or np.sum(st == EstimateStatus.UPDATED) < 200:
            return "no predicted epoch, or fewer than 200 updated"
        if gated and not np.any(st == EstimateStatus.GATED):
            return "no gated epoch"
        if dropped and not np.any((out["n_rejected"] > 0) & (st == EstimateStatus.UPDATED)):
            return "no update with anchors dropped"
        return None
    return check


# ============================================================================ the registry
_ESKF = "uwbwb.filters.eskf.kernels."
_INS = "uwbwb.models.ins."
_TIGHT_TEST = "tests/filters/test_eskf.py::test_compiled_run_equals_the_reference_loop"
_LOOSE_TEST = "tests/filters/test_eskf.py::test_compiled_loose_run_equals_the_reference_loop"
_PIECES_TEST = "tests/filters/test_eskf.py::test_compiled_pieces_equal_the_model_functions"
_SWEEP_KERNELS = (*(f"uwbwb.filters.setnoise.pf.{f}" for f in ("_predict_weigh", "_moments")),
                  "uwbwb.filters.particle._systematic")


def _registry() -> tuple[Twin, ...]:
    tight_tol = {**{f: Tol(1e-9, 1e-10) for f in _FUSION_FLOATS}, **{f: BIT for f in _FUSION_INTS}}
    twins = [
        Twin("eskf._tight_loop", _fusion_fast, _fusion_definition, _tight_inputs, tight_tol, _TIGHT_TEST,
             (_ESKF + "_tight_loop", _ESKF + "_uwb_rows", _INS + "propagate", "uwbwb.filters.kalman._sequential",
              "uwbwb.filters.kalman._scalar_updates"), _tight_exercised),
        Twin("eskf._loose_loop", _fusion_fast, _fusion_definition, _loose_inputs, tight_tol, _LOOSE_TEST,
             (_ESKF + "_loose_loop", _ESKF + "_consistent_nb", _INS + "propagate", _INS + "coast",
              "uwbwb.filters.ekf.kernels._predict", "uwbwb.filters.ekf.kernels._update"), _loose_exercised),
        Twin("ins._exp_left_nb", _per_case(_exp_left_fast),
             _per_case(lambda rv, q, P: {"quat": ins._exp_left(rv, q)}), _rotation_inputs,
             {"quat": BIT}, _PIECES_TEST,
             (_INS + "_exp_left_nb", _INS + "_unit_into", _INS + "_exp_quat3_nb", _INS + "_qmul_nb")),
        Twin("eskf._reset_block", _per_case(_reset_block_fast),
             _per_case(lambda rv, q, P: {"G_theta": ins.reset_jacobian(rv)[6:9, 6:9]}), _rotation_inputs,
             {"G_theta": Tol(0.0, 1e-15)}, _PIECES_TEST, (_ESKF + "_reset_block", _ESKF + "_skew_into")),
        Twin("eskf._reset_covariance", _per_case(_reset_cov_fast), _per_case(_reset_cov_definition), _rotation_inputs,
             {"P": Tol(0.0, 1e-14)}, _PIECES_TEST, (_ESKF + "_reset_covariance",)),
        Twin("eskf._fill_row", _rows_fast, _rows_definition, _rows_inputs, {"H": Tol(0.0, 1e-15)}, _PIECES_TEST,
             (_ESKF + "_fill_row", _ESKF + "_skew_into")),
        Twin("eskf._skew_into", _per_case(_skew_fast), _per_case(lambda rv, q, P: {"S": ins.skew(rv)}),
             _rotation_inputs, {"S": BIT}, _PIECES_TEST, (_ESKF + "_skew_into",)),
        Twin("ins._dcm_nb", _per_case(_dcm_fast), _per_case(lambda rv, q, P: {"C": ins._dcm(q)}), _rotation_inputs,
             {"C": BIT}, _TIGHT_TEST, (_INS + "_dcm_nb",)),
        # not bit for bit: the definition's F @ Phi and F Qacc Fᵀ are BLAS products whose summation order
        # depends on the CPU's kernel (equal to the loop's with OpenBLAS's Haswell kernel, 1 ULP off with
        # its SkylakeX or Prescott kernels); 15 terms a product, a few steps, so 16 ULP of the largest element
        Twin("ins.propagate", _propagate_fast, _propagate_definition, _imu_inputs,
             {k: Tol(ulps=16) for k in ("pos", "vel", "quat", "Phi", "Qacc")}, _TIGHT_TEST,
             (_INS + "propagate", _INS + "_dcm_nb", _INS + "_exp_quat3_nb", _INS + "_qmul_nb", _INS + "_unit_into")),
        Twin("ins.coast", _coast_fast, _coast_definition, _imu_inputs,
             {"pos": BIT, "Phi": BIT, "Qacc": Tol(1e-9, 1e-10)}, _TIGHT_TEST, (_INS + "coast",)),
    ]
    for kind, correlated in (("diagonal R", False), ("correlated R", True)):
        twins.append(Twin(f"kalman.update_sequential[{kind}]", _sequential_fast, _sequential_definition,
                          _sequential_inputs(correlated),
                          {"x": Tol(0.0, 1e-10), "P": Tol(0.0, 1e-10), "nis": Tol(1e-10, 0.0)},
                          "tests/filters/test_kalman.py::test_sequential_update_equals_the_batch_update",
                          ("uwbwb.filters.kalman._sequential", "uwbwb.filters.kalman._scalar_updates")))
    twins.append(Twin("setnoise.kf_sweep", _kf_fast, _kf_definition, _kf_inputs,
                      {"state": Tol(0.0, 1e-12), "cov": Tol(0.0, 1e-12), "nis": Tol(0.0, 1e-9)},
                      "tests/filters/test_setnoise.py::test_kf_sweep_matches_the_filterpy_edge_step_by_step"))
    for resampler in ("multinomial", "systematic"):
        twins.append(Twin(f"setnoise.pf_sweep[{resampler}]", _pf_fast, _pf_definition, _pf_inputs(resampler),
                          {"pos_m": Tol(0.0, 1e-9), "n_resampled": BIT, "ess_mean": Tol(1e-6, 1e-12)},
                          "tests/filters/test_setnoise.py::test_sweep_reproduces_the_reference_filter",
                          _SWEEP_KERNELS[:2 if resampler == "multinomial" else 3], _pf_exercised))
    # not bit for bit: the states, the log-weights, np.exp, the resampling decisions and copies are, but the compiled
    # sums of eqs. 11-12 are float64 loops where NumPy's are pairwise (Σw) and float32 einsum (Σwx, Σw²) sums: on
    # these cases the positions differ by up to 3.4 ULP of the largest (float32) and 17 ULP (float64), the ESS sums
    # by 2e-8 and 7e-16 relative; the resampling counts are equal (an ESS within that of its threshold would flip one)
    for case, dtype, crn, pos_tol, ess_tol in (("float32, common random numbers", np.float32, True, 8, 1e-6),
                                               ("float64, independent noise", np.float64, False, 64, 1e-12)):
        twins.append(Twin(f"setnoise._sweep_block_compiled[{case}]", _block(_sweep_block_compiled),
                          _block(_sweep_block), _block_inputs(dtype, crn),
                          {"pos_m": Tol(ulps=pos_tol), "n_resampled": BIT, "ess_sum": Tol(ess_tol)},
                          "tests/filters/test_setnoise.py::test_sweep_reproduces_the_reference_filter",
                          _SWEEP_KERNELS, _block_exercised))
    for method in ("systematic", "multinomial"):
        twins.append(Twin(f"particle.{method}_indices[batched]", _indices_fast, _indices_definition,
                          _indices_inputs(method), {"indices": BIT},
                          "tests/filters/test_particle.py::test_batched_indices_equal_row_by_row"))
    twins.append(Twin("doppler.pf[room, motion, roughening]", _doppler_pf_fast, _doppler_pf_definition,
                      _doppler_pf_inputs, dict.fromkeys(("propagated", "coasted", "roughened", "roughened all", "kept",
                                                         "kept logw", "lost"), BIT),
                      "tests/golden/test_doppler_golden.py::test_every_doppler_configuration_reproduces_the_golden_outputs",
                      ("uwbwb.filters.doppler.pf._inside_room", "uwbwb.models.motion._propagate_rows",
                       "uwbwb.filters.particle._roughen_rows"), _doppler_pf_exercised))
    # the moments not bit for bit: the compiled sums run over the particles in order, einsum and matmul in their own
    twins.append(Twin("doppler.pf[likelihood, moments, resampling]", _pf_pieces_fast, _pf_pieces_definition,
                      _doppler_pf_inputs, {**dict.fromkeys(("log-likelihood", "log-likelihood, range", "resampled",
                                                            "resampled logw"), BIT),
                                           **dict.fromkeys(("pos_m", "vel_mps", "pos_cov_m2"), Tol(0.0, 1e-12))},
                      "tests/golden/test_doppler_golden.py::test_every_doppler_configuration_reproduces_the_golden_outputs",
                      ("uwbwb.filters.doppler.pf._chirp_log_likelihood", "uwbwb.filters.doppler.pf._moments_rows",
                       "uwbwb.filters.particle._systematic")))
    # not bit for bit: the compiled loop's products and S⁻¹ are plain loops where the Python run calls BLAS and LAPACK
    # (as the EKF's compiled run); on these cases the estimates differ by at most 3e-14 of a metre (m/s, m²), the
    # hypotheses, their count and the beacons chosen are equal
    mh_tol = {**dict.fromkeys(("pos_m", "vel_mps", "pos_cov_m2"), Tol(1e-9, 1e-12)),
              **dict.fromkeys(("status", "n_hypotheses", "beacon"), BIT)}
    for case, ranges, settings in (("default", False, {}), ("ranges, clutter", True,
                                                            {"spurious_rate_hz": 5.0, "p_detect": 0.8})):
        twins.append(Twin(f"doppler.ScaatMhEkf.run[{case}]",
                          lambda a: _mh_outputs(a[0].run(a[1], a[3], ranges_m=a[2])),
                          lambda a: _mh_outputs(a[0]._run_python(a[1], a[3], a[2])), _mh_inputs(ranges, **settings),
                          mh_tol, "tests/golden/test_doppler_golden.py::"
                                  "test_every_doppler_configuration_reproduces_the_golden_outputs",
                          ("uwbwb.filters.doppler.scaat._mh_loop", "uwbwb.filters.doppler.scaat._transition",
                           "uwbwb.filters.doppler.scaat._doppler_rows", "uwbwb.filters.ekf.kernels._predict",
                           "uwbwb.filters.ekf.kernels._update", "uwbwb.filters.ekf.kernels._lu"), _mh_exercised))
    twins.append(Twin("sampling._brute_kernel", _brute_fast, _brute_definition, _brute_inputs,
                      {"counts": BIT, "delta_m": Tol(1e-9, 0.0)},
                      "tests/test_sampling.py::test_kernel_counts_equal_numpy_on_the_same_stream",
                      ("uwbwb.sampling._brute_kernel",), _brute_exercised))
    # not bit for bit: NumPy forms M = AᵀA and Aᵀb with einsum and solves with LAPACK's LU, the compiled loop sums
    # the products in its own order and solves through the Cholesky factor; on these cases the results differ by
    # up to 5 ULP of the largest element (v*), the decisions (which positions take draws) are equal
    for case, ranges in (("Doppler", False), ("with ranges", True)):
        twins.append(Twin(f"sampling._ellipsoids[{case}]", _ellipsoid_fast, _ellipsoid_definition,
                          _ellipsoid_inputs(ranges), {**dict.fromkeys(("L", "v_star", "r2", "rr2"), Tol(ulps=64)),
                                                      "active": BIT},
                          "tests/test_sampling.py::test_conditional_agrees_with_brute_force_within_intervals",
                          ("uwbwb.sampling._ellipsoids",), _ellipsoid_exercised))
    twins.append(Twin("ins.error_transition", lambda a: {"F": ins.error_transition(*a)}, _transition_definition,
                      _transition_inputs, {"F": Tol(0.0, 1e-14)},
                      "tests/models/test_ins.py::test_block_transition_equals_the_matrix_series"))
    for dim in (2, 3):
        twins.append(Twin(f"geometry.multilaterate[gauss-newton, {dim}-D]", _multilaterate("gauss-newton"),
                          _multilaterate("least_squares"), _multilateration_inputs(dim),
                          {"pos_m": Tol(0.0, 1e-6), "cov_m2": Tol(1e-4, 1e-12), "ok": BIT},
                          "tests/test_geometry.py::test_gauss_newton_and_least_squares_agree",
                          exercised=lambda out: None if out["ok"].all() else "an epoch without a fix"))
    # bit for bit on the machines measured: the same differences, quotients and products; each squared length is
    # three products summed in the order NumPy's einsum takes here (x² + z², then + y²), which is its SIMD loop's
    # choice and may be another on other CPUs: then a distance differs by an ulp (1e-14 m at these ranges) and a
    # Jacobian entry by an ulp of the largest
    for dim, static in ((2, False), (2, True), (3, False), (3, True)):
        twins.append(Twin(f"track.residuals_jacobian[{dim}-D{', static' if static else ''}]", _track_terms(True),
                          _track_terms(False), _track_inputs(dim, static),
                          {"res_m": Tol(0.0, 1e-14), "res_only_m": Tol(0.0, 1e-14), "J": Tol(ulps=4)},
                          "tests/models/test_track.py::test_gradient_and_jacobian_match_finite_differences",
                          ("uwbwb.models.track._residuals_jacobian",)))
    # not bit for bit: the compiled loop solves the 2 × 2 normal equations in closed form where multilaterate takes
    # LAPACK's eigen-decomposition, so each step differs by rounding; both stop once a step is below 1e-9 m, so
    # the fixes differ by far less than that (1e-9 m here, which the tuple counts show hides no other decision)
    twins.append(Twin("pruning.tuple_fixes", _tuple_fast, _tuple_definition, _tuple_inputs,
                      {"pos_m": Tol(0.0, 1e-9), "tuple_index": BIT, "n_failed": BIT},
                      "tests/filters/test_pruning.py::test_tuple_fixes_noise_free_and_collinear_tuples_skipped",
                      ("uwbwb.filters.pruning._tuple_gauss_newton", "uwbwb.filters.pruning._solve2")))
    # bit for bit: the same distances and sums in the same order; only points at exactly the cut distance could be
    # dropped otherwise (argpartition leaves that open: the kept mask, and by rounding the centroid, would differ)
    twins.append(Twin("pruning.robust_mean[static]", _robust_mean_fast, _robust_mean_definition, _robust_mean_inputs,
                      {"kept": BIT, "history_m": BIT},
                      "tests/filters/test_pruning.py::test_robust_mean_keeps_the_cluster_and_drops_the_scatter",
                      ("uwbwb.filters.pruning._static_robust_mean",)))
    # bit for bit here (the same products and sums in the same order), but the definition's norms and F x are BLAS
    # calls whose summation order (and use of FMA) depends on the CPU: a few ulps per step, which the stable pursuit
    # loop does not amplify past 1e-9 m
    twins.append(Twin("walk._steer_loop", _steer_fast, _steer_definition, _steer_inputs, {"x": Tol(0.0, 1e-9)},
                      "tests/sim/test_walk.py::test_steering_follows_the_path_at_the_scenario_speed",
                      ("uwbwb.sim.walk._steer_loop",)))
    # bit for bit: the same products summed over the rows in the same order, and medians (an element, or (a + b) / 2
    # on both sides) whatever the order
    twins.append(Twin("calibration._irls", _irls_fast, _irls_definition, _irls_inputs,
                      dict.fromkeys(("bias", "scale", "median", "sigma", "rms"), BIT),
                      "tests/test_calibration.py::test_recovers_known_bias_and_scale_despite_outliers",
                      ("uwbwb.calibration.twr._irls", "uwbwb.calibration.twr._median"),
                      lambda out: None if len(set(_irls_inputs()[2].sum(0).ravel() % 2)) == 2
                      else "sample counts of one parity only"))
    # bit for bit: a median is one of the epochs (or the mean of two, (a + b) / 2 on both sides), whatever the order
    twins.append(Twin("metrics._median_replicates", _median_fast, _median_definition, _median_inputs,
                      {"d": BIT, "ratio": BIT},
                      "tests/test_metrics.py::test_block_bootstrap_median_difference_sees_a_shift_and_not_a_tie",
                      ("uwbwb.metrics.errors._median_replicates",)))
    # not bit for bit: the Python loop's products and S⁻¹ are BLAS and LAPACK calls (their summation order depends
    # on the CPU's kernels), the compiled loop's are plain loops. A filter carries a rounding difference from
    # epoch to epoch and grows it where its gain is high (the first epochs, re-acquiring after a gap), as it
    # carries a one-ulp change of its prior: on these cases the Python loop itself moves by up to 750 ULP of the
    # largest element for such a change, the compiled loop differs by up to 710 (states), 30 (covariances), 560
    # (NIS) with the TDoAs, 82, 135, 283 with the ranges (whose lengths are the same operations as numpy's norm);
    # the bounds below are those with a margin for other CPUs' kernels. The decisions are equal. The Robust cases
    # (reweighted passes after a screening gate that fires) stay within the same bounds.
    ekf_tol = {"x_prior": Tol(ulps=2048), "x_post": Tol(ulps=2048), "P_prior": Tol(ulps=256),
               "P_post": Tol(ulps=256), "nis": Tol(ulps=2048), **{f: BIT for f in _EKF_INTS}}
    ekf_kernels = tuple(f"uwbwb.filters.ekf.kernels.{f}" for f in (
        "_loop", "_reference", "_linearise", "_mul", "_mul_t", "_symmetric", "_predict", "_lu", "_lu_solve",
        "_quadratic", "_nis", "_update", "_use", "_add_into"))
    for case, motion, gate, correlated, gated, dropped in (
            ("no gate, RW 2-D", RandomWalk(0.3, dim=2), NoGate(), True, False, False),
            ("χ² epoch, RF 2-D, diagonal Σ", RandomForce(0.5, dim=2), ChiSquareEpoch(0.999), False, True, False),
            ("χ² per measurement, RJ 2-D", RandomJerk(1.0, dim=2), ChiSquarePerMeasurement(0.999, 2), True, True, True),
            ("anchor dropping, RF 2-D", RandomForce(0.5, dim=2), AnchorDropping(0.9999, 2), True, True, True),
            ("anchor dropping, RJ 3-D", RandomJerk(1.0, dim=3), AnchorDropping(0.999, 3), True, True, True),
            ("robust Huber, χ² per measurement, RF 2-D", RandomForce(0.5, dim=2),
             Robust(gate=ChiSquarePerMeasurement(0.999, 2)), True, True, True),
            ("robust Cauchy, χ² epoch, RF 2-D, diagonal Σ", RandomForce(0.5, dim=2),
             Robust("cauchy", gate=ChiSquareEpoch(0.999)), False, True, False)):
        twins.append(Twin(f"ekf.TdoaEkf.run[{case}]", _tdoa_ekf_fast, _tdoa_ekf_definition,
                          _tdoa_ekf_inputs(motion, gate, correlated), ekf_tol,
                          "tests/filters/test_ekf.py::test_compiled_run_equals_the_python_loop", ekf_kernels,
                          _tdoa_ekf_exercised(gated, dropped)))
    for case, motion, gate, gated, dropped in (
            ("no gate, RF 2-D", RandomForce(0.5, dim=2), NoGate(), False, False),
            ("χ² epoch, RW 2-D", RandomWalk(0.3, dim=2), ChiSquareEpoch(0.999), True, False),
            ("anchor dropping, RF 2-D", RandomForce(0.5, dim=2), AnchorDropping(0.9999, 2), True, True),
            ("anchor dropping, RJ 3-D", RandomJerk(1.0, dim=3), AnchorDropping(0.999, 3), True, True),
            ("robust Huber, no gate, RF 2-D", RandomForce(0.5, dim=2), Robust(), False, False),
            ("robust Huber, χ² epoch, RW 2-D", RandomWalk(0.3, dim=2), Robust(gate=ChiSquareEpoch(0.999)), True,
             False),
            ("robust Cauchy, anchor dropping, RF 2-D", RandomForce(0.5, dim=2),
             Robust("cauchy", gate=AnchorDropping(0.9999, 2)), True, True)):
        twins.append(Twin(f"ekf.RangeEkf.run[{case}]", _tdoa_ekf_fast, _tdoa_ekf_definition,
                          _tdoa_ekf_inputs(motion, gate, ranges=True), ekf_tol,
                          "tests/filters/test_ekf_ranges.py::test_compiled_run_equals_the_python_loop", ekf_kernels,
                          _tdoa_ekf_exercised(gated, dropped)))
    return tuple(twins)


#: Every declared twin, by name.
TWINS: dict[str, Twin] = {t.name: t for t in _registry()}


def compile_kernels() -> int:
    """Run the fast side of every twin once, so that numba compiles each kernel for the argument types the
    workbench uses and writes it to its on-disk cache (``cache=True``): a student's first run then loads the
    kernels instead of compiling them (about 30 s on 2 cores). Returns the number of twins run."""
    for twin in TWINS.values():
        twin.fast(twin.inputs())
    return len(TWINS)


if __name__ == "__main__":
    print(f"compiled the kernels of {compile_kernels()} twins")
