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
  *share kept* is ``log(ratio_case) / log(ratio_matched)`` (1: all of it, 0: none, < 0: reversed),
  both ratios over the same seeds (the case's).
* A row **diverged** in a mismatch case when its dynamic RMSE or its max error in the recovery
  after the outage (mean over the case's seeds) exceeds :data:`DIVERGED_FACTOR` × its matched
  value on the same seeds: a failure, not a degradation, and named as such.
* A tuning-grid entry **blew up** when its RMSE exceeds 10× the row's lowest on the grid
  (:func:`~.ablation.choose_knobs`): the filter fails at that knob.
* Eq. 4 **can fire** in the matched world when the smallest excess that trips it anywhere on the
  ablation's path (:func:`~.ablation.eq4_thresholds`) lies below the largest excess the matched
  simulator draws.
"""

from __future__ import annotations

import math

import numpy as np

from .ablation import (EKF_TDOA_GATE, LADDER, RECOVERY_MAX_M, RECOVERY_S, AblationResult, choose_knobs, eq4_path, eq4_thresholds,
                       pair_rmse)
from .scoring import HOLD_S

__all__ = ["DIVERGED_FACTOR", "verdict", "facts", "ingredient_sentence", "outage_sentence", "survival_sentence",
           "diverged_sentence", "matched_failure_sentence", "tuning_sentence", "eq4_sentence", "summary_markdown"]

#: A mismatch row whose dynamic RMSE or recovery max exceeds this many times its matched value diverged.
DIVERGED_FACTOR = 10.0

#: The rows tight coupling's outage advantage is measured against.
_VERSUS = ("loose + gate", "EKF + gate", EKF_TDOA_GATE)
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


def _ratio(res: AblationResult, a: str, b: str, metric: str, case: str = "matched", seeds=None) -> dict:
    r = res.ratio(a, b, metric, case, seeds=seeds)
    return {**r, "verdict": verdict(r["lo"], r["hi"])}


def _gated(rows) -> list:
    return [r for r in rows if r.endswith("+ gate") and not r.startswith("LS")]


def _matched_failures(res: AblationResult) -> dict:
    """Gated rows that did not re-acquire (:func:`~.ablation.reacquisition_s`) within the recovery
    time on some matched seed: row → per-seed re-acquisition times (s)."""
    rec = res.case("matched")["reacq_s"].unstack("method")
    lim = res.config.recovery_s
    return {str(r): {int(k): float(v) for k, v in rec[r].items()} for r in _gated(rec.columns)
            if not (rec[r] <= lim).all()}


def _return_errors(res: AblationResult, limit_m: float) -> dict:
    """Gated rows whose max error in the recovery window reaches ``limit_m`` on some matched seed
    (the earlier reading of the re-acquisition check, which also counts the drift UWB finds on its
    return): row → {seed: max error, m}."""
    rec = res.case("matched")["recovery_max"].unstack("method")
    return {str(r): {int(k): float(v) for k, v in rec[r].items() if not v < limit_m} for r in _gated(rec.columns)
            if not (rec[r] < limit_m).all()}


def _slowest_reacquisition(res: AblationResult) -> dict:
    """The slowest matched re-acquisition among the gated rows: row, seed, seconds (empty if none)."""
    rec = res.case("matched")["reacq_s"].unstack("method")[_gated(res.case("matched").index.unique("method"))]
    st = rec.stack()
    if st.empty or not np.isfinite(st.to_numpy(float)).any():
        return {}
    (seed, row), v = st.idxmax(), float(st.max())
    return {"row": str(row), "seed": int(seed), "s": v}


def _diverged(res: AblationResult, case: str) -> list[dict]:
    """Rows of ``case`` whose dyn RMSE or recovery max exceeds DIVERGED_FACTOR × matched (same seeds)."""
    c, m = res.case(case), res.case("matched")
    out = []
    for row in c.index.get_level_values("method").unique():
        if row not in m.index.get_level_values("method"):
            continue
        cs = c.xs(row, level="method")
        ms = m.xs(row, level="method").reindex(cs.index)
        for metric in ("dyn_rmse", "recovery_max"):
            v, v0 = float(cs[metric].mean()), float(ms[metric].mean())
            if np.isfinite(v) and np.isfinite(v0) and v > DIVERGED_FACTOR * v0:
                out.append({"row": str(row), "metric": metric, "value": v, "matched": v0})
    return out


def facts(res: AblationResult, *, outage_s: float | None = None) -> dict:
    """Numbers and rule outcomes behind every sentence of notebook 05's ablation.

    Returns a dict with ``mode`` ("FAST" or "full"), ``seeds``, ``outage_s``, ``ladder``
    (step → metric → ratio/lo/hi/n/verdict), ``outage`` (versus "loose + gate" and "EKF + gate":
    the matched ratio of max outage errors and its verdict), ``survival`` (case → versus →
    ratio/lo/hi/verdict/share), ``winners`` (case → metric → best gated row) and ``eq4``
    (counts per case, and ``eq4_geometry``: the smallest excess that fires eq. 4 on the path, its
    pair and side, and the matched world's excess range), ``diverged`` (case → list of
    row/metric/value/matched) and ``tuning`` (row → knob/rmse/edge/blowups; empty without a
    tuning table).
    """
    cfg = res.config
    f = {"mode": "FAST" if res.fast else "full", "seeds": cfg.seeds,
         "mismatch_seeds": min(cfg.mismatch_seeds, cfg.seeds),
         "outage_s": cfg.outage_s if outage_s is None else outage_s, "ladder": {}, "outage": {},
         "survival": {}, "winners": {}, "eq4": dict(res.counts), "diverged": {},
         "tuning": ({} if res.tuning.empty else
                    {r: dict(v) for r, v in choose_knobs(res.tuning).to_dict("index").items()}),
         "grid": tuple(float(g) for g in cfg.grid),
         "matched_failures": _matched_failures(res), "recovery_max_m": RECOVERY_MAX_M,
         "recovery_s": cfg.recovery_s, "slowest_reacq": _slowest_reacquisition(res),
         "return_errors": _return_errors(res, RECOVERY_MAX_M)}
    if cfg.outlier_c_m is not None:
        th = eq4_thresholds(cfg.model, eq4_path(cfg), cfg.outlier_c_m).iloc[:, 1:]
        pair, side = th.stack().idxmin()
        f["eq4_geometry"] = {"min_m": float(th.to_numpy().min()), "pair": str(pair),
                             "side": "reference" if "reference" in side else "station",
                             "excess_m": tuple(float(x) for x in cfg.model.outlier_excess_m)}
    for what, a, b in LADDER:
        f["ladder"][what] = {}
        for m in _METRIC_WORDS:
            r = pair_rmse(res, what, m)
            f["ladder"][what][m] = {**r, "verdict": verdict(r["lo"], r["hi"])}
    for other in _VERSUS:
        f["outage"][other] = _ratio(res, other, "tight + gate", "outage_max")
    gated = [r for r in ("LS + gate", "EKF + gate", EKF_TDOA_GATE, "loose + gate", "tight + gate")]
    for case in cfg.cases:
        t = res.table(case)
        rows = [r for r in gated if r in t.index]
        f["winners"][case] = {m: (str(t.loc[rows, m].idxmin()) if t.loc[rows, m].notna().any() else None)
                              for m in ("static_rmse", "dyn_rmse", "outage_max")}
        if case == "matched":
            continue
        f["diverged"][case] = _diverged(res, case)
        f["survival"][case] = {}
        seeds = res.case(case).index.get_level_values("seed").unique()
        for other in _VERSUS:
            r = _ratio(res, other, "tight + gate", "outage_max", case)
            r0 = _ratio(res, other, "tight + gate", "outage_max", "matched", seeds=seeds)["ratio"]
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
    bc = r.get("both_cov", np.nan)
    if np.isfinite(bc) and bc < 1:
        what += f" (on the {bc * 100:.0f} % of epochs both rows cover)"
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
    for other, label in (("loose + gate", "the gated loose filter"), ("EKF + gate", "the gated IMU-free EKF"),
                         (EKF_TDOA_GATE, "the IMU-free EKF with the same per-TDoA gate")):
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


_WHAT = {"dyn_rmse": "dynamic RMSE", "recovery_max": "max error in the recovery after the outage"}


def matched_failure_sentence(f: dict) -> str:
    """Names every gated filter that failed to re-acquire after the outage in the matched world."""
    fl = f.get("matched_failures", {})
    lim, dl = f.get("recovery_max_m", RECOVERY_MAX_M), f.get("recovery_s", RECOVERY_S)
    rule = f"error below {lim:g} m within {dl:g} s of UWB's return, held for {HOLD_S:g} s"
    if not fl:
        slow = f.get("slowest_reacq") or {}
        worst = (f" The slowest took {slow['s']:.2f} s ({slow['row']}, seed {slow['seed']})." if slow else "")
        text = f"Every gated filter re-acquired after the outage in the matched world ({rule}, on every seed).{worst}"
    else:
        text = (f"**Failed to re-acquire after the outage in the matched world** ({rule}): "
                + "; ".join(f"{r} (" + ", ".join(f"seed {k}: " + ("never" if not np.isfinite(v) else f"{v:.3g} s")
                                                 for k, v in s.items() if not v <= dl) + ")"
                            for r, s in fl.items())
                + ". A filter defect, not a tuning result: every ratio involving it measures the failure.")
    ret = f.get("return_errors", {})
    if ret:
        text += (f" By the check's earlier reading (max error in the {dl:g} s after UWB's return below {lim:g} m, "
                 "which also counts the drift UWB finds on its return — the outage's own score) these fail: "
                 + "; ".join(f"{r} (" + ", ".join(f"seed {k}: {v:.3g} m" for k, v in s.items()) + ")"
                             for r, s in ret.items())
                 + ". The check was changed to the re-acquisition time after that reading failed in full mode.")
    return text


def diverged_sentence(f: dict) -> str:
    """Names every mismatch row that diverged (:data:`DIVERGED_FACTOR` × its matched value)."""
    parts = [f"{d['row']} with {case} ({_WHAT[d['metric']]} {d['value']:.3g} m against {d['matched']:.3g} m "
             f"matched)" for case, ds in f["diverged"].items() for d in ds]
    k = f"{DIVERGED_FACTOR:g}×"
    if not parts:
        return (f"No gated row diverged under mismatch (none has a dynamic RMSE or recovery max above {k} its "
                f"matched value).")
    return (f"**Diverged** (dynamic RMSE or recovery max above {k} the matched value, same seeds): "
            + "; ".join(parts) + ". These are filter failures, not degradations; ratios and shares involving "
                                 "them measure the failure.")


def tuning_sentence(f: dict) -> str:
    """The chosen knobs, those on the grid's edge, and grid entries where a filter blew up."""
    t = f["tuning"]
    if not t:
        return "No tuning table."
    grid = f["grid"]
    text = (f"Knobs from a {len(grid)}-point grid {grid[0]:g}–{grid[-1]:g}"
            + (" (FAST: fewer points than the full run's 9)" if f["mode"] == "FAST" else "") + ": "
            + ", ".join(f"{r} {v['knob']:g}" + (" (grid edge)" if v["edge"] else "") for r, v in t.items()) + ".")
    edge = [r for r, v in t.items() if v["edge"]]
    if edge:
        text += f" On the grid's edge (the optimum may lie outside it): {', '.join(edge)}."
    blow = [(r, v["blowups"]) for r, v in t.items() if len(v["blowups"])]
    if blow:
        text += (" **Blew up** (tuning RMSE above 10× the row's lowest — the filter fails there, not a trade-off): "
                 + "; ".join(f"{r} at {', '.join(f'{g:g}' for g in b)}" for r, b in blow) + ".")
    else:
        text += " No grid entry exceeds 10× its row's lowest RMSE."
    return text


def eq4_sentence(f: dict, *, wide_case: str = "multipath up to 12 m") -> str:
    """Where eq. 4 can fire on the ablation's path, and how often it fired on injected multipath,
    in the matched world and where excesses reach 12 m."""
    m = f["eq4"].get("matched", {})
    text = ""
    g = f.get("eq4_geometry")
    if g:
        lo, hi = g["excess_m"]
        text = (f"On the ablation's path eq. 4 fires for excesses above {g['min_m']:.2f} m at the least (pair "
                f"{g['pair']}, excess on the {g['side']}); the matched world draws {lo:g}–{hi:g} m, so ")
        text += ("eq. 4 can fire on the largest of them. " if g["min_m"] < hi else
                 "eq. 4 cannot fire there. ")
    text += (f"Eq. 4 removed {m.get('eq4_on_injected', 0)} of {m.get('injected', 0)} TDoAs carrying injected "
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
    failed = f.get("matched_failures", {})
    rows = {what: (a, b) for what, a, b in LADDER}
    for step, r in f["ladder"].items():
        bad = [x for x in rows.get(step, ()) if x in failed]
        note = (f" *({', '.join(bad)} failed to re-acquire after the outage: this ratio measures that failure.)*"
                if bad else "")
        lines.append("- " + ingredient_sentence(step, r["dyn_rmse"], "dyn_rmse") + note)
    lines += ["", matched_failure_sentence(f), "", "**Headline.** " + outage_sentence(f), "",
              " ".join(survival_sentence(f, v) for v in ("EKF + gate", EKF_TDOA_GATE, "loose + gate")), "",
              diverged_sentence(f), "", tuning_sentence(f), "", eq4_sentence(f)]
    return "\n".join(lines)
