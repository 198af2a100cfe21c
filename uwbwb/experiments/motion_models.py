"""Notebook 03: TDoA EKF with random-walk / random-force / random-jerk models vs LS and raw output.

Reproduces De Angelis, *Analysis of the performance of an UWB localization
system using Bayesian tracking filters* (Politecnico di Milano, thesis summary,
2021–22): pseudo-TDoA from two-way ranges, a per-epoch Gauss–Newton LS fix, an
EKF with three motion models whose driving-noise level is calibrated against
ground truth (Table 1), and CEP95 tables (Tables 2–5) and path figures (Figs 5–10).

The pipeline for one tag of one recording (:class:`~uwbwb.types.TagRun`):

1. ranges → pseudo-TDoA to a reference anchor (:class:`~uwbwb.types.TdoaLog`);
2. range-noise level per anchor from a *calibration* run with truth
   (:func:`fit_range_sigma`; by default the part of the range error that does
   not cancel in a TDoA) → TDoA covariance ``Σ = diag(σ_j²) + σ_ref² 11ᵀ``;
3. driving-noise calibration: CEP95 of each EKF over a grid of driving
   standard deviations on the calibration run (:func:`calibration_curves`),
   the minimum per model (:func:`best_sigmas`);
4. on a *different* test run: raw output, LS and the three EKFs
   (:func:`estimate`), CEP95 tables (:func:`cep95_table`) and figures;
5. the comparison with the thesis, written from the run's numbers
   (:func:`discussion_markdown`).

Driving "variances" follow the thesis' Table 1 units (m/s, m/s², m/s³): they
are the standard deviation ``σ_w`` of the white driving process over one step
of the nominal epoch period ``T``, i.e. PSD ``q = σ_w² T`` (see
:mod:`uwbwb.models.motion`).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field, replace
from typing import Iterable, Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from .. import geometry, metrics, plotting
from ..filters.ekf import EkfResult, TdoaEkf
from ..filters.tdoa_ls import TdoaLsResult, tdoa_least_squares
from ..models.motion import MOTION_MODELS, make_motion_model
from ..models.tdoa import TdoaModel, empirical_tdoa_covariance, range_sigma_from_truth
from ..sim import walk
from ..types import RangeLog, Recording, TagRun, TdoaLog, Trajectory

__all__ = [
    "MODELS", "PAPER_SIGMA", "PAPER_METHODS_CEP95", "PAPER_MODELS_CEP95", "DEFAULT_GRIDS",
    "Estimates", "tag_runs", "thin", "synthetic_acquisition", "fit_range_sigma",
    "raw_multilateration", "ranging_summary", "estimate", "calibration_curves", "best_sigmas", "cep95_table", "ranking",
    "paper_table", "split_runs", "Study", "run_study", "tdoa_noise_check", "banner", "scenario_figure",
    "covariance_figure", "calibration_figure", "paths_figure", "cdf_figure", "ekf_name", "run_ekf",
    "discussion_markdown",
]

#: Motion models in the thesis' order.
MODELS = ("RW", "RF", "RJ")

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


def tag_runs(rec: Recording, tags: Sequence[str] | None = None, *, dim: int = 2, z_m: Mapping | None = None,
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
        2 (known height) or 3.
    z_m
        Tag height per tag for ``dim=2``; default: the median truth height of the tag
        (a rigidly mounted tag's height is known in practice).
    rate_hz
        Decimate to at most this rate (see :meth:`TagRun.decimated`).
    raw
        The device's own output per tag, if any.
    name
        Display name (default ``rec.name``).
    """
    tags = list(tags) if tags is not None else [t for t in rec.tags if t in rec.truth]
    missing = [t for t in tags if t not in rec.truth or t not in rec.ranges]
    if missing:
        raise ValueError(f"{rec.label}: no ranges or truth for tags {missing}; available {list(rec.truth)}")
    data = "synthetic" if rec.dataset == "synthetic" else rec.label
    runs = []
    for tag in tags:
        truth = rec.truth[tag]
        h = float(np.median(truth.pos_m[:, 2])) if truth.dim == 3 else 0.0
        if z_m is not None and tag in z_m:
            h = float(z_m[tag])
        runs.append(TagRun(data, name or rec.name, tag, rec.ranges[tag], truth, rec.anchors, dim, h,
                           None if raw is None else raw.get(tag)).decimated(rate_hz))
    return runs


def thin(recordings: Iterable[Recording], step: int) -> list[Recording]:
    """Every ``step``-th epoch of each tag's ranges and truth (for FAST runs of slow fits)."""
    out = []
    for rec in recordings:
        ranges = {t: log.select(slice(None, None, step)) for t, log in rec.ranges.items()}
        truth = {t: tr.select(slice(None, None, step)) for t, tr in rec.truth.items()}
        out.append(replace(rec, ranges=ranges, truth=truth))
    return out


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


def fit_range_sigma(run: TagRun, *, method: str = "tdoa", floor_m: float = 0.02) -> np.ndarray:
    """Range-noise standard deviation per anchor from a run with truth, ``(n_anchors,)``, metres.

    The thesis builds its TDoA covariance from the measurement errors of its
    acquisitions; three readings of that are offered:

    ``"tdoa"`` (default)
        RMS of the range errors after removing, at every epoch, their mean over
        the anchors measured (× ``sqrt(n/(n−1))`` to undo the shrinkage for
        independent errors). A range error common to all anchors cancels in
        every TDoA, so this is the part of the error the TDoA filter sees; the
        rest (per-anchor biases, NLOS excursions) stays in.
    ``"rms"``
        RMS of the range errors themselves (common part included).
    ``"robust"``
        1.4826·MAD around the median (spread only, biases and outliers excluded).

    Values are floored at ``floor_m`` (range resolution, unmodelled effects).
    """
    err = run.ranges.range_m - run.true_range_m()
    if method == "tdoa":
        ok = np.isfinite(err)
        n = ok.sum(axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            common = np.where(n >= 2, np.nansum(np.where(ok, err, 0.0), axis=1, keepdims=True) / n, np.nan)
            shrink = np.where(n >= 2, n / np.maximum(n - 1, 1), np.nan)
        centred = (err - common) * np.sqrt(shrink)
        sig = range_sigma_from_truth(centred, np.zeros_like(centred), robust=False)
    elif method in ("rms", "robust"):
        sig = range_sigma_from_truth(run.ranges.range_m, run.true_range_m(), robust=method == "robust")
    else:
        raise ValueError(f"method must be 'tdoa', 'rms' or 'robust', got {method!r}")
    return np.maximum(sig, floor_m)


def raw_multilateration(run: TagRun, *, sigma_m=None, name: str = "raw") -> Trajectory:
    """Per-epoch range multilateration (:func:`uwbwb.geometry.multilaterate`, Gauss–Newton, all anchors)."""
    kw = {"z_m": run.z_m} if run.dim == 2 else {}
    res = geometry.multilaterate(run.ranges.range_m, run.anchors.pos_m, dim=run.dim, sigma_m=sigma_m, **kw)
    return res.to_trajectory(run.ranges.t_s, name=name)


@dataclass(frozen=True)
class Estimates:
    """Every estimator's output for one :class:`TagRun`.

    Attributes
    ----------
    run
        The input.
    trajectories
        Name → trajectory (``"raw"``, ``"LS"``, ``"EKF-RW"``, ...).
    errors
        Name → horizontal errors against truth (:class:`~uwbwb.metrics.ErrorSeries`).
    ekf
        Model → EKF result.
    ls
        The LS result (per-epoch status included).
    sigmas
        Model → driving standard deviation used.
    n_epochs
        Epochs in the run (for coverage: estimators may leave epochs out).
    """

    run: TagRun
    trajectories: dict
    errors: dict
    ekf: dict
    ls: TdoaLsResult
    sigmas: dict
    n_epochs: int

    def cep95(self) -> dict[str, float]:
        """Name → CEP95 (m)."""
        return {k: metrics.cep95(e.err_m) for k, e in self.errors.items()}

    def coverage(self) -> dict[str, float]:
        """Name → fraction of the run's epochs with an estimate."""
        return {k: len(t) / self.n_epochs for k, t in self.trajectories.items()}

    def nis(self) -> pd.DataFrame:
        """NIS consistency per EKF (see :meth:`~uwbwb.filters.ekf.EkfResult.nis_consistency`)."""
        rows = [{"model": m, **r.nis_consistency(), "n_rejected": int(r.n_rejected.sum())} for m, r in self.ekf.items()]
        return pd.DataFrame(rows).set_index("model")


def _errors(traj: Trajectory, run: TagRun) -> metrics.ErrorSeries:
    return metrics.errors_vs_truth(traj, run.truth, horizontal=True, max_gap_s=TagRun.max_truth_gap_s)


def run_ekf(run: TagRun, model: str, sigma: float, measurement: TdoaModel, *, ref: int = 0,
            gate_prob: float | None = None, tdoa: TdoaLog | None = None) -> EkfResult:
    """The EKF with motion model ``model`` at driving standard deviation ``sigma`` over one run."""
    motion = make_motion_model(model, sigma=sigma, dt_s=run.dt_s, dim=run.dim)
    log = tdoa if tdoa is not None else run.tdoa(ref)
    return TdoaEkf(motion, measurement, gate_prob=gate_prob).run(log, name=ekf_name(model))


def estimate(run: TagRun, sigma_m, sigmas: Mapping[str, float], *, ref: int = 0, gate_prob: float | None = None,
             correlated: bool = True, models: Sequence[str] = MODELS) -> Estimates:
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
        χ² gate of the EKFs (None: no gating).
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
    return Estimates(run, trajs, errors, ekfs, ls, {m: float(sigmas[m]) for m in models}, len(run.ranges))


def calibration_curves(runs: Sequence[TagRun], sigma_m: Mapping[str, np.ndarray], *,
                       grids: Mapping[str, Sequence[float]] | None = None, models: Sequence[str] = MODELS,
                       ref: int = 0, gate_prob: float | None = None, correlated: bool = True,
                       progress: bool = True) -> pd.DataFrame:
    """CEP95 of each EKF over a grid of driving standard deviations (thesis Table 1 procedure).

    Parameters
    ----------
    runs
        Calibration runs (with truth).
    sigma_m
        Range-noise standard deviation per anchor for each run, keyed by :attr:`TagRun.key`.
    grids
        Driving standard deviations per model (default :data:`DEFAULT_GRIDS`).

    Returns
    -------
    DataFrame
        One row per (run, model, sigma): ``run, tag, model, sigma, sigma_unit, psd, psd_unit,
        cep95_m, rmse_m``.
    """
    from tqdm.auto import tqdm

    grids = dict(DEFAULT_GRIDS if grids is None else grids)
    jobs = [(r, m, s) for r in runs for m in models for s in grids[m]]
    rows = []
    cache = {}
    for r, m, s in tqdm(jobs, desc="driving-noise calibration", disable=not progress, leave=False):
        if r.key not in cache:
            cache[r.key] = (TdoaModel.for_tag(r, sigma_m[r.key], correlated=correlated), r.tdoa(ref))
        meas, log = cache[r.key]
        res = run_ekf(r, m, float(s), meas, gate_prob=gate_prob, tdoa=log)
        err = _errors(res.to_trajectory(), r).err_m
        cls = MOTION_MODELS[m]
        rows.append({"run": r.name, "tag": r.tag, "model": m, "sigma": float(s), "sigma_unit": cls.sigma_unit,
                     "psd": float(s) ** 2 * r.dt_s, "psd_unit": cls.psd_unit,
                     "cep95_m": metrics.cep95(err), "rmse_m": metrics.rmse(err)})
    return pd.DataFrame(rows)


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
    estimates
        One :class:`Estimates` per test run.
    """

    curves: pd.DataFrame
    best: dict
    sigma_m: dict
    estimates: list

    def table(self, methods: Sequence[str] = ("raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ")) -> pd.DataFrame:
        """CEP95 per test run (rows) and method (columns), metres."""
        return cep95_table(self.estimates, methods)

    def estimate_for(self, name: str, tag: str) -> Estimates:
        """The test result of run ``name`` and ``tag``."""
        for e in self.estimates:
            if e.run.name == name and e.run.tag == tag:
                return e
        raise KeyError(f"no test result for {name}/{tag}; have {[e.run.key for e in self.estimates]}")


def run_study(cal_runs: Sequence[TagRun], test_runs: Sequence[TagRun], *, grids=None,
              models: Sequence[str] = MODELS, ref: int = 0, gate_prob: float | None = None,
              correlated: bool = True, sigma_method: str = "tdoa", progress: bool = True) -> Study:
    """Fit range noise and driving noise on ``cal_runs``, then run every estimator on ``test_runs``.

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
                                correlated=correlated, progress=progress)
    best = best_sigmas(curves)
    ests = [estimate(r, sigma_tag[r.tag], best, ref=ref, gate_prob=gate_prob, correlated=correlated, models=models)
            for r in test_runs]
    return Study(curves, best, sigma_tag, ests)


def cep95_table(estimates: Iterable[Estimates], methods: Sequence[str]) -> pd.DataFrame:
    """CEP95 (m) per run/tag (rows) and method (columns)."""
    rows = []
    for est in estimates:
        c = est.cep95()
        rows.append({"run": est.run.name, "tag": est.run.tag, **{m: c[m] for m in methods}})
    return pd.DataFrame(rows).set_index(["run", "tag"])


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


# --------------------------------------------------------------------------- discussion


#: Model differences (m) up to which two motion models count as tied in :func:`discussion_markdown`.
TIE_M = 0.02


def _m(x: float) -> str:
    return f"{x:.2f} m"


def _cm(x_m: float) -> str:
    """Centimetres with one decimal and a typographic minus."""
    return f"{100 * x_m + 0.0:.1f}".replace("-0.0", "0.0").replace("-", "−") + " cm"


def _signed_cm(x_m: float) -> str:
    return f"{100 * x_m:+.0f}".replace("-", "−") + " cm"


def _span_m(values) -> str:
    lo, hi = f"{np.min(values):.2f}", f"{np.max(values):.2f}"
    return f"{lo} m" if lo == hi else f"{lo}–{hi} m"


def _model_row(row: pd.Series) -> str:
    """How the three EKFs of one CEP95 row compare, in words."""
    cols = [ekf_name(m) for m in MODELS]
    order = sorted(cols, key=lambda c: row[c])
    spread = row[order[-1]] - row[order[0]]
    if spread <= TIE_M:
        return f"the three models are within {_cm(spread)} ({order[0][4:]} ahead)"
    lead = row[order[1]] - row[order[0]]
    if order[0] == "EKF-RW":
        return f"the random walk is {_m(lead)} better than the next model ({order[1][4:]})"
    return f"{order[0][4:]} is best, {_m(row['EKF-RW'] - row[order[0]])} ahead of the random walk"


def _rw_margin(row: pd.Series) -> float:
    """CEP95 of the better of RF and RJ minus that of RW (positive: RW ahead), metres."""
    return float(min(row["EKF-RF"], row["EKF-RJ"]) - row["EKF-RW"])


def _curve_at(curves: pd.DataFrame, model: str, sigma: float) -> float:
    """Mean calibration curve of ``model`` at ``sigma`` (log-interpolated; NaN outside the grid)."""
    mean = curves[curves.model == model].groupby("sigma")["cep95_m"].mean()
    s = mean.index.to_numpy(float)
    if not s.min() <= sigma <= s.max():
        return np.nan
    return float(np.interp(np.log(sigma), np.log(s), mean.to_numpy(float)))


def discussion_markdown(synthetic: pd.DataFrame, *, curves: Mapping[str, pd.DataFrame],
                        best: Mapping[str, Mapping[str, float]], ablation: pd.DataFrame | None = None,
                        lias: Mapping[str, pd.DataFrame] | None = None, lias_label: str = "lias-planar-uwb",
                        iasl: pd.DataFrame | None = None, iasl_label: str = "iasl-uwb-imu",
                        office: walk.WalkScenario | None = None) -> str:
    """Notebook 03's reading of the tables against the thesis, as Markdown written from the run's numbers.

    The thesis' numbers come from :data:`PAPER_SIGMA`, :data:`PAPER_METHODS_CEP95` and
    :data:`PAPER_MODELS_CEP95`; everything about our run is read from the arguments,
    and the claims that depend on the outcome (who wins, by how much, whether the
    ablation removes the random walk's lead) are worded from the numbers.

    Parameters
    ----------
    synthetic
        CEP95 (m) of the synthetic test runs, rows ``(run, tag)`` with runs ``office``,
        ``agv1``, ``agv2``; columns ``raw, LS, EKF-RW, EKF-RF, EKF-RJ`` (:meth:`Study.table`).
    curves, best
        Scenario (``"office"``, ``"agv"``) → :attr:`Study.curves` / :attr:`Study.best`.
    ablation
        CEP95 of the body-shadowed office tag as simulated (first row) and without body
        shadow (second row), columns ``EKF-RW, EKF-RF, EKF-RJ``.
    lias
        ``"calibrated ranges"`` / ``"raw ranges"`` → CEP95 table of the LIAS test part.
    iasl
        CEP95 table of the IASL test scenario.
    office
        The office scenario simulated (default :func:`uwbwb.sim.walk.office`).
    """
    office = walk.office() if office is None else office
    shadowed = {t.tag_id for t in office.tags if t.body_shadow}
    models = [ekf_name(m) for m in MODELS]
    p_office = {k[1]: v for k, v in PAPER_MODELS_CEP95.items() if k[0] == "office"}
    tags = sorted(p_office)

    def thesis(model):
        return "/".join(f"{p_office[t][model]:.2f}" for t in tags) + " m"

    out = [f"**Reading the table.** The thesis finds the random walk clearly best (office: RW {thesis('EKF-RW')} "
           f"against RF {thesis('EKF-RF')} and RJ {thesis('EKF-RJ')}) and attributes it to walking being best "
           "described by a random walk. What this run shows:", ""]

    # --- office
    off = synthetic.loc["office"]
    rw_best = {t: _rw_margin(r) > TIE_M for t, r in off.iterrows()}
    desc = {t: _model_row(r) for t, r in off.iterrows()}

    def tag_label(t):
        return f"the body-shadowed tag ({t})" if t in shadowed else f"the unshadowed tag ({t})"

    if all(rw_best.values()):
        head = "the ranking holds on every tag"
    elif any(rw_best.values()) and {t for t, b in rw_best.items() if b} <= shadowed:
        head = "the ranking holds, but only for the body-shadowed tag"
    elif any(rw_best.values()):
        head = f"the ranking holds on {', '.join(t for t, b in rw_best.items() if b)} only"
    else:
        head = "the ranking does not hold"
    text = (f"* **Synthetic office — {head}.** "
            + "; ".join(f"On {tag_label(t)} {d}" if i == 0 else f"on {tag_label(t)} {d}"
                        for i, (t, d) in enumerate(desc.items())) + ".")
    if ablation is not None and len(ablation) >= 2:
        with_, without = _rw_margin(ablation.iloc[0]), _rw_margin(ablation.iloc[1])
        if with_ > TIE_M and without <= TIE_M:
            text += (f" The ablation above shows why: without body shadowing the random walk's lead on that tag "
                     f"({_m(with_)}) shrinks to {_m(without)} and the three models tie. The body's NLOS bias switches "
                     "anchors on and off as the walker turns — steps in the measurements that a velocity (or "
                     "acceleration) state turns into overshoot, and that a position-only model absorbs. So the "
                     "thesis' ranking is reproduced where a person's own body biases the ranges (its office "
                     "setting), not because human kinematics are a random walk.")
        else:
            text += (f" The ablation above does not single out body shadowing: the random walk's lead over the "
                     f"better of RF and RJ on that tag is {_m(with_)} with it and {_m(without)} without.")
    out.append(text)

    # --- AGV
    agv = synthetic.loc[[r for r in ("agv1", "agv2") if r in synthetic.index.get_level_values(0)]]
    margins = agv.apply(_rw_margin, axis=1)
    n_rw = int((agv[models].idxmin(axis=1) == "EKF-RW").sum())
    n = len(agv)
    if n_rw == n:
        head = "RW is best on every tag-run"
    elif 2 * n_rw > n:
        head = f"RW is usually best ({n_rw} of {n} tag-runs)"
    else:
        head = f"RW is best on only {n_rw} of {n} tag-runs"
    out.append(f"* **Synthetic AGV — {head}**; the random walk's lead over the better of RF and RJ ranges from "
               f"{_cm(margins.min())} to {_cm(margins.max())} (negative: behind). The thesis' own Table 5 is not "
               "uniform (its last row has RJ 0.28 m < RW 0.34 m, and its first row, RW 0.13 m, disagrees with Table "
               "4's 0.41 m for the same run).")

    # --- size of the gaps and the driving noise
    paper_ratio = max(v[m] / v["EKF-RW"] for v in PAPER_MODELS_CEP95.values() for m in ("EKF-RF", "EKF-RJ"))
    ratio = float((synthetic[["EKF-RF", "EKF-RJ"]].max(axis=1) / synthetic["EKF-RW"]).max())
    at_thesis = []
    for scen, c in curves.items():
        rw_min = c[c.model == "RW"].groupby("sigma")["cep95_m"].mean().min()
        for m in ("RF", "RJ"):
            v = _curve_at(c, m, PAPER_SIGMA[scen][m])
            if np.isfinite(v):
                at_thesis.append(v - rw_min)
    reproduced = "is not reproduced" if ratio - 1 < 0.5 * (paper_ratio - 1) else "is roughly reproduced"
    lose_by = (f"lose to the random walk by a factor of at most {ratio:.2f}" if ratio > 1
               else f"never lose to the random walk (CEP95 ratio at most {ratio:.2f})")
    text = (f"* **The size of the thesis' gaps {reproduced}.** With each model's driving noise calibrated on its "
            f"own, RF and RJ {lose_by} (thesis: up to {paper_ratio:.2f})")
    if at_thesis:
        lose = np.asarray(at_thesis)
        if lose.min() < 0:
            how = f"from {_cm(-lose.min())} better to {_cm(lose.max())} worse than"
        else:
            how = f"{_cm(lose.min())} to {_cm(lose.max())} worse than"
        text += (f"; along our calibration curves, at the thesis' {PAPER_SIGMA['office']['RF']:g} m/s² and "
                 f"{PAPER_SIGMA['office']['RJ']:g} m/s³ they are {how} the best random walk")
    scen_name = {"office": "office", "agv": "AGV"}
    rw = {s: b["RW"] for s, b in best.items()}
    rw_close = all(0.5 <= rw[s] / PAPER_SIGMA[s]["RW"] <= 2 for s in rw)
    text += (". Our calibrated random-walk driving noise ("
             + ", ".join(f"{v:.2g} m/s {scen_name.get(s, s)}" for s, v in rw.items()) + ") is "
             + ("within a factor of two of" if rw_close else "more than a factor of two from")
             + " the thesis' " + ", ".join(f"{PAPER_SIGMA[s]['RW']:g} m/s" for s in rw) + ".")
    phrase = {"larger": "larger values than", "smaller": "smaller values than", "equal": "the same values as"}
    for m, unit in (("RF", "m/s²"), ("RJ", "m/s³")):
        vals = {s: b[m] for s, b in best.items()}
        rel = {"larger" if v > PAPER_SIGMA[s][m] else ("smaller" if v < PAPER_SIGMA[s][m] else "equal")
               for s, v in vals.items()}
        word = phrase[rel.pop()] if len(rel) == 1 else "other values than"
        text += (f" {m} prefers {word} the thesis' {PAPER_SIGMA['office'][m]:g} {unit} ("
                 + ", ".join(f"{v:.2g} {unit} {scen_name.get(s, s)}" for s, v in vals.items()) + ").")
    out.append(text)

    # --- real data
    real = {}
    if lias is not None and "calibrated ranges" in lias:
        real[("the LIAS trolley", f"{lias_label}, calibrated ranges")] = lias["calibrated ranges"]
    if iasl is not None:
        real[("the IASL drone", iasl_label)] = iasl
    if real:
        parts, spreads, gains = [], [], []
        for (name, detail), t in real.items():
            spread = float((t[models].max(axis=1) - t[models].min(axis=1)).max())
            winners = sorted({c[4:] for c in t[models].idxmin(axis=1)})
            spreads.append(spread)
            gains.append((t["LS"] - t[models].min(axis=1)) / t["LS"])
            if len(winners) > 1:
                win = f"the winner changes from tag to tag ({', '.join(winners)})"
            else:
                win = f"{winners[0]} is best" + (" on every tag" if len(t) > 1 else "")
            parts.append(f"{'On' if not parts else 'on'} {name} ({detail}; EKF CEP95 ≈ "
                         f"{t[models].to_numpy().mean():.2f} m) the models differ by at most {_cm(spread)} and {win}")
        head = "no ranking" if max(spreads) <= TIE_M else "small differences"
        text = f"* **Real data: {head}.** " + "; ".join(parts) + "."
        g = pd.concat(gains)
        lower = f"{100 * g.mean():.0f} % lower CEP95 on average, at most {100 * g.max():.0f} %"
        if g.mean() < 0.15:
            how = "barely improve" if g.mean() < 0.05 else "improve only a little"
            text += (f" The filters {how} on LS ({lower}): with every anchor in view the per-epoch fix is already "
                     "precise, and what is left is slowly varying bias (multipath, calibration residuals) that no "
                     "motion model averages out.")
        else:
            text += f" The best filter improves on LS ({lower})."
        out.append(text)
    else:
        out.append("* **Real data.** Neither real dataset was found on this machine (sections 6–7 are skipped).")

    if lias is not None and {"calibrated ranges", "raw ranges"} <= set(lias):
        raw_t, cal_t = lias["raw ranges"], lias["calibrated ranges"]
        ls_r, ml_r = raw_t["LS"].mean(), raw_t["raw"].mean()
        ls_c, ml_c = cal_t["LS"].mean(), cal_t["raw"].mean()
        if ls_r < ml_r:
            unc = (f"Uncalibrated, TDoA LS beats range multilateration ({_m(ls_r)} against {_m(ml_r)} mean CEP95), "
                   "because the part of the per-pair biases common to all anchors cancels in the differences.")
        else:
            unc = f"Uncalibrated, TDoA LS does not beat range multilateration ({_m(ls_r)} against {_m(ml_r)})."
        if ml_c <= ls_c:
            cal = (f"Calibrated, range multilateration is as good or better ({_m(ml_c)} against {_m(ls_c)}): "
                   "differencing throws away one measurement's worth of information.")
        else:
            cal = f"Calibrated, TDoA LS is still ahead ({_m(ls_c)} against {_m(ml_c)} for range multilateration)."
        out.append(f"* **TDoA vs raw ranges on LIAS.** {unc} {cal}")

    # --- raw output and LS in the office
    p_raw = [PAPER_METHODS_CEP95[("office", t)]["raw"] for t in tags]
    p_ls = [PAPER_METHODS_CEP95[("office", t)]["LS"] for t in tags]
    p_ekf = [PAPER_METHODS_CEP95[("office", t)]["EKF-RW"] for t in tags]
    raw_o, ls_o, ekf_o = off["raw"].to_numpy(), off["LS"].to_numpy(), off["EKF-RW"].to_numpy()
    worse = "much worse than" if min(p_raw) > 1.5 * raw_o.max() else "comparable to"
    d_ours, d_thesis = float(np.mean(raw_o - ls_o)), float(np.mean(np.subtract(p_raw, p_ls)))
    if d_ours > 0:
        vs_ls = f"worse than LS, as in the thesis, but by {'less' if d_ours < d_thesis else 'more'}"
    else:
        vs_ls = "not worse than LS, unlike in the thesis"
    out.append(f"* **Raw output.** The thesis' raw T4F positions ({_span_m(p_raw)} CEP95 in the office) are {worse} "
               f"ours ({_span_m(raw_o)}); our stand-in for the device output (interpretation 6) is {vs_ls} "
               f"({_signed_cm(d_ours)} on average; thesis {_signed_cm(d_thesis)}). The T4F algorithm is unknown, "
               "so this comparison is qualitative.")
    gap = float(np.max(ls_o - ekf_o))
    biases = [o.bias_m for o in office.obstacles] + ([office.body_bias_m] if shadowed else [])
    kinder = (f"{len(office.anchor_pos_m)} well-spread anchors, {100 * office.sigma_los_m:.0f} cm LOS noise, "
              f"obstacle{' and body' if shadowed else ''} biases of {min(biases):.2f}–{max(biases):.2f} m plus an "
              f"NLOS excess of mean {office.nlos_excess_mean_m:.2f} m")
    if gap < 0.5 * (min(p_ls) - max(p_ekf)):
        ls_txt = (f"ours is within {_m(max(gap, 0.0))} of the random-walk EKF. Our simulated office may be kinder "
                  f"than the real one ({kinder}), and the thesis' LS may not have weighted the TDoAs by their "
                  "correlated covariance.")
    else:
        ls_txt = f"ours trails the random-walk EKF by up to {_m(gap)} as well (simulated office: {kinder})."
    out.append(f"* **LS.** The thesis' LS ({_span_m(p_ls)} in the office) is far worse than its EKF "
               f"({_span_m(p_ekf)}); {ls_txt}")
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- figures


def banner(message: str):
    """A conspicuous HTML banner (e.g. "real data absent: ..."), for ``IPython.display.display``."""
    import html

    from IPython.display import HTML

    return HTML('<div style="background:#fde2e1;border:2px solid #c0392b;padding:8px;font-weight:bold">'
                f"{html.escape(message)}</div>")


def scenario_figure(config: walk.WalkScenario, *, ax=None, truth: Trajectory | None = None):
    """Floor plan of a simulated scenario: anchors, obstacles (grey: low, black: full height) and the path."""
    ax = plotting.floor_plan(config.anchors, ax=ax)
    for o in config.obstacles:
        tall = o.height_m >= 1.9
        ax.plot([o.x0_m, o.x1_m], [o.y0_m, o.y1_m], color="#000000" if tall else "#9e9e9e",
                linewidth=2.5 if tall else 1.5, solid_capstyle="butt")
    xy, _ = walk.path_points(config.waypoints_m, config.corner_radius_m)
    ax.plot(np.r_[xy[:, 0], xy[0, 0]], np.r_[xy[:, 1], xy[0, 1]], color="#bdbdbd", linestyle=":", label="path")
    if truth is not None:
        ax.plot(truth.pos_m[:, 0], truth.pos_m[:, 1], color=plotting.color_for("truth"), linewidth=1, label="truth")
    ax.set_title(f"{config.name}: {len(config.anchors)} anchors, obstacles (black ≥ 1.9 m tall, grey lower)")
    ax.legend(loc="best", fontsize="small")
    return ax



def covariance_figure(empirical: np.ndarray, model: np.ndarray, labels: Sequence[str], *, title: str = ""):
    """Empirical TDoA error covariance beside the reference-correlated model, in cm², same colour scale."""
    fig, axes = plt.subplots(1, 2, figsize=(8.4, 3.8))
    vmax = 1e4 * max(np.abs(empirical).max(), np.abs(model).max())
    for ax, M, name in zip(axes, (empirical, model), ("empirical (truth)", "model diag(σ²) + σ_ref² 11ᵀ")):
        im = ax.imshow(1e4 * M, cmap="RdBu_r", vmin=-vmax, vmax=vmax)
        ax.set_xticks(range(len(labels)), labels)
        ax.set_yticks(range(len(labels)), labels)
        ax.set_title(name, fontsize="medium")
    fig.colorbar(im, ax=axes, label="cm²", shrink=0.85)
    if title:
        fig.suptitle(title)
    return fig


def calibration_figure(curves: pd.DataFrame, *, best: Mapping[str, float] | None = None,
                       paper: Mapping[str, float] | None = None, models: Sequence[str] = MODELS,
                       title: str | None = None):
    """CEP95 against driving standard deviation, one panel per motion model (thesis Table 1 procedure).

    Each run/tag is a thin line; the mean over them (what :func:`best_sigmas` minimises)
    is thick; ``best`` is marked and ``paper`` drawn as a dashed vertical line.
    Returns the Figure.
    """
    fig, axes = plt.subplots(1, len(models), figsize=(4.2 * len(models), 3.4), sharey=True, squeeze=False)
    for ax, m in zip(axes[0], models):
        sub = curves[curves.model == m]
        color = plotting.color_for(ekf_name(m))
        for (run, tag), g in sub.groupby(["run", "tag"]):
            ax.plot(g.sigma, g.cep95_m, color=color, alpha=0.35, linewidth=1, marker=".")
        mean = sub.groupby("sigma")["cep95_m"].mean()
        ax.plot(mean.index, mean.values, color=color, linewidth=2.2, label=f"{ekf_name(m)} mean")
        if best is not None and m in best:
            ax.plot([best[m]], [mean.loc[best[m]]], marker="*", markersize=13, color="#000000", linestyle="none",
                    label=f"best {best[m]:.3g} {MOTION_MODELS[m].sigma_unit}")
        if paper is not None and m in paper:
            ax.axvline(paper[m], color="#555555", linestyle="--", linewidth=1,
                       label=f"thesis {paper[m]:g} {MOTION_MODELS[m].sigma_unit}")
        ax.set_xscale("log")
        ax.set_xlabel(f"driving σ of {MOTION_MODELS[m].driven} ({MOTION_MODELS[m].sigma_unit})")
        ax.set_title(f"{m}: white {MOTION_MODELS[m].driven}")
        ax.legend(fontsize="small")
    axes[0, 0].set_ylabel("CEP95 (m)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def paths_figure(est: Estimates, names: Sequence[str] = ("EKF-RW", "LS", "raw"), *, ax=None,
                 t_range_s: tuple[float, float] | None = None):
    """Paths of the chosen estimators against truth on the floor plan (thesis Figs 5, 7, 9 / 6, 8, 10)."""
    trajs = {"truth": est.run.truth}
    trajs.update({n: est.trajectories[n] for n in names})
    if t_range_s is not None:
        trajs = {k: v.between(*t_range_s) for k, v in trajs.items()}
    ax = plotting.trajectories(trajs, ax=ax, anchors=est.run.anchors)
    ax.set_title(f"{est.run.name}, {est.run.tag}")
    return ax


def cdf_figure(est: Estimates, names: Sequence[str] = ("EKF-RW", "EKF-RF", "EKF-RJ", "LS", "raw"), *, ax=None):
    """Empirical CDFs of the horizontal error with CEP50/CEP95 marked."""
    ax = plotting.error_cdf({n: est.errors[n] for n in names}, ax=ax)
    ax.set_title(f"{est.run.name}, {est.run.tag}")
    return ax
