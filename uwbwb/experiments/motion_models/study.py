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
3. driving-noise calibration: CEP95 of each EKF over a grid of driving
   standard deviations on the calibration run (:func:`calibration_curves`),
   the minimum per model (:func:`best_sigmas`);
4. on a *different* test run: raw output, LS and the three EKFs
   (:func:`estimate`), scored on the epochs where *every* estimator has a
   position (:meth:`TagResults.common_errors`), with each one's coverage beside
   it (:func:`cep95_table`, :func:`coverage_table`), and the NIS χ² verdict of
   each EKF (:meth:`TagResults.nis`);
5. headline rows for the reproduction summary, each with its kind
   (:func:`summary_rows`).

Driving "variances" follow the thesis' Table 1 units (m/s, m/s², m/s³): they
are the standard deviation ``σ_w`` of the white driving process over one step
of the nominal epoch period ``T``, i.e. PSD ``q = σ_w² T`` (see
:mod:`uwbwb.models.motion`).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ... import geometry, metrics, parallel
from ...calibration import empirical_tdoa_covariance, fit_range_sigma
from ...filters.ekf import KalmanRun, TdoaEkf
from ...filters.tdoa_ls import tdoa_least_squares
from ...models.motion import MOTION_MODELS, make_motion_model
from ...models.tdoa import TdoaModel
from ...scoreboard.estimators import EKF_GRIDS
from ...sim import walk
from ...types import Recording, TagRun, TdoaLog, Trajectory

from .results import METHODS, MODELS, TagResults, _errors, cep95_table, coverage_table, ekf_name, nis_table

__all__ = ["DEFAULT_GRIDS", "tag_runs", "synthetic_acquisition", "raw_multilateration", "ranging_summary", "estimate",
           "calibration_curves", "best_sigmas", "split_runs", "Study", "run_study", "tdoa_noise_check", "run_ekf"]


#: Default calibration grids of the driving standard deviation (model units), log-spaced over the
#: same spans as the scoreboard's EKF grids (:data:`~uwbwb.scoreboard.estimators.EKF_GRIDS`: the spans are
#: written once, so notebooks 03 and 06 tune the same EKF over the same range), 11 values each.
DEFAULT_GRIDS = {m: np.geomspace(g[0], g[-1], 11) for m, g in EKF_GRIDS.items()}


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


def raw_multilateration(run: TagRun, *, sigma_m=None, name: str = "raw") -> Trajectory:
    """Per-epoch range multilateration (:func:`uwbwb.geometry.multilaterate`, Gauss–Newton, all anchors)."""
    kw = {"z_m": run.z_m} if run.dim == 2 else {}
    res = geometry.multilaterate(run.ranges.range_m, run.anchors.pos_m, dim=run.dim, sigma_m=sigma_m, **kw)
    return res.to_trajectory(run.ranges.t_s, name=name)



def run_ekf(run: TagRun, model: str, sigma: float, measurement: TdoaModel, *, gate_prob: float | None,
            ref: int = 0, tdoa: TdoaLog | None = None) -> KalmanRun:
    """The EKF with motion model ``model`` at driving standard deviation ``sigma`` over one run.

    ``gate_prob`` is required: the χ² gate (or None, no gate) is a setting of the
    study, never left to the filter's default.
    """
    motion = make_motion_model(model, sigma=sigma, dt_s=run.dt_s, dim=run.dim)
    log = tdoa if tdoa is not None else run.tdoa(ref)
    return TdoaEkf(motion, measurement, gate_prob=gate_prob).run(log, name=ekf_name(model))


def estimate(run: TagRun, sigma_m, sigmas: Mapping[str, float], *, gate_prob: float | None, ref: int = 0,
             correlated: bool = True, models: Sequence[str] = MODELS) -> TagResults:
    """Raw output, TDoA LS and the EKFs on one run.

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
        Model the reference correlation of the TDoA noise.
    """
    measurement = TdoaModel.for_tag(run, sigma_m, correlated=correlated)
    log = run.tdoa(ref)
    ls = tdoa_least_squares(log, measurement)
    trajs = {"raw": run.raw if run.raw is not None else raw_multilateration(run), "LS": ls.to_trajectory("LS")}
    ekfs = {}
    for m in models:
        ekfs[m] = run_ekf(run, m, sigmas[m], measurement, gate_prob=gate_prob, tdoa=log)
        trajs[ekf_name(m)] = ekfs[m].to_trajectory()
    errors = {k: _errors(t, run) for k, t in trajs.items()}
    return TagResults(run, trajs, errors, ekfs, ls, {m: float(sigmas[m]) for m in models}, gate_prob,
                      len(run.ranges))


def calibration_curves(runs: Sequence[TagRun], sigma_m: Mapping[str, np.ndarray], *,
                       gate_prob: float | None, grids: Mapping[str, Sequence[float]] | None = None,
                       models: Sequence[str] = MODELS, ref: int = 0, correlated: bool = True,
                       progress: bool | None = True, workers: int = 1, scheduler=None) -> pd.DataFrame:
    """CEP95 of each EKF over a grid of driving standard deviations (thesis Table 1 procedure).

    Parameters
    ----------
    runs
        Calibration runs (with truth).
    sigma_m
        Range-noise standard deviation per anchor for each run, keyed by :attr:`TagRun.key`.
    gate_prob
        χ² gate of the EKFs (None: no gating); required.
    grids
        Driving standard deviations per model (default :data:`DEFAULT_GRIDS`).
    workers, scheduler
        Threads in this process, or a Dask scheduler (``"local"``, an address or a
        ``distributed.Client``): each (run, model) pair is one task of the sweep
        (:mod:`uwbwb.parallel`); the table does not depend on where it ran.

    Each EKF is scored over its own epochs (it has a position at every epoch
    after its first LS fix).

    Returns
    -------
    DataFrame
        One row per (run, model, sigma): ``run, tag, model, sigma, sigma_unit, psd, psd_unit,
        cep95_m, rmse_m``.
    """
    grids = {m: tuple(map(float, g)) for m, g in dict(DEFAULT_GRIDS if grids is None else grids).items()}
    tasks = [parallel.Task({"key": r.key, "model": m}, size=len(grids[m])) for r in runs for m in models]
    shared = {"runs": {r.key: r for r in runs}, "sigma_m": {r.key: sigma_m[r.key] for r in runs}, "grids": grids,
              "ref": ref, "gate_prob": gate_prob, "correlated": correlated}
    rows = []
    for _, out in parallel.imap(_curve_task, tasks, shared=shared, workers=workers, scheduler=scheduler,
                                progress=progress, desc="driving-noise calibration", unit="EKF run"):
        rows.extend(out)
    return pd.DataFrame(rows)


def _curve_task(key: str, model: str, runs, sigma_m, grids, ref, gate_prob, correlated) -> list[dict]:
    """One run's calibration curve for one motion model (a task of :func:`calibration_curves`)."""
    r = runs[key]
    meas, log = TdoaModel.for_tag(r, sigma_m[key], correlated=correlated), r.tdoa(ref)
    cls = MOTION_MODELS[model]
    rows = []
    for s in grids[model]:
        res = run_ekf(r, model, s, meas, gate_prob=gate_prob, tdoa=log)
        err = _errors(res.to_trajectory(), r).err_m
        rows.append({"run": r.name, "tag": r.tag, "model": model, "sigma": s, "sigma_unit": cls.sigma_unit,
                     "psd": s ** 2 * r.dt_s, "psd_unit": cls.psd_unit,
                     "cep95_m": metrics.cep95(err), "rmse_m": metrics.rmse(err)})
    return rows


def best_sigmas(curves: pd.DataFrame) -> dict[str, float]:
    """Per model, the grid value minimising the mean CEP95 over the calibration runs/tags.

    One value per model and scenario, as in the thesis' Table 1.
    """
    mean = curves.groupby(["model", "sigma"], sort=True)["cep95_m"].mean().reset_index()
    best = mean.loc[mean.groupby("model")["cep95_m"].idxmin()]
    return {m: float(s) for m, s in zip(best["model"], best["sigma"])}


def split_runs(runs: Sequence[TagRun], fraction: float = 0.5) -> tuple[list[TagRun], list[TagRun]]:
    """Split each run in time: the first ``fraction`` for calibration, the rest for testing.

    The names say which part (``"fast 0–67 s"``). Used when a dataset has a single
    run of the kind (the LIAS ``fast`` run): calibration and test never share epochs.
    """
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must be in (0, 1), got {fraction!r}")
    first, second = [], []
    for r in runs:
        t0, t1 = float(r.ranges.t_s[0]), float(r.ranges.t_s[-1])
        tm = t0 + fraction * (t1 - t0)
        first.append(r.between(t0, tm, name=f"{r.name} {t0:.0f}–{tm:.0f} s"))
        second.append(r.between(tm, t1 + 1e-9, name=f"{r.name} {tm:.0f}–{t1:.0f} s"))
    return first, second


@dataclass(frozen=True)
class Study:
    """Calibrate on some runs, test on others.

    Attributes
    ----------
    curves
        Calibration curves (:func:`calibration_curves`).
    best
        Driving standard deviation per model (:func:`best_sigmas`).
    sigma_m
        Range-noise standard deviation per anchor, per tag, fitted on the calibration runs.
    results
        One :class:`TagResults` per test run.
    """

    curves: pd.DataFrame
    best: dict
    sigma_m: dict
    results: list

    def table(self, methods: Sequence[str] = METHODS, *, common: bool = True) -> pd.DataFrame:
        """CEP95 per test run (rows) and method (columns), metres (:func:`cep95_table`)."""
        return cep95_table(self.results, methods, common=common)

    def coverage(self, methods: Sequence[str] = METHODS) -> pd.DataFrame:
        """Coverage (%) per test run and method (:func:`coverage_table`)."""
        return coverage_table(self.results, methods)

    def nis(self, prob: float = 0.95) -> pd.DataFrame:
        """NIS verdict per test run and EKF (:func:`nis_table`)."""
        return nis_table(self.results, prob)

    def result_for(self, name: str, tag: str) -> TagResults:
        """The test result of run ``name`` and ``tag``."""
        for e in self.results:
            if e.run.name == name and e.run.tag == tag:
                return e
        raise KeyError(f"no test result for {name}/{tag}; have {[e.run.key for e in self.results]}")


def run_study(cal_runs: Sequence[TagRun], test_runs: Sequence[TagRun], *, gate_prob: float | None, grids=None,
              models: Sequence[str] = MODELS, ref: int = 0, correlated: bool = True, sigma_method: str = "tdoa",
              progress: bool = True, scheduler=None) -> Study:
    """Fit range noise and driving noise on ``cal_runs``, then run every estimator on ``test_runs``.

    ``gate_prob`` (the EKFs' χ² gate, None for none) is required. ``scheduler`` says
    where the driving-noise calibration sweep runs (:func:`calibration_curves`; None:
    in this process).

    A test run takes the range-noise fit of the calibration run with the same tag
    (pooled over those runs by taking the RMS when a tag has several). The driving
    noise per model is one value for all tags (:func:`best_sigmas`).
    """
    fits = {r.key: fit_range_sigma(r, method=sigma_method) for r in cal_runs}
    per_tag: dict[str, list] = {}
    for r in cal_runs:
        per_tag.setdefault(r.tag, []).append(fits[r.key])
    sigma_tag = {t: np.sqrt(np.mean(np.square(v), axis=0)) for t, v in per_tag.items()}
    missing = sorted({r.tag for r in test_runs} - set(sigma_tag))
    if missing:
        raise ValueError(f"test tags {missing} have no calibration run")
    curves = calibration_curves(cal_runs, fits, grids=grids, models=models, ref=ref, gate_prob=gate_prob,
                                correlated=correlated, progress=progress, scheduler=scheduler)
    best = best_sigmas(curves)
    ests = [estimate(r, sigma_tag[r.tag], best, ref=ref, gate_prob=gate_prob, correlated=correlated, models=models)
            for r in test_runs]
    return Study(curves, best, sigma_tag, ests)



def tdoa_noise_check(run: TagRun, sigma_m, *, ref: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Empirical covariance of the TDoA errors of ``run`` next to the model's ``diag(σ_j²) + σ_ref² 11ᵀ``.

    Uses the epochs where every anchor was measured (reference ``ref``); rows and
    columns are the anchors other than ``ref``. Returns ``(empirical, model)``, m².
    """
    log = run.tdoa(ref)
    true = run.true_range_m()
    true_tdoa = true - true[:, [ref]]
    empirical = empirical_tdoa_covariance(log.tdoa_m, true_tdoa, ref)
    others = np.delete(np.arange(len(run.anchors)), ref)
    return empirical, TdoaModel.for_tag(run, sigma_m).covariance(others, ref)
