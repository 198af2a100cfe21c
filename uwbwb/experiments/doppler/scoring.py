"""Notebook 04's filter results and their scores: one recording's runs and the tables over recordings.

Fig 6 and the filter comparison: :class:`TrackStudy` (the PF runs and the MH-EKF on one simulated
recording, its snapshot errors), :func:`coverage_95` (coverage of a filter's own 95 % region) and
:func:`filter_scores` (PF and MH-EKF on the same epochs, with the keeps-track rule :data:`KEEPS_TRACK` applied
to each per recording).
:mod:`.study` runs the filters and builds the :class:`TrackStudy`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import chi2

from ... import metrics
from ...calibration import MAD_TO_SIGMA
from ...models import doppler as dm
from ...sim import chirps as sc

__all__ = ["TrackStudy", "coverage_95", "filter_scores", "keeps_track", "KEEPS_TRACK", "LOST_M"]

#: A filter *keeps track* on a recording when at least ``KEEPS_TRACK[0]`` of its scored epochs have a
#: horizontal error under :data:`LOST_M` (the PF: pooled over its runs) and, for the PF, at most
#: ``KEEPS_TRACK[1]`` of its runs restarted (the MH-EKF does not restart).
KEEPS_TRACK = (0.95, 0.05)
#: Horizontal error (m) beyond which an epoch counts as off the track.
LOST_M = 0.5


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
            c = np.array([-a[1], a[0]])
            centre = np.median(e, axis=0)
            along, cross = e @ a, e @ c
            rows.append({"corner": ("bottom-left", "top-left")[k], "t (s)": t, "runs": e.shape[0],
                         "CEP50 (cm)": 100 * metrics.cep50(np.linalg.norm(e, axis=1)),
                         "offset (cm)": 100 * float(np.linalg.norm(centre)),
                         "run-to-run CEP50 (cm)": 100 * metrics.cep50(np.linalg.norm(e - centre, axis=1)),
                         "along (cm)": 100 * MAD_TO_SIGMA * np.median(np.abs(along)),
                         "across (cm)": 100 * MAD_TO_SIGMA * np.median(np.abs(cross))})
        df = pd.DataFrame(rows)
        df["along / across"] = df["along (cm)"] / df["across (cm)"]
        return df

    def pf_errors_m(self, variant: str) -> np.ndarray:
        """Horizontal errors (m) of every PF run on the scored epochs (its update times after ``t_score_s``),
        shape ``(runs, epochs)``."""
        runs = self.pf[variant]
        keep = runs.t_s > self.t_score_s
        return np.linalg.norm(runs.pos_m[:, keep, :2] - self.track.pos_m(runs.t_s[keep])[:, :2], axis=-1)


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

    CEP50/CEP95 pool all PF runs; the MH-EKF is deterministic (one run). Beside accuracy:
    ``coverage`` (share of scored epochs whose horizontal truth lies in the filter's own
    95 % region, :func:`coverage_95` on the x–y block of its position covariance: the
    MH-EKF's ``pos_cov_m2``, the PF run's weighted particle covariance), ``with an
    estimate`` (share of scored epochs with a finite estimate), ``in track`` (share of scored
    epochs with horizontal error under ``lost_m``) and, for the PF, its restarts (runs
    whose particles had all left the room) and the share of tempered updates. The MH-EKF
    has no restart mechanism (its column is 0 by construction). ``PF keeps track`` and ``MH-EKF
    keeps track`` apply the rule :data:`KEEPS_TRACK` to each filter on each recording.
    """
    rows = []
    for k, st in enumerate(studies):
        for variant in st.pf:
            runs = st.pf[variant]
            keep = runs.t_s > st.t_score_s
            t = runs.t_s[keep]
            truth = st.track.pos_m(t)[:, :2]
            e_pf = st.pf_errors_m(variant).ravel()
            kf = st.kf[variant]
            idx = np.searchsorted(kf.t_s, t)
            e_kf = np.linalg.norm(kf.pos_m[idx, :2] - truth, axis=-1)
            v_kf = np.linalg.norm(kf.vel_mps[idx] - st.track.vel(t), axis=-1)
            v_pf = np.linalg.norm(runs.vel_mps[:, keep] - st.track.vel(t), axis=-1).ravel()
            rows.append({"recording": k, "variant": variant, "epochs": int(keep.sum()), "PF runs": runs.n_runs,
                         "PF CEP50 (cm)": 100 * metrics.cep50(e_pf), "MH-EKF CEP50 (cm)": 100 * metrics.cep50(e_kf),
                         "PF CEP95 (cm)": 100 * metrics.cep95(e_pf), "MH-EKF CEP95 (cm)": 100 * metrics.cep95(e_kf),
                         "PF coverage": coverage_95(runs.pos_m[:, keep, :2] - truth, runs.pos_cov_m2[:, keep, :2, :2]),
                         "MH-EKF coverage": coverage_95(kf.pos_m[idx, :2] - truth, kf.pos_cov_m2[idx, :2, :2]),
                         "PF with an estimate": float(np.mean(np.all(np.isfinite(runs.pos_m[:, keep]), axis=-1))),
                         "MH-EKF with an estimate": float(np.mean(np.all(np.isfinite(kf.pos_m[idx]), axis=-1))),
                         "PF in track": float(np.mean(e_pf < lost_m)), "MH-EKF in track": float(np.mean(e_kf < lost_m)),
                         "PF restarts": int(runs.restarts.sum()), "PF runs restarted": int(np.count_nonzero(runs.restarts)),
                         "MH-EKF restarts": 0,
                         "PF tempered updates": float(np.mean(runs.meta.get("tempered", np.zeros(1)))),
                         "PF median |V err| (m/s)": float(np.median(v_pf)),
                         "MH-EKF median |V err| (m/s)": float(np.median(v_kf))})
    df = pd.DataFrame(rows)
    if len(df):
        pf, kf = keeps_track(df)
        df.insert(df.columns.get_loc("PF in track"), "PF keeps track", pf)
        df.insert(df.columns.get_loc("PF in track"), "MH-EKF keeps track", kf)
    return df


def keeps_track(scores: pd.DataFrame) -> tuple[pd.Series, pd.Series]:
    """:data:`KEEPS_TRACK` on each row of :func:`filter_scores` (one recording and variant): ``(PF, MH-EKF)``.

    The PF keeps track when its share of scored epochs within :data:`LOST_M` (pooled over runs) is at
    least ``KEEPS_TRACK[0]`` and at most ``KEEPS_TRACK[1]`` of its runs restarted; the MH-EKF on its share
    alone.
    """
    pf = (scores["PF in track"] >= KEEPS_TRACK[0]) & (scores["PF runs restarted"] <= KEEPS_TRACK[1] * scores["PF runs"])
    return pf.rename("PF keeps track"), (scores["MH-EKF in track"] >= KEEPS_TRACK[0]).rename("MH-EKF keeps track")
