"""What notebook 00's calibration comparison shows, written from the run's numbers."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...calibration import RangeCalibration


def discussion_markdown(table: pd.DataFrame, calibration: RangeCalibration, *, synthetic: bool) -> str:
    """The "what to look for" paragraph of notebook 00.

    Parameters
    ----------
    table
        :func:`.study.compare_calibration` table.
    calibration
        The fitted range calibration (its per-pair biases are quoted).
    synthetic
        The run used the synthetic stand-in (said in the text).
    """
    b = np.asarray(calibration.bias_m, float)
    b = b[np.isfinite(b)]
    raw = table[table.variant == "raw"].set_index("tag")
    cal = table[table.variant == "calibrated"].set_index("tag")
    where = "the simulated rig" if synthetic else "this room"
    r95, c95 = raw.cep95_m.mean(), cal.cep95_m.mean()
    rr, cr = raw.median_abs_range_resid_m.median(), cal.median_abs_range_resid_m.median()
    text = (f"The per-pair range biases fitted on the static poses of {where} span {100 * b.min():.1f} to "
            f"{100 * b.max():.1f} cm (median |bias| {100 * np.median(np.abs(b)):.1f} cm); on the dynamic run the "
            f"median |range residual| per pair is {100 * rr:.1f} cm on raw ranges and {100 * cr:.1f} cm after "
            "calibration. ")
    if c95 < r95:
        text += (f"Calibration lowers CEP95 from {r95:.3f} m to {c95:.3f} m on average over the tags "
                 f"({100 * (r95 - c95) / r95:.0f} % lower), although it was fitted on other recordings than the "
                 "one it is scored on. ")
    else:
        text += (f"Calibration does not lower CEP95 here ({r95:.3f} m raw, {c95:.3f} m calibrated, mean over tags): "
                 "what it learnt on the static poses does not carry over to this run. ")
    cov = table.groupby("variant")["coverage"].min()
    same = (raw.compared == cal.compared).all() and bool(np.isclose(cov.min(), cov.max()))
    text += (f"Both variants fix at least {100 * cov.min():.1f} % of the epochs with truth"
             + (" and are scored on the same epochs." if same else
                f" (raw {100 * cov['raw']:.1f} %, calibrated {100 * cov['calibrated']:.1f} %); the CEPs above use "
                "only the epochs both fixed."))
    return text
