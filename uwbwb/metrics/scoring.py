"""Accuracy on common epochs, coverage beside it: the one scorer of methods compared on equal terms.

Methods are compared on one epoch grid (a tag's epochs, a run's scored epochs). Per method and
epoch there is an error (metres) or none (NaN: the method gave no position there; an infinite error
is an estimate, a diverged one, and stays in the statistics); an optional mask says where truth exists. For each method the scorer keeps

* the epochs with truth (``n_epochs``, the denominator of coverage),
* its *own* epochs: truth and an estimate (``n_scored``; ``coverage = n_scored / n_epochs``),
* the *common* epochs: truth and an estimate of every compared method (``n_common``), the epochs
  on which methods are ranked, so that a method that skips hard epochs is not scored on easy ones,

and computes the statistics asked for on its own epochs, on the common ones, or on every epoch with
truth with a missing estimate counted as an unbounded error (``+inf``). Statistics are callables
(``metrics.rmse``, ``metrics.cep95``, ``np.median``, ...) applied to the selected errors in epoch
order; an empty selection gives NaN.

* :func:`score_epochs` — per-method errors on one grid → :class:`EpochScores`.
* :func:`pool_scores` — several grids (e.g. one per tag) pooled per method, in the given order.
* :func:`errors_on_grid` — errors given on each method's own times put onto one grid by exact time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, Iterator, Mapping, Sequence

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from .errors import ErrorSeries

__all__ = ["EpochScores", "MethodEpochs", "Statistic", "errors_on_grid", "pool_scores", "score_epochs"]

#: A statistic of errors: a 1-D array of errors (metres) in epoch order → one number.
Statistic = Callable[[np.ndarray], float]


def _frozen(name: str, a, dtype) -> np.ndarray:
    out = np.array(a, dtype=dtype)
    if out.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {out.shape}")
    out.setflags(write=False)
    return out


def _apply(stats: Mapping[str, Statistic] | None, err_m: np.ndarray) -> dict[str, float]:
    return {k: (f(err_m) if err_m.size else np.nan) for k, f in (stats or {}).items()}


@dataclass(frozen=True)
class MethodEpochs:
    """One method's errors on its epoch grid, with the epochs it is scored on.

    Attributes
    ----------
    name
        The method's label.
    err_m
        Error per epoch, shape ``(T,)``, metres; NaN where the method gave no position (an
        infinite error is an estimate).
    truth
        Epochs where truth exists, bool ``(T,)``.
    common
        The common epochs: truth and an estimate of every compared method, bool ``(T,)``; a subset
        of :attr:`scored`.
    scored
        The method's own epochs: truth and an estimate, bool ``(T,)`` (derived, read-only).
    """

    name: str
    err_m: np.ndarray
    truth: np.ndarray
    common: np.ndarray
    scored: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        e = _frozen(f"{self.name}: err_m", self.err_m, float)
        for attr in ("truth", "common"):
            a = _frozen(f"{self.name}: {attr}", getattr(self, attr), bool)
            if a.shape != e.shape:
                raise ValueError(f"{self.name}: {attr} has shape {a.shape}, err_m has {e.shape}")
            object.__setattr__(self, attr, a)
        object.__setattr__(self, "err_m", e)
        scored = self.truth & ~np.isnan(e)              # the method's own epochs: truth and an estimate
        scored.setflags(write=False)
        object.__setattr__(self, "scored", scored)
        if np.any(self.common & ~self.scored):
            raise ValueError(f"{self.name}: a common epoch must have truth and an estimate of this method")

    @property
    def n_epochs(self) -> int:
        """Epochs with truth (the denominator of :attr:`coverage`)."""
        return int(np.count_nonzero(self.truth))

    @property
    def n_scored(self) -> int:
        """Epochs with truth and an estimate."""
        return int(np.count_nonzero(self.scored))

    @property
    def n_common(self) -> int:
        """Common epochs."""
        return int(np.count_nonzero(self.common))

    @property
    def coverage(self) -> float:
        """Share of the epochs with truth where the method gave a position (NaN without such epochs)."""
        return self.n_scored / self.n_epochs if self.n_epochs else np.nan

    @property
    def own_m(self) -> np.ndarray:
        """Errors on the method's own epochs, ``(n_scored,)``, metres, in epoch order."""
        return self.err_m[self.scored]

    @property
    def common_m(self) -> np.ndarray:
        """Errors on the common epochs, ``(n_common,)``, metres, in epoch order."""
        return self.err_m[self.common]

    @property
    def failed_counted_m(self) -> np.ndarray:
        """Errors on every epoch with truth, ``+inf`` where the method gave no position, ``(n_epochs,)``."""
        return np.where(self.scored, self.err_m, np.inf)[self.truth]

    def stats(self, *, own: Mapping[str, Statistic] | None = None, common: Mapping[str, Statistic] | None = None,
              failed_counted: Mapping[str, Statistic] | None = None) -> dict[str, float]:
        """Statistics by name: ``own`` on :attr:`own_m`, ``common`` on :attr:`common_m`,
        ``failed_counted`` on :attr:`failed_counted_m` (NaN where the selection is empty)."""
        return {**_apply(own, self.own_m), **_apply(common, self.common_m),
                **_apply(failed_counted, self.failed_counted_m)}


@dataclass(frozen=True)
class EpochScores:
    """Every compared method's :class:`MethodEpochs`, in order (see the module docstring).

    Attributes
    ----------
    methods
        One entry per method, names unique.
    """

    methods: tuple[MethodEpochs, ...]

    def __post_init__(self):
        object.__setattr__(self, "methods", tuple(self.methods))
        names = self.names
        if len(set(names)) != len(names):
            raise ValueError(f"method names must be unique, got {list(names)}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.methods)

    def __getitem__(self, name: str) -> MethodEpochs:
        for m in self.methods:
            if m.name == name:
                return m
        raise KeyError(f"no method {name!r}; methods {list(self.names)}")

    def __iter__(self) -> Iterator[MethodEpochs]:
        return iter(self.methods)

    def __len__(self) -> int:
        return len(self.methods)

    def table(self, *, own: Mapping[str, Statistic] | None = None, common: Mapping[str, Statistic] | None = None,
              failed_counted: Mapping[str, Statistic] | None = None, index: str = "method") -> pd.DataFrame:
        """One row per method: ``n_epochs``, ``n_scored``, ``coverage``, ``n_common`` and the
        statistics of :meth:`MethodEpochs.stats` (column = the statistic's name), indexed by ``index``."""
        rows = [{index: m.name, "n_epochs": m.n_epochs, "n_scored": m.n_scored, "coverage": m.coverage,
                 "n_common": m.n_common, **m.stats(own=own, common=common, failed_counted=failed_counted)}
                for m in self.methods]
        return pd.DataFrame(rows).set_index(index)


def score_epochs(err_m: Mapping[str, np.ndarray], truth: np.ndarray | Mapping[str, np.ndarray] | None = None, *,
                 compare: bool = True) -> EpochScores:
    """Score methods on one epoch grid: their own epochs, the common epochs and coverage.

    Parameters
    ----------
    err_m
        Method → error per epoch, shape ``(T,)``, metres; NaN where the method
        gave no position.
    truth
        Epochs where truth exists, bool ``(T,)``, one mask for all or one per method (every key of
        ``err_m``); None: every epoch.
    compare
        True: the methods share the grid and the common epochs are those where every method has truth
        and an estimate. False: each method is on a grid of its own (lengths may differ) and compared
        with nothing (its common epochs are its own).

    Returns
    -------
    EpochScores
        The methods in the order of ``err_m``.
    """
    errs = {k: _frozen(f"{k}: err_m", v, float) for k, v in err_m.items()}
    if isinstance(truth, Mapping):
        if set(truth) != set(errs):
            raise ValueError(f"truth masks given for {sorted(truth)}, errors for {sorted(errs)}")
        masks = {k: _frozen(f"{k}: truth", truth[k], bool) for k in errs}
    elif truth is None:
        masks = {k: np.ones(e.shape, bool) for k, e in errs.items()}
    else:
        t = _frozen("truth", truth, bool)
        masks = {k: t for k in errs}
    for k, e in errs.items():
        if masks[k].shape != e.shape:
            raise ValueError(f"{k}: truth mask has shape {masks[k].shape}, err_m has {e.shape}")
    scored = {k: masks[k] & ~np.isnan(e) for k, e in errs.items()}
    if compare and errs:
        sizes = {k: e.size for k, e in errs.items()}
        if len(set(sizes.values())) > 1:
            raise ValueError(f"compared methods must share one epoch grid, got lengths {sizes} "
                             "(errors_on_grid puts errors on one grid by time)")
        common = np.logical_and.reduce(list(scored.values()))
        return EpochScores(tuple(MethodEpochs(k, e, masks[k], common) for k, e in errs.items()))
    return EpochScores(tuple(MethodEpochs(k, e, masks[k], scored[k]) for k, e in errs.items()))


def pool_scores(parts: Sequence[EpochScores]) -> EpochScores:
    """Pool several grids (e.g. one per tag) per method: each method's epochs concatenated in the order
    of ``parts``, over the parts it appears in; its common epochs stay those of each part.

    Returns
    -------
    EpochScores
        Methods in order of first appearance.
    """
    pieces: dict[str, list[MethodEpochs]] = {}
    for part in parts:
        for m in part:
            pieces.setdefault(m.name, []).append(m)
    return EpochScores(tuple(
        MethodEpochs(k, *(np.concatenate([getattr(m, f) for m in ms]) for f in ("err_m", "truth", "common")))
        for k, ms in pieces.items()))


def errors_on_grid(series: Mapping[str, ErrorSeries]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Errors given on each method's own times, put onto one grid by exact time.

    Parameters
    ----------
    series
        Method → its errors (:class:`~uwbwb.metrics.ErrorSeries`, or anything with ``t_s`` strictly
        increasing, seconds, and ``err_m``, metres, NaN = no position).

    Returns
    -------
    t_s : numpy.ndarray
        The grid: every time of any series, sorted, ``(T,)``, seconds.
    err_m : dict
        Method → errors on the grid, ``(T,)``, metres; NaN at the times the method does not have.
    """
    if not series:
        raise ValueError("no error series to put on a grid")
    for k, s in series.items():
        if np.any(np.diff(s.t_s) <= 0):
            raise ValueError(f"{k}: t_s must be strictly increasing")
    t = series[next(iter(series))].t_s
    for s in series.values():
        t = np.union1d(t, s.t_s)
    t = np.asarray(t, float)
    out = {}
    for k, s in series.items():
        e = np.full(t.size, np.nan)
        e[np.searchsorted(t, s.t_s)] = s.err_m
        out[k] = e
    return t, out
