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
from typing import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from ... import geometry, metrics, parallel
from ...calibration import empirical_tdoa_covariance, fit_range_sigma
from ...filters.ekf import KalmanRun, TdoaEkf
from ...filters.tdoa_ls import TdoaLsResult, tdoa_least_squares
from ...models.motion import MOTION_MODELS, make_motion_model
from ...models.tdoa import TdoaModel
from ...sim import walk
from ...types import Recording, TagRun, TdoaLog, Trajectory

__all__ = [
    "MODELS", "METHODS", "PAPER_SIGMA", "PAPER_METHODS_CEP95", "PAPER_MODELS_CEP95", "DEFAULT_GRIDS",
    "TagResults", "tag_runs", "synthetic_acquisition",
    "raw_multilateration", "ranging_summary", "estimate", "calibration_curves", "best_sigmas", "cep95_table",
    "coverage_table", "nis_table", "ranking", "paper_table", "split_runs", "Study", "run_study",
    "tdoa_noise_check", "ekf_name", "run_ekf", "SIGMA_KIND", "summary_rows", "sigma_rows", "record",
]

#: Motion models in the thesis' order.
MODELS = ("RW", "RF", "RJ")

#: Every estimator of a :class:`TagResults`, in table order.
METHODS = ("raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ")

#: Thesis Table 1: driving-process standard deviation per model and scenario (m/s, m/s², m/s³).
#: The AGV row prints "1 m/" for RW; read as 1 m/s.
PAPER_SIGMA = {"office": {"RW": 0.83, "RF": 1.0, "RJ": 1.0}, "agv": {"RW": 1.0, "RF": 1.0, "RJ": 1.0}}

#: Thesis Tables 2 (office) and 4 (AGV): CEP95 (m) of EKF (random walk), LS and the raw T4F output.
PAPER_METHODS_CEP95 = {
    ("office", "tag1"): {"EKF-RW": 0.41, "LS": 1.02, "raw": 1.23},
    ("office", "tag2"): {"EKF-RW": 0.48, "LS": 1.02, "raw": 2.03},
    ("agv1", "tag1"): {"EKF-RW": 0.41, "LS": 0.77, "raw": 1.03},
    ("agv1", "tag2"): {"EKF-RW": 0.44, "LS": 0.76, "raw": 0.61},
    ("agv2", "tag1"): {"EKF-RW": 0.35, "LS": 0.37, "raw": 0.46},
    ("agv2", "tag2"): {"EKF-RW": 0.34, "LS": 0.45, "raw": 0.60},
}

#: Thesis Tables 3 (office) and 5 (AGV): CEP95 (m) per motion model. Table 5 labels its rows
#: "Acq 1 Tag 1, Acq 1 Tag 2, Acq 1 Tag 1, Acq 1 Tag 2"; we read them in order as acquisitions
#: 1 and 2 (the third label repeats a row name; its values differ from the first row).
PAPER_MODELS_CEP95 = {
    ("office", "tag1"): {"EKF-RW": 0.41, "EKF-RF": 0.77, "EKF-RJ": 1.03},
    ("office", "tag2"): {"EKF-RW": 0.48, "EKF-RF": 1.13, "EKF-RJ": 1.14},
    ("agv1", "tag1"): {"EKF-RW": 0.13, "EKF-RF": 0.25, "EKF-RJ": 0.33},
    ("agv1", "tag2"): {"EKF-RW": 0.44, "EKF-RF": 0.60, "EKF-RJ": 0.58},
    ("agv2", "tag1"): {"EKF-RW": 0.44, "EKF-RF": 0.60, "EKF-RJ": 0.59},
    ("agv2", "tag2"): {"EKF-RW": 0.34, "EKF-RF": 0.34, "EKF-RJ": 0.28},
}

#: Default calibration grids of the driving standard deviation (model units), log-spaced.
DEFAULT_GRIDS = {"RW": np.geomspace(0.05, 5.0, 11), "RF": np.geomspace(0.05, 20.0, 11),
                 "RJ": np.geomspace(0.05, 100.0, 11)}


def ekf_name(model: str) -> str:
    """Estimator label of the EKF with ``model`` (``"EKF-RW"`` ...), as in :data:`uwbwb.plotting.COLORS`."""
    return f"EKF-{model}"


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
        dt = float(np.median(np.concatenate([np.diff(rec.ranges[t].t_s) for t in tags])))
        rec = rec.decimate(max(1, int(np.floor(1.0 / (rate_hz * dt) + 1e-9))))
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


@dataclass(frozen=True)
class TagResults:
    """Every estimator's output for one :class:`TagRun`.

    Attributes
    ----------
    run
        The input.
    trajectories
        Name → trajectory (``"raw"``, ``"LS"``, ``"EKF-RW"``, ...); an estimator leaves
        out the epochs where it has no position (LS: too few anchors or no
        convergence; EKF: before its first LS fix).
    errors
        Name → horizontal errors against truth over that estimator's own epochs
        (:class:`~uwbwb.metrics.ErrorSeries`).
    ekf
        Model → EKF result.
    ls
        The LS result (per-epoch status included).
    sigmas
        Model → driving standard deviation used.
    gate_prob
        The EKFs' χ² gate (None: every measurement used).
    n_epochs
        Epochs in the run (the denominator of coverage).

    Notes
    -----
    Scoring. Estimators cover different epochs: LS fails at an epoch with too
    few anchors where the EKF coasts on its prediction. CEP95 over each one's own
    epochs would score LS on the easy epochs only, so the tables score every
    estimator on the *common* epochs (those where all of them have a position
    and truth exists, :meth:`common_errors`) and give each one's coverage
    (:meth:`coverage`) beside it.
    """

    run: TagRun
    trajectories: dict
    errors: dict
    ekf: dict
    ls: TdoaLsResult
    sigmas: dict
    gate_prob: float | None
    n_epochs: int

    def common_t_s(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Epoch times scored by every estimator in ``names`` (default: all), seconds."""
        names = list(self.errors) if names is None else list(names)
        t = None
        for n in names:
            e = self.errors[n]
            tn = e.t_s[np.isfinite(e.err_m)]
            t = tn if t is None else np.intersect1d(t, tn)
        return np.asarray(t, float)

    def common_errors(self, names: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Name → horizontal errors (m) at :meth:`common_t_s`, the same epochs for every estimator."""
        names = list(self.errors) if names is None else list(names)
        t = self.common_t_s(names)
        if t.size == 0:
            cov = {k: f"{100 * v:.0f} %" for k, v in self.coverage_own().items()}
            raise ValueError(f"{self.run.key}: no epoch where every estimator of {names} has a position and truth "
                             f"exists (coverage {cov}); nothing can be scored on common epochs")
        return {n: self.errors[n].err_m[np.isin(self.errors[n].t_s, t)] for n in names}

    def cep95(self, *, common: bool = True) -> dict[str, float]:
        """Name → CEP95 (m), on the common epochs (default) or on each estimator's own."""
        if common:
            return {k: metrics.cep95(e) for k, e in self.common_errors().items()}
        return {k: metrics.cep95(e.err_m) for k, e in self.errors.items()}

    def coverage_own(self) -> dict[str, float]:
        """Name → fraction of the run's epochs with a position."""
        return {k: len(t) / self.n_epochs for k, t in self.trajectories.items()}

    def coverage(self) -> dict[str, float]:
        """:meth:`coverage_own`, and ``"common"``: the share of epochs the tables score."""
        return {**self.coverage_own(), "common": self.common_t_s().size / self.n_epochs}

    def nis(self, prob: float = 0.95) -> pd.DataFrame:
        """NIS consistency per EKF (:meth:`uwbwb.filters.ekf.KalmanRun.nis_consistency`).

        Under right noise models the NIS summed over the ``n`` updates is χ² with
        ``sum_dof`` degrees of freedom; the verdict compares it with the central
        ``prob`` interval of that χ² (``mean_lo``, ``mean_hi``: the interval divided
        by ``sum_dof``, around a mean NIS per degree of freedom of 1).
        *Over-confident*: errors larger than the filter's covariance says.
        """
        rows = []
        for m, r in self.ekf.items():
            c = r.nis_consistency(prob)
            dof = max(c["sum_dof"], 1)
            rows.append({"model": m, "n": c["n"], "mean_nis_over_dof": c["mean_nis_over_dof"],
                         "mean_lo": c["sum_lo"] / dof, "mean_hi": c["sum_hi"] / dof,
                         "fraction_inside": c["fraction_inside"], "verdict": c["verdict"],
                         "n_rejected": int(r.n_rejected.sum())})
        return pd.DataFrame(rows).set_index("model")


def _errors(traj: Trajectory, run: TagRun) -> metrics.ErrorSeries:
    return metrics.errors_vs_truth(traj, run.truth, horizontal=True, max_gap_s=TagRun.max_truth_gap_s)


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


def cep95_table(results: Iterable[TagResults], methods: Sequence[str] = METHODS, *,
                common: bool = True) -> pd.DataFrame:
    """CEP95 (m) per run/tag (rows) and method (columns).

    ``common=True`` (default): every method on the epochs where all of a run's
    estimators have a position (:meth:`TagResults.common_errors`); False: each
    method over its own epochs (see :func:`coverage_table` for how many).
    """
    rows = []
    for res in results:
        c = res.cep95(common=common)
        rows.append({"run": res.run.name, "tag": res.run.tag, **{m: c[m] for m in methods}})
    return pd.DataFrame(rows).set_index(["run", "tag"])


def coverage_table(results: Iterable[TagResults], methods: Sequence[str] = METHODS) -> pd.DataFrame:
    """Coverage (%) per run/tag and method, and ``common``: the share of epochs the CEP95 tables score."""
    rows = []
    for res in results:
        c = res.coverage()
        rows.append({"run": res.run.name, "tag": res.run.tag, **{m: 100 * c[m] for m in (*methods, "common")}})
    return pd.DataFrame(rows).set_index(["run", "tag"])


def nis_table(results: Iterable[TagResults], prob: float = 0.95) -> pd.DataFrame:
    """:meth:`TagResults.nis` of several runs, rows ``(run/tag, model)``."""
    return pd.concat({res.run.key: res.nis(prob) for res in results}, names=["run/tag"])


def ranking(table: pd.DataFrame, models: Sequence[str] = MODELS) -> pd.Series:
    """Order of the motion models by CEP95 per row, e.g. ``"RW < RF < RJ"``."""
    cols = [ekf_name(m) for m in models]

    def order(row):
        ranked = sorted(zip(row[cols], models))
        return " < ".join(m for _, m in ranked)

    return table.apply(order, axis=1).rename("ranking")


def paper_table(paper: Mapping, keys: Sequence[tuple[str, str]], methods: Sequence[str]) -> pd.DataFrame:
    """The thesis' CEP95 values for ``keys`` (scenario, tag) in the layout of :func:`cep95_table`."""
    rows = [{"run": k[0], "tag": k[1], **{m: paper.get(k, {}).get(m, np.nan) for m in methods}} for k in keys]
    return pd.DataFrame(rows).set_index(["run", "tag"])


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


# --------------------------------------------------------------------------- summary rows


#: Kind of each calibrated driving σ in the summary. The simulated targets move at a speed
#: chosen equal to the thesis' random-walk σ (0.83 m/s walking, 1 m/s AGV; the thesis gives no
#: speeds), so the calibrated RW σ lands near the thesis' value by construction: a *target*.
SIGMA_KIND = {"RW": "target", "RF": "reproduced", "RJ": "reproduced"}


def sigma_rows(best: Mapping[str, float], scenario: str) -> list[dict]:
    """Summary rows of the calibrated driving σ of one synthetic scenario (``"office"``/``"agv"``), with kind."""
    return [{"quantity": f"driving sigma {m} ({scenario})", "value": float(best[m]),
             "unit": MOTION_MODELS[m].sigma_unit, "data": "synthetic", "paper_value": PAPER_SIGMA[scenario][m],
             "kind": SIGMA_KIND[m]} for m in MODELS if m in best]


def summary_rows(results: Iterable[TagResults], *, data: str, label: str = "{run} {tag} {method}",
                 paper: bool = False) -> list[dict]:
    """Headline rows of test results: CEP95 on common epochs, coverage, mean NIS/dof (all *reproduced*).

    Parameters
    ----------
    results
        Test results.
    data
        Summary ``data`` label (``"synthetic"`` or ``"dataset/recording"``).
    label
        Format of the quantity's name with fields ``run``, ``tag``, ``method``.
    paper
        Attach the thesis' CEP95 (Tables 2–5) where ``(run, tag)`` is one of its rows;
        for the AGV runs the random-walk EKF also gets a row against Table 5, which
        disagrees with Table 4 on acquisition 1 tag 1.
    """
    rows = []
    for res in results:
        key = (res.run.name, res.run.tag)
        c, cov = res.cep95(), res.coverage()
        nis = res.nis()["mean_nis_over_dof"]

        def name(method):
            return label.format(run=res.run.name, tag=res.run.tag, method=method)

        for meth in c:
            pv = None
            if paper:
                pv = PAPER_METHODS_CEP95.get(key, {}).get(meth, PAPER_MODELS_CEP95.get(key, {}).get(meth))
            rows.append({"quantity": f"CEP95 {name(meth)}", "value": c[meth], "unit": "m", "data": data,
                         "paper_value": pv, "kind": "reproduced"})
        if paper and key[0].startswith("agv") and key in PAPER_MODELS_CEP95:
            rows.append({"quantity": f"CEP95 {name('EKF-RW')} (vs thesis Table 5)", "value": c["EKF-RW"],
                         "unit": "m", "data": data, "paper_value": PAPER_MODELS_CEP95[key]["EKF-RW"],
                         "kind": "reproduced"})
        for meth in c:
            rows.append({"quantity": f"coverage {name(meth)}", "value": 100 * cov[meth], "unit": "%", "data": data,
                         "paper_value": None, "kind": "reproduced"})
        for m, v in nis.items():
            if np.isfinite(v):
                rows.append({"quantity": f"mean NIS/dof {name(ekf_name(m))}", "value": float(v), "unit": "",
                             "data": data, "paper_value": None, "kind": "reproduced"})
    return rows


def record(summary: metrics.Summary, rows: Iterable[dict]) -> None:
    """Add :func:`summary_rows` / :func:`sigma_rows` rows to a :class:`~uwbwb.metrics.Summary`."""
    for r in rows:
        summary.add(**r)
