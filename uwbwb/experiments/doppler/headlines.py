"""Notebook 04's summary rows, declared as data, and its checks (read from :func:`.facts.facts`).

Each :class:`~uwbwb.metrics.Headline` names the quantity, its unit, its kind (*reproduced*, *target* or
*input*), the paper's value where one is comparable, and how to read it from the facts.
The lab layout is a *reconstruction* and its row says so.
"""

from __future__ import annotations

import numpy as np

from .facts import PF_RUN_VERDICTS
from .study import PAPER, READINGS
from ...metrics import Headline, interval_rows

__all__ = ["HEADLINES", "PF_RUN_ROWS", "JUDGED_IF_CONVERGED", "rows", "checks"]


#: The two data variants the PF and the MH-EKF filter, and the tag their summary rows carry.
VARIANTS = (("Doppler", ""), ("Doppler + ranges", " with ranges"))


def _headlines() -> tuple[tuple[Headline, ...], frozenset]:
    out, pf_runs = [], set()

    def add(h: Headline, pf_run: bool = False):
        out.append(h)
        if pf_run:
            pf_runs.add(h.quantity)

    for r in READINGS:
        for b in (0, 7):
            add(Headline(f"ΔP_ref beacon {b} ({r})", "ms", "reproduced",
                         lambda f, r=r, b=b: f[f"dp_ms[{r}][{b}]"], PAPER["dp_ref_ms"][b]))
        for layout in ("cubic", "lab"):
            note = "" if layout == "cubic" else ", reconstruction of the layout"
            paper = PAPER["fraction_15cm_pct"][layout]
            add(Headline(f"fraction δ < 15 cm, {layout} layout{note} ({r})", "%", "reproduced",
                         lambda f, k=f"[{layout}][{r}]": f["frac_pct" + k], paper))
            for end in ("low", "high"):
                add(Headline(f"fraction δ < 15 cm, {layout} layout{note} ({r}), 95 % interval {end}", "%",
                             "reproduced", lambda f, k=f"[{layout}][{r}]", e=end: f[f"frac_{e[:2]}_pct" + k]))
    brute = "fraction δ < 15 cm, cubic layout (brute force, per-beacon periods)"
    add(Headline(brute, "%", "reproduced", lambda f: f["brute_frac_pct"]))
    for end in ("low", "high"):
        add(Headline(f"{brute}, 95 % interval {end}", "%", "reproduced", lambda f, e=end: f[f"brute_{e[:2]}_pct"]))
    for layout in ("cubic", "lab"):
        add(Headline(f"fraction δ < 15 cm with pseudo-ranges, {layout} layout", "%", "reproduced",
                     lambda f, l=layout: f["ranges_frac_pct"][l]))
    lab = ", reconstructed lab"
    for v, tag in VARIANTS:
        gated = f"pf_track_verdict[{v}]" in PF_RUN_VERDICTS      # the PF runs the particle count test stands for
        for key, name, paper in (("cep50", "median over recordings", PAPER["cep50_cm"] if not tag else None),
                                 ("offset", "shared offset, median over recordings", None),
                                 ("spread", "run-to-run CEP50, median over recordings", None)):
            add(Headline(f"PF snapshot CEP50{tag}{lab}, {name}" if key == "cep50" else
                         f"PF snapshot {name}{tag}{lab}", "cm", "reproduced",
                         lambda f, k=f"{key}_cm[{v}]": f[k]["median"], paper), gated)
        for flt, key in (("PF", "pf"), ("MH-EKF", "kf")):
            add(Headline(f"{flt} CEP50, scored epochs{tag}{lab}, median over recordings", "cm", "reproduced",
                         lambda f, v=v, k=key: f[f"{k}_cep50_cm[{v}]"]), gated and key == "pf")
            add(Headline(f"{flt} coverage of its own 95 % region, scored epochs{tag}{lab}", "", "reproduced",
                         lambda f, v=v, k=key: f[f"{k}_coverage[{v}]"]), gated and key == "pf")
        add(Headline(f"PF CEP95, scored epochs{tag}{lab}, median over recordings", "cm", "reproduced",
                     lambda f, v=v: f[f"pf_cep95_cm[{v}]"]), gated)
        add(Headline(f"PF share of runs restarted{tag}{lab}", "", "reproduced",
                     lambda f, v=v: f[f"pf_restarted_share[{v}]"]), gated)
        for flt, key in (("PF", "pf"), ("MH-EKF", "kf")):      # the verdict table's keeps-track rows
            add(Headline(f"{flt} share of scored epochs within 0.5 m{tag}{lab}", "", "reproduced",
                         lambda f, v=v, k=key: f[f"{k}_in_track[{v}]"]), gated and key == "pf")
            add(Headline(f"recordings where the {flt} lost track{tag}{lab}", "", "reproduced",
                         lambda f, v=v, w=flt: len(f[f"lost_track[{v}]"][w])), gated and key == "pf")
        add(Headline(f"recordings where both filters keep track{tag}{lab}", "", "reproduced",
                     lambda f, v=v: f[f"both_keep_track[{v}]"][0]), gated)
    for corner in ("bottom-left", "top-left"):
        add(Headline(f"PF along/across-track ratio, {corner} corner{lab}, median over recordings", "", "reproduced",
                     lambda f, c=corner: f["corners"][c]["median"] if c in f["corners"] else np.nan,
                     PAPER["along_over_cross"]), "ratio_verdict" in PF_RUN_VERDICTS)
    # not called a floor: it is one only where 4× the particles no longer change it (facts: particles_verdict)
    for cond, more in (("zero noise, exact eq-1 ΔP", ""), ("zero noise, exact eq-1 ΔP, 4× particles", ", 4× particles")):
        add(Headline(f"PF CEP50, scored epochs, first recording with zero noise and exact eq-1 ΔP{more}{lab}",
                     "cm", "reproduced", lambda f, c=cond: f["floor_cm"][c]))
    return tuple(out), frozenset(pf_runs)


HEADLINES, PF_RUN_ROWS = _headlines()
#: PF_RUN_ROWS are the rows read from the Doppler-only PF runs at the tested particle count (those facts'
#: ``PF_RUN_VERDICTS`` judge). Until that count has converged (facts' ``particles_verdict``) each carries the count's
#: verdict after its name, as the verdict table's rows carry it in place of their verdicts, and the rows set beside
#: a paper value (JUDGED_IF_CONVERGED: the CEP50 and the along/across ratios) lose it: the notebook gives no verdict
#: on them, and neither does the summary.
JUDGED_IF_CONVERGED = frozenset(h.quantity for h in HEADLINES if h.quantity in PF_RUN_ROWS and h.paper is not None)


def _qualifier(f: dict) -> str:
    return "" if f["particles_converged"] else f" (particle count: {f['particles_verdict']})"


def rows(f: dict) -> list[dict]:
    """The summary rows: ``quantity, value, unit, paper_value, kind`` (data: synthetic). Until
    ``f["particles_converged"]``, :data:`PF_RUN_ROWS` carry the particle count's verdict after their name and
    :data:`JUDGED_IF_CONVERGED` rows no paper value. After the headlines, the verdict table's MH-EKF − PF
    differences per recording with their 95 % intervals (all recordings; and those where both keep track, where
    there are any), qualified where that comparison's verdict waits for the particle count."""
    out = []
    for h in HEADLINES:
        r = h.row(f)
        if h.quantity in PF_RUN_ROWS:
            r["quantity"] += _qualifier(f)
        if h.quantity in JUDGED_IF_CONVERGED and not f["particles_converged"]:
            r["paper_value"] = None
        out.append(r)
    for v, tag in VARIANTS:
        if f"kf_vs_pf[{v}]" not in f:
            continue
        q = _qualifier(f) if f"kf_vs_pf[{v}]" in PF_RUN_VERDICTS else ""
        for key, which in (("", "all recordings"), ("_tracked", "recordings where both keep track")):
            t = f[f"kf_minus_pf_cm{key}[{v}]"]
            if t["n"]:
                out += interval_rows(f"MH-EKF − PF CEP50 on the scored epochs per recording{tag}, reconstructed lab, "
                                     f"mean over {which}{q}", t["mean"], t["lo"], t["hi"], unit="cm",
                                     paper_value=None, kind="reproduced", data="synthetic")
    return out


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
