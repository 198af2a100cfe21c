"""The estimator interface of the board, and the pieces every adapter shares.

A method joins the board by implementing :class:`Estimator` (see :mod:`.estimators` for what each
member means); :class:`BaseEstimator` gives the defaults. The helpers place truth on a tag's
epochs (:meth:`~uwbwb.types.Recording.truth_at`, one gap rule: :data:`MAX_TRUTH_GAP_S`), apply the shared range
calibration (:meth:`~uwbwb.types.Recording.ranges_of`) and evaluate the range and TDoA information the adapters'
bounds are built from.

Whether a measurement domain is informative on a recording is judged once, on the calibration part
(:func:`measurement_geometry`, stored in the calibration under :data:`GEOMETRY`): a TDoA method does not
run where the TDoAs' position CRLB there exceeds the ranges' by more than :data:`MAX_TDOA_OVER_RANGES`
(:func:`tdoa_geometry_note` says why, with the numbers, in the board's note column).
"""

from __future__ import annotations

from typing import Mapping, Protocol, Sequence, runtime_checkable

import numpy as np

from dataclasses import replace

from .. import bounds, metrics
from ..calibration import range_sigma_from_truth
from ..models.ranging import predict_ranges
from ..models.tdoa import TdoaModel
from ..types import EstimateStatus, Estimates, MAX_TRUTH_GAP_S, RangeLog, Recording
from .protocol import Calibration

__all__ = ["Estimator", "BaseEstimator", "GEOMETRY", "MAX_TDOA_OVER_RANGES", "MIN_NOISE_SAMPLES", "TUNING_CRITERIA",
           "measured_noise_calibration", "measurement_geometry", "tdoa_geometry_note",
           "on_grid_edge"]

#: Fewest range residuals of an anchor on the scored part for its noise to be measured there
#: (:func:`measured_noise_calibration`; an anchor with fewer keeps its calibrated σ).
MIN_NOISE_SAMPLES = 10

#: A TDoA method (TDoA LS, the TDoA EKFs) is not run where the median position CRLB of the TDoAs on the
#: calibration part exceeds that of the ranges by more than this factor (:func:`tdoa_geometry_note`). With
#: reference-correlated pseudo-TDoAs the factor is at least 1 (a TDoA loses only the common offset). Measured on
#: the calibration parts the boards use: 1.04–1.05 on the LIAS planar run ``fast`` (8 anchors around the floor;
#: its first half), 1.07 and 1.15 on the i-ASL drone scenarios 1 and 2 (8 anchors around the room), 27–714 on the
#: four Hanyang cases (4 anchors in a 2 m cluster, the robot up to 50 m away; 35–201 on notebook 06's boards,
#: 27–543 on their FAST parts, 93–714 on the command line's first halves in 3-D).
MAX_TDOA_OVER_RANGES = 10.0
#: Key of the calibration's entry holding :func:`measurement_geometry` (per tag).
GEOMETRY = "measurement geometry"

_UP, _NONE = int(EstimateStatus.UPDATED), int(EstimateStatus.NO_ESTIMATE)


@runtime_checkable
class Estimator(Protocol):
    """What the board needs from a method (module docstring)."""

    name: str

    def applies(self, rec: Recording, tag: str, cal: Calibration) -> str | None: ...

    def tune(self, rec: Recording, tags: Sequence[str], cal: Calibration) -> Mapping: ...

    def estimate(self, rec: Recording, tag: str, cal: Calibration) -> Estimates: ...

    def bound(self, rec: Recording, tag: str, cal: Calibration, est: Estimates) -> bounds.Bound: ...


class BaseEstimator:
    """Defaults: applies everywhere, tunes nothing."""

    name = "estimator"

    def applies(self, rec: Recording, tag: str, cal: Calibration) -> str | None:
        return None

    def tune(self, rec: Recording, tags: Sequence[str], cal: Calibration) -> Mapping:
        return {}

    def measured_noise_bound(self, rec: Recording, tag: str, cal: Calibration, est: Estimates):
        """The method's own bound with its noise assumption replaced by what the scored part's truth measures
        (:func:`measured_noise_calibration`: every bound of the package built on the calibrated range σ takes the
        scored part's own robust range σ). The board sets it beside the bound: a method below its own bound but
        not below this one beats the bound's noise assumption, not its model. None: not measured."""
        return self.bound(rec, tag, measured_noise_calibration(rec, tag, cal), est)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


# ----------------------------------------------------------------------------- shared pieces

def measured_noise_calibration(rec: Recording, tag: str, cal: Calibration) -> Calibration:
    """``cal`` with ``tag``'s range σ replaced by the robust σ (1.4826 × MAD, as the calibration's) of the
    calibrated ranges of ``rec`` against the true ranges (truth at the calibrated tag height on a 2-D board);
    anchors with fewer than :data:`MIN_NOISE_SAMPLES` residuals keep their calibrated σ. ``cal`` unchanged where
    ``rec`` has no truth for ``tag``."""
    log = rec.ranges_of(tag, cal.range_calibration)
    if tag not in rec.truth:
        return cal
    pos = rec.truth_at(tag, log.t_s, 3 if rec.truth[tag].dim == 3 else 2)
    if pos.shape[1] == 2:
        h = cal.height(tag)
        if h is None:
            return cal
        pos = np.column_stack([pos, np.full(len(pos), h)])
    true_r = predict_ranges(pos, rec.anchors.pos_m)
    resid = log.range_m - true_r
    sigma = cal.sigma(tag).copy()
    ok = np.isfinite(resid).sum(axis=0) >= MIN_NOISE_SAMPLES
    if ok.any():
        sigma[ok] = range_sigma_from_truth(log.range_m[:, ok], true_r[:, ok])
    return replace(cal, range_sigma_m={**cal.range_sigma_m, tag: sigma})


def _range_information(rec, tag, cal, log: RangeLog, tdoa: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Information ``(T, dim, dim)`` of the epoch's ranges at the calibrated noise (``tdoa``: of their
    reference-correlated pseudo-TDoAs, zero at an epoch with fewer than two ranges) at the true positions (zero where
    no truth), and where truth exists ``(T,)``."""
    pos = rec.truth_at(tag, log.t_s, cal.dim)
    have = np.all(np.isfinite(pos), axis=1)
    info = np.zeros((len(log), cal.dim, cal.dim))
    if have.any() and tdoa:
        mask = np.isfinite(log.range_m[have])
        info[have] = np.where((mask.sum(axis=1) >= 2)[:, None, None],
                              bounds.tdoa_information(pos[have], _tdoa_model(rec, tag, cal), mask=mask), 0.0)
    elif have.any():
        info[have] = bounds.range_information(pos[have], rec.anchors.pos_m, cal.sigma(tag), z_m=cal.height(tag),
                                              mask=np.isfinite(log.range_m[have]))
    return info, have


def _range_bound(rec, tag, cal, log: RangeLog, kind="CRLB ranges") -> bounds.Bound:
    info, have = _range_information(rec, tag, cal, log)
    C = np.full((len(log), cal.dim, cal.dim), np.nan)
    if have.any():
        C[have] = bounds.crlb(info[have])
    return bounds.Bound(log.t_s, C, kind)


def _tdoa_model(rec, tag, cal, correlated: bool = True) -> TdoaModel:
    return TdoaModel(rec.anchors.pos_m, cal.sigma(tag), dim=cal.dim, z_m=cal.height(tag) or 0.0, correlated=correlated)


def _median_position_sd(info: np.ndarray) -> float:
    """Median over epochs of ``sqrt(trace(CRLB))`` (m); a singular epoch counts as infinite."""
    if not len(info):
        return float("nan")
    sd = np.sqrt(np.trace(bounds.crlb(info), axis1=1, axis2=2))
    return float(np.median(np.where(np.isfinite(sd), sd, np.inf)))


def measurement_geometry(rec: Recording, tags: Sequence[str], cal: Calibration) -> dict[str, dict]:
    """How much the TDoA domain loses against the range domain on ``rec`` (the calibration part).

    Per tag, at the true positions of its epochs with truth and with the calibrated range noise: the median
    position standard deviation of the CRLB of the ranges (``crlb_ranges_m``) and of the reference-correlated
    pseudo-TDoAs (``crlb_tdoa_m``; an epoch whose TDoA information is singular counts as infinite), their ratio
    ``tdoa_over_ranges`` (≥ 1) and the epochs used (``n_epochs``). Tags without truth epochs are left out.
    """
    out = {}
    for tag in tags:
        log = rec.ranges_of(tag, cal.range_calibration)
        info_t, have = _range_information(rec, tag, cal, log, tdoa=True)
        if not have.any():
            continue
        r, t = _median_position_sd(_range_information(rec, tag, cal, log)[0][have]), _median_position_sd(info_t[have])
        out[tag] = {"crlb_ranges_m": r, "crlb_tdoa_m": t, "tdoa_over_ranges": t / r if r > 0 else float("nan"),
                    "n_epochs": int(have.sum())}
    return out


def tdoa_geometry_note(cal: Calibration, tag: str) -> str | None:
    """Why a TDoA method does not run for ``tag`` (None: it runs): the calibration's :func:`measurement_geometry`
    puts the TDoAs' median position CRLB above the ranges' by more than :data:`MAX_TDOA_OVER_RANGES`. A
    calibration without the measurement (or a tag without truth there) lets it run."""
    g = cal.params(GEOMETRY).get(tag)
    if not g or not g["tdoa_over_ranges"] > MAX_TDOA_OVER_RANGES:
        return None
    return (f"TDoAs uninformative here: on the calibration part their median position CRLB is "
            f"{g['crlb_tdoa_m']:.3g} m, {g['tdoa_over_ranges']:.3g}× the ranges' {g['crlb_ranges_m']:.3g} m "
            f"(limit {MAX_TDOA_OVER_RANGES:g}×)")


#: What a tuning on the calibration part may minimise (mean over tags), both of the horizontal error over the
#: estimator's own epochs: the RMSE (the board's) or the CEP95 (notebook 03's, the thesis' Table 1 procedure).
TUNING_CRITERIA = ("rmse", "cep95")


def _tuning_scores(est: Estimates, rec: Recording, tag: str) -> dict[str, float]:
    """Every :data:`TUNING_CRITERIA` score of ``est`` against ``rec``'s truth (inf where nothing can be scored)."""
    tr = est.to_trajectory()
    if len(tr) == 0:
        return {c: float("inf") for c in TUNING_CRITERIA}
    e = metrics.errors_vs_truth(tr, rec.truth[tag], horizontal=True, max_gap_s=MAX_TRUTH_GAP_S)
    if not len(e):
        return {c: float("inf") for c in TUNING_CRITERIA}
    return {"rmse": metrics.rmse(e.err_m), "cep95": metrics.cep95(e.err_m)}


def on_grid_edge(best: int, n: int) -> bool:
    """Whether a tuning pick (index ``best`` of ``n`` ordered grid values) is on the grid's edge, where a
    wider grid might do better (a one-value grid tunes nothing: always on its edge)."""
    return n < 2 or best in (0, n - 1)
