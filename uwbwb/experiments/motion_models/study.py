"""Notebook 03's study: calibrate range and driving noise on one run, test every estimator on another.

Reproduces De Angelis, *Analysis of the performance of an UWB localization
system using Bayesian tracking filters* (Politecnico di Milano, thesis summary,
2021–22): pseudo-TDoA from two-way ranges, a per-epoch Gauss–Newton LS fix, an
EKF with three motion models whose driving-noise level is calibrated against
ground truth (Table 1), and CEP95 tables (Tables 2–5) and path figures (Figs 5–10).

The pipeline for one tag of one recording (:class:`~uwbwb.types.TagRun`):

1. ranges → pseudo-TDoA to a reference anchor (:class:`~uwbwb.types.TdoaLog`);
2. range-noise level per anchor from a *calibration* run with truth
   (:func:`uwbwb.calibration.fit_range_sigma`; by default the part of the range error that does
   not cancel in a TDoA) → TDoA covariance ``Σ = diag(σ_j²) + σ_ref² 11ᵀ``;
3. tuning by the board's protocol: the range-noise fits form a
   :class:`~uwbwb.scoreboard.protocol.Calibration` of the calibration run (ranges as logged), and each of the
   notebook's methods — the registry's estimators on pseudo-TDoAs (:func:`~.results.estimators`) — tunes itself
   on it: each EKF (:class:`~uwbwb.scoreboard.estimators.TdoaEkfEstimator`) its driving σ over the notebook's
   grid with the CEP95 criterion (``criterion="cep95"``, mean over the tags; :func:`run_study`);
4. on a *different* test run: raw output and those estimators on the protocol's calibration of that run
   (:func:`estimate`), held as a board of its tag and scored by it
   (:meth:`~uwbwb.scoreboard.board.Board.scores`) on the epochs where *every* estimator has a position
   (:meth:`TagResults.common_errors`), with each one's coverage beside it (:meth:`Study.table`,
   :meth:`Study.coverage`), and the NIS χ² verdict of each filter (:meth:`TagResults.nis`).

Driving "variances" follow the thesis' Table 1 units (m/s, m/s², m/s³): they
are the standard deviation ``σ_w`` of the white driving process over one step
of the nominal epoch period ``T``, i.e. PSD ``q = σ_w² T`` (see
:mod:`uwbwb.models.motion`).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ... import parallel
from ...calibration import fit_range_sigma
from ...models.motion import MOTION_MODELS
from ...scoreboard.board import Board, Entry
from ...scoreboard.estimators import ExternalEstimates, RawLs
from ...scoreboard.protocol import Calibration
from ...sim import walk
from ...types import Recording, TagRun, Trajectory

from .results import MODELS, TagResults, ekf_name, estimators

__all__ = ["tag_runs", "synthetic_acquisition", "ranging_summary", "estimate", "Study", "run_study"]


# --------------------------------------------------------------------------- inputs


def tag_runs(rec: Recording, tags: Sequence[str] | None = None, *, dim: int, z_m: Mapping[str, float] | None = None,
             rate_hz: float | None = None, raw: Mapping[str, Trajectory] | None = None,
             name: str | None = None) -> list[TagRun]:
    """:class:`TagRun` per tag of a recording.

    Parameters
    ----------
    rec
        A recording with truth per tag.
    tags
        Tags to use (default: all with truth).
    dim
        2 (tag at a known height) or 3.
    z_m
        Tag height per tag, required for ``dim=2``. It must come from calibration data
        or the dataset's description (:func:`uwbwb.calibration.tag_mount_height`, a
        simulator's declared mount), never from the truth of the run being scored.
    rate_hz
        Thin to at most this rate with :meth:`uwbwb.types.Recording.decimate`, the
        step taken from the median epoch period over the tags (None: unchanged).
    raw
        The device's own output per tag, if any (kept at the remaining epochs).
    name
        Display name (default ``rec.name``).
    """
    tags = list(tags) if tags is not None else [t for t in rec.tags if t in rec.truth]
    missing = [t for t in tags if t not in rec.truth or t not in rec.ranges]
    if missing:
        raise ValueError(f"{rec.label}: no ranges or truth for tags {missing}; available {list(rec.truth)}")
    if dim == 2 and (z_m is None or any(t not in z_m for t in tags)):
        raise ValueError(f"{rec.label}: 2-D runs need the tag height of every tag {tags} (from calibration data "
                         f"or the dataset's description), got {z_m!r}")
    if rate_hz is not None:
        rec = rec.decimate(rate_hz=rate_hz)
    data = "synthetic" if rec.dataset == "synthetic" else rec.label
    runs = []
    for tag in tags:
        log = rec.ranges[tag]
        dev = None if raw is None else raw.get(tag)
        if dev is not None:
            dev = dev.select(np.isin(dev.t_s, log.t_s))
        runs.append(TagRun(data, name or rec.name, tag, log, rec.truth[tag], rec.anchors, dim,
                           float(z_m[tag]) if dim == 2 else 0.0, dev))
    return runs


def synthetic_acquisition(name: str, *, seed: int, duration_s: float | None = None, rate_hz: float | None = None,
                          role: str = "test", changes: Mapping | None = None,
                          label: str | None = None) -> tuple[list[TagRun], walk.WalkTruth]:
    """Simulate one acquisition of scenario ``name`` (``office``, ``agv1``, ``agv2``) and wrap its tags.

    Parameters
    ----------
    seed
        Seed of the acquisition.
    duration_s, rate_hz
        Override the scenario's length and location rate.
    role
        ``"test"`` or ``"calibration"``: an independent random stream for the same
        ``seed``, so calibration and test acquisitions never share noise.
    changes
        Further :class:`~uwbwb.sim.walk.WalkScenario` field changes (an ablation).
        The random stream depends only on ``name``, ``role`` and ``seed``, so an
        ablation sees the same walk and the same noise draws.
    label
        Display name (default ``name``; ``" (calibration)"`` is appended for that role).

    The device output (:func:`uwbwb.sim.walk.device_output`) is attached as ``raw``.
    """
    changes = dict(changes or {})
    if duration_s is not None:
        changes["duration_s"] = float(duration_s)
    if rate_hz is not None:
        changes["rate_hz"] = float(rate_hz)
    cfg = walk.scenario(name, **changes)
    rng = np.random.default_rng([int(seed), zlib.crc32(f"{name}/{role}".encode())])
    rec, truth = walk.simulate_walk(cfg, rng=rng)
    heights = {m.tag_id: m.height_m for m in cfg.tags}
    raw = {t: walk.device_output(rec.ranges[t], rec.anchors, z_m=heights[t]) for t in rec.tags}
    label = label or name
    label = label if role == "test" else f"{label} (calibration)"
    return tag_runs(rec, dim=2, z_m=heights, raw=raw, name=label), truth


# --------------------------------------------------------------------------- estimation


def ranging_summary(runs: Sequence[TagRun], truth: walk.WalkTruth) -> pd.DataFrame:
    """What the simulator did to the ranges of each tag: NLOS share, error by condition, dropouts."""
    rows = []
    for r in runs:
        nlos, err = truth.nlos[r.tag], truth.range_error_m[r.tag]
        ok = np.isfinite(err)
        rows.append({"run": r.name, "tag": r.tag, "epochs": len(r.ranges), "NLOS links (%)": 100 * nlos.mean(),
                     "LOS error mean (cm)": 100 * err[ok & ~nlos].mean(),
                     "LOS error sd (cm)": 100 * err[ok & ~nlos].std(),
                     "NLOS error mean (cm)": 100 * err[ok & nlos].mean() if (ok & nlos).any() else np.nan,
                     "missing ranges (%)": 100 * (~ok).mean()})
    return pd.DataFrame(rows).set_index(["run", "tag"])


def _protocol(runs: Sequence[TagRun], sigma_m: Mapping[str, np.ndarray]) -> tuple[Recording, Calibration]:
    """Runs (one per tag of one recording) as the board's recording, and the protocol's calibration holding the
    range σ per anchor of each tag, the tag heights and the runs' rate (1 / median epoch step); the ranges are
    used as logged (no range calibration)."""
    r0 = runs[0]
    rec = Recording(r0.data, r0.name, r0.anchors, {r.tag: r.ranges for r in runs}, {r.tag: r.truth for r in runs})
    cal = Calibration(r0.name, r0.dim, {r.tag: r.z_m for r in runs}, None, dict(sigma_m),
                      1.0 / float(np.median([r.dt_s for r in runs])))
    return rec, cal


def estimate(run: TagRun, sigma_m, sigmas: Mapping[str, float], *, gate_prob: float | None, ref: int = 0,
             correlated: bool = True, models: Sequence[str] = MODELS, tuned: Mapping | None = None) -> TagResults:
    """Raw output and the notebook's estimators (:func:`~.results.estimators`) on one run, held and scored as a
    board of its tag.

    ``raw`` is the device's own output where the run has one (an outside estimate,
    :class:`~uwbwb.scoreboard.estimators.ExternalEstimates`), else per-epoch multilateration of the ranges
    (:class:`~uwbwb.scoreboard.estimators.RawLs`); the others (``LS``, ``EKF-<model>`` ...) run on pseudo-TDoAs.
    The estimators see the ranges, never the truth.

    Parameters
    ----------
    run
        The test run.
    sigma_m
        Range-noise standard deviation per anchor (from a calibration run), metres.
    sigmas
        Driving standard deviation per model (model units, see :data:`PAPER_SIGMA`).
    ref
        Reference anchor index of the pseudo-TDoA.
    gate_prob
        χ² gate of the EKFs (None: no gating); required.
    correlated
        Model the reference correlation of the TDoA noise (False: the diagonal shortcut).
    tuned
        What the estimators tuned on the calibration runs, by estimator name (:attr:`Study.calibration`'s
        ``tuned``); ``sigmas`` replaces the EKFs' driving σ there.
    """
    rec, cal = _protocol([run], {run.tag: sigma_m})
    cal = replace(cal, tuned={**(tuned or {}), **{ekf_name(m): {"sigma_w": float(sigmas[m])} for m in models}})
    ests = {"raw": RawLs("raw") if run.raw is None else ExternalEstimates("device", {run.tag: run.raw},
                                                                                  max_gap_s=0.0),
            **estimators(gate_prob=gate_prob, ref=ref, correlated=correlated, models=models)}
    blind, truth = replace(rec, truth={}), rec.truth_at(run.tag, run.ranges.t_s, run.dim)
    entries = tuple(Entry(n, run.tag, e.estimate(blind, run.tag, cal), None, truth) for n, e in ests.items())
    return TagResults(run, Board(run.data, run.key, cal, entries, tuple(ests)))


@dataclass(frozen=True)
class Study:
    """Calibrate on some runs, test on others.

    Attributes
    ----------
    calibration
        The protocol's calibration of the calibration runs (:func:`run_study`): range σ per anchor and tag
        (``calibration.sigma(tag)``, fitted on the calibration runs), and per EKF (``"EKF-RW"`` ...) what its
        ``tune`` kept (σ_w, the grid, each tag's CEP95 and RMSE there).
    best
        Driving standard deviation per model.
    results
        One :class:`TagResults` per test run.
    """

    calibration: Calibration
    best: dict
    results: list

    @property
    def curves(self) -> pd.DataFrame:
        """The driving-noise calibration, one row per (tag, model, σ): ``run, tag, model, sigma, sigma_unit, psd,
        psd_unit, cep95_m, rmse_m`` (``psd = σ² T``)."""
        rows, cal = [], self.calibration
        for m in self.best:
            p, cls = cal.params(ekf_name(m)), MOTION_MODELS[m]
            for tag, sc in p["grid_by_tag"].items():
                rows += [{"run": cal.source, "tag": tag, "model": m, "sigma": s, "sigma_unit": cls.sigma_unit,
                          "psd": s ** 2 / cal.rate_hz, "psd_unit": cls.psd_unit, "cep95_m": c, "rmse_m": r}
                         for s, c, r in zip(p["grid"], sc["cep95"], sc["rmse"])]
        return pd.DataFrame(rows)

    def _per_run(self, values) -> pd.DataFrame:
        return pd.DataFrame([{"run": r.run.name, "tag": r.run.tag, **values(r)} for r in self.results]).set_index(
            ["run", "tag"])

    def table(self, methods: Sequence[str] | None = None) -> pd.DataFrame:
        """CEP95 (m) per test run/tag (rows) and method (columns; None: every method, in table order): every method
        on the epochs where all of a run's estimators have a position (:meth:`TagResults.common_errors`; see
        :meth:`coverage` for how many)."""
        table = self._per_run(lambda r: r.cep95())
        return table if methods is None else table[list(methods)]

    def coverage(self) -> pd.DataFrame:
        """Coverage (%) per test run/tag and method, and ``common``: the share of epochs the CEP95 tables score."""
        return self._per_run(lambda r: {k: 100 * v for k, v in r.coverage().items()})

    def nis(self) -> pd.DataFrame:
        """:meth:`TagResults.nis` of every test run, rows ``(run/tag, method)``."""
        return pd.concat({r.run.key: r.nis() for r in self.results}, names=["run/tag"])

    def result_for(self, name: str, tag: str) -> TagResults:
        """The test result of run ``name`` and ``tag``."""
        for e in self.results:
            if e.run.name == name and e.run.tag == tag:
                return e
        raise KeyError(f"no test result for {name}/{tag}; have {[e.run.key for e in self.results]}")


def _tune(name: str, estimators, rec: Recording, tags, cal: Calibration) -> dict:
    """One estimator's ``tune`` on the calibration recording (a task of :func:`run_study`'s sweep)."""
    return estimators[name].tune(rec, tags, cal)


def run_study(cal_runs: Sequence[TagRun], test_runs: Sequence[TagRun], *, gate_prob: float | None, grids=None,
              models: Sequence[str] = MODELS, ref: int = 0, progress: bool = True, scheduler=None) -> Study:
    """Fit range noise and tune every estimator on ``cal_runs`` (one run per tag of one recording), then run every
    estimator on ``test_runs``.

    The range σ per anchor of each tag is :func:`~uwbwb.calibration.fit_range_sigma` (its ``tdoa`` reading) on its
    calibration run; with the tag heights and the runs' rate it forms the protocol's
    :class:`~uwbwb.scoreboard.protocol.Calibration` (ranges as logged). On it each of the notebook's estimators
    (:func:`~.results.estimators`, with the χ² gate ``gate_prob`` (None for none; required) and reference anchor
    ``ref``) tunes itself: the driving σ per model is one value for all tags, which the board's
    :class:`~uwbwb.scoreboard.estimators.TdoaEkfEstimator` picks on the calibration runs over ``grids[model]``
    (None: the board's :data:`~uwbwb.scoreboard.estimators.EKF_GRIDS`) with the CEP95 criterion (thesis Table 1).
    ``scheduler`` says where the sweep runs, one task per estimator (:mod:`uwbwb.parallel`; None: in this
    process); the result does not depend on where it ran.
    """
    tags = [r.tag for r in cal_runs]
    if len(set(tags)) != len(tags) or len({r.name for r in cal_runs}) != 1:
        raise ValueError(f"calibration runs must be one per tag of one recording, got {[r.key for r in cal_runs]}")
    fits = {r.tag: fit_range_sigma(r) for r in cal_runs}
    missing = sorted({r.tag for r in test_runs} - set(fits))
    if missing:
        raise ValueError(f"test tags {missing} have no calibration run")
    rec, cal = _protocol(cal_runs, fits)
    ests = estimators(gate_prob=gate_prob, ref=ref, grids=grids, models=models)
    for task, params in parallel.imap(_tune, [parallel.Task({"name": n}) for n in ests],
                                      shared={"estimators": ests, "rec": rec, "tags": tags, "cal": cal},
                                      scheduler=scheduler, progress=progress, desc="tuning", unit="estimator"):
        if params:
            cal = cal.with_tuned(ests[task.params["name"]].name, params)
    best = {m: cal.params(ekf_name(m))["sigma_w"] for m in models}
    return Study(cal, best, [estimate(r, fits[r.tag], best, ref=ref, gate_prob=gate_prob, models=models,
                                      tuned=cal.tuned) for r in test_runs])
