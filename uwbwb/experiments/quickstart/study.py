"""What notebook 00 (quickstart) runs: the room's recordings (or a stand-in), raw
multilateration of every tag against ground truth, and the effect of a range calibration
fitted on other recordings of the same room.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from ... import geometry, metrics
from ...metrics import interval_side
from ...calibration import RangeCalibration, range_residuals
from ...datasets.standin import RoomData, load_lias_room
from ...sim import rig
from ...types import Recording

#: The two variants compared: per-epoch multilateration of raw and of calibrated ranges.
VARIANTS = ("raw", "calibrated")


def load(data_dir=None, recording: str = "fast", static_session: str = "8.14", *, seed: int = 0,
         fast: bool = False) -> RoomData:
    """The LIAS dynamic run + static poses, or the synthetic rig when they are absent.

    Under ``fast`` the static recordings are decimated 10× (calibration needs far
    fewer than their ~10,000 samples per pose); the dynamic run is used whole.
    """
    stand_in = rig.RigConfig(duration_s=60.0 if fast else 180.0)
    room = load_lias_room(data_dir, recording, static_session, stand_in=stand_in,
                          static_duration_s=5.0 if fast else 30.0, rng=np.random.default_rng(seed))
    if fast:
        room = replace(room, static=tuple(r.decimate(10) for r in room.static))
    return room


def multilaterate_tags(rec: Recording, *, tag_height_m, calibration: RangeCalibration | None = None
                       ) -> dict[str, geometry.MultilaterationResult]:
    """Per-epoch 2-D multilateration (known tag height) of every tag's ranges.

    ``tag_height_m`` is one height for all tags or a mapping tag → height, metres.
    """
    out = {}
    for tag in rec.tags:
        z = tag_height_m[tag] if isinstance(tag_height_m, dict) else float(tag_height_m)
        log = rec.ranges_of(tag, calibration)
        out[tag] = geometry.multilaterate(log.range_m, rec.anchors.pos_m, dim=2, z_m=z)
    return out


def compare_calibration(rec: Recording, calibration: RangeCalibration, *, tag_height_m
                        ) -> tuple[pd.DataFrame, dict]:
    """Raw multilateration before vs after calibration, per tag, scored on the same epochs.

    A variant can fail to fix an epoch the other fixes; both are therefore scored on
    the epochs where *both* have a fix and truth covers the epoch (``compared``), and
    each variant's ``coverage`` (its fixes ÷ epochs inside the truth's span) stands
    beside its errors.

    Returns
    -------
    table
        One row per tag and variant (``raw``/``calibrated``): ``epochs``, ``with_truth``,
        ``fixes`` (with truth), ``coverage``, ``compared``, CEP50, CEP95 and RMSE (m) on
        the compared epochs, median |range residual| (m).
    errors
        ``{variant: {tag: ErrorSeries}}`` of every fix with truth, for plotting.
    """
    errors, resid = {}, {}
    for variant, cal in zip(VARIANTS, (None, calibration)):
        fixes = multilaterate_tags(rec, tag_height_m=tag_height_m, calibration=cal)
        errors[variant] = {tag: metrics.errors_vs_truth(res.to_trajectory(rec.ranges[tag].t_s, name=variant),
                                                        rec.truth[tag]) for tag, res in fixes.items()}
        resid[variant] = range_residuals(rec, cal)
    rows = []
    for tag in rec.tags:
        t = rec.ranges[tag].t_s
        span = rec.truth[tag].t_s
        with_truth = int(np.count_nonzero((t >= span[0]) & (t <= span[-1])))
        _, on_grid = metrics.errors_on_grid({v: errors[v][tag] for v in VARIANTS})
        scores = metrics.score_epochs(on_grid)            # both variants on the epochs where both have a fix
        for v in VARIANTS:
            s, r = scores[v], resid[v]
            cmp = s.common_m
            rows.append({"tag": tag, "variant": v, "epochs": t.size, "with_truth": with_truth,
                         "fixes": s.n_scored, "coverage": s.n_scored / with_truth if with_truth else np.nan,
                         "compared": cmp.size, "cep50_m": metrics.cep50(cmp), "cep95_m": metrics.cep95(cmp),
                         "rmse_m": metrics.rmse(cmp),
                         "median_abs_range_resid_m": float(r.loc[r.tag_id == tag, "median_m"].abs().median())})
    return pd.DataFrame(rows), errors


def headline_rows(table: pd.DataFrame) -> list[dict]:
    """Summary rows of notebook 00 (keyword arguments of ``Summary.add`` without ``data``); all reproduced."""
    rows = []
    for row in table.itertuples():
        for q in ("cep50", "cep95"):
            rows.append(dict(quantity=f"{q.upper()}, tag {row.tag}, {row.variant} multilateration",
                             value=getattr(row, f"{q}_m"), unit="m", kind="reproduced"))
        rows.append(dict(quantity=f"coverage, tag {row.tag}, {row.variant} multilateration",
                         value=100 * row.coverage, unit="%", kind="reproduced"))
    raw = table[table.variant == "raw"].set_index("tag")
    cal = table[table.variant == "calibrated"].set_index("tag")
    rows.append(dict(quantity="CEP95 change from calibration, mean over tags", unit="m", kind="reproduced",
                     value=float((cal.cep95_m - raw.cep95_m).mean())))
    return rows


def verdicts(errors: dict, *, rng: np.random.Generator) -> pd.DataFrame:
    """Does the range calibration make the fixes more accurate? One row per tag: ``claim, ours, low, high, rule,
    verdict``.

    ``ours`` is the RMSE of the raw fixes minus that of the calibrated ones (m; > 0: calibration helps) on the
    epochs where both have a fix, with the 95 % block-bootstrap interval of
    :func:`uwbwb.metrics.block_bootstrap_difference` (pairs of epochs stay together, so the correlation of
    consecutive errors is kept). The verdict is *better* (calibrated) or *worse* when the interval excludes 0,
    *not significant* otherwise; no interval and *no verdict* with fewer than :data:`uwbwb.metrics.MIN_BLOCKS`
    independent blocks. ``errors`` is the second
    result of :func:`compare_calibration`.
    """
    rows = []
    for tag in errors["raw"]:
        scores = metrics.score_epochs(metrics.errors_on_grid({v: errors[v][tag] for v in VARIANTS})[1])   # both fixed
        d = metrics.block_bootstrap_difference(scores["raw"].common_m, scores["calibrated"].common_m, rng=rng)
        lo, hi = d["lo_m"], d["hi_m"]
        verdict = {"above": "better", "below": "worse", "contains": "not significant"}.get(
            interval_side(lo, hi), "no verdict")
        rows.append({"claim": f"tag {tag}: calibrated vs raw ranges, RMSE reduction on the epochs both fixed (m)",
                     "ours": d["diff_m"], "low": lo, "high": hi, "epochs": d["n"], "blocks": d["n_blocks"],
                     "rule": "95 % block bootstrap excludes 0", "verdict": verdict})
    return pd.DataFrame(rows)
