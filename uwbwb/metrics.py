"""Position errors, their distribution (ECDF, CEP, RMSE), filter consistency (NEES, NIS χ² test)
and the reproduction summary table.

Missing values
--------------
NaN in an error array means "no estimate" (e.g. an epoch multilateration
could not solve). Every statistic raises ``ValueError`` on NaN so that a
missing epoch is never silently ignored; :func:`error_stats` accepts
``nan="omit"`` and then reports how many values it left out (``n_omitted``).
Infinite values are always an error.

Quantile rule
-------------
``cep(err, p)`` is the empirical quantile that inverts the ECDF returned by
:func:`ecdf`: the smallest observed error ``x`` with ``F(x) >= p``, i.e. the
``ceil(p * n)``-th smallest value (numpy's ``method="inverted_cdf"``). It is
always one of the observed errors, and a CEP marker drawn on the ECDF sits
exactly on the curve.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd
from scipy.stats import chi2

from .types import Trajectory
from .validate import probability

__all__ = [
    "ErrorSeries", "Summary", "cep", "cep50", "cep95", "ecdf", "epoch_summary", "error_stats", "errors_vs_truth",
    "nees", "nis_consistency", "position_error_m", "rmse", "block_bootstrap_difference",
    "Headline",
]


# --------------------------------------------------------------------------- errors


def position_error_m(est_pos_m, true_pos_m, *, horizontal: bool = True) -> np.ndarray:
    """Euclidean position error per epoch.

    Parameters
    ----------
    est_pos_m, true_pos_m
        Estimated and true positions, shape ``(T, 2)`` or ``(T, 3)``, metres.
    horizontal
        If True, use ``x, y`` only (the two arrays may then differ in
        dimension); otherwise both must have the same dimension.

    Returns
    -------
    numpy.ndarray
        Errors, shape ``(T,)``, metres. NaN rows in either input give NaN.
    """
    est = np.asarray(est_pos_m, dtype=float)
    true = np.asarray(true_pos_m, dtype=float)
    for name, a in (("est_pos_m", est), ("true_pos_m", true)):
        if a.ndim != 2 or a.shape[1] not in (2, 3):
            raise ValueError(f"{name} must have shape (T, 2) or (T, 3), got {a.shape}")
    if est.shape[0] != true.shape[0]:
        raise ValueError(f"est_pos_m has {est.shape[0]} epochs, true_pos_m has {true.shape[0]}")
    if horizontal:
        est, true = est[:, :2], true[:, :2]
    elif est.shape[1] != true.shape[1]:
        raise ValueError(f"3-D errors need positions of equal dimension, got {est.shape[1]} and "
                         f"{true.shape[1]} (use horizontal=True for x, y only)")
    return np.linalg.norm(est - true, axis=1)


@dataclass(frozen=True)
class ErrorSeries:
    """Errors of an estimate against interpolated truth (see :func:`errors_vs_truth`).

    Attributes
    ----------
    name
        The estimate's name (legend label).
    t_s
        Times of the compared epochs, shape ``(N,)``, seconds.
    err_m
        Errors at those times, shape ``(N,)``, metres (NaN where the estimate is NaN).
    n_outside
        Estimate epochs left out because they lie outside the truth's time span.
    n_in_gap
        Estimate epochs left out because the bracketing truth samples are more
        than ``max_gap_s`` apart.
    horizontal
        Whether the errors are horizontal (x, y) only.
    """

    name: str
    t_s: np.ndarray
    err_m: np.ndarray
    n_outside: int = 0
    n_in_gap: int = 0
    horizontal: bool = True

    def __post_init__(self):
        t = np.array(self.t_s, dtype=float)
        e = np.array(self.err_m, dtype=float)
        if t.ndim != 1 or e.shape != t.shape:
            raise ValueError(f"t_s and err_m must be 1-D of equal length, got {t.shape} and {e.shape}")
        t.setflags(write=False)
        e.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "err_m", e)

    def __len__(self) -> int:
        return self.t_s.size

    @property
    def n_excluded(self) -> int:
        """Estimate epochs without a truth reference (outside the span or in a gap)."""
        return self.n_outside + self.n_in_gap

    def stats(self, *, nan: str = "raise") -> dict:
        """:func:`error_stats` of :attr:`err_m`, plus ``n_excluded``."""
        return {**error_stats(self.err_m, nan=nan), "n_excluded": self.n_excluded}

    def report(self) -> str:
        """One line saying how many epochs were compared and why others were not."""
        parts = [f"{self.name}: {len(self)} epochs compared with truth"]
        if self.n_outside:
            parts.append(f"{self.n_outside} outside the truth time span excluded")
        if self.n_in_gap:
            parts.append(f"{self.n_in_gap} in truth gaps excluded")
        n_nan = int(np.count_nonzero(np.isnan(self.err_m)))
        if n_nan:
            parts.append(f"{n_nan} without an estimate (NaN)")
        return "; ".join(parts)


def errors_vs_truth(estimate: Trajectory, truth: Trajectory, *, horizontal: bool = True,
                    max_gap_s: float | None = None) -> ErrorSeries:
    """Errors of ``estimate`` at its own times against linearly interpolated truth.

    Truth is never extrapolated: estimate epochs before the first or after the
    last truth sample are excluded and counted (``n_outside``). With
    ``max_gap_s``, epochs falling between two truth samples more than
    ``max_gap_s`` apart (e.g. a motion-capture dropout) are excluded and counted
    too (``n_in_gap``); epochs coinciding with a truth sample are always kept.

    Parameters
    ----------
    estimate, truth
        Trajectories on the same clock and frame.
    horizontal
        Horizontal (x, y) errors if True, else 3-D (both must be 3-D).
    max_gap_s
        Largest truth sampling gap to interpolate across, seconds; None = any.

    Returns
    -------
    ErrorSeries
        Compared times and errors, with the exclusion counts.
    """
    if not isinstance(estimate, Trajectory) or not isinstance(truth, Trajectory):
        raise ValueError("estimate and truth must be uwbwb.Trajectory objects")
    if len(truth) < 1:
        raise ValueError("truth is empty")
    if max_gap_s is not None and not (np.isfinite(max_gap_s) and max_gap_s > 0):
        raise ValueError(f"max_gap_s must be positive, got {max_gap_s!r}")
    t = estimate.t_s
    tt = truth.t_s
    inside = (t >= tt[0]) & (t <= tt[-1])
    keep = inside.copy()
    n_in_gap = 0
    if max_gap_s is not None and len(truth) > 1:
        i = np.clip(np.searchsorted(tt, t, side="right"), 1, tt.size - 1)
        exact = tt[np.clip(np.searchsorted(tt, t), 0, tt.size - 1)] == t
        in_gap = inside & ~exact & (tt[i] - tt[i - 1] > max_gap_s)
        n_in_gap = int(np.count_nonzero(in_gap))
        keep &= ~in_gap
    true_pos = truth.interp(t[keep])
    err = position_error_m(estimate.pos_m[keep], true_pos, horizontal=horizontal)
    return ErrorSeries(estimate.name, t[keep], err, int(np.count_nonzero(~inside)), n_in_gap, horizontal)


# --------------------------------------------------------------------------- statistics


def _errors(err, *, nan: str = "raise", nonneg: bool = True) -> tuple[np.ndarray, int]:
    if nan not in ("raise", "omit"):
        raise ValueError(f"nan must be 'raise' or 'omit', got {nan!r}")
    e = np.asarray(getattr(err, "err_m", err), dtype=float)
    if e.ndim != 1:
        raise ValueError(f"errors must be 1-D, got shape {e.shape}")
    if np.any(np.isinf(e)):
        raise ValueError("errors contain infinite values")
    missing = np.isnan(e)
    n_nan = int(np.count_nonzero(missing))
    if n_nan and nan == "raise":
        raise ValueError(f"errors contain {n_nan} NaN value(s) of {e.size}; drop them explicitly or use "
                         f"error_stats(..., nan='omit'), which reports how many were left out")
    e = e[~missing]
    if e.size == 0:
        raise ValueError("no errors to summarise (empty input)")
    if nonneg and np.any(e < 0):
        raise ValueError("position errors must be non-negative (radial errors)")
    return e, n_nan


def ecdf(err) -> tuple[np.ndarray, np.ndarray]:
    """Empirical cumulative distribution function.

    Parameters
    ----------
    err
        Errors, shape ``(N,)`` (signed values allowed), no NaN.

    Returns
    -------
    x : numpy.ndarray
        Sorted errors, shape ``(N,)``.
    F : numpy.ndarray
        ``F[k] = (k + 1) / N``, the fraction of errors ``<= x[k]``, shape ``(N,)``.
    """
    e, _ = _errors(err, nonneg=False)
    return np.sort(e), np.arange(1, e.size + 1) / e.size


def cep(err, p: float) -> float:
    """Circular error probable at level ``p``: the empirical ``p``-quantile of radial errors.

    Uses the ECDF-inverting rule of the module docstring: the ``ceil(p * N)``-th
    smallest error.

    Parameters
    ----------
    err
        Radial errors, shape ``(N,)``, metres, non-negative, no NaN.
    p
        Probability level in ``(0, 1]``.

    Returns
    -------
    float
        The error radius, metres.
    """
    if not (isinstance(p, numbers.Real) and 0 < p <= 1):
        raise ValueError(f"p must be a probability in (0, 1], got {p!r}")
    e, _ = _errors(err)
    k = math.ceil(round(float(p) * e.size, 9))   # rounding guards 0.95 * 100 = 95.00000000000001
    return float(np.partition(e, k - 1)[k - 1])


def cep50(err) -> float:
    """:func:`cep` at 50 %, metres."""
    return cep(err, 0.5)


def cep95(err) -> float:
    """:func:`cep` at 95 %, metres."""
    return cep(err, 0.95)


def rmse(err) -> float:
    """Root mean square of ``err`` (shape ``(N,)``, signed allowed, no NaN)."""
    e, _ = _errors(err, nonneg=False)
    return float(np.sqrt(np.mean(e * e)))


def error_stats(err, *, nan: str = "raise") -> dict:
    """Summary statistics of radial errors.

    Parameters
    ----------
    err
        Radial errors, shape ``(N,)``, metres (an :class:`ErrorSeries` works too).
    nan
        ``"raise"`` (default): NaN is a ValueError. ``"omit"``: NaN values are
        left out and counted in ``n_omitted``.

    Returns
    -------
    dict
        ``n`` (values used), ``n_omitted``, ``mean``, ``median`` (numpy's, the
        average of the middle two for even ``n``), ``rmse``, ``cep50``, ``cep95``
        (rule of :func:`cep`), ``max``; metres.
    """
    e, n_nan = _errors(err, nan=nan)
    return {"n": int(e.size), "n_omitted": n_nan, "mean": float(np.mean(e)), "median": float(np.median(e)),
            "rmse": rmse(e), "cep50": cep50(e), "cep95": cep95(e), "max": float(np.max(e))}


def epoch_summary(epochs: pd.DataFrame, *, by: str = "estimator", order: Sequence[str] = ()) -> pd.DataFrame:
    """Coverage beside accuracy per estimator, from an epoch table scored on common epochs.

    Parameters
    ----------
    epochs
        One row per estimator and scored epoch: ``by`` and ``err_m`` (NaN = the
        estimator produced no position at that epoch), metres.
    by
        The column naming the estimator.
    order
        Estimators listed first, in this order; the others follow in order of appearance.

    Returns
    -------
    pandas.DataFrame
        Indexed by estimator: ``n_epochs``, ``coverage`` (fraction with a position),
        ``median_m`` and ``p90_m`` over the covered epochs, and ``p90_failed_counted_m``
        -- the 90th percentile (inverted CDF) when an epoch without a position counts
        as an unbounded error (``inf`` below 90 % coverage).
    """
    rows = []
    names = list(dict.fromkeys(epochs[by]))
    for h in [h for h in order if h in names] + [h for h in names if h not in order]:
        e = epochs.loc[epochs[by] == h, "err_m"].to_numpy(float)
        ok = np.isfinite(e)
        rows.append({by: h, "n_epochs": e.size, "coverage": ok.mean() if e.size else np.nan,
                     "median_m": np.median(e[ok]) if ok.any() else np.nan,
                     "p90_m": np.quantile(e[ok], 0.9) if ok.any() else np.nan,
                     "p90_failed_counted_m": (np.quantile(np.where(ok, e, np.inf), 0.9, method="inverted_cdf")
                                                 if e.size else np.nan)})
    return pd.DataFrame(rows).set_index(by)


# --------------------------------------------------------------------------- consistency
# The one place where a filter's covariances are held to its errors (NEES) and its innovations (NIS):
# every run type (``KalmanRun``, ``FusionRun``, the set-noise ``FilterRun``), the scoreboard and the
# experiments call these two functions.


def nees(err, cov, where=None) -> np.ndarray:
    """Normalised estimation error squared ``eᵀ P⁻¹ e`` per epoch.

    Parameters
    ----------
    err
        Estimation errors, shape ``(T, d)`` (estimate minus truth).
    cov
        The estimator's own covariances of those components, shape ``(T, d, d)``.
    where
        Epochs to evaluate, bool ``(T,)`` (default: all); epochs whose error or covariance is
        not finite are left out as well.

    Returns
    -------
    numpy.ndarray
        Shape ``(T,)``; χ²(d)-distributed when the estimator is consistent; NaN where not evaluated.
    """
    e, P = np.asarray(err, float), np.asarray(cov, float)
    if e.ndim != 2 or P.shape != e.shape + (e.shape[1],):
        raise ValueError(f"nees: err (T, d) and cov (T, d, d) expected, got {e.shape} and {P.shape}")
    T = e.shape[0]
    ok = np.all(np.isfinite(e), axis=1) & np.all(np.isfinite(P), axis=(1, 2))
    if where is not None:
        ok &= np.asarray(where, bool)
    out = np.full(T, np.nan)
    out[ok] = np.einsum("ti,ti->t", e[ok], np.linalg.solve(P[ok], e[ok][..., None])[..., 0])
    return out


def nis_consistency(nis, dof, prob: float = 0.95) -> dict:
    """χ² test of a filter's NIS over its updates (also of NEES values, with ``dof`` the state size).

    Under correct models the sum of the NIS over ``n`` updates is χ²(Σ dof). The verdict
    compares that sum with its central ``prob`` interval: above it the filter is
    *over-confident* (its covariances are too small for its errors), below it
    *under-confident*. Epochs with ``dof == 0`` or a non-finite value (nothing used) are
    left out.

    Returns
    -------
    dict
        ``n`` updates, ``mean_nis_over_dof`` (≈ 1 when consistent), ``fraction_inside``
        (share of single updates inside their own central ``prob`` interval),
        ``sum_nis``, ``sum_dof``, the interval ``sum_lo``/``sum_hi`` and ``verdict``
        (``"consistent"``, ``"over-confident"``, ``"under-confident"`` or ``"no updates"``).
    """
    probability("prob", prob)
    nis, dof = np.asarray(nis, float), np.asarray(dof, int)
    ok = (dof > 0) & np.isfinite(nis)
    if not ok.any():
        return {"n": 0, "mean_nis_over_dof": np.nan, "fraction_inside": np.nan, "sum_nis": np.nan,
                "sum_dof": 0, "sum_lo": np.nan, "sum_hi": np.nan, "verdict": "no updates"}
    nis, dof = nis[ok], dof[ok]
    a = (1 - prob) / 2
    inside = (nis >= chi2.ppf(a, dof)) & (nis <= chi2.ppf(1 - a, dof))
    total = int(dof.sum())
    lo, hi, s = float(chi2.ppf(a, total)), float(chi2.ppf(1 - a, total)), float(nis.sum())
    verdict = "over-confident" if s > hi else "under-confident" if s < lo else "consistent"
    return {"n": int(ok.sum()), "mean_nis_over_dof": s / total, "fraction_inside": float(inside.mean()),
            "sum_nis": s, "sum_dof": total, "sum_lo": lo, "sum_hi": hi, "verdict": verdict}


def block_bootstrap_difference(err_a: np.ndarray, err_b: np.ndarray, *, rng: np.random.Generator,
                               n_boot: int = 2000, n_blocks: int = 20, level: float = 0.95) -> dict:
    """``RMSE(a) − RMSE(b)`` on paired epochs and its block-bootstrap interval (non-overlapping blocks).

    Parameters
    ----------
    err_a, err_b
        Error norms of two methods on the same epochs, shape ``(n,)``, in time order, m.
    n_blocks
        The run is cut into this many blocks of consecutive epochs; a replicate draws
        ``n_blocks`` of them with replacement (pairs stay together).

    Returns
    -------
    dict
        ``diff_m``, ``lo_m``, ``hi_m`` (NaN interval with fewer than ``2·n_blocks`` epochs), ``n``.
    """
    a, b = np.asarray(err_a, float), np.asarray(err_b, float)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"paired errors must be 1-D of the same length, got {a.shape} and {b.shape}")
    n = a.size
    diff = float(np.sqrt(np.mean(a ** 2)) - np.sqrt(np.mean(b ** 2))) if n else np.nan
    if n < 2 * n_blocks:
        return {"diff_m": diff, "lo_m": np.nan, "hi_m": np.nan, "n": n}
    edges = np.linspace(0, n, n_blocks + 1).astype(int)
    sa = np.add.reduceat(a ** 2, edges[:-1])
    sb = np.add.reduceat(b ** 2, edges[:-1])
    cnt = np.diff(edges)
    pick = rng.integers(0, n_blocks, (n_boot, n_blocks))
    N = cnt[pick].sum(axis=1)
    d = np.sqrt(sa[pick].sum(axis=1) / N) - np.sqrt(sb[pick].sum(axis=1) / N)
    lo, hi = np.quantile(d, [(1 - level) / 2, (1 + level) / 2])
    return {"diff_m": diff, "lo_m": float(lo), "hi_m": float(hi), "n": n}


# --------------------------------------------------------------------------- summary table


def _real(value, what: str, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{what} must be a real number, got {value!r}")
    v = float(value)
    if allow_none and math.isnan(v):
        return None
    if not math.isfinite(v):
        raise ValueError(f"{what} must be finite, got {value!r}")
    return v


class Summary:
    """Headline numbers of one notebook, for the reproduction report.

    Every row says what kind of number it is and which mode produced it:

    ``kind``
        ``"reproduced"`` — came out of the method; ``"target"`` — a simulator
        parameter was chosen to hit it (agreement with the paper is by
        construction); ``"input"`` — taken from the paper (or follows directly
        from a value taken from it).
    ``mode``
        ``"FAST"`` (small CI-sized experiments: smoke-test numbers) or ``"full"``.

    Parameters
    ----------
    notebook
        Notebook name, e.g. ``"00_quickstart"``.
    fast
        The notebook's ``FAST`` parameter: the mode of every row.

    Examples
    --------
    >>> s = Summary("00_quickstart", fast=False)
    >>> s.add(quantity="CEP95, tag t0, raw multilateration", value=0.31, unit="m",
    ...       paper_value=None, data="lias-planar-uwb/fast", kind="reproduced")
    >>> list(s.frame().columns)
    ['notebook', 'quantity', 'value', 'unit', 'paper_value', 'data', 'kind', 'mode']
    >>> s.frame()["mode"].tolist()
    ['full']
    """

    COLUMNS = ("notebook", "quantity", "value", "unit", "paper_value", "data", "kind", "mode")
    #: Allowed values of ``kind``.
    KINDS = ("reproduced", "target", "input")
    #: Allowed values of ``mode``: under ``FAST=True`` and otherwise.
    MODES = ("FAST", "full")

    def __init__(self, notebook: str, *, fast: bool):
        if not isinstance(notebook, str) or not notebook.strip():
            raise ValueError(f"notebook must be a non-empty string, got {notebook!r}")
        if not isinstance(fast, (bool, np.bool_)):
            raise ValueError(f"fast must be True or False (the notebook's FAST parameter), got {fast!r}")
        self.notebook = notebook
        self.mode = "FAST" if fast else "full"
        self._rows: list[dict] = []

    def __len__(self) -> int:
        return len(self._rows)

    def __repr__(self) -> str:
        return f"Summary({self.notebook!r}, {len(self)} rows, mode {self.mode})"

    def add(self, *, quantity: str, value, unit: str, data: str, kind: str, paper_value=None) -> None:
        """Record one headline number.

        Parameters
        ----------
        quantity
            What was measured, specific enough to be unique with ``data``
            (e.g. ``"CEP95, tag t0, raw multilateration"``).
        value
            The value: a finite real number (numpy scalars accepted).
        unit
            Unit of ``value`` and ``paper_value`` (e.g. ``"m"``, ``"cm"``, ``"%"``, ``""``).
        data
            ``"synthetic"`` or ``"dataset/recording"`` (e.g. ``Recording.label``).
        kind
            ``"reproduced"``, ``"target"`` or ``"input"`` (see the class docstring).
        paper_value
            The value the paper reports, or None (NaN is read as None).

        Raises
        ------
        ValueError
            On an invalid field or a repeated ``(quantity, data)`` pair.
        """
        if not isinstance(quantity, str) or not quantity.strip():
            raise ValueError(f"quantity must be a non-empty string, got {quantity!r}")
        v = _real(value, f"value of {quantity!r}")
        pv = _real(paper_value, f"paper_value of {quantity!r}", allow_none=True)
        if not isinstance(unit, str):
            raise ValueError(f"unit of {quantity!r} must be a string, got {unit!r}")
        if not isinstance(data, str) or not (data == "synthetic" or _is_recording_label(data)):
            raise ValueError(f"data of {quantity!r} must be 'synthetic' or 'dataset/recording', got {data!r}")
        if kind not in self.KINDS:
            raise ValueError(f"kind of {quantity!r} must be one of {', '.join(self.KINDS)}, got {kind!r}")
        if any(r["quantity"] == quantity and r["data"] == data for r in self._rows):
            raise ValueError(f"{self.notebook}: quantity {quantity!r} on data {data!r} was already added")
        self._rows.append({"notebook": self.notebook, "quantity": quantity, "value": v, "unit": unit,
                           "paper_value": pv, "data": data, "kind": kind, "mode": self.mode})

    def frame(self) -> pd.DataFrame:
        """The rows as a DataFrame with exactly :attr:`COLUMNS` (``paper_value`` NaN where None)."""
        df = pd.DataFrame(self._rows, columns=list(self.COLUMNS))
        return df.astype({"value": float, "paper_value": float})

    def publish(self, path: str | os.PathLike | None = None) -> pd.DataFrame:
        """Return :meth:`frame` and, if ``path`` is given, also write the rows there.

        The file is a JSON list of objects with the keys of :attr:`COLUMNS`,
        missing ``paper_value`` written as ``null``. Parent directories are created.
        Writing an empty summary is a ValueError (the report needs at least one row).
        """
        if path is not None:
            if not self._rows:
                raise ValueError(f"{self.notebook}: nothing to publish (no rows were added)")
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(self._rows, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        return self.frame()

    @classmethod
    def from_json(cls, path: str | os.PathLike) -> "Summary":
        """Read a file written by :meth:`publish` (rows are validated again)."""
        path = Path(path)
        try:
            rows = json.loads(path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not valid JSON ({exc})") from None
        if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
            raise ValueError(f"{path}: expected a non-empty JSON list of objects")
        for i, r in enumerate(rows):
            if set(r) != set(cls.COLUMNS):
                raise ValueError(f"{path}: row {i} has keys {sorted(r)}, expected {list(cls.COLUMNS)}")
        names = {r["notebook"] for r in rows}
        if len(names) != 1:
            raise ValueError(f"{path}: rows from several notebooks {sorted(map(str, names))}")
        modes = {r["mode"] for r in rows}
        if len(modes) != 1 or not modes <= set(cls.MODES):
            raise ValueError(f"{path}: mode must be one of {', '.join(cls.MODES)} and the same in every row, "
                             f"got {sorted(map(str, modes))}")
        s = cls(rows[0]["notebook"], fast=rows[0]["mode"] == "FAST")
        for r in rows:
            s.add(quantity=r["quantity"], value=r["value"], unit=r["unit"], data=r["data"], kind=r["kind"],
                  paper_value=r["paper_value"])
        return s


def _is_recording_label(data: str) -> bool:
    dataset, _, recording = data.partition("/")
    return bool(dataset.strip()) and bool(recording.strip())


@dataclass(frozen=True)
class Headline:
    """One summary row declared as data: what it is, and how to read its value from an
    experiment's ``facts`` dict (each experiment's ``headlines.py`` lists its rows as these).

    Attributes
    ----------
    quantity, unit
        As in :meth:`Summary.add`.
    kind
        One of :attr:`Summary.KINDS`: *reproduced*, *target* or *input*.
    read
        ``facts → value``.
    paper
        The paper's value where one is comparable (None otherwise).
    """

    quantity: str
    unit: str
    kind: str
    read: Callable[[dict], float]
    paper: float | None = None

    def __post_init__(self):
        if self.kind not in Summary.KINDS:
            raise ValueError(f"Headline.kind must be one of {', '.join(Summary.KINDS)}, got {self.kind!r}")

    def row(self, facts: dict, *, data: str = "synthetic") -> dict:
        """Keyword arguments of :meth:`Summary.add` for this headline, read from ``facts``."""
        return {"quantity": self.quantity, "value": float(self.read(facts)), "unit": self.unit,
                "paper_value": self.paper, "kind": self.kind, "data": data}
