"""The set-noise filters of notebook 01 and the windowed trajectory NLS of notebook 02 as board estimators.

Both run on parts of a recording (emulated sensor-set fixes; fixed-length windows) and place their
parts on the tag's epochs here; both tune one knob on the calibration part (σ_d; the window length).
"""

from __future__ import annotations

import hashlib
import zlib
from dataclasses import dataclass, field

import numpy as np

from .. import bounds
from ..calibration import fit_set_noise_from_fixes
from ..filters.nls import TrajectoryFit, fit_trajectory
from ..filters.setnoise import kf_sweep, model_noise, run_set_noise_kf, run_set_noise_pf
from ..models.motion import VelocityKick
from ..sim.setnoise import SetEmulation, emulate_set_fixes
from ..types import Estimates, RangeLog, RangeSamples
from .interface import _NONE, _UP, BaseEstimator, _tuning_scores, on_grid_edge

__all__ = ["SIGMA_D_GRID_MPS", "SetNoiseFilter", "NLS_WINDOWS_S", "WindowNls"]


# ----------------------------------------------------------------------------- set-noise filters

#: σ_d grid (m/s per step) searched by the set-noise KF on the calibration part.
SIGMA_D_GRID_MPS = (0.02, 0.04, 0.08, 0.15, 0.3, 0.6)


@dataclass(frozen=True)
class SetNoiseFilter(BaseEstimator):
    """The set-noise Kalman filter or particle filter of notebook 01 on emulated sensor sets.

    ``tune`` emulates fixes on the calibration part, fits the per-set noise model on them
    (one location per tag) and picks σ_d minimising the KF's RMSE there; the PF uses the
    same σ_d and model. Both start at the first fix (the paper starts at the known true
    position; that would use the truth). 2-D only. Bound: the posterior CRLB of the same
    constant-velocity model given the fixes and their per-set σ.
    """

    kind: str = "KF"
    n_particles: int = 1000
    emulation: SetEmulation = SetEmulation()
    seed: int = 0

    @property
    def name(self) -> str:
        return f"set-noise {self.kind}"

    def applies(self, rec, tag, cal):
        if cal.dim != 2:
            return "the set-noise filters are planar (state x, ẋ, y, ẏ)"
        if len(rec.anchors) < self.emulation.set_size:
            return f"needs at least {self.emulation.set_size} anchors to emulate sets"
        return None

    def _rng(self, rec, tag) -> np.random.Generator:
        return np.random.default_rng([self.seed, zlib.crc32(f"{rec.label}/{tag}/{self.name}".encode())])

    def _fixes(self, rec, tag, cal, truth: bool = False):
        log = rec.ranges_of(tag, cal.range_calibration)
        t = rec.truth_at(tag, log.t_s, 2) if truth else None
        em = emulate_set_fixes(log, rec.anchors.pos_m, cal.height(tag), self.emulation, rng=self._rng(rec, tag),
                               truth_m=t, name=f"{rec.label}/{tag}")
        return em.fixes, em.row

    def tune(self, rec, tags, cal):
        if self.kind != "KF":
            return {}                                 # the PF takes the KF's tuning (see estimate)
        fixes = [self._fixes(rec, t, cal, truth=True)[0] for t in tags]
        model = fit_set_noise_from_fixes(fixes)
        sq = [np.sum((kf_sweep(f.t_s, f.pos_m, *model_noise(f, model), f.pos_m[0], SIGMA_D_GRID_MPS).pos_m
                      - f.truth_m) ** 2, axis=-1) for f in fixes]          # per tag (σ_d, fix): every σ_d at once
        cost = [float(np.sqrt(np.mean(np.concatenate([e[j] for e in sq])))) for j in range(len(SIGMA_D_GRID_MPS))]
        best = int(np.argmin(cost))
        return {"sigma_d_mps": float(SIGMA_D_GRID_MPS[best]), "model": model, "n_sets": len(model),
                "grid_rmse_m": tuple(cost), "grid_edge": on_grid_edge(best, len(SIGMA_D_GRID_MPS))}

    def _params(self, cal):
        p = cal.params("set-noise KF")
        if "model" not in p:
            raise ValueError("the set-noise filters need the set-noise KF's tuning (include 'set-noise KF' in the board)")
        return p

    def estimate(self, rec, tag, cal):
        p = self._params(cal)
        log = rec.ranges[tag]
        fixes, idx = self._fixes(rec, tag, cal)
        T = len(log)
        pos = np.full((T, 2), np.nan)
        status = np.full(T, _NONE, np.int8)
        cov = np.full((T, 2, 2), np.nan) if self.kind == "KF" else None
        info = {"nis": np.full(T, np.nan), "dof": np.zeros(T, int)}
        if len(fixes):
            if self.kind == "KF":
                run = run_set_noise_kf(fixes, p["model"], fixes.pos_m[0], p["sigma_d_mps"], name=self.name)
                cov[idx] = run.cov[:, :2, :2]
                info["nis"][idx], info["dof"][idx] = run.nis, run.dof
            else:
                run = run_set_noise_pf(fixes, p["model"], fixes.pos_m[0], p["sigma_d_mps"], rng=self._rng(rec, tag),
                                       n_particles=self.n_particles, name=self.name)
            pos[idx] = run.pos_m
            status[idx] = _UP
        return Estimates(log.t_s, pos, status, self.name, cov, None, info)

    def bound(self, rec, tag, cal, est):
        p = self._params(cal)
        return self._bound(rec, tag, cal, est, p["model"], p["sigma_d_mps"])

    def measured_noise_bound(self, rec, tag, cal, est):
        """The bound with the per-set noise model refitted on the scored part's own emulated fixes against its
        truth (the bound's noise assumption, measured where it is scored); None where that fit is not possible."""
        p = self._params(cal)
        fixes = self._fixes(rec, tag, cal, truth=True)[0]
        if len(fixes) == 0 or not np.all(np.isfinite(fixes.truth_m)):
            return None
        try:
            model = fit_set_noise_from_fixes([fixes])
            return self._bound(rec, tag, cal, est, model, p["sigma_d_mps"])
        except ValueError:            # too few fixes of a set on this part to fit its noise
            return None

    def _bound(self, rec, tag, cal, est, model, sigma_d_mps):
        fixes, idx = self._fixes(rec, tag, cal)
        C = np.full((len(est), 2, 2), np.nan)
        kind = "PCRLB set-noise CV (given the fixes)"
        if len(fixes) == 0:
            return bounds.Bound(est.t_s, C, kind)
        _, sd = model_noise(fixes, model)
        info = np.zeros((len(fixes), 2, 2))
        info[:, [0, 1], [0, 1]] = 1 / sd ** 2                          # per-axis σ of each fix's set
        P0 = np.diag([1e4, 1e4, 1.0, 1.0])       # position from the first fix, velocity ~ 1 m/s
        C[idx] = bounds.tracking_bound(VelocityKick(sigma_d_mps), fixes.t_s, info, P0)
        have = np.all(np.isfinite(rec.truth_at(tag, est.t_s, 2)), axis=1)
        C[~have] = np.nan
        return bounds.Bound(est.t_s, C, kind)


# ----------------------------------------------------------------------------- trajectory NLS

#: Window lengths (s) the windowed NLS tries on the calibration part.
NLS_WINDOWS_S = (0.5, 1.0, 2.0)


@dataclass(frozen=True)
class WindowNls(BaseEstimator):
    """Trajectory NLS of notebook 02 (:func:`uwbwb.filters.nls.fit_trajectory`, eq. 1: a
    constant-velocity line ``P0 + v (t − t0)`` fitted to all ranges of a segment) on
    consecutive fixed-length windows, so that no truth is needed to cut segments. ``tune``
    picks the window length on the calibration part. Bound: the CRLB of the same line fit
    per window (:func:`uwbwb.bounds.line_crlb`).

    ``fits`` keeps each window's line by the window's content (the same window recurs: the pruned variants of
    :class:`uwbwb.experiments.hanyang.estimators.PrunedNls` given the same dict start from it).
    """

    name: str = "NLS"
    windows_s: tuple[float, ...] = NLS_WINDOWS_S
    fits: dict = field(default_factory=dict, repr=False, compare=False)
    _covariance = True                        # a subclass whose window fits give no covariance sets False

    def _windows(self, log: RangeLog, w: float) -> np.ndarray:
        return np.floor((log.t_s - log.t_s[0]) / w).astype(int) if len(log) else np.zeros(0, int)

    def _line(self, samples: RangeSamples, rec, tag, cal) -> TrajectoryFit | None:
        """Eq. (1) fitted to one window's ranges (None where it cannot be solved), from :attr:`fits` where solved."""
        z, A = cal.height(tag), rec.anchors.pos_m
        head = [len(samples), len(A), cal.dim, np.nan if z is None else z]
        key = hashlib.blake2b(b"".join(np.ascontiguousarray(a).tobytes() for a in (
            head, samples.t_s, samples.anchor_index, samples.range_m, A)), digest_size=16).digest()
        if key not in self.fits:
            try:
                self.fits[key] = fit_trajectory(samples, rec.anchors, dim=cal.dim, z_m=z)
            except ValueError:
                self.fits[key] = None
        return self.fits[key]

    def _fit(self, part: RangeLog, rec, tag, cal) -> tuple[np.ndarray, np.ndarray | None] | None:
        """One window's positions (and covariances) at its epochs, or None where it does not fit."""
        d = cal.dim
        samples = RangeSamples.from_ranges(part)
        if len(samples) < 2 * d + 2:
            return None
        fit = self._line(samples, rec, tag, cal)
        if fit is None or not fit.converged:
            return None
        tau = part.t_s - fit.t0_s
        A = np.concatenate([np.broadcast_to(np.eye(d), (len(part), d, d)), tau[:, None, None] * np.eye(d)], axis=-1)
        return fit.position_at(part.t_s)[:, :d], np.einsum("kij,jl,kml->kim", A, fit.cov, A)

    def _run(self, rec, tag, cal, w) -> Estimates:
        log = rec.ranges_of(tag, cal.range_calibration)
        T, d = len(log), cal.dim
        pos, cov = np.full((T, d), np.nan), np.full((T, d, d), np.nan)
        status = np.full(T, _NONE, np.int8)
        win = self._windows(log, w)
        for k in np.unique(win):
            idx = np.flatnonzero(win == k)
            got = self._fit(log.select(idx), rec, tag, cal) if idx.size >= 3 else None
            if got is None:
                continue
            pos[idx], status[idx] = got[0], _UP
            if got[1] is not None:
                cov[idx] = got[1]
        return Estimates(log.t_s, pos, status, self.name, cov if self._covariance else None, None, {"window": win})

    def tune(self, rec, tags, cal):
        cost = [np.mean([_tuning_scores(self._run(rec, t, cal, w), rec, t)["rmse"] for t in tags])
                for w in self.windows_s]
        best = int(np.argmin(cost))
        return {"window_s": float(self.windows_s[best]), "grid_rmse_m": tuple(float(c) for c in cost),
                "grid_edge": on_grid_edge(best, len(self.windows_s))}

    def estimate(self, rec, tag, cal):
        return self._run(rec, tag, cal, cal.params(self.name)["window_s"])

    def bound(self, rec, tag, cal, est):
        log = rec.ranges_of(tag, cal.range_calibration)
        pos = rec.truth_at(tag, log.t_s, cal.dim)
        C = np.full((len(log), cal.dim, cal.dim), np.nan)
        win = np.asarray(est.info["window"])
        for k in np.unique(win):
            idx = np.flatnonzero((win == k) & est.has_estimate)
            if idx.size < 2 or not np.all(np.isfinite(pos[idx])):
                continue
            C[idx] = bounds.line_crlb(log.t_s[idx], pos[idx], rec.anchors.pos_m, cal.sigma(tag), z_m=cal.height(tag),
                                      mask=np.isfinite(log.range_m[idx]))
        return bounds.Bound(log.t_s, C, "CRLB line fit per window")
