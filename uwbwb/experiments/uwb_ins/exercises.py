"""Exercises of notebook 05 ("change X, predict Y") on the panel's short synthetic runs.

Each runs both settings on the same simulated run and returns a
:class:`uwbwb.widgets.ExerciseCheck` (the direction to predict, whether this run shows it, the
numbers). The reasoning is the check's ``why``, shown
once the student has predicted; ``TEACHING.md`` gives one run's numbers.
"""

from __future__ import annotations

import numpy as np

from ... import validate
from ...filters import alignment
from ...models.imu import GRADES
from ...sim import robot
from ...widgets import ExerciseCheck
from . import study
from .ablation import legs_for_outage

__all__ = ["outage_loose_vs_tight", "gate_off"]


def outage_loose_vs_tight(*, seed: int, outage_s: float = 5.0, grade: str = "consumer",
                          outlier_rate: float = 0.02, factor: float = 2.0) -> ExerciseCheck:
    """Exercise: an outage of ``outage_s`` (only BS1 and BS2 heard: one TDoA per epoch, no fix);
    predict which filter's maximum error in the outage is larger, loose or tight.

    The loose filter needs a position fix, so through the outage it runs on the INS alone from the
    velocity it had when the fixes stopped — a velocity from differenced fixes, wrong by decimetres
    per second — and the IMU's drift adds to that; the tight filter still updates with the single
    TDoA of each epoch. Claim: the loose filter's maximum error in the outage exceeds ``factor`` ×
    the tight one's (notebook 05 asks it with a ``"tactical"`` IMU, whose drift over seconds is
    millimetres, so the entry velocity is what is left).
    """
    outage_s = validate.number("outage_s", outage_s, minimum=0.0, strict_minimum=True)
    factor = validate.number("factor", factor, minimum=1.0)
    run = study.simulate("dynamic", robot.RobotConfig(imu=GRADES[grade], outlier_rate=outlier_rate),
                         rng=np.random.default_rng(seed), outage_s=outage_s, legs=legs_for_outage(outage_s))
    comp = study.compare_synthetic(run, alignment.FusionSettings(), label="outage", methods=("UWB-only", "loose", "tight"))
    t = comp.table("outage")
    loose, tight = float(t.loc["loose", "max (m)"]), float(t.loc["tight", "max (m)"])
    return ExerciseCheck(f"{outage_s:g} s outage: loose max error more than {factor:g}× tight's",
                         loose > factor * tight, {"loose max in outage (m)": loose, "tight max in outage (m)": tight},
                         (f"loose, by more than {factor:g}×", f"not loose by more than {factor:g}×"),
                         "Two stations give no position fix, so the loose filter coasts on the INS from the velocity "
                         "it had when the fixes stopped (differenced fixes: wrong by decimetres per second), plus the "
                         "IMU's drift; a better IMU removes only the drift. The tight filter still uses the one TDoA "
                         "per epoch, which holds one direction of the error.")


def gate_off(*, seed: int, outlier_rate: float = 0.1, duration_s: float = 8.0, gate_prob: float = 0.999,
             grade: str = "consumer") -> ExerciseCheck:
    """Exercise: switch the tight filter's χ² gate off at multipath rate ``outlier_rate``; predict its RMSE.

    Eq. 4 is left on, but in this room it fires only on excesses of metres; the multipath excess
    is drawn at 0.3–4 m, so the gate is what removes the biased TDoAs. Without it every biased
    TDoA pulls the estimate. Claim: the RMSE without the gate is higher than with it (static run
    of ``duration_s`` seconds, the same simulated run for both).
    """
    outlier_rate = validate.number("outlier_rate", outlier_rate, minimum=0.0, maximum=1.0)
    duration_s = validate.number("duration_s", duration_s, minimum=1.0)
    run = study.simulate("static", robot.RobotConfig(imu=GRADES[grade], outlier_rate=outlier_rate),
                         rng=np.random.default_rng(seed), static_s=duration_s)
    rmse = {}
    for g in (gate_prob, None):
        comp = study.compare_synthetic(run, alignment.FusionSettings(gate_prob=g), label="static",
                                       methods=("UWB-only", "tight"))
        rmse[g] = float(comp.table().loc["tight", "RMSE (m)"])
    return ExerciseCheck(f"multipath rate {outlier_rate:g}: tight RMSE higher without the χ² gate",
                         rmse[None] > rmse[gate_prob] and np.isfinite(rmse[None]),
                         {"tight RMSE with gate (m)": rmse[gate_prob], "tight RMSE without gate (m)": rmse[None]},
                         ("higher", "not higher"),
                         "Eq. 4 only rejects excesses of metres; the multipath excesses here are decimetres, which the "
                         "χ² gate rejects and the ungated filter averages into its position.")
