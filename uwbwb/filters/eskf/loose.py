"""The paper's loosely coupled filter, eqs 5–7 (:class:`LooseFilter`).

Its UWB update is the Gaussian engine's: the fix (position, and the differenced velocity) is a
linear :class:`~uwbwb.filters.ekf.Linearisation` of the error state, updated through the injected
gate policy (:mod:`uwbwb.filters.gating`) or :func:`~uwbwb.filters.gating.ungated_update`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ... import validate
from ...models.imu import HeadingLog
from ...models.ins import N_ERR, Mechanization, NavState, _dcm, _exp_left, _yaw, coast
from ...types import Estimates, EstimateStatus, ImuLog
from .. import kalman
from ..ekf import Linearisation
from ..gating import ChiSquareEpoch, GatePolicy, NoGate, _chi2_ppf, gate_policy, ungated_update
from ..kalman import Gaussian
from .common import LOST_BUILD_S, _lever, check_inputs, gap_timeline
from .kernels import LOOSE_INTS, LOOSE_SCALARS, _loose_loop
from .result import FusionRun, _empty, _wrap


# ====================================================================== loose (the paper's filter)
def _consistent(innovations: list) -> bool:
    """Whether a run of gated position innovations says the *filter* is off rather than the fixes:
    they change smoothly (a drifting filter against fixes that agree with each other), i.e. the RMS
    step between consecutive innovations is shorter than their mean. Scattered outliers (a
    multipath burst) jump from fix to fix and are not taken for a lost lock."""
    if not innovations:
        return False
    y = np.asarray(innovations, float)
    m = y.mean(axis=0)
    step2 = float(np.mean(np.sum(np.diff(y, axis=0) ** 2, axis=1))) if len(y) > 1 else 0.0
    return bool(m @ m > step2)


_DEFAULT_GATE = (None, 25)      # LooseFilter's gate_prob, max_gated defaults


@dataclass(frozen=True)
class LooseFilter:
    """The paper's loosely coupled filter, eqs 5–7 (module docstring).

    Attributes
    ----------
    dim
        2: the paper's 4 states (E, N); 3: 6 states with the vertical pair.
    q_pos_m_rts, q_vel_mps_rts
        Process noise densities of ``W_P`` and ``W_V`` (eq. 5): over a UWB step ``T`` their
        variances are ``q² T`` (m/√s and m/s/√s).
    sigma_r_pos_m, sigma_r_vel_mps
        Measurement noise SDs of the UWB position and differenced velocity (eq. 6).
    vel_window
        Epochs spanned by the backward difference giving ``V_uwb``.
    attitude_tau_s
        Time constant of the complementary attitude correction (levelling; heading where
        a magnetometer heading is given).
    height_m
        For ``dim=2``: the known tag height the INS vertical channel is held at.
    q_scale, r_scale
        Multipliers on Q and R.
    feedback
        Closed loop (True) or open loop.
    gate_prob
        χ² innovation gate on each epoch's UWB update (position, or position + velocity):
        the update is rejected (status ``GATED``) when its NIS against the prior exceeds the
        ``gate_prob`` quantile of χ²(m), ``m`` the measurement dimension. None: no gate. Stands
        for :class:`~uwbwb.filters.gating.ChiSquareEpoch` when ``gate`` is not given; otherwise
        it mirrors the policy's ``prob`` (None if it has none).
    max_gated
        Consecutive gated epochs after which the next epoch's fix is used ungated, after the
        lock's loss is admitted in ``P`` (:meth:`lost_lock_variance`); mirrors
        ``gate.max_gated`` when ``gate`` is given.
    gate
        Gate policy (:mod:`uwbwb.filters.gating`) on the linear measurement of the fix (rows:
        position, then velocity; :attr:`gate_policy`); None: the one ``gate_prob`` and
        ``max_gated`` stand for. The policy must decide per epoch (:class:`~uwbwb.filters.gating.NoGate`
        or :class:`~uwbwb.filters.gating.ChiSquareEpoch`; its own ``max_gated`` applies): the rows are
        one fix and a velocity differenced from the same fixes, so a per-row decision would keep a
        rejected fix in the velocity difference and, by updating with the remaining rows, never
        count the epoch towards the release. A gated fix does not enter the velocity difference;
        ``n_gated`` is 1 for a gated epoch; its NIS is not reported (NaN, ``dof`` 0). The policy's
        release rule uses the fix after ``max_gated`` gated epochs; before it this filter's own
        lost-lock rule widens ``P`` (:meth:`lost_lock_variance`).
    max_imu_gap_s
        An interval between IMU samples longer than this is a gap: the INS coasts across it
        (:func:`~uwbwb.models.ins.coast`, as :class:`~uwbwb.filters.eskf.TightEskf` does: velocity
        and attitude held, no IMU value interpolated or invented, no levelling at the epochs
        inside it), the covariance grows by the assumed acceleration below, the UWB updates
        continue, and the gaps are listed in ``FusionRun.meta["imu_gaps_s"]``. None:
        :data:`~uwbwb.filters.eskf.MAX_IMU_GAP_STEPS` (5) median IMU steps, the loader's rule.
    coast_acc_sigma_mps2
        Assumption for a coast: the unknown acceleration as white noise of PSD ``σ² · 1 s``
        (1 m/s², as the tight filter; the position/velocity blocks of
        :func:`~uwbwb.models.ins.coast_transition`). The loose error state has no attitude, so the
        tight filter's assumed rotation rate has nothing to act on here.
    """

    mechanization: Mechanization = Mechanization()
    dim: int = 2
    q_pos_m_rts: float = 0.01
    q_vel_mps_rts: float = 0.05
    sigma_r_pos_m: float = 0.05
    sigma_r_vel_mps: float = 0.15
    vel_window: int = 5
    attitude_tau_s: float = 2.0
    height_m: float | None = None
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    q_scale: float = 1.0
    r_scale: float = 1.0
    feedback: bool = True
    gate_prob: float | None = None
    max_gated: int = 25
    max_imu_gap_s: float | None = None
    coast_acc_sigma_mps2: float = 1.0
    name: str = "loose"
    gate: GatePolicy | None = None

    def __post_init__(self):
        if not isinstance(self.mechanization, Mechanization):
            raise ValueError(f"LooseFilter.mechanization must be a Mechanization, got {self.mechanization!r}")
        validate.choice("LooseFilter.dim", self.dim, (2, 3))
        validate.integer("LooseFilter.vel_window", self.vel_window, minimum=1)
        for name in ("q_pos_m_rts", "q_vel_mps_rts"):
            validate.number(f"LooseFilter.{name}", getattr(self, name), minimum=0.0)
        for name in ("sigma_r_pos_m", "sigma_r_vel_mps", "attitude_tau_s", "q_scale", "r_scale"):
            validate.number(f"LooseFilter.{name}", getattr(self, name), minimum=0.0, strict_minimum=True)
        if self.height_m is not None:
            validate.number("LooseFilter.height_m", self.height_m)
        validate.choice("LooseFilter.feedback", self.feedback, (True, False))
        object.__setattr__(self, "lever_arm_m", _lever("LooseFilter.lever_arm_m", self.lever_arm_m))
        if self.gate_prob is not None:
            validate.probability("LooseFilter.gate_prob", self.gate_prob)
        validate.integer("LooseFilter.max_gated", self.max_gated, minimum=0)
        policy = self.gate_policy
        if not isinstance(policy, (NoGate, ChiSquareEpoch)):
            raise ValueError(f"LooseFilter.gate must decide per epoch (NoGate or ChiSquareEpoch), got "
                             f"{type(policy).__name__}: the fix's position and differenced-velocity rows come "
                             f"from the same fixes, so a fix cannot be used in part")
        if self.gate is not None:                       # mirror the given policy (as Ekf does)
            object.__setattr__(self, "gate_prob", getattr(policy, "prob", None))
            object.__setattr__(self, "max_gated", policy.max_gated)
        if self.max_imu_gap_s is not None:
            validate.number("LooseFilter.max_imu_gap_s", self.max_imu_gap_s, minimum=0.0, strict_minimum=True)
        validate.number("LooseFilter.coast_acc_sigma_mps2", self.coast_acc_sigma_mps2, minimum=0.0)

    @property
    def gate_policy(self) -> GatePolicy:
        """The gate the filter runs with: ``gate``, or the one ``gate_prob`` and ``max_gated``
        stand for (:func:`~uwbwb.filters.gating.gate_policy`; default no gate, released after 25)."""
        return gate_policy("LooseFilter", self.gate, self.gate_prob, self.max_gated, _DEFAULT_GATE)

    def lost_lock_variance(self, innovation_ms_m2: float = 0.0) -> np.ndarray:
        """What a lost lock adds to the diagonal of ``P`` before the ungated epoch, ``(2 dim,)``:
        the tight filter's rule (:meth:`~uwbwb.filters.eskf.TightEskf.lost_lock_variance`) on this
        filter's states — position: the initial variance plus the mean squared position innovation
        of the epoch (``innovation_ms_m2``, m²); velocity: the initial variance plus that over
        ``(1 s)²`` (the error assumed built up over about a second). It is added only when the
        gated run's innovations agree on an offset (a lost lock, not a burst of outliers:
        :func:`_consistent`) and at least one epoch was gated. Without it the released fix
        meets a covariance that still claims centimetres, moves the state by a fraction of the
        innovation and the gate shuts again: with the IMU 10× worse than modelled the gated
        filter never re-acquired after a 5 s outage."""
        d = self.dim
        return np.array([self.sigma_r_pos_m ** 2 + innovation_ms_m2] * d
                        + [self.sigma_r_vel_mps ** 2 + innovation_ms_m2 / LOST_BUILD_S ** 2] * d)

    def matrices(self, T_s: float):
        """``A``, ``Q``, ``R`` of eqs 5–6 for UWB period ``T_s``."""
        d = self.dim
        A = np.eye(2 * d)
        A[:d, d:] = T_s * np.eye(d)
        Q = np.diag([self.q_pos_m_rts ** 2] * d + [self.q_vel_mps_rts ** 2] * d) * (T_s * self.q_scale)
        R = np.diag([self.sigma_r_pos_m ** 2] * d + [self.sigma_r_vel_mps ** 2] * d) * self.r_scale
        return A, Q, R

    def run(self, imu: ImuLog, fixes: Estimates, x0: NavState, *, heading: HeadingLog | None = None,
            name: str | None = None, reference_step: bool = False) -> FusionRun:
        """Filter a recording.

        Parameters
        ----------
        imu
            Body-frame SI samples.
        fixes
            UWB position fixes at the UWB epochs (e.g. TDoA LS after the eq-4 test); epochs
            without a fix (``NO_ESTIMATE``) are prediction only.
        x0
            Navigation state at the first IMU sample.
        heading
            Magnetometer headings (used by the attitude correction).
        reference_step
            Same as :meth:`run_reference` (kept as an alias): run the readable loop below, step by
            step in Python (the mechanization, the engine's predict and the gate policy's update)
            instead of the compiled loop (:func:`~.kernels._loose_loop`: the same steps); results are
            identical up to rounding (tested). Where the compiled loop meets what the Python loop
            refuses (a non-finite fix, an innovation covariance that is not positive definite), the
            Python loop runs and decides.
        """
        check_inputs("LooseFilter.run", imu, x0)
        d = self.dim
        t_ep = fixes.t_s
        T = t_ep.size
        t, acc, gyro, ep_idx, coasting, gaps_s = gap_timeline(imu, t_ep, self.max_imu_gap_s)
        yaw_meas = heading.at(t_ep) if heading is not None else np.full(T, np.nan)
        fix = np.full((T, 3), np.nan)
        fix[:, :fixes.dim] = fixes.pos_m
        has = fixes.has_estimate & np.all(np.isfinite(fixes.pos_m), axis=1)
        out = _empty(T, 2 * d)
        mech, lever = self.mechanization, self.lever_arm_m
        p, v, q = x0.pos_m.copy(), x0.vel_mps.copy(), x0.quat.copy()
        dx = np.zeros(2 * d)
        _, _, R = self.matrices(1.0)
        P = np.diag([self.sigma_r_pos_m ** 2] * d + [self.sigma_r_vel_mps ** 2] * d)
        ep_at = np.full(t.size, -1)
        ok = ep_idx >= 0
        ep_at[ep_idx[ok]] = np.flatnonzero(ok)
        last_t = None
        hist_t, hist_p = [], []
        g_up = -mech.g_n / np.linalg.norm(mech.g_n)
        gate = self.gate_policy
        gated_run, gated_y = 0, []                      # position innovations of the current gated run
        # coast across IMU gaps: the 15-state accumulators of models.ins.coast since the last epoch,
        # whose position/velocity block is the extra process noise of the assumed acceleration
        blk = np.r_[0:d, 3:3 + d]
        no_q, acc_var = np.zeros(N_ERR), float(self.coast_acc_sigma_mps2) ** 2
        Phi_c, Q_c = np.eye(N_ERR), np.zeros((N_ERR, N_ERR))
        coasted = False
        if not reference_step:
            try:
                self._run_compiled(t, acc, gyro, ep_at, coasting, t_ep, fix, has, yaw_meas, p, v, q, P, out)
                return FusionRun(t_ep.copy(), name=name or self.name, meta={"imu_gaps_s": gaps_s}, **out)
            except FloatingPointError:
                out = _empty(T, 2 * d)
        for i in range(t.size):
            if i > 0 and coasting[i]:                    # inside an IMU gap: nothing measured the motion
                coast(p, v, t, i - 1, i, no_q, acc_var, 0.0, Phi_c, Q_c)
                coasted = True
            elif i > 0:
                p, v, q, _, _ = mech.step(p, v, q, acc[i - 1], acc[i], gyro[i - 1], gyro[i], t[i] - t[i - 1])
                if coasted:                              # carry the coast noise to the epoch (F of a step)
                    dt = t[i] - t[i - 1]
                    Q_c[:3, :] += dt * Q_c[3:6, :]
                    Q_c[:, :3] += dt * Q_c[:, 3:6]
                if d == 2 and self.height_m is not None:
                    p[2], v[2] = self.height_m - (_dcm(q) @ lever)[2], 0.0
            k = ep_at[i]
            if k < 0:
                continue
            T_s = 0.0 if last_t is None else t[i] - last_t
            last_t = t[i]
            # attitude: complementary levelling (+ heading), the paper's gyro + magnetometer AHRS
            C = _dcm(q)
            gain = min(1.0, T_s / self.attitude_tau_s) if T_s > 0 else 0.0
            if gain > 0:
                fn = C @ acc[i]
                corr = (gain * np.cross(fn / max(math.sqrt(fn @ fn), 1e-9), g_up) if np.all(np.isfinite(fn))
                        else np.zeros(3))                # inside an IMU gap: no specific force to level with
                if np.isfinite(yaw_meas[k]):
                    corr[2] += gain * _wrap(yaw_meas[k] - _yaw(C))
                q = _exp_left(corr, q)
            A, Q, _ = self.matrices(T_s)
            if coasted:
                Q = Q + Q_c[np.ix_(blk, blk)]
                Phi_c, Q_c, coasted = np.eye(N_ERR), np.zeros((N_ERR, N_ERR)), False
            st = kalman.predict(Gaussian(dx, P), A, Q)
            dx, P = st.x, st.P
            C = _dcm(q)
            tag = p + C @ lever
            nis, dof, status = np.nan, 0, EstimateStatus.PREDICTED
            if has[k]:
                hist_t.append(t_ep[k])
                hist_p.append(fix[k, :d].copy())
                z_pos = tag[:d] - fix[k, :d]
                if len(hist_t) > self.vel_window and t_ep[k] - hist_t[-1 - self.vel_window] < 1.0:
                    v_uwb = (hist_p[-1] - hist_p[-1 - self.vel_window]) / (t_ep[k] - hist_t[-1 - self.vel_window])
                    z, H, Rk = np.concatenate([z_pos, v[:d] - v_uwb]), np.eye(2 * d), R
                else:
                    z, H, Rk = z_pos, np.eye(2 * d)[:d], R[:d, :d]
                if 0 < gated_run >= gate.max_gated and _consistent(gated_y):
                    y = z_pos - dx[:d]                   # lock lost (the gated fixes agree): admit it, re-acquire
                    P = P + np.diag(self.lost_lock_variance(float(np.mean(y * y))))
                lin = Linearisation(z, H @ dx, H, Rk, linear=True)      # eq 6: z = H δx + v
                if gate.active(gated_run):
                    st, info = gate.update(Gaussian(dx, P), lin, None)
                else:
                    st, info = ungated_update(Gaussian(dx, P), lin)
                if info.status == EstimateStatus.GATED:
                    hist_t.pop()
                    hist_p.pop()
                    gated_run += 1
                    gated_y.append(z_pos - dx[:d])
                    status = EstimateStatus.GATED
                    out["n_gated"][k] = 1
                else:
                    gated_run, gated_y = 0, []
                    dx, P = st.x, st.P
                    nis, dof, status = info.nis, info.dof, EstimateStatus.UPDATED
                hist_t, hist_p = hist_t[-self.vel_window - 1:], hist_p[-self.vel_window - 1:]
            if self.feedback:
                p[:d] -= dx[:d]
                v[:d] -= dx[d:]
                dx = np.zeros(2 * d)
                po, vo = p.copy(), v.copy()
            else:
                po, vo = p.copy(), v.copy()
                po[:d] -= dx[:d]
                vo[:d] -= dx[d:]
            out["pos_m"][k] = po + C @ lever
            out["vel_mps"][k], out["quat"][k] = vo, q
            out["acc_bias_mps2"][k] = out["gyro_bias_radps"][k] = 0.0
            out["P"][k] = P
            cov = np.full((3, 3), np.nan)
            cov[:d, :d] = P[:d, :d]
            out["pos_cov_m2"][k] = cov
            out["nis"][k], out["dof"][k], out["status"][k] = nis, dof, status
        return FusionRun(t_ep.copy(), name=name or self.name, meta={"imu_gaps_s": gaps_s}, **out)

    def run_reference(self, imu: ImuLog, fixes: Estimates, x0: NavState, *, heading: HeadingLog | None = None,
                      name: str | None = None) -> FusionRun:
        """The Python definition of :meth:`run` (its ``reference_step=True``): per IMU sample the
        mechanization (:meth:`~uwbwb.models.ins.Mechanization.step`) or a coast, per epoch the
        attitude correction, :func:`kalman.predict <uwbwb.filters.kalman.predict>` with
        :meth:`matrices` and the fix as a linear :class:`~uwbwb.filters.ekf.Linearisation` through
        :attr:`gate_policy` (or :func:`~uwbwb.filters.gating.ungated_update` once released). The
        compiled loop must equal it to rounding (the twin tests)."""
        return self.run(imu, fixes, x0, heading=heading, name=name, reference_step=True)

    def _run_compiled(self, t, acc, gyro, ep_at, coasting, t_ep, fix, has, yaw_meas, p, v, q, P, out):
        """The filter of :meth:`run` as one compiled loop (:func:`_loose_loop`), writing into ``out``."""
        d, gate = self.dim, self.gate_policy
        prob = getattr(gate, "prob", None)
        thr = {m: float(_chi2_ppf(prob, m)) if prob is not None else math.inf for m in (d, 2 * d)}
        named = dict(attitude_tau_s=self.attitude_tau_s, q_scale=self.q_scale, height_m=float(self.height_m or 0.0),
                     coast_acc_var=float(self.coast_acc_sigma_mps2) ** 2, gate_pos=thr[d], gate_full=thr[2 * d],
                     dim=d, vel_window=self.vel_window, gated=isinstance(gate, ChiSquareEpoch),
                     max_gated=gate.max_gated, use_height=self.height_m is not None, feedback=bool(self.feedback),
                     st_updated=EstimateStatus.UPDATED, st_gated=EstimateStatus.GATED,
                     st_predicted=EstimateStatus.PREDICTED)
        q_diag = np.array([self.q_pos_m_rts ** 2] * d + [self.q_vel_mps_rts ** 2] * d)
        g_n = self.mechanization.g_n
        _loose_loop(
            (t, acc, gyro, ep_at, np.ascontiguousarray(coasting, np.bool_)),
            (np.asarray(t_ep, float), fix, np.ascontiguousarray(has, np.bool_), np.asarray(yaw_meas, float)),
            np.array([float(named[n]) for n in LOOSE_SCALARS]), np.array([int(named[n]) for n in LOOSE_INTS], np.int64),
            (q_diag, self.matrices(1.0)[2], self.lost_lock_variance(), self.lever_arm_m, g_n, -g_n / np.linalg.norm(g_n)),
            (p.copy(), v.copy(), q.copy()), P.copy(),
            (out["pos_m"], out["vel_mps"], out["quat"], out["acc_bias_mps2"], out["gyro_bias_radps"], out["P"],
             out["pos_cov_m2"], out["nis"], out["dof"], out["n_gated"], out["status"]))
