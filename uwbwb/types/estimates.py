"""The result type every estimator returns (:class:`Estimates`), the same fields batched over runs or
parameter values (:class:`EstimatesBatch`), and the per-epoch status."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field, fields
from typing import ClassVar, Iterator, Mapping

import numpy as np
import pandas as pd

from ._base import ArrayRecord, _check_time, _frozen_array
from .containers import Trajectory, _optional_rows


class EstimateStatus(enum.IntEnum):
    """What an estimator did at one epoch (stored as ``int8`` in :attr:`Estimates.status`).

    ``UPDATED``
        The epoch's measurements were used: a filter update, or a snapshot fix was computed.
    ``PREDICTED``
        A filter coasted: nothing usable was measured at this epoch (prediction only).
    ``GATED``
        A filter coasted: the epoch's measurements were rejected by its innovation gate.
    ``NO_ESTIMATE``
        Nothing to report: before initialisation, too few measurements, degenerate
        geometry or no convergence. ``pos_m`` is NaN there.
    """

    UPDATED = 0
    PREDICTED = 1
    GATED = 2
    NO_ESTIMATE = 3

    @property
    def label(self) -> str:
        """Lower-case name used in tables, e.g. ``"no_estimate"``."""
        return self.name.lower()


@dataclass(frozen=True)
class _EstimateFields:
    """The fields of the result family, declared once (:class:`Estimates`, :class:`EstimatesBatch`)."""

    t_s: np.ndarray
    pos_m: np.ndarray
    status: np.ndarray
    name: str = "estimate"
    pos_cov_m2: np.ndarray | None = None
    vel_mps: np.ndarray | None = None
    info: Mapping[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class Estimates(_EstimateFields, ArrayRecord):
    """Per-epoch estimates of one method on one recording — the type every estimator returns.

    Snapshot methods (multilateration, TDoA LS) and tracking filters (EKF, PF, error-state
    filters) all report through this one shape, so metrics, plots and the scoreboard treat
    them alike: accuracy on :attr:`has_estimate` epochs, :attr:`coverage` beside it.

    Attributes
    ----------
    t_s
        Epoch times, shape ``(T,)``, seconds, strictly increasing.
    pos_m
        Estimated positions, shape ``(T, dim)``, metres; NaN exactly where ``status`` is
        ``NO_ESTIMATE``.
    status
        :class:`EstimateStatus` per epoch, shape ``(T,)``.
    name
        Label in legends and tables (e.g. ``"LS"``, ``"EKF-RF"``).
    pos_cov_m2
        Position covariances, shape ``(T, dim, dim)``, m², or None if the method has none.
    vel_mps
        Velocity estimates, shape ``(T, dim)``, m/s, or None.
    info
        Extra per-epoch columns, each shape ``(T,)`` (e.g. ``nis``, ``dof``, ``n_rejected``).
    """

    _rows: ClassVar[tuple[str, ...]] = ("t_s", "pos_m", "status", "pos_cov_m2", "vel_mps")
    _row_maps: ClassVar[tuple[str, ...]] = ("info",)
    _columns: ClassVar[tuple[tuple[str, str], ...]] = (("pos_m", "{a}_m"), ("vel_mps", "v{a}_mps"))

    def __post_init__(self):
        t = _frozen_array("Estimates.t_s", self.t_s, ndim=1)
        p = _frozen_array("Estimates.pos_m", self.pos_m, ndim=2)
        T = t.size
        if p.shape[0] != T or p.shape[1] not in (2, 3):
            raise ValueError(f"Estimates.pos_m must have shape ({T}, 2|3), got {p.shape}")
        _check_time(t, "Estimates")
        st = np.array(self.status, copy=True)
        if st.shape != (T,) or not np.issubdtype(st.dtype, np.integer):
            raise ValueError(f"Estimates.status must be integer codes of shape ({T},), got {st.dtype} {st.shape}")
        codes = {int(s) for s in EstimateStatus}
        bad = ~np.isin(st, list(codes))
        if bad.any():
            raise ValueError(f"Estimates.status has unknown codes {sorted(set(st[bad].tolist()))}; "
                             f"known: {[s.label for s in EstimateStatus]}")
        st = st.astype(np.int8)
        st.setflags(write=False)
        none = st == EstimateStatus.NO_ESTIMATE
        finite = np.all(np.isfinite(p), axis=1)
        if np.any(finite == none):
            k = int(np.flatnonzero(finite == none)[0])
            raise ValueError(f"Estimates.pos_m must be finite exactly where status is not NO_ESTIMATE; "
                             f"epoch {k} has status {EstimateStatus(st[k]).label} and position {p[k].tolist()}")
        self._set(t_s=t, pos_m=p, status=st, name=str(self.name))
        d = p.shape[1]
        if self.pos_cov_m2 is not None:
            self._set(pos_cov_m2=_optional_rows("Estimates.pos_cov_m2", self.pos_cov_m2, (T, d, d)))
        if self.vel_mps is not None:
            self._set(vel_mps=_optional_rows("Estimates.vel_mps", self.vel_mps, p.shape))
        info = {}
        for key, col in dict(self.info).items():
            a = np.array(col, copy=True)
            if a.shape != (T,):
                raise ValueError(f"Estimates.info[{key!r}] must have shape ({T},), got {a.shape}")
            a.setflags(write=False)
            info[str(key)] = a
        self._set(info=info)

    @property
    def dim(self) -> int:
        return self.pos_m.shape[1]

    @property
    def has_estimate(self) -> np.ndarray:
        """Epochs with a position, bool ``(T,)``."""
        return self.status != EstimateStatus.NO_ESTIMATE

    @property
    def coverage(self) -> float:
        """Share of epochs with a position (NaN for an empty series)."""
        return float(self.has_estimate.mean()) if len(self) else float("nan")

    def status_counts(self) -> dict[str, int]:
        """Number of epochs per status label (all labels present, zeros included)."""
        return {s.label: int(np.count_nonzero(self.status == s)) for s in EstimateStatus}

    def to_trajectory(self, name: str | None = None) -> Trajectory:
        """The epochs with a position, as a :class:`Trajectory`."""
        ok = self.has_estimate
        return Trajectory(self.t_s[ok], self.pos_m[ok], None if self.vel_mps is None else self.vel_mps[ok],
                          name=name or self.name)

    def to_frame(self) -> pd.DataFrame:
        """Table ``t_s, x_m, y_m[, z_m][, vx_mps ..][, sd_x_m ..], status`` (label) and the ``info`` columns."""
        axes = "xyz"[: self.dim]
        cols = self._wide_columns()
        if self.pos_cov_m2 is not None:
            sd = np.sqrt(np.diagonal(self.pos_cov_m2, axis1=1, axis2=2))
            cols.update({f"sd_{a}_m": sd[:, k] for k, a in enumerate(axes)})
        labels = np.array([s.label for s in EstimateStatus])
        cols["status"] = labels[self.status]
        cols.update(self.info)
        return pd.DataFrame(cols)



@dataclass(frozen=True)
class EstimatesBatch(_EstimateFields):
    """:class:`Estimates` of many runs that share their epochs, batched along leading axes.

    A Monte Carlo sweep (trials, parameter values, filter variants) keeps its arrays batched;
    its ``to_estimates()`` gives this, and ``batch[i]`` (or iterating) gives each member as an
    :class:`Estimates`, in C order of the batch axes.

    Attributes
    ----------
    t_s
        Epoch times shared by every member, shape ``(T,)``, seconds.
    pos_m
        Positions, shape ``(*batch, T, dim)``, metres.
    status
        :class:`EstimateStatus` codes, shape ``(*batch, T)``.
    name, pos_cov_m2, vel_mps, info
        As for :class:`Estimates`, with the batch axes first: ``(*batch, T, dim, dim)``,
        ``(*batch, T, dim)``, each ``info`` column ``(*batch, T)``.
    """

    def __post_init__(self):
        t, p, st = np.asarray(self.t_s), np.asarray(self.pos_m), np.asarray(self.status)
        if t.ndim != 1 or p.ndim < 2 or p.shape[-2:] != (t.size, p.shape[-1]) or p.shape[-1] not in (2, 3):
            raise ValueError(f"{type(self).__name__}: t_s (T,) and pos_m (..., T, 2|3) expected, "
                             f"got {t.shape} and {p.shape}")
        lead = p.shape[:-1]
        if st.shape != lead:
            raise ValueError(f"{type(self).__name__}.status must have shape {lead}, got {st.shape}")
        d = p.shape[-1]
        for name, shape in (("pos_cov_m2", lead + (d, d)), ("vel_mps", lead + (d,))):
            a = getattr(self, name)
            if a is not None and np.shape(a) != shape:
                raise ValueError(f"{type(self).__name__}.{name} must have shape {shape}, got {np.shape(a)}")
        for key, col in dict(self.info).items():
            if np.shape(col) != lead:
                raise ValueError(f"{type(self).__name__}.info[{key!r}] must have shape {lead}, got {np.shape(col)}")

    @property
    def batch_shape(self) -> tuple[int, ...]:
        """Shape of the batch axes (``pos_m.shape[:-2]``)."""
        return np.shape(self.pos_m)[:-2]

    @property
    def dim(self) -> int:
        return np.shape(self.pos_m)[-1]

    def __len__(self) -> int:
        """Number of members (the product of :attr:`batch_shape`)."""
        return int(np.prod(self.batch_shape, dtype=int))

    def estimates(self, index=0) -> Estimates:
        """One member as :class:`Estimates`: ``index`` is a flat member number or a tuple over the batch axes."""
        idx = np.unravel_index(index, self.batch_shape) if np.ndim(index) == 0 else tuple(index)
        pick = (lambda a: None if a is None else np.asarray(a)[idx])
        return Estimates(self.t_s, pick(self.pos_m), pick(self.status), self.name, pick(self.pos_cov_m2),
                         pick(self.vel_mps), {k: pick(v) for k, v in self.info.items()})

    def __getitem__(self, index) -> Estimates:
        return self.estimates(index)

    def __iter__(self) -> Iterator[Estimates]:
        return (self.estimates(i) for i in range(len(self)))

    def to_estimates(self) -> "EstimatesBatch":
        """The batch itself as a plain :class:`EstimatesBatch` (what a sweep's ``to_estimates()`` returns)."""
        return EstimatesBatch(**{f.name: getattr(self, f.name) for f in fields(EstimatesBatch)})
