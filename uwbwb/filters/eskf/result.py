"""The fusion result (:class:`FusionRun`) and INS-only dead reckoning."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ... import validate
from ...metrics import nis_consistency
from ...models.ins import N_ERR, Mechanization, NavState, coast, euler_from_dcm, quat_to_dcm
from ...types import EstimateStatus, Estimates, ImuLog
from .common import check_inputs, gap_timeline


# ====================================================================== result
@dataclass(frozen=True)
class FusionRun:
    """One fusion run at the UWB epochs.

    Attributes
    ----------
    t_s
        Epoch times ``(T,)``, s.
    pos_m, vel_mps
        Tag position and IMU velocity ``(T, 3)`` (corrected output); NaN before the start.
    quat
        Attitude ``(T, 4)`` ``[w, x, y, z]`` body → navigation.
    acc_bias_mps2, gyro_bias_radps
        Estimated IMU biases ``(T, 3)`` (zero for filters that do not estimate them).
    P
        Error covariance after each epoch ``(T, n, n)`` (15 for the tight filter, 4/6 loose).
    pos_cov_m2
        Tag position covariance ``(T, 3, 3)`` (NaN in the vertical of a 2-D loose filter).
    nis, dof
        Sum of the epoch's update NIS and the number of scalar updates used.
    n_outliers, n_gated
        Per epoch: TDoAs (or fixes) rejected by the eq-4 test, and by the χ² gate — the tight filter's
        rejected TDoA rows, the loose filter's rejected fix (1: its gate decides per epoch).
    status
        :class:`~uwbwb.types.EstimateStatus` codes ``(T,)``.
    name
        Label.
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    vel_mps: np.ndarray
    quat: np.ndarray
    acc_bias_mps2: np.ndarray
    gyro_bias_radps: np.ndarray
    P: np.ndarray
    pos_cov_m2: np.ndarray
    nis: np.ndarray
    dof: np.ndarray
    n_outliers: np.ndarray
    n_gated: np.ndarray
    status: np.ndarray
    name: str = "fusion"
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def euler_rad(self) -> np.ndarray:
        """Roll, pitch, yaw ``(T, 3)``, rad."""
        out = np.full((len(self), 3), np.nan)
        ok = np.all(np.isfinite(self.quat), axis=1)
        out[ok] = euler_from_dcm(quat_to_dcm(self.quat[ok]))
        return out

    def to_estimates(self, dim: int = 3, name: str | None = None) -> Estimates:
        """The common result type (positions in ``dim`` coordinates)."""
        status = self.status.copy()
        pos = self.pos_m[:, :dim].copy()
        pos[status == EstimateStatus.NO_ESTIMATE] = np.nan
        return Estimates(self.t_s, pos, status, name or self.name, self.pos_cov_m2[:, :dim, :dim],
                         self.vel_mps[:, :dim], {"nis": self.nis, "dof": self.dof, "n_outliers": self.n_outliers,
                                                 "n_gated": self.n_gated})

    def nis_consistency(self, prob: float = 0.95) -> dict:
        """χ² consistency of the NIS over the epochs with updates (:func:`uwbwb.metrics.nis_consistency`:
        the keys of every run type)."""
        return nis_consistency(self.nis, self.dof, prob)

    def to_frame(self) -> pd.DataFrame:
        eul = np.degrees(self.euler_rad)
        cols = {"t_s": self.t_s}
        cols.update({f"{a}_m": self.pos_m[:, k] for k, a in enumerate("xyz")})
        cols.update({f"v{a}_mps": self.vel_mps[:, k] for k, a in enumerate("xyz")})
        cols.update({f"{a}_deg": eul[:, k] for k, a in enumerate(("roll", "pitch", "yaw"))})
        cols.update(nis=self.nis, dof=self.dof, n_outliers=self.n_outliers, n_gated=self.n_gated,
                    status=[EstimateStatus(s).label for s in self.status])
        return pd.DataFrame(cols)


def _empty(T: int, n: int):
    nan = lambda *s: np.full((T,) + s, np.nan)  # noqa: E731
    return dict(pos_m=nan(3), vel_mps=nan(3), quat=nan(4), acc_bias_mps2=nan(3), gyro_bias_radps=nan(3),
                P=nan(n, n), pos_cov_m2=nan(3, 3), nis=nan(), dof=np.zeros(T, int), n_outliers=np.zeros(T, int),
                n_gated=np.zeros(T, int), status=np.full(T, EstimateStatus.NO_ESTIMATE, np.int8))


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def dead_reckon(imu: ImuLog, x0: NavState, t_s: np.ndarray, *, mechanization: Mechanization = Mechanization(),
                lever_arm_m=(0.0, 0.0, 0.0), acc_bias=None, gyro_bias=None, max_imu_gap_s: float | None = None,
                name: str = "INS-only") -> FusionRun:
    """INS alone: the mechanization from ``x0`` with constant bias corrections, no aiding at all,
    reported at ``t_s`` (status ``PREDICTED``; no covariance).

    Across an IMU gap (a step between samples longer than ``max_imu_gap_s``; None:
    :data:`~uwbwb.filters.eskf.MAX_IMU_GAP_STEPS` median steps, the rule of the filters) nothing
    is interpolated: the INS coasts as the filters do (:func:`~uwbwb.models.ins.coast`: velocity
    and attitude held, ``p += v Δt``) and goes on from there when the samples return. The gaps are
    listed in ``meta["imu_gaps_s"]`` ``(G, 2)`` s, and ``meta["imu_coasted"]`` ``(T,)`` marks the
    epochs whose state went through one (from the first gap on: with no aiding, a coast's error
    stays in every later position). Coasting rather than stopping keeps INS-only scored on the
    same epochs, under the same assumption, as the filters it is compared with.
    """
    check_inputs("dead_reckon", imu, x0)
    t_ep = np.asarray(t_s, float)
    if max_imu_gap_s is not None:
        validate.number("dead_reckon.max_imu_gap_s", max_imu_gap_s, minimum=0.0, strict_minimum=True)
    t, acc, gyro, idx, coasting, gaps_s = gap_timeline(imu, t_ep, max_imu_gap_s)
    ba = np.zeros(3) if acc_bias is None else np.asarray(acc_bias, float)
    bg = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, float)
    if not coasting.any():
        p, v, q = mechanization.integrate(t, acc - ba, gyro - bg, x0)
    else:
        p, v, q = np.empty((t.size, 3)), np.empty((t.size, 3)), np.empty((t.size, 4))
        p[0], v[0], q[0] = x0.pos_m, x0.vel_mps, x0.quat
        edge = np.flatnonzero(np.diff(coasting[1:].astype(np.int8))) + 1   # last step of each run
        no_q, dummy_phi, dummy_q = np.zeros(N_ERR), np.eye(N_ERR), np.zeros((N_ERR, N_ERR))
        for j0, j1 in zip(np.r_[0, edge], np.r_[edge, t.size - 1]):       # steps j0 → j1, one kind
            if coasting[j1]:
                for j in range(j0 + 1, j1 + 1):
                    p[j], v[j], q[j] = p[j - 1], v[j - 1], q[j - 1]
                    coast(p[j], v[j], t, j - 1, j, no_q, 0.0, 0.0, dummy_phi, dummy_q)
            else:
                x = NavState(p[j0], v[j0], q[j0])
                p[j0:j1 + 1], v[j0:j1 + 1], q[j0:j1 + 1] = mechanization.integrate(
                    t[j0:j1 + 1], acc[j0:j1 + 1] - ba, gyro[j0:j1 + 1] - bg, x)
    out = _empty(t_ep.size, N_ERR)
    ok = idx >= 0
    C = quat_to_dcm(q[idx[ok]])
    out["pos_m"][ok] = p[idx[ok]] + C @ np.asarray(lever_arm_m, float)
    out["vel_mps"][ok], out["quat"][ok] = v[idx[ok]], q[idx[ok]]
    out["acc_bias_mps2"][ok], out["gyro_bias_radps"][ok] = ba, bg
    out["status"][ok] = EstimateStatus.PREDICTED
    coasted = np.zeros(t_ep.size, bool)
    if gaps_s.size:
        coasted[ok] = t_ep[ok] > gaps_s[0, 0]
    return FusionRun(t_ep.copy(), name=name, meta={"imu_gaps_s": gaps_s, "imu_coasted": coasted}, **out)
