"""TDoA extended Kalman filter with a white-noise-driven motion model (thesis eqs 1–10).

Prediction (eqs 5–6, with the covariance propagation written correctly as
``A P Aᵀ + Q``; the thesis prints ``AᵀPA + Q``)::

    x⁻ = F(dt) x,        P⁻ = F(dt) P F(dt)ᵀ + Q(dt)

with ``F``, ``Q`` from a :mod:`uwbwb.models.motion` model. Update (eqs 7–9) with
the TDoA model linearised at the prior (eqs 3–4)::

    y = z − h(x⁻),  S = H P⁻ Hᵀ + R,  G = P⁻ Hᵀ S⁻¹,  x = x⁻ + G y,
    P = (I − G H) P⁻ (I − G H)ᵀ + G R Gᵀ              (Joseph form)

Both steps go through :mod:`uwbwb.filters.kalman`, the one edge that touches
filterpy. The estimate is the posterior mean (eq. 10).

Every update reports the normalised innovation squared ``NIS = yᵀ S⁻¹ y``,
χ²-distributed with ``m`` (number of TDoAs) degrees of freedom when the
models are right. Optional χ² gating (``gate_prob``): if the NIS of an epoch
exceeds the ``gate_prob`` quantile of χ²(m), the anchor whose removal lowers
the NIS most is dropped (re-referencing if it was the reference) and the test
repeated, until the epoch passes or fewer than ``min_tdoa`` TDoAs remain, in
which case the epoch is skipped (prediction only). A filter that has drifted
away (e.g. a random walk whose driving noise is far too small to follow the
target) would otherwise reject every later epoch and never come back; so after
``max_skipped`` consecutive skipped epochs the next epoch is used ungated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import chi2

from ..models.motion import MotionModel
from ..models.tdoa import TdoaLog, TdoaModel
from ..types import Trajectory
from . import kalman
from .kalman import Gaussian
from .tdoa_ls import tdoa_least_squares

__all__ = ["TdoaEkf", "EkfResult", "EpochUpdate", "run_tdoa_ekf"]


@dataclass(frozen=True)
class EpochUpdate:
    """What one update did.

    Attributes
    ----------
    nis
        NIS of the accepted measurement set (NaN if the epoch was skipped).
    dof
        Number of TDoAs used (0 if skipped).
    n_rejected
        Anchors removed by the gate.
    """

    nis: float
    dof: int
    n_rejected: int


@dataclass(frozen=True)
class TdoaEkf:
    """A TDoA EKF: motion model + measurement model + gating and initialisation settings.

    Attributes
    ----------
    motion
        Motion model (its ``dim`` must equal ``measurement.dim``).
    measurement
        TDoA measurement model (anchors, noise, reference correlation).
    gate_prob
        χ² gate probability (e.g. 0.999), or None for no gating.
    min_tdoa
        Fewest TDoAs an update may use after gating; default ``dim``.
    max_skipped
        Consecutive epochs the gate may skip before the next one is used ungated.
    init_pos_sigma_m, init_vel_sigma_mps, init_acc_sigma_mps2
        Prior standard deviations at initialisation (per axis).
    """

    motion: MotionModel
    measurement: TdoaModel
    gate_prob: float | None = None
    min_tdoa: int | None = None
    max_skipped: int = 10
    init_pos_sigma_m: float = 1.0
    init_vel_sigma_mps: float = 1.0
    init_acc_sigma_mps2: float = 1.0

    def __post_init__(self):
        if self.motion.dim != self.measurement.dim:
            raise ValueError(f"motion model is {self.motion.dim}-D but the measurement model is "
                             f"{self.measurement.dim}-D")
        if self.gate_prob is not None and not 0 < self.gate_prob < 1:
            raise ValueError(f"gate_prob must be in (0, 1) or None, got {self.gate_prob!r}")
        if self.min_tdoa is not None and self.min_tdoa < 1:
            raise ValueError("min_tdoa must be >= 1")
        if self.max_skipped < 0:
            raise ValueError("max_skipped must be >= 0")

    @property
    def name(self) -> str:
        return f"EKF-{self.motion.abbreviation}"

    # ------------------------------------------------------------ steps
    def init(self, pos_m: np.ndarray, vel_mps: np.ndarray | None = None) -> Gaussian:
        """Initial state at ``pos_m`` (velocity and acceleration zero unless given)."""
        m = self.motion
        return Gaussian(m.initial_state(pos_m, vel_mps),
                        m.initial_covariance(self.init_pos_sigma_m, self.init_vel_sigma_mps,
                                             self.init_acc_sigma_mps2))

    def predict(self, state: Gaussian, dt_s: float) -> Gaussian:
        """Prior after ``dt_s`` seconds (eqs 5–6)."""
        return kalman.predict(state, self.motion.F(dt_s), self.motion.Q(dt_s))

    def _terms(self, state, row, ref, anchors):
        z, h, H_pos, R, _ = self.measurement.epoch(row, self.motion.position(state.x), ref, anchors)
        H = H_pos @ self.motion.H_pos
        return z, h, H, R

    def _nis(self, state, row, ref, anchors) -> float:
        z, h, H, R = self._terms(state, row, ref, anchors)
        y = z - h
        S = H @ state.P @ H.T + R
        return float(y @ np.linalg.solve(S, y))

    def update(self, state: Gaussian, tdoa_row_m: np.ndarray, ref: int, *,
               gate: bool = True) -> tuple[Gaussian, EpochUpdate]:
        """Posterior after one epoch's TDoAs (eqs 7–9, Joseph form), with optional gating.

        Parameters
        ----------
        tdoa_row_m
            One row of :attr:`~uwbwb.models.tdoa.TdoaLog.tdoa_m`, shape ``(n_anchors,)``.
        ref
            That row's reference anchor (−1: nothing to update).
        gate
            Apply the χ² gate (if ``gate_prob`` is set).
        """
        row = np.asarray(tdoa_row_m, float)
        anchors = np.flatnonzero(np.isfinite(row))
        min_tdoa = self.min_tdoa if self.min_tdoa is not None else self.measurement.dim
        if ref < 0 or anchors.size < 2:
            return state, EpochUpdate(np.nan, 0, 0)
        n_rejected = 0
        if self.gate_prob is not None and gate:
            while True:
                nis = self._nis(state, row, ref, anchors)
                if nis <= chi2.ppf(self.gate_prob, anchors.size - 1):
                    break
                if anchors.size - 2 < max(min_tdoa, 1):
                    return state, EpochUpdate(np.nan, 0, n_rejected + anchors.size)
                trial = []
                for k in anchors:
                    rest = anchors[anchors != k]
                    trial.append(self._nis(state, row, ref if k != ref else int(rest[0]), rest))
                drop = anchors[int(np.argmin(trial))]
                anchors = anchors[anchors != drop]
                if drop == ref:
                    ref = int(anchors[0])
                n_rejected += 1
        z, h, H, R = self._terms(state, row, ref, anchors)
        post, inn = kalman.update(state, z, H, R, h_x=h)
        return post, EpochUpdate(inn.nis, z.size, n_rejected)

    # ------------------------------------------------------------ batch
    def run(self, log: TdoaLog, *, x0: Gaussian | None = None, name: str | None = None) -> "EkfResult":
        """Filter a whole recording.

        Parameters
        ----------
        log
            TDoAs per epoch; the filter steps from epoch to epoch (``dt`` from ``log.t_s``).
        x0
            Initial state at ``log.t_s[0]``. Default: at the first epoch with a
            valid LS fix (:func:`~uwbwb.filters.tdoa_ls.tdoa_least_squares`), with
            zero velocity/acceleration and the ``init_*_sigma`` prior; that
            epoch's TDoAs then update this weak prior. Earlier epochs are NaN.
        name
            Label of the result (default ``"EKF-RW"`` etc.).

        Returns
        -------
        EkfResult
        """
        if log.n_anchors != self.measurement.n_anchors:
            raise ValueError(f"TdoaEkf.run: log has {log.n_anchors} anchors, the model {self.measurement.n_anchors}")
        T, n_x = len(log), self.motion.n_x
        x = np.full((T, n_x), np.nan)
        P = np.full((T, n_x, n_x), np.nan)
        nis = np.full(T, np.nan)
        dof = np.zeros(T, int)
        n_rej = np.zeros(T, int)
        if x0 is None:
            start = None
            for lo in range(0, T, 64):
                ls = tdoa_least_squares(log.select(slice(lo, lo + 64)), self.measurement)
                if ls.ok.any():
                    k = int(np.flatnonzero(ls.ok)[0])
                    start, state = lo + k, self.init(ls.pos_m[k])
                    break
            if start is None:
                return EkfResult(log.t_s.copy(), x, P, nis, dof, n_rej, self.motion, name or self.name)
        else:
            start, state = 0, x0
        dt = np.diff(log.t_s[start:])
        F_all, Q_all = self.motion.F(dt), self.motion.Q(dt)      # all steps at once
        skipped = 0
        for k in range(start, T):
            if k > start:
                state = kalman.predict(state, F_all[k - start - 1], Q_all[k - start - 1])
            state, info = self.update(state, log.tdoa_m[k], int(log.ref[k]), gate=skipped < self.max_skipped)
            skipped = skipped + 1 if info.n_rejected and not info.dof else 0
            x[k], P[k], nis[k], dof[k], n_rej[k] = state.x, state.P, info.nis, info.dof, info.n_rejected
        return EkfResult(log.t_s.copy(), x, P, nis, dof, n_rej, self.motion, name or self.name)


@dataclass(frozen=True)
class EkfResult:
    """Filtered states of one recording.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds.
    x
        Posterior means, shape ``(T, n_x)`` (state layout of ``motion``); NaN before initialisation.
    P
        Posterior covariances, shape ``(T, n_x, n_x)``.
    nis
        NIS per epoch, shape ``(T,)``; NaN where no update was made.
    dof
        TDoAs used per epoch (the NIS degrees of freedom), shape ``(T,)``.
    n_rejected
        Anchors rejected by the χ² gate per epoch, shape ``(T,)``.
    motion
        The motion model used.
    name
        Label, e.g. ``"EKF-RW"``.
    """

    t_s: np.ndarray
    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray
    dof: np.ndarray
    n_rejected: np.ndarray
    motion: MotionModel
    name: str = "EKF"

    @property
    def pos_m(self) -> np.ndarray:
        """Positions, shape ``(T, dim)``, metres."""
        return self.motion.position(self.x)

    @property
    def pos_cov_m2(self) -> np.ndarray:
        """Position covariances, shape ``(T, dim, dim)``, m²."""
        d = self.motion.dim
        return self.P[:, :d, :d]

    @property
    def valid(self) -> np.ndarray:
        """Epochs after initialisation, bool ``(T,)``."""
        return np.all(np.isfinite(self.x), axis=1)

    def nis_consistency(self, prob: float = 0.95) -> dict[str, float]:
        """χ² consistency of the NIS over the updated epochs.

        Returns
        -------
        dict
            ``n`` epochs, ``mean_nis_over_dof`` (≈ 1 when consistent),
            ``fraction_inside`` (share of epochs with NIS inside the central
            ``prob`` interval of χ²(dof), ≈ ``prob`` when consistent) and
            ``sum_nis``/``sum_dof`` with the two-sided ``prob`` bounds of the
            sum under the χ²(Σdof) hypothesis.
        """
        up = self.dof > 0
        if not up.any():
            return {"n": 0, "mean_nis_over_dof": np.nan, "fraction_inside": np.nan, "sum_nis": np.nan,
                    "sum_dof": 0, "sum_lo": np.nan, "sum_hi": np.nan}
        nis, dof = self.nis[up], self.dof[up]
        a = (1 - prob) / 2
        inside = (nis >= chi2.ppf(a, dof)) & (nis <= chi2.ppf(1 - a, dof))
        total = int(dof.sum())
        return {"n": int(up.sum()), "mean_nis_over_dof": float(nis.sum() / total),
                "fraction_inside": float(inside.mean()), "sum_nis": float(nis.sum()), "sum_dof": total,
                "sum_lo": float(chi2.ppf(a, total)), "sum_hi": float(chi2.ppf(1 - a, total))}

    def to_frame(self) -> pd.DataFrame:
        """Table ``t_s``, the state columns (``x_m, y_m, vx_mps, ...``), position SDs, ``nis, dof, n_rejected``."""
        cols = {"t_s": self.t_s}
        cols.update({lab: self.x[:, k] for k, lab in enumerate(self.motion.state_labels)})
        sd = np.sqrt(np.diagonal(self.pos_cov_m2, axis1=1, axis2=2))
        cols.update({f"sd_{a}_m": sd[:, k] for k, a in enumerate("xyz"[: self.motion.dim])})
        cols.update(nis=self.nis, dof=self.dof, n_rejected=self.n_rejected)
        return pd.DataFrame(cols)

    def to_trajectory(self, name: str | None = None) -> Trajectory:
        """Filtered positions (and velocities, if in the state) after initialisation."""
        ok = self.valid
        vel = self.motion.velocity(self.x)
        return Trajectory(self.t_s[ok], self.pos_m[ok], None if vel is None else vel[ok], name=name or self.name)


def run_tdoa_ekf(log: TdoaLog, motion: MotionModel, measurement: TdoaModel, *, gate_prob: float | None = None,
                 x0: Gaussian | None = None, name: str | None = None, **settings) -> EkfResult:
    """Shorthand for ``TdoaEkf(motion, measurement, gate_prob, **settings).run(log, x0=x0, name=name)``."""
    return TdoaEkf(motion, measurement, gate_prob=gate_prob, **settings).run(log, x0=x0, name=name)
