"""Section 4.1's Kalman filter for independent ultrasonic beacons (paper 003): SCAAT MH-EKF.

:class:`ScaatMhEkf` takes a single constraint at a time (SCAAT) on eq 1, one hypothesis per
plausible source of an ambiguous chirp (including noise), pruned by likelihood. Each hypothesis
runs through the Gaussian engine, :class:`uwbwb.filters.ekf.Ekf` over the
:class:`DopplerMeasurement` linearisation (the EKF's view of
:class:`~uwbwb.models.doppler.DopplerModel`): :meth:`~uwbwb.filters.ekf.Ekf.predict`, then
:meth:`~uwbwb.filters.ekf.Ekf.update` without a gate, whose
:attr:`~uwbwb.filters.gating.UpdateInfo.log_likelihood` weights the child.
Part of the :mod:`uwbwb.filters.doppler` package.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from ...models.doppler import DopplerModel
from ...models.motion import ReceiverMotion
from ...types import ChirpFlag, ChirpLog, EstimateStatus, Estimates
from ...validate import integer, number, probability
from ..ekf import Ekf, Linearisation
from ..ekf.kernels import _lu, _mul, _mul_t, _predict, _symmetric, _update
from ..kalman import Gaussian
from .frontend import _check, _per_row

__all__ = ["DopplerMeasurement", "ScaatMhEkf"]


@dataclass(frozen=True)
class DopplerMeasurement:
    """One chirp of :class:`~uwbwb.models.doppler.DopplerModel` as :class:`~uwbwb.filters.ekf.Ekf` sees it.

    ``measurement`` is ``(beacon, dp_s, range_m)``: the beacon index (−1: none), the
    measured ΔP (NaN: none) and a pseudo-range (NaN: none). The rows, predictions,
    Jacobians and noise come from :meth:`DopplerModel.measurement_rows` (lagged eq 1).
    """

    model: DopplerModel

    def __post_init__(self):
        _check("DopplerMeasurement", "model", self.model, DopplerModel)

    def linearise(self, x: np.ndarray, measurement) -> Linearisation | None:
        """:class:`Linearisation` at state ``x = [X, V]`` (6,); None when nothing usable was measured."""
        rows = self.model.measurement_rows(x, measurement)
        return None if rows is None else Linearisation(*rows)


@dataclass
class _Hypothesis:
    state: Gaussian
    t_s: float
    last_s: np.ndarray            # last assigned arrival per beacon (NaN: not locked)
    logw: float
    assigned: bool = False


@dataclass(frozen=True)
class ScaatMhEkf:
    """Section 4.1's Kalman filter: SCAAT EKF on eq 1 with multiple hypotheses per ambiguous chirp.

    Every detection is one constraint. For each live hypothesis, the detection may come
    from any beacon whose train it fits (as in :func:`assign_chirps`, but with that
    hypothesis' own assignment history) or be noise; each possibility becomes a child
    hypothesis. A child that assigns the chirp to beacon ``i`` after ``k`` periods is
    updated by :meth:`Ekf.update` with ``ΔP = (t − t_i)/k − P_i`` and weighted by
    ``p_d (1 − p_d)^(k−1) N(ΔP; h(x⁻), S)``; the noise child keeps its state and is
    weighted by the clutter density ``spurious_rate_hz`` (per second of arrival time,
    the unit of ΔP). Children below ``prune_ratio`` of the best are dropped and at most
    ``max_hypotheses`` kept. Beacon trains are started from the front end's ``LOCK``
    rows. The estimate is the most probable hypothesis' mean.

    Attributes
    ----------
    model, motion
        As for :class:`DopplerPf`.
    p_detect
        Probability that a chirp is detected.
    spurious_rate_hz
        Rate of spurious detections (clutter).
    window_s, max_gap
        Gates of the association, as in :func:`assign_chirps`.
    max_hypotheses, prune_ratio
        Pruning.
    """

    model: DopplerModel
    motion: ReceiverMotion = ReceiverMotion()
    p_detect: float = 0.95
    spurious_rate_hz: float = 0.5
    window_s: float = 0.004
    max_gap: int = 3
    max_hypotheses: int = 8
    prune_ratio: float = 1e-3
    name: str = "MH-EKF"

    def __post_init__(self):
        _check("ScaatMhEkf", "model", self.model, DopplerModel)
        _check("ScaatMhEkf", "motion", self.motion, ReceiverMotion)
        p = probability("p_detect", self.p_detect, open_interval=False)
        if p <= 0.0:
            raise ValueError(f"p_detect must be a number in (0, 1], got {self.p_detect!r}")
        object.__setattr__(self, "p_detect", p)
        object.__setattr__(self, "spurious_rate_hz", number("spurious_rate_hz", self.spurious_rate_hz, minimum=0.0))
        object.__setattr__(self, "window_s", number("window_s", self.window_s, minimum=0.0, strict_minimum=True))
        object.__setattr__(self, "max_gap", integer("max_gap", self.max_gap, minimum=1))
        object.__setattr__(self, "max_hypotheses", integer("max_hypotheses", self.max_hypotheses, minimum=1))
        object.__setattr__(self, "prune_ratio", probability("prune_ratio", self.prune_ratio, open_interval=False))
        if not isinstance(self.name, str):
            raise ValueError(f"name must be text, got {self.name!r}")

    @property
    def ekf(self) -> Ekf:
        return Ekf(self.motion, DopplerMeasurement(self.model), vel_index=self.motion.layout.vel_index,
                   gate_prob=None)

    def run(self, log: ChirpLog, x0: Gaussian, *, ranges_m=None) -> Estimates:
        """Filter ``log`` from the prior ``x0`` (at the first detection's time).

        Returns
        -------
        Estimates
            One epoch per detection; status UPDATED where the best hypothesis used the
            detection, PREDICTED where it read it as noise. ``info``: ``n_hypotheses``,
            ``beacon`` (the best hypothesis' assignment, −1 for noise).
        """
        _check("ScaatMhEkf.run", "log", log, ChirpLog)
        if not isinstance(x0, Gaussian) or np.shape(x0.x) != (6,):
            raise ValueError(f"x0 must be a Gaussian over [X, V] (6 components), got {x0!r}")
        rr = np.full(len(log), np.nan) if ranges_m is None else _per_row("ranges_m", ranges_m, len(log))
        m, T = self.model, len(log)
        pos, vel = np.full((T, 3), np.nan), np.full((T, 3), np.nan)
        cov = np.full((T, 3, 3), np.nan)
        status = np.full(T, EstimateStatus.PREDICTED, np.int8)
        n_h, chosen = np.zeros(T, int), np.full(T, -1)
        try:
            _mh_loop((np.asarray(log.t_s, float), np.asarray(log.beacon, np.int64), log.has(ChirpFlag.LOCK),
                      rr),
                     (np.ascontiguousarray(m.beacons.pos_m, float), np.array(m.period_s, float), m.v_s_mps, m.lag,
                      m.sigma_dp_s() ** 2, m.sigma_m ** 2, np.asarray(self.motion.sigma_acc_mps2, float)),
                     (np.log(self.p_detect), np.log1p(-self.p_detect),
                      np.log(self.spurious_rate_hz) if self.spurious_rate_hz > 0 else -np.inf,
                      np.log(self.prune_ratio), self.window_s),
                     np.array([self.max_gap, self.max_hypotheses, EstimateStatus.UPDATED], np.int64),
                     np.array(x0.x, float), np.array(x0.P, float, order="C"), (pos, vel, cov, status, n_h, chosen))
        except FloatingPointError:
            return self._run_python(log, x0, rr)
        return Estimates(np.asarray(log.t_s, float), pos, status, self.name, pos_cov_m2=cov, vel_mps=vel,
                         info={"n_hypotheses": n_h, "beacon": chosen})

    def _run_python(self, log: ChirpLog, x0: Gaussian, rr: np.ndarray) -> Estimates:
        """:meth:`run` step by step on :class:`~uwbwb.filters.ekf.Ekf`'s prediction and update (``rr``: a
        pseudo-range per row, NaN for none): the definition of the compiled loop (twin ``doppler.ScaatMhEkf.run``)
        and the run wherever that loop stops (a non-finite state or a covariance that is not positive definite)."""
        ekf = self.ekf
        P = self.model.period_s
        n_b = P.size
        hyps = [_Hypothesis(x0, float(log.t_s[0]) if len(log) else 0.0, np.full(n_b, np.nan), 0.0)]
        T = len(log)
        pos, vel = np.full((T, 3), np.nan), np.full((T, 3), np.nan)
        cov = np.full((T, 3, 3), np.nan)
        status = np.full(T, EstimateStatus.PREDICTED, np.int8)
        n_h, chosen = np.zeros(T, int), np.full(T, -1)
        log_clutter = np.log(self.spurious_rate_hz) if self.spurious_rate_hz > 0 else -np.inf
        lock = log.has(ChirpFlag.LOCK)
        for r, t in enumerate(log.t_s):
            children = []
            for h in hyps:
                last = h.last_s.copy()
                stale = np.isfinite(last) & (t - last > (self.max_gap + 0.5) * P)
                last[stale] = np.nan
                if lock[r] and log.beacon[r] >= 0 and not np.isfinite(last[log.beacon[r]]):
                    started = last.copy()
                    started[log.beacon[r]] = t
                    children.append(_Hypothesis(h.state, h.t_s, started, h.logw, False))
                    continue
                gap = t - last
                k = np.rint(gap / P)
                shift = gap / np.where(k > 0, k, np.nan) - P
                fits = np.flatnonzero(np.isfinite(last) & (k >= 1) & (k <= self.max_gap)
                                      & (np.abs(shift) <= self.window_s))
                if fits.size:
                    prior = ekf.predict(h.state, t - h.t_s)
                for i in fits:
                    meas = (int(i), float(shift[i]), rr[r] if log.beacon[r] == i else np.nan)
                    post, info = ekf.update(prior, meas, gate=False)
                    moved = last.copy()
                    moved[i] = t
                    children.append(_Hypothesis(post, float(t), moved,
                                                h.logw + info.log_likelihood + np.log(self.p_detect)
                                                + (k[i] - 1) * np.log1p(-self.p_detect), True))
                children.append(_Hypothesis(h.state, h.t_s, last, h.logw + log_clutter, False))
            logw = np.array([c.logw for c in children])
            logw -= logw.max()
            order = np.argsort(-logw, kind="stable")
            keep = [children[j] for j in order[: self.max_hypotheses] if logw[j] >= np.log(self.prune_ratio)]
            for c in keep:
                c.logw -= np.max([c2.logw for c2 in keep])
            hyps = keep
            best = hyps[0]
            x = ekf.predict(best.state, t - best.t_s) if t > best.t_s else best.state
            pos[r], vel[r], cov[r] = x.x[:3], x.x[3:], x.P[:3, :3]
            status[r] = EstimateStatus.UPDATED if best.assigned and best.t_s == t else EstimateStatus.PREDICTED
            n_h[r] = len(hyps)
            if best.assigned and best.t_s == t:
                chosen[r] = int(np.flatnonzero(best.last_s == t)[0])
        return Estimates(np.asarray(log.t_s, float), pos, status, self.name, pos_cov_m2=cov, vel_mps=vel,
                         info={"n_hypotheses": n_h, "beacon": chosen})


@numba.njit(cache=True, nogil=True)
def _mh_loop(chirps, model, weights, settings, x0, P0, outputs):
    """:meth:`ScaatMhEkf.run`'s loop over the detections, compiled; its definition is
    :meth:`ScaatMhEkf._run_python` and every step repeats that method's in its order. ``chirps = (t, beacon,
    LOCK flag, pseudo-range or NaN)`` per row; ``model = (beacon positions, periods, v_s, lag, σ_ΔP² per beacon,
    σ_range², σ_acc)``; ``weights = (log p_d, log(1 − p_d), log clutter, log prune_ratio, window_s)``;
    ``settings = (max_gap, max_hypotheses, UPDATED)``; outputs ``(pos, vel, cov, status, n_hypotheses, beacon)``
    written in place. The prediction and the Joseph-form update are :mod:`uwbwb.filters.ekf.kernels`' (the
    products summed in their own order: results equal the Python run's to rounding); the ΔP row is
    :meth:`~uwbwb.models.doppler.DopplerModel.measurement_rows`' (lagged eq 1 and its Jacobian). Raises
    FloatingPointError where the Python run would raise or meets a NaN weight: that run then decides."""
    t_s, beacon, lock, rr = chirps
    Tb, Pb, v_s, lag, var_dp, var_r, sig = model
    log_pd, log_miss, log_clutter, log_prune, window = weights
    max_gap, max_h, updated = settings[0], settings[1], settings[2]
    pos, vel, cov, status, n_hyp, chosen = outputs
    nb, cap = Pb.size, settings[1] * (Pb.size + 1)
    hx, hP, ht, hl, hw, ha = (np.empty((cap, 6)), np.empty((cap, 6, 6)), np.empty(cap), np.empty((cap, nb)),
                              np.empty(cap), np.zeros(cap, np.bool_))
    cx, cP, ct, cl, cw, ca = (np.empty((cap, 6)), np.empty((cap, 6, 6)), np.empty(cap), np.empty((cap, nb)),
                              np.empty(cap), np.zeros(cap, np.bool_))
    hx[0], hP[0], ht[0], hl[0], hw[0] = x0, P0, t_s[0] if t_s.size else 0.0, np.nan, 0.0
    nh = 1
    last, gap, k, shift = np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb)
    z, h, H, R = np.empty(2), np.empty(2), np.zeros((2, 6)), np.zeros((2, 2))
    lw = np.empty(cap)
    xp, Pp = hx[0], hP[0]
    for r in range(t_s.size):
        t = t_s[r]
        nc = 0
        for j in range(nh):
            for i in range(nb):
                last[i] = np.nan if t - hl[j, i] > (max_gap + 0.5) * Pb[i] else hl[j, i]
            b = beacon[r]
            if lock[r] and b >= 0 and not np.isfinite(last[b]):       # a train starts: no update
                cx[nc], cP[nc], ct[nc], cl[nc], cw[nc], ca[nc] = hx[j], hP[j], ht[j], last, hw[j], False
                cl[nc, b] = t
                nc += 1
                continue
            n_fit = 0
            for i in range(nb):
                gap[i] = t - last[i]
                k[i] = np.rint(gap[i] / Pb[i])
                shift[i] = gap[i] / (k[i] if k[i] > 0 else np.nan) - Pb[i]
                if np.isfinite(last[i]) and 1 <= k[i] <= max_gap and abs(shift[i]) <= window:
                    n_fit += 1
            if n_fit:
                F, Q = _transition(t - ht[j], sig)
                xp, Pp = _predict(hx[j], hP[j], F, Q)
            for i in range(nb):
                if not (np.isfinite(last[i]) and 1 <= k[i] <= max_gap and abs(shift[i]) <= window):
                    continue
                m = _doppler_rows(xp, i, shift[i], rr[r] if b == i else np.nan, Tb, Pb[i], v_s, lag, var_dp[i],
                                  var_r, z, h, H, R)
                for a in range(m):
                    if not (np.isfinite(z[a]) and np.isfinite(h[a]) and np.isfinite(H[a]).all()):
                        raise FloatingPointError("the Python run decides")
                xn, Pn, nis = _update(xp, Pp, z, h, H, R, m)
                S = _symmetric(_mul(H, _mul_t(Pp, H, 6, 6, m), m, 6, m)[:m, :m] + R[:m, :m])
                LU, _ = _lu(2 * np.pi * S, m)                          # slogdet(2π S)
                logdet = 0.0
                for a in range(m):
                    logdet += math.log(abs(LU[a, a]))
                cx[nc], cP[nc], ct[nc], cl[nc] = xn, Pn, t, last
                cl[nc, i] = t
                cw[nc] = hw[j] + -0.5 * (nis + logdet) + log_pd + (k[i] - 1) * log_miss
                ca[nc] = True
                nc += 1
            cx[nc], cP[nc], ct[nc], cl[nc], cw[nc], ca[nc] = hx[j], hP[j], ht[j], last, hw[j] + log_clutter, False
            nc += 1
        top = cw[:nc].max()
        for j in range(nc):
            lw[j] = cw[j] - top
            if np.isnan(lw[j]):
                raise FloatingPointError("the Python run decides")
        order = np.argsort(-lw[:nc], kind="mergesort")
        nh = 0
        for j in order[:max_h]:
            if lw[j] >= log_prune:
                hx[nh], hP[nh], ht[nh], hl[nh], hw[nh], ha[nh] = cx[j], cP[j], ct[j], cl[j], cw[j], ca[j]
                nh += 1
        for j in range(nh):                    # each kept weight less the largest of the kept ones at its turn
            hw[j] -= hw[:nh].max()
        x, Px = hx[0], hP[0]
        if t > ht[0]:
            F, Q = _transition(t - ht[0], sig)
            x, Px = _predict(x, Px, F, Q)
        pos[r], vel[r], cov[r] = x[:3], x[3:], Px[:3, :3]
        n_hyp[r] = nh
        if ha[0] and ht[0] == t:
            status[r] = updated
            for i in range(nb):
                if hl[0, i] == t:
                    chosen[r] = i
                    break


@numba.njit(cache=True, nogil=True)
def _transition(dt, sig):
    """:meth:`~uwbwb.models.motion.ReceiverMotion.F` and ``.Q`` over ``dt`` with the acceleration σ ``sig`` (3,)
    (powers as Python's ``float ** int``: the C library's ``pow``)."""
    F, Q = np.eye(6), np.zeros((6, 6))
    for c in range(3):
        s2 = sig[c] ** 2
        F[c, 3 + c] = dt
        Q[c, c], Q[c, 3 + c] = math.pow(dt, 4) / 4 * s2, math.pow(dt, 3) / 2 * s2
        Q[3 + c, c], Q[3 + c, 3 + c] = math.pow(dt, 3) / 2 * s2, math.pow(dt, 2) * s2
    return F, Q


@numba.njit(cache=True, nogil=True)
def _doppler_rows(x, i, dp, range_m, Tb, P, v_s, lag, var_dp, var_r, z, h, H, R):
    """:meth:`~uwbwb.models.doppler.DopplerModel.measurement_rows` of beacon ``i`` at ``x = [X, V]``: the ΔP row
    (lagged eq 1 and its Jacobian), then the pseudo-range row where ``range_m`` is finite; written into
    ``z, h, H, R`` (``R`` diagonal), returns the number of rows."""
    V0, V1, V2 = x[3], x[4], x[5]
    lp = lag * P
    d0, d1, d2 = (x[0] - lp * V0) - Tb[i, 0], (x[1] - lp * V1) - Tb[i, 1], (x[2] - lp * V2) - Tb[i, 2]
    rho = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    r = (d0 * V0 + d1 * V1 + d2 * V2) / (rho * v_s)
    z[0], h[0] = dp, P * r / (1.0 - r)
    u0, u1, u2 = d0 / rho, d1 / rho, d2 / rho
    uv = u0 * V0 + u1 * V1 + u2 * V2
    ru = uv / v_s
    scale = P / (1.0 - ru) ** 2
    for c in range(3):
        u = (u0, u1, u2)[c]
        dr_dx = (x[3 + c] - uv * u) / (rho * v_s)
        H[0, c] = scale * dr_dx
        H[0, 3 + c] = scale * (u / v_s - lp * dr_dx)
    R[0, 0], R[0, 1], R[1, 0] = var_dp, 0.0, 0.0
    if not np.isfinite(range_m):
        return 1
    e0, e1, e2 = x[0] - Tb[i, 0], x[1] - Tb[i, 1], x[2] - Tb[i, 2]
    rho = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    z[1], h[1] = range_m, rho
    H[1, 0], H[1, 1], H[1, 2], H[1, 3], H[1, 4], H[1, 5] = e0 / rho, e1 / rho, e2 / rho, 0.0, 0.0, 0.0
    R[1, 1] = var_r
    return 2
