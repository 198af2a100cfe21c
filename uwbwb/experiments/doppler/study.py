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

from ... import metrics
from ... import sampling as smp
from ...calibration import MAD_TO_SIGMA
from ...filters import doppler as fd
from ...filters.kalman import Gaussian
from ...models import doppler as dm
from ...sim import chirps as sc

__all__ = ["PAPER", "StudyConfig", "LAYOUTS", "ROOMS", "make_model", "reference_table", "SpaceMap", "map_space",
           "fraction_table", "band_direction", "cuts", "fisher_analysis", "ghost_geometry", "TrackStudy",
           "track_study", "filter_scores"]

#: Numbers quoted by the paper (inputs, never targets of a tuning).
PAPER = {
    "dp_ref_ms": {0: 1.1, 7: -1.2},
    "fraction_15cm_pct": {"cubic": 0.0005, "lab": 0.0186},
    "cep50_cm": 25.0,
    "along_over_cross": 0.5,
    "thresholds_cm": {"cubic": (2, 4, 6, 8), "lab": (4, 8)},
}

LAYOUTS = {"cubic": dm.cubic_layout, "lab": dm.lab_layout}
#: Rooms the receiver is known to be in (filters' bounds and priors): the cube, and the
#: reconstructed lab (6 m × 5 m, floor 1.2 m below the receiver's carrying height z = 0,
#: ceiling at 1.5 m).
ROOMS = {"cubic": ((-2.0, -2.0, -2.0), (2.0, 2.0, 2.0)), "lab": ((-3.0, -2.5, -1.2), (3.0, 2.5, 1.5))}


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
        Independent particle-filter runs over the one recording (Fig 6: 1000) and particles
        per run (the paper does not say; 1000 runs × 1000 particles over the ~30 s walk take
        about half an hour on two busy cores).
    n_recordings
        Independent recordings on which the PF and the MH-EKF are compared.
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
    pf_runs: int = 1000
    n_particles: int = 1000
    n_recordings: int = 5
    compare_runs: int = 20
    temperature_c: float = 20.0
    sigma_range_m: float = 0.015
    p_miss: float = 0.05
    spurious_rate_hz: float = 0.5
    laps_before: int = 1

    @classmethod
    def for_mode(cls, fast: bool, seed: int = 0, **changes) -> "StudyConfig":
        base = cls(fast=True, seed=seed, n_brute=20_000_000, n_positions=100_000, pf_runs=16, n_particles=800,
                   n_recordings=1, compare_runs=4, laps_before=0) if fast else cls(seed=seed)
        return replace(base, **changes)


def make_model(layout: str, cfg: StudyConfig, **changes) -> dm.DopplerModel:
    """The layout's :class:`DopplerModel`: periods 501, 507, … ms, v_s at ``cfg.temperature_c``."""
    v_s = dm.speed_of_sound_mps(cfg.temperature_c)
    return dm.DopplerModel.for_layout(LAYOUTS[layout](), v_s_mps=v_s, sigma_t_s=cfg.sigma_range_m / v_s,
                                      **changes)


def reference_table(model: dm.DopplerModel) -> pd.DataFrame:
    """ΔP_ref per beacon at the reference pair: with the model's periods and with P = 0.5 s for all."""
    X, V = dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS
    dp = model.delta_p(X, V)
    half = dm.DopplerModel(model.beacons, 0.5 + 1e-9 * np.arange(model.n_beacons), v_s_mps=model.v_s_mps)
    rows = []
    for i, b in enumerate(model.beacons.ids):
        rows.append({"beacon": b, "position (m)": tuple(model.beacons.pos_m[i].round(2)),
                     "P (ms)": 1e3 * model.period_s[i], "ΔP_ref (ms), this P": 1e3 * dp[i],
                     "ΔP_ref (ms), P = 500 ms": 1e3 * half.delta_p(X, V)[i],
                     "paper (ms)": PAPER["dp_ref_ms"].get(i, np.nan)})
    return pd.DataFrame(rows).set_index("beacon")


@dataclass(frozen=True)
class SpaceMap:
    """Section 3 for one layout: brute force, conditional, and conditional with pseudo-ranges."""

    layout: str
    model: dm.DopplerModel
    brute: smp.SamplerResult
    conditional: smp.SamplerResult
    ranging: smp.SamplerResult
    seconds: dict = field(default_factory=dict)


def map_space(layout: str, cfg: StudyConfig, *, workers: int = 2, progress: bool = False,
              scheduler=None) -> SpaceMap:
    """Fractions of the 6-D box under each threshold, by both estimators, and with the ranging term.

    The samplers' chunks run in ``workers`` threads, or on the Dask cluster ``scheduler``
    (:mod:`uwbwb.parallel`; the numbers do not depend on it).
    """
    import time

    model = make_model(layout, cfg)
    ref = (dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    seeds = np.random.SeedSequence(cfg.seed).spawn(3)
    t0 = time.perf_counter()
    brute = smp.brute_force(model, *ref, cfg.n_brute, seed=seeds[0], keep_below_m=0.15, workers=workers,
                            progress=progress, scheduler=scheduler)
    t1 = time.perf_counter()
    cond = smp.conditional(model, *ref, cfg.n_positions, seed=seeds[1], workers=workers, progress=progress,
                           scheduler=scheduler)
    t2 = time.perf_counter()
    rang = smp.conditional(model, *ref, cfg.n_positions, seed=seeds[2], workers=workers, ranges=True,
                           progress=progress, scheduler=scheduler)
    t3 = time.perf_counter()
    return SpaceMap(layout, model, brute, cond, rang, {"brute force": t1 - t0, "conditional": t2 - t1,
                                                       "conditional + ranges": t3 - t2})


def fraction_table(maps: dict[str, SpaceMap]) -> pd.DataFrame:
    """One row per layout, estimator and threshold: fraction (%), 95 % interval, draws, time."""
    rows = []
    for name, m in maps.items():
        for label, res in (("brute force", m.brute), ("conditional", m.conditional),
                           ("conditional + ranges", m.ranging)):
            for e in res.estimates:
                rows.append({"layout": name, "estimator": label, "δ < (cm)": round(100 * e.threshold_m),
                             "fraction (%)": 100 * e.fraction, "95 % low (%)": 100 * e.ci_low,
                             "95 % high (%)": 100 * e.ci_high, "hits": e.n_hits, "exact δ evaluations": e.n_draws,
                             "seconds": m.seconds[label],
                             "paper (%)": PAPER["fraction_15cm_pct"][name] if round(100 * e.threshold_m) == 15
                             and label == "conditional" else np.nan})
    return pd.DataFrame(rows)


def band_direction(samples: smp.GhostSamples) -> np.ndarray:
    """Unit x–y direction of the longest axis of the (weighted) position cloud (Fig 3d's diagonal band)."""
    w = samples.weight / samples.weight.sum()
    xy = samples.pos_m[:, :2]
    mean = w @ xy
    cov = (xy - mean).T @ ((xy - mean) * w[:, None])
    vals, vecs = np.linalg.eigh(cov)
    d = vecs[:, -1]
    return np.array([d[0], d[1], 0.0]) * (1 if d[0] >= 0 else -1)


def cuts(model: dm.DopplerModel, direction, velocities: dict[str, np.ndarray], s_m: np.ndarray) -> pd.DataFrame:
    """Fig 5: δ (cm) along ``X_ref + s · direction`` for fixed velocities."""
    X = dm.REFERENCE_POS_M + np.outer(s_m, direction)
    ref = model.delta_p(dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    out = {"s (m)": s_m}
    for name, v in velocities.items():
        out[name] = 100 * model.distance_m(model.delta_p(X, np.broadcast_to(v, X.shape)), ref)
    return pd.DataFrame(out)


def fisher_analysis(model: dm.DopplerModel) -> dict:
    """Jacobian of ``v_s ΔP`` at the reference pair and the weak directions of its information matrix.

    Returns the singular values (m per unit of state) and, for the two weakest
    directions, the angle (degrees) between the direction's position part and
    ``V_ref`` and between its velocity part and ``V_ref``.
    """
    X, V = dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS
    J = model.v_s_mps * model.jacobian(X, V)                     # (n, 6), metres per (m | m/s)
    _, s, vt = np.linalg.svd(J)
    v_hat = V / np.linalg.norm(V)
    rows = []
    for k in (5, 4):
        d = vt[k]
        rows.append({"singular value": s[k], "position part": d[:3], "velocity part": d[3:],
                     "|position part|": np.linalg.norm(d[:3]),
                     "angle(position part, V) (°)": _angle(d[:3], v_hat),
                     "angle(velocity part, ±V) (°)": min(_angle(d[3:], v_hat), _angle(-d[3:], v_hat))})
    return {"J": J, "singular_values": s, "weak": rows}


def _angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.degrees(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1, 1))))


def ghost_geometry(samples: smp.GhostSamples) -> dict:
    """Shape of a ghost cloud: the normal of the plane the positions lie on (smallest principal axis)
    and the main axis of the velocities, each with its angle to ``V_ref`` (degrees)."""
    w = samples.weight / samples.weight.sum()
    v_hat = dm.REFERENCE_VEL_MPS / np.linalg.norm(dm.REFERENCE_VEL_MPS)
    out = {}
    for name, pts, axis in (("position plane normal", samples.pos_m, 0), ("velocity main axis", samples.vel_mps, -1)):
        c = pts - w @ pts
        vals, vecs = np.linalg.eigh(c.T @ (c * w[:, None]))
        d = vecs[:, axis]
        out[name] = d
        out[f"angle({name}, V) (°)"] = min(_angle(d, v_hat), _angle(-d, v_hat))
        out[f"{name}: spread ratio"] = float(np.sqrt(vals[0] / vals[-1]))
    return out


# ------------------------------------------------------------------------------------------ filters

@dataclass(frozen=True)
class TrackStudy:
    """Fig 6 on one simulated recording: PF runs, the MH-EKF, with and without pseudo-ranges."""

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
        """Per snapshot: CEP50 (cm) of the run cloud and its error along / across the direction of travel.

        Along and across are robust spreads about the truth, ``1.4826 · median |e|``
        per component (a run that lost track does not dominate them), and their ratio.
        """
        rows = []
        for k, t in enumerate(self.snapshots_s):
            e = self.cloud(variant, k)[:, :2] - self.track.pos_m(t)[:2]
            a = self.along_dirs[k][:2]
            c = np.array([-a[1], a[0]])
            along, cross = e @ a, e @ c
            rows.append({"snapshot": ("bottom-left corner", "top-left corner")[k], "t (s)": t,
                         "CEP50 (cm)": 100 * metrics.cep50(np.linalg.norm(e, axis=1)),
                         "along (cm)": 100 * MAD_TO_SIGMA * np.median(np.abs(along)),
                         "across (cm)": 100 * MAD_TO_SIGMA * np.median(np.abs(cross))})
        df = pd.DataFrame(rows)
        df["along / across"] = df["along (cm)"] / df["across (cm)"]
        return df

    def headline(self, variant: str) -> dict:
        """CEP50 (cm) of both snapshot clouds pooled, and the pooled along / across ratio."""
        errs, along, cross = [], [], []
        for k, t in enumerate(self.snapshots_s):
            e = self.cloud(variant, k)[:, :2] - self.track.pos_m(t)[:2]
            a = self.along_dirs[k][:2]
            errs.append(np.linalg.norm(e, axis=1))
            along.append(e @ a)
            cross.append(e @ np.array([-a[1], a[0]]))
        along, cross = np.abs(np.concatenate(along)), np.abs(np.concatenate(cross))
        return {"cep50_cm": 100 * metrics.cep50(np.concatenate(errs)),
                "along_over_cross": float(np.median(along) / np.median(cross))}


def _kf_prior(layout: str) -> Gaussian:
    lo, hi = (np.asarray(v, float) for v in ROOMS[layout])
    # moments of the PF's uniform initial cloud: same information for both filters
    return Gaussian(np.concatenate([(lo + hi) / 2, np.zeros(3)]),
                    np.diag(np.concatenate([(hi - lo) ** 2 / 12, np.full(3, 3.0 ** 2 / 12)])))


def track_study(layout: str, cfg: StudyConfig, *, seed_offset: int = 0, pf_runs: int | None = None,
                n_particles: int | None = None, motion: dm.ReceiverMotion = dm.ReceiverMotion(),
                workers: int = 1, progress: bool = False, scheduler=None) -> TrackStudy:
    """Simulate one walk of the rectangle (clockwise) and run both filters, with and without ranges.

    The walk starts at the top-left corner; after ``cfg.laps_before`` full laps the two
    snapshots are the arrivals at the bottom-left and then the top-left corner, 3 s apart.
    ``workers`` threads, or the Dask cluster ``scheduler``, run blocks of 25 PF runs
    (the numbers do not depend on it).
    """
    model = make_model(layout, cfg)
    track, apex = sc.rectangle_track()
    lap = track.length_m / track.speed_mps
    t_a = track.time_at(apex["bottom-left"]) + cfg.laps_before * lap
    t_b = track.time_at(apex["top-left"], after_s=t_a)
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 4, seed_offset]))
    rec = sc.simulate_chirps(model, track, t_b + 1.0, rng=rng, p_miss=cfg.p_miss,
                             spurious_rate_hz=cfg.spurious_rate_hz)
    log = fd.assign_chirps(rec.t_s, model)
    ranges = fd.clock_pseudo_ranges(log, model, rec.phase_s)
    lo, hi = ROOMS[layout]
    pf = fd.DopplerPf(model, motion, n_particles=n_particles or cfg.n_particles, room_lo_m=lo, room_hi_m=hi)
    kf = fd.ScaatMhEkf(model, motion, p_detect=1 - cfg.p_miss, spurious_rate_hz=max(cfg.spurious_rate_hz, 1e-3))
    pf_out, kf_out = {}, {}
    for variant, r in (("Doppler", None), ("Doppler + ranges", ranges)):
        pf_out[variant] = replace_name(pf.run(log, n_runs=pf_runs or cfg.pf_runs, rng=rng, ranges_m=r,
                                              block_runs=25, workers=workers, progress=progress,
                                              scheduler=scheduler),
                                       f"PF ({variant})")
        est = kf.run(log, _kf_prior(layout), ranges_m=r)
        kf_out[variant] = est
    dirs = (np.array([-1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))    # arriving along the bottom, then the left side
    return TrackStudy(model, track, rec, log, pf_out, kf_out, (t_a, t_b), dirs, t_score_s=min(8.0, t_a / 2))


def replace_name(runs: fd.PfRuns, name: str) -> fd.PfRuns:
    return replace(runs, name=name)


def filter_scores(studies: list[TrackStudy]) -> pd.DataFrame:
    """CEP50 (cm) of PF and MH-EKF on the same epochs (PF update times after ``t_score_s``), per recording.

    The PF value pools all its runs; the MH-EKF is deterministic (one run). Coverage is 1
    for both (every scored epoch has an estimate).
    """
    rows = []
    for k, st in enumerate(studies):
        for variant in st.pf:
            runs = st.pf[variant]
            keep = runs.t_s > st.t_score_s
            t = runs.t_s[keep]
            truth = st.track.pos_m(t)[:, :2]
            e_pf = np.linalg.norm(runs.pos_m[:, keep, :2] - truth, axis=-1).ravel()
            kf = st.kf[variant]
            idx = np.searchsorted(kf.t_s, t)
            e_kf = np.linalg.norm(kf.pos_m[idx, :2] - truth, axis=-1)
            v_kf = np.linalg.norm(kf.vel_mps[idx] - st.track.vel(t), axis=-1)
            v_pf = np.linalg.norm(runs.vel_mps[:, keep] - st.track.vel(t), axis=-1).ravel()
            rows.append({"recording": k, "variant": variant, "epochs": int(keep.sum()),
                         "PF CEP50 (cm)": 100 * metrics.cep50(e_pf), "MH-EKF CEP50 (cm)": 100 * metrics.cep50(e_kf),
                         "PF CEP95 (cm)": 100 * metrics.cep95(e_pf), "MH-EKF CEP95 (cm)": 100 * metrics.cep95(e_kf),
                         "PF median |V err| (m/s)": float(np.median(v_pf)),
                         "MH-EKF median |V err| (m/s)": float(np.median(v_kf))})
    return pd.DataFrame(rows)
