"""Notebook 04's results as numbers and computed verdicts (paper 003).

:func:`facts` turns what the notebook computed into a flat ``dict`` of numbers and verdict labels;
:func:`verdict_table` and :func:`fig6_table` lay them out as the notebook's verdict tables and :mod:`.headlines`
reads the summary rows from them, so a test can feed numbers on either side of each threshold and see the verdict
flip.

Every interval verdict is :func:`uwbwb.metrics.interval_side` of an interval against a stated value, named by one
mapping of its sides to words per claim; "no interval" where there is none. Intervals over recordings (which are
independent) are :func:`uwbwb.metrics.seeds_interval`: the Student-t 95 % interval of the mean over recordings.

Rules
-----
Each claim of :func:`verdict_table` states its rule in the table's ``rule`` column; the constants below set them.
Those of :func:`fig6_table`:

* The particle count (one rule for every verdict on the Doppler-only PF runs of Fig 6 and the filter comparison,
  :data:`PF_RUN_VERDICTS`): they all run at the particle count whose convergence the last row of
  :func:`verdict_table` tests (the drop of the CEP50 with 4× the particles inside ±1 cm, on Doppler-only data).
  Until it has converged each of them reads :data:`NOT_CONVERGED` or :data:`NOT_JUDGED` in place of its verdict:
  more particles may still move the numbers it rests on. The numbers stay in their tables. The Doppler + ranges
  runs are outside the test (it filters Doppler-only data); their verdicts do not wait for it.
* Fig 6 CEP50 (paper ≈ 25 cm, from *one* recording): judged against the spread of single recordings ([min, max]
  over ≥ 3 recordings: consistent, or above / below), and against the interval of the mean separately.
* The along/across ratio per corner (paper ≈ 0.5) claims an asymmetry, so the interval of the mean ratio over
  recordings gets two verdicts, each of which it can reject: *asymmetry (≠ 1)* (:data:`ASYMMETRY`) and *the paper's
  0.5* inside or outside. Reproduced when every corner detects an asymmetry below 1 and holds 0.5; "no asymmetry
  detected" when no corner detects one (a range that holds 0.5 and 1 alike rejects nothing).
* MH-EKF vs PF on all recordings: a better filter that lost track (:func:`~.study.keeps_track`) is named with
  the recordings it lost (recording 0 is the one Fig 6 draws).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...metrics import interval_side, interval_text, seeds_interval
from .study import KEEPS_TRACK, PAPER, READINGS, keeps_track

__all__ = ["facts", "fig6_table", "verdict_table", "DP_TOLERANCE_MS", "GHOST_ANGLE_DEG", "OFFSET_SHARE",
           "EQUAL_CM", "PARTICLE_STEP_CM", "SAME_ORDER_LOG10", "NOT_CONVERGED", "NOT_JUDGED", "PF_RUN_VERDICTS",
           "ASYMMETRY", "TRACK_WORDS", "particles_verdict", "track_cells"]

#: Half of the last printed digit of the paper's ΔP_ref (ms).
DP_TOLERANCE_MS = 0.05
#: Largest angle (°) between the ghost plane's normal (and the velocity ghosts' axis) and V_ref.
GHOST_ANGLE_DEG = 20.0
#: Share offset² / (offset² + spread²) that the interval must exclude to name one part the larger.
OFFSET_SHARE = 0.5
#: Half-width (cm) of the band the interval of MH-EKF − PF must lie inside for the filters to count as equal.
EQUAL_CM = 0.5
#: Largest |log10(ours / paper)| of the lab-over-cubic fraction ratio that counts as the same order of magnitude.
SAME_ORDER_LOG10 = 0.5
#: Half-width (cm) of the band the interval of the CEP50's drop with 4× the particles must lie inside (converged).
PARTICLE_STEP_CM = 1.0
#: A Fig 5 minimum closer than this to s = 0 (m) with δ under REFERENCE_DELTA_CM is the reference itself.
REFERENCE_S_M = 0.01
REFERENCE_DELTA_CM = 1e-3
#: Threshold (cm) under which a cut's minimum counts as a ghost.
GHOST_CUT_CM = 8.0
#: What every verdict of PF_RUN_VERDICTS reads while the particle count has not converged, or while that is undecided.
NOT_CONVERGED = "not converged"
NOT_JUDGED = "not judged (convergence not shown)"
#: Words of a keeps-track verdict (:func:`~.study.keeps_track`), and of a keeps-track cell (:func:`track_cells`).
TRACK_WORDS = {True: "keeps track", False: "does not keep track"}
#: Verdicts read from the Doppler-only PF runs at the tested particle count (keys of :func:`facts`; the corners'
#: "asymmetry" and "paper" too): each is given only once that count has converged.
PF_RUN_VERDICTS = ("cep50_verdict", "cep50_mean_verdict", "offset_or_spread", "ratio_verdict", "corner_dependence",
                   "kf_vs_pf[Doppler]", "kf_vs_pf_tracked[Doppler]", "pf_track_verdict[Doppler]")
#: Appended to the rule of each verdict-table row whose verdict is one of PF_RUN_VERDICTS.
PF_GATE = "; given once the particle count has converged (last row)"
NO_INTERVAL = "no interval"
#: Fig 6 (which draws recording 0): a better filter that lost track there is named with it.
FIG6_RECORDING = 0
#: The period reading the brute force ran on (the model's own periods): its fraction row has two estimators.
BRUTE_READING = next(r for r, p in READINGS.items() if p is None)
#: Words of each claim for the sides of :func:`~uwbwb.metrics.interval_side`.
ASYMMETRY = {"contains": "not detected", "below": "detected (< 1)", "above": "detected, the other way (> 1)"}
PAPER_INSIDE = {"contains": "inside", "above": "outside (interval above 0.5)", "below": "outside (interval below 0.5)"}
CONSISTENT = {"contains": "consistent", "above": "above", "below": "below"}
FRACTION = {"below": "agrees", "above": "disagrees", "contains": "undecided"}
OFFSET = {"above": "offset", "below": "spread", "contains": "comparable"}
CORNERS = {"above": "depends", "below": "depends", "contains": "not significant"}
BETTER = {"above": "PF better", "below": "MH-EKF better", "contains": "no significant difference"}


def _side(lo: float, hi: float, null: float, words: dict) -> str:
    return words.get(interval_side(lo, hi, null), NO_INTERVAL)


def _over_recordings(x) -> dict:
    """Median, min and max of one value per recording, and the mean with its interval (:func:`seeds_interval`)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return {"median": float(np.median(x)), **seeds_interval(x), "min": float(x.min()), "max": float(x.max())}


def facts(*, ref_table: pd.DataFrame, readings: pd.DataFrame, at15: dict, fig_runs: dict, geometry: dict,
          cut_minima: dict, snap: pd.DataFrame, scores: pd.DataFrame, floor: pd.DataFrame) -> dict:
    """Numbers and verdicts of notebook 04 (see the module docstring for every rule), from what it computed.

    ``ref_table``: :func:`~.study.reference_table`; ``readings``: :func:`~.study.period_readings`; ``at15``:
    ``{layout: {"conditional" | "brute force" | "ranges": FractionEstimate}}`` at 15 cm; ``fig_runs``:
    :func:`~.study.figure_samples` per layout; ``geometry``:
    :func:`~.ghosts.ghost_geometry`; ``cut_minima``: ``{curve: (s (m), δ (cm)) at the minimum}`` of Fig 5; ``snap``:
    :meth:`~.study.TrackStudy.snapshot_errors` of every recording and variant (columns ``recording``,
    ``variant``); ``scores``: :func:`~.study.filter_scores`; ``floor``: :func:`~.study.error_floor`.
    """
    f: dict = {"readings": list(READINGS), "dp_reproduces": []}
    for r in READINGS:
        for b in (0, 7):
            f[f"dp_ms[{r}][{b}]"] = float(ref_table[f"ΔP_ref (ms), {r}"].iloc[b])
        if all(abs(f[f"dp_ms[{r}][{b}]"] - PAPER["dp_ref_ms"][b]) <= DP_TOLERANCE_MS + 1e-12 for b in (0, 7)):
            f["dp_reproduces"].append(r)
    for _, row in readings.iterrows():
        key = f"[{row['layout']}][{row['reading']}]"
        f[f"frac_pct{key}"], f[f"frac_lo_pct{key}"], f[f"frac_hi_pct{key}"] = (
            float(row[c]) for c in ("fraction (%)", "95 % low (%)", "95 % high (%)"))
        if row["layout"] == "cubic":
            f[f"frac_verdict{key}"] = _side(f[f"frac_lo_pct{key}"], f[f"frac_hi_pct{key}"],
                                            PAPER["fraction_15cm_pct"]["cubic"], FRACTION)

    # --- estimators, the lab, Figs 3-5
    c, lab = at15["cubic"], at15["lab"]
    b = c["brute force"]
    f["brute_frac_pct"], f["brute_lo_pct"], f["brute_hi_pct"] = 100 * b.fraction, 100 * b.ci_low, 100 * b.ci_high
    f["brute_draws"] = int(b.n_draws)
    # the brute force ran on the per-beacon periods only: that row rests on two estimators, and says so when they differ
    k = f"[cubic][{BRUTE_READING}]"
    f["frac_verdict_brute"] = _side(f["brute_lo_pct"], f["brute_hi_pct"], PAPER["fraction_15cm_pct"]["cubic"], FRACTION)
    if f["frac_verdict_brute"] != f["frac_verdict" + k]:
        f["frac_verdict" + k] += f" (conditional); brute force {f['frac_verdict_brute']}"
    f["estimators_agree"] = bool(all(
        e["conditional"].ci_low <= e["brute force"].ci_high and e["brute force"].ci_low <= e["conditional"].ci_high
        for e in at15.values()))
    f["lab_over_cubic"] = float(lab["conditional"].fraction / c["conditional"].fraction)
    f["lab_over_cubic_paper"] = PAPER["fraction_15cm_pct"]["lab"] / PAPER["fraction_15cm_pct"]["cubic"]
    f["lab_same_order"] = bool(abs(np.log10(f["lab_over_cubic"] / f["lab_over_cubic_paper"])) < SAME_ORDER_LOG10)
    f["ranges_frac_pct"] = {k: 100 * v["ranges"].fraction for k, v in at15.items()}
    f["fig_empty_panels"] = [(lay, t) for lay, runs in fig_runs.items() for t, r in runs.items()
                             if len(r.samples.below(t)) == 0]
    f["plane_angle_deg"] = float(geometry["angle(position plane normal, V) (°)"])
    f["vel_axis_angle_deg"] = float(geometry["angle(velocity main axis, V) (°)"])
    f["ghost_shape_holds"] = bool(max(f["plane_angle_deg"], f["vel_axis_angle_deg"]) < GHOST_ANGLE_DEG)
    f["cut_min_cm"] = {k: float(v[1]) for k, v in cut_minima.items()}
    f["cut_verdict"] = {k: "the reference itself" if abs(s) < REFERENCE_S_M and d < REFERENCE_DELTA_CM else
                        "a ghost" if d < GHOST_CUT_CM else "not a ghost" for k, (s, d) in cut_minima.items()}

    # --- Fig 6 over recordings
    f["n_recordings"] = int(snap["recording"].nunique())
    per_rec = snap.groupby(["variant", "recording"])[["CEP50 (cm)", "offset (cm)", "run-to-run CEP50 (cm)"]].mean()
    for variant in per_rec.index.unique(0):
        for q, key in (("CEP50 (cm)", "cep50"), ("offset (cm)", "offset"), ("run-to-run CEP50 (cm)", "spread")):
            f[f"{key}_cm[{variant}]"] = _over_recordings(per_rec.loc[variant, q])
    cep = f["cep50_cm[Doppler]"]
    f["cep50_verdict"] = _side(cep["min"], cep["max"], PAPER["cep50_cm"], CONSISTENT) if f["n_recordings"] >= 3 \
        else NO_INTERVAL
    f["cep50_mean_verdict"] = _side(cep["lo"], cep["hi"], PAPER["cep50_cm"], CONSISTENT)
    d = per_rec.loc["Doppler"]
    f["offset_share"] = seeds_interval(d["offset (cm)"] ** 2 / (d["offset (cm)"] ** 2 + d["run-to-run CEP50 (cm)"] ** 2))
    f["offset_or_spread"] = _side(f["offset_share"]["lo"], f["offset_share"]["hi"], OFFSET_SHARE, OFFSET)
    dop = snap[snap["variant"] == "Doppler"]
    f["corners"] = {}
    for corner, d in dop.groupby("corner", sort=False):
        s = _over_recordings(d["along / across"])
        f["corners"][corner] = {**s, "asymmetry": _side(s["lo"], s["hi"], 1.0, ASYMMETRY),
                                "paper": _side(s["lo"], s["hi"], PAPER["along_over_cross"], PAPER_INSIDE)}
    sides = [(v["asymmetry"], v["paper"]) for v in f["corners"].values()]
    f["ratio_verdict"] = (NO_INTERVAL if not sides or any(NO_INTERVAL in s for s in sides) else
                          "reproduced" if all(s == (ASYMMETRY["below"], "inside") for s in sides) else
                          "no asymmetry detected" if all(a == ASYMMETRY["contains"] for a, _ in sides) else
                          "not reproduced")
    if len(f["corners"]) == 2:                     # paired per recording: first corner minus second corner
        piv = dop.pivot_table(index="recording", columns="corner", values="along / across")
        f["corner_pair"] = a, b = tuple(f["corners"])
        f["corner_diff"] = seeds_interval(piv[a] - piv[b])
        f["corner_dependence"] = _side(f["corner_diff"]["lo"], f["corner_diff"]["hi"], 0.0, CORNERS)

    # --- filters: accuracy, keeping track, coverage
    for variant, d in scores.groupby("variant"):
        pf_ok, kf_ok = d["PF keeps track"], d["MH-EKF keeps track"]
        both = (pf_ok & kf_ok).to_numpy()
        lost = {who: [int(r) for r in d.loc[~ok, "recording"]] for who, ok in (("PF", pf_ok), ("MH-EKF", kf_ok))}
        diff = (d["MH-EKF CEP50 (cm)"] - d["PF CEP50 (cm)"]).to_numpy()
        for key, sel in (("", np.ones_like(both)), ("_tracked", both)):
            t = f[f"kf_minus_pf_cm{key}[{variant}]"] = seeds_interval(diff[sel])
            say = _side(t["lo"], t["hi"], 0.0, BETTER)
            if (interval_side(t["lo"], t["hi"], -EQUAL_CM), interval_side(t["lo"], t["hi"], EQUAL_CM)) == ("above",
                                                                                                          "below"):
                say = "equal within 5 mm"
            elif not key and say.endswith(" better") and lost[say.split()[0]]:
                rec = lost[say.split()[0]]
                say += f" (it lost track on recordings {rec}{'; Fig 6 draws recording 0' if FIG6_RECORDING in rec else ''})"
            f[f"kf_vs_pf{key}[{variant}]"] = say if sel.any() else "no recording"
        f[f"both_keep_track[{variant}]"] = (int(both.sum()), int(both.size))
        f[f"lost_track[{variant}]"] = lost
        runs = d["PF runs"].sum()
        for who, k in (("PF", "pf"), ("MH-EKF", "kf")):
            f[f"{k}_cep50_cm[{variant}]"] = float(d[f"{who} CEP50 (cm)"].median())
            w = d["epochs"] * (d["PF runs"] if who == "PF" else 1)
            f[f"{k}_in_track[{variant}]"] = float(np.average(d[f"{who} in track"], weights=w))
            f[f"{k}_coverage[{variant}]"] = float(np.average(d[f"{who} coverage"], weights=w))
        f[f"pf_cep95_cm[{variant}]"] = float(d["PF CEP95 (cm)"].median())
        f[f"pf_restarted_runs[{variant}]"] = (int(d["PF runs restarted"].sum()), int(runs))
        f[f"pf_restarted_share[{variant}]"] = float(d["PF runs restarted"].sum() / runs)
        f[f"pf_keeps_track[{variant}]"], f[f"kf_keeps_track[{variant}]"] = (bool(k) for k in keeps_track(   # pooled
            f[f"pf_in_track[{variant}]"], runs, d["PF runs restarted"].sum(), f[f"kf_in_track[{variant}]"]))
        for k in ("pf", "kf"):
            f[f"{k}_track_verdict[{variant}]"] = TRACK_WORDS[f[f"{k}_keeps_track[{variant}]"]]

    # --- the particle count (zero noise, exact ΔP, 1× and 4× the particles)
    fl = floor["CEP50, scored epochs (cm)"]
    f["floor_cm"] = {k: float(v) for k, v in fl.items()}
    lo, hi = (float(floor.iloc[-1].get(c, np.nan)) for c in ("drop 95 % low (cm)", "drop 95 % high (cm)"))
    f["floor_particles_step"] = (float(fl.iloc[-2] - fl.iloc[-1]), lo, hi)
    f["particles_verdict"] = particles_verdict(floor)
    f["particles_converged"] = f["particles_verdict"] == "converged"
    if not f["particles_converged"]:        # the PF runs may still change with more particles: no verdict on them
        gate = _gate(f["particles_verdict"])
        f.update({k: gate for k in PF_RUN_VERDICTS if k in f})
        for corner in f["corners"].values():
            corner["asymmetry"] = corner["paper"] = gate
    return f


def particles_verdict(floor: pd.DataFrame) -> str:
    """The particle count's verdict from :func:`~.study.error_floor`'s last row (the CEP50's drop with 4× the
    particles and its interval): "converged" inside ±:data:`PARTICLE_STEP_CM`, "not converged" wholly outside,
    else "undecided"; :data:`NO_INTERVAL` without an interval."""
    lo, hi = (float(floor.iloc[-1].get(c, np.nan)) for c in ("drop 95 % low (cm)", "drop 95 % high (cm)"))
    up, down = interval_side(lo, hi, PARTICLE_STEP_CM), interval_side(lo, hi, -PARTICLE_STEP_CM)
    return (NO_INTERVAL if up == "none" else "converged" if (up, down) == ("below", "above") else
            "not converged" if up == "above" or down == "below" else "undecided")


def _gate(particles: str) -> str:
    """What a verdict of :data:`PF_RUN_VERDICTS` reads while the particle count is ``particles`` (not converged)."""
    return NOT_CONVERGED if particles == "not converged" else NOT_JUDGED


def track_cells(table: pd.DataFrame, particles: str) -> pd.DataFrame:
    """``table`` (rows with a ``variant`` column or index level and the columns ``PF keeps track`` / ``MH-EKF keeps
    track`` of :func:`~.study.filter_scores`) with each of those cells in the words of its verdict
    (:data:`TRACK_WORDS`), and the PF's on Doppler-only rows reading the particle count's gate (:data:`NOT_CONVERGED`
    or :data:`NOT_JUDGED`) while ``particles`` (:func:`particles_verdict`) is not "converged": a cell says what
    the verdict on it says (``pf_track_verdict[Doppler]`` is one of :data:`PF_RUN_VERDICTS`)."""
    out = table.copy()
    variant = out.index.get_level_values("variant") if "variant" in out.index.names else out["variant"]
    for col in ("PF keeps track", "MH-EKF keeps track"):
        out[col] = [TRACK_WORDS[bool(v)] for v in out[col]]
    if particles != "converged":
        out.loc[np.asarray(variant == "Doppler"), "PF keeps track"] = _gate(particles)
    return out


def fig6_table(f: dict) -> pd.DataFrame:
    """The Fig 6 numbers over recordings, one row per quantity: median, mean with its 95 % interval, range, and the
    verdicts (the paper's single-recording CEP50 against the range and against the mean's interval; for the
    along/across ratio, whether the paper's 0.5 lies inside the interval and whether it detects an asymmetry)."""
    rows = []
    for variant in ("Doppler", "Doppler + ranges"):
        for key, q in (("cep50", "snapshot CEP50 (cm)"), ("offset", "shared offset (cm)"),
                       ("spread", "run-to-run CEP50 (cm)")):
            if f"{key}_cm[{variant}]" in f:
                paper = key == "cep50" and variant == "Doppler"
                rows.append((variant, q, f[f"{key}_cm[{variant}]"], f["cep50_verdict"] if paper else "",
                             f["cep50_mean_verdict"] if paper else "", ""))
    rows += [("Doppler", f"along / across, {c}", s, "", s["paper"], s["asymmetry"]) for c, s in f["corners"].items()]
    return pd.DataFrame([{"variant": v, "quantity": q, "recordings": s["n"], "median": s["median"], "mean": s["mean"],
                          "95 % low": s["lo"], "95 % high": s["hi"], "min": s["min"], "max": s["max"],
                          "paper vs range": vr, "paper vs mean": vm, "asymmetry (≠ 1)": va}
                         for v, q, s, vr, vm, va in rows])


def verdict_table(f: dict) -> pd.DataFrame:
    """Every claim of notebook 04 outside Fig 6 (that is :func:`fig6_table`), one row each: ``claim, paper, ours,
    interval, rule, verdict``, read from :func:`facts` (the rules are this module's)."""
    rows = []

    def add(claim, paper, ours, interval, rule, verdict):
        rows.append({"claim": claim, "paper": paper, "ours": ours, "interval": interval, "rule": rule,
                     "verdict": verdict})

    for r in f["readings"]:
        add(f"ΔP_ref of beacons 0 and 7 (ms), {r}", f"{PAPER['dp_ref_ms'][0]:g}, {PAPER['dp_ref_ms'][7]:g} (input)",
            f"{f[f'dp_ms[{r}][0]']:.2f}, {f[f'dp_ms[{r}][7]']:.2f}", f"±{DP_TOLERANCE_MS:g} (printed precision)",
            "both within the printed precision", "reproduces" if r in f["dp_reproduces"] else "does not reproduce")
    for r in f["readings"]:
        k = f"[cubic][{r}]"
        ours, ci = f"{f['frac_pct' + k]:.3g}", interval_text(f["frac_lo_pct" + k], f["frac_hi_pct" + k], ".3g")
        if r == BRUTE_READING:
            ours += f" (conditional); {f['brute_frac_pct']:.3g} (brute force)"
            ci += f" (conditional); {interval_text(f['brute_lo_pct'], f['brute_hi_pct'], '.3g')} (brute force)"
        add(f"fraction of the 6-D space with δ < 15 cm, cubic (%), {r}", f"< {PAPER['fraction_15cm_pct']['cubic']:g}",
            ours, ci, "95 % interval below the bound: agrees; above: disagrees; each estimator that ran, both named "
            "where they differ", f["frac_verdict" + k])
    add("brute force and conditional estimator agree (δ < 15 cm, cubic and lab)", "—",
        f"cubic brute force {f['brute_frac_pct']:.3g} % from {f['brute_draws']:.2g} draws",
        "both 95 % intervals, each layout", "intervals overlap in both layouts",
        "agree" if f["estimators_agree"] else "disagree")
    add("lab fraction over cubic fraction (δ < 15 cm)", f"{f['lab_over_cubic_paper']:.0f}×",
        f"{f['lab_over_cubic']:.0f}×", "—",
        f"same order of magnitude: |log10(ours / paper)| < {SAME_ORDER_LOG10:g}, a factor under "
        f"{10 ** SAME_ORDER_LOG10:.1f} either way (the lab is a reconstruction)",
        "agrees" if f["lab_same_order"] else "differs")
    add("ghost positions on a plane ⟂ V, ghost velocities along V (angles, °)", "observed",
        f"{f['plane_angle_deg']:.0f}, {f['vel_axis_angle_deg']:.0f}", "—", f"both under {GHOST_ANGLE_DEG:g}°",
        "holds" if f["ghost_shape_holds"] else "does not hold")
    for k, v in f["cut_min_cm"].items():
        add(f"Fig 5: minimum of δ along the band, {k} (cm)", "—", f"{v:.1f}", "—",
            f"a ghost when under {GHOST_CUT_CM:g} cm away from the reference (s ≠ 0)", f["cut_verdict"][k])
    t = f["offset_share"]
    add("Fig 6: offset² / (offset² + run-to-run²), mean over recordings", "—", f"{t['mean']:.2f}",
        interval_text(t["lo"], t["hi"], ".2f"), f"interval above {OFFSET_SHARE:g}: offset; below: spread{PF_GATE}",
        f["offset_or_spread"])
    if f["corners"]:
        add("along/across ratio ≈ 0.5 at every corner (Fig 6)", f"{PAPER['along_over_cross']:g}",
            ", ".join(f"{c} {v['mean']:.2f}" for c, v in f["corners"].items()),
            "; ".join(f"{c} {interval_text(v['lo'], v['hi'], '.2f')}" for c, v in f["corners"].items()),
            f"at every corner the mean's interval excludes 1 (asymmetry detected, < 1) and holds 0.5{PF_GATE}",
            f["ratio_verdict"])
    if "corner_dependence" in f:
        t = f["corner_diff"]
        add(f"along/across ratio, {f['corner_pair'][0]} − {f['corner_pair'][1]} per recording", "—", f"{t['mean']:+.2f}",
            interval_text(t["lo"], t["hi"], "+.2f"), f"interval excludes 0: depends on the corner{PF_GATE}",
            f["corner_dependence"])
    keeps = f"≥ {100 * KEEPS_TRACK[0]:.0f} % within 0.5 m"
    for v in ("Doppler", "Doppler + ranges"):
        if f"kf_vs_pf[{v}]" not in f:
            continue
        lost = f[f"lost_track[{v}]"]
        n_both, n_rec = f[f"both_keep_track[{v}]"]
        gated = PF_GATE if f"kf_vs_pf[{v}]" in PF_RUN_VERDICTS else ""
        rule = f"interval inside ±{EQUAL_CM:g} cm: equal; else one that excludes 0 names the better filter{gated}"
        t = f[f"kf_minus_pf_cm[{v}]"]
        add(f"MH-EKF − PF CEP50 on the scored epochs per recording, {v}, all recordings (cm)", "—",
            f"{t['mean']:+.1f}; lost track: PF {len(lost['PF'])}, MH-EKF {len(lost['MH-EKF'])} of {n_rec}",
            interval_text(t["lo"], t["hi"], "+.1f"), rule, f[f"kf_vs_pf[{v}]"])
        t = f[f"kf_minus_pf_cm_tracked[{v}]"]
        add(f"MH-EKF − PF CEP50 on the scored epochs per recording, {v}, recordings where both keep track (cm)",
            "—", f"{t['mean']:+.1f} on {n_both} of {n_rec}" if n_both else f"none of {n_rec}",
            interval_text(t["lo"], t["hi"], "+.1f"), rule, f[f"kf_vs_pf_tracked[{v}]"])
        rs, runs = f[f"pf_restarted_runs[{v}]"]
        for who, k, what, extra in (("PF", "pf", ", runs restarted", f", {rs} of {runs}"), ("MH-EKF", "kf", "", "")):
            add(f"{who} keeps track, {v}: epochs within 0.5 m{what}, recordings where it lost track", "—",
                f"{100 * f[f'{k}_in_track[{v}]']:.1f} %{extra}, {lost[who] or 'none'}", "—",
                keeps + (f" and ≤ {100 * KEEPS_TRACK[1]:.0f} % restarted" if who == "PF" else "")
                + ", pooled (per recording: the scores table)"
                + (PF_GATE if f"{k}_track_verdict[{v}]" in PF_RUN_VERDICTS else ""), f[f"{k}_track_verdict[{v}]"])
    drop, lo, hi = f["floor_particles_step"]
    add("particle count: drop of the scored-epoch CEP50 with 4× the particles, zero noise and exact ΔP (cm)", "—",
        f"{drop:.1f}", interval_text(lo, hi, ".1f"), f"interval inside ±{PARTICLE_STEP_CM:g} cm: converged; wholly "
        "outside: not converged (the CEP50 is then no floor, and no verdict is given on the Doppler-only PF runs)",
        f["particles_verdict"])
    return pd.DataFrame(rows)
