"""Notebook 05's verdicts, computed: :func:`verdict_table` reads the numbers and the rules out of an
:class:`~.ablation.AblationResult`, one claim a row.

Rules
-----
* An ingredient **helps** when the 95 % interval of the paired ratio (without / with it, over
  seeds) lies above 1, **hurts** when it lies below 1, and is **not significant** otherwise;
  with one seed there is no interval and the verdict is **undetermined**.
* Tight coupling's outage advantage over a method **survives** a mismatch case when the ratio
  (that method's max outage error / tight's; likewise its steady-state lead, on the dynamic RMSE) has its interval above 1 in that case, is **not
  significant** when the interval includes 1 and **reversed** when it lies below 1; its
  *share kept* is ``log(ratio_case) / log(ratio_matched)`` (1: all of it, 0: none; < 0 prints as none kept),
  both ratios over the same seeds (the case's). It is a share of the matched *lead*, not of any count, so it has
  no 100 % ceiling: above 100 % the case widened the lead, and it prints as *lead grew to … % of matched*.
* A row **diverged** in a mismatch case when its dynamic RMSE or its max error in the recovery
  after the outage (mean over the case's seeds) exceeds :data:`DIVERGED_FACTOR` × its matched
  value on the same seeds *and* the re-acquisition limit :data:`~.ablation.RECOVERY_MAX_M`: a failure,
  not a degradation, and named as such (a centimetre error ten times a millimetre one is not a failure).
  A divergence voids a ratio only of a metric it enters (:data:`ENTERS`): one in the recovery voids the
  outage-and-recovery ratios, not the dynamic RMSE (which leaves out the outage and the recovery after it);
  a steady-state one voids the dynamic RMSE's, not the outage's.
* A ladder step on the max error in the outage is **not applicable** when a row has no estimate in the
  outage window on any seed (LS: one TDoA per epoch gives no fix): there is nothing to compare.
* A verdict on two rows (a ladder step, the headline, a mismatch case) is **edge-bound** when either row's
  tuning pick lies on an edge of its grid (:func:`~.ablation.choose_knobs`): the ratio then compares a filter whose
  best knob may lie off the grid, and the interval's reading is given only as at the picks. A ladder or headline
  verdict also names a row that failed to re-acquire after the outage in the matched world.
* Eq. 4 **can fire** in the matched world when the smallest excess that trips it anywhere on the
  ablation's path (:func:`~.ladder.eq4_thresholds`) lies below the largest excess the matched
  simulator draws.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ...metrics import interval_side, interval_text
from ...scoreboard.verdicts import EDGE_BOUND
from .ablation import COVERAGE, HOLD_S, RECOVERY_MAX_M, AblationResult, EKF_TDOA_GATE, LADDER, choose_knobs
from .ladder import eq4_path, eq4_thresholds, pair_rmse

__all__ = ["DIVERGED_FACTOR", "ENTERS", "diverged", "diverged_on", "qualified", "ratios", "tuning_picks", "verdict",
           "verdict_table"]

#: A mismatch row whose dynamic RMSE or recovery max exceeds this many times its matched value (and
#: RECOVERY_MAX_M) diverged.
DIVERGED_FACTOR = 10.0
#: Per metric a ratio or summary row is on, the divergences (:func:`diverged`'s metrics) that enter it.
ENTERS = {"outage_max": ("recovery_max",), "recovery_max": ("recovery_max",), "dyn_rmse": ("dyn_rmse",)}

#: The rows tight coupling's outage advantage is measured against.
_VERSUS = ("loose + gate", "EKF + gate", EKF_TDOA_GATE)
_METRIC_WORDS = {"dyn_rmse": "dynamic RMSE", "outage_max": "max error in the outage"}
_RATIO_RULE = "paired ratio over seeds; interval above 1: helps, below 1: hurts, else not significant"


def verdict(lo: float, hi: float) -> str:
    """``"helps"``, ``"hurts"``, ``"not significant"`` or ``"undetermined"`` from a ratio interval."""
    return {"above": "helps", "below": "hurts", "contains": "not significant"}.get(interval_side(lo, hi, 1.0),
                                                                                  "undetermined")


def tuning_picks(res: AblationResult) -> dict:
    """Row → its tuning pick (:func:`~.ablation.choose_knobs`: ``Q ×``, ``R ×``, ``edge``, ...); empty untuned."""
    return {} if res.tuning.empty else choose_knobs(res.tuning).to_dict("index")


def qualified(v: str, pair, picks: dict, failed=()) -> str:
    """``v`` with the qualifiers every verdict on the rows of ``pair`` carries: edge-bound (:data:`EDGE_BOUND`) where
    either row's pick (``picks``: :func:`tuning_picks`) lies on its grid's edge and ``v`` is a verdict, and the rows
    of ``pair`` among ``failed`` (those that failed to re-acquire after the outage in the matched world)."""
    edge = [f"{x} {k} ×" for x in pair for k in picks.get(x, {}).get("edge", "—").split(", ") if k in ("Q", "R")]
    bad = [x for x in pair if x in failed]
    if edge and v != "undetermined":
        v = f"{EDGE_BOUND}: {v} at the picks ({', '.join(edge)} on the grid's edge)"
    return v + (f" ({', '.join(bad)} failed to re-acquire)" if bad else "")


def kept(res: AblationResult, other: str, metric: str, case: str) -> dict:
    """``other / tight + gate`` on ``metric`` in ``case`` (:meth:`~.ablation.AblationResult.ratio`) with its
    ``share`` of the matched advantage on the case's seeds (NaN where there was none to keep)."""
    r = res.ratio(other, "tight + gate", metric, case)
    r0 = res.ratio(other, "tight + gate", metric, "matched",
                   seeds=res.case(case).index.get_level_values("seed").unique())["ratio"]
    share = math.log(r["ratio"]) / math.log(r0) if np.isfinite(r["ratio"]) and np.isfinite(r0) and r0 > 1 else np.nan
    return {**r, "share": share}


def _gated(rows) -> list:
    return [r for r in rows if r.endswith("+ gate") and not r.startswith("LS")]


def diverged(res: AblationResult, case: str) -> list[dict]:
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


def diverged_on(ds: list[dict], metric: str) -> set[str]:
    """The rows of :func:`diverged`'s ``ds`` whose divergence enters ``metric`` (:data:`ENTERS`)."""
    return {d["row"] for d in ds if d["metric"] in ENTERS.get(metric, ())}


def _failed(res: AblationResult) -> dict:
    """Gated row → ``{seed: re-acquisition time}`` of those that failed to re-acquire in the matched world."""
    rec = res.case("matched")["reacq_s"].unstack("method")
    return {str(r): {int(k): float(v) for k, v in rec[r].items()} for r in _gated(rec.columns)
            if not (rec[r] <= res.config.recovery_s).all()}


def ratios(res: AblationResult) -> list[dict]:
    """The ablation's paired ratios, each computed once for :func:`verdict_table` (its first rows) and the summary
    rows (:func:`~.headlines.ablation_rows`): every ladder step on the dynamic RMSE and the max outage error (without /
    with, :func:`~.ladder.pair_rmse`), the headline (the others' max outage error over tight's, matched) and per
    mismatch case tight's lead on both metrics with its share kept (:func:`kept`). Each is the ratio's dict
    (``ratio``, ``lo``, ``hi``, ``n``) with ``kind`` (``"ladder"``, ``"headline"``, ``"mismatch"``), ``what`` (the
    ladder step or the case), ``pair``, ``metric``, ``diverged`` (a row of the pair diverged in the case on a metric
    that enters the ratio, :data:`ENTERS`: it measures a failure) and the verdict table's columns."""
    cfg, out = res.config, []
    cov, picks, failed = res.table("matched"), tuning_picks(res), _failed(res)

    def add(r, kind, what, pair, metric, claim, ours, rule, verdict, diverged=False):
        out.append({**r, "kind": kind, "what": what, "pair": pair, "metric": metric, "diverged": diverged,
                    "claim": claim, "ours": ours, "interval": interval_text(r["lo"], r["hi"], ".2f"), "seeds": r["n"],
                    "rule": rule, "verdict": verdict})

    for what, a, b in LADDER:
        for metric in ("dyn_rmse", "outage_max"):
            r = pair_rmse(res, what, metric)
            none = [x for x in (a, b) if not cov.loc[x, COVERAGE[metric]] > 0]      # no estimate in the window
            window = "outage" if metric == "outage_max" else "scored epochs"
            add(r, "ladder", what, (a, b), metric, f"{what}: {_METRIC_WORDS[metric]}, without / with",
                "—" if none else f"{r['ratio']:.2f}×", _RATIO_RULE, f"not applicable (no fix in the {window}: "
                f"{', '.join(none)})" if none else qualified(verdict(r["lo"], r["hi"]), (a, b), picks, failed))
    for other in _VERSUS:
        r = res.ratio(other, "tight + gate", "outage_max")
        add(r, "headline", "matched", (other, "tight + gate"), "outage_max",
            f"headline: {other} / tight + gate, max error in the {cfg.outage_s:g} s outage, matched",
            f"{r['ratio']:.2f}×", _RATIO_RULE,
            qualified(verdict(r["lo"], r["hi"]), (other, "tight + gate"), picks, failed))
    words = {"helps": "survives", "hurts": "reversed", "not significant": "not significant",
             "undetermined": "undetermined"}
    diverged_in = {case: diverged(res, case) for case in cfg.cases[1:]}          # the first is "matched"
    for metric, what, versus in (("outage_max", "max outage error", _VERSUS), ("dyn_rmse", "dynamic RMSE", _VERSUS[:2])):
        for case in cfg.cases[1:]:
            gone = diverged_on(diverged_in[case], metric)          # only a divergence that enters this metric
            for other in versus:
                r = kept(res, other, metric, case)
                failure = bool({other, "tight + gate"} & gone)          # the ratio measures a failure: no share
                pct = f"{100 * r['share']:.0f}"                   # as printed: above 100, the lead grew
                share = ("" if failure or not np.isfinite(r["share"]) else ", none kept" if r["share"] < 0 else
                         f", share kept {pct} %" if float(pct) <= 100 else f", lead grew to {pct} % of matched")
                add(r, "mismatch", case, (other, "tight + gate"), metric, f"{case}: {other} / tight + gate, {what}",
                    f"{r['ratio']:.2f}×{share}", _RATIO_RULE + " (above 1: the advantage survives)",
                    f"a row diverged on {', '.join(ENTERS[metric])} (the ratio measures a failure)" if failure else
                    qualified(words[verdict(r["lo"], r["hi"])], (other, "tight + gate"), picks), failure)
    return out


def verdict_table(res: AblationResult) -> pd.DataFrame:
    """Notebook 05's ablation verdicts, one row each: ``claim, ours, interval, seeds, rule, verdict``.

    Rows: the ratios of :func:`ratios` — each ladder step on the dynamic RMSE and the max outage error (without /
    with the ingredient); the headline (the others' max outage error over tight's, matched); how much of that
    advantage, and of tight's lead on the dynamic RMSE, each mismatch case keeps (``share kept`` in log ratio; none
    where reversed; "lead grew" above 100 %) — *a row diverged* instead of a verdict where tight or the other
    row diverged in that case on a metric that enters the ratio (:data:`ENTERS`; the ratio then measures a failure);
    *not applicable* for a ladder step where a row has no estimate in the metric's window —; every diverged row;
    every gated row that failed to re-acquire in the matched world (:func:`~.ablation.reacquisition_s` beyond the
    recovery time on some seed) and every one whose max error in the recovery window reaches
    :data:`~.ablation.RECOVERY_MAX_M` (the earlier reading of the re-acquisition check, which also counts the drift
    UWB finds on its return); where eq. 4 can fire and what it removed."""
    cfg = res.config
    n_mis = min(cfg.mismatch_seeds, cfg.seeds)
    rows = [{k: r[k] for k in ("claim", "ours", "interval", "seeds", "rule", "verdict")} for r in ratios(res)]

    def add(claim, ours, interval, seeds, rule, verdict):
        rows.append({"claim": claim, "ours": ours, "interval": interval, "seeds": seeds, "rule": rule,
                     "verdict": verdict})

    back = res.case("matched")["recovery_max"].unstack("method")
    for case in cfg.cases[1:]:
        for d in diverged(res, case):
            add(f"{case}: {d['row']} diverged ({d['metric']})", f"{d['value']:.3g} m against {d['matched']:.3g} m "
                "matched", "—", n_mis, f"above {DIVERGED_FACTOR:g}× the matched value and {RECOVERY_MAX_M:g} m",
                "diverged")
    for row, per_seed in _failed(res).items():
        add(f"matched: {row} re-acquires after the outage", ", ".join(
            f"seed {k}: " + ("never" if not np.isfinite(v) else f"{v:.3g} s") for k, v in per_seed.items()),
            "—", cfg.seeds, f"error below {RECOVERY_MAX_M:g} m within {cfg.recovery_s:g} s of UWB's return, "
            f"held {HOLD_S:g} s", "failed")
    for row in _gated(back.columns):
        if not (back[row] < RECOVERY_MAX_M).all():
            add(f"matched: {row}, max error in the {cfg.recovery_s:g} s after UWB's return", ", ".join(
                f"seed {k}: {v:.3g} m" for k, v in back[row].items() if not v < RECOVERY_MAX_M), "—", cfg.seeds,
                f"below {RECOVERY_MAX_M:g} m (counts the drift UWB finds on its return)", "drift found on the return")
    if cfg.outlier_c_m is not None:
        th = eq4_thresholds(cfg.model, eq4_path(cfg), cfg.outlier_c_m).iloc[:, 1:]
        pair, side = th.stack().idxmin()
        min_m, top_m = float(th.to_numpy().min()), float(cfg.model.outlier_excess_m[1])
        add(f"eq. 4 can fire on the path (smallest excess that trips it: pair {pair}, on the "
            f"{'reference' if 'reference' in side else 'station'})", f"{min_m:.2f} m", "—", "—",
            f"below the largest matched excess ({top_m:g} m)", "can fire" if min_m < top_m else "cannot fire")
    for case, c in res.counts.items():
        if c.get("injected"):
            add(f"{case}: injected-multipath TDoAs that eq. 4 removed", f"{c.get('eq4_on_injected', 0)} of "
                f"{c['injected']}", "—", "—", "count (the rest only a gate can catch)", "—")
    return pd.DataFrame(rows)
