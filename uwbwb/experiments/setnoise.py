"""What notebook 01 calls: sensor-set switching noise and the set-noise particle filter (paper 000).

Banerjee, Suski & Hoover, *Sensor Set Switching Noise in UWB Indoor Position
Tracking*. The pieces:

* :func:`synthetic_study` — the simulated facility, its calibration campaign
  (6 locations × 1000 fixes), the calibrated :class:`~uwbwb.models.setnoise.SetNoiseModel`
  and the five Table I recordings;
* :func:`table1`, :func:`set_shares` — Table I and the Fig. 4 statistics;
* :func:`sweep` — Fig. 9: mean error against σ_d for raw fixes, baseline PF,
  set-noise PF (trials × σ_d values as one batched computation per recording) and
  the exact set-noise / baseline Kalman filters; :func:`band_summary` — the
  improvement over raw in the paper's σ_d band of 30–50 cm/s;
* :func:`trace` — Fig. 8 (one run of every filter on one recording);
* :func:`pf_kf_gap` — the PF approaching the exact KF as K grows;
* the real-data section on ``lias-planar-uwb``: :func:`real_inputs`,
  :func:`emulate_fixes` (sensor sets *emulated* on real ranges), :func:`real_study`;
* figure builders ``plot_*`` (take ``ax=``, return Axes).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from .. import geometry
from ..calibration import RangeCalibration, fit_range_calibration
from ..datasets.discovery import dataset_available
from ..filters import setnoise as filt
from ..models.setnoise import SetFixLog, SetNoiseModel, location_statistics, set_id_from_mask
from ..sim import setnoise as sim
from ..types import Recording

LIAS = "lias-planar-uwb"

#: Numbers the paper reports (Table I, section II-B1, section III).
PAPER = {
    "n_fixes": (1521, 467, 250, 164, 135),
    "speed_cmps": (11, 35, 65, 100, 120),
    "raw_error_cm": (18, 19, 21, 23, 22),
    "top5_share_pct": 85.8,
    "top1_share_max_pct": 45.0,
    "improvement_pct": 15.0,
    "improvement_cm": 5.0,
    "raw_error_all_cm": 23.0,
    "fig8_sigma_d_mps": 0.06,
}

#: σ_d values of the Fig. 9 sweep, m/s (15 values, denser where the filters change fastest).
SIGMA_D_GRID_MPS = (0.02, 0.04, 0.06, 0.08, 0.10, 0.15, 0.20, 0.25, 0.30, 0.35, 0.40, 0.50, 0.60, 0.80, 1.00)
#: The paper's band for its headline improvement ("σ_d = 30 to 50 cm/s"), m/s.
BAND_MPS = (0.30, 0.50)
#: Estimator names (also the colour keys of :mod:`uwbwb.plotting`).
RAW, BASE_PF, SET_PF, BASE_KF, SET_KF = "raw", "baseline PF", "set-noise PF", "baseline KF", "set-noise KF"
SET_KF_POOLED = "set-noise KF (pooled σ)"
FILTERS = (RAW, BASE_PF, SET_PF, BASE_KF, SET_KF, SET_KF_POOLED)


# --------------------------------------------------------------------------- configs

@dataclass(frozen=True)
class SweepConfig:
    """Size and settings of a Monte Carlo sweep over σ_d (Fig. 9).

    Attributes
    ----------
    sigma_d_mps
        Velocity-noise values, m/s.
    n_trials
        Independent PF runs per σ_d (paper: 100).
    n_particles
        K (paper: 1000).
    ess_fraction
        Resample when ESS < ess_fraction · K (paper: 0.5).
    resampler
        ``"systematic"`` (default: O(K), lowest variance) or ``"multinomial"`` (the
        paper's "select with replacement"); see :mod:`uwbwb.filters.particle`.
    common_random_numbers
        Share process-noise draws between σ_d values and the two filters of a trial
        (see :func:`uwbwb.filters.setnoise.pf_sweep`).
    n_threads
        Worker threads of the sweep (the numbers do not depend on it).
    """

    sigma_d_mps: tuple = SIGMA_D_GRID_MPS
    n_trials: int = 100
    n_particles: int = 1000
    ess_fraction: float = 0.5
    resampler: str = "systematic"
    common_random_numbers: bool = True
    n_threads: int = 1

    def __post_init__(self):
        s = np.asarray(self.sigma_d_mps, float)
        if s.ndim != 1 or s.size < 1 or np.any(s <= 0) or np.any(np.diff(s) <= 0):
            raise ValueError("sigma_d_mps must be increasing positive values")
        if self.n_trials < 1 or self.n_particles < 1 or self.n_threads < 1:
            raise ValueError("n_trials, n_particles and n_threads must be >= 1")
        if not 0 <= self.ess_fraction <= 1:
            raise ValueError("ess_fraction must be in [0, 1]")

    @classmethod
    def fast(cls) -> "SweepConfig":
        """A small sweep for FAST runs (CI)."""
        return cls(sigma_d_mps=(0.02, 0.06, 0.15, 0.30, 0.40, 0.50, 1.00), n_trials=3, n_particles=200)


# --------------------------------------------------------------------------- synthetic study

@dataclass(frozen=True)
class SyntheticStudy:
    """The simulated facility with its calibration campaign, models and Table I recordings.

    ``model`` follows the paper's calibration rules; ``pooled`` differs only in σ
    (``sigma_rule="pooled"``, see :meth:`~uwbwb.models.setnoise.SetNoiseModel.fit`).
    """

    facility: sim.Facility
    calibration: tuple[SetFixLog, ...]
    model: SetNoiseModel
    pooled: SetNoiseModel
    recordings: tuple[SetFixLog, ...]

    @property
    def fig3(self) -> SetFixLog:
        """The calibration fixes at the paper's Fig. 3 location (450, 590) cm."""
        xy = np.asarray(self.facility.config.fig3_xy_m)
        for log in self.calibration:
            if np.allclose(log.truth_m[0], xy):
                return log
        raise ValueError("the Fig. 3 location is not among the calibration locations")

    def recording(self, name: str) -> SetFixLog:
        for r in self.recordings:
            if r.name == name:
                return r
        raise KeyError(f"no recording {name!r}; have {[r.name for r in self.recordings]}")


def synthetic_study(config: sim.FacilityConfig = sim.FacilityConfig(), *, rng: np.random.Generator
                    ) -> SyntheticStudy:
    """Draw a facility, run its calibration campaign, calibrate the model, record Table I."""
    facility = sim.make_facility(config, rng=rng)
    calibration = tuple(sim.calibration_campaign(facility, rng=rng))
    model = SetNoiseModel.from_fixes(calibration)
    pooled = SetNoiseModel.from_fixes(calibration, sigma_rule="pooled")
    recordings = tuple(sim.table1_recordings(facility, rng=rng))
    return SyntheticStudy(facility, calibration, model, pooled, recordings)


def raw_error_m(log: SetFixLog) -> float:
    """Mean Euclidean error of the raw fixes, metres."""
    return float(np.linalg.norm(log.error_m, axis=1).mean())


def table1(recordings, speeds_mps=None) -> pd.DataFrame:
    """Table I: fixes, speed and raw error per recording, with the paper's values beside ours.

    ``speeds_mps`` defaults to the ground-truth speed of each recording (path length / duration).
    """
    rows = []
    for i, r in enumerate(recordings):
        steps = np.linalg.norm(np.diff(r.truth_m, axis=0), axis=1)
        v = steps.sum() / (r.t_s[-1] - r.t_s[0]) if speeds_mps is None else speeds_mps[i]
        row = {"recording": r.name, "n_fixes": len(r), "speed_cmps": 100 * v, "raw_error_cm": 100 * raw_error_m(r)}
        if i < len(PAPER["n_fixes"]):
            row.update(paper_n_fixes=PAPER["n_fixes"][i], paper_speed_cmps=PAPER["speed_cmps"][i],
                       paper_raw_error_cm=PAPER["raw_error_cm"][i])
        rows.append(row)
    return pd.DataFrame(rows)


def set_shares(log: SetFixLog) -> dict:
    """Fig. 4 statistics: share of the most frequent set and of the top five, number of sets."""
    fr = log.set_frequency()
    return {"top1_share": float(fr["share"].iloc[0]), "top5_share": float(fr["cum_share"].iloc[min(4, len(fr) - 1)]),
            "n_sets": len(fr), "top_labels": tuple(fr["label"].iloc[:5])}


# --------------------------------------------------------------------------- Fig. 9 sweep

def _noise(log: SetFixLog, model: SetNoiseModel) -> tuple[np.ndarray, np.ndarray]:
    """``(μ, σ)`` for the baseline (facility-wide) and set-noise filters, stacked ``(2, T, 2)``."""
    mu_b, sd_b, _ = model.facility_only().lookup(log.set_id)
    mu_s, sd_s, _ = model.lookup(log.set_id)
    return np.stack([mu_b, mu_s]), np.stack([sd_b, sd_s])


def sweep(recordings, model: SetNoiseModel, config: SweepConfig = SweepConfig(), *, rng: np.random.Generator,
          pooled: SetNoiseModel | None = None, progress: bool = True) -> pd.DataFrame:
    """Fig. 9: mean Euclidean error against σ_d for every recording and estimator.

    Per recording, baseline and set-noise PF for all trials and σ_d values run as one
    batched computation (:func:`uwbwb.filters.setnoise.pf_sweep`); the Kalman filters
    are deterministic and need no trials. With ``pooled`` (a model fitted with
    ``sigma_rule="pooled"``) its Kalman filter is added as :data:`SET_KF_POOLED`.

    Returns
    -------
    DataFrame
        Tidy: ``recording, filter, sigma_d_mps, mean_error_m, sem_error_m, n_trials``
        (``sem`` = standard error of the trial mean; 0 for deterministic estimators).
    """
    sig = np.asarray(config.sigma_d_mps, float)
    rows = []
    for log in recordings:
        mu, sd = _noise(log, model)
        x0 = log.truth_m[0]
        pf = filt.pf_sweep(log.t_s, log.pos_m, mu, sd, x0, sig, rng=rng, n_trials=config.n_trials,
                           n_particles=config.n_particles, ess_fraction=config.ess_fraction,
                           resampler=config.resampler, common_random_numbers=config.common_random_numbers,
                           n_threads=config.n_threads, progress=progress, desc=f"{log.name}: PF sweep")
        err = pf.mean_error_m(log.truth_m)                                  # (2, trials, S)
        kf = filt.kf_sweep(log.t_s, log.pos_m, mu, sd, x0, sig).mean_error_m(log.truth_m)   # (2, S)
        if pooled is not None:
            mu_p, sd_p, _ = pooled.lookup(log.set_id)
            kf_pooled = filt.kf_sweep(log.t_s, log.pos_m, mu_p, sd_p, x0, sig).mean_error_m(log.truth_m)
        raw = raw_error_m(log)
        n = config.n_trials
        for j, s in enumerate(sig):
            rows.append((log.name, RAW, s, raw, 0.0, 1))
            for m, name in enumerate((BASE_PF, SET_PF)):
                e = err[m, :, j]
                rows.append((log.name, name, s, e.mean(), e.std(ddof=1) / np.sqrt(n) if n > 1 else np.nan, n))
            rows.append((log.name, BASE_KF, s, kf[0, j], 0.0, 1))
            rows.append((log.name, SET_KF, s, kf[1, j], 0.0, 1))
            if pooled is not None:
                rows.append((log.name, SET_KF_POOLED, s, kf_pooled[j], 0.0, 1))
    return pd.DataFrame(rows, columns=["recording", "filter", "sigma_d_mps", "mean_error_m", "sem_error_m",
                                       "n_trials"])


def mean_over_recordings(df: pd.DataFrame, name: str = "mean") -> pd.DataFrame:
    """The sweep averaged over recordings (as one more ``recording`` called ``name``)."""
    g = df.groupby(["filter", "sigma_d_mps"], sort=False)
    out = pd.DataFrame({"mean_error_m": g["mean_error_m"].mean(),
                        "sem_error_m": np.sqrt((g["sem_error_m"].apply(lambda s: np.sum(s ** 2)))) / g.size(),
                        "n_trials": g["n_trials"].min()}).reset_index()
    out.insert(0, "recording", name)
    return out[["recording", "filter", "sigma_d_mps", "mean_error_m", "sem_error_m", "n_trials"]]


def band_summary(df: pd.DataFrame, band=BAND_MPS) -> pd.DataFrame:
    """Mean error in the σ_d band and the improvement over the raw fixes.

    Returns
    -------
    DataFrame
        One row per recording and estimator, plus recording ``"mean"`` (average over
        recordings): ``recording, filter, error_cm, raw_cm, improvement_cm, improvement_pct``.
    """
    lo, hi = band
    sel = df[(df["sigma_d_mps"] >= lo - 1e-12) & (df["sigma_d_mps"] <= hi + 1e-12)]
    if sel.empty:
        raise ValueError(f"no σ_d values in the band {band} m/s")
    g = sel.groupby(["recording", "filter"], sort=False)["mean_error_m"].mean().unstack("filter")
    g.loc["mean"] = g.mean(axis=0)
    raw = g[RAW]
    out = []
    for rec, row in g.iterrows():
        for name in g.columns:
            out.append({"recording": rec, "filter": name, "error_cm": 100 * row[name], "raw_cm": 100 * raw[rec],
                        "improvement_cm": 100 * (raw[rec] - row[name]),
                        "improvement_pct": 100 * (raw[rec] - row[name]) / raw[rec]})
    return pd.DataFrame(out)


def best_sigma(df: pd.DataFrame) -> pd.DataFrame:
    """Per recording and estimator, the σ_d with the lowest mean error (chosen on the data itself).

    Returns
    -------
    DataFrame
        ``recording, filter, sigma_d_mps, mean_error_m``.
    """
    idx = df.groupby(["recording", "filter"], sort=False)["mean_error_m"].idxmin()
    return df.loc[idx, ["recording", "filter", "sigma_d_mps", "mean_error_m"]].reset_index(drop=True)


def normalised_residuals(log: SetFixLog, models: dict) -> dict:
    """Mean squared normalised fix residual ``((z − x − μ)/σ)²`` per model (1 when σ is right)."""
    out = {}
    for name, m in models.items():
        mu, sd, _ = m.lookup(log.set_id)
        out[name] = float(np.mean(((log.error_m - mu) / sd) ** 2))
    return out


# --------------------------------------------------------------------------- Fig. 8 and PF → KF

def trace(log: SetFixLog, model: SetNoiseModel, sigma_d_mps: float, *, rng: np.random.Generator,
          n_particles: int = 1000, ess_fraction: float = 0.5, resampler: str = "systematic") -> dict:
    """One run of every estimator on one recording (Fig. 8).

    Returns
    -------
    dict
        name → estimated positions ``(T, 2)``, metres, for ``truth``, ``raw`` and the four filters.
    """
    mu, sd = _noise(log, model)
    x0 = log.truth_m[0]
    pf = filt.pf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps, rng=rng, n_particles=n_particles,
                       ess_fraction=ess_fraction, resampler=resampler)
    kf = filt.kf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps)
    return {"truth": log.truth_m, RAW: log.pos_m, BASE_PF: pf.pos_m[0, 0, 0], SET_PF: pf.pos_m[1, 0, 0],
            BASE_KF: kf.pos_m[0, 0], SET_KF: kf.pos_m[1, 0]}


def pf_kf_gap(log: SetFixLog, model: SetNoiseModel, sigma_d_mps: float, n_particles=(30, 100, 300, 1000, 3000),
              *, n_trials: int = 10, rng: np.random.Generator) -> pd.DataFrame:
    """How far the set-noise PF is from the exact set-noise KF, against K.

    Returns
    -------
    DataFrame
        ``n_particles, rms_gap_m`` (RMS over trials and fixes of PF − KF position),
        ``pf_error_m`` (mean error of the PF), ``kf_error_m``.
    """
    mu, sd, _ = model.lookup(log.set_id)
    x0 = log.truth_m[0]
    kf = filt.kf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps)
    rows = []
    for K in n_particles:
        pf = filt.pf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps, rng=rng, n_trials=n_trials,
                           n_particles=int(K))
        gap = pf.pos_m[0, :, 0] - kf.pos_m[0]
        rows.append({"n_particles": int(K), "rms_gap_m": float(np.sqrt(np.mean(np.sum(gap ** 2, axis=-1)))),
                     "pf_error_m": float(pf.mean_error_m(log.truth_m).mean()),
                     "kf_error_m": float(kf.mean_error_m(log.truth_m)[0])})
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------- real data

@dataclass(frozen=True)
class Emulation:
    """How sensor sets are emulated on real two-way ranges.

    Per epoch, every anchor with a range gets an emulated received power
    ``−10 n log10(range)`` plus independent fading ``N(0, fading_db)``, and the
    ``set_size`` strongest anchors form the set (:func:`uwbwb.sim.setnoise.select_sets`,
    the rule the simulator uses). The fix is the 2-D least-squares position from
    that set's ranges at the tag's known height. The fading makes sets switch even
    for a static tag, as in the paper; ``fading_db = 0`` keeps the shortest ranges.

    Attributes
    ----------
    set_size
        Anchors per fix (paper: sets of ≥ 5 of 8 sensors).
    fading_db
        Fading standard deviation, dB.
    path_loss_exponent
        ``n``.
    decimate
        Keep every ``decimate``-th epoch (LIAS ranges come at ~100 Hz; 10 gives the
        paper's ~10 Hz).
    """

    set_size: int = 5
    fading_db: float = 2.5
    path_loss_exponent: float = 2.0
    decimate: int = 10

    def __post_init__(self):
        if self.set_size < 3 or self.fading_db < 0 or self.decimate < 1 or self.path_loss_exponent <= 0:
            raise ValueError("set_size >= 3, fading_db >= 0, decimate >= 1 and path_loss_exponent > 0 are needed")


@dataclass(frozen=True)
class RealInputs:
    """A dynamic run to test on and static recordings of the same room to calibrate with."""

    dynamic: Recording
    static: tuple[Recording, ...]
    synthetic: bool
    note: str

    @property
    def data_label(self) -> str:
        """The ``data`` field of summary rows: ``synthetic`` or ``dataset/recording``."""
        return "synthetic" if self.synthetic else self.dynamic.label


def real_inputs(data_dir=None, recording: str = "fast", static_session: str = "8.14", *, seed: int = 0,
                fast: bool = False) -> RealInputs:
    """Load a LIAS dynamic run and the static poses of its room, or the synthetic rig if absent.

    With ``fast`` only the first yaw of every static site is loaded (5 poses instead of 30).
    """
    if dataset_available(LIAS, data_dir):
        from ..datasets import lias

        dynamic = lias.load_dynamic(recording, data_dir)
        static = lias.load_static(static_session, data_dir)
        if fast:
            first = {}
            for rec in static:
                first.setdefault(rec.meta["site"], rec)
            static = list(first.values())
        return RealInputs(dynamic, tuple(static), False,
                          f"{LIAS}: dynamic run {recording!r}, {len(static)} static poses of session {static_session}")
    from ..sim import rig

    rng = np.random.default_rng(seed)
    cfg = rig.RigConfig(duration_s=60.0 if fast else 120.0)
    dynamic, truth = rig.simulate_dynamic(cfg, rng=rng)
    static, _ = rig.simulate_static(cfg, duration_s=10.0 if fast else 20.0, rng=rng, range_model=truth.range_model)
    return RealInputs(dynamic, tuple(static), True,
                      f"{LIAS} not found: synthetic LIAS-like rig (uwbwb.sim.rig) in its place")


def emulate_fixes(rec: Recording, tag: str, emulation: Emulation = Emulation(), *, rng: np.random.Generator,
                  calibration: RangeCalibration | None = None, name: str | None = None) -> tuple[SetFixLog, dict]:
    """Position fixes of one tag from emulated sensor sets (see :class:`Emulation`).

    Parameters
    ----------
    rec
        A recording with ranges and 3-D truth for ``tag``.
    calibration
        Optional per-pair range calibration applied to the ranges first.

    Returns
    -------
    fixes
        :class:`SetFixLog` with truth, named ``name`` (default ``"<recording>/<tag>"``).
    report
        Counts: ``epochs``, ``kept_after_decimation``, ``no_truth`` (outside the
        motion capture), ``too_few_ranges`` (fewer than ``set_size``), ``fix_failed``, ``fixes``.
    """
    log = rec.ranges[tag]
    if calibration is not None:
        log = calibration.apply(log)
    log = log.select(slice(None, None, emulation.decimate))
    truth = rec.truth[tag]
    if truth.dim != 3:
        raise ValueError(f"{rec.label}: truth of tag {tag!r} must be 3-D (its height fixes the 2-D solve)")
    truth_xyz = truth.interp(log.t_s)
    has_truth = np.all(np.isfinite(truth_xyz), axis=1)
    r = log.range_m[has_truth]
    with np.errstate(divide="ignore"):
        power = -10 * emulation.path_loss_exponent * np.log10(np.where(r > 0, r, np.nan))
    used = sim.select_sets(power, emulation.set_size, emulation.fading_db, rng=rng)
    enough = used.sum(axis=1) >= emulation.set_size
    res = geometry.multilaterate(np.where(used, r, np.nan)[enough], rec.anchors.pos_m, dim=2,
                                 z_m=truth_xyz[has_truth][enough, 2], min_anchors=emulation.set_size)
    ok = res.ok
    t = log.t_s[has_truth][enough][ok]
    fixes = SetFixLog(t, res.pos_m[ok], set_id_from_mask(used[enough][ok]), rec.anchors.ids,
                      truth_xyz[has_truth][enough][ok, :2], name or f"{rec.name}/{tag}")
    report = {"epochs": len(rec.ranges[tag]), "kept_after_decimation": len(log),
              "no_truth": int((~has_truth).sum()), "too_few_ranges": int((~enough).sum()),
              "fix_failed": int((~ok).sum()), "fixes": len(fixes)}
    return fixes, report


@dataclass(frozen=True)
class RealStudy:
    """The set-noise model calibrated on static poses and the dynamic run's fixes per tag."""

    inputs: RealInputs
    emulation: Emulation
    range_calibration: RangeCalibration | None
    calibration: tuple[SetFixLog, ...]
    model: SetNoiseModel
    pooled: SetNoiseModel
    tests: tuple[SetFixLog, ...]
    reports: pd.DataFrame = field(repr=False)

    @property
    def label(self) -> str:
        return "calibrated ranges" if self.range_calibration is not None else "raw ranges"


def real_study(inputs: RealInputs, emulation: Emulation = Emulation(), *, range_calibration: bool = True,
               tags=None, rng: np.random.Generator) -> RealStudy:
    """Calibrate the set-noise model on the static poses and emulate the dynamic run's fixes.

    Every (static pose, tag) is one calibration location. With ``range_calibration``
    the per-pair range bias/scale fitted on the *same* static poses
    (:func:`uwbwb.calibration.fit_range_calibration`, on the epochs the emulation
    keeps) is applied to all ranges first.
    """
    cal = None
    if range_calibration:
        cal = fit_range_calibration([_decimated(rec, emulation.decimate) for rec in inputs.static])
    tags = tuple(inputs.dynamic.tags if tags is None else tags)
    logs, rows = [], []
    for rec in inputs.static:
        for tag in tags:
            fixes, rep = emulate_fixes(rec, tag, emulation, rng=rng, calibration=cal, name=f"{rec.name}/{tag}")
            logs.append(fixes)
            rows.append({"recording": rec.name, "tag": tag, "role": "calibration", **rep})
    model = SetNoiseModel.from_fixes(logs)
    pooled = SetNoiseModel.from_fixes(logs, sigma_rule="pooled")
    tests = []
    for tag in tags:
        fixes, rep = emulate_fixes(inputs.dynamic, tag, emulation, rng=rng, calibration=cal)
        tests.append(fixes)
        rows.append({"recording": inputs.dynamic.name, "tag": tag, "role": "test", **rep})
    return RealStudy(inputs, emulation, cal, tuple(logs), model, pooled, tuple(tests), pd.DataFrame(rows))


def _decimated(rec: Recording, step: int) -> Recording:
    """Every ``step``-th epoch of each tag's ranges (truth kept whole)."""
    if step <= 1:
        return rec
    return replace(rec, ranges={t: log.select(slice(None, None, step)) for t, log in rec.ranges.items()})


def modelled_share(log: SetFixLog, model: SetNoiseModel) -> float:
    """Fraction of fixes whose set has its own model (the rest use the facility-wide default)."""
    return float(model.lookup(log.set_id)[2].mean())


# --------------------------------------------------------------------------- figures

def _ax(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots()
    return ax


def _set_colours(n: int):
    import matplotlib

    return [matplotlib.colormaps["tab10"](i) for i in range(n)]


def plot_facility(facility: sim.Facility, ax=None):
    """Floor plan: sensors, walls, calibration locations and the test track (cf. paper Figs. 2, 7)."""
    from .. import plotting

    ax = _ax(ax)
    cfg = facility.config
    x0, x1, y0, y1 = cfg.lab_m
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="#bdbdbd", linewidth=1, label="lab")
    for i, (wx1, wy1, wx2, wy2) in enumerate(cfg.walls_m):
        ax.plot([wx1, wx2], [wy1, wy2], color="#636363", linewidth=4, solid_capstyle="butt",
                label="walls (NLOS)" if i == 0 else "_nolegend_")
    plotting.floor_plan(facility.sensor_xyz_m, ax)
    cal = np.asarray(cfg.calibration_xy_m)
    ax.plot(cal[:, 0], cal[:, 1], "s", color="#31a354", markersize=6, label="calibration locations")
    a, b = np.asarray(cfg.track_start_xy_m), np.asarray(cfg.track_end_xy_m)
    ax.plot([a[0], b[0]], [a[1], b[1]], color="#000000", linewidth=2.5, label="test track")
    ax.plot(*cfg.fig3_xy_m, "+", color="#d62728", markersize=12, mew=2, label="Fig. 3 location")
    ax.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize="small")
    ax.set_title("simulated facility")
    return ax


def plot_fixes(log: SetFixLog, ax=None, *, n_sets: int = 5, unit: str = "cm"):
    """Fig. 3: fixes of a static tag, coloured by their (most frequent) sets; truth as '+'."""
    ax = _ax(ax)
    s = 100.0 if unit == "cm" else 1.0
    fr = log.set_frequency()
    top = fr["set_id"].iloc[:n_sets].tolist()
    other = ~np.isin(log.set_id, top)
    ax.plot(log.pos_m[other, 0] * s, log.pos_m[other, 1] * s, ".", color="#bdbdbd", markersize=3,
            label=f"other sets ({other.sum()})")
    for c, (sid, lab, n) in zip(_set_colours(n_sets), fr[["set_id", "label", "count"]].iloc[:n_sets].itertuples(index=False)):
        m = log.set_id == sid
        ax.plot(log.pos_m[m, 0] * s, log.pos_m[m, 1] * s, ".", color=c, markersize=3, label=f"'{lab}' ({n})")
    tx, ty = log.truth_m[0] * s
    ax.plot(tx, ty, "+", color="#000000", markersize=14, mew=2, label="truth")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.legend(fontsize="x-small", loc="best")
    return ax


def plot_set_frequency(log: SetFixLog, ax=None, *, n_bars: int = 12):
    """Fig. 4: how often each set occurs, most frequent first, with the top-five share."""
    ax = _ax(ax)
    fr = log.set_frequency().iloc[:n_bars]
    colours = _set_colours(5) + ["#bdbdbd"] * max(0, len(fr) - 5)
    ax.bar(range(len(fr)), fr["count"], color=colours[:len(fr)])
    ax.set_xticks(range(len(fr)))
    ax.set_xticklabels(fr["label"], rotation=60, fontsize="small")
    ax.set_ylabel("fixes")
    sh = set_shares(log)
    ax.set_title(f"top set {100 * sh['top1_share']:.1f} %, top five {100 * sh['top5_share']:.1f} % "
                 f"of {len(log)} ({sh['n_sets']} sets)")
    return ax


def plot_set_ellipses(log: SetFixLog, ax=None, *, n_sets: int = 4, n_sigma: float = 3.0, unit: str = "cm"):
    """Fig. 5: the noise models ``(μ, σ)`` of the most frequent sets at one location as n-σ ellipses.

    The per-axis model has no correlation, so the ellipses are axis-aligned, centred on
    truth + μ with semi-axes ``n_sigma · σ``.
    """
    from matplotlib.patches import Ellipse

    ax = _ax(ax)
    s = 100.0 if unit == "cm" else 1.0
    st = location_statistics(log.error_m, log.set_id, np.zeros(len(log))).iloc[:n_sets]
    truth = log.truth_m[0]
    ax.plot(log.pos_m[:, 0] * s, log.pos_m[:, 1] * s, ".", color="#d9d9d9", markersize=2, label="fixes")
    for c, row in zip(_set_colours(n_sets), st.itertuples(index=False)):
        centre = (truth + [row.mu_x_m, row.mu_y_m]) * s
        lab = log.set_frequency().set_index("set_id").loc[row.set_id, "label"]
        ax.add_patch(Ellipse(centre, 2 * n_sigma * row.sigma_x_m * s, 2 * n_sigma * row.sigma_y_m * s,
                             fill=False, color=c, linewidth=1.8, label=f"'{lab}' (n = {row.n})"))
        ax.plot(*centre, "o", color=c, markersize=4)
    ax.plot(*(truth * s), "+", color="#000000", markersize=14, mew=2, label="truth")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_title(f"{n_sigma:g}σ ellipses of the {n_sets} most frequent sets")
    ax.legend(fontsize="x-small", loc="best")
    return ax


def plot_trace(estimates: dict, ax=None, *, index=None, axis: int = 0, unit: str = "cm",
               names=(RAW, BASE_PF, SET_PF)):
    """Fig. 8: one coordinate (default X) against measurement index for truth, raw and filters."""
    from .. import plotting

    ax = _ax(ax)
    s = 100.0 if unit == "cm" else 1.0
    n = len(estimates["truth"])
    idx = np.arange(n) if index is None else np.arange(n)[index]
    ax.plot(idx, estimates["truth"][idx, axis] * s, color=plotting.color_for("truth"), linewidth=1.5, label="truth")
    for name in names:
        est = estimates[name]
        style = dict(linestyle="none", marker=".", markersize=4) if name == RAW else dict(linewidth=1.3)
        ax.plot(idx, est[idx, axis] * s, color=plotting.color_for(name), label=name, **style)
    ax.set_xlabel("measurement index")
    ax.set_ylabel(f"{'XY'[axis]} ({unit})")
    ax.legend(fontsize="small", loc="best")
    return ax


def _sweep_style() -> dict:
    from ..plotting import color_for

    # Kalman filters dashed in the colour of their family (the baseline KF has no colour of its own)
    return {BASE_KF: (color_for(BASE_PF), "--"), SET_KF: (color_for(SET_KF), "--"),
            SET_KF_POOLED: (color_for(SET_KF), ":")}


def plot_sweep(df: pd.DataFrame, recording: str, ax=None, *, names=FILTERS, unit: str = "cm", band=BAND_MPS):
    """Fig. 9 (one recording): mean error against σ_d; PF curves with ±2 standard errors."""
    from .. import plotting

    ax = _ax(ax)
    s = 100.0 if unit == "cm" else 1.0
    d = df[df["recording"] == recording]
    for name in names:
        g = d[d["filter"] == name].sort_values("sigma_d_mps")
        if g.empty:
            continue
        x = g["sigma_d_mps"].to_numpy() * 100
        y = g["mean_error_m"].to_numpy() * s
        colour, dash = _sweep_style().get(name, (plotting.color_for(name), "-"))
        ax.plot(x, y, color=colour, label=name, linestyle=dash, marker="" if name == RAW else ".")
        e = 2 * g["sem_error_m"].to_numpy() * s
        if np.any(e > 0):
            ax.fill_between(x, y - e, y + e, color=colour, alpha=0.2, linewidth=0)
    if band is not None:
        ax.axvspan(100 * band[0], 100 * band[1], color="#f0f0f0", zorder=0)
    ax.set_xlabel("σ_d (cm/s)")
    ax.set_ylabel(f"mean error ({unit})")
    ax.set_title(recording)
    return ax


def plot_pf_kf_gap(df: pd.DataFrame, ax=None, *, unit: str = "cm"):
    """RMS distance between the set-noise PF and the exact KF against K, with a 1/√K guide."""
    ax = _ax(ax)
    s = 100.0 if unit == "cm" else 1.0
    K = df["n_particles"].to_numpy(float)
    g = df["rms_gap_m"].to_numpy() * s
    ax.loglog(K, g, "o-", color="#bcbd22", label="set-noise PF − set-noise KF (RMS)")
    ax.loglog(K, g[0] * np.sqrt(K[0] / K), ":", color="#636363", label="∝ 1/√K")
    ax.set_xlabel("particles K")
    ax.set_ylabel(f"RMS gap ({unit})")
    ax.legend(fontsize="small")
    return ax
