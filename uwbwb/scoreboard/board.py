"""The board: every estimator on the same scoring part, with the same calibration, against its bound.

:func:`score` runs the protocol of :mod:`.protocol` with the estimators of
:mod:`.estimators` and returns a :class:`Board`. Per method (rows of
:meth:`Board.table`, all tags pooled):

``coverage``
    Share of the scoring epochs (those with truth) where the method gave a position.
``rmse_m, cep50_m, cep95_m``
    Horizontal errors over the epochs it covered.
``rmse_common_m``
    RMSE over the epochs *every* method on the board covered (the like-for-like figure).
``common_bound_m``, ``rmse_over_common``, ``rmse_over_common_se``, ``rmse_over_common_blocks``
    The recording's **common bound** (:mod:`.reference`: the posterior CRLB of the motion
    model that best fits the calibration truth, with every range at the calibrated robust noise
    treated as Gaussian, evaluated along the one realised true track; the same for every method;
    it bounds causal estimators only — a smoother or a method with an IMU may go below it)
    aggregated as ``sqrt(mean_k tr C_k)`` over the method's covered epochs, and the method's RMSE
    over those epochs divided by it, with a block standard error (:func:`.verdicts.block_se_ratio`:
    the board's one block rule; NaN with fewer than :data:`uwbwb.metrics.MIN_BLOCKS` blocks) and its number of
    blocks (each ``_se`` column has its ``_blocks`` beside it). These are each method's own covered epochs: a
    method that skips the hard epochs is placed on easier ones.
``common_bound_common_m``, ``rmse_common_over_common``
    The same on the epochs *every* method covered: one bound and one set of epochs for all, so this
    is the column to rank methods by (it orders them as ``rmse_common_m`` does); the coverage beside it.
``bound_m``, ``bound_kind``
    The method's *own* Cramér–Rao bound (its own noise and motion model, its own tuning)
    aggregated the same way over the covered epochs where it exists (``n_bound`` of them);
    empty ("—") for a method that has none (e.g. an external method's estimates).
``rmse_over_bound``, ``rmse_over_bound_se``
    RMSE over those epochs divided by ``bound_m`` (the textbook *efficiency* is the inverse,
    bound / RMSE): a consistency check of each method against its own model — near 1 the
    method does what its model promises; below 1 by more than 2 standard errors it *beats* its own
    bound (:func:`.verdicts.own_bound_table` gives the verdict beside the next columns). Not comparable across
    methods (a poor model has a loose bound).
``bound_measured_m``, ``rmse_over_bound_measured``, ``rmse_over_bound_measured_se``
    The own bound re-evaluated with its noise assumption replaced by what the scored part's truth
    measures (:meth:`~.interface.BaseEstimator.measured_noise_bound`: the scored part's robust range σ;
    the set-noise filters' noise model refitted on the scored part), and RMSE over it: a method below its
    own bound but not below this one beats the bound's noise assumption. NaN where not measured.
``ranges_crlb_m``, ``bound_over_ranges_crlb``
    The snapshot CRLB of every range of the epoch at the calibrated noise (the range-domain bound of the
    geometry) over the epochs of ``bound_m`` where it is finite, and the own bound over it on those epochs: far
    above 1 the method's own
    measurement model (e.g. range differences of a small anchor cluster) carries far less information than the
    ranges.
``bias_share``
    The constant part of the error: ``sqrt(Σ_tag n |mean error vector|² / Σ n) / RMSE`` over the scored epochs
    (0: no constant offset; 1: all of the error is one offset per tag). A Cramér–Rao bound holds for unbiased
    estimators.
``nees_mean``, ``nees_dof``, ``nees_ok``
    Mean NEES of the position (methods with a covariance) against its χ² 95 % interval
    (epochs treated as independent: a tracking filter's errors are correlated, so read it
    as indicative).
``nis_over_dof``, ``nis_verdict``
    NIS per degree of freedom and the χ² verdict (:func:`uwbwb.metrics.nis_consistency`, which also gives ``nees_ok``).
``us_per_epoch``, ``time_ratio``
    Compute time per epoch (this machine, this run) and its ratio to ``raw LS``'s in the
    same run; NaN for an external method (its estimates are read from file, not run here: the
    Markdown says "external: not timed").
``grid_edge``
    Whether the method's tuning pick on the calibration part lies on the edge of its grid (a wider
    grid might do better: its tuning effort fell short); None for a method that tunes nothing.
``tuning_pick``
    The picked value(s) (σ_w; Q ×, R ×; σ_d; window) and where they lie on the grid (which knob sits on
    which end, where the tuning says); "—" for a method that tunes nothing.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from .. import metrics
from ..types import Estimates, Recording
from . import checks as _checks
from .estimators import default_estimators
from .interface import GEOMETRY, Estimator, _range_bound, measurement_geometry
from .protocol import Calibration, fit_calibration, scored_tags
from .reference import NO_COMMON_BOUND, REFERENCE, common_bound, fit_reference_motion
from .verdicts import block_se_ratio

__all__ = ["Board", "Entry", "calibrate", "score", "TABLE_COLUMNS"]

#: Columns of :meth:`Board.table`, in order.
TABLE_COLUMNS = ("method", "coverage", "n_scored", "rmse_m", "cep50_m", "cep95_m", "rmse_common_m",
                 "common_bound_m", "rmse_over_common", "rmse_over_common_se", "rmse_over_common_blocks",
                 "common_bound_common_m", "rmse_common_over_common", "bound_m", "bound_kind", "n_bound",
                 "rmse_over_bound", "rmse_over_bound_se", "rmse_over_bound_blocks", "bound_measured_m",
                 "rmse_over_bound_measured", "rmse_over_bound_measured_se", "rmse_over_bound_measured_blocks",
                 "ranges_crlb_m", "bound_over_ranges_crlb", "bias_share",
                 "nees_mean", "nees_dof", "nees_ok", "nis_over_dof",
                 "nis_verdict", "us_per_epoch", "time_ratio", "grid_edge", "tuning_pick", "note")


#: Bound → its board column and the RMSE-over-it column (its block standard error: that name + ``_se``).
_BOUND_COLUMNS = {"common": ("common_bound_m", "rmse_over_common"), "bound": ("bound_m", "rmse_over_bound"),
                  "bound_measured": ("bound_measured_m", "rmse_over_bound_measured")}


@dataclass(frozen=True)
class Entry:
    """One method on one tag of the scoring part.

    Attributes
    ----------
    method, tag
        Labels.
    estimates
        The method's output (None if it did not apply).
    bound
        Its own bound at the same epochs (None if it did not apply or has none).
    truth_pos_m
        True positions at the epochs, ``(T, dim)``; NaN where the truth does not reach.
    seconds
        Wall time of :meth:`Estimator.estimate`.
    skipped
        Why the method did not run here (None if it ran).
    common
        The recording's common bound at the same epochs (:mod:`.reference`; None if there is none).
    bound_measured
        The own bound with its noise assumption measured on the scored part
        (:meth:`~.interface.BaseEstimator.measured_noise_bound`; None if not measured).
    ranges_crlb
        The snapshot CRLB of all the epoch's ranges at the calibrated noise (the geometry's range-domain bound).
    """

    method: str
    tag: str
    estimates: Estimates | None
    bound: object | None
    truth_pos_m: np.ndarray | None
    seconds: float = float("nan")
    skipped: str | None = None
    common: object | None = None
    bound_measured: object | None = None
    ranges_crlb: object | None = None

    @property
    def error_m(self) -> np.ndarray:
        """Horizontal error per epoch, ``(T,)``; NaN where no estimate or no truth."""
        e = self.estimates.pos_m[:, :2] - self.truth_pos_m[:, :2]
        return np.sqrt(np.sum(e * e, axis=1))

    @property
    def scoring(self) -> np.ndarray:
        """Epochs with truth, bool ``(T,)``."""
        return np.all(np.isfinite(self.truth_pos_m), axis=1)

    @property
    def scored(self) -> np.ndarray:
        """Epochs with truth and an estimate, bool ``(T,)``."""
        return self.scoring & self.estimates.has_estimate

    def trace_m2(self, which: str = "bound") -> np.ndarray:
        """Horizontal trace per epoch, ``(T,)``, m², of the bound ``which`` names: ``"bound"`` (its own),
        ``"common"``, ``"bound_measured"`` or ``"ranges_crlb"`` (NaN where there is none)."""
        b = getattr(self, which)
        if b is None:
            return np.full(len(self.estimates), np.nan)
        return np.trace(b.pos_cov_m2[:, :2, :2], axis1=1, axis2=2)

    @property
    def nees(self) -> np.ndarray:
        """Position NEES per epoch (NaN where no covariance or no truth)."""
        est = self.estimates
        out = np.full(len(est), np.nan)
        if est.pos_cov_m2 is None:
            return out
        ok = self.scored & np.all(np.isfinite(est.pos_cov_m2.reshape(len(est), -1)), axis=1)
        ok[ok] = np.linalg.eigvalsh(est.pos_cov_m2[ok])[:, 0] > 0      # a zero covariance has no NEES
        return metrics.nees(est.pos_m - self.truth_pos_m, est.pos_cov_m2, ok)


def _se(ents: list[Entry], which: str) -> tuple[float, int]:
    """Block standard error of RMSE / bound over the entries' scored epochs with that bound, and its number of
    blocks (:func:`.verdicts.block_se_ratio`: the board's one block rule, blocks cut per tag)."""
    sq, tr = [], []
    for e in ents:
        t = e.trace_m2(which)[e.scored]
        have = np.isfinite(t)
        sq.append(e.error_m[e.scored][have] ** 2)
        tr.append(t[have])
    return block_se_ratio(sq, tr)


def _run_estimate(est: Estimator, rec: Recording, tag: str, cal: Calibration) -> tuple[Estimates | None, str]:
    """``est.estimate`` on ``rec`` (without its truth), checked: the estimates and ``""``, or None and what went
    wrong (an exception, a return that is not :class:`~uwbwb.types.Estimates`, or estimates off the tag's epochs)."""
    try:
        out = est.estimate(rec, tag, cal)
    except Exception as exc:                           # a user's estimator: named on the board, not fatal to it
        return None, f"estimate raised {type(exc).__name__}: {exc}"
    if not isinstance(out, Estimates):
        return None, f"estimate returned {type(out).__name__}, expected uwbwb.types.Estimates"
    if not np.array_equal(out.t_s, rec.ranges[tag].t_s):
        return None, f"estimates must be on the tag's {len(rec.ranges[tag])} epochs, got {len(out)}"
    return out, ""


def calibrate(cal_rec: Recording, estimators: Sequence[Estimator], tags: Sequence[str] | None = None, *,
              rate_hz: float | None = None, dim: int | None = None, progress: bool = False,
              tag_height_m: Mapping[str, float] | None = None, calibration: Calibration | None = None) -> Calibration:
    """Fit the shared calibration on ``cal_rec``, the common bound's motion model
    (:func:`.reference.fit_reference_motion`) and the measurement geometry (:func:`.interface.measurement_geometry`:
    whether the TDoA methods run), then let each estimator that applies tune itself on it.

    ``calibration``: a calibration made elsewhere (the exact noise of a synthetic run, an earlier board's on the same
    calibration part) to start from instead: only what it lacks is fitted on ``cal_rec`` (the common bound's model,
    the geometry, the tuning of each estimator it holds none of, by name); ``dim`` and ``tag_height_m`` are its."""
    tags = scored_tags(cal_rec, tags)
    cal = fit_calibration(cal_rec, tags, rate_hz=rate_hz, dim=dim, tag_height_m=tag_height_m) if calibration is None \
        else calibration
    done = set(cal.tuned) if calibration is not None else set()
    rec = cal_rec if rate_hz is None else cal_rec.decimate(rate_hz=rate_hz)
    if REFERENCE not in cal.tuned:
        reference = fit_reference_motion(rec, tags, cal)
        if reference:
            cal = cal.with_tuned(REFERENCE, reference)
    if GEOMETRY not in cal.tuned:
        cal = cal.with_tuned(GEOMETRY, measurement_geometry(rec, tags, cal))
    for est in estimators:
        usable = [] if est.name in done else [t for t in tags if est.applies(rec, t, cal) is None]
        if not usable:
            continue
        if progress:
            print(f"tuning {est.name} on {rec.label} ...", flush=True)
        try:
            params = est.tune(rec, usable, cal)
        except Exception as exc:
            raise RuntimeError(f"{est.name}: tune on {rec.label} (tags {', '.join(usable)}) raised "
                               f"{type(exc).__name__}: {exc}") from exc
        if params:
            cal = cal.with_tuned(est.name, params)
    return cal


@dataclass(frozen=True)
class Board:
    """The scoreboard of one recording (see the module docstring for the columns).

    Attributes
    ----------
    label
        ``dataset/recording`` the board is about.
    part
        Label of the scored data itself (e.g. the second half of ``label``).
    calibration
        The calibration every method used (fitted on ``calibration.source``).
    entries
        One :class:`Entry` per (method, tag).
    methods
        Method names in board order.
    fast
        Whether CI-sized settings were used (numbers are then smoke tests).
    checks
        What the input checks found and did (:mod:`.checks`: measured vs predicted ranges, the
        truth clock offset estimate, dropped anchors, a lifted 2-D truth), one line each.
    external
        Methods whose estimates were made outside the workbench (:class:`~.estimators.ExternalEstimates`):
        their numbers are *inputs* scored here, not reproduced.
    """

    label: str
    part: str
    calibration: Calibration
    entries: tuple[Entry, ...]
    methods: tuple[str, ...]
    fast: bool = False
    checks: tuple[str, ...] = ()
    external: tuple[str, ...] = ()

    def __post_init__(self):
        seen = [(e.method, e.tag) for e in self.entries]
        twice = sorted({k for k in seen if seen.count(k) > 1})
        if twice:
            raise ValueError(f"Board: one entry per (method, tag) expected, got several for {twice}")

    @property
    def data_label(self) -> str:
        """The ``data`` field of summary rows: ``synthetic`` or ``dataset/recording``."""
        return "synthetic" if self.label.startswith("synthetic/") else self.label

    @property
    def mode(self) -> str:
        return "FAST" if self.fast else "full"

    @property
    def tags(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(e.tag for e in self.entries))

    def entry(self, method: str, tag: str) -> Entry:
        for e in self.entries:
            if e.method == method and e.tag == tag:
                return e
        raise KeyError(f"no entry for {method!r} on tag {tag!r}; methods {list(self.methods)}, tags {list(self.tags)}")

    def ran(self, tag: str | None = None) -> list[Entry]:
        """Entries that ran (optionally of one tag)."""
        return [e for e in self.entries if e.skipped is None and (tag is None or e.tag == tag)]

    @cached_property
    def _scores_by_tag(self) -> dict[str, metrics.EpochScores]:
        # scored once per board (the entries are frozen), not once per table cell
        return {tag: metrics.score_epochs({e.method: e.error_m for e in self.ran(tag)},
                                          {e.method: e.scoring for e in self.ran(tag)}) for tag in self.tags}

    def scores(self, tag: str) -> metrics.EpochScores:
        """The methods that ran on ``tag`` on its epochs (:func:`uwbwb.metrics.score_epochs`: each
        scored where truth exists and it has an estimate; common = every method that ran there)."""
        return self._scores_by_tag[tag]

    def _pooled(self, ents: list[Entry]) -> metrics.MethodEpochs:
        """One method's entries pooled over their tags, in the entries' order."""
        return metrics.pool_scores([self.scores(e.tag) for e in ents])[ents[0].method]

    def errors(self, tag: str | None = None) -> dict[str, np.ndarray]:
        """Method → scored horizontal errors (pooled over tags, or of one tag), metres."""
        ran = self.ran(tag)
        return {m: self._pooled([e for e in ran if e.method == m]).own_m for m in dict.fromkeys(e.method for e in ran)}

    def _common(self, tag: str) -> np.ndarray:
        scores = self.scores(tag)
        return scores.methods[0].common if len(scores) else np.zeros(0, bool)

    def _row(self, method: str, ents: list[Entry], skipped: list[Entry]) -> dict:
        row = {c: np.nan for c in TABLE_COLUMNS}
        params = self.calibration.params(method)
        row.update(method=method, note="", bound_kind="", nis_verdict="", nees_ok=None,
                   grid_edge=params.get("grid_edge"), tuning_pick=pick_label(params))
        if not ents:
            row["note"] = "not run: " + "; ".join(sorted({e.skipped for e in skipped}))
            row["coverage"] = 0.0
            row["n_scored"] = 0
            return row
        pooled = self._pooled(ents)
        err = pooled.own_m
        row["coverage"] = pooled.coverage
        row["n_scored"] = pooled.n_scored
        row.update(pooled.stats(own={"rmse_m": metrics.rmse, "cep50_m": metrics.cep50, "cep95_m": metrics.cep95},
                                common={"rmse_common_m": metrics.rmse}))
        if pooled.n_common:
            cc = np.concatenate([e.trace_m2("common")[self._common(e.tag)] for e in ents])
            if np.isfinite(cc).all():
                row["common_bound_common_m"] = float(np.sqrt(np.mean(cc)))
                row["rmse_common_over_common"] = row["rmse_common_m"] / row["common_bound_common_m"]
        row["bound_kind"] = ents[0].bound.kind if ents[0].bound is not None else ""
        tr = {w: np.concatenate([e.trace_m2(w)[e.scored] for e in ents]) for w in (*_BOUND_COLUMNS, "ranges_crlb")}
        row["n_bound"] = int(np.isfinite(tr["bound"]).sum())
        for w, (col, ratio) in _BOUND_COLUMNS.items():     # each bound over the epochs where it exists
            have = np.isfinite(tr[w])
            if have.any():
                row[col] = float(np.sqrt(np.mean(tr[w][have])))
                row[ratio] = float(np.sqrt(np.mean(err[have] ** 2)) / row[col])
                row[ratio + "_se"], row[ratio + "_blocks"] = _se(ents, w)
        both = np.isfinite(tr["bound"]) & np.isfinite(tr["ranges_crlb"])   # epochs whose ranges alone fix the position
        if both.any():
            row["ranges_crlb_m"] = float(np.sqrt(np.mean(tr["ranges_crlb"][both])))
            row["bound_over_ranges_crlb"] = float(np.sqrt(np.mean(tr["bound"][both]))) / row["ranges_crlb_m"]
        row["bias_share"] = _bias_share(ents)
        nees = np.concatenate([e.nees[e.scored] for e in ents])
        nees = nees[np.isfinite(nees)]
        if nees.size:
            d = ents[0].estimates.dim
            c = metrics.nis_consistency(nees, np.full(nees.size, d))      # the same χ² test as the NIS
            row.update(nees_mean=float(nees.mean()), nees_dof=d, nees_ok=c["verdict"] == "consistent")
        if "nis" in ents[0].estimates.info:
            nis = np.concatenate([e.estimates.info["nis"][e.scored] for e in ents])
            dof = np.concatenate([np.asarray(e.estimates.info["dof"])[e.scored] for e in ents])
            c = metrics.nis_consistency(nis, dof)
            row.update(nis_over_dof=c["mean_nis_over_dof"], nis_verdict=c["verdict"])
        epochs = sum(len(e.estimates) for e in ents)
        if method not in self.external:         # an external method's estimates are read, not run: not timed
            row["us_per_epoch"] = 1e6 * sum(e.seconds for e in ents) / epochs if epochs else np.nan
        return row

    def table(self) -> pd.DataFrame:
        """One row per method (tags pooled), columns :data:`TABLE_COLUMNS`."""
        rows = []
        for m in self.methods:
            ents = [e for e in self.entries if e.method == m]
            rows.append(self._row(m, [e for e in ents if e.skipped is None], [e for e in ents if e.skipped]))
        df = pd.DataFrame(rows, columns=list(TABLE_COLUMNS))
        base = df.loc[df["method"] == "raw LS", "us_per_epoch"]
        if len(base) and np.isfinite(base.iloc[0]) and base.iloc[0] > 0:
            df["time_ratio"] = df["us_per_epoch"] / base.iloc[0]
        return df

    # ------------------------------------------------------------------ output
    def markdown(self) -> str:
        """The table as Markdown (the bound in its own column), with a header saying what it is."""
        df = self.table()
        kinds = ("numbers are *reproduced*: they come out of the methods run here"
                 + (f"; rows of {', '.join(self.external)} are *input*: outside estimates scored here"
                    if self.external else ""))
        lines = [f"# Scoreboard: {self.label} ({self.mode} mode; {kinds})", "",
                 f"Calibration and tuning on {self.calibration.source}; scored on {self.part}, "
                 f"tags {', '.join(self.tags)}; {self.calibration.dim}-D, {self.calibration.rate_hz:.3g} Hz. "
                 "Errors are horizontal. *Common bound*: one bound for every method, the posterior CRLB of the "
                 "motion model most likely on the calibration truth (model and σ_w in the calibration block below; "
                 "none where it has none), every range at the calibrated robust noise treated as Gaussian, along the "
                 "scored true track; it bounds causal estimators only. RMSE / common "
                 "bound on the common epochs (those every method covered) is the figure to rank methods by: one "
                 "bound on one set of epochs; RMSE / common bound on a method's own epochs places it with its "
                 "coverage (a method that skips hard epochs is placed on easier ones). *Own bound*: each method's Cramér–Rao bound under its "
                 "own noise and motion model (its kind in the next column); RMSE / own bound checks the method "
                 "against its own model and is not comparable across methods (the textbook efficiency is its "
                 "inverse). Both are bounds only under their stated Gaussian noise and motion models.", ""]
        if self.fast:
            lines += ["FAST mode: CI-sized tuning grids and particle counts — smoke-test numbers.", ""]
        if "model" not in self.calibration.params(REFERENCE):
            lines += [NO_COMMON_BOUND, ""]
        head = ["method", "coverage", "RMSE (m)", "CEP50 (m)", "CEP95 (m)", "RMSE common epochs (m)",
                "common bound (m)", "RMSE / common bound", "RMSE / common bound, common epochs", "own bound (m)", "own bound kind", "RMSE / own bound",
                "RMSE / own bound at measured noise", "own bound / ranges' CRLB", "bias share",
                "NEES / dof", "NIS / dof", "µs/epoch", "time × raw LS", "tuning pick", "note"]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

        def f(x, fmt=".3f"):
            return "—" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, fmt)

        def took(x, fmt, method):          # a time: a method that ran took some, so it never shows as 0
            if method in self.external:
                return "external: not timed"
            return f(x, ".2g" if x > 0 and float(format(x, fmt)) == 0 else fmt)

        for r in df.itertuples(index=False):
            eff = (f"{r.rmse_over_bound:.2f} ± {r.rmse_over_bound_se:.2f}" if np.isfinite(r.rmse_over_bound_se)
                   else f(r.rmse_over_bound, ".2f"))
            com = (f"{r.rmse_over_common:.2f} ± {r.rmse_over_common_se:.2f}" if np.isfinite(r.rmse_over_common_se)
                   else f(r.rmse_over_common, ".2f"))
            meas = (f"{r.rmse_over_bound_measured:.2f} ± {r.rmse_over_bound_measured_se:.2f}"
                    if np.isfinite(r.rmse_over_bound_measured_se) else f(r.rmse_over_bound_measured, ".2f"))
            nees = f"{r.nees_mean:.2f} / {r.nees_dof:.0f}" if np.isfinite(r.nees_mean) else "—"
            nis = f"{r.nis_over_dof:.2f} ({r.nis_verdict})" if np.isfinite(r.nis_over_dof) else "—"
            lines.append("| " + " | ".join([r.method, f(r.coverage, ".1%"), f(r.rmse_m), f(r.cep50_m), f(r.cep95_m),
                                              f(r.rmse_common_m), f(r.common_bound_m), com,
                                              f(r.rmse_common_over_common, ".2f"), f(r.bound_m),
                                              r.bound_kind or "—", eff, meas, f(r.bound_over_ranges_crlb, ".3g"),
                                              f(r.bias_share, ".2f"), nees, nis,
                                              took(r.us_per_epoch, ".0f", r.method),
                                              took(r.time_ratio, ".1f", r.method),
                                              r.tuning_pick, r.note or ""]) + " |")
        lines += ["", "```", self.calibration.describe(), *self.checks, "```", ""]
        return "\n".join(lines)

    def write(self, out: str | Path, *, figure: bool = True) -> dict[str, Path]:
        """Write ``scoreboard.csv``, ``scoreboard.md`` (and ``scoreboard.png``) into ``out``."""
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"csv": out / "scoreboard.csv", "md": out / "scoreboard.md"}
        df = self.table()
        df.insert(0, "data", self.label)
        df["mode"] = self.mode
        df["kind"] = ["input" if m in self.external else "reproduced" for m in df["method"]]
        df.to_csv(paths["csv"], index=False, lineterminator="\n")
        paths["md"].write_text(self.markdown(), encoding="utf-8")
        if figure:
            import matplotlib.pyplot as plt

            from .figures import board_figure

            fig = board_figure(self)
            paths["png"] = out / "scoreboard.png"
            fig.savefig(paths["png"], dpi=110, bbox_inches="tight")
            plt.close(fig)
        return paths

    def to_summary(self, summary, *, methods: Sequence[str] | None = None) -> None:
        """Record each method's RMSE, bounds and their ratios into a :class:`uwbwb.metrics.Summary`.

        ``RMSE/own bound`` is RMSE / the method's own bound (the textbook efficiency is its inverse).
        Rows of a method run here are
        *reproduced*; rows of an external method (:attr:`external`) are *input* (estimates made
        elsewhere), with the data label marked ``(external estimates)``."""
        df = self.table().set_index("method")
        for m in (methods or self.methods):
            r = df.loc[m]
            if not np.isfinite(r.rmse_m):
                continue
            for q, v, u in ((f"RMSE, {m}", r.rmse_m, "m"), (f"bound, {m} ({r.bound_kind})", r.bound_m, "m"),
                            (f"RMSE/own bound, {m}", r.rmse_over_bound, ""),
                            (f"common bound, {m}", r.common_bound_m, "m"),
                            (f"RMSE/common bound, {m}", r.rmse_over_common, ""), (f"coverage, {m}", r.coverage, "")):
                if np.isfinite(v) and m in self.external:      # an outside method's numbers: input
                    summary.add(quantity=q, value=float(v), unit=u, data=f"{self.label} (external estimates)",
                                kind="input")
                elif np.isfinite(v):
                    summary.add(quantity=q, value=float(v), unit=u, data=self.data_label, kind="reproduced")


#: Tuned knobs the board names in its *tuning pick* column: key in the tuned parameters, label, unit.
TUNED_KNOBS = (("sigma_w", "σ_w", ""), ("q_scale", "Q ×", ""), ("r_scale", "R ×", ""),
               ("sigma_d_mps", "σ_d", " m/s"), ("window_s", "window", " s"))


def pick_label(params: Mapping) -> str:
    """A method's tuning pick as the board shows it: the picked knob values (:data:`TUNED_KNOBS`) and whether
    they lie on the grid's edge, naming the knob(s) there where the tuning records them (``edge_knobs``);
    "—" for a method that tunes nothing (no ``grid_edge``)."""
    edge = params.get("grid_edge")
    if edge is None or (isinstance(edge, float) and not np.isfinite(edge)):
        return "—"
    where = "on the grid's edge" if edge else "inside the grid"
    values = ", ".join(f"{label} {float(params[k]):.3g}{unit}" for k, label, unit in TUNED_KNOBS if k in params)
    knobs = params.get("edge_knobs") or ()
    if params.get("grid_edge") and knobs:
        where += f" ({', '.join(knobs)})"
    return f"{values}: {where}" if values else where


def _bias_share(ents: list[Entry]) -> float:
    """``sqrt(Σ_tag n |mean error vector|² / Σ n) / RMSE`` over the entries' scored epochs, horizontal."""
    n, b2, e2 = 0, 0.0, 0.0
    for e in ents:
        d = (e.estimates.pos_m[:, :2] - e.truth_pos_m[:, :2])[e.scored]
        if len(d):
            n += len(d)
            b2 += len(d) * float(np.sum(d.mean(axis=0) ** 2))
            e2 += float(np.sum(d * d))
    return float(np.sqrt(b2 / e2)) if n and e2 > 0 else float("nan")


def score(test_rec: Recording, cal_rec: Recording, *, estimators: Sequence[Estimator] | None = None,
          tags: Sequence[str] | None = None, rate_hz: float | None = 10.0, dim: int | None = None,
          calibration: Calibration | None = None, fast: bool = False, progress: bool = False,
          label: str | None = None, tag_height_m: float | Mapping[str, float] | None = None,
          truth_offset_s: float = 0.0, check: bool = True,
          min_epochs: int = _checks.MIN_SCORED_EPOCHS, other_anchors: bool = False) -> Board:
    """Calibrate on ``cal_rec`` and score every estimator on ``test_rec``.

    Parameters
    ----------
    test_rec, cal_rec
        Scoring and calibration recordings of the same anchors and tags, both with truth.
    estimators
        Default :func:`~.estimators.default_estimators`.
    tags
        Tags to score (default all with truth in both).
    rate_hz
        Rate every method runs at (ranges thinned to it; None = native).
    dim
        Force 2 or 3 (default from the calibration truth).
    calibration
        Use this calibration (e.g. the exact noise of a synthetic run, or an earlier board's on the same calibration
        part) instead of fitting one; what it lacks is fitted on ``cal_rec`` (:func:`calibrate`).
    fast
        CI-sized settings (recorded in the board's mode).
    label
        What the board is about (default ``test_rec.label``; give the whole run's label when ``test_rec`` is a part
        of it, as the command line does).
    tag_height_m
        Height of the tag(s) for a 2-D truth (one value or per tag); None fits it from the
        calibration ranges (:func:`.checks.fit_tag_height`). 3-D truth is left as it is.
    truth_offset_s
        Known truth clock offset (truth time = range time + offset), removed from both recordings.
    check
        Run the input checks of :mod:`.checks` (measured vs predicted ranges with a diagnosis of
        units, swapped axes, clock offset and anchor mismatches; silent anchors dropped and
        counted); with ``calibration`` given the anchors are not dropped.
    min_epochs
        Fewest scored epochs with truth per tag (fewer is an error).

    Raises
    ------
    ValueError
        A recording that the checks find unscorable, with the diagnosis.
    """
    estimators = list(default_estimators(fast=fast) if estimators is None else estimators)
    names = [getattr(e, "name", None) for e in estimators]
    odd = [n for n in names if not isinstance(n, str) or not n.strip() or any(c in n for c in "|\n\r`")]
    if odd:
        raise ValueError(f"estimator names must be non-empty text without '|', '`' or line breaks (they head the "
                         f"board's Markdown table), got {odd!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"estimator names must be unique, got {names}")
    tags = scored_tags(test_rec, tags)
    scored_tags(cal_rec, tags)
    moved = _checks.check_same_anchors(cal_rec, test_rec, allow_moved=other_anchors)
    if tag_height_m is not None:
        _checks.check_height_applies(test_rec, cal_rec, tags)
    # what the loaders dropped or set to NaN (both parts of one run carry the same steps: each once)
    notes: list[str] = list(dict.fromkeys(f"loader: {step}" for rec in (cal_rec, test_rec) for step in rec.cleaning))
    if moved:
        notes.append(f"calibrated on a recording whose anchors sit elsewhere ({moved}): the per-anchor calibration "
                     "and the tuned parameters are carried over by anchor id")
    if truth_offset_s:
        cal_rec, test_rec = _checks.shift_truth(cal_rec, truth_offset_s), _checks.shift_truth(test_rec, truth_offset_s)
        notes.append(f"truth clock shifted by {-truth_offset_s:+.3f} s (given)")
    if isinstance(tag_height_m, Mapping) or tag_height_m is None:
        given = tag_height_m
    else:
        given = {t: float(tag_height_m) for t in tags}
    if calibration is not None and given is None:
        given = {t: h for t, h in calibration.tag_height_m.items()}
    cal_rec, how = _checks.lift_truth(cal_rec, given)
    heights = {t: float(cal_rec.truth[t].pos_m[0, 2]) for t in how}
    test_rec, _ = _checks.lift_truth(test_rec, {**(given or {}), **heights})
    notes += [f"tag {t}: 2-D truth, {h}" for t, h in how.items()]
    if check:
        thinned = cal_rec if rate_hz is None else cal_rec.decimate(rate_hz=rate_hz)
        _checks.check_overlap(thinned, tags, min_epochs=_checks.MIN_ANCHOR_SAMPLES, part="calibration part")
        if calibration is None:
            cal_rec, test_rec, dropped = _checks.drop_silent_anchors(cal_rec, test_rec, tags)
            if dropped:
                notes.append(f"anchors dropped (fewer than {_checks.MIN_ANCHOR_SAMPLES} ranges on the calibration "
                             f"part, cannot be calibrated): {', '.join(dropped)}")
        thinned = test_rec if rate_hz is None else test_rec.decimate(rate_hz=rate_hz)
        _checks.check_overlap(thinned, tags, min_epochs=min_epochs)
        for part, r in (("calibration part", cal_rec), ("scored part", test_rec)):
            for tag in tags:
                c = _checks.check_ranges_against_truth(r, tag)
                notes.append(f"{part}: {c.describe()}")
        if cal_rec.imu is not None and len(cal_rec.imu.t_s):
            notes.append(f"calibration part: {_checks.check_gyro_against_truth(cal_rec, tags[0])}")
    if calibration is None:
        known = {**(given or {}), **heights} if (tag_height_m is not None or how) else None
        calibration = calibrate(cal_rec, estimators, tags, rate_hz=rate_hz, dim=dim, progress=progress,
                                tag_height_m=known)
    else:      # a calibration made elsewhere: what it lacks of calibrate's fits, on this one's calibration part
        calibration = calibrate(cal_rec, estimators, tags, rate_hz=rate_hz, progress=progress, calibration=calibration)
    rec = test_rec if rate_hz is None else test_rec.decimate(rate_hz=rate_hz)
    commons = {t: common_bound(rec, t, calibration) for t in tags}
    ranges_crlb = {t: _range_bound(rec, t, calibration, rec.ranges[t], "CRLB of the ranges") for t in tags}
    blind = replace(rec, truth={})                    # what an estimator sees: the measurements, not the truth
    entries = []
    for tag in tags:
        for est in estimators:
            why = est.applies(rec, tag, calibration)
            if why is not None:
                entries.append(Entry(est.name, tag, None, None, None, skipped=why))
                continue
            if progress:
                print(f"scoring {est.name} on {rec.label}/{tag} ...", flush=True)
            t0 = time.perf_counter()
            out, failed = _run_estimate(est, blind, tag, calibration)
            seconds = time.perf_counter() - t0
            if failed:
                warnings.warn(f"{est.name} on {rec.label}/{tag}: {failed}; the board keeps the other rows",
                              RuntimeWarning, stacklevel=2)
                entries.append(Entry(est.name, tag, None, None, None, skipped=f"failed: {failed}"))
                continue
            try:
                b = est.bound(rec, tag, calibration, out)
            except NotImplementedError:
                b = None                              # e.g. an external method's estimates: no model, no bound
            measured = None
            if b is not None and hasattr(est, "measured_noise_bound"):
                try:
                    measured = est.measured_noise_bound(rec, tag, calibration, out)
                except Exception as exc:                # a measurement that cannot be made is "not measured"
                    warnings.warn(f"{est.name} on {rec.label}/{tag}: its bound at the measured noise raised "
                                  f"{type(exc).__name__}: {exc}; left out", RuntimeWarning, stacklevel=2)
            truth = rec.truth_at(tag, out.t_s, out.dim)
            entries.append(Entry(est.name, tag, out, b, truth, seconds, common=commons[tag], bound_measured=measured,
                                 ranges_crlb=ranges_crlb[tag]))
    external = tuple(e.name for e in estimators if getattr(e, "external", False))
    return Board(label or test_rec.label, test_rec.label, calibration, tuple(entries), tuple(names), fast, tuple(notes),
                 external)
