"""UWB/INS fusion by error-state Kalman filters (paper 004): the paper's loose filter and a tight one.

Both run the strapdown mechanization of :mod:`uwbwb.models.ins` at the IMU rate and
correct it at the UWB epochs; every prediction and update goes through
:mod:`uwbwb.filters.kalman`. Results come back as :class:`FusionRun` (with
:meth:`FusionRun.to_estimates` giving the common :class:`~uwbwb.types.Estimates`).

**Loose — the paper's filter (eqs 5–7).** Error state ``[δP_E, δP_N, δV_E, δV_N]``
(``dim=2``; ``dim=3`` adds the vertical pair for a flying platform), constant-velocity
transition ``A`` with the UWB period ``T``, ``H = I`` and
``z = [P_ins − P_uwb; V_ins − V_uwb]``. ``P_uwb`` is a UWB position fix (TDoA least
squares after the eq-4 test); ``V_uwb`` is its backward difference over ``vel_window``
epochs, ``(P_k − P_{k−w}) / (t_k − t_{k−w})``. The INS attitude comes, as in the paper's
IMU, from the gyro with a complementary correction towards accelerometer levelling and,
where there is one, the magnetometer heading (time constant ``attitude_tau_s``); the
filter does not estimate attitude or sensor biases. Closed loop: the estimated errors are
subtracted from the INS position and velocity and the error state is reset to zero.

**Tight.** Error state ``[δp, δv, δθ, δb_a, δb_g]`` (15; :mod:`uwbwb.models.ins`),
propagated with the IMU (``F = I + AΔt + ½(AΔt)²``, ``Q`` from the
:class:`~uwbwb.models.imu.ImuErrorModel`). Every TDoA (or range) of an epoch is its own
scalar update, with the Jacobian of ``h = ‖p + C l − a_j‖ − ‖p + C l − a_ref‖`` with
respect to position *and attitude* (lever arm ``l``): first the eq-4 test drops
implausible TDoAs, then each remaining TDoA must pass a χ²(1) innovation gate
(``gate_prob``) against the prior, then the survivors are applied one at a time
(decorrelated through the Cholesky factor of their reference-correlated covariance,
:func:`~uwbwb.filters.kalman.update_sequential`). So a single TDoA still corrects the
INS when too few stations are heard for a position fix. Optional pseudo-measurements:
a magnetometer heading and a known tag height (a ground robot). Closed loop
(``feedback=True``): after the epoch the error estimate is injected into the nominal
state, the error reset to zero and ``P ← G P Gᵀ``
(:func:`~uwbwb.models.ins.reset_jacobian`). With ``feedback=False`` the nominal INS
runs open loop and the error state carries the whole correction (output = nominal ⊕ δx).

Time: the IMU samples and the UWB epochs are merged into one time line; IMU values at
a UWB epoch are interpolated linearly between neighbouring samples, so each update happens at
its own time stamp. Across an IMU gap (longer than ``max_imu_gap_s``) the tight filter
interpolates nothing: it coasts (velocity and attitude held, covariance grown by an assumed
motion, :func:`~uwbwb.models.ins.coast_transition`), keeps updating with UWB, and lists the gaps
in ``FusionRun.meta["imu_gaps_s"]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
import pandas as pd
from scipy.stats import chi2

from .. import validate
from ..models.imu import HeadingLog, ImuErrorModel
from ..models.ins import (BA_, BG_, N_ERR, P_, TH_, V_, Mechanization, NavState, _dcm, _dcm_nb, _exp_left,
                          _skew3, _yaw, coast, coast_transition,
                          euler_from_dcm, error_transition, inject, propagate, quat_to_dcm, reset_jacobian,
                          yaw_jacobian)
from ..models.tdoa import TdoaModel, triangle_outliers
from ..types import EstimateStatus, Estimates, ImuLog, RangeLog, TdoaLog
from . import kalman
from .ekf import Linearisation
from .kalman import Gaussian, _sequential
from .tdoa_ls import tdoa_least_squares

__all__ = ["FusionRun", "HeadingLog", "LooseFilter", "RangeUpdate", "TdoaUpdate", "TightEskf", "dead_reckon",
           "imu_gaps", "merge_timeline"]

_DEG = math.pi / 180.0
_ITER_TOL_M = 1e-4           # an iterated update stops when the position moves less than this, m
HEADING_KNOWN_RAD = 10 * _DEG  # an initial yaw σ at most this is a known heading: the gate is engaged at once
LOST_BUILD_S = 1.0           # lost lock: the time over which the position error is assumed to have built up, s
MAX_IMU_GAP_STEPS = 5        # an IMU step longer than this many median steps is a gap (the loader's rule)
SNAPSHOT_RMS_SIGMAS = 3.0    # a snapshot fix is consistent when its TDoA residual RMS is at most this many TDoA σ


def _lever(name: str, value) -> np.ndarray:
    """A lever arm: 3 finite numbers, m, body frame."""
    try:
        lever = np.array(value, float)
    except (TypeError, ValueError):
        lever = np.array([np.nan])
    if lever.shape != (3,) or not np.all(np.isfinite(lever)):
        raise ValueError(f"{name} must be 3 finite numbers (m, body frame), got {value!r}")
    return lever


# ====================================================================== inputs
def merge_timeline(imu: ImuLog, t_epoch_s: np.ndarray):
    """IMU samples and UWB epochs on one time line.

    Returns
    -------
    t_s (N,), acc_mps2 (N, 3), gyro_radps (N, 3), epoch_idx (E,)
        The union of the IMU times and the epochs inside the IMU span, the IMU values
        there (linear interpolation at epochs between samples), and each epoch's index
        in ``t_s`` (−1 for epochs outside the IMU span).
    """
    te = np.asarray(t_epoch_s, float)
    inside = (te >= imu.t_s[0]) & (te <= imu.t_s[-1])
    t = np.union1d(imu.t_s, te[inside])
    acc = np.column_stack([np.interp(t, imu.t_s, imu.acc_mps2[:, j]) for j in range(3)])
    gyro = np.column_stack([np.interp(t, imu.t_s, imu.gyro_radps[:, j]) for j in range(3)])
    idx = np.full(te.size, -1)
    idx[inside] = np.searchsorted(t, te[inside])
    return t, acc, gyro, idx


def imu_gaps(imu_t_s: np.ndarray, t_s: np.ndarray, max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The IMU gaps on a merged time line.

    Returns
    -------
    coast (N,), gaps_s (G, 2)
        ``coast[i]``: the step ``t_s[i−1] → t_s[i]`` lies inside an interval between IMU samples
        longer than ``max_gap_s`` (no sample measured the motion there); the ``(start, end)``
        times of those intervals, s.
    """
    ti = np.asarray(imu_t_s, float)
    step = np.diff(ti)
    big = np.flatnonzero(step > max_gap_s)
    gaps = np.column_stack([ti[big], ti[big + 1]]) if big.size else np.zeros((0, 2))
    t = np.asarray(t_s, float)
    coast = np.zeros(t.size, bool)
    for a, b in gaps:
        coast[1:] |= (t[1:] > a) & (t[1:] <= b)
    return coast, gaps


# ====================================================================== measurement models
def _tag_jacobian(C: np.ndarray, lever_m: np.ndarray) -> np.ndarray:
    """``∂(p + C l)/∂δx``, shape ``(3, 15)``: identity on δp, ``−[C l ×]`` on δθ."""
    J = np.zeros((3, N_ERR))
    J[:, P_] = np.eye(3)
    J[:, TH_] = -_skew3(C @ lever_m)
    return J


@dataclass(frozen=True)
class TdoaUpdate:
    """Raw TDoAs as error-state measurements (plus the eq-4 test).

    Attributes
    ----------
    model
        TDoA model with ``dim=3`` (anchors, per-anchor range σ, reference correlation).
    outlier_c_m
        ``C`` of eq. (4), metres; None disables the test.
    """

    model: TdoaModel
    outlier_c_m: float | None = 0.1

    def __post_init__(self):
        if not isinstance(self.model, TdoaModel):
            raise ValueError(f"TdoaUpdate.model must be a TdoaModel, got {type(self.model).__name__}")
        if self.outlier_c_m is not None:
            validate.number("TdoaUpdate.outlier_c_m", self.outlier_c_m, minimum=0.0, strict_minimum=True)
        if self.model.dim != 3:
            raise ValueError("TdoaUpdate needs a 3-D TdoaModel (the INS state is 3-D; a known height is a "
                             "separate pseudo-measurement)")

    def screen(self, tdoa_m: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The eq-4 test over a whole log: TDoAs with the rejected ones set to NaN, and the
        number rejected per epoch."""
        d = np.array(tdoa_m, float)
        if self.outlier_c_m is None:
            return d, np.zeros(d.shape[0], int)
        bad = triangle_outliers(d, ref, self.model.anchor_pos_m, self.outlier_c_m)
        d[bad] = np.nan
        return d, bad.sum(axis=1)

    def snapshot(self, t_s: np.ndarray, tdoa_m: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Each epoch's own TDoA least-squares fix (started at the anchors' centroid, no prior),
        ``(T, 3)``, m; NaN where there is none or it is inconsistent: not converged, or a
        residual RMS above :data:`SNAPSHOT_RMS_SIGMAS` TDoA σ (``√2`` times the median range σ).

        :class:`TightEskf` starts its iterated update there when the prior is far off (after an
        outage), instead of linearising at a prior metres away."""
        d = np.asarray(tdoa_m, float)
        ids = tuple(str(j) for j in range(d.shape[1]))
        ls = tdoa_least_squares(TdoaLog(np.asarray(t_s, float), d, np.asarray(ref, int), ids), self.model)
        limit = SNAPSHOT_RMS_SIGMAS * math.sqrt(2.0) * float(np.median(self.model.sigma_m))
        good = (ls.status == 0) & (ls.residual_rms_m <= limit) & np.all(np.isfinite(ls.pos_m), axis=1)
        return np.where(good[:, None], ls.pos_m, np.nan)

    def linearise(self, tag_pos_m, J_tag, row, ref) -> Linearisation | None:
        """Linearisation of one epoch's (screened) TDoAs at the tag position."""
        if ref < 0 or np.isfinite(row).sum() < 2:
            return None
        z, h, H_pos, R, _ = self.model.epoch(row, tag_pos_m, int(ref))
        return Linearisation(z, h, H_pos @ J_tag, R)


@dataclass(frozen=True)
class RangeUpdate:
    """Ranges (two-way, independent noise) as error-state measurements.

    Attributes
    ----------
    anchor_pos_m
        ``(n_anchors, 3)``, m.
    sigma_m
        Range noise SD, scalar or per anchor, m.
    bias_m
        Common range bias subtracted from every range, m.
    """

    anchor_pos_m: np.ndarray
    sigma_m: np.ndarray | float = 0.1
    bias_m: float = 0.0

    def __post_init__(self):
        a = np.array(self.anchor_pos_m, float)
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"RangeUpdate.anchor_pos_m must be (n, 3), got {a.shape}")
        s = np.broadcast_to(np.array(self.sigma_m, float), (a.shape[0],)).copy()
        if not np.all(np.isfinite(a)):
            raise ValueError("RangeUpdate.anchor_pos_m must be finite")
        if np.any(~(s > 0)) or not np.all(np.isfinite(s)):
            raise ValueError(f"RangeUpdate.sigma_m must be positive and finite, got {self.sigma_m!r}")
        validate.number("RangeUpdate.bias_m", self.bias_m)
        object.__setattr__(self, "anchor_pos_m", a)
        object.__setattr__(self, "sigma_m", s)

    def screen(self, range_m: np.ndarray, ref=None) -> tuple[np.ndarray, np.ndarray]:
        """Ranges have no eq-4 test: returned unchanged, zero rejections."""
        return np.asarray(range_m, float), np.zeros(len(range_m), int)

    def linearise(self, tag_pos_m, J_tag, row, ref=None) -> Linearisation | None:
        ok = np.flatnonzero(np.isfinite(row))
        if ok.size == 0:
            return None
        d = tag_pos_m - self.anchor_pos_m[ok]
        r = np.sqrt(np.einsum("ij,ij->i", d, d))
        u = d / np.maximum(r, 1e-9)[:, None]
        return Linearisation(row[ok] - self.bias_m, r, u @ J_tag, np.diag(self.sigma_m[ok] ** 2))


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
        Per epoch: TDoAs (or fixes) rejected by the eq-4 test, and by the χ² gate.
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

    def nis_consistency(self, prob: float = 0.95) -> dict[str, float]:
        """Mean NIS per degree of freedom and the two-sided χ² bounds of the NIS sum."""
        up = self.dof > 0
        total = int(self.dof[up].sum())
        if total == 0:
            return {"n": 0, "mean_nis_over_dof": np.nan, "sum_lo": np.nan, "sum_hi": np.nan, "sum_nis": np.nan}
        a = (1 - prob) / 2
        s = float(self.nis[up].sum())
        return {"n": int(up.sum()), "mean_nis_over_dof": s / total, "sum_nis": s, "sum_dof": total,
                "sum_lo": float(chi2.ppf(a, total)), "sum_hi": float(chi2.ppf(1 - a, total))}

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
                lever_arm_m=(0.0, 0.0, 0.0), acc_bias=None, gyro_bias=None, name: str = "INS-only") -> FusionRun:
    """INS alone: the mechanization from ``x0`` with constant bias corrections, no aiding at all,
    reported at ``t_s`` (status ``PREDICTED``; no covariance)."""
    t_ep = np.asarray(t_s, float)
    t, acc, gyro, idx = merge_timeline(imu, t_ep)
    ba = np.zeros(3) if acc_bias is None else np.asarray(acc_bias, float)
    bg = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, float)
    p, v, q = mechanization.integrate(t, acc - ba, gyro - bg, x0)
    out = _empty(t_ep.size, N_ERR)
    ok = idx >= 0
    C = quat_to_dcm(q[idx[ok]])
    out["pos_m"][ok] = p[idx[ok]] + C @ np.asarray(lever_arm_m, float)
    out["vel_mps"][ok], out["quat"][ok] = v[idx[ok]], q[idx[ok]]
    out["acc_bias_mps2"][ok], out["gyro_bias_radps"][ok] = ba, bg
    out["status"][ok] = EstimateStatus.PREDICTED
    return FusionRun(t_ep.copy(), name=name, **out)


# ====================================================================== tight
@dataclass(frozen=True)
class TightEskf:
    """Tightly coupled 15-state error-state filter (module docstring).

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
        Per-measurement χ²(1) gate probability; None: no gate.
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

    # ---------------------------------------------------------------- run
    def run(self, imu: ImuLog, uwb: TdoaLog | RangeLog | None, x0: NavState, *, t_s: np.ndarray | None = None,
            heading: HeadingLog | None = None, acc_bias0=None, gyro_bias0=None, name: str | None = None,
            reference_step: bool = False) -> FusionRun:
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
        reference_step
            Same as :meth:`run_reference` (kept as an alias): run the straightforward form, step by step in Python (the mechanization and
            :func:`kalman.predict` at every IMU step, the measurement models and
            :func:`kalman.update_sequential` at every epoch; for benchmarks and tests) instead
            of the compiled loop (:func:`_tight_loop`: the accumulated transition once per
            epoch, same updates); results are identical up to rounding (tested).
        """
        t_ep = (imu.t_s if t_s is None else np.asarray(t_s, float)) if uwb is None else uwb.t_s
        T = t_ep.size
        if uwb is not None and isinstance(uwb, TdoaLog) != isinstance(self.uwb, TdoaUpdate):
            raise ValueError("TightEskf.run: a TdoaLog needs a TdoaUpdate model and a RangeLog a RangeUpdate")
        rows, refs, n_out_all = None, None, np.zeros(T, int)
        if uwb is not None:
            refs = uwb.ref if isinstance(uwb, TdoaLog) else np.zeros(T, int)
            rows, n_out_all = self.uwb.screen(uwb.tdoa_m if isinstance(uwb, TdoaLog) else uwb.range_m, refs)
        fix_tag = np.full((T, 3), np.nan)       # first linearisation point of an iterated update
        if rows is not None and isinstance(self.uwb, TdoaUpdate) and math.isfinite(self.iterate_sigma_m):
            fix_tag = self.uwb.snapshot(t_ep, rows, refs)
        t, acc, gyro, ep_idx = merge_timeline(imu, t_ep)
        max_gap = (MAX_IMU_GAP_STEPS * float(np.median(np.diff(imu.t_s))) if self.max_imu_gap_s is None
                   else self.max_imu_gap_s) if imu.t_s.size > 1 else math.inf
        coasting, gaps_s = imu_gaps(imu.t_s, t, max_gap)
        inside = coasting & ~np.isin(t, imu.t_s)        # epochs inside a gap: nothing measured there,
        acc[inside], gyro[inside] = np.nan, np.nan      # so no IMU value is invented
        meta = {"imu_gaps_s": gaps_s}
        yaw_meas = heading.at(t_ep) if heading is not None else np.full(T, np.nan)
        out = _empty(T, N_ERR)
        mech, lever = self.mechanization, self.lever_arm_m
        p, v, q = x0.pos_m.copy(), x0.vel_mps.copy(), x0.quat.copy()
        ba = np.zeros(3) if acc_bias0 is None else np.array(acc_bias0, float)
        bg = np.zeros(3) if gyro_bias0 is None else np.array(gyro_bias0, float)
        dx = np.zeros(N_ERR)
        P = self.initial_covariance()
        qrate = self.process_noise_rate()
        gate1 = chi2.ppf(self.gate_prob, 1) if self.gate_prob is not None else np.inf
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
        # The reference form, step by step in Python: mechanization and filterpy predict at every
        # IMU step, then the epoch's update through the measurement models and kalman.update_sequential.
        last = 0
        for i in np.flatnonzero(ep_at >= 0):
            for j in range(last + 1, i + 1):
                dt = t[j] - t[j - 1]
                if coasting[j]:                           # inside an IMU gap: coast
                    p = p + v * dt
                    F, Q = coast_transition(dt, qrate, self.coast_acc_sigma_mps2, self.coast_rate_sigma_radps)
                    st = kalman.predict(Gaussian(dx, P), F, Q)
                    dx, P = st.x, st.P
                    continue
                f0, f1 = acc[j - 1] - ba, acc[j] - ba
                p, v, q, C0, _ = mech.step(p, v, q, f0, f1, gyro[j - 1] - bg, gyro[j] - bg, dt)
                st = kalman.predict(Gaussian(dx, P), error_transition(C0, f0, dt), np.diag(qrate * dt))
                dx, P = st.x, st.P
            last = i
            k = ep_at[i]
            C = _dcm(q)
            J_tag = _tag_jacobian(C, lever)
            tag = p + C @ lever
            far = np.sqrt(np.trace(J_tag @ P @ J_tag.T)) > self.iterate_sigma_m   # before any lost-lock inflation
            parts = []                                   # (z, h, H, R) blocks used this epoch
            n_gated, n_out = 0, int(n_out_all[k])
            uwb_used = 0
            keep = None
            if rows is not None:
                lin = self.uwb.linearise(tag, J_tag, rows[k], int(refs[k]))
                if lin is not None:
                    y = lin.z - lin.h - lin.H @ dx
                    if gated_run >= self.max_gated:         # lock lost: admit it, then re-acquire ungated
                        P = P + np.diag(self.lost_lock_variance(float(np.mean(y * y))))
                    R = lin.R * self.r_scale
                    s = np.einsum("ij,jk,ik->i", lin.H, P, lin.H) + np.diag(R)
                    test = y * y / s <= gate1
                    keep = test if engaged and gated_run < self.max_gated else np.ones(y.size, bool)
                    if not engaged:                       # start-up: is the heading resolved?
                        clean_run = clean_run + 1 if 2 * int((~test).sum()) < y.size else 0
                        engaged = clean_run >= self.max_gated and P[8, 8] <= self.gate_yaw_sigma_rad ** 2
                    n_gated = int((~keep).sum())
                    if keep.any():
                        parts.append((lin.z[keep], lin.h[keep] + lin.H[keep] @ dx, lin.H[keep],
                                      R[np.ix_(keep, keep)]))
                        uwb_used = int(keep.sum())
                    lost = n_gated >= uwb_used and self.feedback
                    gated_run = gated_run + 1 if (n_gated and lost) else 0
            if np.isfinite(yaw_meas[k]) and sig_yaw > 0:
                Hy = np.zeros(N_ERR)
                Hy[TH_] = yaw_jacobian(C)
                resid = _wrap(yaw_meas[k] - _yaw(C))
                parts.append((np.array([resid]), np.array([Hy @ dx]), Hy[None], np.array([[sig_yaw ** 2]])))
            if self.height_m is not None:
                parts.append((np.array([self.height_m]), np.array([tag[2] + J_tag[2] @ dx]), J_tag[2:3],
                              np.array([[self.height_sigma_m ** 2]])))
            nis, dof = np.nan, 0
            if parts:
                z = np.concatenate([a[0] for a in parts])
                h = np.concatenate([a[1] for a in parts])
                H = np.vstack([a[2] for a in parts])
                R = _block_diag([a[3] for a in parts])
                st, nis_parts = kalman.update_sequential(Gaussian(dx, P), z, H, R, h_x=h)
                nis = float(nis_parts[:uwb_used].sum()) if uwb_used else np.nan
                dof = uwb_used
                if uwb_used and far:
                    # iterated update (IEKF): relinearise the UWB rows at the updated tag position
                    for it in range(self.max_iter - 1):
                        d = st.x
                        if it == 0 and np.all(np.isfinite(fix_tag[k])):   # start at the snapshot fix
                            d = dx.copy()
                            d[P_] = fix_tag[k] - tag - J_tag[:, TH_] @ dx[TH_]
                        li = self.uwb.linearise(tag + d[P_] + J_tag[:, TH_] @ d[TH_], J_tag, rows[k], int(refs[k]))
                        zi, hi, Hi = li.z[keep], li.h[keep], li.H[keep]
                        h[:uwb_used] = hi + Hi @ (dx - d)     # y_i = z − h(x_i) − H_i (dx − δx_i) − H_i dx
                        H[:uwb_used] = Hi
                        st, _ = kalman.update_sequential(Gaussian(dx, P), z, H, R, h_x=h)
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
                      gyro_bias0=None, name: str | None = None) -> FusionRun:
        """The Python definition of :meth:`run` (its ``reference_step=True``): the mechanization
        and :func:`kalman.predict` at every IMU step, the measurement models and
        :func:`kalman.update_sequential` at every epoch. The compiled loop must equal it to
        rounding (the twin tests)."""
        return self.run(imu, uwb, x0, t_s=t_s, heading=heading, acc_bias0=acc_bias0, gyro_bias0=gyro_bias0,
                        name=name, reference_step=True)

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
        code = _tight_loop(
            t, acc, gyro, tl, ep_at[tl], np.ascontiguousarray(rows, float), np.asarray(refs, np.int64), kind,
            np.ascontiguousarray(anchors, float), np.ascontiguousarray(var_m, float), correlated, float(bias_m),
            float(self.r_scale), float(gate1), int(self.max_gated), float(self.gate_yaw_sigma_rad) ** 2, HEADING_KNOWN_RAD ** 2,
            self.lost_lock_variance(), float(self.iterate_sigma_m), int(self.max_iter), _ITER_TOL_M,
            np.ascontiguousarray(fix_tag, float), np.ascontiguousarray(coasting, np.bool_),
            float(self.coast_acc_sigma_mps2) ** 2, float(self.coast_rate_sigma_radps) ** 2, np.asarray(yaw_meas, float),
            float(self.imu_model.mag_heading_sigma_rad), self.height_m is not None,
            float(self.height_m or 0.0), float(self.height_sigma_m), bool(self.feedback), self.lever_arm_m, qrate,
            self.mechanization.g_n, p.copy(), v.copy(), q.copy(), ba.copy(), bg.copy(), P.copy(), out["pos_m"],
            out["vel_mps"], out["quat"], out["acc_bias_mps2"], out["gyro_bias_radps"], out["P"], out["pos_cov_m2"],
            out["nis"], out["dof"], out["n_gated"], out["status"], int(EstimateStatus.UPDATED),
            int(EstimateStatus.GATED), int(EstimateStatus.PREDICTED))
        if code == 1:
            raise ValueError("update_sequential: non-finite values; a missing measurement is left out, not passed as NaN")
        if code == 2:
            raise ValueError("update_sequential: R must be symmetric positive definite")


def _block_diag(blocks) -> np.ndarray:
    n = sum(b.shape[0] for b in blocks)
    out = np.zeros((n, n))
    i = 0
    for b in blocks:
        m = b.shape[0]
        out[i:i + m, i:i + m] = b
        i += m
    return out


# ====================================================================== tight, compiled
@numba.njit(cache=True, nogil=True)
def _skew_into(v, S):
    S[0, 0], S[0, 1], S[0, 2] = 0.0, -v[2], v[1]
    S[1, 0], S[1, 1], S[1, 2] = v[2], 0.0, -v[0]
    S[2, 0], S[2, 1], S[2, 2] = -v[1], v[0], 0.0


@numba.njit(cache=True, nogil=True)
def _exp_left_nb(rv, q):
    """:func:`~uwbwb.models.ins._exp_left` (``Exp(rv) ⊗ q``, normalised), in place on ``q``."""
    ang = math.sqrt(rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2])
    k = math.sin(0.5 * ang) / ang if ang > 1e-8 else 0.5 - ang * ang / 48.0
    rw, rx, ry, rz = math.cos(0.5 * ang), k * rv[0], k * rv[1], k * rv[2]
    w, x, y, z = q[0], q[1], q[2], q[3]
    o0 = rw * w - rx * x - ry * y - rz * z
    o1 = rw * x + rx * w + ry * z - rz * y
    o2 = rw * y - rx * z + ry * w + rz * x
    o3 = rw * z + rx * y - ry * x + rz * w
    nq = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2 + o3 * o3)
    q[0], q[1], q[2], q[3] = o0 / nq, o1 / nq, o2 / nq, o3 / nq


@numba.njit(cache=True, nogil=True)
def _reset_block(phi):
    """The attitude block of :func:`~uwbwb.models.ins.reset_jacobian`, ``(3, 3)``."""
    th = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    S = np.empty((3, 3))
    _skew_into(phi, S)
    if th < 1e-6:
        a, b = 0.5 - th * th / 24.0, 1.0 / 6.0 - th * th / 120.0
    else:
        a, b = (1 - math.cos(th)) / th ** 2, (th - math.sin(th)) / th ** 3
    return np.eye(3) + (a * S + b * (S @ S))


@numba.njit(cache=True, nogil=True)
def _reset_covariance(P, Gt):
    """``P ← G P Gᵀ`` in place, with ``G`` the identity but for the attitude block ``Gt``."""
    rows = np.empty((3, 15))
    for a in range(3):
        for b in range(15):
            rows[a, b] = Gt[a, 0] * P[6, b] + Gt[a, 1] * P[7, b] + Gt[a, 2] * P[8, b]
    P[6:9, :] = rows
    cols = np.empty((15, 3))
    for a in range(15):
        for b in range(3):
            cols[a, b] = P[a, 6] * Gt[b, 0] + P[a, 7] * Gt[b, 1] + P[a, 8] * Gt[b, 2]
    P[:, 6:9] = cols


@numba.njit(cache=True, nogil=True)
def _tight_loop(t, acc, gyro, tl_idx, ep_of, rows, refs, kind, anchors, var_m, correlated, bias_m, r_scale, gate1,
                max_gated, gate_yaw_var, heading_known_var, p_lost, iterate_sigma_m, max_iter, iter_tol, fix_tag, coasting,
                coast_acc_var, coast_rate_var, yaw_meas, sig_yaw,
                use_height, height_m,
                sig_height, feedback, lever, qrate, g_n, p, v, q, ba, bg, P, pos_o, vel_o, quat_o, ba_o, bg_o, P_o,
                cov_o, nis_o, dof_o, gated_o, status_o, st_updated, st_gated, st_predicted):
    """:meth:`TightEskf.run` compiled: the same steps as its reference loop, epoch after epoch.

    Per epoch (timeline index ``tl_idx[e]``, epoch ``ep_of[e]``): :func:`propagate` from the last
    epoch and one predict ``dx ← Φ dx``, ``P ← Φ P Φᵀ + Q`` (symmetrised); the epoch's TDoAs
    (``kind`` 1, :meth:`TdoaModel.epoch` with the lever-arm Jacobian) or ranges (``kind`` 2,
    :meth:`RangeUpdate.linearise`, both :func:`_uwb_rows`), the lost-lock inflation ``P += diag(p_lost)``,
    the χ² gate, the heading and height pseudo-measurements; :func:`~uwbwb.filters.kalman._sequential`,
    iterated (relinearised UWB rows) while the prior tag σ exceeds ``iterate_sigma_m``; injection and reset. ``p, v, q, ba, bg, P`` are
    worked on in place; outputs go to row ``ep_of[e]`` of the ``*_o`` arrays. Returns 0, or the
    error code of ``_sequential``. Tested equal to the reference loop and to the model functions.
    """
    n_a = anchors.shape[0]
    m_max = n_a + 2
    dx = np.zeros(15)
    C = np.empty((3, 3))
    Sl = np.empty((3, 3))
    Phi = np.empty((15, 15))
    Qacc = np.empty((15, 15))
    z = np.empty(m_max)
    h = np.empty(m_max)
    H = np.zeros((m_max, 15))
    Rd = np.empty(m_max)
    keep = np.empty(m_max, np.bool_)
    hp = np.empty(3)
    z2 = np.empty(m_max)
    h2 = np.empty(m_max)
    H2 = np.zeros((m_max, 15))
    Rd2 = np.empty(m_max)
    gated_run, clean_run = 0, 0
    engaged = P[8, 8] <= heading_known_var
    last = 0
    for e in range(tl_idx.size):
        i, k = tl_idx[e], ep_of[e]
        if i > last:
            Phi[:, :] = 0.0
            Qacc[:, :] = 0.0
            for j in range(15):
                Phi[j, j] = 1.0
            j0 = last                           # runs of IMU steps and of coast steps (IMU gaps)
            while j0 < i:
                j1 = j0 + 1
                while j1 < i and coasting[j1 + 1] == coasting[j0 + 1]:
                    j1 += 1
                if coasting[j0 + 1]:
                    coast(p, v, t, j0, j1, qrate, coast_acc_var, coast_rate_var, Phi, Qacc)
                else:
                    propagate(p, v, q, ba, bg, t, acc, gyro, j0, j1, g_n, qrate, Phi, Qacc)
                j0 = j1
            dx = Phi @ dx
            P = Phi @ P @ Phi.T + Qacc
            P = 0.5 * (P + P.T)
        last = i
        _dcm_nb(q, C)
        cl = C @ lever
        _skew_into(cl, Sl)                      # J_tag = [I, 0, −[C l ×], 0, 0]
        tag = p + cl
        Jt = np.zeros((3, 15))
        for a in range(3):
            Jt[a, a] = 1.0
            for b in range(3):
                Jt[a, 6 + b] = -Sl[a, b]
        far = math.sqrt(np.trace(Jt @ P @ Jt.T)) > iterate_sigma_m   # the propagated prior, before any lost-lock inflation
        # ---- UWB rows (z, h, H) and their noise (diagonal Rd; TDoA adds the reference's variance)
        n_gated, uwb_used = 0, 0
        row = rows[k]
        m, lin, var_ref = _uwb_rows(kind, row, refs[k], anchors, var_m, bias_m, tag, Sl, z, h, H, Rd, hp)
        m_lin = m
        off = 0.0                               # R = (diag(Rd) + var_ref 1 1ᵀ) r_scale, or its diagonal
        if lin:
            if gated_run >= max_gated:          # lock lost: admit it, then re-acquire ungated
                ms = 0.0
                for a in range(m):
                    ya = z[a] - h[a] - H[a] @ dx
                    ms += ya * ya
                ms /= m
                for a in range(15):
                    if a < 3:
                        P[a, a] += p_lost[a] + ms
                    elif a < 6:
                        P[a, a] += p_lost[a] + ms / LOST_BUILD_S ** 2
                    else:
                        P[a, a] += p_lost[a]
            for a in range(m):
                Rd[a] = (Rd[a] + var_ref) * r_scale
            if correlated:
                off = var_ref * r_scale
            n_fail = 0
            for a in range(m):
                Hdx = H[a] @ dx
                y = z[a] - h[a] - Hdx
                s = H[a] @ P @ H[a] + Rd[a]
                test = y * y / s <= gate1
                keep[a] = test if (engaged and gated_run < max_gated) else True
                if not test:
                    n_fail += 1
                h[a] += Hdx
            if not engaged:                     # start-up: is the heading resolved?
                clean_run = clean_run + 1 if 2 * n_fail < m else 0
                engaged = clean_run >= max_gated and P[8, 8] <= gate_yaw_var
            w = 0
            for a in range(m):                  # the kept rows first, in order
                if keep[a]:
                    z[w], h[w], Rd[w] = z[a], h[a], Rd[a]
                    H[w] = H[a]
                    w += 1
            n_gated = m - w
            uwb_used = w
            m = w
            lost = n_gated >= uwb_used and feedback
            gated_run = gated_run + 1 if (n_gated > 0 and lost) else 0
        n_uwb = m
        # ---- heading and height pseudo-measurements
        if np.isfinite(yaw_meas[k]) and sig_yaw > 0:
            c0, c1, c2 = C[0, 0], C[1, 0], C[2, 0]
            den = c0 ** 2 + c1 ** 2
            H[m] = 0.0
            H[m, 6], H[m, 7], H[m, 8] = (-c0 * c2 + c1 * 0.0) / den, (-c0 * 0.0 + c1 * -c2) / den, \
                (-c0 * -c0 + c1 * c1) / den
            a = yaw_meas[k] - math.atan2(C[1, 0], C[0, 0])
            z[m] = (a + np.pi) % (2 * np.pi) - np.pi
            h[m] = H[m] @ dx
            Rd[m] = sig_yaw ** 2
            m += 1
        if use_height:
            H[m] = 0.0
            H[m, 2] = 1.0
            for b in range(3):
                H[m, 6 + b] = -Sl[2, b]
            z[m] = height_m
            h[m] = tag[2] + H[m] @ dx
            Rd[m] = sig_height ** 2
            m += 1
        nis, dof = np.nan, 0
        if m:
            R = np.zeros((m, m))
            for a in range(m):
                R[a, a] = Rd[a]
                if a < n_uwb:
                    for b in range(n_uwb):
                        if b != a:
                            R[a, b] = off
            y = z[:m] - h[:m]
            nis_parts = np.empty(m)
            iterate = uwb_used > 0 and far
            dx0, P0 = dx.copy(), P.copy()
            code = _sequential(dx, P, y, H[:m].copy(), R, nis_parts)
            if code:
                return code
            if iterate:                         # iterated update (IEKF): relinearise the UWB rows
                nis_it = np.empty(m)
                for it in range(max_iter - 1):
                    d = dx.copy()
                    if it == 0 and np.isfinite(fix_tag[k, 0]):   # start at the snapshot fix
                        d[:] = dx0
                        for a in range(3):
                            d[a] = fix_tag[k, a] - tag[a] + Sl[a, 0] * dx0[6] + Sl[a, 1] * dx0[7] + Sl[a, 2] * dx0[8]
                    tag_i = tag + d[0:3] - Sl @ d[6:9]
                    _uwb_rows(kind, row, refs[k], anchors, var_m, bias_m, tag_i, Sl, z2, h2, H2, Rd2, hp)
                    w = 0
                    for a in range(m_lin):
                        if keep[a]:
                            h[w] = h2[a] + H2[a] @ (dx0 - d)
                            H[w] = H2[a]
                            w += 1
                    y = z[:m] - h[:m]
                    dx[:] = dx0
                    P[:, :] = P0
                    code = _sequential(dx, P, y, H[:m].copy(), R, nis_it)
                    if code:
                        return code
                    step = 0.0
                    for a in range(3):
                        step = max(step, abs(dx[a] - d[a]))
                    if step < iter_tol:
                        break
            P = 0.5 * (P + P.T)
            if uwb_used:
                nis = nis_parts[:uwb_used].sum()
            dof = uwb_used
        # ---- closed loop: inject and reset; open loop: report nominal ⊕ δx
        qo = q.copy()
        if feedback:
            p += dx[0:3]
            v += dx[3:6]
            _exp_left_nb(dx[6:9], q)
            ba += dx[9:12]
            bg += dx[12:15]
            _reset_covariance(P, _reset_block(dx[6:9]))
            dx[:] = 0.0
            qo[:] = q
        else:
            _exp_left_nb(dx[6:9], qo)
        _dcm_nb(qo, C)
        clo = C @ lever
        _skew_into(clo, Sl)
        for a in range(3):
            pos_o[k, a] = p[a] + dx[a] + clo[a]
            vel_o[k, a] = v[a] + dx[3 + a]
            ba_o[k, a] = ba[a] + dx[9 + a]
            bg_o[k, a] = bg[a] + dx[12 + a]
        quat_o[k] = qo
        P_o[k] = P
        Jo = np.zeros((3, 15))
        for a in range(3):
            Jo[a, a] = 1.0
            for b in range(3):
                Jo[a, 6 + b] = -Sl[a, b]
        cov_o[k] = Jo @ P @ Jo.T
        nis_o[k], dof_o[k], gated_o[k] = nis, dof, n_gated
        status_o[k] = st_updated if uwb_used else (st_gated if n_gated else st_predicted)
    return 0


@numba.njit(cache=True, nogil=True)
def _uwb_rows(kind, row, ref, anchors, var_m, bias_m, tag, Sl, z, h, H, Rd, hp):
    """One epoch's UWB rows at tag position ``tag``: ``z``, ``h``, ``H`` (with the lever-arm
    columns from ``Sl = [C l ×]``) and the per-row variance ``Rd`` (without the reference's);
    TDoAs (``kind`` 1, :meth:`TdoaModel.epoch`) or ranges (``kind`` 2, :meth:`RangeUpdate.linearise`).
    Returns ``(m, linearised, var_ref)``."""
    n_a = anchors.shape[0]
    m, lin, var_ref = 0, False, 0.0
    if kind == 1:
        n_fin = 0
        for j in range(n_a):
            if np.isfinite(row[j]):
                n_fin += 1
        if ref >= 0 and n_fin >= 2:
            lin = True
            dr = tag - anchors[ref]
            rr = math.sqrt(dr[0] * dr[0] + dr[1] * dr[1] + dr[2] * dr[2])
            ur = dr / max(rr, 1e-12)
            var_ref = var_m[ref]
            for j in range(n_a):
                if j == ref or not np.isfinite(row[j]):
                    continue
                d = tag - anchors[j]
                r = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                u = d / max(r, 1e-12)
                z[m] = row[j] - row[ref]
                h[m] = r - rr
                for a in range(3):
                    hp[a] = u[a] - ur[a]
                Rd[m] = var_m[j]
                m += 1
                _fill_row(H, m - 1, hp, Sl)
    elif kind == 2:
        for j in range(n_a):
            if not np.isfinite(row[j]):
                continue
            lin = True
            d = tag - anchors[j]
            r = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            rm = max(r, 1e-9)
            for a in range(3):
                hp[a] = d[a] / rm
            z[m] = row[j] - bias_m
            h[m] = r
            Rd[m] = var_m[j]
            m += 1
            _fill_row(H, m - 1, hp, Sl)
    return m, lin, var_ref


@numba.njit(cache=True, nogil=True)
def _fill_row(H, a, hp, Sl):
    """Row ``a`` of ``H = ∂h/∂p · J_tag``: ``hp`` on δp and ``−hp [C l ×]`` on δθ."""
    H[a] = 0.0
    for b in range(3):
        H[a, b] = hp[b]
        H[a, 6 + b] = -(hp[0] * Sl[0, b] + hp[1] * Sl[1, b] + hp[2] * Sl[2, b])


# ====================================================================== loose (the paper's filter)
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
        the update is rejected (status ``GATED``, ``n_gated`` 1) when its NIS against the
        prior exceeds the ``gate_prob`` quantile of χ²(m), ``m`` the measurement dimension;
        a rejected fix does not enter the velocity difference. None: no gate.
    max_gated
        Consecutive gated epochs after which the next epoch's fix is used ungated.
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
    name: str = "loose"

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

    def matrices(self, T_s: float):
        """``A``, ``Q``, ``R`` of eqs 5–6 for UWB period ``T_s``."""
        d = self.dim
        A = np.eye(2 * d)
        A[:d, d:] = T_s * np.eye(d)
        Q = np.diag([self.q_pos_m_rts ** 2] * d + [self.q_vel_mps_rts ** 2] * d) * (T_s * self.q_scale)
        R = np.diag([self.sigma_r_pos_m ** 2] * d + [self.sigma_r_vel_mps ** 2] * d) * self.r_scale
        return A, Q, R

    def run(self, imu: ImuLog, fixes: Estimates, x0: NavState, *, heading: HeadingLog | None = None,
            name: str | None = None) -> FusionRun:
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
        """
        d = self.dim
        t_ep = fixes.t_s
        T = t_ep.size
        t, acc, gyro, ep_idx = merge_timeline(imu, t_ep)
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
        gate_m = None if self.gate_prob is None else {m: chi2.ppf(self.gate_prob, m) for m in (d, 2 * d)}
        gated_run = 0
        for i in range(t.size):
            if i > 0:
                p, v, q, _, _ = mech.step(p, v, q, acc[i - 1], acc[i], gyro[i - 1], gyro[i], t[i] - t[i - 1])
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
                corr = gain * np.cross(fn / max(math.sqrt(fn @ fn), 1e-9), g_up)
                if np.isfinite(yaw_meas[k]):
                    corr[2] += gain * _wrap(yaw_meas[k] - _yaw(C))
                q = _exp_left(corr, q)
            A, Q, _ = self.matrices(T_s)
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
                if gate_m is not None and gated_run < self.max_gated:
                    y = z - H @ dx
                    if y @ np.linalg.solve(H @ P @ H.T + Rk, y) > gate_m[z.size]:
                        hist_t.pop()
                        hist_p.pop()
                        gated_run += 1
                        z = None
                        status = EstimateStatus.GATED
                        out["n_gated"][k] = 1
                if z is not None:
                    gated_run = 0
                    st, inn = kalman.update(Gaussian(dx, P), z, H, Rk)
                    dx, P = st.x, st.P
                    nis, dof, status = inn.nis, z.size, EstimateStatus.UPDATED
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
        return FusionRun(t_ep.copy(), name=name or self.name, **out)
