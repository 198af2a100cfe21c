"""What notebook 04 computes: paper 003's solution-space maps, cuts, and filters on simulated chirps.

Every function here is a thin composition of the package's parts —
:class:`~uwbwb.models.doppler.DopplerModel` (eq 1), :mod:`uwbwb.sampling` (the Monte
Carlo maps), :mod:`uwbwb.sim.chirps` (the chirp simulator) and
:mod:`uwbwb.filters.doppler` (front end, particle filter, SCAAT MH-EKF).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from scipy.stats import chi2

from ... import metrics, sampling as smp
from ...calibration import MAD_TO_SIGMA
from ...filters import doppler as fd
from ...filters.kalman import Gaussian
from ...models import doppler as dm
from ...models.motion import ReceiverMotion
from ...sim import chirps as sc

__all__ = ["PAPER", "StudyConfig", "LAYOUTS", "ROOMS", "READINGS", "make_model", "reference_table", "SpaceMap",
           "map_space", "period_readings", "figure_samples", "fraction_table", "make_filters",
           "TrackStudy", "track_study", "coverage_95", "filter_scores", "keeps_track", "KEEPS_TRACK", "LOST_M",
           "error_floor"]

#: Numbers quoted by the paper (inputs, never targets of a tuning).
PAPER = {
    "dp_ref_ms": {0: 1.1, 7: -1.2},
    "fraction_15cm_pct": {"cubic": 0.0005, "lab": 0.0186},
    "cep50_cm": 25.0,
    "along_over_cross": 0.5,
    "thresholds_cm": {"cubic": (2, 4, 6, 8), "lab": (4, 8)},
}

LAYOUTS = {"cubic": dm.cubic_layout, "lab": dm.lab_layout}
#: The two literal readings of the paper's periods: this workbench's per-beacon 501 + 6i ms
#: ("for example 501 or 507 ms", "around 520 ms") and "P = 500 ms" for every beacon.
READINGS = {"per-beacon 501 + 6i ms": None, "500 ms for all": 0.5}
#: Rooms the receiver is known to be in (filters' bounds and priors): the cube, and the
#: reconstructed lab (6 m × 5 m, floor 1.2 m below the receiver's carrying height z = 0,
#: ceiling at 1.5 m).
ROOMS = {"cubic": ((-2.0, -2.0, -2.0), (2.0, 2.0, 2.0)), "lab": ((-3.0, -2.5, -1.2), (3.0, 2.5, 1.5))}
#: A filter *keeps track* on a recording when at least ``KEEPS_TRACK[0]`` of its scored epochs have a
#: horizontal error under :data:`LOST_M` (the PF: pooled over its runs) and, for the PF, at most
#: ``KEEPS_TRACK[1]`` of its runs restarted (the MH-EKF does not restart).
KEEPS_TRACK = (0.95, 0.05)
#: Horizontal error (m) beyond which an epoch counts as off the track.
LOST_M = 0.5
#: PF runs per block of :func:`track_study` (a block's runs draw from one child of the recording's generator).
BLOCK_RUNS = 25


@dataclass(frozen=True)
class StudyConfig:
    """Sizes and settings of the notebook's experiments (FAST shrinks every size, nothing else).

    Attributes
    ----------
    n_brute
        Brute-force draws per layout (the issue asks for ≥ 10⁹ in full mode).
    n_positions
        Positions of the conditional estimator per layout.
    pf_runs, n_particles
        Independent particle-filter runs over the first recording (the paper's Fig 6: 1000;
        full mode here 200, which with 10 recordings keeps the notebook within minutes on
        two cores) and particles per run (the paper does not say).
    n_recordings
        Independent simulated recordings for Fig 6 and the filter comparison (≥ 10 in
        full mode); the first gets ``pf_runs`` PF runs, the others ``compare_runs``.
    n_fig_positions
        Positions of the conditional sampler run *per threshold* for Figs 3–4.
    floor_runs
        PF runs per condition of :func:`error_floor`.
    temperature_c
        Air temperature setting the speed of sound.
    sigma_range_m
        Timing jitter of one arrival, as a distance (the paper's lab: 1–2 cm).
    p_miss, spurious_rate_hz
        Missed chirps and spurious detections (assumptions: the paper gives no rates).
    """

    fast: bool = False
    seed: int = 0
    n_brute: int = 1_000_000_000
    n_positions: int = 2_000_000
    pf_runs: int = 200
    n_particles: int = 1000
    n_recordings: int = 10
    compare_runs: int = 25
    n_fig_positions: int = 4_000_000
    floor_runs: int = 25
    temperature_c: float = 20.0
    sigma_range_m: float = 0.015
    p_miss: float = 0.05
    spurious_rate_hz: float = 0.5
    laps_before: int = 1

    @classmethod
    def for_mode(cls, fast: bool, seed: int = 0, **changes) -> "StudyConfig":
        base = cls(fast=True, seed=seed, n_brute=20_000_000, n_positions=100_000, pf_runs=8, n_particles=800,
                   n_recordings=2, compare_runs=3, laps_before=0, n_fig_positions=100_000,
                   floor_runs=2) if fast else cls(seed=seed)
        return replace(base, **changes)

    @classmethod
    def for_class(cls, seed: int = 0, **changes) -> "StudyConfig":
        """A lecturer's run (notebook parameter ``CLASS``): FAST sizes, with fewer sampler draws and PF runs
        (5e6 brute-force draws, 3e4 conditional positions, 4 + 2 PF runs, 1 run per error-floor condition) so that
        Run All stays near a minute and a half on two shared cores. Smoke-test numbers, like FAST's."""
        return replace(cls.for_mode(True, seed), n_brute=5_000_000, n_positions=30_000, n_fig_positions=30_000,
                       pf_runs=4, compare_runs=2, floor_runs=1, **changes)


def make_model(layout: str, cfg: StudyConfig, reading: str = "per-beacon 501 + 6i ms", **changes) -> dm.DopplerModel:
    """The layout's :class:`DopplerModel` under a period ``reading`` (:data:`READINGS`), v_s at ``cfg.temperature_c``.

    "500 ms for all" uses ``0.5 s + i ns`` (the model needs distinct periods to tell the
    beacons apart; a nanosecond changes no printed digit).
    """
    if reading not in READINGS:
        raise ValueError(f"reading must be one of {', '.join(map(repr, READINGS))}, got {reading!r}")
    v_s = dm.speed_of_sound_mps(cfg.temperature_c)
    beacons = LAYOUTS[layout]()
    P = READINGS[reading]
    period = dm.beacon_periods_s(len(beacons)) if P is None else P + 1e-9 * np.arange(len(beacons))
    return dm.DopplerModel(beacons, period, v_s_mps=v_s, sigma_t_s=cfg.sigma_range_m / v_s, **changes)


def reference_table(cfg: StudyConfig) -> pd.DataFrame:
    """ΔP_ref per beacon at the reference pair (cubic), under both period readings (ms), beside the paper."""
    X, V = dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS
    models = {r: make_model("cubic", cfg, r) for r in READINGS}
    first = next(iter(models.values()))
    rows = []
    for i, b in enumerate(first.beacons.ids):
        row = {"beacon": b, "position (m)": tuple(first.beacons.pos_m[i].round(2))}
        for r, m in models.items():
            row[f"P (ms), {r}"] = 1e3 * m.period_s[i]
            row[f"ΔP_ref (ms), {r}"] = 1e3 * m.delta_p(X, V)[i]
        row["paper (ms)"] = PAPER["dp_ref_ms"].get(i, np.nan)
        rows.append(row)
    return pd.DataFrame(rows).set_index("beacon")


@dataclass(frozen=True)
class SpaceMap:
    """Section 3 for one layout: brute force, conditional, and conditional with pseudo-ranges.

    ``peak_traced_bytes`` is the peak of :mod:`tracemalloc` over the three sampler runs
    (measured; NaN when the chunks ran on a Dask cluster, whose memory is not traced here).
    """

    layout: str
    model: dm.DopplerModel
    brute: smp.SamplerResult
    conditional: smp.SamplerResult
    ranging: smp.SamplerResult
    seconds: dict = field(default_factory=dict)
    peak_traced_bytes: float = np.nan


def map_space(layout: str, cfg: StudyConfig, *, workers: int = 2, progress: bool = False,
              scheduler=None) -> SpaceMap:
    """Fractions of the 6-D box under each threshold, by both estimators, and with the ranging term.

    Periods: the per-beacon reading. The samplers' chunks run in ``workers`` threads, or
    on the Dask cluster ``scheduler`` (:mod:`uwbwb.parallel`; the numbers do not depend on it).
    """
    import time
    import tracemalloc

    model = make_model(layout, cfg)
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    seeds = np.random.SeedSequence(cfg.seed).spawn(3)
    started = not tracemalloc.is_tracing()          # the peak of the allocations meanwhile (numpy buffers included)
    tracemalloc.start() if started else tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    try:
        t0 = time.perf_counter()
        brute = smp.brute_force(model, *ref, cfg.n_brute, seed=seeds[0], keep_below_m=0.15, workers=workers,
                                progress=progress, scheduler=scheduler)
        t1 = time.perf_counter()
        cond = smp.conditional(model, *ref, cfg.n_positions, seed=seeds[1], workers=workers, progress=progress,
                               scheduler=scheduler)
        t2 = time.perf_counter()
        rang = smp.conditional(model, *ref, cfg.n_positions, seed=seeds[2], workers=workers, ranges=True,
                               progress=progress, scheduler=scheduler)
        seconds = {"brute force": t1 - t0, "conditional": t2 - t1, "conditional + ranges": time.perf_counter() - t2}
        peak = float(tracemalloc.get_traced_memory()[1] - base)
    finally:
        if started:
            tracemalloc.stop()
    return SpaceMap(layout, model, brute, cond, rang, seconds, np.nan if scheduler is not None else peak)


def _percent(e: smp.FractionEstimate) -> dict:
    return {"fraction (%)": 100 * e.fraction, "95 % low (%)": 100 * e.ci_low, "95 % high (%)": 100 * e.ci_high}


def period_readings(cfg: StudyConfig, maps: dict[str, SpaceMap] | None = None, *, threshold_m: float = 0.15,
                    workers: int = 2, scheduler=None) -> pd.DataFrame:
    """Fraction under ``threshold_m`` by the conditional estimator for every layout and period reading.

    Same seed and size for every cell (``cfg.n_positions``), so the readings differ only by
    their periods; the per-beacon cells are read from ``maps`` (:func:`map_space`, the same
    run) when given. One row per (layout, reading): fraction, 95 % interval (%), positions.
    """
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    rows = []
    for layout in LAYOUTS:
        for reading in READINGS:
            if maps is not None and layout in maps and READINGS[reading] is None:
                e = maps[layout].conditional.estimate(threshold_m)
            else:
                e = smp.conditional(make_model(layout, cfg, reading), *ref, cfg.n_positions,
                                    seed=np.random.SeedSequence(cfg.seed).spawn(3)[1], thresholds_m=(threshold_m,),
                                    workers=workers, scheduler=scheduler).estimates[0]
            rows.append({"layout": layout, "reading": reading, **_percent(e), "positions": e.n_positions,
                         "paper (%)": PAPER["fraction_15cm_pct"][layout]})
    return pd.DataFrame(rows)


def figure_samples(layout: str, cfg: StudyConfig, *, workers: int = 2, scheduler=None) -> dict[float, smp.SamplerResult]:
    """Figs 3–4: the conditional sampler run once *per threshold* of the paper's panels.

    A run sized for one threshold draws its velocities in that threshold's ellipsoid, so
    small thresholds get samples of their own (a run sized for 15 cm holds almost none
    under 2 cm). Returns ``{threshold_m: SamplerResult}``, ``cfg.n_fig_positions`` positions each.
    """
    model = make_model(layout, cfg)
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    out = {}
    for k, t_cm in enumerate(PAPER["thresholds_cm"][layout]):
        seed = np.random.SeedSequence([cfg.seed, 3, k])
        out[t_cm / 100] = smp.conditional(model, *ref, cfg.n_fig_positions, seed=seed, thresholds_m=(t_cm / 100,),
                                          workers=workers, scheduler=scheduler)
    return out


def distinct_counts(samples: smp.GhostSamples) -> tuple[int, int]:
    """``(distinct (X, V) samples, distinct positions X)`` of a sample set (copies of a sample count once)."""
    if len(samples) == 0:
        return 0, 0
    pairs = np.unique(np.concatenate([samples.pos_m, samples.vel_mps], axis=1), axis=0)
    return int(len(pairs)), int(len(np.unique(samples.pos_m, axis=0)))


def fraction_table(maps: dict[str, SpaceMap], per_threshold: dict[str, dict] | None = None) -> pd.DataFrame:
    """One row per layout, estimator and threshold: fraction (%), 95 % interval, draws, time.

    ``per_threshold`` (:func:`figure_samples` per layout) adds the rows of the conditional
    sampler run for that one threshold ("conditional, per threshold").
    """
    rows = []
    for name, m in maps.items():
        runs = [("brute force", m.brute, m.seconds["brute force"]), ("conditional", m.conditional,
                m.seconds["conditional"]), ("conditional + ranges", m.ranging, m.seconds["conditional + ranges"])]
        runs += [("conditional, per threshold", r, np.nan) for r in (per_threshold or {}).get(name, {}).values()]
        for label, res, sec in runs:
            for e in res.estimates:
                rows.append({"layout": name, "estimator": label, "δ < (cm)": round(100 * e.threshold_m), **_percent(e),
                             "hits": e.n_hits, "exact δ evaluations": e.n_draws, "seconds": sec})
    return pd.DataFrame(rows)


# ------------------------------------------------------------------------------------------ filters

def kf_prior(layout: str) -> Gaussian:
    """The MH-EKF's prior: the moments of the PF's uniform initial cloud (same information for both filters)."""
    lo, hi = (np.asarray(v, float) for v in ROOMS[layout])
    return Gaussian(np.concatenate([(lo + hi) / 2, np.zeros(3)]),
                    np.diag(np.concatenate([(hi - lo) ** 2 / 12, np.full(3, 3.0 ** 2 / 12)])))


def make_filters(layout: str, cfg: StudyConfig, model: dm.DopplerModel, motion: ReceiverMotion = ReceiverMotion(),
                 *, n_particles: int | None = None) -> tuple[fd.DopplerPf, fd.ScaatMhEkf]:
    """The particle filter and the MH-EKF of :func:`track_study`, as configured for ``layout`` and ``cfg``."""
    lo, hi = ROOMS[layout]
    pf = fd.DopplerPf(model, motion, n_particles=n_particles or cfg.n_particles, room_lo_m=lo, room_hi_m=hi)
    mh = fd.ScaatMhEkf(model, motion, p_detect=1 - cfg.p_miss, spurious_rate_hz=max(cfg.spurious_rate_hz, 1e-3))
    return pf, mh


@dataclass(frozen=True)
class TrackStudy:
    """Fig 6 on one simulated recording (:func:`track_study`): PF runs, the MH-EKF, with and without pseudo-ranges."""

    model: dm.DopplerModel
    track: sc.LoopTrack
    recording: sc.ChirpRecording
    log: object
    pf: dict                      # "Doppler" / "Doppler + ranges" -> PfRuns
    kf: dict                      # same keys -> Estimates
    snapshots_s: tuple[float, float]
    along_dirs: tuple[np.ndarray, np.ndarray]
    t_score_s: float

    def cloud(self, variant: str, k: int) -> np.ndarray:
        """PF position estimates of every run at snapshot ``k``, shape ``(R, 3)``."""
        return self.pf[variant].at(self.snapshots_s[k])

    def snapshot_errors(self, variant: str) -> pd.DataFrame:
        """Per snapshot (corner): the run cloud's error, split into the shared offset and the run-to-run spread.

        ``CEP50`` is about the truth; ``offset`` is the distance from the truth to the
        cloud's centre (coordinate-wise median of the runs: what every run shares, the
        recording's own bias); ``run-to-run CEP50`` is about that centre. Along and
        across are robust spreads about the truth, ``1.4826 · median |e|`` per component
        along / across the direction of travel, and their ratio.
        """
        rows = []
        for k, t in enumerate(self.snapshots_s):
            e = self.cloud(variant, k)[:, :2] - self.track.pos_m(t)[:2]
            a = self.along_dirs[k][:2]
            centre = np.median(e, axis=0)
            rows.append({"corner": ("bottom-left", "top-left")[k], "t (s)": t, "runs": e.shape[0],
                         "CEP50 (cm)": 100 * metrics.cep50(np.linalg.norm(e, axis=1)),
                         "offset (cm)": 100 * float(np.linalg.norm(centre)),
                         "run-to-run CEP50 (cm)": 100 * metrics.cep50(np.linalg.norm(e - centre, axis=1)),
                         "along (cm)": 100 * MAD_TO_SIGMA * np.median(np.abs(e @ a)),
                         "across (cm)": 100 * MAD_TO_SIGMA * np.median(np.abs(e @ np.array([-a[1], a[0]])))})
        df = pd.DataFrame(rows)
        df["along / across"] = df["along (cm)"] / df["across (cm)"]
        return df

    def pf_errors_m(self, variant: str) -> np.ndarray:
        """Horizontal errors (m) of every PF run on the scored epochs (its update times after ``t_score_s``),
        shape ``(runs, epochs)``."""
        runs = self.pf[variant]
        keep = runs.t_s > self.t_score_s
        return np.linalg.norm(runs.pos_m[:, keep, :2] - self.track.pos_m(runs.t_s[keep])[:, :2], axis=-1)


def track_study(layout: str, cfg: StudyConfig, *, seed_offset: int = 0, pf_runs: int | None = None,
                n_particles: int | None = None, motion: ReceiverMotion = ReceiverMotion(),
                noise: bool = True, exact_dp: bool = False, variants=("Doppler", "Doppler + ranges"),
                kf: bool = True, workers: int = 1, progress: bool = False, scheduler=None) -> TrackStudy:
    """Simulate one walk of the rectangle (clockwise) and run both filters, with and without ranges.

    The walk starts at the top-left corner; after ``cfg.laps_before`` full laps the two
    snapshots are the arrivals at the bottom-left and then the top-left corner, 3 s apart.
    ``workers`` threads, or the Dask cluster ``scheduler``, run blocks of :data:`BLOCK_RUNS` PF runs
    (the numbers do not depend on it).

    ``noise=False`` simulates no timing jitter, no missed and no spurious chirps;
    ``exact_dp=True`` also replaces every measured ΔP by the filters' own measurement
    model (eq 1, lagged by half a period) evaluated at the true state at its arrival, so
    no model error is left from reading a period average as one state. Both serve :func:`error_floor`.
    """
    model = make_model(layout, cfg)
    track, apex = sc.rectangle_track()
    lap = track.length_m / track.speed_mps
    t_a = track.time_at(apex["bottom-left"]) + cfg.laps_before * lap
    t_b = track.time_at(apex["top-left"], after_s=t_a)
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 4, seed_offset]))
    sim_model = model if noise else replace(model, sigma_t_s=0.0)
    rec = sc.simulate_chirps(sim_model, track, t_b + 1.0, rng=rng, p_miss=cfg.p_miss if noise else 0.0,
                             spurious_rate_hz=cfg.spurious_rate_hz if noise else 0.0)
    log = fd.assign_chirps(rec.t_s, model)
    if exact_dp:
        ok = log.measured
        dp = np.array(log.dp_s, float, copy=True)
        dp[ok] = model.delta_p(track.pos_m(log.t_s[ok]), track.vel(log.t_s[ok]), log.beacon[ok], instantaneous=False)
        log = replace(log, dp_s=dp)
    ranges = fd.clock_pseudo_ranges(log, model, rec.phase_s)
    pf, mh = make_filters(layout, cfg, model, motion, n_particles=n_particles)
    pf_out, kf_out = {}, {}
    for variant in variants:
        r = ranges if variant == "Doppler + ranges" else None
        pf_out[variant] = replace(pf.run(log, n_runs=pf_runs or cfg.pf_runs, rng=rng, ranges_m=r, block_runs=BLOCK_RUNS,
                                         workers=workers, progress=progress, scheduler=scheduler),
                                  name=f"PF ({variant})")
        if kf:
            kf_out[variant] = mh.run(log, kf_prior(layout), ranges_m=r)
    dirs = (np.array([-1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))    # arriving along the bottom, then the left side
    return TrackStudy(model, track, rec, log, pf_out, kf_out, (t_a, t_b), dirs, t_score_s=min(8.0, t_a / 2))


def coverage_95(err_m: np.ndarray, cov_m2: np.ndarray) -> float:
    """Share of errors ``(..., d)`` inside the filter's own 95 % region, :func:`uwbwb.metrics.nees` ``≤ χ²_d(0.95)``
    on its covariances ``(..., d, d)``; a non-finite or singular covariance covers nothing."""
    d = err_m.shape[-1]
    e, P = np.reshape(err_m, (-1, d)), np.reshape(cov_m2, (-1, d, d))
    ok = np.all(np.isfinite(P), axis=(1, 2))
    ok[ok] = np.linalg.det(P[ok]) > 1e-300
    return float(np.mean(metrics.nees(e, P, where=ok) <= chi2.ppf(0.95, d)))


def filter_scores(studies: list[TrackStudy], *, lost_m: float = LOST_M) -> pd.DataFrame:
    """PF and MH-EKF on the same epochs (PF update times after ``t_score_s``), per recording and variant.

    Scored by :func:`uwbwb.metrics.score_epochs`, each filter on its own epochs (the PF's runs pooled; the MH-EKF is
    deterministic, one run): CEP50/CEP95 on the epochs with an estimate, ``with an estimate`` (its ``coverage``),
    ``in track`` (share of scored epochs with horizontal error under ``lost_m``, a missing estimate off the track).
    Beside them ``coverage`` (share of scored epochs whose horizontal truth lies in the filter's own 95 % region,
    :func:`coverage_95` on the x–y block of its position covariance: the MH-EKF's ``pos_cov_m2``, the PF run's
    weighted particle covariance), for the PF its restarts (runs whose particles had all left the room) and the
    share of tempered updates (the MH-EKF has no restart mechanism: its column is 0 by construction), and
    ``PF keeps track`` / ``MH-EKF keeps track`` (:func:`keeps_track`).
    """
    stats = {"own": {"CEP50 (cm)": lambda e: 100 * metrics.cep50(e), "CEP95 (cm)": lambda e: 100 * metrics.cep95(e)},
             "failed_counted": {"in track": lambda e: float(np.mean(e < lost_m))}}
    rows = []
    for k, st in enumerate(studies):
        for variant, runs in st.pf.items():
            keep = runs.t_s > st.t_score_s
            t = runs.t_s[keep]
            kf = st.kf[variant]
            idx = np.searchsorted(kf.t_s, t)
            fit = {"PF": (runs.pos_m[:, keep], runs.pos_cov_m2[:, keep], runs.vel_mps[:, keep]),
                   "MH-EKF": (kf.pos_m[idx], kf.pos_cov_m2[idx], kf.vel_mps[idx])}
            err = {m: p[..., :2] - st.track.pos_m(t)[:, :2] for m, (p, _, _) in fit.items()}
            tab = metrics.score_epochs({m: np.linalg.norm(e, axis=-1).ravel() for m, e in err.items()},
                                       compare=False).table(**stats)
            tab["coverage 95"] = [coverage_95(err[m], fit[m][1][..., :2, :2]) for m in fit]
            row = {"recording": k, "variant": variant, "epochs": int(keep.sum()), "PF runs": runs.n_runs}
            for col, name in (("CEP50 (cm)", "CEP50 (cm)"), ("CEP95 (cm)", "CEP95 (cm)"), ("coverage 95", "coverage"),
                              ("coverage", "with an estimate"), ("in track", "in track")):
                row.update({f"{m} {name}": float(tab.loc[m, col]) for m in fit})
            row.update({"PF restarts": int(runs.restarts.sum()),
                        "PF runs restarted": int(np.count_nonzero(runs.restarts)), "MH-EKF restarts": 0,
                        "PF tempered updates": float(np.mean(runs.meta.get("tempered", np.zeros(1)))),
                        **{f"{m} median |V err| (m/s)": float(np.median(np.linalg.norm(v - st.track.vel(t), axis=-1)))
                           for m, (_, _, v) in fit.items()}})
            rows.append(row)
    df = pd.DataFrame(rows)
    if len(df):
        pf, kf = keeps_track(df["PF in track"], df["PF runs"], df["PF runs restarted"], df["MH-EKF in track"])
        df.insert(df.columns.get_loc("PF in track"), "PF keeps track", pf)
        df.insert(df.columns.get_loc("PF in track"), "MH-EKF keeps track", kf)
    return df


def keeps_track(pf_in_track, pf_runs, pf_runs_restarted, kf_in_track):
    """:data:`KEEPS_TRACK` on one recording and variant (or on Series of them, or on the pooled shares):
    ``(PF keeps track, MH-EKF keeps track)``. The PF keeps track when its share of scored epochs within
    :data:`LOST_M` (pooled over runs) is at least ``KEEPS_TRACK[0]`` and at most ``KEEPS_TRACK[1]`` of its runs
    restarted; the MH-EKF on its share alone."""
    return ((pf_in_track >= KEEPS_TRACK[0]) & (pf_runs_restarted <= KEEPS_TRACK[1] * pf_runs),
            kf_in_track >= KEEPS_TRACK[0])


#: Conditions of :func:`error_floor`: (label, simulate noise, ΔP from eq 1 at the true state, particles factor).
FLOOR_CONDITIONS = (("as simulated", True, False, 1), ("zero noise", False, False, 1),
                    ("zero noise, exact eq-1 ΔP", False, True, 1), ("zero noise, exact eq-1 ΔP, 4× particles",
                                                                     False, True, 4))


def error_floor(layout: str, cfg: StudyConfig, *, seed_offset: int = 0, workers: int = 1,
                scheduler=None, first: TrackStudy | None = None) -> pd.DataFrame:
    """What the Doppler-only PF's CEP50 is made of, measured on one recording (Doppler only).

    The same walk (same seed) is filtered under each of :data:`FLOOR_CONDITIONS`: as
    simulated; with no timing jitter, misses or spurious chirps; with ΔP also replaced by
    eq 1 at the true state (removes the model error of reading a period-averaged ΔP as one
    state); and that with four times the particles (the particle count's share). Each row:
    snapshot CEP50 (both corners pooled), offset and run-to-run CEP50 (mean of the corners),
    CEP50 over all scored epochs, and its drop from the row above with the 95 % interval of
    :func:`uwbwb.metrics.block_bootstrap_difference` (medians, each run one block) where the two rows'
    runs share their epochs (not across the noise step, whose chirps differ; NaN also with fewer runs than
    :data:`uwbwb.metrics.MIN_BLOCKS`). The last condition's CEP50 is a floor only if that drop is nil within its
    interval.

    ``first`` is :func:`track_study` of the same ``layout``, ``cfg`` and ``seed_offset`` with its default motion and
    particles (the notebook's first recording). Where its Doppler PF ran ``cfg.floor_runs`` runs or more and
    ``cfg.floor_runs`` fills whole blocks of :data:`BLOCK_RUNS`, its first ``cfg.floor_runs`` runs are the first
    condition's (the same recording, the same draws) and are read from it instead of run again.
    """
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 5, seed_offset]))
    rows, errs = [], []
    runs = None if first is None else first.pf.get("Doppler")
    for label, noise, exact, factor in FLOOR_CONDITIONS:
        n = cfg.floor_runs
        if (noise, exact, factor) == (True, False, 1) and runs is not None and n % BLOCK_RUNS == 0 \
                and runs.n_runs >= n and runs.meta["n_particles"] == cfg.n_particles:
            st = replace(first, kf={}, pf={"Doppler": replace(
                runs, pos_m=runs.pos_m[:n], status=runs.status[:n], pos_cov_m2=runs.pos_cov_m2[:n],
                vel_mps=runs.vel_mps[:n], info={"ess": runs.ess[:n]},
                meta={**runs.meta, "restarts": runs.restarts[:n], "tempered": runs.meta["tempered"][:n]})})
        else:
            st = track_study(layout, cfg, seed_offset=seed_offset, pf_runs=n, noise=noise, exact_dp=exact,
                             n_particles=factor * cfg.n_particles, variants=("Doppler",), kf=False, workers=workers,
                             scheduler=scheduler)
        snap, e = st.snapshot_errors("Doppler"), st.pf_errors_m("Doppler")
        clouds = [st.cloud("Doppler", k)[:, :2] - st.track.pos_m(t)[:2] for k, t in enumerate(st.snapshots_s)]
        drop = (metrics.block_bootstrap_difference(list(errs[-1]), list(e), rng=rng, statistic="median",
                                                    blocks="segment") if errs and errs[-1].shape == e.shape else {})
        errs.append(e)
        rows.append({"condition": label, "particles": factor * cfg.n_particles, "runs": e.shape[0],
                     "snapshot CEP50 (cm)": 100 * metrics.cep50(np.linalg.norm(np.concatenate(clouds), axis=1)),
                     "offset (cm)": float(snap["offset (cm)"].mean()),
                     "run-to-run CEP50 (cm)": float(snap["run-to-run CEP50 (cm)"].mean()),
                     "CEP50, scored epochs (cm)": 100 * metrics.cep50(e.ravel()),
                     "drop 95 % low (cm)": 100 * drop.get("lo_m", np.nan),
                     "drop 95 % high (cm)": 100 * drop.get("hi_m", np.nan)})
    df = pd.DataFrame(rows).set_index("condition")
    df.insert(df.columns.get_loc("drop 95 % low (cm)"), "drop from the row above (cm)",
              -df["CEP50, scored epochs (cm)"].diff())
    return df
