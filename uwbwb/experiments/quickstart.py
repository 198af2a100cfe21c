"""What notebook 00 (quickstart) calls: data with a synthetic fallback, raw
multilateration of every tag against ground truth, and the effect of range calibration.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import geometry, metrics
from ..calibration import RangeCalibration, fit_range_calibration, range_residuals
from ..datasets.discovery import dataset_available
from ..sim import rig
from ..types import Recording

LIAS = "lias-planar-uwb"


@dataclass(frozen=True)
class QuickstartData:
    """The recordings notebook 00 works on.

    Attributes
    ----------
    dynamic
        A moving recording with per-tag ground truth.
    static
        Static recordings of the same room (calibration material).
    synthetic
        True when the real data was absent and the synthetic rig stands in.
    tag_height_m
        Known tag height used by 2-D multilateration, metres.
    note
        One sentence saying what data this is.
    """

    dynamic: Recording
    static: tuple[Recording, ...]
    synthetic: bool
    tag_height_m: float
    note: str

    @property
    def data_label(self) -> str:
        """The ``data`` field of summary rows: ``synthetic`` or ``dataset/recording``."""
        return "synthetic" if self.synthetic else self.dynamic.label


def decimate(rec: Recording, step: int) -> Recording:
    """Every ``step``-th epoch of each tag's ranges (truth kept whole); for FAST runs."""
    if step <= 1:
        return rec
    return dataclasses.replace(rec, ranges={t: log.select(slice(None, None, step))
                                            for t, log in rec.ranges.items()})


def load(data_dir=None, recording: str = "fast", static_session: str = "8.14", *, seed: int = 0,
         fast: bool = False) -> QuickstartData:
    """The LIAS dynamic run + static poses, or the synthetic rig when they are absent.

    Under ``fast`` the static recordings are decimated 10× (calibration needs far
    fewer than their ~10,000 samples per pose); the dynamic run is used whole.
    """
    step = 10 if fast else 1
    if dataset_available(LIAS, data_dir):
        from ..datasets import lias

        dynamic = lias.load_dynamic(recording, data_dir)
        static = tuple(decimate(r, step) for r in lias.load_static(static_session, data_dir))
        return QuickstartData(dynamic, static, False, lias.TROLLEY_CENTROID_Z_M,
                              f"real data: {dynamic.label}, calibration from {len(static)} static poses "
                              f"of session {static_session}")
    rng = np.random.default_rng(seed)
    cfg = rig.RigConfig(duration_s=60.0 if fast else 180.0)
    dynamic, truth = rig.simulate_dynamic(cfg, rng=rng)
    static, _ = rig.simulate_static(cfg, duration_s=5.0 if fast else 30.0, rng=rng,
                                    range_model=truth.range_model)
    return QuickstartData(dynamic, tuple(static), True, cfg.centroid_z_m,
                          f"SYNTHETIC stand-in: {LIAS} was not found, so a simulated rig "
                          f"(8 anchors, 3 tags, per-pair range biases) is shown instead")


def multilaterate_tags(rec: Recording, *, tag_height_m: float,
                       calibration: RangeCalibration | None = None) -> dict[str, geometry.MultilaterationResult]:
    """Per-epoch 2-D multilateration (known tag height) of every tag's ranges."""
    out = {}
    for tag in rec.tags:
        log = rec.ranges[tag] if calibration is None else calibration.apply(rec.ranges[tag])
        out[tag] = geometry.multilaterate(log.range_m, rec.anchors.pos_m, dim=2, z_m=tag_height_m)
    return out


def tag_errors(rec: Recording, fixes: dict[str, geometry.MultilaterationResult], name: str
               ) -> dict[str, metrics.ErrorSeries]:
    """Horizontal errors of each tag's fixes against its ground truth."""
    out = {}
    for tag, res in fixes.items():
        est = res.to_trajectory(rec.ranges[tag].t_s, name=name)
        out[tag] = metrics.errors_vs_truth(est, rec.truth[tag], horizontal=True)
    return out


def compare_calibration(rec: Recording, calibration: RangeCalibration, *, tag_height_m: float
                        ) -> tuple[pd.DataFrame, dict]:
    """Raw multilateration before vs after calibration, per tag.

    Returns
    -------
    table
        One row per tag and variant (``raw``/``calibrated``): epochs, fixes,
        CEP50, CEP95 and RMSE (m), median |range residual| (m).
    errors
        ``{variant: {tag: ErrorSeries}}`` for plotting.
    """
    rows, errors = [], {}
    for variant, cal in (("raw", None), ("calibrated", calibration)):
        fixes = multilaterate_tags(rec, tag_height_m=tag_height_m, calibration=cal)
        errs = tag_errors(rec, fixes, variant)
        resid = range_residuals(rec, cal)
        errors[variant] = errs
        for tag, e in errs.items():
            ok = e.err_m[np.isfinite(e.err_m)]
            rows.append({"tag": tag, "variant": variant, "epochs": len(rec.ranges[tag]),
                         "fixes": int(fixes[tag].ok.sum()), "compared": ok.size,
                         "cep50_m": metrics.cep50(ok), "cep95_m": metrics.cep95(ok),
                         "rmse_m": metrics.rmse(ok),
                         "median_abs_range_resid_m": float(resid.loc[resid.tag_id == tag, "median_m"].abs().median())})
    return pd.DataFrame(rows), errors


def calibrate(data: QuickstartData) -> RangeCalibration:
    """Fit the per-pair range calibration on the static recordings only."""
    return fit_range_calibration(list(data.static))

