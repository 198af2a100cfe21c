"""Notebook 04's summary rows, declared as data, and its checks (read from :func:`.facts.facts`).

Each :class:`~uwbwb.metrics.Headline` names the quantity, its unit, its kind (*reproduced*, *target* or
*input*), the paper's value where one is comparable, and how to read it from the facts.
The lab layout is a *reconstruction* and its row says so.
"""

from __future__ import annotations

import numpy as np

from .study import PAPER, READINGS
from ...metrics import Headline

__all__ = ["HEADLINES", "JUDGED_IF_CONVERGED", "rows", "checks"]


def _headlines() -> tuple[Headline, ...]:
    out = []
    for r in READINGS:
        for b in (0, 7):
            out.append(Headline(f"ΔP_ref beacon {b} ({r})", "ms", "reproduced",
                                lambda f, r=r, b=b: f[f"dp_ms[{r}][{b}]"], PAPER["dp_ref_ms"][b]))
        for layout in ("cubic", "lab"):
            note = "" if layout == "cubic" else ", reconstruction of the layout"
            paper = PAPER["fraction_15cm_pct"][layout]
            out.append(Headline(f"fraction δ < 15 cm, {layout} layout{note} ({r})", "%", "reproduced",
                                lambda f, k=f"[{layout}][{r}]": f["frac_pct" + k], paper))
            for end in ("low", "high"):
                out.append(Headline(f"fraction δ < 15 cm, {layout} layout{note} ({r}), 95 % interval {end}", "%",
                                    "reproduced", lambda f, k=f"[{layout}][{r}]", e=end: f[f"frac_{e[:2]}_pct" + k]))
    brute = "fraction δ < 15 cm, cubic layout (brute force, per-beacon periods)"
    out.append(Headline(brute, "%", "reproduced", lambda f: f["brute_frac_pct"]))
    for end in ("low", "high"):
        out.append(Headline(f"{brute}, 95 % interval {end}", "%", "reproduced",
                            lambda f, e=end: f[f"brute_{e[:2]}_pct"]))
    for layout in ("cubic", "lab"):
        out.append(Headline(f"fraction δ < 15 cm with pseudo-ranges, {layout} layout", "%", "reproduced",
                            lambda f, l=layout: f["ranges_frac_pct"][l]))
    lab = ", reconstructed lab"
    for v, tag in (("Doppler", ""), ("Doppler + ranges", " with ranges")):
        for key, name, paper in (("cep50", "median over recordings", PAPER["cep50_cm"] if not tag else None),
                                 ("offset", "shared offset, median over recordings", None),
                                 ("spread", "run-to-run CEP50, median over recordings", None)):
            out.append(Headline(f"PF snapshot CEP50{tag}{lab}, {name}" if key == "cep50" else
                                f"PF snapshot {name}{tag}{lab}", "cm", "reproduced",
                                lambda f, k=f"{key}_cm[{v}]": f[k]["median"], paper))
        for flt, key in (("PF", "pf"), ("MH-EKF", "kf")):
            out.append(Headline(f"{flt} CEP50, scored epochs{tag}{lab}, median over recordings", "cm", "reproduced",
                                lambda f, v=v, k=key: f[f"{k}_cep50_cm[{v}]"]))
            out.append(Headline(f"{flt} coverage of its own 95 % region, scored epochs{tag}{lab}", "", "reproduced",
                                lambda f, v=v, k=key: f[f"{k}_coverage[{v}]"]))
        out.append(Headline(f"PF CEP95, scored epochs{tag}{lab}, median over recordings", "cm", "reproduced",
                            lambda f, v=v: f[f"pf_cep95_cm[{v}]"]))
        out.append(Headline(f"PF share of runs restarted{tag}{lab}", "", "reproduced",
                            lambda f, v=v: f[f"pf_restarted_share[{v}]"]))
        out.append(Headline(f"PF share of scored epochs within 0.5 m{tag}{lab}", "", "reproduced",
                            lambda f, v=v: f[f"pf_in_track[{v}]"]))
    for corner in ("bottom-left", "top-left"):
        out.append(Headline(f"PF along/across-track ratio, {corner} corner{lab}, median over recordings", "",
                            "reproduced", lambda f, c=corner: f["corners"][c]["median"] if c in f["corners"] else np.nan,
                            PAPER["along_over_cross"]))
    # not called a floor: it is one only where 4× the particles no longer change it (facts: particles_verdict)
    for cond, more in (("zero noise, exact eq-1 ΔP", ""), ("zero noise, exact eq-1 ΔP, 4× particles", ", 4× particles")):
        out.append(Headline(f"PF CEP50, scored epochs, first recording with zero noise and exact eq-1 ΔP{more}{lab}",
                            "cm", "reproduced", lambda f, c=cond: f["floor_cm"][c]))
    return tuple(out)


HEADLINES = _headlines()
#: Rows set beside the paper's value only where the particle count has converged (facts' ``particles_verdict``):
#: until then the notebook gives no verdict on the Doppler-only PF runs (facts' ``PF_RUN_VERDICTS``: the CEP50 and
#: the along/across ratios against the paper's), and neither does the summary.
JUDGED_IF_CONVERGED = frozenset(h.quantity for h in HEADLINES if h.quantity.startswith("PF ")
                                and h.paper is not None)


def rows(f: dict) -> list[dict]:
    """The summary rows: ``quantity, value, unit, paper_value, kind`` (data: synthetic); the paper's value is left
    out of :data:`JUDGED_IF_CONVERGED` rows unless ``f["particles_converged"]``."""
    return [dict(h.row(f), paper_value=None) if h.quantity in JUDGED_IF_CONVERGED and not f["particles_converged"]
            else h.row(f) for h in HEADLINES]


def checks(f: dict, *, fast: bool) -> list[str]:
    """What must hold whatever the mode (looser under FAST); returns the failures (empty: all hold)."""
    fail = []
    if not abs(f[f"dp_ms[{list(READINGS)[1]}][0]"] - 1.06) < 0.01:
        fail.append("eq 1 at P = 500 ms must give ΔP_ref(beacon 0) ≈ 1.06 ms")
    if not f["estimators_agree"]:
        fail.append("brute force and conditional disagree beyond their intervals")
    if f["fig_empty_panels"] and not fast:          # FAST: reported under the figure's panels
        fail.append(f"empty figure panels: {f['fig_empty_panels']}")
    if not all(f["ranges_frac_pct"][k] < 0.01 * f[f"frac_pct[{k}][{list(READINGS)[0]}]"] for k in ("cubic", "lab")):
        fail.append("the ranging term must shrink the fraction under 15 cm a hundredfold")
    if not (f["cut_min_cm"].get("V = V_ref", np.inf) < 1e-4):
        fail.append("the cut with V_ref must reach δ = 0 at the reference")
    limit = 100 if fast else 60
    if not 0 < f["cep50_cm[Doppler]"]["median"] < limit:
        fail.append(f"PF snapshot CEP50 outside (0, {limit}) cm")
    if not f["cep50_cm[Doppler + ranges]"]["median"] < f["cep50_cm[Doppler]"]["median"]:
        fail.append("pseudo-ranges must lower the PF's snapshot CEP50")
    return fail
