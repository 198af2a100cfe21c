"""Trajectory of a linearly moving node by nonlinear least squares (Zupanec et al., eq. 1).

The *resolution routine* fits an initial position ``P`` and a constant velocity
``v`` to every range measured during one straight walk::

    [P0, v] = argmin_{P, v}  sum_k sum_{m in D_k} ( ||P + v t_m - P_k|| - d_{k,m} )^2        (1)

with ``P_k`` the position of anchor ``k``, ``d_{k,m}`` its ``m``-th range and
``t_m`` the measurement time from the segment's start (``t_0 = 0``). With
``v = 0`` (``static=True``) it is ordinary static localisation from all ranges
of a stationary segment.

The range model of eq. (1), its residuals and analytic Jacobian, is
:class:`uwbwb.models.track.LinearTrackRanges`; this module solves it.

Measurements are handled *unrolled*: one entry per (time, anchor, range)
(:class:`~uwbwb.types.RangeSamples`), so that pruning heuristics can drop single ranges.

Solvers
-------
``method="bfgs"``
    Quasi-Newton (BFGS) on the sum of squares with its analytic gradient,
    :func:`scipy.optimize.minimize` -- the paper's ``fminunc(...,
    'SpecifyObjectiveGradient', true, 'Algorithm', 'quasi-newton')``. The
    inverse-Hessian estimate starts from the Gauss--Newton matrix ``(J^T J)^-1``
    at the initial guess rather than the identity (same method, fewer iterations).
``method="least_squares"``
    :func:`scipy.optimize.least_squares` (trust-region reflective) on the
    residual vector with its analytic Jacobian; optionally a robust ``loss``.

Both work internally on a centred and scaled time axis (``t' = (t - t_mid) /
half_span``, velocity ``v' = v · half_span``), which leaves the minimiser of (1)
unchanged and keeps the position and velocity unknowns on the same scale (so
BFGS's identity start is not badly conditioned); results are reported in the
paper's parameters ``(P0, v)`` at ``t_0``.

Dimensions
----------
``dim=3`` solves ``P, v`` in 3-D as in the paper. ``dim=2`` solves the
horizontal ``(x, y)`` of ``P`` and ``v`` for a node at a known height ``z_m``
(``v_z = 0``) -- the right choice when the anchors are (nearly) coplanar with the
node, which makes the height unobservable.

Initial guess
-------------
Not the paper's all-zeros vector (the anchor frame's origin can be far from the
node, and with coplanar anchors ``P = 0`` may sit on the mirror side): each
epoch with enough ranges gets a closed-form linear fix
(:func:`uwbwb.geometry.linear_multilaterate`); ``P0, v`` come from a line fitted
to those fixes over time (two passes, the second without fixes further than
3 robust standard deviations from the first line). In 3-D with coplanar anchors
the fixes are horizontal at the height hint ``z_m`` (default: 1 m below the
lowest anchor, i.e. on the side of the anchor plane where nodes are). Without
any fix the guess is the anchors' centroid, at rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, minimize

from ..calibration import MAD_TO_SIGMA
from ..geometry import linear_multilaterate
from ..models.track import LinearTrackRanges, anchor_array
from ..types import EstimateStatus, Estimates, RangeLog, RangeSamples, Trajectory

__all__ = ["TrajectoryFit", "fit_trajectory", "initial_guess"]



# --------------------------------------------------------------------------- initial guess


def _line_fit(t: np.ndarray, X: np.ndarray, static: bool) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``X ≈ a + b t`` (b = 0 when static); returns (a, b)."""
    if static or np.ptp(t) == 0:
        return X.mean(axis=0), np.zeros(X.shape[1])
    G = np.column_stack([np.ones_like(t), t])
    coef, *_ = np.linalg.lstsq(G, X, rcond=None)
    return coef[0], coef[1]


def _coplanar(A: np.ndarray, rel_tol: float = 0.05) -> bool:
    """True when the anchors' spread off their best plane is below ``rel_tol`` of their extent."""
    if A.shape[0] < 4:
        return True
    sv = np.linalg.svd(A - A.mean(axis=0), compute_uv=False)
    return bool(sv[2] <= rel_tol * sv[0])


def initial_guess(samples: RangeSamples, anchors, *, dim: int = 3, static: bool = False,
                  z_m: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A start point ``(P0, v)`` for eq. (1) from per-epoch linear fixes (see module notes).

    Parameters
    ----------
    samples, anchors, dim, static
        As in :func:`fit_trajectory`.
    z_m
        ``dim=2``: the node height. ``dim=3``: a height hint used only when the
        anchors are (nearly) coplanar -- out-of-plane spread below 5 % of their
        extent -- (default 1 m below the lowest anchor).

    Returns
    -------
    P0_m, vel_mps : numpy.ndarray
        Shape ``(3,)`` each.
    """
    A = anchor_array(anchors)
    if dim == 2 and z_m is None:
        raise ValueError("dim=2 needs the node height z_m (metres)")
    t, R = samples.to_matrix()
    z_hint = float(z_m) if z_m is not None else float(A[:, 2].min() - 1.0)
    if dim == 3 and not _coplanar(A):
        fix = linear_multilaterate(R, A, dim=3)
    else:
        # coplanar anchors: the linear 3-D fix is singular (and its mirror ambiguous): fix at the hint
        xy = linear_multilaterate(R, A, dim=2, z_m=z_hint)
        fix = np.column_stack([xy, np.full(len(xy), z_hint)])
    good = np.isfinite(fix).all(axis=1)
    if good.sum() < (1 if static else 2):
        P = A.mean(axis=0)
        P[2] = z_hint
        return P, np.zeros(3)
    tg, X = t[good], fix[good]
    a, b = _line_fit(tg, X, static)
    resid = np.linalg.norm(X - (a + np.multiply.outer(tg, b)), axis=1)
    scale = MAD_TO_SIGMA * np.median(np.abs(resid - np.median(resid))) + 1e-6
    keep = resid <= np.median(resid) + 3 * scale
    if keep.sum() >= 2:
        a, b = _line_fit(tg[keep], X[keep], static)
    t0 = samples.t_s[0] if len(samples) else 0.0
    P0 = a + b * t0
    if dim == 2:
        P0[2], b[2] = z_hint, 0.0
    return P0, b


# --------------------------------------------------------------------------- fit


@dataclass(frozen=True)
class TrajectoryFit:
    """Result of the resolution routine (eq. 1) and how the solver got there.

    Attributes
    ----------
    p0_m
        Position at ``t0_s``, shape ``(3,)``, metres (``z`` = the fixed height for ``dim=2``).
    vel_mps
        Velocity, shape ``(3,)``, m/s (zeros when ``static``).
    t0_s
        Time of ``p0_m``: the first measurement of the segment, seconds.
    t_end_s
        Time of the last measurement, seconds.
    cost_m2
        Sum of squared residuals at the solution (the objective of eq. 1).
    residual_rms_m
        ``sqrt(cost / M)``.
    n_used
        Number of ranges ``M`` in the fit.
    cov
        Covariance of the solved unknowns (order of ``theta``), ``s^2 (J^T J)^-1``
        with ``s^2 = cost / (M - n_params)``; NaN where singular.
    success
        The solver's own success flag.
    converged
        ``success``, or the gradient at the solution is below ``gtol`` anyway
        (BFGS may stop on rounding with a solution that is already optimal).
    message
        The solver's message.
    n_iter, n_fev
        Iterations and function evaluations.
    grad_norm
        Infinity norm of the gradient of the *mean* squared residual at the
        solution, metres (scale-free across segment sizes).
    method, dim, static
        How the fit was set up.
    theta0
        Initial guess, in the order of ``theta`` (paper parameters).
    name
        Label of the fitted line.
    """

    p0_m: np.ndarray
    vel_mps: np.ndarray
    t0_s: float
    t_end_s: float
    cost_m2: float
    residual_rms_m: float
    n_used: int
    cov: np.ndarray
    success: bool
    converged: bool
    message: str
    n_iter: int
    n_fev: int
    grad_norm: float
    method: str
    dim: int
    static: bool
    theta0: np.ndarray = field(repr=False)
    name: str = "NLS"

    @property
    def theta(self) -> np.ndarray:
        """The solution in the paper's parameters (see :class:`~uwbwb.models.track.LinearTrackRanges`)."""
        d = self.dim
        return self.p0_m[:d].copy() if self.static else np.concatenate([self.p0_m[:d], self.vel_mps[:d]])

    @property
    def speed_mps(self) -> float:
        return float(np.linalg.norm(self.vel_mps))

    def position_at(self, t_s) -> np.ndarray:
        """``P0 + v (t - t0)``, shape ``(..., 3)``, metres."""
        return self.p0_m + np.multiply.outer(np.asarray(t_s, float) - self.t0_s, self.vel_mps)

    def _epochs(self, t_s) -> np.ndarray:
        t = np.array([self.t0_s, self.t_end_s] if t_s is None else t_s, float)
        if t.size == 2 and t[0] == t[1]:
            t = t[:1]
        return t

    def to_trajectory(self, t_s=None, name: str | None = None) -> Trajectory:
        """The fitted straight line sampled at ``t_s`` (default: its start and end)."""
        t = self._epochs(t_s)
        vel = np.broadcast_to(self.vel_mps, (t.size, 3))
        return Trajectory(t, self.position_at(t), vel, name=name or self.name)

    def to_estimates(self, t_s=None, name: str | None = None) -> Estimates:
        """The common result type at epochs ``t_s`` ``(T,)`` (default: the segment's start and end,
        as :meth:`to_trajectory`): the fitted line's positions and velocity, and the position
        covariance propagated from :attr:`cov` (``A cov Aᵀ`` with ``A = [I, (t − t0) I]``). All
        epochs are ``UPDATED`` if the solver converged, else ``NO_ESTIMATE``. Labelled :attr:`name`
        unless ``name`` is given."""
        t, name = self._epochs(t_s), name or self.name
        d, T = self.dim, t.size
        if not self.converged:
            return Estimates(t, np.full((T, d), np.nan), np.full(T, EstimateStatus.NO_ESTIMATE, np.int8), name)
        A = np.broadcast_to(np.eye(d), (T, d, d))
        if not self.static:
            A = np.concatenate([A, (t - self.t0_s)[:, None, None] * np.eye(d)], axis=-1)
        cov = np.einsum("kij,jl,kml->kim", A, self.cov, A)
        return Estimates(t, self.position_at(t)[:, :d], np.full(T, EstimateStatus.UPDATED, np.int8), name, cov,
                         np.broadcast_to(self.vel_mps[:d], (T, d)))

    def report(self) -> str:
        """One line: solver, outcome, iterations, residual RMS."""
        state = "converged" if self.converged else "NOT converged"
        return (f"{self.method}: {state} after {self.n_iter} iterations / {self.n_fev} evaluations, "
                f"|grad| = {self.grad_norm:.2e} m, residual RMS = {self.residual_rms_m:.3f} m over "
                f"{self.n_used} ranges ({self.message})")


def fit_trajectory(samples: RangeSamples | RangeLog, anchors, *, dim: int = 3, static: bool = False,
                   z_m: float | None = None, method: str = "bfgs", x0=None, loss: str = "linear",
                   f_scale_m: float = 1.0, gtol: float = 1e-7, max_iter: int = 500) -> TrajectoryFit:
    """Solve eq. (1) for the initial position and velocity of a straight walk.

    Parameters
    ----------
    samples
        The ranges of one segment: :class:`RangeSamples` or a
        :class:`~uwbwb.RangeLog` (NaN = missing). ``t0`` is the first
        measurement's time.
    anchors
        :class:`~uwbwb.Anchors` (or array ``(n_anchors, 3)``), metres, in the
        order of the range columns.
    dim
        3 (solve ``P, v`` in 3-D, the paper) or 2 (horizontal, node at height ``z_m``).
    static
        Fix ``v = 0``: static localisation from all ranges.
    z_m
        Node height for ``dim=2`` (required), height hint for the initial guess
        with ``dim=3`` (optional; see :func:`initial_guess`), metres.
    method
        ``"bfgs"`` (quasi-Newton, like the paper's ``fminunc``) or ``"least_squares"``.
    x0
        Initial ``(P0, v)`` as a pair of 3-vectors, or ``theta``; default :func:`initial_guess`.
    loss, f_scale_m
        Robust loss of ``least_squares`` (``"linear"`` is eq. 1 itself); scale in metres.
    gtol
        Gradient tolerance on the mean squared residual (metres).
    max_iter
        Iteration cap.

    Returns
    -------
    TrajectoryFit

    Raises
    ------
    ValueError
        Fewer ranges than unknowns, or bad parameters.
    """
    if isinstance(samples, RangeLog):
        samples = RangeSamples.from_ranges(samples)
    if method not in ("bfgs", "least_squares"):
        raise ValueError(f"method must be 'bfgs' or 'least_squares', got {method!r}")
    if method == "bfgs" and loss != "linear":
        raise ValueError("a robust loss needs method='least_squares'")
    model = LinearTrackRanges(anchors, dim, static, z_m if dim == 2 else None)
    A = model.anchor_pos_m
    if len(samples.anchor_ids) != A.shape[0]:
        raise ValueError(f"samples have {len(samples.anchor_ids)} anchors, anchors {A.shape[0]}")
    M, p = len(samples), model.n_params
    if M < p:
        raise ValueError(f"{M} ranges cannot determine {p} unknowns")

    t0 = float(samples.t_s[0])
    t_end = float(samples.t_s[-1])
    if x0 is None:
        P_init, v_init = initial_guess(samples, A, dim=dim, static=static, z_m=z_m)
        theta0 = model.pack(P_init, v_init)
    elif isinstance(x0, tuple) and len(x0) == 2:
        theta0 = model.pack(np.asarray(x0[0], float), np.asarray(x0[1], float))
    else:
        theta0 = model.check_theta(x0)
    if not np.all(np.isfinite(theta0)):
        raise ValueError("the initial guess is not finite")

    # centred, scaled time axis: t' = (t - t_mid) / h, v' = v h, P_mid = P0 + v (t_mid - t0)
    t_mid = 0.5 * (t0 + t_end)
    h = 0.5 * (t_end - t0) if (t_end > t0 and not static) else 1.0
    tc = (samples.t_s - t_mid) / h
    k, d = samples.anchor_index, samples.range_m
    d_ = model.dim

    def to_internal(theta):
        if static:
            return theta.copy()
        P, v = theta[:d_], theta[d_:]
        return np.concatenate([P + v * (t_mid - t0), v * h])

    def from_internal(q):
        if static:
            return q.copy()
        Pm, vq = q[:d_], q[d_:]
        v = vq / h
        return np.concatenate([Pm - v * (t_mid - t0), v])

    last = {}

    def terms(q):
        """Residuals and Jacobian at ``q``; the last point evaluated is kept, since the solver's first
        evaluation is the start (where the BFGS matrix was set up) and its solution is usually its last."""
        key = q.tobytes()
        if last.get("key") != key:
            last.update(key=key, value=model.residuals_jacobian(q, tc, k, d))
        return last["value"]

    def fun_grad(q):
        r, J = terms(q)
        return float(r @ r) / M, (2.0 / M) * (J.T @ r)

    q0 = to_internal(theta0)
    if method == "bfgs":
        options = {"gtol": gtol, "maxiter": int(max_iter)}
        # start the quasi-Newton matrix from the Gauss-Newton Hessian (2/M) J^T J at q0 instead of the
        # identity: same BFGS iteration, far fewer steps (it matters inside residual pruning's loop)
        J0 = terms(q0)[1]
        H0 = (2.0 / M) * (J0.T @ J0)
        lam, V = np.linalg.eigh(H0)
        if lam[0] > 1e-9 * lam[-1] > 0:
            Hi = (V / lam) @ V.T
            options["hess_inv0"] = 0.5 * (Hi + Hi.T)
        res = minimize(fun_grad, q0, jac=True, method="BFGS", options=options)
        q, n_iter, n_fev, success, msg = res.x, int(res.nit), int(res.nfev), bool(res.success), str(res.message)
    else:
        res = least_squares(lambda q: model.residuals_jacobian(q, tc, k, d, jacobian=False)[0], q0,
                            jac=lambda q: model.residuals_jacobian(q, tc, k, d)[1], method="trf",
                            loss=loss, f_scale=f_scale_m, gtol=1e-12, xtol=1e-12, ftol=1e-12,
                            max_nfev=int(max_iter))
        q, n_iter, n_fev, success, msg = res.x, int(res.nfev), int(res.nfev), bool(res.success), str(res.message)

    r, J = terms(q)
    f, g = float(r @ r) / M, (2.0 / M) * (J.T @ r)           # fun_grad(q), from the one evaluation
    grad_norm = float(np.max(np.abs(g)))
    theta = from_internal(q)
    P, v = model.unpack(theta)

    # covariance in the paper's parameters: Jacobian of eq. 1 at theta (t from t0)
    Jp = model.residuals_jacobian(theta, samples.t_s - t0, k, d)[1]
    dof = M - p
    cov = np.full((p, p), np.nan)
    if dof > 0:
        H = Jp.T @ Jp
        lam = np.linalg.eigvalsh(H)
        if lam[0] > 1e-12 * lam[-1] > 0:
            cov = float(r @ r) / dof * np.linalg.inv(H)
    return TrajectoryFit(P, v, t0, t_end, float(r @ r), float(np.sqrt(f)), M, cov, success,
                         bool(success or grad_norm <= max(gtol, 1e-7)), msg, n_iter, n_fev, grad_norm,
                         method, model.dim, model.static, theta0)
