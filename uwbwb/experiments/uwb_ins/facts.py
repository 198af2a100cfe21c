"""Notebook 05's verdicts, computed: :func:`facts` reads the numbers and the rules out of an
:class:`~.ablation.AblationResult`; the ``*_sentence`` templates only word them.

Rules
-----
* An ingredient **helps** when the 95 % interval of the paired ratio (without / with it, over
  seeds) lies above 1, **hurts** when it lies below 1, and is **not significant** otherwise;
  with one seed there is no interval and the verdict is **undetermined**.
* Tight coupling's outage advantage over a method **survives** a mismatch case when the ratio
  (that method's max outage error / tight's) has its interval above 1 in that case, is **not
  significant** when the interval includes 1 and **reversed** when it lies below 1; its
  *share kept* is ``log(ratio_case) / log(ratio_matched)`` (1: all of it, 0: none, < 0: reversed).
"""

from __future__ import annotations

import math

import numpy as np

from .ablation import LADDER, AblationResult

__all__ = ["verdict", "facts", "ingredient_sentence", "outage_sentence", "survival_sentence", "eq4_sentence",
           "summary_markdown"]

_METRIC_WORDS = {"static_rmse": "static RMSE", "dyn_rmse": "dynamic RMSE", "outage_max": "max error in the outage"}


def verdict(lo: float, hi: float) -> str:
    """``"helps"``, ``"hurts"``, ``"not significant"`` or ``"undetermined"`` from a ratio interval."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "undetermined"
    if lo > 1:
        return "helps"
    if hi < 1:
        return "hurts"
    return "not significant"


def _ratio(res: AblationResult, a: str, b: str, metric: str, case: str = "matched") -> dict:
    r = res.ratio(a, b, metric, case)
    return {**r, "verdict": verdict(r["lo"], r["hi"])}


def facts(res: AblationResult, *, outage_s: float | None = None) -> dict:
    """Numbers and rule outcomes behind every sentence of notebook 05's ablation.

    Returns a dict with ``mode`` ("FAST" or "full"), ``seeds``, ``outage_s``, ``ladder``
    (step → metric → ratio/lo/hi/n/verdict), ``outage`` (versus "loose + gate" and "EKF + gate":
    the matched ratio of max outage errors and its verdict), ``survival`` (case → versus →
    ratio/lo/hi/verdict/share), ``winners`` (case → metric → best gated row) and ``eq4``
    (counts per case).
    """
    cfg = res.config
    f = {"mode": "FAST" if res.fast else "full", "seeds": cfg.seeds,
         "mismatch_seeds": min(cfg.mismatch_seeds, cfg.seeds),
         "outage_s": cfg.outage_s if outage_s is None else outage_s, "ladder": {}, "outage": {},
         "survival": {}, "winners": {}, "eq4": dict(res.counts)}
    for what, a, b in LADDER:
        f["ladder"][what] = {m: _ratio(res, a, b, m) for m in _METRIC_WORDS}
    for other in ("loose + gate", "EKF + gate"):
        f["outage"][other] = _ratio(res, other, "tight + gate", "outage_max")
    gated = [r for r in ("LS + gate", "EKF + gate", "loose + gate", "tight + gate")]
    for case in cfg.cases:
        t = res.table(case)
        rows = [r for r in gated if r in t.index]
        f["winners"][case] = {m: (str(t.loc[rows, m].idxmin()) if t.loc[rows, m].notna().any() else None)
                              for m in ("static_rmse", "dyn_rmse", "outage_max")}
        if case == "matched":
            continue
        f["survival"][case] = {}
        for other in ("loose + gate", "EKF + gate"):
            r = _ratio(res, other, "tight + gate", "outage_max", case)
            r0 = f["outage"][other]["ratio"]
            r["share"] = (math.log(r["ratio"]) / math.log(r0)
                          if np.isfinite(r["ratio"]) and np.isfinite(r0) and r0 > 1 else np.nan)
            f["survival"][case][other] = r
    return f


def _ci(r: dict, nd: int = 1) -> str:
    if not (np.isfinite(r["lo"]) and np.isfinite(r["hi"])):
        return "no interval"
    return f"95 % CI {r['lo']:.{nd}f}–{r['hi']:.{nd}f}"


def ingredient_sentence(step: str, r: dict, metric: str = "dyn_rmse") -> str:
    """One ladder step in words, e.g. ``"temporal filtering … helps: 3.1× lower dynamic RMSE (95 % CI …)"``."""
    v, x = r["verdict"], r["ratio"]
    what = _METRIC_WORDS[metric]
    if not np.isfinite(x):
        return f"{step}: not measurable on the {what} (a row has no estimate there)."
    size = f"{x:.1f}× lower {what}" if x >= 1 else f"{1 / x:.1f}× higher {what}"
    if v == "helps":
        return f"{step} helps: {size} ({_ci(r)}, {r['n']} seeds)."
    if v == "hurts":
        return f"{step} hurts: {size} ({_ci(r)}, {r['n']} seeds)."
    if v == "not significant":
        return f"{step}: {size}, not significant ({_ci(r)} includes 1, {r['n']} seeds)."
    return f"{step}: {size} on {r['n']} seed — undetermined (no interval)."


def outage_sentence(f: dict) -> str:
    """The headline: tight coupling's single-TDoA update through the outage, against the gated
    loose filter and the gated IMU-free EKF."""
    parts = []
    for other, label in (("loose + gate", "the gated loose filter"), ("EKF + gate", "the gated IMU-free EKF")):
        r = f["outage"][other]
        x = r["ratio"]
        if not np.isfinite(x):
            parts.append(f"{label}: not measurable")
        elif r["verdict"] == "helps":
            parts.append(f"{x:.1f}× smaller than {label}'s ({_ci(r)})")
        elif r["verdict"] == "hurts":
            parts.append(f"{1 / x:.1f}× *larger* than {label}'s ({_ci(r)})")
        elif r["verdict"] == "not significant":
            parts.append(f"not significantly different from {label}'s ({x:.2f}×, {_ci(r, 2)})")
        else:
            parts.append(f"{x:.1f}× smaller than {label}'s on one seed (undetermined)")
    return (f"Through the {f['outage_s']:g} s outage (one TDoA per epoch, no position fix), tight coupling's "
            f"max error is " + "; ".join(parts) + f" ({f['mode']}, {f['seeds']} seeds, matched model).")


def survival_sentence(f: dict, versus: str = "EKF + gate") -> str:
    """How much of the outage advantage over ``versus`` survives each mismatch case."""
    r0 = f["outage"][versus]
    if not (np.isfinite(r0["ratio"]) and r0["ratio"] > 1):
        return (f"In the matched case tight coupling has no outage advantage over {versus} "
                f"({r0['ratio']:.2f}×), so there is nothing to survive mismatch.")
    kept = [c for c, v in f["survival"].items() if v[versus]["verdict"] == "helps"]
    unsure = [c for c, v in f["survival"].items() if v[versus]["verdict"] == "not significant"]
    lost = [c for c, v in f["survival"].items() if v[versus]["verdict"] == "hurts"]
    und = [c for c, v in f["survival"].items() if v[versus]["verdict"] == "undetermined"]
    shares = ", ".join(f"{c} {v[versus]['share'] * 100:.0f} %" for c, v in f["survival"].items()
                       if np.isfinite(v[versus]["share"]))
    sig = "" if r0["verdict"] == "helps" else ", itself not significant"
    text = (f"Of the matched outage advantage over {versus} ({r0['ratio']:.1f}×{sig}), the share kept (in log "
            f"ratio) is: {shares or 'not measurable'}.")
    if kept:
        text += f" It survives (interval above 1) with {', '.join(kept)}."
    if unsure:
        text += f" Not significant (interval includes 1) with {', '.join(unsure)}."
    if lost:
        text += f" Reversed (interval below 1: tight is worse) with {', '.join(lost)}."
    if und:
        text += f" Undetermined ({f['mismatch_seeds']} seed, no interval): {', '.join(und)}."
    return text


def eq4_sentence(f: dict, *, wide_case: str = "multipath up to 12 m") -> str:
    """How often eq. 4 fired on injected multipath, in the matched world and where excesses reach 12 m."""
    m = f["eq4"].get("matched", {})
    text = (f"Eq. 4 removed {m.get('eq4_on_injected', 0)} of {m.get('injected', 0)} TDoAs carrying injected "
            f"multipath in the matched runs ({m.get('eq4', 0)} TDoAs in all)")
    w = f["eq4"].get(wide_case)
    if w:
        text += (f"; with excesses up to 12 m it removed {w['eq4_on_injected']} of {w['injected']} "
                 f"(the rest only a gate can catch)")
    return text + "."


def summary_markdown(f: dict) -> str:
    """The ablation's verdicts as markdown (one line per ladder step on the dynamic RMSE and the
    outage, then the headline, the survival and the eq-4 sentences)."""
    lines = [f"*{f['mode']} run: {f['seeds']} scoring seeds; mismatch cases on {f['mismatch_seeds']}.*", ""]
    for step, r in f["ladder"].items():
        lines.append("- " + ingredient_sentence(step, r["dyn_rmse"], "dyn_rmse"))
    lines += ["", "**Headline.** " + outage_sentence(f), "",
              survival_sentence(f, "EKF + gate") + " " + survival_sentence(f, "loose + gate"), "",
              eq4_sentence(f)]
    return "\n".join(lines)
