"""Exercises of notebook 04 ("change X, predict Y").

Each exercise computes both settings with the package's own functions and returns a
:class:`uwbwb.widgets.ExerciseCheck` (the direction to predict, whether this run shows it, the
numbers). The reasoning is the check's ``why``, shown
once the student has predicted; ``TEACHING.md`` gives one run's numbers.
"""

from __future__ import annotations

import numpy as np

from ... import metrics, validate
from ...widgets import ExerciseCheck
from . import panels, study

__all__ = ["slower_receiver", "pseudo_ranges", "ranging_verdict"]


def slower_receiver(cfg: study.StudyConfig, *, layout: str = "cubic", threshold_cm: float = 15.0,
                    speed_scale: float = 0.5, n_positions: int = 10_000) -> ExerciseCheck:
    """Exercise: the receiver moves at ``speed_scale`` × ``|V_ref|``; predict the fraction of the 6-D space under δ.

    Position enters eq 1 only through the unit vectors ``u_i`` that the velocity is projected on:
    a slower receiver makes every ΔP smaller and lets more (X, V) pairs reproduce them, so the
    ghost set grows. Both fractions come from the conditional sampler
    (:func:`.panels.ghost_map`, the space panel's back end) with ``n_positions`` positions; the
    claim holds when the slower receiver's 95 % interval lies wholly above the reference one's.
    """
    threshold_cm = validate.number("threshold_cm", threshold_cm, minimum=0.0, strict_minimum=True)
    speed_scale = validate.number("speed_scale", speed_scale, minimum=0.0, strict_minimum=True)
    n_positions = validate.integer("n_positions", n_positions, minimum=100)
    ref = panels.ghost_map(cfg, layout, threshold_cm, 1.0, 0.0, n_positions)[2].estimates[0]
    slow = panels.ghost_map(cfg, layout, threshold_cm, speed_scale, 0.0, n_positions)[2].estimates[0]
    return ExerciseCheck(
        f"{layout} layout, δ < {threshold_cm:g} cm: at {speed_scale:g} × |V_ref| the fraction under the threshold is "
        "larger (95 % intervals apart)",
        bool(slow.ci_low > ref.ci_high),
        {"fraction at V_ref (%)": 100 * ref.fraction, "95 % high at V_ref (%)": 100 * ref.ci_high,
         f"fraction at {speed_scale:g} V_ref (%)": 100 * slow.fraction,
         f"95 % low at {speed_scale:g} V_ref (%)": 100 * slow.ci_low},
        ("grows", "does not grow"),
        "Doppler shifts are proportional to the radial speed: a slower receiver changes them less for the same "
        "error in position, so more of the space explains the measured periods to within the threshold.")


def ranging_verdict(cep50_doppler_cm: float, cep50_ranges_cm: float, *, factor: float = 5.0) -> bool:
    """Whether pseudo-ranges cut the CEP50 at least ``factor``-fold (both finite and positive)."""
    factor = validate.number("factor", factor, minimum=1.0)
    return bool(np.isfinite(cep50_doppler_cm) and np.isfinite(cep50_ranges_cm) and cep50_ranges_cm > 0
                and cep50_doppler_cm >= factor * cep50_ranges_cm)


def pseudo_ranges(cfg: study.StudyConfig, *, layout: str = "lab", seed_offset: int = 100, n_runs: int = 3,
                  factor: float = 5.0) -> ExerciseCheck:
    """Exercise: give the particle filter the pseudo-ranges of section 5; predict its CEP50.

    One fresh simulated walk (``seed_offset`` 100: not one of the notebook's recordings), the
    PF of :func:`.study.make_filters` (``cfg.n_particles`` particles) run ``n_runs`` times with
    and without the pseudo-ranges of an exact clock model, scored as in
    :func:`.study.filter_scores` (horizontal CEP50 of all runs after ``t_score_s``). The
    claim: the ranges cut CEP50 at least ``factor``-fold (:func:`ranging_verdict`).
    """
    n_runs = validate.integer("n_runs", n_runs, minimum=1)
    st = study.track_study(layout, cfg, seed_offset=seed_offset, pf_runs=n_runs, kf=False)
    d, r = (100 * metrics.cep50(st.pf_errors_m(v).ravel()) for v in ("Doppler", "Doppler + ranges"))
    return ExerciseCheck(
        f"PF ({n_runs} runs × {cfg.n_particles} particles, one fresh walk): pseudo-ranges cut CEP50 at least "
        f"{factor:g}×", ranging_verdict(d, r, factor=factor),
        {"CEP50, Doppler only (cm)": d, "CEP50, Doppler + pseudo-ranges (cm)": r, "ratio": d / r},
        (f"several-fold (at least {factor:g}×)", f"less than {factor:g}×"),
        "A range pins the distance to each beacon, which the Doppler ghosts (same velocity pattern, shifted "
        "position) do not keep: the cloud collapses onto the true position.")
