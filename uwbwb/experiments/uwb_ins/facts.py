"""Notebook 05's verdicts, computed: :func:`facts` reads the numbers and the rules out of an
:class:`~.ablation.AblationResult`; :func:`verdict_table` lays them out, one claim a row.

Rules
-----
* An ingredient **helps** when the 95 % interval of the paired ratio (without / with it, over
  seeds) lies above 1, **hurts** when it lies below 1, and is **not significant** otherwise;
  with one seed there is no interval and the verdict is **undetermined**.
* Tight coupling's outage advantage over a method **survives** a mismatch case when the ratio
  (that method's max outage error / tight's; likewise its steady-state lead, on the dynamic RMSE) has its interval above 1 in that case, is **not
  significant** when the interval includes 1 and **reversed** when it lies below 1; its
  *share kept* is ``log(ratio_case) / log(ratio_matched)`` (1: all of it, 0: none; < 0 prints as none kept),
  both ratios over the same seeds (the case's).
* A row **diverged** in a mismatch case when its dynamic RMSE or its max error in the recovery
  after the outage (mean over the case's seeds) exceeds :data:`DIVERGED_FACTOR` × its matched
  value on the same seeds *and* the re-acquisition limit :data:`~.ablation.RECOVERY_MAX_M`: a failure,
  not a degradation, and named as such (a centimetre error ten times a millimetre one is not a failure).
* A ladder step's verdict is **edge-bound** when either side's tuning pick lies on an edge of its grid
  (:func:`~.ablation.choose_knobs`): the ratio then compares a filter whose best knob may lie off the grid, and
  the interval's reading is given only as at the picks.
* A tuning-grid entry **blew up** when its RMSE exceeds 10× the row's lowest on the grid
  (:func:`~.ablation.choose_knobs`): the filter fails at that knob.
* Eq. 4 **can fire** in the matched world when the smallest excess that trips it anywhere on the
  ablation's path (:func:`~.ladder.eq4_thresholds`) lies below the largest excess the matched
  simulator draws.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ...metrics import interval_side
from .ablation import HOLD_S, RECOVERY_MAX_M, AblationResult, EKF_TDOA_GATE, LADDER, choose_knobs
from .ladder import eq4_path, eq4_thresholds, pair_rmse

__all__ = ["DIVERGED_FACTOR", "verdict", "facts", "verdict_table"]

#: A mismatch row whose dynamic RMSE or recovery max exceeds this many times its matched value (and
#: RECOVERY_MAX_M) diverged.
DIVERGED_FACTOR = 10.0

#: The rows tight coupling's outage advantage is measured against.
_VERSUS = ("loose + gate", "EKF + gate", EKF_TDOA_GATE)
_METRIC_WORDS = {"static_rmse": "static RMSE", "dyn_rmse": "dynamic RMSE", "outage_max": "max error in the outage"}


def verdict(lo: float, hi: float) -> str:
    """``"helps"``, ``"hurts"``, ``"not significant"`` or ``"undetermined"`` from a ratio interval."""
    return {"above": "helps", "below": "hurts", "contains": "not significant"}.get(interval_side(lo, hi, 1.0),
                                                                                  "undetermined")


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


def _diverged(res: AblationResult, case: str) -> list[dict]:
    """Rows of ``case`` whose dyn RMSE or recovery max exceeds DIVERGED_FACTOR × matched (same seeds) and
    RECOVERY_MAX_M."""
    c, m = res.case(case), res.case("matched")
    out = []
    for row in c.index.get_level_values("method").unique():
        if row not in m.index.get_level_values("method"):
            continue
        cs = c.xs(row, level="method")
        ms = m.xs(row, level="method").reindex(cs.index)
        for metric in ("dyn_rmse", "recovery_max"):
            v, v0 = float(cs[metric].mean()), float(ms[metric].mean())
            if np.isfinite(v) and np.isfinite(v0) and v > DIVERGED_FACTOR * v0 and v > RECOVERY_MAX_M:
                out.append({"row": str(row), "metric": metric, "value": v, "matched": v0})
    return out


def facts(res: AblationResult) -> dict:
    """Numbers and rule outcomes behind notebook 05's ablation verdict table.

    Returns a dict with ``seeds``, ``mismatch_seeds``, ``outage_s``, ``ladder``
    (step → metric → ratio/lo/hi/n/verdict), ``outage`` (versus "loose + gate" and "EKF + gate":
    the matched ratio of max outage errors and its verdict), ``survival`` (case → versus →
    ratio/lo/hi/verdict/share, on the max outage error), ``survival_dyn`` (the same on the dynamic RMSE,
    versus "loose + gate" and "EKF + gate"), ``eq4`` (counts per case, and ``eq4_geometry``: the smallest
    excess that fires eq. 4 on the path, its pair and side, and the matched world's excess range),
    ``diverged`` (case → list of row/metric/value/matched), ``tuning`` (row → Q ×/R ×/rmse/edge/blowups; empty
    without a tuning table), and the re-acquisition failures (``matched_failures``, ``return_errors``, with
    ``recovery_max_m`` and ``recovery_s``).
    """
    cfg = res.config
    f = {"seeds": cfg.seeds, "mismatch_seeds": min(cfg.mismatch_seeds, cfg.seeds), "outage_s": cfg.outage_s,
         "ladder": {}, "outage": {}, "survival": {}, "eq4": dict(res.counts), "diverged": {},
         "tuning": ({} if res.tuning.empty else
                    {r: dict(v) for r, v in choose_knobs(res.tuning).to_dict("index").items()}),
         "matched_failures": _matched_failures(res), "recovery_max_m": RECOVERY_MAX_M,
         "recovery_s": cfg.recovery_s, "return_errors": _return_errors(res, RECOVERY_MAX_M)}
    if cfg.outlier_c_m is not None:
        th = eq4_thresholds(cfg.model, eq4_path(cfg), cfg.outlier_c_m).iloc[:, 1:]
        pair, side = th.stack().idxmin()
        f["eq4_geometry"] = {"min_m": float(th.to_numpy().min()), "pair": str(pair),
                             "side": "reference" if "reference" in side else "station",
                             "excess_m": tuple(float(x) for x in cfg.model.outlier_excess_m)}
    for what, a, b in LADDER:
        f["ladder"][what] = {}
        edge = [f"{x} {k} ×" for x in (a, b) for k in f["tuning"].get(x, {}).get("edge", "—").split(", ")
                if k in ("Q", "R")]
        for m in _METRIC_WORDS:
            r = pair_rmse(res, what, m)
            v = verdict(r["lo"], r["hi"])
            f["ladder"][what][m] = {**r, "verdict": f"edge-bound: {v} at the picks ({', '.join(edge)} on the grid's "
                                                    "edge)" if edge and v != "undetermined" else v}
    for other in _VERSUS:
        f["outage"][other] = _ratio(res, other, "tight + gate", "outage_max")
    for case in cfg.cases[1:]:                                  # the first is "matched"
        f["diverged"][case] = _diverged(res, case)
        seeds = res.case(case).index.get_level_values("seed").unique()
        for key, metric, versus in (("survival", "outage_max", _VERSUS), ("survival_dyn", "dyn_rmse", _VERSUS[:2])):
            f.setdefault(key, {})[case] = {}
            for other in versus:
                r = _ratio(res, other, "tight + gate", metric, case)
                r0 = _ratio(res, other, "tight + gate", metric, "matched", seeds=seeds)["ratio"]
                r["share"] = (math.log(r["ratio"]) / math.log(r0)
                              if np.isfinite(r["ratio"]) and np.isfinite(r0) and r0 > 1 else np.nan)
                f[key][case][other] = r
    return f


def _share(share: float) -> str:
    """The share of the matched advantage a case keeps, as words: a negative share is a reversal, not "−51 %"."""
    if not np.isfinite(share):
        return ""
    return f", share kept {100 * share:.0f} %" if share >= 0 else ", none kept"


def _interval(r: dict) -> str:
    return f"[{r['lo']:.2f}, {r['hi']:.2f}]" if np.isfinite(r["lo"]) and np.isfinite(r["hi"]) else "—"


_RATIO_RULE = "paired ratio over seeds; interval above 1: helps, below 1: hurts, else not significant"


def verdict_table(f: dict) -> pd.DataFrame:
    """Notebook 05's ablation verdicts, one row each: ``claim, ours, interval, seeds, rule, verdict``.

    Rows: each ladder step on the dynamic RMSE and the max outage error (without / with the ingredient); the
    headline (the others' max outage error over tight's, matched); how much of that advantage, and of tight's
    lead on the dynamic RMSE, each mismatch case keeps (``share kept`` in log ratio; none where reversed) — *a row diverged* instead of a verdict where tight or the other
    row diverged in that case (the ratio then measures a failure); every diverged row; every gated row that
    failed to re-acquire in the matched world; where eq. 4 can fire and what it removed."""
    rows = []

    def add(claim, ours, interval, seeds, rule, verdict):
        rows.append({"claim": claim, "ours": ours, "interval": interval, "seeds": seeds, "rule": rule,
                     "verdict": verdict})

    failed = f.get("matched_failures", {})
    steps = {what: (a, b) for what, a, b in LADDER}
    for step, by_metric in f["ladder"].items():
        for metric in ("dyn_rmse", "outage_max"):
            r = by_metric[metric]
            bad = [x for x in steps.get(step, ()) if x in failed]
            add(f"{step}: {_METRIC_WORDS[metric]}, without / with", f"{r['ratio']:.2f}×", _interval(r), r["n"],
                _RATIO_RULE, r["verdict"] + (f" ({', '.join(bad)} failed to re-acquire)" if bad else ""))
    for other, r in f["outage"].items():
        add(f"headline: {other} / tight + gate, max error in the {f['outage_s']:g} s outage, matched",
            f"{r['ratio']:.2f}×", _interval(r), r["n"], _RATIO_RULE, r["verdict"])
    words = {"helps": "survives", "hurts": "reversed", "not significant": "not significant",
             "undetermined": "undetermined"}
    for key, what in (("survival", "max outage error"), ("survival_dyn", "dynamic RMSE")):
        for case, by_other in f.get(key, {}).items():
            gone = {d["row"] for d in f["diverged"].get(case, [])}
            for other, r in by_other.items():
                failure = bool({other, "tight + gate"} & gone)          # the ratio measures a failure: no share
                v = "a row diverged (the ratio measures a failure)" if failure else words[r["verdict"]]
                add(f"{case}: {other} / tight + gate, {what}",
                    f"{r['ratio']:.2f}×{'' if failure else _share(r['share'])}", _interval(r), r["n"],
                    _RATIO_RULE + " (above 1: the advantage survives)", v)
    for case, ds in f["diverged"].items():
        for d in ds:
            add(f"{case}: {d['row']} diverged ({d['metric']})", f"{d['value']:.3g} m against {d['matched']:.3g} m "
                "matched", "—", f["mismatch_seeds"], f"above {DIVERGED_FACTOR:g}× the matched value and "
                f"{RECOVERY_MAX_M:g} m", "diverged")
    for row, per_seed in failed.items():
        add(f"matched: {row} re-acquires after the outage", ", ".join(
            f"seed {k}: " + ("never" if not np.isfinite(v) else f"{v:.3g} s") for k, v in per_seed.items()),
            "—", f["seeds"], f"error below {f['recovery_max_m']:g} m within {f['recovery_s']:g} s of UWB's return, "
            f"held {HOLD_S:g} s", "failed")
    for row, per_seed in f.get("return_errors", {}).items():
        add(f"matched: {row}, max error in the {f['recovery_s']:g} s after UWB's return", ", ".join(
            f"seed {k}: {v:.3g} m" for k, v in per_seed.items()), "—", f["seeds"],
            f"below {f['recovery_max_m']:g} m (counts the drift UWB finds on its return)", "drift found on the return")
    g = f.get("eq4_geometry")
    if g:
        add(f"eq. 4 can fire on the path (smallest excess that trips it: pair {g['pair']}, on the {g['side']})",
            f"{g['min_m']:.2f} m", "—", "—", f"below the largest matched excess ({g['excess_m'][1]:g} m)",
            "can fire" if g["min_m"] < g["excess_m"][1] else "cannot fire")
    for case, c in f["eq4"].items():
        if c.get("injected"):
            add(f"{case}: injected-multipath TDoAs that eq. 4 removed", f"{c.get('eq4_on_injected', 0)} of "
                f"{c['injected']}", "—", "—", "count (the rest only a gate can catch)", "—")
    return pd.DataFrame(rows)
