"""One estimator interface, and every method of the package wrapped into it.

A method joins the board by implementing :class:`Estimator`:

``name``
    Its label in tables and plots (one fixed colour per name, :data:`uwbwb.plotting.COLORS`).
``applies(rec, tag, cal)``
    None if it can run on this recording, else the reason it cannot (e.g. "needs an IMU").
``tune(rec, tags, cal)``
    Parameters chosen on the *calibration* recording (driving noise, window length...),
    returned as a dict; the board stores them in the :class:`~.protocol.Calibration`.
``estimate(rec, tag, cal)``
    Per-epoch :class:`~uwbwb.types.Estimates` over the recording's epochs of ``tag``, using
    only ``cal`` (fitted on other data) and the recording's measurements — never its truth.
``bound(rec, tag, cal, est)``
    The Cramér–Rao bound of this method's own measurement and motion model at the
    estimate's epochs (:class:`uwbwb.bounds.Bound`), evaluated along the truth; None (or
    ``NotImplementedError``) when the method has no model to bound — the board then shows "—"
    for its own bound and still places it against the recording's common bound.

The interface and the helpers every adapter shares are in :mod:`.interface`; the set-noise filters
and the windowed NLS in :mod:`.setnoise_nls`. The adapters wrap the existing
estimators without changing them. Every method
but ``raw LS`` uses the calibrated ranges (the calibration is information every method
is given; ``raw LS`` shows what it is worth). Estimators return the package's common
result type through their results' ``to_estimates()``; the set-noise filters and the
windowed NLS, which run on parts of a recording, place their parts on its epochs here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Mapping

import numpy as np

from .. import bounds, geometry
from ..filters import alignment, imu_calibration
from ..filters.ekf import Ekf, TdoaEkf
from ..filters.ekf.ranges import RangeMeasurement, run_ranges
from ..filters.gating import AnchorDropping, NoGate, Robust, gate_from_prob
from ..filters.kalman import Gaussian
from ..filters.tdoa_ls import tdoa_least_squares
from ..models.motion import RandomForce, make_motion_model
from ..types import Estimates, RangeLog, TdoaLog, Trajectory
from .interface import (BaseEstimator, Estimator, TUNING_CRITERIA, _NONE, _UP, _range_bound, _range_information,
                        _tdoa_model, _tuning_scores, on_grid_edge, tdoa_geometry_note)
from .protocol import Calibration
from .reference import REFERENCE
from .setnoise_nls import NLS_WINDOWS_S, SetNoiseFilter, WindowNls

__all__ = ["RawLs", "CalibratedLs", "TdoaLs", "TdoaEkfEstimator", "RangeEkfEstimator", "UwbInsFilter", "ExternalEstimates", "INS_GRID", "INS_GRID_FAST",
           "UPDATES", "default_estimators", "update_variants"]

# ----------------------------------------------------------------------------- snapshot methods

@dataclass(frozen=True)
class RawLs(BaseEstimator):
    """Per-epoch Gauss–Newton multilateration of the raw ranges (:func:`uwbwb.geometry.multilaterate`),
    unweighted, no range calibration: the baseline. ``front_end`` (``(t_s, range_m) → range_m``), where given,
    transforms the raw ranges first (the Hanyang authors' jump gate and hold; a static range model's correction);
    the bound stays the CRLB of the raw ranges."""

    name: str = "raw LS"
    front_end: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None

    def estimate(self, rec, tag, cal):
        log = rec.ranges[tag]
        r = log.range_m if self.front_end is None else self.front_end(log.t_s, log.range_m)
        res = geometry.multilaterate(r, rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag), t_s=log.t_s,
                                     name=self.name)
        return res.to_estimates()

    def bound(self, rec, tag, cal, est):
        return _range_bound(rec, tag, cal, rec.ranges[tag])


@dataclass(frozen=True)
class CalibratedLs(BaseEstimator):
    """Multilateration of the per-pair calibrated ranges, weighted by the calibrated range noise."""

    name: str = "LS"

    def estimate(self, rec, tag, cal):
        log = rec.ranges_of(tag, cal.range_calibration)
        res = geometry.multilaterate(log.range_m, rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag),
                                     sigma_m=cal.sigma(tag), t_s=log.t_s, name=self.name)
        return res.to_estimates()

    def bound(self, rec, tag, cal, est):
        return _range_bound(rec, tag, cal, rec.ranges_of(tag, cal.range_calibration))


@dataclass(frozen=True)
class TdoaLs(BaseEstimator):
    """Gauss–Newton TDoA fix per epoch (:func:`uwbwb.filters.tdoa_ls.tdoa_least_squares`), pseudo-TDoA
    to anchor ``ref`` with the reference-correlated covariance (``correlated=False``: its diagonal, the shortcut
    notebook 03's exercise tries). Not run where the TDoAs are uninformative
    (:func:`~.interface.tdoa_geometry_note`)."""

    name: str = "TDoA LS"
    ref: int = 0
    correlated: bool = True
    #: on pseudo-TDoAs: notebook 03 runs every estimator of :func:`default_estimators` that says so
    tdoa = True

    def applies(self, rec, tag, cal):
        return tdoa_geometry_note(cal, tag)

    def estimate(self, rec, tag, cal):
        log = rec.ranges_of(tag, cal.range_calibration)
        res = tdoa_least_squares(TdoaLog.from_ranges(log, self.ref), _tdoa_model(rec, tag, cal, self.correlated),
                                 name=self.name)
        return res.to_estimates()

    def bound(self, rec, tag, cal, est):
        log = rec.ranges_of(tag, cal.range_calibration)
        info, _ = _range_information(rec, tag, cal, log, tdoa=True)
        return bounds.Bound(log.t_s, bounds.crlb(info), "CRLB TDoA")


# ----------------------------------------------------------------------------- EKFs: TDoAs and ranges

#: Driving-noise grids searched on the calibration part (model units: m/s, m/s², m/s³).
EKF_GRIDS = {"RW": np.geomspace(0.05, 5.0, 9), "RF": np.geomspace(0.05, 20.0, 9), "RJ": np.geomspace(0.05, 100.0, 9)}
#: The measurement updates an EKF of the board can run (its ``update`` field), each with the suffix its row name
#: gets: ``"gate"`` the filter's χ² gate (the default, no suffix: anchor dropping at ``gate_prob``), ``"none"`` every
#: measurement used, ``"robust"`` / ``"cauchy"`` the M-estimation update (:class:`~uwbwb.filters.gating.Robust`,
#: Huber / Cauchy weights at their declared constants) of every measurement, ``"both"`` the χ² gate first, then the
#: Huber update of the rows it keeps.
UPDATES = {"gate": "", "none": "no gate", "robust": "Huber", "cauchy": "Cauchy", "both": "gate + Huber"}


def _noisier(cal: Calibration, r_scale: float) -> Calibration:
    """``cal`` with every range variance multiplied by ``r_scale`` (itself at 1)."""
    if r_scale == 1.0:
        return cal
    return replace(cal, range_sigma_m={t: np.asarray(s, float) * math.sqrt(r_scale) for t, s in cal.range_sigma_m.items()})


def edge_knobs(grid: tuple[tuple[float, float], ...], best: int) -> tuple[str, ...]:
    """The knobs of the pick ``grid[best]`` (a ``(Q ×, R ×)`` pair) that lie on their grid's edge, each named with
    the end it sits on (``"R × at its highest"``); empty where the pick is inside on both."""
    q, r = grid[best]
    qs, rs = sorted({g[0] for g in grid}), sorted({g[1] for g in grid})
    return tuple(f"{label} at its {'lowest' if v == vals[0] else 'highest'}"
                 for label, v, vals in (("Q ×", q, qs), ("R ×", r, rs)) if on_grid_edge(vals.index(v), len(vals)))


@dataclass(frozen=True)
class _MotionEkf(BaseEstimator):
    """What the TDoA and the range EKFs share: motion model ``model`` (RW, RF, RJ of notebook 03), its
    driving noise tuned on the calibration part over :data:`EKF_GRIDS` (or ``grid``; one value for all tags,
    minimising the mean RMSE, or the mean CEP95 with ``criterion="cep95"``, notebook 03's thesis Table 1
    procedure; both means and each tag's scores are kept at every grid value), and a bound that is the
    posterior CRLB with the same motion model (tuned driving noise), the information of the filter's
    measurements at every epoch and its initial covariance as prior, from the filter's first epoch. ``update``
    picks the measurement update (:data:`UPDATES`; a variant's row name carries its suffix, the default
    ``"gate"`` none), so an ablation row is one argument. A subclass gives the filter (:meth:`_filter`), what its
    run reads that no knob changes (:meth:`_inputs`, made once per tag for the whole grid), its run (:meth:`_run`)
    and its initial covariance (:meth:`_prior`); the information is that of its measurements.

    ``knobs``: tune instead the UWB/INS filters' two knobs on their grid of ``(Q ×, R ×)`` pairs (:data:`INS_GRID`),
    multipliers on the calibrated noise: ``σ_w² = Q × · σ_w,fit²`` (σ_w,fit: this motion model fitted to the
    calibration truth, :func:`~.reference.fit_reference_motion`) and the range variance ``R × · σ²`` of the board's
    calibration. ``R ×`` scales the filter's measurement noise only; its bound keeps the calibrated σ (as the UWB/INS
    filters' bound does)."""

    model: str = "RF"
    gate_prob: float | None = 0.9999
    grid: tuple[float, ...] | None = None
    criterion: str = "rmse"
    update: str = "gate"
    knobs: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self):
        if self.update not in UPDATES:
            raise ValueError(f"{type(self).__name__}.update must be one of {sorted(UPDATES)}, got {self.update!r}")

    _domain = ""                  # what the filter measures, beside its model in its name and bound: TDoAs, " ranges"

    @property
    def name(self) -> str:
        return f"EKF-{self.model}{self._domain}" + (f" ({UPDATES[self.update]})" if UPDATES[self.update] else "")

    def _policy(self, gate):
        """The update policy :data:`UPDATES` names, from the filter's χ² ``gate``."""
        return {"gate": gate, "none": NoGate(gate.max_gated), "robust": Robust(), "cauchy": Robust("cauchy"),
                "both": Robust(gate=gate)}[self.update]

    def _motion(self, cal: Calibration, sigma_w: float):
        return make_motion_model(self.model, sigma=sigma_w, dt_s=1.0 / cal.rate_hz, dim=cal.dim)

    def tune(self, rec, tags, cal):
        if self.criterion not in TUNING_CRITERIA:
            raise ValueError(f"{self.name}: criterion must be one of {TUNING_CRITERIA}, got {self.criterion!r}")
        if self.knobs is None:
            grid = EKF_GRIDS[self.model] if self.grid is None else np.asarray(self.grid, float)
            points = [(float(s), 1.0) for s in grid]
        else:
            s0 = cal.params(REFERENCE).get("sigma_w_per_model", {}).get(self.model)
            if s0 is None:
                raise ValueError(f"{self.name}: (Q ×, R ×) knobs need the {self.model} model fitted to the calibration "
                                 "truth (the common bound's fit found too little truth)")
            grid = tuple((float(q), float(r)) for q, r in self.knobs)
            points = [(s0 * math.sqrt(q), r) for q, r in grid]
        inputs = {t: self._inputs(rec, t, cal) for t in tags}     # what no knob changes: once per tag
        scores = [[_tuning_scores(self._run(rec, t, _noisier(cal, r), s, inputs[t]), rec, t) for t in tags]
                  for s, r in points]
        mean = {c: tuple(float(np.mean([sc[c] for sc in row])) for row in scores) for c in TUNING_CRITERIA}
        best = int(np.argmin(mean[self.criterion]))
        out = {"sigma_w": points[best][0], "grid": tuple(grid) if self.knobs else tuple(float(g) for g in grid),
               "criterion": self.criterion, "grid_rmse_m": mean["rmse"], "grid_cep95_m": mean["cep95"],
               "grid_edge": on_grid_edge(best, len(grid)),
               "grid_by_tag": {t: {c: tuple(row[k][c] for row in scores) for c in TUNING_CRITERIA}
                               for k, t in enumerate(tags)}}
        if self.knobs:
            knobs = edge_knobs(grid, best)
            out.update(q_scale=grid[best][0], r_scale=grid[best][1], grid_edge=bool(knobs), edge_knobs=knobs)
        return out

    def estimate(self, rec, tag, cal):
        p = cal.params(self.name)
        return self._run(rec, tag, _noisier(cal, p.get("r_scale", 1.0)), p["sigma_w"])

    def bound(self, rec, tag, cal, est):
        log = rec.ranges_of(tag, cal.range_calibration)
        info, have = _range_information(rec, tag, cal, log, tdoa=not self._domain)
        start = np.flatnonzero(est.has_estimate)
        C = np.full((len(log), cal.dim, cal.dim), np.nan)
        if start.size:
            k0 = int(start[0])
            ekf = self._filter(rec, tag, cal, cal.params(self.name)["sigma_w"])
            C[k0:] = bounds.tracking_bound(ekf.transition, log.t_s[k0:], info[k0:], self._prior(ekf))
            C[~have] = np.nan                     # no truth there: the bound is not evaluated
        return bounds.Bound(log.t_s, C, f"PCRLB {self.model}{self._domain}")


@dataclass(frozen=True)
class TdoaEkfEstimator(_MotionEkf):
    """The TDoA EKF of notebook 03 (:class:`uwbwb.filters.ekf.TdoaEkf`) with motion model ``model``, on
    pseudo-TDoAs to anchor ``ref`` (reference-correlated covariance; ``correlated=False``: its diagonal), the χ²
    gate on (``gate_prob``). Tuning and bound: :class:`_MotionEkf`, with the TDoA information and the filter's
    initial covariance. Not run where the TDoAs are uninformative (:func:`~.interface.tdoa_geometry_note`).
    """

    ref: int = 0
    correlated: bool = True
    tdoa = True                                # on pseudo-TDoAs (notebook 03 runs it, as :class:`TdoaLs`)

    def applies(self, rec, tag, cal):
        return tdoa_geometry_note(cal, tag)

    def _filter(self, rec, tag, cal, sigma_w) -> TdoaEkf:
        motion, model = self._motion(cal, sigma_w), _tdoa_model(rec, tag, cal, self.correlated)
        ekf = TdoaEkf(motion, model, gate_prob=self.gate_prob)
        return ekf if self.update == "gate" else TdoaEkf(motion, model, gate=self._policy(ekf.gate))

    def _inputs(self, rec, tag, cal) -> TdoaLog:
        """The pseudo-TDoAs of the calibrated ranges (no knob changes them)."""
        return TdoaLog.from_ranges(rec.ranges_of(tag, cal.range_calibration), self.ref)

    def _run(self, rec, tag, cal, sigma_w, inputs=None) -> Estimates:
        log = self._inputs(rec, tag, cal) if inputs is None else inputs
        return self._filter(rec, tag, cal, sigma_w).run(log, name=self.name).to_estimates()

    def _prior(self, ekf):
        return ekf.motion.initial_covariance(ekf.init_pos_sigma_m, ekf.init_vel_sigma_mps, ekf.init_acc_sigma_mps2)


@dataclass(frozen=True)
class RangeEkfEstimator(_MotionEkf):
    """An EKF on the ranges themselves (:class:`~uwbwb.filters.ekf.ranges.RangeMeasurement`): the motion models
    of the TDoA EKF, the calibrated ranges and range noise of the board and the anchor-dropping χ² gate
    (``gate_prob``). Where the TDoAs are uninformative (four anchors in a 2 m cluster, the tag up to 50 m away)
    the ranges still locate the tag. The filter starts at the first epoch with a multilateration fix, with
    standard deviation ``init_sigma`` on every state component (m, m/s, m/s²). Tuning and bound:
    :class:`_MotionEkf`, with the range information.
    """

    init_sigma: float = 1.0
    _domain = " ranges"

    def _filter(self, rec, tag, cal, sigma_w) -> Ekf:
        motion = self._motion(cal, sigma_w)
        meas = RangeMeasurement(rec.anchors.pos_m, cal.sigma(tag), motion, cal.height(tag))
        gate = gate_from_prob(self.gate_prob, 10, self.name, kind=AnchorDropping, min_rows=2)
        return Ekf(motion, meas, vel_index=motion.layout.vel_index, gate=self._policy(gate))

    def _inputs(self, rec, tag, cal) -> tuple[RangeLog, int | None, np.ndarray | None]:
        """The calibrated ranges, the first epoch with a multilateration fix and that fix (None, None: no epoch
        has one); no knob changes them."""
        log = rec.ranges_of(tag, cal.range_calibration)
        fix = geometry.multilaterate(log.range_m, rec.anchors.pos_m, dim=cal.dim, z_m=cal.height(tag))
        ok = np.flatnonzero(np.all(np.isfinite(fix.pos_m), axis=1))
        return (log, None, None) if ok.size == 0 else (log, int(ok[0]), fix.pos_m[ok[0], : cal.dim])

    def _run(self, rec, tag, cal, sigma_w, inputs=None) -> Estimates:
        log, k0, pos0 = self._inputs(rec, tag, cal) if inputs is None else inputs
        ekf = self._filter(rec, tag, cal, sigma_w)
        if k0 is None:
            T = len(log)
            return Estimates(log.t_s, np.full((T, cal.dim), np.nan), np.full(T, _NONE, np.int8), self.name)
        x0 = Gaussian(ekf.transition.initial_state(pos0), self._prior(ekf))
        return run_ranges(ekf, log, x0, start=k0, name=self.name).to_estimates()

    def _prior(self, ekf):
        s = self.init_sigma
        return ekf.transition.initial_covariance(s, s, s)


# ----------------------------------------------------------------------------- UWB/INS

#: Rest at the start of a flight (levelling) and in-motion heading alignment before the fusion
#: filters start, seconds (:func:`uwbwb.filters.alignment.align_iasl`).
INS_REST_S, INS_ALIGN_S = 2.0, 20.0
#: ``(q_scale, r_scale)`` pairs the UWB/INS filters search on the calibration part (here and in notebook 05):
#: multipliers on the IMU process-noise (Q × 0.01–100) and the UWB measurement-noise variances (R × 0.1–30), 30
#: pairs of two knobs (the EKFs search the same pairs where ``default_estimators(equal_knobs=True)``, else 9 values
#: of σ_w). On the i-ASL drone the former grid (Q × 1–1000,
#: R × 1–10) put both filters' picks on its lower Q edge, and a 4 × 4 one (Q × 0.01–10, R × 0.3–10) put them on an
#: R edge; on this one loose picks (10, 10) and tight (0.1, 0.3), both inside.
INS_GRID = tuple((q, r) for q in (0.01, 0.1, 1.0, 10.0, 100.0) for r in (0.1, 0.3, 1.0, 3.0, 10.0, 30.0))
#: The FAST (and class-mode) grid: two values of each knob, the untuned (1, 1) among them (a smoke test).
INS_GRID_FAST = tuple((q, r) for q in (0.1, 1.0) for r in (1.0, 3.0))


@dataclass(frozen=True, eq=False)
class UwbInsFilter(BaseEstimator):
    """The UWB/INS error-state filters of notebook 05 (``"loose"``: the paper's 6-state filter on
    TDoA LS fixes; ``"tight"``: the 15-state filter with one update per TDoA; ``"tight (ranges)"``: the same
    with one update per range; ``"INS-only"``: the mechanization alone, no knob and no bound), where an IMU exists.

    ``tune`` is notebook 05's IMU calibration on the calibration recording (each filter keeps its own copy)
    (:func:`~uwbwb.filters.imu_calibration.calibrate_iasl`: sensor axes, accelerometer scale,
    noise densities), then the ``(q_scale, r_scale)`` pair of :data:`INS_GRID` (``grid``; 30 pairs of two knobs,
    which the EKFs search too with ``default_estimators(equal_knobs=True)``) that minimises the filter's horizontal
    RMSE on the calibration part (mean over every usable tag, as the EKFs; the IMU calibration itself
    uses the first tag's truth: one IMU); the ranges are the board's calibrated ones with the board's range
    noise, so the fusion filters get the same UWB information as every other method. ``estimate`` runs
    notebook 05's start-up (rest levelling, in-motion heading alignment over the first
    :data:`INS_ALIGN_S` s: :func:`~uwbwb.filters.alignment.align_iasl`, untuned: the pair scales the fusion
    filters only, so every grid point and both filters start from one state), then this adapter's filter
    only (:func:`~uwbwb.filters.alignment.run_fusion_filter`); no estimate before the alignment ends. The start-up is run once per recording and tag (each
    adapter its own: its time is part of the adapter's). The filters never see the scored
    truth: the start-up is handed a hidden (all-NaN) truth, and the board scores the estimates itself.

    Bound: the posterior CRLB of position and velocity driven by the accelerometer's white noise
    (a random-force model with PSD = noise density²) with the TDoA information of every epoch —
    attitude, biases and lever arm taken as known, so it is a lower bound for the full
    error-state filter, not its exact bound.
    """

    kind: str = "tight"
    _cache: dict = field(default_factory=dict, repr=False)
    grid: tuple[tuple[float, float], ...] = INS_GRID
    #: eq. 4's margin, the χ² gate, the loose filter's velocity window (notebook 05's parameters; defaults as there)
    settings: alignment.FusionSettings = alignment.FusionSettings()

    def __post_init__(self):
        if self.kind not in alignment.TUNABLE + ("INS-only",):
            raise ValueError(f"UwbInsFilter kind must be loose, tight, tight (ranges) or INS-only, got {self.kind!r}")

    @property
    def name(self) -> str:
        return self.kind

    def applies(self, rec, tag, cal):
        if rec.imu is None:
            return "needs an IMU (this recording has none)"
        if cal.dim != 3:
            return "the UWB/INS filters run in 3-D"
        span = rec.ranges[tag].t_s[-1] - rec.ranges[tag].t_s[0] if len(rec.ranges[tag]) else 0.0
        if span < INS_REST_S + INS_ALIGN_S + 5.0:
            return f"needs {INS_REST_S + INS_ALIGN_S + 5.0:.0f} s of data (rest, heading alignment, then scoring)"
        return None

    def tune(self, rec, tags, cal):
        # the IMU is one device: its calibration is fitted once, with the first tag's ranges and truth
        one = replace(rec, ranges={"tag": rec.ranges[tags[0]]}, truth={"tag": rec.truth[tags[0]]})
        store = self._cache.setdefault("imu", {})          # one IMU calibration for both adapters
        ikey = (rec.label, tags[0], float(rec.ranges[tags[0]].t_s[0]), len(rec.ranges[tags[0]]))
        if ikey not in store:
            store[ikey] = imu_calibration.calibrate_iasl(one, still_s=INS_REST_S)
        imu_cal = store[ikey]
        cal_ins = cal.with_tuned(self.name, {"calibration": imu_cal})
        self._cache["n_tags"] = max(len(tags), self._cache.get("n_tags", 1))
        if self.kind not in alignment.TUNABLE:              # INS-only: no knob to tune
            return {"calibration": imu_cal}
        # the (q, r) pick minimises the mean RMSE over every usable tag, as the EKFs' σ_w search
        cost = [np.mean([_tuning_scores(self._run(rec, t, cal_ins, (q, r)), rec, t)["rmse"] for t in tags])
                for q, r in self.grid]
        best = int(np.argmin(cost))
        q, r = self.grid[best]
        knobs = edge_knobs(self.grid, best)
        return {"calibration": imu_cal, "q_scale": float(q), "r_scale": float(r), "grid": tuple(self.grid),
                "grid_rmse_m": tuple(float(c) for c in cost), "grid_edge": bool(knobs), "edge_knobs": knobs}

    def _imu_calibration(self, cal):
        try:
            return cal.params(self.name)["calibration"]
        except KeyError:
            raise ValueError(f"{self.name}: no IMU calibration in {cal.source} (its recording has no IMU)") from None

    def _start(self, rec, tag, cal):
        """The start-up every grid point shares (rest levelling, heading alignment), run once per recording,
        tag and calibration (the last few are kept). Each adapter runs its own, so that its time column holds
        the whole of what it costs."""
        imu_cal = self._imu_calibration(cal)
        key = (self.kind, rec.label, tag, float(rec.ranges[tag].t_s[0]), len(rec.ranges[tag]), id(imu_cal),
               cal.sigma(tag).tobytes(), hash(rec.imu.t_s.tobytes()))     # the IMU clock may differ, not the ranges
        starts = self._cache.setdefault("starts", {})
        if key not in starts:
            real = replace(imu_cal, range_sigma_m=cal.sigma(tag), range_bias_m=0.0)
            log = rec.ranges_of(tag, cal.range_calibration)
            # the truth is hidden from the filters: the board scores the estimates itself
            hidden = Trajectory(log.t_s[[0, -1]], np.full((2, 3), np.nan), name="truth (hidden)")
            one = replace(rec, ranges={"tag": log}, truth={"tag": hidden})
            while len(starts) >= 4 * self._cache.get("n_tags", 1) + 4:   # bounded: calibration and test, both kinds
                starts.pop(next(iter(starts)))
            starts[key] = (one, real, alignment.align_iasl(one, real, self.settings, still_s=INS_REST_S,
                                                           align_s=INS_ALIGN_S))
        return starts[key]

    def _run(self, rec, tag, cal, scales=None):
        """This filter from the shared start-up with its ``(q, r)`` multipliers (the tuned pair by default):
        the pair scales the fusion filter only, so every grid point starts from one state."""
        if scales is None:
            p = cal.params(self.name)
            scales = (float(p.get("q_scale", 1.0)), float(p.get("r_scale", 1.0)))
        one, real, start = self._start(rec, tag, cal)
        _, est = alignment.run_fusion_filter(self.kind, start, one, real, self.settings,
                                             scales=(float(scales[0]), float(scales[1])))
        return self._placed(est, rec, tag)

    def estimate(self, rec, tag, cal):
        return self._run(rec, tag, cal)

    def _placed(self, part, rec, tag):
        """The filter's estimates placed on ``tag``'s epochs (no estimate before the alignment ends)."""
        log = rec.ranges[tag]
        idx = np.searchsorted(log.t_s, part.t_s)
        T, d = len(log), part.dim
        pos, status = np.full((T, d), np.nan), np.full(T, _NONE, np.int8)
        cov = np.full((T, d, d), np.nan)
        pos[idx], status[idx] = part.pos_m, part.status
        if part.pos_cov_m2 is not None:
            cov[idx] = part.pos_cov_m2
        info = {k: np.zeros(T, np.asarray(v).dtype) if np.issubdtype(np.asarray(v).dtype, np.integer)
                else np.full(T, np.nan) for k, v in part.info.items()}
        for k, v in part.info.items():
            info[k][idx] = v
        return Estimates(log.t_s, pos, status, self.name, cov, None, info)

    def bound(self, rec, tag, cal, est):
        if self.kind == "INS-only":                         # no UWB, no model of its own drift: no bound
            return None
        log = rec.ranges_of(tag, cal.range_calibration)
        info, have = _range_information(rec, tag, cal, log, tdoa=True)
        C = np.full((len(log), cal.dim, cal.dim), np.nan)
        kind = "PCRLB INS (white acc. noise; attitude, biases known)"
        start = np.flatnonzero(est.has_estimate)
        if start.size == 0:
            return bounds.Bound(log.t_s, C, kind)
        k0 = int(start[0])
        imu = self._imu_calibration(cal).imu_model
        motion = RandomForce(psd_m2ps3=float(imu.acc_noise_density) ** 2, dim=cal.dim)
        P0 = motion.initial_covariance(0.2, 0.3)          # the alignment's initial position/velocity SDs
        C[k0:] = bounds.tracking_bound(motion, log.t_s[k0:], info[k0:], P0)
        C[~have] = np.nan
        return bounds.Bound(log.t_s, C, kind)


# ----------------------------------------------------------------------------- outside methods

@dataclass(frozen=True, eq=False)
class ExternalEstimates(BaseEstimator):
    """Estimates made outside the workbench (another group's method, a vendor's RTLS output, the Hanyang authors'
    LS/ESKF), scored on the board as they are: no tuning (it happened elsewhere, on data the board cannot check), no
    own bound (shown as "—"), placed against the recording's common bound like every method. Its numbers are
    *inputs* (made elsewhere), not reproduced: the board's summary rows and CSV say so.

    Parameters
    ----------
    name
        Label on the board; ``" (external)"`` is appended unless it already says ``(external``.
    tracks
        Per tag, the outside method's positions (:class:`~uwbwb.types.Trajectory`, 2-D or 3-D, on the
        recording's clock).
    max_gap_s
        An epoch of the tag takes the outside position interpolated linearly between its two neighbouring outputs,
        or the output at that very time; none beyond the first/last output or across a gap over ``max_gap_s``
        (0: outputs at the tag's own epochs only). Epochs with none have no estimate (coverage).
    """

    name: str = "external"
    tracks: Mapping = field(default_factory=dict)
    max_gap_s: float = 0.5

    def __post_init__(self):
        if "(external" not in str(self.name):
            object.__setattr__(self, "name", f"{self.name} (external)")

    external = True

    def applies(self, rec, tag, cal):
        return None if tag in self.tracks else f"no outside estimates for tag {tag!r}"

    def estimate(self, rec, tag, cal):
        src, t = self.tracks[tag], rec.ranges[tag].t_s
        if len(src) and src.pos_m.shape[1] < cal.dim:
            raise ValueError(f"{self.name}: 2-D outside estimates cannot be scored on a 3-D board")
        pos = src.interp(t)[:, :cal.dim] if len(src) else np.full((len(t), cal.dim), np.nan)
        i = np.clip(np.searchsorted(src.t_s, t, side="right"), 1, max(len(src) - 1, 1))
        ok = (t >= src.t_s[0]) & (t <= src.t_s[-1]) if len(src) else np.zeros(len(t), bool)
        if len(src) > 1:
            ok &= (src.t_s[i] - src.t_s[i - 1] <= self.max_gap_s) | np.isin(t, src.t_s)
        pos[~ok] = np.nan
        return Estimates(t, pos, np.where(ok, _UP, _NONE).astype(np.int8), self.name)

    def bound(self, rec, tag, cal, est):
        return None


def default_estimators(*, fast: bool = False, seed: int = 0, ins_kinds: tuple[str, ...] = ("loose", "tight"),
                       ins_settings: alignment.FusionSettings = alignment.FusionSettings(),
                       equal_knobs: bool = False) -> list[Estimator]:
    """Every method of the package, in the board's order: the snapshot fixes (raw LS, LS, TDoA LS), the EKFs
    RW/RF/RJ on TDoAs and on ranges, the set-noise filters, NLS and the UWB/INS filters. Each says where it does
    not run (the TDoA methods where the TDoAs are uninformative: :func:`~.interface.tdoa_geometry_note`; the
    UWB/INS filters without an IMU).

    ``ins_kinds`` are the UWB/INS filters on the board (:class:`UwbInsFilter` kinds; notebook 05 adds
    ``"tight (ranges)"`` and ``"INS-only"``), all with ``ins_settings``; they share one IMU calibration.
    ``equal_knobs``: the EKFs tune the UWB/INS filters' ``(Q ×, R ×)`` pairs (:class:`_MotionEkf` ``knobs``) instead
    of σ_w alone, so that on a recording with an IMU every filter is tuned on the same two knobs and grid.

    ``fast`` shrinks what costs time (particles, tuning grids) for CI-sized runs: every other value
    of each tuning grid (the EKFs' σ_w, on TDoAs and on ranges: 5 of 9; the UWB/INS (q, r) pairs: :data:`INS_GRID_FAST`, 4 of 30); the NLS windows: 2 of 3 (1 and
    2 s: a 0.5 s window holds too few epochs at the low rates FAST runs use); the set-noise KF's σ_d grid
    is searched in full.
    """
    ins_grid = INS_GRID_FAST if fast else INS_GRID
    ekfs = []
    for kind in (TdoaEkfEstimator, RangeEkfEstimator):
        ekfs += [kind(m, grid=tuple(float(g) for g in EKF_GRIDS[m][::2]) if fast else None,
                      knobs=ins_grid if equal_knobs else None) for m in ("RW", "RF", "RJ")]
    ins_cache: dict = {}
    return [RawLs(), CalibratedLs(), TdoaLs(), *ekfs,
            SetNoiseFilter("KF", seed=seed), SetNoiseFilter("PF", n_particles=200 if fast else 1000, seed=seed),
            WindowNls(windows_s=NLS_WINDOWS_S[1:] if fast else NLS_WINDOWS_S),
            *(UwbInsFilter(kind, ins_cache, ins_grid, ins_settings) for kind in ins_kinds)]


def update_variants(model: str = "RF", *, fast: bool = False) -> list[RangeEkfEstimator]:
    """The range EKF with motion model ``model`` once per measurement update of :data:`UPDATES` (the default χ² gate
    first), each with the board's tuning grid (FAST: every other value, as :func:`default_estimators`): the rows of
    an update ablation, tuned alike."""
    (base,) = [e for e in default_estimators(fast=fast) if e.name == f"EKF-{model} ranges"]
    return [replace(base, update=u) for u in UPDATES]
