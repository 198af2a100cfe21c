"""Back end of notebook 05's panel: short synthetic runs, cached, and the readout beside them.

The panel's dynamic run drives the fewest legs of the broken line that hold the longest outage
the slider offers (the notebook's ``OUTAGE_S``) and one second after it, so every offered length
is simulated, never clipped.
"""

from __future__ import annotations

import functools

import numpy as np

from ... import validate
from ...filters import alignment
from ...models.imu import GRADES
from ...sim import robot
from ...widgets import Panel, PanelFigure, dropdown, float_slider
from . import figures, study
from .ablation import legs_for_outage

__all__ = ["panel_run", "panel_comparison", "readout", "build_panel"]

#: Length of the panel's static run, s.
PANEL_STATIC_S = 8.0


@functools.lru_cache(maxsize=16)
def panel_run(scenario: str, grade: str, outlier_rate: float, outage_s: float, *, seed: int, legs: int):
    """One short simulated run (cached per scenario, grade, multipath rate, outage, seed and legs)."""
    return study.simulate(scenario, robot.RobotConfig(imu=GRADES[grade], outlier_rate=outlier_rate),
                          rng=np.random.default_rng(seed), outage_s=outage_s if scenario == "dynamic" else 0.0,
                          static_s=PANEL_STATIC_S, legs=legs)


@functools.lru_cache(maxsize=64)
def panel_comparison(scenario: str, grade: str, q_scale: float, r_scale: float, c_m: float, outlier_rate: float,
                     outage_s: float, feedback: bool, method: str, *, seed: int, legs: int, gate_prob: float | None,
                     loose_window: int) -> alignment.Comparison:
    """UWB-only and ``method`` on :func:`panel_run` (``c_m`` < 0: no eq-4 test)."""
    run = panel_run(scenario, grade, outlier_rate, outage_s, seed=seed, legs=legs)
    settings = alignment.FusionSettings(outlier_c_m=c_m if c_m >= 0 else None, gate_prob=gate_prob, q_scale=q_scale,
                                    r_scale=r_scale, feedback=feedback, loose_window=loose_window)
    return study.compare_synthetic(run, settings, label=scenario, methods=("UWB-only", method))


def readout(comp: alignment.Comparison, method: str) -> dict:
    """The panel's numbers: RMSE and max of ``method`` and UWB-only, rejections, max in the outage."""
    t = comp.table()
    read = {f"RMSE {method} (m)": t.loc[method, "RMSE (m)"], "RMSE UWB-only (m)": t.loc["UWB-only", "RMSE (m)"],
            f"max {method} (m)": t.loc[method, "max (m)"], "eq-4 rejections": comp.rejected["eq4"],
            "gated (tight)": comp.rejected["gated"] if method == "tight" else 0}
    if comp.masks["outage"].any():
        read[f"max {method} in outage (m)"] = comp.table("outage").loc[method, "max (m)"]
    return read


def build_panel(*, seed: int, grade: str, outlier_rate: float, outage_s: float, outlier_c_m: float | None,
                gate_prob: float | None, loose_window: int, stations_m) -> Panel:
    """The panel: IMU grade, Q/R scales, eq-4 margin, multipath rate, outage length 0 … ``outage_s``,
    feedback, filter, scenario; the track (with the stations) and the error against time."""
    outage_s = validate.number("outage_s", outage_s, minimum=0.0)
    legs = legs_for_outage(outage_s)
    view = PanelFigure(1, 2, figsize=(12, 4))
    fixed = dict(seed=seed, legs=legs, gate_prob=gate_prob, loose_window=loose_window)

    def render(scenario, grade, q_scale, r_scale, c_m, outlier_rate, outage_s, feedback, method):
        comp = panel_comparison(scenario, grade, q_scale, r_scale, c_m, outlier_rate, outage_s, feedback, method,
                                **fixed)
        axes = view.clear()
        figures.track(comp, ("UWB-only", method), ax=axes[0], anchors_m=stations_m)
        figures.error_vs_time(comp, ("UWB-only", method), ax=axes[1])
        return view.done(), readout(comp, method)

    c0 = outlier_c_m if outlier_c_m in (0.0, 0.1, 0.5, 1.0) else 0.1
    panel = Panel("UWB/INS fusion: loose (paper) vs tight", {
        "scenario": dropdown("scenario", {f"dynamic ({legs} legs)": "dynamic", "static": "static"}, "dynamic"),
        "grade": dropdown("IMU grade", list(GRADES), grade),
        "q_scale": float_slider("Q scale", 1.0, 0.01, 100.0, 0.1, log=True),
        "r_scale": float_slider("R scale", 1.0, 0.1, 10.0, 0.1, log=True),
        "c_m": dropdown("eq. 4 margin C", {"off": -1.0, "0 m": 0.0, "0.1 m": 0.1, "0.5 m": 0.5, "1 m": 1.0}, c0),
        "outlier_rate": float_slider("multipath rate", outlier_rate, 0.0, 0.2, 0.01),
        "outage_s": float_slider("outage length", outage_s, 0.0, outage_s, 0.5, unit="s"),
        "feedback": dropdown("feedback", {"closed loop": True, "open loop": False}, True),
        "method": dropdown("filter", {"tight (15 states, per TDoA)": "tight", "loose (paper, eqs 5-7)": "loose"},
                           "tight"),
    }, render)
    panel.fixed = fixed
    return panel

