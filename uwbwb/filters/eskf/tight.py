"""The tightly coupled 15-state error-state filter (:class:`TightEskf`): configuration, the Python
reference (:meth:`TightEskf.run_reference`) and the call of the compiled loop (:mod:`.kernels`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ... import validate
from ...models.imu import HeadingLog, ImuErrorModel
from ...models.ins import (BA_, BG_, N_ERR, P_, TH_, V_, InsErrorTransition, Mechanization, NavState, _dcm, _yaw,
                           inject, reset_jacobian, yaw_jacobian)
from ...types import EstimateStatus, ImuLog, RangeLog, TdoaLog
from .. import kalman
from ..ekf import Linearisation
from ..gating import ChiSquarePerMeasurement, NoGate, ungated_update
from ..kalman import Gaussian
from .common import _DEG, _ITER_TOL_M, HEADING_KNOWN_RAD, LOST_BUILD_S, _lever, check_inputs, gap_timeline
from .kernels import INTS, SCALARS, _tight_loop
from .result import FusionRun, _empty, _wrap
from .updates import RangeUpdate, TdoaUpdate, _tag_jacobian


# ====================================================================== tight
def _checked_covariance(P0) -> np.ndarray:
    """``P0`` as a fresh symmetric ``(15, 15)`` array, or a ValueError saying what is wrong."""
    P = np.array(P0, float)
    if P.shape != (N_ERR, N_ERR) or not np.all(np.isfinite(P)):
        raise ValueError(f"P0 must be a finite ({N_ERR}, {N_ERR}) covariance, got shape {P.shape}")
    if not np.allclose(P, P.T, rtol=1e-9, atol=1e-12) or np.any(np.diag(P) <= 0):
        raise ValueError("P0 must be symmetric with a positive diagonal")
    return 0.5 * (P + P.T)


@dataclass(frozen=True)
class TightEskf:
    """Tightly coupled 15-state error-state filter (module docstring).

    Its Python definition (:meth:`run_reference`) is a model, the Gaussian engine and options:

    * **model** — the nominal state moves with :class:`~uwbwb.models.ins.Mechanization`; the error
      state ``δx`` is predicted by the engine (:func:`~uwbwb.filters.kalman.predict`) with the
      ``(F, Q)`` of :attr:`transition` (:class:`~uwbwb.models.ins.InsErrorTransition`: an IMU step,
      or a coast across an IMU gap); after each epoch ``δx`` is injected into the nominal state and
      reset, ``P ← G P Gᵀ`` (closed loop).
    * **measurements** — per epoch, the UWB rows the gate keeps (``uwb.linearise`` at the nominal
      tag position), the heading and the known height, each a
      :class:`~uwbwb.filters.ekf.Linearisation` in error-state form (predicted measurement
      ``h(x̂) + H δx``), stacked (:meth:`Linearisation.stack`) and applied by the engine's
      sequential update (:func:`~uwbwb.filters.gating.ungated_update` with ``sequential=True``);
      the epoch's NIS is the sum of the UWB rows' ``UpdateInfo.nis_rows``. An iterated update
      re-linearises the UWB rows and goes through the same route.
    * **options** — the row test is :attr:`row_gate` (``keep`` / ``threshold``); the start-up
      engagement (``gate_yaw_sigma_rad``) and the lost-lock release (``max_gated``, with the
      inflation of :meth:`lost_lock_variance`) are this filter's own rules, described below.

    The compiled loop (:func:`~.kernels._tight_loop`) does the same arithmetic in one function.

    Attributes
    ----------
    imu_model
        IMU errors: the process noise (white noise, bias random walks) and the initial bias
        uncertainty; its ``mag_heading_sigma_rad`` is the heading measurement's σ.
    uwb
        :class:`TdoaUpdate` or :class:`RangeUpdate`.
    mechanization
        Navigation frame and gravity.
    lever_arm_m
        Tag position relative to the IMU in the body frame, m.
    gate_prob
        Per-measurement χ²(1) gate probability: a UWB row is rejected when ``y_i² / S_ii`` exceeds
        :meth:`ChiSquarePerMeasurement(gate_prob).threshold()
        <uwbwb.filters.gating.ChiSquarePerMeasurement.threshold>`; None: no gate.
    max_gated
        Lost lock: after this many consecutive epochs in which the gate rejected at least half of
        the UWB measurements (outliers are a minority; a majority rejected means the prior is
        wrong), the filter admits the lost lock: it inflates ``P`` (:meth:`lost_lock_variance`)
        and uses the next epoch ungated, so that it re-acquires. Closed loop only: open loop
        linearises at the uncorrected nominal, where an inflated update metres away makes
        things worse, so it keeps its gate throughout.
    iterate_sigma_m
        Prior tag-position σ (``√trace``), m, above which the UWB update is iterated (IEKF:
        relinearised at the updated position until it moves less than 0.1 mm, at most
        ``max_iter`` linearisations). With TDoAs the first relinearisation is at the epoch's own
        snapshot fix (:meth:`TdoaUpdate.snapshot`) when it has a consistent one, so a prior tens
        of metres off (after a UWB outage) is not linearised where a TDoA is nearly flat.
        Default 1 m: a range linearised 1 m from the truth at 4 m from an anchor is off by about
        ``δ²/2r`` ≈ 0.12 m, several range σ; in normal tracking the prior σ is centimetres and
        nothing changes. Measured on 8 synthetic i-ASL flights with a 30 s outage (consumer
        IMU, error 33–80 m when UWB returns): without it tight TDoA/range filters ended 0.8 m to
        10¹¹ m off; with it every run was back under 0.5 m within 0.1 s. ``inf`` turns it off.
        The σ is that of the propagated prior, before a lost-lock inflation: an inflation is a
        guess from innovations that may be outliers, and relinearising on them was seen to
        diverge (RMSE 0.92 → 5.7 m, max 60 m, on the outlier-laden golden run with
        ``gate_prob=0.6, max_gated=2``).
    max_iter
        Most linearisations of one iterated update.
    gate_yaw_sigma_rad
        Start-up: with an initial yaw σ above :data:`HEADING_KNOWN_RAD` (10°; an in-motion heading
        alignment), the gate engages (once, for the rest of the run) only when the heading is
        resolved: the prior yaw σ is at most this and ``max_gated`` consecutive epochs have passed
        in which the gate would have rejected fewer than half of the UWB measurements. With a
        known initial heading it is engaged from the first epoch. Before that every
        measurement is used: during an in-motion heading alignment (yaw σ tens of degrees) the
        innovations are large because the attitude is wrong, not because the measurements are,
        and a gate would lock the filter out.
    q_scale, r_scale
        Multipliers on the process-noise and UWB measurement variances.
    feedback
        Closed loop (True) or open loop (False).
    height_m, height_sigma_m
        Known tag height (a ground robot) used as a pseudo-measurement at every epoch; None: not used.
    init_sigma
        Initial error SDs: position m, velocity m/s, roll/pitch rad, yaw rad.
    max_imu_gap_s
        An interval between IMU samples longer than this is a gap: the filter coasts across it
        (:func:`~uwbwb.models.ins.coast_transition`: velocity and attitude held, no IMU value
        interpolated or invented, the covariance grown by the assumed motion below) and keeps
        updating at the UWB epochs inside it; the gaps are listed in ``FusionRun.meta["imu_gaps_s"]``.
        None: :data:`MAX_IMU_GAP_STEPS` (5) median IMU steps, the loader's rule
        (:mod:`uwbwb.datasets.imu_checks`).
    coast_acc_sigma_mps2, coast_rate_sigma_radps
        Assumptions for a coast: the unknown acceleration and rotation rate, as white noise of
        PSD ``σ² · 1 s`` (1 m/s² and 0.2 rad/s: a walking person or a slow drone).
    """

    imu_model: ImuErrorModel
    uwb: TdoaUpdate | RangeUpdate
    mechanization: Mechanization = Mechanization()
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gate_prob: float | None = 0.999
    max_gated: int = 5
    q_scale: float = 1.0
    r_scale: float = 1.0
    feedback: bool = True
    height_m: float | None = None
    height_sigma_m: float = 0.01
    init_sigma: tuple[float, float, float, float] = (0.3, 0.1, 2 * _DEG, 5 * _DEG)
    iterate_sigma_m: float = 1.0
    max_iter: int = 10
    gate_yaw_sigma_rad: float = 3 * _DEG
    max_imu_gap_s: float | None = None
    coast_acc_sigma_mps2: float = 1.0
    coast_rate_sigma_radps: float = 0.2
    name: str = "tight"

    def __post_init__(self):
        if not isinstance(self.imu_model, ImuErrorModel):
            raise ValueError(f"TightEskf.imu_model must be an ImuErrorModel, got {self.imu_model!r}")
        if not isinstance(self.uwb, (TdoaUpdate, RangeUpdate)):
            raise ValueError(f"TightEskf.uwb must be a TdoaUpdate or a RangeUpdate, got {type(self.uwb).__name__}")
        if not isinstance(self.mechanization, Mechanization):
            raise ValueError(f"TightEskf.mechanization must be a Mechanization, got {self.mechanization!r}")
        object.__setattr__(self, "lever_arm_m", _lever("TightEskf.lever_arm_m", self.lever_arm_m))
        if self.gate_prob is not None:
            validate.probability("TightEskf.gate_prob", self.gate_prob)
        validate.integer("TightEskf.max_gated", self.max_gated, minimum=1)
        validate.number("TightEskf.gate_yaw_sigma_rad", self.gate_yaw_sigma_rad, minimum=0.0, strict_minimum=True,
                        maximum=math.pi)
        validate.number("TightEskf.q_scale", self.q_scale, minimum=0.0, strict_minimum=True)
        validate.number("TightEskf.r_scale", self.r_scale, minimum=0.0, strict_minimum=True)
        validate.choice("TightEskf.feedback", self.feedback, (True, False))
        if self.height_m is not None:
            validate.number("TightEskf.height_m", self.height_m)
        validate.number("TightEskf.height_sigma_m", self.height_sigma_m, minimum=0.0, strict_minimum=True)
        init = tuple(self.init_sigma) if isinstance(self.init_sigma, (tuple, list, np.ndarray)) else ()
        if len(init) != 4:
            raise ValueError(f"TightEskf.init_sigma must be 4 SDs (position m, velocity m/s, roll/pitch rad, "
                             f"yaw rad), got {self.init_sigma!r}")
        for what, v, hi in zip(("position", "velocity", "roll/pitch", "yaw"), init, (None, None, math.pi, math.pi)):
            validate.number(f"TightEskf.init_sigma ({what})", v, minimum=0.0, strict_minimum=True, maximum=hi)
        object.__setattr__(self, "init_sigma", tuple(float(v) for v in init))
        validate.number("TightEskf.iterate_sigma_m", self.iterate_sigma_m, minimum=0.0, allow_inf=True)
        validate.integer("TightEskf.max_iter", self.max_iter, minimum=1)
        if self.max_imu_gap_s is not None:
            validate.number("TightEskf.max_imu_gap_s", self.max_imu_gap_s, minimum=0.0, strict_minimum=True)
        validate.number("TightEskf.coast_acc_sigma_mps2", self.coast_acc_sigma_mps2, minimum=0.0)
        validate.number("TightEskf.coast_rate_sigma_radps", self.coast_rate_sigma_radps, minimum=0.0)
        if not isinstance(self.name, str):
            raise ValueError(f"TightEskf.name must be a string, got {self.name!r}")

    # ---------------------------------------------------------------- noise
    def initial_covariance(self) -> np.ndarray:
        sp, sv, stilt, syaw = self.init_sigma
        m = self.imu_model
        d = np.concatenate([[sp] * 3, [sv] * 3, [stilt, stilt, syaw], [max(m.acc_bias_sigma_mps2, 1e-6)] * 3,
                            [max(m.gyro_bias_sigma_radps, 1e-8)] * 3])
        return np.diag(d ** 2)

    def lost_lock_variance(self, innovation_ms_m2: float = 0.0) -> np.ndarray:
        """What a lost lock adds to the diagonal of ``P`` before the ungated epoch, ``(15,)``.

        Position: the initial variance plus the mean squared UWB innovation of the epoch
        (``innovation_ms_m2``, m²: how far off the measurements say the filter is); velocity: the
        initial variance plus that over ``(1 s)²`` (an assumption: the error built up over about a
        second); attitude and biases: nothing (an attitude error shows as velocity error; adding
        yaw variance would restart the heading alignment).
        """
        d = np.diag(self.initial_covariance()).copy()
        d[TH_] = d[BA_] = d[BG_] = 0.0
        d[P_] += innovation_ms_m2
        d[V_] += innovation_ms_m2 / LOST_BUILD_S ** 2
        return d

    def process_noise_rate(self) -> np.ndarray:
        """Diagonal of ``G Q_c Gᵀ`` per second (isotropic noises: no attitude dependence), ``(15,)``."""
        m = self.imu_model
        q = np.zeros(N_ERR)
        q[V_] = m.acc_noise_density ** 2
        q[TH_] = m.gyro_noise_density ** 2
        q[BA_] = m.acc_bias_rw ** 2
        q[BG_] = m.gyro_bias_rw ** 2
        return q * self.q_scale

    @property
    def transition(self) -> InsErrorTransition:
        """The error-state transition model: :meth:`process_noise_rate` and the coast assumptions."""
        return InsErrorTransition(self.process_noise_rate(), self.coast_acc_sigma_mps2, self.coast_rate_sigma_radps)

    @property
    def row_gate(self) -> ChiSquarePerMeasurement | NoGate:
        """The per-row test: :class:`~uwbwb.filters.gating.ChiSquarePerMeasurement` (``gate_prob``)
        or, without a gate, :class:`~uwbwb.filters.gating.NoGate`. Only its decision part is read
        (``keep``, ``threshold``); when it applies (start-up engagement) and when it is released
        (lost lock) are this filter's rules, not the policy's ``active``."""
        if self.gate_prob is None:
            return NoGate(max_gated=self.max_gated)
        return ChiSquarePerMeasurement(self.gate_prob, max_gated=self.max_gated)

    # ---------------------------------------------------------------- run
    def run(self, imu: ImuLog, uwb: TdoaLog | RangeLog | None, x0: NavState, *, t_s: np.ndarray | None = None,
            heading: HeadingLog | None = None, acc_bias0=None, gyro_bias0=None, P0=None, name: str | None = None,
            reference_step: bool = False, fix_tag: np.ndarray | None = None) -> FusionRun:
        """Filter a recording.

        Parameters
        ----------
        imu
            Body-frame SI samples (see :class:`~uwbwb.models.imu.ImuConvention`).
        uwb
            TDoA log (with :class:`TdoaUpdate`) or range log (with :class:`RangeUpdate`);
            None: INS only (no UWB updates at all).
        x0
            Navigation state at the first IMU sample.
        t_s
            Output epochs when ``uwb`` is None (default: the IMU times).
        heading
            Magnetometer headings, used at the UWB epochs if given.
        acc_bias0, gyro_bias0
            Initial bias estimates (default zero).
        P0
            Initial error-state covariance ``(15, 15)`` (default :meth:`initial_covariance`), e.g.
            the covariance a heading alignment ended with: a filter started from another filter's
            state should inherit how well that state is known.
        reference_step
            Same as :meth:`run_reference` (kept as an alias): run the straightforward form, step
            by step in Python (the mechanization and the engine's predict with :attr:`transition`
            at every IMU step, the epoch's rows through the engine's sequential update; for
            benchmarks and tests) instead of the compiled loop (:func:`_tight_loop`: the
            accumulated transition once per epoch, same updates); results are identical up to
            rounding (tested).
        fix_tag
            The snapshot fixes of ``uwb`` (:meth:`TdoaUpdate.snapshot` of its TDoAs after :meth:`TdoaUpdate.screen`,
            ``(T, 3)``) when the caller has them: runs of several filters with this ``uwb`` model on one log share
            them (:func:`uwbwb.experiments.uwb_ins.study.start`); None computes them here.
        """
        check_inputs("TightEskf.run", imu, x0)
        t_ep = (imu.t_s if t_s is None else np.asarray(t_s, float)) if uwb is None else uwb.t_s
        T = t_ep.size
        if uwb is not None and isinstance(uwb, TdoaLog) != isinstance(self.uwb, TdoaUpdate):
            raise ValueError("TightEskf.run: a TdoaLog needs a TdoaUpdate model and a RangeLog a RangeUpdate")
        rows, refs, n_out_all = None, None, np.zeros(T, int)
        if uwb is not None:
            refs = uwb.ref if isinstance(uwb, TdoaLog) else np.zeros(T, int)
            rows, n_out_all = self.uwb.screen(uwb.tdoa_m if isinstance(uwb, TdoaLog) else uwb.range_m, refs)
        given, fix_tag = fix_tag, np.full((T, 3), np.nan)   # first linearisation point of an iterated update
        if rows is not None and isinstance(self.uwb, TdoaUpdate) and math.isfinite(self.iterate_sigma_m):
            fix_tag = self.uwb.snapshot(t_ep, rows, refs) if given is None else np.asarray(given, float)
            if fix_tag.shape != (T, 3):
                raise ValueError(f"TightEskf.run: fix_tag must have shape ({T}, 3), got {fix_tag.shape}")
        # epochs inside an IMU gap: nothing measured there, so no IMU value is invented (NaN)
        t, acc, gyro, ep_idx, coasting, gaps_s = gap_timeline(imu, t_ep, self.max_imu_gap_s)
        meta = {"imu_gaps_s": gaps_s}
        yaw_meas = heading.at(t_ep) if heading is not None else np.full(T, np.nan)
        out = _empty(T, N_ERR)
        mech, lever = self.mechanization, self.lever_arm_m
        p, v, q = x0.pos_m.copy(), x0.vel_mps.copy(), x0.quat.copy()
        ba = np.zeros(3) if acc_bias0 is None else np.array(acc_bias0, float)
        bg = np.zeros(3) if gyro_bias0 is None else np.array(gyro_bias0, float)
        dx = np.zeros(N_ERR)
        P = self.initial_covariance() if P0 is None else _checked_covariance(P0)
        transition, gate = self.transition, self.row_gate     # the error-state model and the row test
        qrate = transition.qrate_per_s.copy()                 # the compiled loop's writeable copy of the same rates
        # the row test of the per-measurement policy (its decision part; the release rule is this filter's own)
        gate1 = gate.threshold()
        sig_yaw = self.imu_model.mag_heading_sigma_rad
        gated_run, clean_run = 0, 0
        engaged = bool(P[8, 8] <= HEADING_KNOWN_RAD ** 2)
        # epochs sorted by their place on the time line (several epochs never share one: t is a union)
        order = np.argsort(ep_idx, kind="stable")
        order = order[ep_idx[order] >= 0]
        ep_at = np.full(t.size, -1)
        ep_at[ep_idx[order]] = order
        name = name or (self.name if uwb is not None else "INS-only")
        if not reference_step:
            self._run_compiled(t, acc, gyro, ep_at, rows, refs, yaw_meas, p, v, q, ba, bg, P, qrate, gate1, out,
                               fix_tag, coasting)
            out["n_outliers"][:] = n_out_all
            return FusionRun(t_ep.copy(), name=name, meta=meta, **out)
        # The reference form, step by step in Python: mechanization and the engine's predict with the
        # transition model at every IMU step, then the epoch's rows through the engine's sequential update.
        last = 0
        for i in np.flatnonzero(ep_at >= 0):
            for j in range(last + 1, i + 1):
                dt = t[j] - t[j - 1]
                if coasting[j]:                           # inside an IMU gap: coast
                    p = p + v * dt
                    F, Q = transition.coast(dt)
                else:
                    f0, f1 = acc[j - 1] - ba, acc[j] - ba
                    p, v, q, C0, _ = mech.step(p, v, q, f0, f1, gyro[j - 1] - bg, gyro[j] - bg, dt)
                    F, Q = transition.step(C0, f0, dt)
                st = kalman.predict(Gaussian(dx, P), F, Q)
                dx, P = st.x, st.P
            last = i
            k = ep_at[i]
            C = _dcm(q)
            J_tag = _tag_jacobian(C, lever)
            tag = p + C @ lever
            far = np.sqrt(np.trace(J_tag @ P @ J_tag.T)) > self.iterate_sigma_m   # before any lost-lock inflation
            parts = []                                   # the epoch's rows used, error-state Linearisations
            n_gated, n_out = 0, int(n_out_all[k])
            uwb_used = 0
            keep = None
            if rows is not None:
                lin = self.uwb.linearise(tag, J_tag, rows[k], int(refs[k]))
                if lin is not None:
                    y = lin.z - lin.h - lin.H @ dx
                    if gated_run >= self.max_gated:         # lock lost: admit it, then re-acquire ungated
                        P = P + np.diag(self.lost_lock_variance(float(np.mean(y * y))))
                    lin = replace(lin, R=lin.R * self.r_scale)
                    s = np.einsum("ij,jk,ik->i", lin.H, P, lin.H) + np.diag(lin.R)
                    test = gate.keep(y, s)
                    keep = test if engaged and gated_run < self.max_gated else np.ones(y.size, bool)
                    if not engaged:                       # start-up: is the heading resolved?
                        clean_run = clean_run + 1 if 2 * int((~test).sum()) < y.size else 0
                        engaged = clean_run >= self.max_gated and P[8, 8] <= self.gate_yaw_sigma_rad ** 2
                    n_gated = int((~keep).sum())
                    if keep.any():
                        parts.append(_error_form(lin.rows(keep), dx))
                        uwb_used = int(keep.sum())
                    lost = n_gated >= uwb_used and self.feedback
                    gated_run = gated_run + 1 if (n_gated and lost) else 0
            if np.isfinite(yaw_meas[k]) and sig_yaw > 0:
                Hy = np.zeros(N_ERR)
                Hy[TH_] = yaw_jacobian(C)
                resid = _wrap(yaw_meas[k] - _yaw(C))     # z − h(x̂), wrapped; h(x̂) + H δx − h(x̂) = H δx
                parts.append(Linearisation(np.array([resid]), np.array([Hy @ dx]), Hy[None],
                                           np.array([[sig_yaw ** 2]])))
            if self.height_m is not None:
                parts.append(Linearisation(np.array([self.height_m]), np.array([tag[2] + J_tag[2] @ dx]),
                                           J_tag[2:3], np.array([[self.height_sigma_m ** 2]])))
            nis, dof = np.nan, 0
            if parts:
                st, info = ungated_update(Gaussian(dx, P), Linearisation.stack(parts), sequential=True)
                nis = float(info.nis_rows[:uwb_used].sum()) if uwb_used else np.nan
                dof = uwb_used
                if uwb_used and far:
                    # iterated update (IEKF): relinearise the UWB rows at the updated tag position
                    for it in range(self.max_iter - 1):
                        d = st.x
                        if it == 0 and np.all(np.isfinite(fix_tag[k])):   # start at the snapshot fix
                            d = dx.copy()
                            d[P_] = fix_tag[k] - tag - J_tag[:, TH_] @ dx[TH_]
                        li = self.uwb.linearise(tag + d[P_] + J_tag[:, TH_] @ d[TH_], J_tag, rows[k],
                                                int(refs[k])).rows(keep)
                        # at x̂ ⊕ δx_i: h(x_i) + H_i (δx − δx_i), so y = z − h(x_i) − H_i (δx − δx_i) − H_i δx
                        # (z and the scaled R of the first pass)
                        parts[0] = _error_form(replace(li, z=parts[0].z, R=parts[0].R), dx - d)
                        st, _ = ungated_update(Gaussian(dx, P), Linearisation.stack(parts), sequential=True)
                        if np.max(np.abs(st.x[P_] - d[P_])) < _ITER_TOL_M:
                            break
                dx, P = st.x, st.P
            if self.feedback:
                p, v, q, ba, bg = inject(p, v, q, ba, bg, dx)
                Gt = reset_jacobian(dx[TH_])[TH_, TH_]       # G P Gᵀ: G differs from I only there
                P = P.copy()
                P[TH_, :] = Gt @ P[TH_, :]
                P[:, TH_] = P[:, TH_] @ Gt.T
                dx = np.zeros(N_ERR)
                po, vo, qo, bao, bgo = p, v, q, ba, bg
            else:
                po, vo, qo, bao, bgo = inject(p, v, q, ba, bg, dx)
            Co = _dcm(qo)
            Jo = _tag_jacobian(Co, lever)
            out["pos_m"][k] = po + Co @ lever
            out["vel_mps"][k], out["quat"][k] = vo, qo
            out["acc_bias_mps2"][k], out["gyro_bias_radps"][k] = bao, bgo
            out["P"][k] = P
            out["pos_cov_m2"][k] = Jo @ P @ Jo.T
            out["nis"][k], out["dof"][k], out["n_outliers"][k], out["n_gated"][k] = nis, dof, n_out, n_gated
            out["status"][k] = (EstimateStatus.UPDATED if uwb_used else
                                EstimateStatus.GATED if n_gated else EstimateStatus.PREDICTED)
        return FusionRun(t_ep.copy(), name=name, meta=meta, **out)

    def run_reference(self, imu: ImuLog, uwb: TdoaLog | RangeLog | None, x0: NavState, *,
                      t_s: np.ndarray | None = None, heading: HeadingLog | None = None, acc_bias0=None,
                      gyro_bias0=None, P0=None, name: str | None = None) -> FusionRun:
        """The Python definition of :meth:`run` (its ``reference_step=True``), as model + engine +
        options (class docstring): per IMU step the mechanization and
        :func:`kalman.predict <uwbwb.filters.kalman.predict>` with ``transition.step`` /
        ``transition.coast``; per epoch the rows :attr:`row_gate` keeps, the heading and the height
        as error-state :class:`~uwbwb.filters.ekf.Linearisation` objects, stacked and applied by
        :func:`~uwbwb.filters.gating.ungated_update` with ``sequential=True``
        (:func:`kalman.update_sequential <uwbwb.filters.kalman.update_sequential>`); then the
        injection and reset. The compiled loop must equal it to rounding (the twin tests)."""
        return self.run(imu, uwb, x0, t_s=t_s, heading=heading, acc_bias0=acc_bias0, gyro_bias0=gyro_bias0,
                        P0=P0, name=name, reference_step=True)

    def _run_compiled(self, t, acc, gyro, ep_at, rows, refs, yaw_meas, p, v, q, ba, bg, P, qrate, gate1, out,
                      fix_tag, coasting):
        """The filter of :meth:`run` as one compiled loop (:func:`_tight_loop`), writing into ``out``."""
        T = yaw_meas.size
        kind, anchors, var_m, correlated, bias_m = 0, np.empty((0, 3)), np.empty(0), False, 0.0
        if rows is not None:
            if isinstance(self.uwb, TdoaUpdate):
                kind, model = 1, self.uwb.model
                anchors, var_m, correlated = model.anchor_pos_m, model.sigma_m ** 2, model.correlated
                # TdoaModel.epoch refuses a reference without a measurement; so does this path
                usable = (refs >= 0) & (np.isfinite(rows).sum(axis=1) >= 2)
                bad = np.flatnonzero(usable & ~np.isfinite(rows[np.arange(T), np.clip(refs, 0, None)]))
                if bad.size:
                    raise ValueError(f"TdoaModel.epoch: reference {refs[bad[0]]} is not among the measured anchors "
                                     f"of epoch {bad[0]}")
            else:
                kind, anchors, var_m, bias_m = 2, self.uwb.anchor_pos_m, self.uwb.sigma_m ** 2, self.uwb.bias_m
        else:
            rows, refs = np.empty((T, 0)), np.zeros(T, np.int64)
        tl = np.flatnonzero(ep_at >= 0)
        named = dict(bias_m=bias_m, r_scale=self.r_scale, gate1=gate1, gate_yaw_var=float(self.gate_yaw_sigma_rad) ** 2,
                     heading_known_var=HEADING_KNOWN_RAD ** 2, iterate_sigma_m=self.iterate_sigma_m, iter_tol=_ITER_TOL_M,
                     coast_acc_var=float(self.coast_acc_sigma_mps2) ** 2,
                     coast_rate_var=float(self.coast_rate_sigma_radps) ** 2,
                     sig_yaw=self.imu_model.mag_heading_sigma_rad, height_m=float(self.height_m or 0.0),
                     sig_height=self.height_sigma_m, kind=kind, correlated=correlated, max_gated=self.max_gated,
                     max_iter=self.max_iter, use_height=self.height_m is not None, feedback=bool(self.feedback),
                     st_updated=EstimateStatus.UPDATED, st_gated=EstimateStatus.GATED,
                     st_predicted=EstimateStatus.PREDICTED)
        # rows, refs and anchors as writable copies: numba compiles the loop once per read-only flag of an argument,
        # and a recording's arrays are read-only where a simulated one's are not (one signature, the one
        # `python -m uwbwb.filters.twins` puts in the cache at install, instead of ~30 s of compiling per variant)
        code = _tight_loop(
            (t, acc, gyro, tl, ep_at[tl], np.ascontiguousarray(coasting, np.bool_)),
            (np.array(rows, float, order="C"), np.array(refs, np.int64), np.ascontiguousarray(fix_tag, float),
             np.asarray(yaw_meas, float)),
            np.array([float(named[n]) for n in SCALARS]), np.array([int(named[n]) for n in INTS], np.int64),
            (np.array(anchors, float, order="C"), np.ascontiguousarray(var_m, float), self.lost_lock_variance(),
             self.lever_arm_m, qrate, self.mechanization.g_n),
            (p.copy(), v.copy(), q.copy(), ba.copy(), bg.copy()), P.copy(),
            (out["pos_m"], out["vel_mps"], out["quat"], out["acc_bias_mps2"], out["gyro_bias_radps"], out["P"],
             out["pos_cov_m2"], out["nis"], out["dof"], out["n_gated"], out["status"]))
        if code == 1:
            raise ValueError("update_sequential: non-finite values; a missing measurement is left out, not passed as NaN")
        if code == 2:
            raise ValueError("update_sequential: R must be symmetric positive definite")


def _error_form(lin: Linearisation, dx: np.ndarray) -> Linearisation:
    """Rows linearised at the nominal state ``x̂``, in error-state form about the error mean ``δx``:
    the predicted measurement ``h(x̂) + H δx`` (``z``, ``H``, ``R`` unchanged), so that the engine's
    update of ``δx`` forms the innovation ``z − h(x̂) − H δx``."""
    return replace(lin, h=lin.h + lin.H @ dx)
