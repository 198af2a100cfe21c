"""The synthetic study of notebook 01 (paper 000): facility, calibration, Table I, Fig. 9 sweep.

Banerjee, Suski & Hoover, *Sensor Set Switching Noise in UWB Indoor Position
Tracking*. :func:`synthetic_study` draws the simulated facility, its calibration
campaign (6 locations × 1000 fixes), the calibrated
:class:`~uwbwb.models.setnoise.SetNoiseModel` and the five Table I recordings,
plus the same five recordings on a track away from the calibration locations;
:func:`table1` and :func:`set_shares` give Table I and the Fig. 4 statistics,
:func:`sweep` Fig. 9 and :func:`band_summary` the improvement in the paper's σ_d
band. Fig. 8 and the PF approaching the exact KF are in :mod:`.diagnostics`; the
summary rows, each with its kind (reproduced, target or input), in :mod:`.headlines`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ...calibration import fit_set_noise_from_fixes
from ...filters import setnoise as filt
from ...models.setnoise import SetNoiseModel
from ...types import SetFixLog
from ...sim import setnoise as sim

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
        Worker threads of the sweep when no ``scheduler`` is given (the numbers do
        not depend on it).
    scheduler
        None (this process), ``"local"`` or a Dask scheduler address: where the
        sweep's blocks of trials run (:mod:`uwbwb.parallel`; the numbers do not
        depend on it).
    """

    sigma_d_mps: tuple = SIGMA_D_GRID_MPS
    n_trials: int = 100
    n_particles: int = 1000
    ess_fraction: float = 0.5
    resampler: str = "systematic"
    common_random_numbers: bool = True
    n_threads: int = 1
    scheduler: str | None = None

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

#: The second test track, away from the calibration locations (an assumption of ours): the same 2.5 m along x,
#: at y = 3.95 m, midway between the two rows of calibration locations (y = 2.0 and 5.9 m), so every fix is
#: 1.95 m or more from the nearest one — about four multipath correlation lengths with the simulator's defaults.
OFF_TRACK_XY_M = ((3.25, 3.95), (5.75, 3.95))


@dataclass(frozen=True)
class SyntheticStudy:
    """The simulated facility with its calibration campaign, models and Table I recordings.

    ``model`` follows the paper's calibration rules; ``pooled`` differs only in σ
    (``sigma_rule="pooled"``, see :func:`uwbwb.calibration.fit_set_noise`).
    ``recordings`` run along the paper's track, which passes through the Fig. 3
    calibration location; ``off_recordings`` are the same five speeds on a track
    away from every calibration location (:data:`OFF_TRACK_XY_M`), drawn after the
    others so that adding them changes none of their numbers.
    """

    facility: sim.Facility
    calibration: tuple[SetFixLog, ...]
    model: SetNoiseModel
    pooled: SetNoiseModel
    recordings: tuple[SetFixLog, ...]
    off_recordings: tuple[SetFixLog, ...] = ()

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


def synthetic_study(config: sim.FacilityConfig = sim.FacilityConfig(), *, rng: np.random.Generator,
                    off_track_xy_m=OFF_TRACK_XY_M) -> SyntheticStudy:
    """Draw a facility, run its calibration campaign, calibrate the model, record Table I.

    With ``off_track_xy_m`` (the two ends of a track, metres; None: none) the five
    speeds are recorded once more on that track, in the same facility.
    """
    facility = sim.make_facility(config, rng=rng)
    calibration = tuple(sim.calibration_campaign(facility, rng=rng))
    model = fit_set_noise_from_fixes(calibration)
    pooled = fit_set_noise_from_fixes(calibration, sigma_rule="pooled")
    recordings = tuple(sim.table1_recordings(facility, rng=rng))
    off = ()
    if off_track_xy_m is not None:
        a, b = (tuple(map(float, p)) for p in off_track_xy_m)
        moved = replace(facility, config=replace(config, track_start_xy_m=a, track_end_xy_m=b))
        off = tuple(replace(r, name=f"off-{r.name}") for r in sim.table1_recordings(moved, rng=rng))
    return SyntheticStudy(facility, calibration, model, pooled, recordings, off)


def calibration_proximity(logs, config: sim.FacilityConfig) -> pd.DataFrame:
    """How close the fixes of each log come to a calibration location.

    The multipath field decorrelates over ``config.multipath_corr_m``, so set biases
    seen at a calibration location carry over to fixes within about that distance.

    Returns
    -------
    DataFrame
        One row per log: ``recording, n_fixes, within_corr_share`` (share of fixes whose
        true position is within one correlation length of a calibration location),
        ``median_distance_m`` (to the nearest one).
    """
    cal = np.asarray(config.calibration_xy_m, float)
    rows = []
    for log in logs:
        d = np.linalg.norm(log.truth_m[:, None, :] - cal[None], axis=-1).min(axis=1)
        rows.append({"recording": log.name, "n_fixes": len(log),
                     "within_corr_share": float(np.mean(d <= config.multipath_corr_m)),
                     "median_distance_m": float(np.median(d))})
    return pd.DataFrame(rows)


def raw_error_m(log: SetFixLog) -> float:
    """Mean Euclidean error of the raw fixes, metres."""
    return float(np.linalg.norm(log.error_m, axis=1).mean())


def table1(recordings) -> pd.DataFrame:
    """Table I: fixes, speed (ground truth: path length / duration) and raw error per recording, with the paper's
    values beside ours."""
    rows = []
    for i, r in enumerate(recordings):
        v = np.linalg.norm(np.diff(r.truth_m, axis=0), axis=1).sum() / (r.t_s[-1] - r.t_s[0])
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
    batched computation (:func:`uwbwb.filters.setnoise.pf_sweep`), in blocks of
    trials run where ``config.scheduler`` says, each scored where it runs (only
    the errors come back); the Kalman filters are deterministic and need no trials. With ``pooled`` (a model fitted with
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
                           n_threads=config.n_threads, scheduler=config.scheduler, truth_m=log.truth_m,
                           keep_positions=False, progress=progress, desc=f"{log.name}: PF sweep")
        err = pf.error_m                                                    # (2, trials, S)
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
    """Mean error in the σ_d band, its Monte Carlo standard error, and the improvement over the raw fixes.

    Per recording the σ_d values share their process-noise draws (common random numbers), so their
    standard errors are combined as their RMS (no smaller than their mean, the fully correlated case);
    recordings are independent. NaN when a point has one trial.

    Returns
    -------
    DataFrame
        One row per recording and estimator, plus recording ``"mean"`` (average over
        recordings): ``recording, filter, error_cm, se_cm, raw_cm, improvement_cm, improvement_pct``.
    """
    lo, hi = band
    sel = df[(df["sigma_d_mps"] >= lo - 1e-12) & (df["sigma_d_mps"] <= hi + 1e-12)]
    if sel.empty:
        raise ValueError(f"no σ_d values in the band {band} m/s")
    by = sel.groupby(["recording", "filter"], sort=False)
    g = by["mean_error_m"].mean().unstack("filter")
    se = by["sem_error_m"].apply(lambda x: float(np.sqrt(np.mean(np.square(x.to_numpy(float)))))).unstack("filter")
    g.loc["mean"] = g.mean(axis=0)
    se.loc["mean"] = np.sqrt((se ** 2).sum(axis=0, skipna=False)) / len(se)
    raw = g[RAW]
    out = []
    for rec, row in g.iterrows():
        for name in g.columns:
            out.append({"recording": rec, "filter": name, "error_cm": 100 * row[name], "se_cm": 100 * se.loc[rec, name],
                        "raw_cm": 100 * raw[rec], "improvement_cm": 100 * (raw[rec] - row[name]),
                        "improvement_pct": 100 * (raw[rec] - row[name]) / raw[rec]})
    return pd.DataFrame(out)
