"""Multilateration from two-way ranges: batched solvers with per-epoch status, and GDOP.

See :mod:`uwbwb.geometry` for the conventions (anchors, ``dim``, known height ``z_m``).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import GeometryError
from ..models.ranging import anchor_positions as _as_anchors
from ..models.ranging import range_jacobian
from ..types import EstimateStatus, Estimates, Trajectory
from .solvers import RCOND, _anchor_span_ok, _gauss_newton, _least_squares, _linear, _Problem, _solve_psd


class Status(enum.IntEnum):
    """Outcome of multilateration for one epoch (stored as ``int8``).

    ``OK``
        A position was computed and the geometry matrix at it is regular.
    ``TOO_FEW``
        Fewer ranges than ``min_anchors`` (at least ``dim + 1``).
    ``DEGENERATE``
        The geometry does not determine the position: the anchors with a range
        are collinear (``dim=2``) or coplanar (``dim=3``) and no start point
        ``x0`` was given to choose between the two mirror solutions, or the
        Jacobian at the solution is singular (tag on the anchors' line/plane).
    ``NOT_CONVERGED``
        The iteration cap was reached (or no descent step could be found).
    """

    OK = 0
    TOO_FEW = 1
    DEGENERATE = 2
    NOT_CONVERGED = 3

    @property
    def label(self) -> str:
        """Lower-case name used in tables, e.g. ``"too_few"``."""
        return self.name.lower()


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class MultilaterationResult:
    """Per-epoch multilateration output (all arrays read-only).

    Epochs whose ``status`` is not ``Status.OK`` hold NaN in ``pos_m``,
    ``cov_m2``, ``gdop`` and ``residual_rms_m``.

    Attributes
    ----------
    pos_m
        Positions, shape ``(T, dim)``, metres (in the anchors' frame).
    cov_m2
        Position covariance, shape ``(T, dim, dim)``, m². It is the
        Gauss--Newton (Cramér--Rao) approximation ``(J^T W J)^-1`` at the
        solution with ``W = diag(1 / sigma_i^2)`` when ``sigma_m`` was given;
        otherwise ``sigma_hat^2 (J^T J)^-1`` with one ``sigma_hat`` pooled over
        all OK epochs of the call: ``sigma_hat^2 = sum(residual^2) / sum(n_used - dim)``
        (assumes one noise level for the whole batch; reported in ``sigma_m``).
        With a robust ``loss`` it is the same least-squares approximation, so
        only indicative.
    gdop
        Geometric dilution of precision ``sqrt(trace((J^T J)^-1))``, shape ``(T,)``.
    n_used
        Number of ranges present at each epoch, shape ``(T,)``.
    residual_rms_m
        RMS of the range residuals (measured - predicted) at the solution, shape ``(T,)``, metres.
    status
        :class:`Status` codes, shape ``(T,)``, ``int8``.
    sigma_m
        The range standard deviation behind ``cov_m2``: as given (scalar or
        ``(n_anchors,)``) or the pooled estimate (float, NaN if no epoch is OK).
    sigma_estimated
        True when ``sigma_m`` was estimated from the residuals.
    method
        ``"gauss-newton"`` or ``"least_squares"``.
    t_s
        Epoch times ``(T,)``, seconds, when given to :func:`multilaterate` (then
        :meth:`to_estimates`, :meth:`to_trajectory` and :meth:`to_frame` need no argument).
    name
        Label of the fixes in legends and tables.
    """

    pos_m: np.ndarray
    cov_m2: np.ndarray
    gdop: np.ndarray
    n_used: np.ndarray
    residual_rms_m: np.ndarray
    status: np.ndarray
    sigma_m: float | np.ndarray
    sigma_estimated: bool
    method: str
    t_s: np.ndarray | None = None
    name: str = "LS"

    def __post_init__(self):
        pos = np.array(self.pos_m, dtype=float)
        if pos.ndim != 2 or pos.shape[1] not in (2, 3):
            raise ValueError(f"pos_m must have shape (T, 2|3), got {pos.shape}")
        T, d = pos.shape
        expected = {"cov_m2": ((T, d, d), float), "gdop": ((T,), float), "n_used": ((T,), int),
                    "residual_rms_m": ((T,), float), "status": ((T,), np.int8)}
        object.__setattr__(self, "pos_m", pos)
        for name, (shape, dtype) in expected.items():
            arr = np.array(getattr(self, name), dtype=dtype)
            if arr.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
            object.__setattr__(self, name, arr)
        for name in ("pos_m", *expected):
            getattr(self, name).setflags(write=False)
        if self.t_s is not None:
            t = np.array(self.t_s, dtype=float)
            if t.shape != (T,):
                raise ValueError(f"t_s must have shape ({T},), got {t.shape}")
            t.setflags(write=False)
            object.__setattr__(self, "t_s", t)
        if isinstance(self.sigma_m, np.ndarray):
            s = np.array(self.sigma_m, dtype=float)
            s.setflags(write=False)
            object.__setattr__(self, "sigma_m", s)

    def __len__(self) -> int:
        return self.pos_m.shape[0]

    @property
    def dim(self) -> int:
        return self.pos_m.shape[1]

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask of epochs with ``Status.OK``, shape ``(T,)``."""
        return self.status == Status.OK

    @property
    def status_labels(self) -> np.ndarray:
        """Status as strings (``"ok"``, ``"too_few"``, ...), shape ``(T,)``."""
        labels = np.array([s.label for s in Status], dtype=object)
        return labels[self.status]

    def counts(self) -> dict[str, int]:
        """Number of epochs per status label (all labels present, zeros included)."""
        return {s.label: int(np.count_nonzero(self.status == s)) for s in Status}

    def to_trajectory(self, t_s=None, name: str | None = None) -> Trajectory:
        """The OK epochs as a :class:`~uwbwb.Trajectory` (at :attr:`t_s` unless given, labelled :attr:`name`).

        Epochs without a position (status other than OK) are left out, so the
        trajectory is shorter than the input by ``len(self) - self.ok.sum()``;
        :meth:`counts` says why.
        """
        t = self._check_t(t_s)
        ok = self.ok
        return Trajectory(t[ok], self.pos_m[ok], name=name or self.name)

    def to_estimates(self, t_s=None, name: str | None = None) -> Estimates:
        """The common result type: OK epochs ``UPDATED`` with position and covariance, the others
        ``NO_ESTIMATE``; ``info`` holds ``n_used``, ``gdop`` and ``residual_rms_m``.

        The epochs are :attr:`t_s` and the label :attr:`name`; ``t_s`` and ``name`` given here
        (the older call) take their place."""
        t = self._check_t(t_s)
        ok = self.ok
        status = np.where(ok, EstimateStatus.UPDATED, EstimateStatus.NO_ESTIMATE).astype(np.int8)
        return Estimates(t, np.where(ok[:, None], self.pos_m, np.nan), status, name or self.name,
                         np.where(ok[:, None, None], self.cov_m2, np.nan), None,
                         {"n_used": self.n_used, "gdop": self.gdop, "residual_rms_m": self.residual_rms_m})

    def to_frame(self, t_s=None) -> pd.DataFrame:
        """One row per epoch (all epochs, NaN where not OK).

        Columns: ``t_s, x_m, y_m[, z_m], var_x_m2, var_y_m2[, var_z_m2], cov_xy_m2[, cov_xz_m2,
        cov_yz_m2], gdop, n_used, residual_rms_m, status`` (status as label).
        """
        t = self._check_t(t_s)
        axes = "xyz"[: self.dim]
        cols = {"t_s": t}
        cols.update({f"{a}_m": self.pos_m[:, k] for k, a in enumerate(axes)})
        cols.update({f"var_{a}_m2": self.cov_m2[:, k, k] for k, a in enumerate(axes)})
        for i in range(self.dim):
            for j in range(i + 1, self.dim):
                cols[f"cov_{axes[i]}{axes[j]}_m2"] = self.cov_m2[:, i, j]
        cols.update(gdop=self.gdop, n_used=self.n_used, residual_rms_m=self.residual_rms_m,
                    status=self.status_labels)
        return pd.DataFrame(cols)

    def _check_t(self, t_s) -> np.ndarray:
        if t_s is None:
            if self.t_s is None:
                raise ValueError("this result has no epoch times: pass t_s to multilaterate (or here)")
            return self.t_s
        t = np.asarray(t_s, dtype=float)
        if t.shape != (len(self),):
            raise ValueError(f"t_s must have shape ({len(self)},), got {t.shape}")
        return t


def _finish(p: _Problem, x: np.ndarray, status: np.ndarray, method: str, sigma_m, t_s=None,
            name: str = "LS") -> MultilaterationResult:
    T, d = x.shape
    n_used = p.n_used
    idx = np.flatnonzero((status == Status.OK) | (status == Status.NOT_CONVERGED))
    diff, rh = p.predict(idx, x[idx])
    J = diff / rh[..., None]
    m = p.mask[idx].astype(float)
    e = np.where(p.mask[idx], p.r[idx] - rh, 0.0)
    H = np.einsum("tn,tni,tnj->tij", m, J, J)
    H_inv, regular = _solve_psd(H)
    status[idx[~regular]] = Status.DEGENERATE
    ok_local = status[idx] == Status.OK

    rss = np.sum(e * e, axis=1)
    if p.sigma is None:
        dof = np.sum(n_used[idx][ok_local] - d)
        sigma = float(np.sqrt(rss[ok_local].sum() / dof)) if dof > 0 else float("nan")
        cov_local = sigma**2 * H_inv
    else:
        sigma = float(sigma_m) if np.ndim(sigma_m) == 0 else p.sigma.copy()
        Hw = np.einsum("tn,tni,tnj->tij", p.w[idx], J, J)
        cov_local, _ = _solve_psd(Hw)

    pos = np.full((T, d), np.nan)
    cov = np.full((T, d, d), np.nan)
    gd = np.full(T, np.nan)
    rms = np.full(T, np.nan)
    k = idx[ok_local]
    pos[k] = x[k] + p.centre
    cov[k] = cov_local[ok_local]
    gd[k] = np.sqrt(np.trace(H_inv[ok_local], axis1=1, axis2=2))
    rms[k] = np.sqrt(rss[ok_local] / n_used[k])
    return MultilaterationResult(pos, cov, gd, n_used, rms, status, sigma, p.sigma is None, method, t_s, name)


# --------------------------------------------------------------------------- public solvers


def linear_multilaterate(range_m, anchor_pos_m, *, dim: int = 2, z_m=None) -> np.ndarray:
    """Closed-form linear least-squares position (the usual initial guess).

    Squaring ``r_i^2 = |p - a_i|^2 + dz_i^2`` gives equations linear in ``p``
    and ``R = |p|^2``; ``R`` is fitted as a free unknown, which is the same as
    differencing every equation against the mean over the anchors with a range.
    The result is exact for noise-free ranges but not optimal for noisy ones
    (use :func:`multilaterate` for that).

    Parameters
    ----------
    range_m
        Ranges, shape ``(T, n_anchors)`` (or ``(n_anchors,)``), metres, NaN = missing.
    anchor_pos_m
        Anchor positions, shape ``(n_anchors, 3)``, metres.
    dim
        2 (horizontal position at the known height ``z_m``) or 3.
    z_m
        Tag height for ``dim=2``: scalar or ``(T,)``, metres.

    Returns
    -------
    numpy.ndarray
        Positions, shape ``(T, dim)`` (or ``(dim,)``), metres; NaN rows where fewer
        than ``dim + 1`` ranges are present or the anchors with a range are
        collinear (``dim=2``) / coplanar (``dim=3``).
    """
    r = np.asarray(range_m, dtype=float)
    single = r.ndim == 1
    p = _Problem.build(r[None] if single else r, anchor_pos_m, dim, z_m, None)
    x, regular = _linear(p)
    pos = np.where((regular & (p.n_used >= dim + 1))[:, None], x + p.centre, np.nan)
    return pos[0] if single else pos


def multilaterate(range_m, anchor_pos_m, *, dim: int = 2, z_m=None, x0=None,
                  method: str = "gauss-newton", sigma_m=None, min_anchors: int | None = None,
                  max_iter: int = 50, tol_m: float = 1e-9, loss: str = "linear",
                  f_scale: float = 1.0, t_s=None, name: str = "LS") -> MultilaterationResult:
    """Nonlinear least-squares position fix for every epoch at once.

    Minimises ``sum_i w_i (r_i - |p - a_i|)^2`` over the ranges present at each
    epoch (``w_i = 1 / sigma_i^2``, or 1 without ``sigma_m``).

    Parameters
    ----------
    range_m
        Ranges, shape ``(T, n_anchors)``, metres, NaN = missing.
    anchor_pos_m
        Anchor positions, shape ``(n_anchors, 3)``, metres (or an :class:`~uwbwb.Anchors`).
    dim
        2 (horizontal position at the known tag height ``z_m``) or 3.
    z_m
        Tag height for ``dim=2``: scalar or ``(T,)``, metres.
    x0
        Start point(s), shape ``(dim,)`` or ``(T, dim)``, metres. Default: the
        closed-form :func:`linear_multilaterate` solution. With collinear
        (``dim=2``) or coplanar (``dim=3``) anchors the ranges fit two mirror
        positions; without ``x0`` such epochs are reported ``DEGENERATE``, with
        ``x0`` the solver converges to the mirror on the side of ``x0``.
    method
        ``"gauss-newton"``: batched over all epochs (vectorised, backtracking
        step, at most ``max_iter`` iterations, stops when a step is below
        ``tol_m``). Where the full Hessian (Gauss--Newton term plus the range
        model's curvature ``sum_i w_i e_i (I - u_i u_i^T) / r_i``) is positive
        definite the Newton step is taken instead of the Gauss--Newton one: same
        minimum, but quadratic convergence also for epochs with large residuals
        and a weak direction (typically the height), where plain Gauss--Newton
        needs hundreds of iterations. ``"least_squares"``:
        :func:`scipy.optimize.least_squares` per epoch with the analytic
        Jacobian and an optional robust ``loss`` (slow; a reference and for
        robust fits).
    sigma_m
        Range standard deviation, metres: scalar or ``(n_anchors,)``. Weights the
        fit and scales ``cov_m2``; if None, the covariance uses a noise level
        estimated from the residuals (see :class:`MultilaterationResult`).
    min_anchors
        Epochs with fewer ranges are ``TOO_FEW``; default and minimum ``dim + 1``.
    max_iter
        Iteration cap (Gauss--Newton) or function-evaluation cap (least_squares).
    tol_m
        Step size below which an epoch has converged, metres.
    loss, f_scale
        Robust loss for ``method="least_squares"`` (see scipy); ``f_scale`` is in
        metres without ``sigma_m`` and in standard deviations with it (residuals
        are divided by ``sigma_m``). Only ``loss="linear"`` is allowed with Gauss--Newton.
    t_s
        Epoch times ``(T,)``, seconds, kept in the result (so ``to_estimates()`` needs no argument).
    name
        Label of the result.

    Returns
    -------
    MultilaterationResult
        Positions, covariances, GDOP, counts and a status per epoch.
    """
    if method not in ("gauss-newton", "least_squares"):
        raise ValueError(f"method must be 'gauss-newton' or 'least_squares', got {method!r}")
    if method == "gauss-newton" and loss != "linear":
        raise ValueError("robust losses need method='least_squares'")
    if isinstance(max_iter, (bool, np.bool_)) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter must be a positive integer, got {max_iter!r}")
    if not np.isfinite(tol_m) or tol_m <= 0:
        raise ValueError(f"tol_m must be positive, got {tol_m!r}")
    p = _Problem.build(range_m, anchor_pos_m, dim, z_m, sigma_m)
    T = p.r.shape[0]
    if min_anchors is None:
        min_anchors = dim + 1
    if isinstance(min_anchors, (bool, np.bool_)) or not isinstance(min_anchors, (int, np.integer)) \
            or min_anchors < dim + 1:
        raise ValueError(f"min_anchors must be an integer >= dim + 1 = {dim + 1}, got {min_anchors!r}")

    status = np.full(T, Status.OK, dtype=np.int8)
    status[p.n_used < min_anchors] = Status.TOO_FEW
    if x0 is None:
        x_init, regular = _linear(p)
        status[(status == Status.OK) & ~regular] = Status.DEGENERATE
    else:
        x0 = np.asarray(x0, dtype=float)
        if x0.shape not in ((dim,), (T, dim)):
            raise ValueError(f"x0 must have shape ({dim},) or ({T}, {dim}), got {x0.shape}")
        if not np.all(np.isfinite(x0)):
            raise ValueError("x0 contains non-finite values")
        x_init = np.broadcast_to(x0, (T, dim)) - p.centre

    run = status == Status.OK
    if method == "gauss-newton":
        x, converged = _gauss_newton(p, x_init, run, int(max_iter), float(tol_m))
    else:
        x, converged = _least_squares(p, x_init, run, int(max_iter), float(tol_m), loss, f_scale)
    status[run & ~converged] = Status.NOT_CONVERGED
    return _finish(p, x, status, method, sigma_m, t_s, name)


def multilaterate_one(range_m, anchor_pos_m, *, dim: int = 2, z_m=None, x0=None,
                      method: str = "gauss-newton", sigma_m=None, min_anchors: int | None = None,
                      max_iter: int = 50, tol_m: float = 1e-9) -> np.ndarray:
    """Position fix for a single epoch; raises instead of reporting a status.

    Parameters are as in :func:`multilaterate` with ``range_m`` of shape
    ``(n_anchors,)`` and scalar ``z_m``. For the covariance, call
    :func:`multilaterate` with ``range_m[None]``.

    Returns
    -------
    numpy.ndarray
        Position, shape ``(dim,)``, metres.

    Raises
    ------
    uwbwb.GeometryError
        Too few ranges, ambiguous or singular geometry, or no convergence.
    """
    r = np.asarray(range_m, dtype=float)
    if r.ndim != 1:
        raise ValueError(f"range_m must have shape (n_anchors,), got {r.shape}")
    if z_m is not None and np.ndim(z_m) != 0:
        raise ValueError("z_m must be a scalar for a single epoch")
    res = multilaterate(r[None], anchor_pos_m, dim=dim, z_m=z_m, x0=x0, method=method,
                        sigma_m=sigma_m, min_anchors=min_anchors, max_iter=max_iter, tol_m=tol_m)
    st = Status(int(res.status[0]))
    if st == Status.OK:
        return res.pos_m[0].copy()
    n_used = int(res.n_used[0])
    need = dim + 1 if min_anchors is None else min_anchors
    if st == Status.TOO_FEW:
        raise GeometryError(f"only {n_used} of {r.size} ranges are present; a {dim}-D fix needs at least {need}")
    if st == Status.DEGENERATE:
        A = _as_anchors(anchor_pos_m)[:, :dim]
        shape = "collinear" if dim == 2 else "coplanar"
        if not _anchor_span_ok(A, np.isfinite(r)[None])[0]:
            if x0 is None:
                raise GeometryError(f"the {n_used} anchors with a range are {shape}: the ranges fit two mirror "
                                    f"positions; give x0 on the correct side to choose one")
            raise GeometryError(f"the {n_used} anchors with a range are {shape} and the solution reached from "
                                f"x0 lies on their {'line' if dim == 2 else 'plane'}, where the position is not "
                                f"determined; start x0 off it, on the correct side")
        raise GeometryError("the geometry matrix J^T J is singular at the solution: the ranges do not "
                            "determine the position")
    raise GeometryError(f"multilateration did not converge ({method}); check the ranges and x0")


def gdop(pos_m, anchor_pos_m, *, dim: int | None = None, z_m=None, mask=None) -> np.ndarray:
    """Geometric dilution of precision of range measurements.

    ``GDOP = sqrt(trace((H^T H)^-1))`` with ``H`` the :func:`range_jacobian`
    (unit vectors), i.e. the ratio of the position RMS error to the range error
    for independent, equal range errors (no clock term: two-way ranging).

    Parameters
    ----------
    pos_m
        Tag positions, shape ``(..., 2)`` (with ``z_m`` if the anchors are 3-D) or ``(..., 3)``, metres.
    anchor_pos_m
        Anchor positions, shape ``(n_anchors, 3)``, metres.
    dim
        Coordinates solved for: default ``pos_m.shape[-1]``. ``dim=2`` with 3-D
        positions gives the horizontal DOP for a known height (``pos_m[..., 2]``).
    z_m
        Tag height for 2-D positions, metres.
    mask
        Anchors used, bool, shape ``(n_anchors,)`` or ``(..., n_anchors)``; default all.

    Returns
    -------
    numpy.ndarray
        GDOP, shape ``pos_m.shape[:-1]``; ``inf`` where the geometry is singular.
    """
    pos = np.asarray(pos_m, dtype=float)
    if pos.ndim == 0 or pos.shape[-1] not in (2, 3):
        raise ValueError(f"pos_m must have shape (..., 2) or (..., 3), got {pos.shape}")
    if dim is None:
        dim = pos.shape[-1]
    if dim not in (2, 3) or dim > pos.shape[-1]:
        raise ValueError(f"dim must be 2 or 3 and at most pos_m.shape[-1]={pos.shape[-1]}, got {dim!r}")
    if dim == 2 and pos.shape[-1] == 3:
        if z_m is not None:
            raise ValueError("z_m is taken from pos_m[..., 2] for 3-D positions")
        J = range_jacobian(pos[..., :2], anchor_pos_m, z_m=pos[..., 2])
    else:
        J = range_jacobian(pos, anchor_pos_m, z_m=z_m)
    if mask is not None:
        mask = np.asarray(mask)
        if mask.dtype != bool:
            raise ValueError("mask must be boolean")
        try:
            J = J * np.broadcast_to(mask, J.shape[:-1])[..., None]
        except ValueError:
            raise ValueError(f"mask of shape {mask.shape} does not match {J.shape[:-1]}") from None
    H = np.einsum("...ni,...nj->...ij", J, J)
    lam = np.linalg.eigvalsh(H)
    regular = (lam[..., -1] > 0) & (lam[..., 0] > RCOND * lam[..., -1])
    safe = np.where(regular[..., None], lam, 1.0)
    return np.where(regular, np.sqrt(np.sum(1.0 / safe, axis=-1)), np.inf)
