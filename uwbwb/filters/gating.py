"""Innovation gates as policies injected into a Gaussian filter.

A gate decides, per epoch, which of the measurement's components the update may use. It is
a small frozen dataclass passed to the filter (``Ekf(..., gate=ChiSquareEpoch(0.9999))``), so
any filter runs with or without it, and an ablation row "with / without gate" is one argument.

Policies
--------
:class:`NoGate`
    Every measurement is used, however far from the prediction.
:class:`ChiSquareEpoch`
    The whole epoch is rejected (status ``GATED``, prediction only) when its normalised
    innovation squared ``NIS = yᵀ S⁻¹ y`` exceeds the ``prob`` quantile of χ²(m).
:class:`ChiSquarePerMeasurement`
    Each component ``i`` is tested on its own, ``y_i² / S_ii`` against the ``prob`` quantile
    of χ²(1); the rejected rows are removed and the rest update the state (the marginal of a
    Gaussian measurement, so correlated noise stays correct). The epoch is gated when fewer
    than ``min_rows`` remain.
:class:`AnchorDropping`
    While the epoch fails the χ²(m) test, the component (anchor) whose removal lowers the
    NIS most is dropped and the measurement re-linearised without it; the epoch is gated when
    one more drop would leave fewer than ``min_rows`` rows. Needs a measurement model that can
    re-linearise a subset of its components (:class:`Subsettable`), e.g.
    :class:`~uwbwb.filters.ekf.TdoaMeasurement`, which re-references the TDoAs when the
    reference anchor is dropped.
:class:`Robust`
    M-estimation: every component is used, with ``R`` inflated by ``1 / w_i`` where Huber (default,
    :data:`HUBER_K`) or Cauchy (:data:`CAUCHY_C`) weights ``w_i`` come from the component's residual
    over ``√S_ii``, reweighted :data:`ROBUST_ITERATIONS` times; ``Robust(gate=ChiSquareEpoch())``
    screens with a χ² policy first ("both"), so the ablation rows none / χ² gate / robust / both are
    ``NoGate()``, ``ChiSquareEpoch()``, ``Robust()``, ``Robust(gate=ChiSquareEpoch())``.

Release rule (every policy): a filter that has lost the target would reject everything
after, so after ``max_gated`` consecutive *gated* epochs the next one is used ungated
(:meth:`active` is False for it). Epochs where only some components were dropped do not count.

Adopting a policy in a filter
-----------------------------
A filter holds a policy and, per epoch, with prior ``state`` and the epoch's
linearisation ``lin`` (``z, h, H, R``; :class:`~uwbwb.filters.ekf.Linearisation`)::

    gated_run = 0
    for each epoch:
        ...predict...
        if gate.active(gated_run):
            post, info = gate.update(state, lin, parts)    # parts = (components, relinearise) or None
        else:
            post, info = ungated_update(state, lin)
        gated_run = gated_run + 1 if info.status == EstimateStatus.GATED else 0

``parts`` is needed only by policies whose ``needs_subsets`` is True (anchor dropping): the
epoch's component identifiers and a function ``relinearise(keep) -> Linearisation`` (see
:class:`Subsettable`). A filter that cannot re-linearise passes None and refuses such a
policy at construction.
:func:`ungated_update` is the plain Joseph-form update every policy ends in; with
``sequential=True`` it applies the rows one scalar at a time (the same posterior in exact
arithmetic, each row's NIS in ``UpdateInfo.nis_rows``), and every policy passes that option on.
Every χ² policy (and :class:`NoGate`) also has ``screen(state, lin, parts)``, its decision alone
(the rows it keeps, :data:`Screened`), which :class:`Robust` reads before reweighting.
Filters with their own rules for when a gate applies, or their own arithmetic (a particle
filter's weights), use the decision part only: :meth:`ChiSquareEpoch.threshold`,
:meth:`ChiSquarePerMeasurement.threshold` and :meth:`ChiSquarePerMeasurement.keep` (also
:class:`NoGate`'s, which keep every row) take the NIS / per-row statistics the filter already
computes. The tight error-state filter's Python definition (``TightEskf.run_reference``) tests its
UWB rows with ``keep`` (its own start-up engagement and release rule) and updates with the rows kept
through ``ungated_update(..., sequential=True)``; its compiled twin does the same arithmetic in one
loop and reads only the threshold.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Callable, Protocol

import numpy as np
from scipy.stats import chi2

from ..types import EstimateStatus
from . import kalman
from .kalman import Gaussian

__all__ = ["AnchorDropping", "CAUCHY_C", "ChiSquareEpoch", "ChiSquarePerMeasurement", "GatePolicy", "HUBER_K", "NoGate",
           "ROBUST_ITERATIONS", "Robust", "Screened", "Subsettable", "UpdateInfo", "gate_from_prob", "gate_policy",
           "ungated_update"]


@dataclass(frozen=True)
class UpdateInfo:
    """What one update did.

    Attributes
    ----------
    nis
        Normalised innovation squared ``yᵀ S⁻¹ y`` (NaN if nothing was measured).
    dof
        Size of the measurement used (0 if none).
    status
        The epoch's :class:`~uwbwb.types.EstimateStatus`.
    n_rejected
        Measurement components (e.g. anchors) a gate removed.
    innovation
        The :class:`~uwbwb.filters.kalman.Innovation` (``y (m,)``, ``S (m, m)``) whose NIS is
        ``nis``: that of the rows used, or of the whole epoch where a χ² epoch gate rejected
        it; None where there is none (nothing measured; an epoch gated row by row).
    nis_rows
        For a sequential update (``sequential=True``) that was applied, the NIS of each scalar row
        in the order applied, shape ``(m,)`` (:func:`~uwbwb.filters.kalman.update_sequential`; rows after
        decorrelating a non-diagonal ``R``): ``y'_i² / s_i`` with ``y'_i`` the row's innovation
        against the mean the rows before it left and ``s_i = h_iᵀ P_{i−1} h_i + r_i``. They sum to
        :attr:`nis`. None for a batch update and for an epoch a row gate rejected; for an epoch
        :class:`ChiSquareEpoch` rejected, the rows' NIS it tested (nothing was applied); None for a
        :class:`Robust` update (its rows are applied with the inflated ``R``, so their NIS would not
        sum to the epoch's).
    n_downweighted
        For a :class:`Robust` update, the components used whose normalised residual exceeded the
        tuning constant in the last pass (Huber: weight below 1; Cauchy: weight below ½); 0 otherwise.
    weights
        For a :class:`Robust` update, the final weight of each component used, shape ``(m,)``, in
        (0, 1] (``R`` was inflated by their inverse); None otherwise.

    Equality and ``repr`` compare ``nis``, ``dof``, ``status``, ``n_rejected`` and ``n_downweighted``
    only: the arrays behind them (``innovation``, ``nis_rows``, ``weights``) are diagnostics, so two
    infos that compare equal may differ in :attr:`log_likelihood`.
    """

    nis: float
    dof: int
    status: EstimateStatus
    n_rejected: int = 0
    innovation: kalman.Innovation | None = field(default=None, compare=False, repr=False)
    nis_rows: np.ndarray | None = field(default=None, compare=False, repr=False)
    n_downweighted: int = 0
    weights: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def log_likelihood(self) -> float:
        """Gaussian log-likelihood of the innovation, the measurement's likelihood under the prior::

            log N(y; 0, S) = −½ (yᵀ S⁻¹ y + log det(2π S))

        with ``y = z − h(x⁻)`` and ``S = H P⁻ Hᵀ + R`` (``yᵀ S⁻¹ y`` is :attr:`nis`). A
        multi-hypothesis filter weights each child hypothesis by it. NaN without an innovation.
        """
        inn = self.innovation
        if inn is None:
            return np.nan
        return -0.5 * (inn.nis + np.linalg.slogdet(2 * np.pi * inn.S)[1])


class Subsettable(Protocol):
    """A measurement model that can re-linearise a subset of one epoch's components."""

    def components(self, measurement) -> np.ndarray:
        """Identifiers of the epoch's usable components (e.g. anchor indices), sorted, shape ``(c,)``."""

    def linearise_components(self, x: np.ndarray, measurement, keep: np.ndarray):
        """The epoch's :class:`~uwbwb.filters.ekf.Linearisation` from components ``keep`` only."""


Parts = tuple[np.ndarray, Callable[[np.ndarray], object]]


@lru_cache(maxsize=1024)
def _chi2_ppf(prob: float, dof: int):
    """``χ²_dof⁻¹(prob)``, cached: scipy's quantile costs about a millisecond a call, the filters ask per epoch."""
    return chi2.ppf(prob, dof)


def _update(state: Gaussian, lin, sequential: bool = False):
    """:func:`~uwbwb.filters.kalman.update` with ``lin``: the innovation ``z − h(x⁻)``, or, for a
    linear measurement (``lin.linear``), ``z − H x⁻`` as in the textbook linear update.
    ``sequential``: :func:`~uwbwb.filters.kalman.update_sequential` instead (see
    :func:`ungated_update`). Returns ``(posterior, innovation, nis_rows)`` (``nis_rows`` None
    for a batch update)."""
    h_x = None if getattr(lin, "linear", False) else lin.h
    if not sequential:
        post, inn = kalman.update(state, lin.z, lin.H, lin.R, h_x=h_x)
        return post, inn, None
    post, nis_rows = kalman.update_sequential(state, lin.z, lin.H, lin.R, h_x=h_x)
    y = lin.z - (lin.H @ state.x if h_x is None else h_x)
    S = lin.H @ state.P @ lin.H.T + lin.R
    return post, kalman.Innovation(y, 0.5 * (S + S.T), float(nis_rows.sum())), nis_rows


def ungated_update(state: Gaussian, lin, *, sequential: bool = False) -> tuple[Gaussian, UpdateInfo]:
    """Joseph-form update with all of ``lin`` (``z, h, H, R``), status ``UPDATED``.

    Parameters
    ----------
    state
        Prior ``(x⁻, P⁻)``.
    lin
        The epoch's :class:`~uwbwb.filters.ekf.Linearisation`.
    sequential
        False (default): one batch update, ``K = P⁻Hᵀ S⁻¹`` with ``S = H P⁻ Hᵀ + R``
        (:func:`~uwbwb.filters.kalman.update`). True: scalar updates, one row after the other
        (:func:`~uwbwb.filters.kalman.update_sequential`): with ``R = L Lᵀ`` the rows of
        ``L⁻¹ y`` and ``L⁻¹ H`` have unit, independent noise, and row ``i`` updates the mean and
        covariance the rows before it left::

            s_i = h_iᵀ P_{i−1} h_i + r_i,   k_i = P_{i−1} h_i / s_i,
            x_i = x_{i−1} + k_i (y_i − h_iᵀ (x_{i−1} − x⁻)),
            P_i = (I − k_i h_iᵀ) P_{i−1} (I − k_i h_iᵀ)ᵀ + r_i k_i k_iᵀ

        For a measurement linear in the state the result equals the batch update in exact
        arithmetic (the rows are independent given the state); in floating point the two
        differ by rounding (about 1e-12 relative), so a χ² decision on the summed NIS can fall
        on the other side of its threshold at the boundary. It needs ``R`` symmetric (to 1e-12
        relative) and positive definite, for its Cholesky factor; the batch update needs only
        ``S`` positive definite. No ``m × m`` inverse is formed. The NIS of each row is reported
        in ``UpdateInfo.nis_rows`` and their sum as ``nis``.
    """
    post, inn, nis_rows = _update(state, lin, sequential)
    return post, UpdateInfo(inn.nis, lin.z.size, EstimateStatus.UPDATED, innovation=inn, nis_rows=nis_rows)


def _epoch_nis(state: Gaussian, lin) -> float:
    y = lin.z - lin.h
    S = lin.H @ state.P @ lin.H.T + lin.R
    return float(y @ np.linalg.solve(S, y))


def _innovation(state: Gaussian, lin) -> kalman.Innovation:
    """The epoch's innovation under the model: ``y = z − h(x⁻)`` (``z − H x⁻`` for a linear
    measurement, as :func:`_update` forms it), ``S = H P⁻ Hᵀ + R`` (symmetrised) and ``yᵀ S⁻¹ y``."""
    y = lin.z - (lin.H @ state.x if getattr(lin, "linear", False) else lin.h)
    S = lin.H @ state.P @ lin.H.T + lin.R
    S = 0.5 * (S + S.T)
    return kalman.Innovation(y, S, float(y @ np.linalg.solve(S, y)))


def _update_screened(state: Gaussian, screened: Screened, sequential: bool) -> tuple[Gaussian, UpdateInfo]:
    """A row gate's update: the prior and its ``GATED`` info, or :func:`ungated_update` of the rows kept."""
    kept, n_rejected, gated = screened
    if kept is None:
        return state, gated
    post, info = ungated_update(state, kept, sequential=sequential)
    return post, replace(info, n_rejected=n_rejected) if n_rejected else info


def _is_int(value, minimum: int) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, np.integer)) and value >= minimum


def _is_prob(p) -> bool:
    """``p`` is a real number (NumPy scalars included, not a bool) strictly between 0 and 1."""
    return isinstance(p, numbers.Real) and not isinstance(p, (bool, np.bool_)) and 0 < p < 1


def _check(owner: str, prob, max_gated, min_rows=None) -> None:
    if prob is not None and not _is_prob(prob):
        raise ValueError(f"{owner}.prob must be in (0, 1), got {prob!r}")
    if not _is_int(max_gated, 0):
        raise ValueError(f"{owner}.max_gated must be an integer >= 0, got {max_gated!r}")
    if min_rows is not None and not _is_int(min_rows, 1):
        raise ValueError(f"{owner}.min_rows must be an integer >= 1, got {min_rows!r}")


class GatePolicy(Protocol):
    """What a filter needs from a gate."""

    max_gated: int
    needs_subsets: bool

    def active(self, n_gated: int) -> bool:
        """Whether the gate applies after ``n_gated`` consecutive gated epochs."""

    def update(self, state: Gaussian, lin, parts: Parts | None = None, *,
               sequential: bool = False) -> tuple[Gaussian, UpdateInfo]:
        """The gated update of one epoch (``sequential``: the update it makes is
        :func:`ungated_update`'s sequential form; a filter passes it only when asked for)."""


Screened = tuple[object | None, int, UpdateInfo | None]
"""What a χ² policy's ``screen`` decides for one epoch: ``(kept, n_rejected, gated)`` — the
linearisation of the rows it lets through (None when it rejects the epoch), the components it removed,
and, for a rejected epoch, the ``GATED`` :class:`UpdateInfo` its ``update`` returns (else None).
:class:`Robust` with ``gate=`` reads it, then updates ``kept`` its own way."""


@dataclass(frozen=True)
class _Release:
    def active(self, n_gated: int) -> bool:
        """True while fewer than ``max_gated`` consecutive epochs have been gated."""
        return n_gated < self.max_gated


class _RowTest:
    """The row test of a policy with a ``threshold()``: what a filter with its own update
    arithmetic reads when it tests each measurement row on its own."""

    def keep(self, y: np.ndarray, S_diag: np.ndarray) -> np.ndarray:
        """Rows that pass, bool ``(m,)``, from innovations ``y (m,)`` and variances ``S_ii (m,)``:
        ``y_i² / S_ii <= threshold()`` (a NaN statistic does not pass)."""
        y, s = np.asarray(y, float), np.asarray(S_diag, float)
        return y * y / s <= self.threshold()


@dataclass(frozen=True)
class NoGate(_RowTest, _Release):
    """No gate: every measurement is used. ``max_gated`` is kept only so that a filter's
    ``max_gated`` setting survives switching the gate off and on. As a row test
    (:meth:`threshold`, :meth:`keep`) every row with a defined statistic passes."""

    max_gated: int = 10
    needs_subsets = False

    def __post_init__(self):
        _check("NoGate", None, self.max_gated)

    def threshold(self) -> float:
        """``inf``: no row is rejected."""
        return float("inf")

    def screen(self, state: Gaussian, lin, parts: Parts | None = None) -> Screened:
        """Every row passes."""
        return lin, 0, None

    def update(self, state: Gaussian, lin, parts: Parts | None = None, *,
               sequential: bool = False) -> tuple[Gaussian, UpdateInfo]:
        """:func:`ungated_update`."""
        return ungated_update(state, lin, sequential=sequential)


@dataclass(frozen=True)
class ChiSquareEpoch(_Release):
    """Reject the whole epoch when ``NIS > χ²_m⁻¹(prob)`` (``m`` components).

    The default ``prob = 0.9999`` rejects one consistent epoch in ten thousand and any absurd
    measurement. A NaN NIS is not above the threshold (the epoch is used).
    """

    prob: float = 0.9999
    max_gated: int = 10
    needs_subsets = False

    def __post_init__(self):
        _check("ChiSquareEpoch", self.prob, self.max_gated)
        object.__setattr__(self, "prob", float(self.prob))

    def threshold(self, m: int) -> float:
        """The NIS above which an ``m``-component epoch is rejected."""
        return float(_chi2_ppf(self.prob, int(m)))

    def screen(self, state: Gaussian, lin, parts: Parts | None = None) -> Screened:
        """The epoch whole, or nothing (``GATED``) when its NIS (batch, ``yᵀ S⁻¹ y``) is above the threshold."""
        inn = _innovation(state, lin)
        if inn.nis > _chi2_ppf(self.prob, lin.z.size):
            return None, 0, UpdateInfo(inn.nis, 0, EstimateStatus.GATED, innovation=inn)
        return lin, 0, None

    def update(self, state: Gaussian, lin, parts: Parts | None = None, *,
               sequential: bool = False) -> tuple[Gaussian, UpdateInfo]:
        """Posterior, or the prior with status ``GATED`` (its NIS kept, ``dof`` 0)."""
        post, inn, nis_rows = _update(state, lin, sequential)
        if inn.nis > _chi2_ppf(self.prob, lin.z.size):
            return state, UpdateInfo(inn.nis, 0, EstimateStatus.GATED, innovation=inn, nis_rows=nis_rows)
        return post, UpdateInfo(inn.nis, lin.z.size, EstimateStatus.UPDATED, innovation=inn, nis_rows=nis_rows)


@dataclass(frozen=True)
class ChiSquarePerMeasurement(_RowTest, _Release):
    """Reject single components with ``y_i² / S_ii > χ²_1⁻¹(prob)``; update with the rest.

    ``S = H P⁻ Hᵀ + R`` is the innovation covariance of the whole epoch, so each row is
    tested against its own marginal. The epoch is gated (prediction only) when fewer than
    ``min_rows`` rows pass; its ``nis`` is then that of the whole epoch and ``n_rejected``
    the number of rows.
    """

    prob: float = 0.9999
    min_rows: int = 1
    max_gated: int = 10
    needs_subsets = False

    def __post_init__(self):
        _check("ChiSquarePerMeasurement", self.prob, self.max_gated, self.min_rows)
        object.__setattr__(self, "prob", float(self.prob))

    def threshold(self) -> float:
        """The ``y_i² / S_ii`` above which a row is rejected, ``χ²_1⁻¹(prob)``."""
        return float(_chi2_ppf(self.prob, 1))

    def screen(self, state: Gaussian, lin, parts: Parts | None = None) -> Screened:
        """The rows that pass (``lin.rows``), or nothing (``GATED``) when fewer than ``min_rows`` do."""
        S = lin.H @ state.P @ lin.H.T + lin.R
        ok = self.keep(lin.z - lin.h, np.diag(S))
        if ok.all():
            return lin, 0, None
        if ok.sum() < self.min_rows:
            return None, int(ok.size), UpdateInfo(_epoch_nis(state, lin), 0, EstimateStatus.GATED, int(ok.size))
        rows = np.flatnonzero(ok)
        return lin.rows(rows), int(ok.size - rows.size), None

    def update(self, state: Gaussian, lin, parts: Parts | None = None, *,
               sequential: bool = False) -> tuple[Gaussian, UpdateInfo]:
        return _update_screened(state, self.screen(state, lin, parts), sequential)


@dataclass(frozen=True)
class AnchorDropping(_Release):
    """Drop the worst component (anchor) until the epoch passes the χ²(m) test.

    While ``NIS > χ²_m⁻¹(prob)`` (a NaN NIS fails too), every single remaining component is
    tried out and the one whose removal gives the smallest NIS is dropped; the measurement is
    re-linearised without it (``parts``: the epoch's components and the function that
    re-linearises a subset of them). When one more drop would leave fewer than
    ``max(min_rows, 1)`` rows, the epoch is gated and all its remaining components count as
    rejected. The NIS reported is that of the update finally made.
    """

    prob: float = 0.9999
    min_rows: int = 1
    max_gated: int = 10
    needs_subsets = True

    def __post_init__(self):
        _check("AnchorDropping", self.prob, self.max_gated, self.min_rows)
        object.__setattr__(self, "prob", float(self.prob))

    def screen(self, state: Gaussian, lin, parts: Parts | None = None) -> Screened:
        """The re-linearised subset that passes, or nothing (``GATED``)."""
        if parts is None:
            raise ValueError("AnchorDropping needs a measurement model that can re-linearise a subset of its "
                             "components (components(), linearise_components())")
        components, subset = parts
        keep = np.asarray(components)
        n_rejected = 0
        while not _epoch_nis(state, lin) <= _chi2_ppf(self.prob, lin.z.size):
            if lin.z.size - 1 < max(self.min_rows, 1):
                n = n_rejected + keep.size
                return None, n, UpdateInfo(np.nan, 0, EstimateStatus.GATED, n)
            trial = [_epoch_nis(state, subset(keep[keep != k])) for k in keep]
            keep = keep[keep != keep[int(np.argmin(trial))]]
            lin = subset(keep)
            n_rejected += 1
        return lin, n_rejected, None

    def update(self, state: Gaussian, lin, parts: Parts | None = None, *,
               sequential: bool = False) -> tuple[Gaussian, UpdateInfo]:
        return _update_screened(state, self.screen(state, lin, parts), sequential)


#: Huber's tuning constant ``k``, the value for which the M-estimate of location (and of a regression with known
#: scale) with ``ψ(r) = max(−k, min(k, r))`` has 95 % asymptotic efficiency at the normal distribution (Holland &
#: Welsch 1977, "Robust regression using iteratively reweighted least-squares", Commun. Stat. Theory Methods 6(9),
#: 813–827; Huber & Ronchetti 2009, *Robust Statistics*, 2nd ed., Wiley). Weight ``w(r) = min(1, k / |r|)``.
#: Only the constant is borrowed: here a residual is scaled by ``√S_ii`` (prior and noise), and after the first
#: pass the residuals are the posterior's, whose spread is below that scale, so the 95 % efficiency is not claimed
#: for this update (it down-weights less than the location estimate would, most when the prior is wide).
HUBER_K = 1.345
#: The Cauchy (Lorentzian) tuning constant ``c`` of the same 95 % efficiency in the location case (Holland &
#: Welsch 1977); the same caveat as :data:`HUBER_K` applies.
#: Weight ``w(r) = 1 / (1 + (r / c)²)``.
CAUCHY_C = 2.3849
#: Reweighted updates per epoch of :class:`Robust`: weights from the prior's residuals, then twice from the
#: posterior's. On the
#: generated 2-D range case of ``tests/filters/test_robust_update.py`` (4 anchors, σ = 10 cm, 10 % of ranges
#: 1–5 m long) three Huber passes leave each epoch's position about 1–2 mm RMS from the converged one (200
#: passes), two about 3–5 mm; the test checks three against 50 passes.
ROBUST_ITERATIONS = 3

_ROBUST_CONSTANTS = {"huber": HUBER_K, "cauchy": CAUCHY_C}


@dataclass(frozen=True)
class Robust:
    """M-estimation update: Huber (or Cauchy) weights on each component's normalised residual, ``R`` inflated.

    Each of ``iterations`` passes (default :data:`ROBUST_ITERATIONS`) reweights and redoes the update
    from the prior ``(x⁻, P⁻)``::

        r_i = (y − H (x_j − x⁻))_i / √S_ii,     S = H P⁻ Hᵀ + R,   y = z − h(x⁻)
        w_i = min(1, k / |r_i|)  (Huber)   or   1 / (1 + (r_i / c)²)  (Cauchy)
        R_w = D R D,  D = diag(1 / √w_i);   x_{j+1}, P_{j+1} = Joseph update of (x⁻, P⁻) with R_w

    starting at ``x_0 = x⁻``, so the first weights come from the epoch's normalised innovation
    ``y_i / √S_ii`` (the statistic :class:`ChiSquarePerMeasurement` tests) and the later ones from the
    residuals left by the last posterior. The measurement stays linearised at ``x⁻``.

    Whitening: per component, by the square root of the diagonal of the model's ``S`` (fixed over the
    passes), not by a Cholesky factor: a weight then belongs to one measured component (one TDoA, one
    range) and an outlier in one stays in its own row; correlated ``R`` (TDoAs sharing a reference)
    is scaled row and column (``D R D``), so its correlation coefficients are kept. For a diagonal
    ``R`` and Huber weights the passes are iteratively reweighted least squares for the convex cost
    ``½ (x − x⁻)ᵀ (P⁻)⁻¹ (x − x⁻) + Σ_i (S_ii / R_ii) ρ_k(e_i / √S_ii)``, ``e = y − H (x − x⁻)``, Huber's
    ``ρ_k(r) = r²/2`` for ``|r| ≤ k`` and ``k|r| − k²/2`` beyond (``w = ψ/r``): the Gaussian cost
    for residuals within ``k √S_ii``, linear beyond, so one residual's pull on the state is bounded;
    :data:`ROBUST_ITERATIONS` passes approach its minimum. A very large ``k`` makes every weight 1 and
    the update :func:`ungated_update` exactly.

    Covariance reported: the Joseph-form posterior of the last pass, i.e. with the *inflated* ``R_w``
    — what the weighted least-squares update claims, not a sandwich (robust) covariance. For
    Gaussian data it is a little larger than the plain update's (its NEES is checked against the χ²
    band in the tests); for down-weighted outliers it is the covariance of a measurement trusted less.
    It does not cover the bias one-sided (NLOS-like) outliers leave: Huber's pull is bounded but not
    zero, so with many of them its NEES runs above the χ² band (on the generated range case with 10 %
    of ranges 1–5 m long, seeds 5–14, mean position NEES about 3.1 for 2 degrees of freedom, Cauchy's about 2.0).
    On that case the per-measurement χ² gate (:class:`ChiSquarePerMeasurement`) does better than either: RMSE
    0.104 m with NEES 1.96, against Huber's 0.138 m and Cauchy's 0.112 m (``tests/filters/test_robust_update.py``
    holds the order and Huber's over-confidence).

    Parameters
    ----------
    kind
        ``"huber"`` (default: a convex cost with one minimum, and a bounded pull for any outlier) or
        ``"cauchy"`` (redescending: a far outlier's weight goes to 0 as ``(c/r)²``, but the cost is not
        convex and the passes converge more slowly for exactly those components).
    k
        Tuning constant; None (default): the kind's declared constant (95 % efficiency in the location case),
        :data:`HUBER_K` or
        :data:`CAUCHY_C` (``inf`` is allowed: every weight 1).
    iterations
        Reweighted updates per epoch, at least 1.
    gate
        A χ² policy screening the epoch first (``Robust(gate=ChiSquareEpoch(0.9999))`` is "both": an
        epoch the gate rejects is ``GATED``, the rows it keeps get the robust update); default
        :class:`NoGate` (robust update of every row). Its ``max_gated`` release rule, ``prob`` and
        ``needs_subsets`` are this policy's. A released epoch (``active`` False) gets the filter's
        :func:`ungated_update`, as with any gate.

    ``UpdateInfo``: status ``UPDATED``, ``dof`` the rows used, ``nis`` and ``innovation`` those of the
    model (``yᵀ S⁻¹ y`` with the uninflated ``S`` of the rows used, so NIS consistency and
    ``log_likelihood`` read the filter's own prediction, not the reweighted one), ``weights`` the
    weights of the last pass, ``n_downweighted`` the rows whose ``|r_i|`` exceeded ``k`` in that pass,
    ``n_rejected`` the rows the gate removed; ``nis_rows`` None. A pass whose weights equal the pass
    before's ends the loop (it would give the same posterior).
    """

    kind: str = "huber"
    k: float | None = None
    iterations: int = ROBUST_ITERATIONS
    gate: GatePolicy = field(default_factory=NoGate)

    def __post_init__(self):
        if self.kind not in _ROBUST_CONSTANTS:
            raise ValueError(f"Robust.kind must be one of {sorted(_ROBUST_CONSTANTS)}, got {self.kind!r}")
        k = _ROBUST_CONSTANTS[self.kind] if self.k is None else self.k
        if not isinstance(k, numbers.Real) or isinstance(k, (bool, np.bool_)) or not k > 0:
            raise ValueError(f"Robust.k must be a positive number (inf allowed) or None, got {self.k!r}")
        object.__setattr__(self, "k", float(k))
        if not _is_int(self.iterations, 1):
            raise ValueError(f"Robust.iterations must be an integer >= 1, got {self.iterations!r}")
        if not hasattr(self.gate, "screen"):
            raise ValueError(f"Robust.gate must be a policy with screen() (NoGate, ChiSquareEpoch, "
                             f"ChiSquarePerMeasurement, AnchorDropping), got {self.gate!r}")

    @property
    def max_gated(self) -> int:
        """The screening gate's ``max_gated``."""
        return self.gate.max_gated

    @property
    def needs_subsets(self) -> bool:
        """The screening gate's ``needs_subsets``."""
        return self.gate.needs_subsets

    @property
    def prob(self) -> float | None:
        """The screening gate's ``prob`` (None for :class:`NoGate`)."""
        return getattr(self.gate, "prob", None)

    def active(self, n_gated: int) -> bool:
        """The screening gate's release rule."""
        return self.gate.active(n_gated)

    def weights(self, r: np.ndarray) -> np.ndarray:
        """Weights of normalised residuals ``r (m,)``, in (0, 1]."""
        a = np.abs(np.asarray(r, float))
        if self.kind == "cauchy":
            return 1.0 / (1.0 + (a / self.k) ** 2)
        w = np.ones(a.shape)
        far = a > self.k
        w[far] = self.k / a[far]
        return w

    def update(self, state: Gaussian, lin, parts: Parts | None = None, *,
               sequential: bool = False) -> tuple[Gaussian, UpdateInfo]:
        """The screening gate's decision, then the reweighted update of the rows it keeps."""
        lin, n_rejected, gated = self.gate.screen(state, lin, parts)
        if lin is None:
            return state, gated
        inn = _innovation(state, lin)
        scale = np.sqrt(np.diag(inn.S))
        x, w_last = state.x, None
        for _ in range(self.iterations):
            r = (inn.y - lin.H @ (x - state.x)) / scale
            w = self.weights(r)
            if w_last is not None and np.array_equal(w, w_last):
                break                            # the same weights would give the same posterior again
            d = 1.0 / np.sqrt(w)
            post, _, _ = _update(state, replace(lin, R=lin.R * np.outer(d, d)), sequential)
            x, w_last = post.x, w
        return post, UpdateInfo(inn.nis, lin.z.size, EstimateStatus.UPDATED, n_rejected, innovation=inn,
                                n_downweighted=int(np.sum(np.abs(r) > self.k)), weights=w)


def gate_policy(owner: str, gate, gate_prob: float | None, max_gated: int, default: tuple) -> GatePolicy:
    """The policy a filter with fields ``gate``, ``gate_prob`` and ``max_gated`` runs with.

    ``gate`` itself when given (then ``gate_prob``/``max_gated`` must be at their defaults,
    ``default = (gate_prob, max_gated)``, or equal to the policy's own ``prob``/``max_gated``);
    otherwise the one ``gate_prob`` and ``max_gated`` stand for (:func:`gate_from_prob`).
    """
    if gate is None:
        return gate_from_prob(gate_prob, max_gated, owner)
    if not all(hasattr(gate, a) for a in ("update", "active", "max_gated", "needs_subsets")):
        raise ValueError(f"{owner}.gate must be a gate policy (uwbwb.filters.gating), got {gate!r}")
    if (gate_prob, max_gated) not in (tuple(default), (getattr(gate, "prob", None), gate.max_gated)):
        raise ValueError(f"{owner}: give the gate either as gate= or as gate_prob=/max_gated=, not both "
                         f"(gate={gate!r}, gate_prob={gate_prob!r}, max_gated={max_gated!r})")
    return gate


def gate_from_prob(gate_prob: float | None, max_gated: int, owner: str, *, kind=ChiSquareEpoch, **settings):
    """The policy a ``gate_prob`` setting stands for: None → :class:`NoGate`, else ``kind(gate_prob, ...)``."""
    if gate_prob is not None and not _is_prob(gate_prob):
        raise ValueError(f"{owner}.gate_prob must be in (0, 1) or None (no gate), got {gate_prob!r}")
    if not _is_int(max_gated, 0):
        raise ValueError(f"{owner}.max_gated must be an integer >= 0, got {max_gated!r}")
    if gate_prob is None:
        return NoGate(max_gated=max_gated)
    return kind(prob=float(gate_prob), max_gated=max_gated, **settings)
