"""The generic extended Kalman filter over a transition and a measurement model (see :mod:`uwbwb.filters.ekf`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Protocol, Sequence

import numpy as np
import pandas as pd
from scipy.linalg import block_diag

from ...metrics import nees as _nees, nis_consistency
from ...types import EstimateStatus, Estimates, Trajectory
from .. import kalman
from ..gating import GatePolicy, UpdateInfo, gate_policy, ungated_update
from ..kalman import Gaussian


@dataclass(frozen=True)
class Linearisation:
    """One epoch's measurement linearised at the prior mean ``x⁻``.

    Attributes
    ----------
    z
        Measurement, shape ``(m,)``.
    h
        Predicted measurement ``h(x⁻)``, shape ``(m,)``.
    H
        Jacobian ``∂h/∂x`` at ``x⁻`` with respect to the *full* state, shape ``(m, n_x)``.
    R
        Measurement noise covariance, shape ``(m, m)``.
    linear
        True for a linear measurement, ``h(x) = H x`` (``h`` is then ``H x⁻``): the update forms
        the innovation as ``y = z − H x⁻`` (the textbook linear update) instead of ``z − h``;
        the two are the same number up to rounding.
    """

    z: np.ndarray
    h: np.ndarray
    H: np.ndarray
    R: np.ndarray
    linear: bool = False

    def __post_init__(self):
        z = np.atleast_1d(np.asarray(self.z, float))
        h = np.atleast_1d(np.asarray(self.h, float))
        H = np.atleast_2d(np.asarray(self.H, float))
        R = np.atleast_2d(np.asarray(self.R, float))
        m = z.size
        if z.ndim != 1 or h.shape != (m,) or H.shape[0] != m or R.shape != (m, m):
            raise ValueError(f"Linearisation: z {z.shape}, h {h.shape}, H {H.shape}, R {R.shape} do not fit "
                             f"(expected (m,), (m,), (m, n_x), (m, m))")
        if self.linear not in (True, False):
            raise ValueError(f"Linearisation.linear must be True or False, got {self.linear!r}")
        for name, a in (("z", z), ("h", h), ("H", H), ("R", R)):
            object.__setattr__(self, name, a)

    @property
    def innovation(self) -> np.ndarray:
        """``z − h(x⁻)``, shape ``(m,)``."""
        return self.z - self.h

    def rows(self, keep) -> "Linearisation":
        """The measurement's rows ``keep`` only (indices or a boolean mask): the marginal of a
        Gaussian measurement, ``z[keep]``, ``h[keep]``, ``H[keep]``, ``R[keep][:, keep]``."""
        keep = np.asarray(keep)
        if keep.dtype == bool:
            keep = np.flatnonzero(keep)
        return replace(self, z=self.z[keep], h=self.h[keep], H=self.H[keep], R=self.R[np.ix_(keep, keep)])

    @staticmethod
    def stack(parts: Sequence["Linearisation"]) -> "Linearisation":
        """Independent measurements of one epoch as one: ``z``, ``h`` and ``H`` stacked row-wise,
        ``R = blockdiag(R₁, R₂, …)`` (no correlation between the parts); linear only when every
        part is. The rows keep the parts' order, which a sequential update follows."""
        parts = list(parts)
        if not parts:
            raise ValueError("Linearisation.stack needs at least one part")
        return Linearisation(np.concatenate([a.z for a in parts]), np.concatenate([a.h for a in parts]),
                             np.vstack([a.H for a in parts]), block_diag(*[a.R for a in parts]),
                             all(a.linear for a in parts))


class MeasurementModel(Protocol):
    """What :class:`Ekf` needs from a measurement model."""

    def linearise(self, x: np.ndarray, measurement: Any) -> Linearisation | None:
        """Linearise ``measurement`` (one epoch's, in the model's own form) at state ``x``.

        Returns None when the epoch holds nothing usable (the filter then only predicts).
        """


class TransitionModel(Protocol):
    """What :class:`Ekf` needs from a motion model (every :class:`~uwbwb.models.layout.KinematicModel` fits;
    a model with a ``layout`` also gives :class:`Ekf` its default ``pos_index``)."""

    n_x: int

    def F(self, dt_s) -> np.ndarray:
        """State transition, shape ``(..., n_x, n_x)`` for ``dt_s`` of shape ``(...)``."""

    def Q(self, dt_s) -> np.ndarray:
        """Process noise covariance, shape ``(..., n_x, n_x)``."""


_DEFAULT_GATE = (0.9999, 10)      # Ekf's gate_prob, max_gated defaults


def _resolve_gate(ekf: "Ekf", owner: str) -> None:
    """Set ``ekf.gate`` from ``gate_prob``/``max_gated`` (or check the given policy) and mirror it back."""
    policy = gate_policy(owner, ekf.gate, ekf.gate_prob, ekf.max_gated, _DEFAULT_GATE)
    if policy.needs_subsets and not (hasattr(ekf.measurement, "components")
                                     and hasattr(ekf.measurement, "linearise_components")):
        raise ValueError(f"{owner}: the {type(policy).__name__} gate needs a measurement model that can "
                         f"re-linearise a subset of its components (components(), linearise_components())")
    object.__setattr__(ekf, "gate", policy)
    object.__setattr__(ekf, "gate_prob", getattr(policy, "prob", None))
    object.__setattr__(ekf, "max_gated", policy.max_gated)


@dataclass(frozen=True)
class Ekf:
    """Extended Kalman filter over any transition and measurement model.

    Attributes
    ----------
    transition
        Gives ``F(dt)`` and ``Q(dt)`` (vectorised over ``dt``) and ``n_x``.
    measurement
        Gives a :class:`Linearisation` per epoch (:class:`MeasurementModel`).
    pos_index
        State components that are the position (2 or 3 of them), for results and metrics;
        default: the transition model's declared ``layout.pos_index``
        (:class:`~uwbwb.models.layout.StateLayout`).
    vel_index
        State components reported as the velocity, or None (none reported; pass
        ``transition.layout.vel_index`` for the declared one).
    gate_prob
        χ² gate probability on each epoch's NIS; None = no gate (every measurement used).
        Stands for :class:`~uwbwb.filters.gating.ChiSquareEpoch` when ``gate`` is not given;
        otherwise it mirrors the policy's ``prob`` (None if it has none).
    max_gated
        Consecutive gated epochs after which the next epoch is used ungated (mirrors
        ``gate.max_gated`` when ``gate`` is given).
    gate
        Gate policy (:mod:`uwbwb.filters.gating`); default: the one ``gate_prob`` and
        ``max_gated`` stand for.
    sequential
        Update with scalar rows one after the other (:func:`~uwbwb.filters.gating.ungated_update`
        with ``sequential=True``: equal to the batch update in exact arithmetic for a linear
        measurement, different by rounding; ``UpdateInfo.nis_rows`` reports each row's NIS)
        instead of one batch update (default).
    """

    transition: TransitionModel
    measurement: MeasurementModel
    pos_index: tuple[int, ...] | None = None
    vel_index: tuple[int, ...] | None = None
    gate_prob: float | None = 0.9999
    max_gated: int = 10
    gate: GatePolicy | None = None
    sequential: bool = False

    def __post_init__(self):
        if self.sequential not in (True, False):
            raise ValueError(f"Ekf.sequential must be True or False, got {self.sequential!r}")
        n = int(self.transition.n_x)
        layout = getattr(self.transition, "layout", None)
        if self.pos_index is None:
            if layout is None:
                raise ValueError(f"Ekf: give pos_index (the transition model {type(self.transition).__name__} "
                                 f"declares no state layout)")
            object.__setattr__(self, "pos_index", layout.pos_index)
        pos = tuple(int(i) for i in self.pos_index)
        if len(pos) not in (2, 3) or not all(0 <= i < n for i in pos):
            raise ValueError(f"Ekf.pos_index must name 2 or 3 of the {n} state components, got {self.pos_index!r}")
        if layout is not None and len(pos) != layout.dim:
            # e.g. dataclasses.replace(ekf, transition=<a 3-D model>) keeps the 2-D pos_index it resolved
            raise ValueError(f"Ekf.pos_index {pos} names {len(pos)} coordinates, the transition model's layout has "
                             f"{layout.dim} ({layout.labels}); give pos_index=None to take the layout's")
        object.__setattr__(self, "pos_index", pos)
        if self.vel_index is not None:
            vel = tuple(int(i) for i in self.vel_index)
            if len(vel) != len(pos) or not all(0 <= i < n for i in vel):
                raise ValueError(f"Ekf.vel_index must name {len(pos)} of the {n} state components, "
                                 f"got {self.vel_index!r}")
            object.__setattr__(self, "vel_index", vel)
        _resolve_gate(self, type(self).__name__)

    def predict(self, state: Gaussian, dt_s: float) -> Gaussian:
        """Prior after ``dt_s`` seconds: ``x⁻ = F x``, ``P⁻ = F P Fᵀ + Q``."""
        return kalman.predict(state, self.transition.F(dt_s), self.transition.Q(dt_s))

    def update(self, state: Gaussian, measurement, *, gate: bool = True) -> tuple[Gaussian, UpdateInfo]:
        """Posterior after one epoch's ``measurement`` (Joseph form), as the gate policy allows.

        Parameters
        ----------
        state
            Prior.
        measurement
            The epoch's measurement in the measurement model's own form.
        gate
            Apply the gate policy (False: use every measurement).

        Returns
        -------
        posterior, info
            The prior itself where nothing was measured (``PREDICTED``) or the gate rejected
            the epoch (``GATED``); ``info.n_rejected`` counts the components the gate removed.
        """
        lin = self.measurement.linearise(state.x, measurement)
        if lin is None or lin.z.size == 0:
            return state, UpdateInfo(np.nan, 0, EstimateStatus.PREDICTED)
        if lin.H.shape[1] != state.x.size:
            raise ValueError(f"Ekf.update: the measurement Jacobian has {lin.H.shape[1]} columns, "
                             f"the state {state.x.size} components")
        if not gate:
            return ungated_update(state, lin, sequential=self.sequential)
        parts = None
        if self.gate.needs_subsets:
            model = self.measurement
            parts = (model.components(measurement),
                     lambda keep: model.linearise_components(state.x, measurement, keep))
        if self.sequential:     # passed only when asked for: a policy of one's own need not know it
            return self.gate.update(state, lin, parts, sequential=True)
        return self.gate.update(state, lin, parts)

    def run(self, t_s, measurements: Sequence, x0: Gaussian, *, start: int = 0, name: str = "EKF") -> "KalmanRun":
        """Filter a whole recording.

        Parameters
        ----------
        t_s
            Epoch times, shape ``(T,)``, seconds, strictly increasing.
        measurements
            One measurement per epoch (length ``T``), in the measurement model's form.
        x0
            Prior at epoch ``start`` (updated with that epoch's measurement).
        start
            First epoch filtered; earlier epochs have no estimate.
        name
            Label of the run.

        Returns
        -------
        KalmanRun
        """
        t_s = np.asarray(t_s, float)
        T, n = t_s.size, x0.x.size
        if len(measurements) != T:
            raise ValueError(f"Ekf.run: {len(measurements)} measurements for {T} epochs")
        if T > 1 and np.any(np.diff(t_s) <= 0):
            raise ValueError("Ekf.run: t_s must be strictly increasing")
        if not 0 <= start <= T:
            raise ValueError(f"Ekf.run: start must be in 0..{T}, got {start}")
        if n != self.transition.n_x:
            raise ValueError(f"Ekf.run: x0 has {n} components, the transition model {self.transition.n_x}")
        xm, Pm = np.full((T, n), np.nan), np.full((T, n, n), np.nan)
        xp, Pp = np.full((T, n), np.nan), np.full((T, n, n), np.nan)
        F = np.full((T, n, n), np.nan)
        nis, dof, n_rej = np.full(T, np.nan), np.zeros(T, int), np.zeros(T, int)
        status = np.full(T, EstimateStatus.NO_ESTIMATE, np.int8)
        if start < T:
            dt = np.diff(t_s[start:])
            F_all, Q_all = self.transition.F(dt), self.transition.Q(dt)   # every step at once
            F[start] = np.eye(n)
            state, gated = x0, 0
            for k in range(start, T):
                if k > start:
                    state = kalman.predict(state, F_all[k - start - 1], Q_all[k - start - 1])
                    F[k] = F_all[k - start - 1]
                xm[k], Pm[k] = state.x, state.P
                state, info = self.update(state, measurements[k], gate=self.gate.active(gated))
                gated = gated + 1 if info.status == EstimateStatus.GATED else 0
                xp[k], Pp[k], nis[k], dof[k], status[k] = state.x, state.P, info.nis, info.dof, info.status
                n_rej[k] = info.n_rejected
        return KalmanRun(t_s.copy(), xm, Pm, xp, Pp, F, nis, dof, status, self.pos_index, self.vel_index, name,
                         n_rej)


@dataclass(frozen=True)
class KalmanRun:
    """Priors and posteriors of one Kalman-filter run.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds.
    x_prior, P_prior
        Predicted means ``(T, n_x)`` and covariances ``(T, n_x, n_x)`` at each epoch, before
        its measurement; NaN where the filter had not started.
    x_post, P_post
        Filtered means and covariances after each epoch's measurement (equal to the prior
        where the epoch was predicted only or gated).
    F
        Transition into each epoch from the one before, ``(T, n_x, n_x)`` (identity at the
        first filtered epoch), kept for smoothing.
    nis, dof
        NIS per epoch (NaN if nothing was measured; computed also for gated epochs) and the
        size of the measurement used (0 if none was used).
    status
        :class:`~uwbwb.types.EstimateStatus` per epoch.
    pos_index, vel_index
        State components of the position and velocity.
    name
        Label.
    n_rejected
        Measurement components removed by the gate per epoch, ``(T,)`` (zeros if none were).
    """

    t_s: np.ndarray
    x_prior: np.ndarray
    P_prior: np.ndarray
    x_post: np.ndarray
    P_post: np.ndarray
    F: np.ndarray
    nis: np.ndarray
    dof: np.ndarray
    status: np.ndarray
    pos_index: tuple[int, ...]
    vel_index: tuple[int, ...] | None = None
    name: str = "EKF"
    n_rejected: np.ndarray | None = None

    def __post_init__(self):
        if self.n_rejected is None:
            object.__setattr__(self, "n_rejected", np.zeros(self.t_s.size, int))

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def pos_m(self) -> np.ndarray:
        """Filtered positions, shape ``(T, dim)``, metres; NaN before the start."""
        return self.x_post[:, list(self.pos_index)]

    @property
    def pos_cov_m2(self) -> np.ndarray:
        """Filtered position covariances, shape ``(T, dim, dim)``, m²."""
        idx = list(self.pos_index)
        return self.P_post[:, idx][:, :, idx]

    @property
    def started(self) -> np.ndarray:
        """Epochs from the first filtered one on, bool ``(T,)``."""
        return self.status != EstimateStatus.NO_ESTIMATE

    def smooth(self, name: str | None = None) -> "KalmanRun":
        """Rauch–Tung–Striebel smoothed run (the posteriors replaced by smoothed estimates).

        For ``k`` from the last epoch back, with ``C_k = P_k Fₖ₊₁ᵀ (P⁻ₖ₊₁)⁻¹``::

            x̂ₖ = xₖ + C_k (x̂ₖ₊₁ − x⁻ₖ₊₁),   P̂ₖ = Pₖ + C_k (P̂ₖ₊₁ − P⁻ₖ₊₁) C_kᵀ
        """
        idx = np.flatnonzero(self.started)
        xs, Ps = self.x_post.copy(), self.P_post.copy()
        for j in range(idx.size - 2, -1, -1):
            k, k1 = idx[j], idx[j + 1]
            # C = P F1ᵀ (P⁻)⁻¹ = ((P⁻)⁻¹ F1 P)ᵀ, P⁻ symmetric positive definite
            C = np.linalg.solve(self.P_prior[k1], self.F[k1] @ self.P_post[k]).T
            xs[k] = self.x_post[k] + C @ (xs[k1] - self.x_prior[k1])
            Ps[k] = self.P_post[k] + C @ (Ps[k1] - self.P_prior[k1]) @ C.T
            Ps[k] = 0.5 * (Ps[k] + Ps[k].T)
        return replace(self, x_post=xs, P_post=Ps, name=name or f"{self.name}-RTS")

    def nees(self, x_true: np.ndarray, index: Sequence[int] | None = None) -> np.ndarray:
        """Normalised estimation error squared ``eᵀ P⁻¹ e`` per epoch, shape ``(T,)``.

        Parameters
        ----------
        x_true
            True values of the state components ``index``, shape ``(T, len(index))``.
        index
            State components compared (default: all). Pass ``pos_index`` for the position NEES.
            χ²(len(index))-distributed when the filter is consistent; NaN before the start.
        """
        idx = np.arange(self.x_post.shape[1]) if index is None else np.asarray(index, int)
        x_true = np.asarray(x_true, float)
        if x_true.shape != (len(self), idx.size):
            raise ValueError(f"KalmanRun.nees: x_true must have shape ({len(self)}, {idx.size}), got {x_true.shape}")
        return _nees(self.x_post[:, idx] - x_true, self.P_post[:, idx[:, None], idx], self.started)

    def nis_consistency(self, prob: float = 0.95) -> dict:
        """χ² consistency of the NIS over the updated epochs (:func:`uwbwb.metrics.nis_consistency`)."""
        up = self.status == EstimateStatus.UPDATED
        return nis_consistency(self.nis[up], self.dof[up], prob)

    def to_estimates(self) -> Estimates:
        """The common result type: posterior positions (velocities, covariances) and status;
        ``info`` holds ``nis``, ``dof`` and ``n_rejected``."""
        vel = None if self.vel_index is None else self.x_post[:, list(self.vel_index)]
        return Estimates(self.t_s, self.pos_m, self.status, self.name, self.pos_cov_m2, vel,
                         {"nis": self.nis, "dof": self.dof, "n_rejected": self.n_rejected})

    def to_trajectory(self, name: str | None = None) -> Trajectory:
        """Filtered positions (and velocities, if in the state) from the first filtered epoch on."""
        return self.to_estimates().to_trajectory(name)

    def to_frame(self) -> pd.DataFrame:
        """Table of :meth:`to_estimates` (``t_s``, positions, velocities, SDs, ``status``, ``nis, dof, n_rejected``)."""
        return self.to_estimates().to_frame()
