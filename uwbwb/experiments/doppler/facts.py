"""Notebook 04's results as numbers and computed verdicts (paper 003).

:class:`Results` holds what the notebook computed; :func:`facts` turns it into a flat
``dict`` of numbers and verdict labels, each label decided by a stated rule on an
interval (never fixed text). :func:`verdict_table` and :func:`fig6_table` lay them out as the
notebook's verdict tables and :mod:`.headlines` reads the summary rows from them, so a test can feed
numbers on either side of each threshold and see the verdict flip.

Rules
-----
* ΔP_ref (a deterministic number per reading): the paper prints one decimal in ms, so a
  value *reproduces the printed number* when it lies within ±0.05 ms of it.
* Fraction under 15 cm, cubic (the paper: "less than 0.0005 %"): 95 % interval entirely
  below the bound → ``"below"`` (agrees); entirely above → ``"above"`` (disagrees);
  otherwise ``"straddles"`` (undecided at this sample size).
* Fig 6 CEP50 (paper ≈ 25 cm): the paper's value comes from *one* recording, so it is judged
  against the spread of single recordings: inside [min, max] over our n recordings →
  ``"consistent"``; else ``"above"`` / ``"below"``; fewer than 3 recordings → ``"no interval"``.
  The bootstrap 95 % interval of the *median* recording is a separate statement
  (``cep50_median_verdict``, same rule).
* The along/across ratio per corner (paper ≈ 0.5: the cloud is half as long along the direction
  of travel as across it) is a claim of asymmetry, so the bootstrap 95 % interval of the median
  recording's ratio (a min–max range over recordings cannot reject anything) gets two verdicts, each
  of which the interval can reject: *asymmetry (≠ 1)* — the interval excludes 1 → ``"detected (< 1)"``
  or ``"detected, the other way (> 1)"``, holds 1 → ``"not detected"``; *the paper's 0.5* — ``"inside"``
  the interval, or ``"outside (interval above 0.5)"`` / ``"outside (interval below 0.5)"``; with no
  interval, both ``"no interval"``. The combined label (``"no asymmetry detected"``, ``"asymmetric,
  consistent with 0.5"``, ...) is kept for the summary; the ratio is *reproduced* when at every corner
  asymmetry (< 1) is detected and 0.5 is inside.
* Offset or spread: per recording ``offset² / (offset² + spread²)``; the bootstrap interval
  of its median entirely above 0.5 → ``"offset"``, below → ``"spread"``, else ``"comparable"``.
* Corner dependence of the ratio: per recording, ratio at the first corner minus at the
  second; its median's bootstrap interval excludes 0 → ``"depends"``, else ``"same"``.
* MH-EKF vs PF: the bootstrap interval of the median per-recording difference of CEP50 inside ±0.5 cm →
  ``"equal within 5 mm"`` (equivalence); else that interval excludes 0 → one is better; else ``"no significant difference"``; with no
  interval (fewer than 3 recordings) ``"no interval"``, and ``"no recording"`` when none qualifies. Decided
  twice: on the recordings where both filters keep track (``kf_vs_pf_tracked``, the statement about
  accuracy), and on all recordings with the count of lost tracks beside it (``kf_vs_pf``), since a
  median difference counts a lost recording like any other.
* Coverage: share of scored epochs whose truth lies in the filter's own 95 % region
  (horizontal, χ²(2) on its position covariance).
* A filter *keeps track* on a recording by :data:`~.scoring.KEEPS_TRACK` (:func:`~.scoring.keeps_track`:
  at least 95 % of its scored epochs within 0.5 m; the PF also at most 5 % of its runs restarted; the
  MH-EKF does not restart), per recording and per filter, and pooled over recordings; the recordings
  where a filter lost track are listed (``lost_track``).
* What the CEP50 is made of: the condition whose removal lowers the scored-epoch CEP50 most, in steps
  noise → model error (exact eq-1 ΔP) → particle count (4×). The particle count has *converged* when
  the 95 % interval of the drop from 4× the particles (bootstrap over the runs of both rows,
  :func:`~.study.error_floor`) lies inside ±1 cm; *not converged* when it lies wholly outside (4× the
  particles still moves the CEP50 by more than 1 cm); else *undecided*. Only a converged CEP50 is a floor
  attributable to the information in Doppler-only data under the motion prior, and only then do the
  Fig 6 CEP50 verdicts judge its value against the paper's (else :data:`NOT_CONVERGED`, or
  :data:`NOT_JUDGED` when undecided or without an interval: no agreement is claimed). The step is measured on the floor run (the
  first recording, no noise, exact ΔP), not on Fig 6's noisy snapshots: a proxy for "more particles
  would still change the answer", stated as such.
* Fig 5: a cut's minimum is "the reference itself" when it lies at s = 0 with δ = 0 (the cut through
  V_ref passes through the reference); as the minimum over the whole cut, that cut's own ghosts (a
  second minimum elsewhere along it) are not judged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...filters import doppler as fd
from ...metrics import interval_side
from .scoring import KEEPS_TRACK, bootstrap_median, keeps_track
from .study import PAPER, READINGS

__all__ = ["Results", "facts", "fig6_table", "verdict_table", "DP_TOLERANCE_MS", "GHOST_ANGLE_DEG", "OFFSET_SHARE", "EQUAL_CM",
           "PARTICLE_STEP_CM", "NOT_CONVERGED", "NOT_JUDGED"]

#: Half of the last printed digit of the paper's ΔP_ref (ms).
DP_TOLERANCE_MS = 0.05
#: Largest angle (°) between the ghost plane's normal (and the velocity ghosts' axis) and V_ref
#: for the paper's two observations to count as holding.
GHOST_ANGLE_DEG = 20.0
#: Share offset² / (offset² + spread²) that the median's interval must exclude to name one part the larger.
OFFSET_SHARE = 0.5
#: Half-width (cm) of the band the interval of the median MH-EKF − PF must lie inside for the filters to count as
#: equal in practice (an equivalence rule: a small median with a wide interval is not equality).
EQUAL_CM = 0.5
#: Half-width (cm) of the band that the interval of the CEP50's drop from 4× the particles must lie inside for the
#: particle count to count as converged (and wholly outside for "not converged").
PARTICLE_STEP_CM = 1.0
#: A Fig 5 minimum closer than this to s = 0 (m along the cut) with δ under REFERENCE_DELTA_CM is the reference
#: point itself (δ = 0 there by construction, on the cut through V_ref only).
REFERENCE_S_M = 0.01
REFERENCE_DELTA_CM = 1e-3
#: The Fig 6 CEP50 verdicts when the particle count has not converged (no agreement is claimed).
NOT_CONVERGED = "not converged"
#: The Fig 6 CEP50 verdicts when the convergence test is undecided or has no interval.
NOT_JUDGED = "not judged (convergence not shown)"
#: Labels of the along/across interval against no asymmetry (1) and against the paper's value.
ASYMMETRY = {"contains": "not detected", "below": "detected (< 1)", "above": "detected, the other way (> 1)",
             "none": "no interval"}
#: Threshold (cm) under which a cut's minimum counts as a ghost (Fig 5 uses 6 cm; Fig 3(d) 8 cm).
GHOST_CUT_CM = 8.0


@dataclass(frozen=True)
class Results:
    """Everything notebook 04 computed that its verdict tables and summary read.

    Attributes
    ----------
    fast
        The notebook's FAST flag (every number then is a smoke test).
    ref_table
        :func:`~.study.reference_table`.
    readings
        :func:`~.study.period_readings` (fraction under 15 cm per layout and period reading).
    at15
        ``{layout: {"conditional" | "brute force" | "ranges": FractionEstimate}}`` at 15 cm.
    fig_counts
        ``{layout: {threshold_cm: (distinct samples, distinct positions, FractionEstimate)}}``.
    geometry, fisher
        :func:`~.ghosts.ghost_geometry` (cubic, 8 cm), :func:`~.ghosts.fisher_analysis`.
    cut_minima
        ``{curve: (s at minimum (m), δ at minimum (cm))}`` of Fig 5.
    snap, scores, floor
        :func:`~.study.snapshot_table`, :func:`~.study.filter_scores`, :func:`~.study.error_floor`.
    peak_traced_mib
        Measured peak (tracemalloc) of the samplers, MiB (NaN: not measured).
    seed
        Seed of the bootstrap intervals.
    temper_ess
        The PF's :attr:`~uwbwb.filters.doppler.DopplerPf.temper_ess` (default: the filter's).
    filter_settings
        :func:`~.study.filter_settings` (what each filter is told; empty: not stated).
    """

    fast: bool
    ref_table: pd.DataFrame
    readings: pd.DataFrame
    at15: dict
    fig_counts: dict
    geometry: dict
    fisher: dict
    cut_minima: dict
    snap: pd.DataFrame
    scores: pd.DataFrame
    floor: pd.DataFrame
    peak_traced_mib: float = np.nan
    seed: int = 0
    temper_ess: float = fd.DopplerPf.temper_ess
    filter_settings: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)


def _interval_verdict(lo: float, hi: float, value: float) -> str:
    return {"contains": "consistent", "above": "above", "below": "below"}.get(interval_side(lo, hi, value),
                                                                               "no interval")


def _ratio_verdict(lo: float, hi: float, paper: float) -> str:
    """The along/across ratio's median interval against no asymmetry (1) and the paper's value (module docstring)."""
    side = interval_side(lo, hi, 1.0)
    if side != "below":
        return {"none": "no interval", "contains": "no asymmetry detected",
                "above": "asymmetric the other way (longer along than across)"}[side]
    where = _interval_verdict(lo, hi, paper)
    return f"asymmetric, consistent with {paper:g}" if where == "consistent" else f"asymmetric, {where} {paper:g}"


def _paper_inside(lo: float, hi: float, paper: float) -> str:
    """Whether the paper's value lies inside the interval (module docstring)."""
    return {"contains": "inside", "above": f"outside (interval above {paper:g})",
            "below": f"outside (interval below {paper:g})"}.get(interval_side(lo, hi, paper), "no interval")


def _particles_verdict(lo: float, hi: float) -> str:
    """The drop of the CEP50 from 4× the particles: inside ±PARTICLE_STEP_CM, wholly outside, or neither."""
    up, down = interval_side(lo, hi, PARTICLE_STEP_CM), interval_side(lo, hi, -PARTICLE_STEP_CM)
    if up == "none":
        return "no interval"
    if up == "below" and down == "above":
        return "converged"
    return "not converged" if up == "above" or down == "below" else "undecided"


def _bound_verdict(lo: float, hi: float, bound: float) -> str:
    side = interval_side(lo, hi, bound)
    return {"contains": "straddles", "none": "no interval"}.get(side, side)


def facts(res: Results) -> dict:
    """Numbers and verdicts of notebook 04 (see the module docstring for every rule)."""
    f: dict = {"fast": bool(res.fast), "mode": "FAST" if res.fast else "full"}
    rng = np.random.default_rng(res.seed)

    # --- ΔP_ref under both readings
    f["readings"] = list(READINGS)
    for r in READINGS:
        for b in (0, 7):
            v = float(res.ref_table[f"ΔP_ref (ms), {r}"].iloc[b])
            f[f"dp_ms[{r}][{b}]"] = v
            f[f"dp_match[{r}][{b}]"] = bool(abs(v - PAPER["dp_ref_ms"][b]) <= DP_TOLERANCE_MS + 1e-12)
        f[f"P7_ms[{r}]"] = float(res.ref_table[f"P (ms), {r}"].iloc[7])
        f[f"dp_reproduces[{r}]"] = f[f"dp_match[{r}][0]"] and f[f"dp_match[{r}][7]"]

    # --- fraction under 15 cm under both readings
    for _, row in res.readings.iterrows():
        key = f"[{row['layout']}][{row['reading']}]"
        f[f"frac_pct{key}"] = float(row["fraction (%)"])
        f[f"frac_lo_pct{key}"] = float(row["95 % low (%)"])
        f[f"frac_hi_pct{key}"] = float(row["95 % high (%)"])
        if row["layout"] == "cubic":
            f[f"frac_verdict{key}"] = _bound_verdict(row["95 % low (%)"], row["95 % high (%)"],
                                                     PAPER["fraction_15cm_pct"]["cubic"])
    f["frac_bound_pct"] = PAPER["fraction_15cm_pct"]["cubic"]
    f["frac_reproduces"] = [r for r in READINGS if f.get(f"frac_verdict[cubic][{r}]") == "below"]
    f["dp_reproduces"] = [r for r in READINGS if f[f"dp_reproduces[{r}]"]]

    # --- estimators and the lab
    c, lab = res.at15["cubic"], res.at15["lab"]
    f["brute_frac_pct"] = 100 * c["brute force"].fraction
    f["brute_draws"] = int(c["brute force"].n_draws)
    f["estimators_agree"] = bool(all(
        e["conditional"].ci_low <= e["brute force"].ci_high and e["brute force"].ci_low <= e["conditional"].ci_high
        for e in res.at15.values()))
    f["lab_frac_pct"] = 100 * lab["conditional"].fraction
    f["lab_paper_pct"] = PAPER["fraction_15cm_pct"]["lab"]
    f["lab_over_cubic"] = float(lab["conditional"].fraction / c["conditional"].fraction)
    f["lab_over_cubic_paper"] = PAPER["fraction_15cm_pct"]["lab"] / PAPER["fraction_15cm_pct"]["cubic"]
    f["lab_same_order"] = bool(abs(np.log10(f["lab_over_cubic"] / f["lab_over_cubic_paper"])) < 0.5)
    f["ranges_frac_pct"] = {k: 100 * v["ranges"].fraction for k, v in res.at15.items()}

    # --- Figs 3-4
    f["fig_counts"] = {layout: {t: (int(n), int(p)) for t, (n, p, _) in d.items()} for layout, d in res.fig_counts.items()}
    f["fig_empty_panels"] = [(layout, t) for layout, d in res.fig_counts.items() for t, (n, _, _) in d.items() if n == 0]

    # --- ghost geometry, information matrix, cuts
    g = res.geometry
    f["plane_angle_deg"] = float(g["angle(position plane normal, V) (°)"])
    f["vel_axis_angle_deg"] = float(g["angle(velocity main axis, V) (°)"])
    f["plane_ratio"] = float(g["position plane normal: spread ratio"])
    f["ghost_shape_holds"] = bool(f["plane_angle_deg"] < GHOST_ANGLE_DEG and f["vel_axis_angle_deg"] < GHOST_ANGLE_DEG)
    weak = res.fisher["weak"][0]
    f["weak_pos_angle_deg"] = float(weak["angle(position part, V) (°)"])
    f["weak_vel_angle_deg"] = float(weak["angle(velocity part, ±V) (°)"])
    f["cut_min_cm"] = {k: float(v[1]) for k, v in res.cut_minima.items()}
    # a minimum at s = 0 on the cut through V_ref is the reference itself (δ = 0 by construction), not a ghost
    f["cut_at_reference"] = {k: bool(abs(v[0]) < REFERENCE_S_M and v[1] < REFERENCE_DELTA_CM)
                             for k, v in res.cut_minima.items()}
    f["cut_is_ghost"] = {k: bool(v[1] < GHOST_CUT_CM and not f["cut_at_reference"][k])
                         for k, v in res.cut_minima.items()}
    f["ghost_cut_cm"] = GHOST_CUT_CM

    # --- Fig 6 over recordings
    snap = res.snap
    per_rec = snap.groupby(["variant", "recording"])[["CEP50 (cm)", "offset (cm)", "run-to-run CEP50 (cm)"]].mean()
    for variant in ("Doppler", "Doppler + ranges"):
        if variant not in per_rec.index.get_level_values(0):
            continue
        d = per_rec.loc[variant]
        for q, key in (("CEP50 (cm)", "cep50"), ("offset (cm)", "offset"), ("run-to-run CEP50 (cm)", "spread")):
            med, lo, hi = bootstrap_median(d[q].to_numpy(), rng=rng)
            f[f"{key}_cm[{variant}]"] = (med, lo, hi, float(d[q].min()), float(d[q].max()))
    f["n_recordings"] = int(snap["recording"].nunique())
    f["pf_runs_first"] = int(snap.loc[snap["recording"] == 0, "runs"].iloc[0])
    med, lo, hi, mn, mx = f["cep50_cm[Doppler]"]
    n_rec = f["n_recordings"]
    # one recording (the paper's) is judged against the spread of single recordings, the median separately
    f["cep50_verdict"] = _interval_verdict(mn, mx, PAPER["cep50_cm"]) if n_rec >= 3 else "no interval"
    f["cep50_median_verdict"] = _interval_verdict(lo, hi, PAPER["cep50_cm"])
    d = snap[snap["variant"] == "Doppler"].groupby("recording")[["offset (cm)", "run-to-run CEP50 (cm)"]].mean()
    share = d["offset (cm)"] ** 2 / (d["offset (cm)"] ** 2 + d["run-to-run CEP50 (cm)"] ** 2)
    m, lo, hi = bootstrap_median(share.to_numpy(), rng=rng)
    f["offset_share"] = (m, lo, hi)
    f["offset_or_spread"] = {"above": "offset", "below": "spread", "contains": "comparable"}.get(
        interval_side(lo, hi, OFFSET_SHARE), "no interval")
    f["corners"] = {}
    # per corner: (median, 95 % low, high, min, max, combined label, asymmetry (≠ 1), the paper's 0.5 inside)
    for corner, d in snap[snap["variant"] == "Doppler"].groupby("corner", sort=False):
        m, lo, hi = bootstrap_median(d["along / across"].to_numpy(), rng=rng)
        mn, mx = float(d["along / across"].min()), float(d["along / across"].max())
        f["corners"][corner] = (m, lo, hi, mn, mx, _ratio_verdict(lo, hi, PAPER["along_over_cross"]),
                                ASYMMETRY[interval_side(lo, hi, 1.0)], _paper_inside(lo, hi, PAPER["along_over_cross"]))
    f["ratio_reproduced"] = bool(f["corners"]) and all(v[6] == ASYMMETRY["below"] and v[7] == "inside"
                                                       for v in f["corners"].values())
    verdicts = {v[5] for v in f["corners"].values()}
    f["ratio_verdict"] = ("no interval" if not verdicts or "no interval" in verdicts else
                          "reproduced" if f["ratio_reproduced"] else "not reproduced")
    # paired per recording: first corner minus second corner
    piv = snap[snap["variant"] == "Doppler"].pivot_table(index="recording", columns="corner", values="along / across")
    names = list(f["corners"])
    if len(names) == 2:
        diff = (piv[names[0]] - piv[names[1]]).to_numpy()
        m, lo, hi = bootstrap_median(diff, rng=rng)
        allv = piv[names].to_numpy().ravel()
        f["corner_diff"] = (m, lo, hi)
        f["corner_pair"] = tuple(names)
        f["ratio_all"] = (float(np.median(allv)), float(np.min(allv)), float(np.max(allv)))
        f["corner_dependence"] = {"contains": "same", "none": "no interval"}.get(interval_side(lo, hi), "depends")

    # --- filters: accuracy, restarts, coverage
    sc = res.scores
    rng_tracked = np.random.default_rng([res.seed, 1])      # its own stream: the other intervals draw as before
    for variant, d in sc.groupby("variant"):
        pf_ok, kf_ok = keeps_track(d)
        both = (pf_ok & kf_ok).to_numpy()
        diff = (d["MH-EKF CEP50 (cm)"] - d["PF CEP50 (cm)"]).to_numpy()
        for key, sel, r in (("", np.ones_like(both), rng), ("_tracked", both, rng_tracked)):
            m, lo, hi = bootstrap_median(diff[sel], rng=r)
            f[f"kf_minus_pf_cm{key}[{variant}]"] = (m, lo, hi)
            side = interval_side(lo, hi)
            f[f"kf_vs_pf{key}[{variant}]"] = (
                "no recording" if not sel.any() else "no interval" if side == "none" else
                "equal within 5 mm" if (interval_side(lo, hi, -EQUAL_CM), interval_side(lo, hi, EQUAL_CM)) == (
                    "above", "below") else                # the interval inside ±EQUAL_CM: an equivalence rule
                {"above": "PF better", "below": "MH-EKF better", "contains": "no significant difference"}[side])
        f[f"both_keep_track[{variant}]"] = (int(both.sum()), int(both.size))
        runs = d["PF runs"].sum()
        f[f"pf_cep50_cm[{variant}]"] = float(d["PF CEP50 (cm)"].median())
        f[f"kf_cep50_cm[{variant}]"] = float(d["MH-EKF CEP50 (cm)"].median())
        f[f"pf_cep95_cm[{variant}]"] = float(d["PF CEP95 (cm)"].median())
        f[f"kf_cep95_cm[{variant}]"] = float(d["MH-EKF CEP95 (cm)"].median())
        f[f"pf_restarted_share[{variant}]"] = float(d["PF runs restarted"].sum() / runs)
        f[f"pf_restarted_runs[{variant}]"] = (int(d["PF runs restarted"].sum()), int(runs))
        f[f"pf_in_track[{variant}]"] = float(np.average(d["PF in track"], weights=d["PF runs"] * d["epochs"]))
        f[f"kf_in_track[{variant}]"] = float(np.average(d["MH-EKF in track"], weights=d["epochs"]))
        f[f"pf_coverage[{variant}]"] = float(np.average(d["PF coverage"], weights=d["PF runs"] * d["epochs"]))
        f[f"kf_coverage[{variant}]"] = float(np.average(d["MH-EKF coverage"], weights=d["epochs"]))
        f[f"pf_tempered[{variant}]"] = float(d["PF tempered updates"].mean())
        f[f"pf_keeps_track[{variant}]"] = bool(f[f"pf_in_track[{variant}]"] >= KEEPS_TRACK[0]
                                              and f[f"pf_restarted_share[{variant}]"] <= KEEPS_TRACK[1])
        f[f"kf_keeps_track[{variant}]"] = bool(f[f"kf_in_track[{variant}]"] >= KEEPS_TRACK[0])
        f[f"lost_track[{variant}]"] = {who: [int(r) for r in d.loc[~ok, "recording"]]
                                       for who, ok in (("PF", pf_ok), ("MH-EKF", kf_ok))}

    # --- the zero-noise floor
    fl = res.floor["CEP50, scored epochs (cm)"]
    steps = {"timing noise, misses and spurious chirps": fl.iloc[0] - fl.iloc[1],
             "reading a period-averaged ΔP as one state (model error)": fl.iloc[1] - fl.iloc[2],
             "the particle count": fl.iloc[2] - fl.iloc[3]}
    f["floor_cm"] = {k: float(v) for k, v in fl.items()}
    f["floor_steps_cm"] = {k: float(v) for k, v in steps.items()}
    f["floor_left_cm"] = float(fl.iloc[3])
    f["floor_main_cause"] = max(steps, key=steps.get)
    f["floor_left_dominates"] = bool(fl.iloc[3] > max(steps.values()))
    f["floor_particles_step_cm"] = float(steps["the particle count"])
    last = res.floor.iloc[3]
    f["floor_particles_step"] = (float(steps["the particle count"]), float(last.get("drop 95 % low (cm)", np.nan)),
                                 float(last.get("drop 95 % high (cm)", np.nan)))
    f["particles_verdict"] = _particles_verdict(*f["floor_particles_step"][1:])
    f["particles_converged"] = f["particles_verdict"] == "converged"
    if not f["particles_converged"]:        # the CEP50 may still change with more particles: no verdict on its value
        f["cep50_verdict"] = f["cep50_median_verdict"] = (
            NOT_CONVERGED if f["particles_verdict"] == "not converged" else NOT_JUDGED)
    f["n_particles"] = int(res.floor["particles"].iloc[0]) if "particles" in res.floor else None
    f["temper_ess"] = float(res.temper_ess)
    f["priors"] = dict(res.filter_settings) or None

    f["peak_traced_mib"] = float(res.peak_traced_mib)
    return f


def fig6_table(f: dict) -> pd.DataFrame:
    """The Fig 6 numbers and verdicts (same bootstrap draws), one row per quantity.

    Columns: median over recordings, its bootstrap 95 % interval, the range over recordings,
    the verdict of the paper's single-recording value against the range, that of the median's
    interval (``""`` where the paper gives no value; for the along/across ratio: whether the paper's
    0.5 lies inside the interval), and, for the ratio, whether the interval detects an asymmetry (≠ 1).
    """
    rows = []
    for variant in ("Doppler", "Doppler + ranges"):
        for key, q in (("cep50", "snapshot CEP50 (cm)"), ("offset", "shared offset (cm)"),
                       ("spread", "run-to-run CEP50 (cm)")):
            if f"{key}_cm[{variant}]" not in f:
                continue
            med, lo, hi, mn, mx = f[f"{key}_cm[{variant}]"]
            paper = key == "cep50" and variant == "Doppler"
            rows.append({"variant": variant, "quantity": q, "recordings": f["n_recordings"], "median": med,
                         "95 % low": lo, "95 % high": hi, "min": mn, "max": mx,
                         "paper vs range": f["cep50_verdict"] if paper else "",
                         "paper vs median": f["cep50_median_verdict"] if paper else "", "asymmetry (≠ 1)": ""})
    for corner, v in f["corners"].items():
        rows.append({"variant": "Doppler", "quantity": f"along / across, {corner}", "recordings": f["n_recordings"],
                     "median": v[0], "95 % low": v[1], "95 % high": v[2], "min": v[3], "max": v[4],
                     "paper vs range": "", "paper vs median": v[7], "asymmetry (≠ 1)": v[6]})
    return pd.DataFrame(rows)


def _ci(lo: float, hi: float, fmt: str) -> str:
    return f"[{lo:{fmt}}, {hi:{fmt}}]" if np.isfinite(lo) and np.isfinite(hi) else "—"


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
            "both within the printed precision",
            "reproduces" if r in f["dp_reproduces"] else "does not reproduce")
    for r in f["readings"]:
        k = f"[cubic][{r}]"
        add(f"fraction of the 6-D space with δ < 15 cm, cubic (%), {r}", f"< {f['frac_bound_pct']:g}",
            f"{f['frac_pct' + k]:.3g}", _ci(f["frac_lo_pct" + k], f["frac_hi_pct" + k], ".3g"),
            "95 % interval below the bound: agrees; above: disagrees", {
                "below": "agrees", "above": "disagrees", "straddles": "undecided",
                "no interval": "undecided"}[f["frac_verdict" + k]])
    add("brute force and conditional estimator agree (δ < 15 cm, cubic and lab)", "—",
        f"cubic brute force {f['brute_frac_pct']:.3g} % from {f['brute_draws']:.2g} draws",
        "both 95 % intervals, each layout", "intervals overlap in both layouts",
        "agree" if f["estimators_agree"] else "disagree")
    add("lab fraction over cubic fraction (δ < 15 cm)", f"{f['lab_over_cubic_paper']:.0f}×",
        f"{f['lab_over_cubic']:.0f}×", "—", "same order of magnitude (the lab is a reconstruction)",
        "agrees" if f["lab_same_order"] else "differs")
    add("ghost positions on a plane ⟂ V, ghost velocities along V (angles, °)", "observed",
        f"{f['plane_angle_deg']:.0f}, {f['vel_axis_angle_deg']:.0f}", "—", f"both under {GHOST_ANGLE_DEG:g}°",
        "holds" if f["ghost_shape_holds"] else "does not hold")
    for k, v in f["cut_min_cm"].items():
        add(f"Fig 5: minimum of δ along the band, {k} (cm)", "—", f"{v:.1f}", "—",
            f"a ghost when under {f['ghost_cut_cm']:g} cm away from the reference (s ≠ 0)",
            "the reference itself" if f["cut_at_reference"][k] else "a ghost" if f["cut_is_ghost"][k] else "not a ghost")
    share, slo, shi = f["offset_share"]
    add("Fig 6: offset² / (offset² + run-to-run²), median recording", "—", f"{share:.2f}", _ci(slo, shi, ".2f"),
        f"interval above {OFFSET_SHARE:g}: offset; below: spread", f["offset_or_spread"])
    if f["corners"]:
        add("along/across ratio ≈ 0.5 at every corner (Fig 6)", f"{PAPER['along_over_cross']:g}",
            ", ".join(f"{c} {v[0]:.2f}" for c, v in f["corners"].items()), "; ".join(
                f"{c} {_ci(v[1], v[2], '.2f')}" for c, v in f["corners"].items()),
            "at every corner the median's interval excludes 1 (asymmetry detected, < 1) and holds 0.5",
            f["ratio_verdict"])
    if "corner_dependence" in f:
        m, lo, hi = f["corner_diff"]
        add(f"along/across ratio, {f['corner_pair'][0]} − {f['corner_pair'][1]} per recording", "—", f"{m:+.2f}",
            _ci(lo, hi, "+.2f"), "interval excludes 0: depends on the corner",
            {"same": "not significant"}.get(f["corner_dependence"], f["corner_dependence"]))
    for v in ("Doppler", "Doppler + ranges"):
        if f"kf_vs_pf[{v}]" not in f:
            continue
        lost = f[f"lost_track[{v}]"]
        n_both, n_rec = f[f"both_keep_track[{v}]"]
        rule = f"interval inside ±{EQUAL_CM:g} cm: equal; else one that excludes 0 names the better filter"
        m, lo, hi = f[f"kf_minus_pf_cm[{v}]"]
        add(f"MH-EKF − PF CEP50 on the scored epochs per recording, {v}, all recordings (cm)", "—",
            f"{m:+.1f}; lost track: PF {len(lost['PF'])}, MH-EKF {len(lost['MH-EKF'])} of {n_rec}",
            _ci(lo, hi, "+.1f"), rule, f[f"kf_vs_pf[{v}]"])
        m, lo, hi = f[f"kf_minus_pf_cm_tracked[{v}]"]
        add(f"MH-EKF − PF CEP50 on the scored epochs per recording, {v}, recordings where both keep track (cm)",
            "—", f"{m:+.1f} on {n_both} of {n_rec}" if n_both else f"none of {n_rec}", _ci(lo, hi, "+.1f"), rule,
            f[f"kf_vs_pf_tracked[{v}]"])
        rs, runs = f[f"pf_restarted_runs[{v}]"]
        keeps = f"≥ {100 * KEEPS_TRACK[0]:.0f} % within 0.5 m"
        add(f"PF keeps track, {v}: epochs within 0.5 m, runs restarted, recordings where it lost track", "—",
            f"{100 * f[f'pf_in_track[{v}]']:.1f} %, {rs} of {runs}, {lost['PF'] or 'none'}", "—",
            f"{keeps} and ≤ {100 * KEEPS_TRACK[1]:.0f} % restarted, pooled (per recording: the scores table)",
            "keeps track" if f[f"pf_keeps_track[{v}]"] else "does not keep track")
        add(f"MH-EKF keeps track, {v}: epochs within 0.5 m, recordings where it lost track", "—",
            f"{100 * f[f'kf_in_track[{v}]']:.1f} %, {lost['MH-EKF'] or 'none'}", "—",
            f"{keeps}, pooled (per recording: the scores table)",
            "keeps track" if f[f"kf_keeps_track[{v}]"] else "does not keep track")
    drop, lo, hi = f["floor_particles_step"]
    add("particle count: drop of the scored-epoch CEP50 with 4× the particles, zero noise and exact ΔP (cm)", "—",
        f"{drop:.1f}", _ci(lo, hi, ".1f"), f"interval inside ±{PARTICLE_STEP_CM:g} cm: converged; wholly outside: "
        "not converged (the CEP50 is then no floor and is not judged against the paper's)", f["particles_verdict"])
    return pd.DataFrame(rows)
