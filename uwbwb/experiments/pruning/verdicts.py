"""Notebook 02's comparison with the paper, computed from the run's tables.

:func:`comparison_facts` derives every statement about our run (which heuristic wins,
whether trajectory NLS beats the point-based fixes, where the percentile's error goes
in 3-D, whether calibration or pruning removes the error...) as numbers and orderings;
:func:`verdict_table` lays the claims out as rows (claim, paper and its kind, ours and its kind, the
assumption a synthetic number rests on, rule, verdict). The paper's claims are *inputs*, our numbers
*reproduced*; a synthetic number is reproduced under our simulator's range-error model, which is an
assumption (``uw.sim.tours.TourConfig``), not the paper's, and is named beside it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ... import metrics
from ...sim.tours import TourConfig
from .scoring import LABELS, PAPER_RANKING, POINT

__all__ = ["COLUMNS", "comparison_facts", "paired_median", "ranking_steps", "verdict_table"]

#: The columns of :func:`verdict_table`.
COLUMNS = ["claim", "paper", "paper kind", "ours", "ours kind", "assumption", "rule", "verdict"]

_NAMES = {"none": "plain NLS", "percentile": "the 5th percentile", "robust_mean": "the robust mean",
          "residual": "residual pruning", POINT: "the point-based fixes"}


def _name(h: str) -> str:
    """An estimator as a sentence names it."""
    return _NAMES.get(h, LABELS.get(h, h))


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %"


def _versus(point_m: float, best_nls_m: float, tol_m: float = 0.005) -> str:
    """How the best trajectory fit compares with the point-based fixes (median errors, 5 mm tolerance)."""
    if best_nls_m < point_m - tol_m:
        return "better than"
    return "as good as" if best_nls_m <= point_m + tol_m else "worse than"


def comparison_facts(synthetic: pd.DataFrame, *, synthetic_dim: int = 2, synthetic_other: pd.DataFrame | None = None,
                     persistence: pd.DataFrame | None = None, lias_static: pd.DataFrame | None = None,
                     lias_static_epochs: dict | None = None, lias_ranges: pd.DataFrame | None = None,
                     lias_dynamic: pd.DataFrame | None = None, lias_dynamic_epochs: dict | None = None,
                     hanyang: pd.DataFrame | None = None, tour: TourConfig | None = None,
                     excess: pd.DataFrame | None = None, stops: pd.DataFrame | None = None,
                     lias_dynamic_errors: dict | None = None, seed: int = 0) -> dict:
    """The facts of the comparison, as numbers and orderings.

    Parameters
    ----------
    synthetic
        :func:`~.scoring.heuristic_summary` of the fair synthetic comparison (stops, walks,
        track; with the point-based baseline).
    synthetic_dim
        Its geometry: 2 (every estimator at the known mount height) or 3 (none has a height).
    synthetic_other
        The same packets in the other geometry (its :func:`~.scoring.heuristic_summary`).
    persistence
        Median stationary error per mean NLOS episode length (index, s) and heuristic.
    lias_static
        ``pd.concat({"raw": summary, "calibrated (LOSO)": summary})`` of the LIAS poses.
    lias_static_epochs
        ``{"raw": epoch_summary, "calibrated (LOSO)": ...}`` (per-epoch scoring, point baseline).
    lias_ranges
        :func:`~.study.range_error_stats` of the static poses.
    lias_dynamic
        Medians per ``(ranges, heuristic)`` of the straight pieces: ``mean_err_m``, ``speed_ratio``.
    lias_dynamic_epochs
        ``{ranges: (epoch_summary, run_coverage)}`` of the dynamic run.
    hanyang
        :func:`uwbwb.calibration.percentile_by_file` of the Hanyang static files.
    tour
        The simulator configuration of the synthetic comparison (its range-error model is named
        beside every synthetic row; None: named without its values).
    excess
        :func:`~.study.nlos_excess_sensitivity` of residual pruning (``all_p90_m`` per simulated mean
        NLOS excess).
    stops
        The per-stop errors behind ``synthetic`` (``SyntheticResult.stops``): each step of the paper's ranking
        then gets the block-bootstrap interval of its median difference (:func:`ranking_steps`, seeded by ``seed``).
    lias_dynamic_errors
        ``{ranges: epoch table}`` of the dynamic run (``DynamicResult.epochs``: ``segment, tag, t_s, heuristic,
        err_m``): the best trajectory fit vs the point fixes then gets the interval of its median difference on
        the epochs both covered (:func:`paired_median`), in place of the 5 mm tolerance.
    """
    f: dict = {"dim": synthetic_dim}
    if tour is not None:
        f["tour"] = {k: getattr(tour, k) for k in ("sigma_m", "bias_range_m", "p_nlos_in", "p_nlos_out",
                                                    "nlos_mean_m", "nlos_sigma_m", "nlos_dwell_s")}
    if excess is not None and len(excess):
        f["excess"] = {"nlos_mean_m": [float(x) for x in excess.index],
                       "p90_m": [float(x) for x in excess["all_p90_m"]]}
    med = synthetic["stop_median_m"].dropna()
    three = [h for h in PAPER_RANKING if h in med.index]
    f["ranking"] = tuple(med[three].sort_values().index)
    f["ranking_all"] = tuple(med.sort_values().index)
    f["stop_median_m"] = med.to_dict()
    f["paper_ranking"] = f["ranking"] == PAPER_RANKING[:len(f["ranking"])] and len(three) == 3
    if stops is not None and len(three) == 3:
        f["ranking_steps"] = ranking_steps(stops, rng=np.random.default_rng(seed))

    if POINT in synthetic.index and "all_p90_m" in synthetic:
        nls = [h for h in ("none", "robust_mean", "residual") if h in synthetic.index
               and bool(synthetic.loc[h].get("all_includes_walks", False))]
        f["point"] = {h: {"p90_m": synthetic.loc[h, "all_p90_m"], "median_m": synthetic.loc[h, "all_median_m"],
                          "coverage": synthetic.loc[h, "coverage"]} for h in [*nls, POINT]}
        best = min(nls, key=lambda h: synthetic.loc[h, "all_p90_m"]) if nls else None
        f["point_best_nls"] = best
        if best is not None:
            f["nls_beats_point_p90"] = bool(synthetic.loc[best, "all_p90_m"] < synthetic.loc[POINT, "all_p90_m"])
            f["nls_beats_point_median"] = bool(synthetic.loc[best, "all_median_m"]
                                               < synthetic.loc[POINT, "all_median_m"])

    if synthetic_other is not None and "percentile" in synthetic_other.index and "percentile" in synthetic.index:
        three_d = synthetic_other if synthetic_dim == 2 else synthetic
        known = synthetic if synthetic_dim == 2 else synthetic_other
        h3 = [h for h in PAPER_RANKING if h in three_d.index]
        f["geometry"] = {
            "percentile_dz_m": float(three_d.loc["percentile", "stop_err_z_median_m"]),
            "percentile_dz_bias_m": float(three_d.loc["percentile", "stop_err_z_bias_m"]),
            "percentile_h_3d_m": float(three_d.loc["percentile", "stop_median_m"]),
            "percentile_h_known_m": float(known.loc["percentile", "stop_median_m"]),
            "dz_m": three_d["stop_err_z_median_m"].dropna().to_dict(),
            "ranking_3d": tuple(three_d.loc[h3, "stop_median_m"].dropna().sort_values().index),
            "ranking_3d_by_3d_error": tuple(three_d.loc[h3, "stop_err_3d_median_m"].dropna().sort_values().index),
            "ranking_known": tuple(known.loc[[h for h in PAPER_RANKING if h in known.index], "stop_median_m"]
                                   .dropna().sort_values().index),
        }

    if persistence is not None and len(persistence) >= 2:
        base = 3.0 if 3.0 in persistence.index else persistence.index[0]
        long = persistence.index.max()
        p0, p1 = persistence.loc[base], persistence.loc[long]
        h3 = [h for h in PAPER_RANKING if h in p0.index]

        def lead(p):
            s = p[h3].sort_values()
            return float(s.iloc[1] - s.iloc[0])

        f["persistence"] = {"base_s": float(base), "long_s": float(long),
                            "worse": [h for h in p0.index if p1[h] > p0[h]], "n": len(p0),
                            "best_base": p0[h3].idxmin(), "best_long": p1[h3].idxmin(),
                            "lead_base_m": lead(p0), "lead_long_m": lead(p1)}

    if lias_ranges is not None and len(lias_ranges):
        b = lias_ranges["bias_m"]
        f["lias_ranges"] = {"bias_p10_m": float(b.quantile(0.1)), "bias_p90_m": float(b.quantile(0.9)),
                            "frac_positive": float((b > 0).mean()),
                            "frac_long": float(np.average(lias_ranges["frac_long"], weights=lias_ranges["n"])),
                            "spread_median_m": float(lias_ranges["spread_m"].median())}

    if lias_static is not None:
        raw = lias_static.loc["raw", "stop_median_m"].dropna()
        cal = lias_static.loc["calibrated (LOSO)", "stop_median_m"].dropna()
        f["lias_static"] = {"raw": raw.to_dict(), "cal": cal.to_dict(),
                            "helps": [h for h in raw.index if h != "none" and raw[h] < raw["none"]],
                            "hurts": [h for h in raw.index if h != "none" and raw[h] > raw["none"]],
                            "cal_gain_m": float(raw["none"] - cal["none"]),
                            "prune_gain_m": float(raw["none"] - raw.min()),
                            "cal_spread_m": float(cal.max() - cal.min())}
    if lias_static_epochs is not None:
        f["lias_static_point"] = {k: {h: (float(r.median_m), float(r.coverage)) for h, r in t.iterrows()}
                                  for k, t in lias_static_epochs.items()}
        f["lias_point_verdict"] = {k: _versus(t[POINT][0], min(v[0] for h, v in t.items() if h != POINT))
                                   for k, t in f["lias_static_point"].items() if POINT in t and len(t) > 1}

    if lias_dynamic is not None:
        verdicts = {}
        for k in lias_dynamic.index.get_level_values(0).unique():
            d = lias_dynamic.loc[k, "mean_err_m"]
            best = d.drop("none").idxmin()
            verdicts[k] = {"none_m": float(d["none"]), "best": best, "best_m": float(d[best]),
                           "verdict": ("plain NLS beats every heuristic" if d["none"] < d[best] - 0.005 else
                                       "plain NLS is as good as any heuristic" if d["none"] <= d[best] + 0.005 else
                                       f"{_name(best)} beats plain NLS")}
        f["lias_dynamic"] = verdicts
    if lias_dynamic_epochs is not None:
        f["lias_dynamic_point"] = {k: {"median_m": {h: float(r.median_m) for h, r in es.iterrows()},
                                       "run_coverage": {h: float(v) for h, v in cov.items()}}
                                   for k, (es, cov) in lias_dynamic_epochs.items()}
        for k, v in f["lias_dynamic_point"].items():
            m = v["median_m"]
            if POINT in m and len(m) > 1:
                v["verdict"] = _versus(m[POINT], min(x for h, x in m.items() if h != POINT))
                if lias_dynamic_errors is not None and k in lias_dynamic_errors and "none" in m:
                    # the contender is fixed before looking — the trajectory fit itself, plain NLS (the heuristics
                    # have rows of their own) —, not the lowest median of this same data, which favours "NLS better"
                    v["paired"] = paired_median(lias_dynamic_errors[k], "none", POINT, ["segment", "tag"],
                                                rng=np.random.default_rng(seed))

    ratios = []
    if "speed_ratio_median" in synthetic and "none" in synthetic.index and np.isfinite(
            synthetic.loc["none", "speed_ratio_median"]):
        ratios.append(("our synthetic walks", float(synthetic.loc["none", "speed_ratio_median"])))
    if lias_dynamic is not None:
        for k in lias_dynamic.index.get_level_values(0).unique():
            ratios.append((f"the {k} LIAS pieces", float(lias_dynamic.loc[(k, "none"), "speed_ratio"])))
    f["speed_ratios"] = ratios

    if hanyang is not None and len(hanyang):
        t = hanyang.groupby("condition")[["median_err_m", "pq_err_m"]].median()
        h = {"conditions": sorted(t.index), "median_err_m": t["median_err_m"].to_dict(),
             "pq_err_m": t["pq_err_m"].to_dict()}
        if {"LOS", "NLOS"} <= set(t.index):
            h["gap_m"] = float(t.loc["NLOS", "median_err_m"] - t.loc["LOS", "median_err_m"])
        span = float(np.ptp(hanyang["true_range_m"]))
        slopes = {c: float(np.polyfit(g["true_range_m"], g["median_err_m"], 1)[0])
                  for c, g in hanyang.groupby("condition") if g["true_range_m"].nunique() > 1}
        h["span_m"] = span
        h["growth_m"] = {c: s * span for c, s in slopes.items()}
        f["hanyang"] = h
    return f


def ranking_steps(stops: pd.DataFrame, order=PAPER_RANKING, *, rng: np.random.Generator) -> list[dict]:
    """Each step of the paper's ranking (``order``, best first) on our stops: ``median(a) − median(b)`` for the
    neighbours ``a`` (ranked better by the paper) and ``b``, over the stops both fitted, with its bootstrap
    interval (:func:`uwbwb.metrics.block_bootstrap_difference`, ``statistic="median"``, ``blocks="segment"``: one
    series per experiment and node, resampled whole, since its stops share the experiment's per-pair range biases)
    and the side of 0 it lies on (:func:`uwbwb.metrics.interval_side`: ``below`` agrees with the paper's step,
    ``above`` reverses it)."""
    wide = stops.pivot_table(index=["experiment", "tag", "segment"], columns="heuristic", values="err_m")
    out = []
    for a, b in zip(order[:-1], order[1:]):
        pair = wide[[a, b]].dropna().sort_index()
        groups = [g for _, g in pair.groupby(level=[0, 1], sort=True)]
        d = metrics.block_bootstrap_difference([g[a].to_numpy() for g in groups], [g[b].to_numpy() for g in groups],
                                               rng=rng, statistic="median", blocks="segment")
        out.append({"better": a, "worse": b, "diff_m": d["diff_m"], "lo_m": d["lo_m"], "hi_m": d["hi_m"],
                    "n": d["n"], "side": metrics.interval_side(d["lo_m"], d["hi_m"])})
    return out


def paired_median(epochs: pd.DataFrame, a: str, b: str, series: list[str], *, rng: np.random.Generator) -> dict:
    """``median(a) − median(b)`` of two estimators of an epoch table (``heuristic``, ``err_m`` and the ``series``
    columns plus ``t_s``) over the epochs both covered, with its block-bootstrap interval (one series per value
    of ``series``, in time order) and its side of 0 (:func:`uwbwb.metrics.interval_side`)."""
    wide = epochs.pivot_table(index=[*series, "t_s"], columns="heuristic", values="err_m")[[a, b]].dropna()
    groups = [g for _, g in wide.sort_index().groupby(level=list(range(len(series))), sort=True)]
    d = metrics.block_bootstrap_difference([g[a].to_numpy() for g in groups], [g[b].to_numpy() for g in groups],
                                           rng=rng, statistic="median")
    return {**d, "a": a, "b": b, "side": metrics.interval_side(d["lo_m"], d["hi_m"])}


#: The paired rows' verdicts from the side of their interval.
_PAIRED_VERDICT = {"below": "NLS better", "above": "NLS worse", "contains": "not significant",
                   "none": "no interval (too few blocks)"}

#: The ranking row's verdict from the sides of its steps: every step as the paper's, one step reversed, or neither.
_RANKING_VERDICT = {"all below": "as in the paper", "a step above": "differs", "otherwise": "not resolved"}


def _assumption(f: dict, what: str = "errors") -> str:
    """The simulator assumption a synthetic row rests on, with its values when the configuration was given."""
    t = f.get("tour")
    if t is None:
        return "simulated range errors: our model (uw.sim.tours.TourConfig), not the paper's"
    nlos = (f"NLOS excess N({t['nlos_mean_m']:g} m, {t['nlos_sigma_m']:g} m) clipped at 0 on "
            f"{_pct(t['p_nlos_out'])} of links outside coverage ({_pct(t['p_nlos_in'])} inside), "
            f"{t['nlos_dwell_s']:g} s episodes")
    los = f"LOS σ {t['sigma_m']:g} m, per-pair bias {t['bias_range_m'][0]:g}–{t['bias_range_m'][1]:g} m"
    tail = "our simulator (uw.sim.tours.TourConfig), not the paper's"
    if what == "p90":
        return f"{nlos}; {los}: {tail}" + ("; the next row scales the excess" if "excess" in f else "")
    if what == "excess":
        return f"nlos_mean_m scaled, the rest as above: {tail}"
    if what == "dwell":
        return f"nlos_dwell_s varied, the rest as above: {tail}"
    return f"{nlos}; {los}: {tail}"


def verdict_table(f: dict) -> pd.DataFrame:
    """The claims of notebook 02, one row each (:data:`COLUMNS`) from :func:`comparison_facts`.

    ``paper kind`` is *input* where the paper states the claim, ``ours kind`` is *reproduced*;
    ``assumption`` names the simulator assumption a synthetic number rests on (real-data rows: none).
    The ranking row, when the per-stop errors were given, decides each step of the paper's order by the
    block-bootstrap interval of its median difference (:func:`ranking_steps`). The other rows have no interval:
    they compare medians and percentiles of one run each. Only the rows that say so allow a tolerance (5 mm,
    where two estimators count as equal); the others follow the sign or the order, so a millimetre can decide them. The NLS-vs-point row takes the best of the NLS variants on
    its own epochs, with coverage beside it."""
    rows = []

    def add(claim, paper, ours, rule, verdict, assumption="—"):
        rows.append({"claim": claim, "paper": paper, "paper kind": "—" if paper == "—" else "input",
                     "ours": ours, "ours kind": "reproduced", "assumption": assumption, "rule": rule,
                     "verdict": verdict})

    syn = _assumption(f)
    geo = "known mount height" if f["dim"] == 2 else "3-D, no height"
    steps = f.get("ranking_steps")
    if steps is None:
        add(f"ranking of the heuristics by median stop error, synthetic ({geo})",
            " < ".join(_name(h) for h in PAPER_RANKING),
            " < ".join(f"{_name(h)} ({f['stop_median_m'][h]:.2f} m)" for h in f["ranking"]),
            "the same order", "as in the paper" if f["paper_ranking"] else "differs", syn)
    else:
        sides = [s["side"] for s in steps]
        key = "all below" if all(x == "below" for x in sides) else "a step above" if "above" in sides else "otherwise"
        add(f"ranking of the heuristics by median stop error, synthetic ({geo})",
            " < ".join(_name(h) for h in PAPER_RANKING),
            "; ".join(f"{_name(s['better'])} − {_name(s['worse'])} {s['diff_m']:+.2f} m "
                      + (f"[{s['lo_m']:+.2f}, {s['hi_m']:+.2f}]" if s["side"] != "none" else
                         "(too few series for an interval)")
                      for s in steps) + f" ({steps[0]['n']} stops)",
            "each step of the paper's order: 95 % bootstrap interval of the median difference (block-bootstrap "
            "rule, each experiment's series of stops one block) below 0 (all: as in the paper; one above 0: differs; "
            "else not resolved)", _RANKING_VERDICT[key], syn)
    if f.get("point_best_nls"):
        b, pt = f["point_best_nls"], f["point"]
        add("best trajectory NLS vs the point-based fixes, 90th percentile of all errors (m)",
            "a slight improvement", f"{_name(b)} {pt[b]['p90_m']:.2f}, point {pt[POINT]['p90_m']:.2f} "
            f"(coverage {_pct(pt[b]['coverage'])}, {_pct(pt[POINT]['coverage'])})", "lower",
            "NLS better" if f["nls_beats_point_p90"] else "NLS not better", syn)
        if "residual" in pt:
            add("residual pruning: 90 % of all distance errors under 4 m", "yes", f"{pt['residual']['p90_m']:.2f} m",
                "90th percentile < 4 m", "agrees" if pt["residual"]["p90_m"] < 4.0 else "differs",
                _assumption(f, "p90"))
    if "excess" in f:
        e = f["excess"]
        under = [p < 4.0 for p in e["p90_m"]]
        add("residual pruning: 90 % of all distance errors under 4 m, as the simulated NLOS excess is scaled", "yes",
            " / ".join(f"{p:.2f}" for p in e["p90_m"]) + " m at a mean excess of "
            + " / ".join(f"{m:g}" for m in e["nlos_mean_m"]) + " m", "90th percentile < 4 m at each",
            "agrees at each" if all(under) else "differs at each" if not any(under) else
            "depends on the assumed excess", _assumption(f, "excess"))
    if "geometry" in f:
        g = f["geometry"]
        known = tuple(h for h in g["ranking_known"] if h in g["ranking_3d_by_3d_error"])
        add("ranking in 3-D without a height, by 3-D median error (the robust mean has no 3-D version)", "—",
            " < ".join(_name(h) for h in g["ranking_3d_by_3d_error"]), "same order as at the known height",
            "same" if g["ranking_3d_by_3d_error"] == known else "changes", syn)
        add("5th percentile in 3-D: median height error (m; > 0: the node sits too high)", "—",
            f"{g['percentile_dz_bias_m']:+.2f}", "sign", "too high" if g["percentile_dz_bias_m"] > 0 else
            "too low" if g["percentile_dz_bias_m"] < 0 else "zero", syn)
    if "persistence" in f:
        p = f["persistence"]
        add(f"best heuristic as NLOS episodes lengthen ({p['base_s']:g} s → {p['long_s']:g} s)", "—",
            f"{_name(p['best_base'])} → {_name(p['best_long'])}", "the same heuristic",
            "same" if p["best_base"] == p["best_long"] else "changes", _assumption(f, "dwell"))
    words = {"better than": "NLS better", "as good as": "equal within 5 mm", "worse than": "NLS worse"}
    for k, v in f.get("lias_point_verdict", {}).items():
        t = f["lias_static_point"][k]
        best = min((h for h in t if h != POINT), key=lambda h: t[h][0])
        add(f"LIAS static, {k} ranges: best trajectory fit vs point fixes, median error (m)", "—",
            f"{_name(best)} {t[best][0]:.3f}, point {t[POINT][0]:.3f}", "5 mm counts as equal", words[v])
    if "lias_static" in f:
        s = f["lias_static"]
        add("LIAS static: range calibration vs the best pruning, median gain over plain NLS (m)", "—",
            f"{s['cal_gain_m']:.3f} vs {s['prune_gain_m']:.3f}", "larger gain",
            "calibration larger" if s["cal_gain_m"] > s["prune_gain_m"] else "pruning larger")
    for k, v in f.get("lias_dynamic", {}).items():
        add(f"LIAS dynamic, {k} ranges: plain NLS vs the best heuristic (mean error, m)", "—",
            f"{v['none_m']:.3f} vs {v['best_m']:.3f} ({_name(v['best'])})", "5 mm counts as equal", v["verdict"])
    for k, v in f.get("lias_dynamic_point", {}).items():
        if "paired" in v:
            p = v["paired"]
            interval = f"[{p['lo_m']:+.3f}, {p['hi_m']:+.3f}]" if p["side"] != "none" else "(no interval)"
            add(f"LIAS dynamic, {k} ranges: {_name(p['a'])} (fixed in advance) vs point fixes, "
                "median error on common epochs (m)",
                "—", f"{_name(p['a'])} {p['median_a_m']:.3f}, point {p['median_b_m']:.3f}: {p['diff_m']:+.3f} "
                f"{interval} ({p['n']} epochs)", "95 % block-bootstrap interval of the median difference vs 0",
                _PAIRED_VERDICT[p["side"]])
        elif "verdict" in v:
            m = v["median_m"]
            best = min((h for h in m if h != POINT), key=lambda h: m[h])
            add(f"LIAS dynamic, {k} ranges: best trajectory fit vs point fixes, median error (m)", "—",
                f"{_name(best)} {m[best]:.3f}, point {m[POINT]:.3f}", "5 mm counts as equal", words[v["verdict"]])
    if "hanyang" in f and "gap_m" in f["hanyang"]:
        add("Hanyang static: NLOS − LOS median range error (m)", "—", f"{f['hanyang']['gap_m']:+.2f}", "> 0",
            "NLOS larger" if f["hanyang"]["gap_m"] > 0 else "not larger")
    return pd.DataFrame(rows, columns=COLUMNS)
