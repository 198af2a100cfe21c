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

from dataclasses import dataclass

import numpy as np

from ...models.doppler import DopplerModel
from ...models.motion import ReceiverMotion
from ...types import ChirpFlag, ChirpLog, EstimateStatus, Estimates
from ...validate import integer, number, probability
from ..ekf import Ekf, Linearisation
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
        ekf = self.ekf
        P = self.model.period_s
        n_b = P.size
        rr = np.full(len(log), np.nan) if ranges_m is None else _per_row("ranges_m", ranges_m, len(log))
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
