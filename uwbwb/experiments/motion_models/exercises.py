"""Exercises of notebook 03 ("change X, predict Y").

Each exercise runs both settings on the same window of the same test run and returns a
:class:`uwbwb.widgets.ExerciseCheck`: the direction the student is asked to predict, whether this
run shows it, and the numbers. The reasoning is the check's ``why``, shown
once the student has predicted; ``TEACHING.md`` gives one run's numbers.
"""

from __future__ import annotations

from typing import Mapping, Sequence


from ... import validate
from ...types import TagRun
from ...widgets import ExerciseCheck
from .results import ekf_name
from .study import estimate

__all__ = ["WINDOW_S", "overconfident_driving_noise", "reference_anchor", "window"]

#: Seconds of a test run the exercises and the panel filter (from its first epoch): short enough
#: that a check takes about a second.
WINDOW_S = 30.0
#: A CEP95 that moves by more than this between reference anchors "depends on the reference", centimetres.
REFERENCE_SPREAD_CM = 1.0


def window(run: TagRun, window_s: float = WINDOW_S) -> TagRun:
    """The first ``window_s`` seconds of ``run``."""
    window_s = validate.number("window_s", window_s, minimum=0.0, strict_minimum=True)
    t0 = float(run.ranges.t_s[0])
    return run.between(t0, t0 + window_s)


def reference_anchor(run: TagRun, sigma_m, sigmas: Mapping[str, float], *, refs: Sequence[int] = (0, 2),
                     model: str = "RW", window_s: float = WINDOW_S) -> ExerciseCheck:
    """Exercise: use the diagonal TDoA covariance and change the reference anchor; predict CEP95.

    With the reference-correlated covariance ``Σ = diag(σ_j²) + σ_ref² 11ᵀ`` every choice of
    reference carries the same information (the ranges up to their common offset), so LS and the
    EKF give the same positions whatever the reference. The diagonal shortcut drops the
    correlation and weights the TDoAs as if independent; which anchor's noise is counted in every
    TDoA then depends on the reference, and so do the positions. The check runs LS and the EKF with
    ``model`` for every reference, both covariances, no gate,
    and compares the spread (largest − smallest CEP95) over the references ``refs`` (anchor indices;
    two keep the check to a few seconds).

    Parameters
    ----------
    run
        A test run (its first ``window_s`` seconds are used).
    sigma_m
        Range-noise standard deviation per anchor (from the calibration run), metres, ``(n_anchors,)``.
    sigmas
        Driving standard deviation per model (model units); ``sigmas[model]`` is used.

    Returns
    -------
    ExerciseCheck
        Claim "with the diagonal covariance the CEP95 of LS and of the EKF each change by more than
        :data:`REFERENCE_SPREAD_CM` between the reference anchors" (the correlated covariance's spread is zero by
        construction, so it is a number, not the claim); numbers: the spreads (cm) and the correlated CEP95s (m).
    """
    part = window(run, window_s)
    refs = [validate.integer("refs", r, minimum=0, maximum=len(part.anchors) - 1) for r in refs]
    if len(set(refs)) < 2:
        raise ValueError(f"refs must name at least two different anchors, got {refs!r}")
    name = ekf_name(model)
    cep = {}
    for correlated in (True, False):
        for ref in refs:
            c = estimate(part, sigma_m, {model: sigmas[model]}, ref=ref, gate_prob=None, correlated=correlated,
                         models=(model,)).cep95()
            cep[correlated, ref] = (c["LS"], c[name])
    spread = {(corr, k): 100.0 * (max(cep[corr, r][k] for r in refs) - min(cep[corr, r][k] for r in refs))
              for corr in (True, False) for k in (0, 1)}
    holds = spread[False, 0] > REFERENCE_SPREAD_CM and spread[False, 1] > REFERENCE_SPREAD_CM
    return ExerciseCheck(
        f"{part.key}, first {window_s:g} s, reference anchor {' vs '.join(map(str, refs))}: with the diagonal Σ the "
        f"CEP95 of LS and of {name} each change by more than {REFERENCE_SPREAD_CM:g} cm",
        holds,
        {"LS spread, correlated Σ (cm)": spread[True, 0], "LS spread, diagonal Σ (cm)": spread[False, 0],
         f"{name} spread, correlated Σ (cm)": spread[True, 1], f"{name} spread, diagonal Σ (cm)": spread[False, 1],
         f"LS CEP95, correlated Σ (m)": cep[True, refs[0]][0], f"{name} CEP95, correlated Σ (m)": cep[True, refs[0]][1]},
        (f"both change by more than {REFERENCE_SPREAD_CM:g} cm", f"not both by more than {REFERENCE_SPREAD_CM:g} cm"),
        "The diagonal shortcut treats the TDoAs as independent, so the reference anchor's noise, shared by every "
        "TDoA, is counted once per row: which anchor that is changes the weights and the fixes. The correlated Σ "
        "carries the same information whatever the reference — its spread is zero up to rounding (see the numbers).")


def overconfident_driving_noise(run: TagRun, sigma_m, sigmas: Mapping[str, float], *, model: str = "RF",
                                factor: float = 0.01, ref: int = 0, window_s: float = WINDOW_S) -> ExerciseCheck:
    """Exercise: divide the calibrated driving noise by ``1/factor``; predict CEP95 and the NIS.

    A driving noise far below what the target does tells the EKF that it moves almost exactly as
    the model predicts. The filter trusts its prediction, lags behind every turn, and its
    innovations come out much larger than its covariance claims: CEP95 rises and the mean NIS per
    degree of freedom rises above the calibrated filter's (over-confidence).

    Parameters
    ----------
    run, sigma_m, sigmas
        As :func:`reference_anchor`; ``sigmas[model]`` is the calibrated value.
    factor
        Multiplier on the calibrated driving standard deviation (0 < factor < 1).

    Returns
    -------
    ExerciseCheck
        Claim "CEP95 and mean NIS/dof both higher with the smaller driving noise"; numbers: both at
        both settings and the two σ values.
    """
    factor = validate.number("factor", factor, minimum=0.0, maximum=1.0, strict_minimum=True)
    part = window(run, window_s)
    name = ekf_name(model)
    out = {}
    for label, s in (("calibrated", float(sigmas[model])), ("small", factor * float(sigmas[model]))):
        est = estimate(part, sigma_m, {model: s}, ref=ref, gate_prob=None, models=(model,))
        out[label] = (s, est.cep95()[name], float(est.nis().loc[name, "mean_nis_over_dof"]))
    cal, small = out["calibrated"], out["small"]
    return ExerciseCheck(
        f"{part.key}, first {window_s:g} s: {name} with σ_w × {factor:g} has a higher CEP95 and a higher mean NIS/dof",
        small[1] > cal[1] and small[2] > cal[2],
        {"σ_w calibrated": cal[0], "σ_w small": small[0], "CEP95 calibrated (m)": cal[1], "CEP95 small (m)": small[1],
         "mean NIS/dof calibrated": cal[2], "mean NIS/dof small": small[2]},
        ("both higher", "not both higher"),
        "Too little driving noise tells the filter the tag moves almost exactly as modelled: it trusts its "
        "prediction, lags behind every turn, and its innovations come out larger than its covariance claims "
        "(NIS/dof above the calibrated filter's: over-confidence).")
