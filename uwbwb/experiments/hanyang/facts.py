"""Verdicts of the Hanyang study, computed from its tables: ``*_facts`` return the numbers and the verdict by
its rule, :func:`verdict_table` lays them out (claim, ours, interval, rule, verdict). The thresholds are the
rules below, never tuned to a run.

* Reproduction (:func:`reproduction_facts`): the authors' numbers are *reproduced* when every
  recomputed RMSE is within :data:`REPRO_TOL_M` of their ``RMSD_results.txt``.
* Ours vs theirs per case (:func:`ratio_facts`), on the epochs both covered: ``better`` when the 95 %
  block-bootstrap interval of RMSE(ours) / RMSE(their LS) lies below 1, ``worse`` when above 1, else
  ``not significant``; with fewer than :data:`uwbwb.metrics.MIN_BLOCKS` independent blocks (the package's
  one interval rule, :func:`uwbwb.metrics.block_bootstrap_difference`) no verdict is given.
* Static range model (:func:`static_facts`): ``helps`` on a case when the interval of
  RMSE(LS on statically corrected ranges) / RMSE(raw LS) lies below 1, ``hurts`` above 1, else
  ``no clear effect``; the answer to "does it help?" is *yes* only if it helps on every case scored.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...metrics import MIN_BLOCKS, interval_side

__all__ = ["NO_VERDICT", "PICKS", "REPRO_TOL_M", "interval_verdict", "pair_verdict", "ratio_facts", "reproduction_facts",
           "static_facts", "summary_rows", "verdict_table"]

#: Largest difference between our recomputation and the authors' published RMSE called agreement, m.
REPRO_TOL_M = 0.01


def interval_verdict(lo: float, hi: float, low: str, high: str, neither: str) -> str:
    """``low`` if the interval lies below 1, ``high`` if above, ``neither`` otherwise (or ``"no interval"``)."""
    return {"below": low, "above": high, "contains": neither}.get(interval_side(lo, hi, 1.0), "no interval")


NO_VERDICT = "no verdict: too few independent blocks"


def pair_verdict(lo: float, hi: float, n_blocks: int, low: str, high: str, neither: str,
                 min_blocks: int = MIN_BLOCKS) -> str:
    """:func:`interval_verdict`, refused (:data:`NO_VERDICT`) with fewer than ``min_blocks`` blocks."""
    if not n_blocks >= min_blocks:
        return f"{NO_VERDICT} ({int(n_blocks)} < {min_blocks})"
    return interval_verdict(lo, hi, low, high, neither)


def reproduction_facts(repro: pd.DataFrame, tol_m: float = REPRO_TOL_M) -> dict:
    """Largest |ours − published| over the rows that have a published value, and the verdict."""
    have = repro[np.isfinite(repro["published_m"])]
    worst = float(np.max(np.abs(have["diff_m"]))) if len(have) else float("nan")
    return {"n_rows": int(len(repro)), "n_published": int(len(have)), "max_abs_diff_m": worst, "tol_m": tol_m,
            "n_cases": int(repro["data"].nunique()) if len(repro) else 0,
            "agree": bool(len(have)) and bool(worst <= tol_m)}


def ratio_facts(ratios: pd.DataFrame, pick: str = "best") -> dict:
    """Per case, our ranges-only method marked ``pick`` (``"best"``: lowest RMSE on the scored case;
    ``"chosen"``: best on the case it was tuned on) against the authors' LS, and the spread across cases."""
    best = ratios[ratios[pick].astype(bool)] if len(ratios) and pick in ratios else ratios.iloc[:0]
    cases = []
    for r in best.itertuples(index=False):
        cases.append({"case": r.case, "method": r.method, "ratio": float(r.ratio), "lo": float(r.ratio_lo),
                      "hi": float(r.ratio_hi), "ours_m": float(r.rmse_2d_m), "theirs_m": float(r.authors_ls_rmse_2d_m),
                      "coverage": float(r.coverage), "coverage_theirs": float(r.coverage_authors_ls),
                      "n": int(r.n), "n_blocks": int(r.n_blocks),
                      "verdict": pair_verdict(r.ratio_lo, r.ratio_hi, r.n_blocks, "better", "worse", "not significant")})
    ratio = np.array([c["ratio"] for c in cases])
    return {"pick": pick, "cases": cases, "n_cases": len(cases),
            "mean_ratio": float(np.mean(ratio)) if ratio.size else float("nan"),
            "sd_ratio": float(np.std(ratio, ddof=1)) if ratio.size > 1 else float("nan"),
            "min_ratio": float(np.min(ratio)) if ratio.size else float("nan"),
            "max_ratio": float(np.max(ratio)) if ratio.size else float("nan"),
            "n_better": sum(c["verdict"] == "better" for c in cases),
            "n_worse": sum(c["verdict"] == "worse" for c in cases),
            "n_no_verdict": sum(c["verdict"].startswith(NO_VERDICT) for c in cases)}


#: The two picks of our ranges-only method against the authors' LS.
PICKS = {"best": "best on the scored case (optimistic)",
         "chosen": "picked on the tuning case alone (nothing of the scored case enters the pick)"}


def static_facts(effect: pd.DataFrame) -> dict:
    """Per case and static model: the ratio to raw LS, its interval and verdict; the yes/no answer."""
    rows = []
    for r in effect.itertuples(index=False):
        rows.append({"case": r.case, "method": r.method, "ratio": float(r.ratio_vs_raw_ls),
                     "lo": float(r.ratio_vs_raw_ls_lo), "hi": float(r.ratio_vs_raw_ls_hi),
                     "verdict": pair_verdict(r.ratio_vs_raw_ls_lo, r.ratio_vs_raw_ls_hi,
                                             getattr(r, "ratio_vs_raw_ls_n_blocks", MIN_BLOCKS), "helps", "hurts",
                                             "no clear effect")})
    helps = [r["verdict"] == "helps" for r in rows]
    return {"rows": rows, "n": len(rows), "n_helps": int(sum(helps)),
            "n_hurts": sum(r["verdict"] == "hurts" for r in rows),
            "answer": "yes" if rows and all(helps) else "no"}


def verdict_table(repro: dict, picks: dict[str, dict], static: dict) -> pd.DataFrame:
    """The Hanyang verdicts, one row each: ``claim, ours, interval, rule, verdict``.

    ``repro``: :func:`reproduction_facts`; ``picks``: ``{pick: ratio_facts(..., pick)}``; ``static``:
    :func:`static_facts`. Rows: the authors' numbers recomputed; per pick and case, ours / their LS on the epochs
    both covered; per pick, the count of verdicts over the cases; per case and static model, its effect on raw
    LS and the yes/no answer."""
    rows = []

    def add(claim, ours, interval, rule, verdict):
        rows.append({"claim": claim, "ours": ours, "interval": interval, "rule": rule, "verdict": verdict})

    def iv(lo, hi, fmt):
        return f"[{lo:{fmt}}, {hi:{fmt}}]" if np.isfinite(lo) and np.isfinite(hi) else "—"

    add("authors' RMSE and RMSE_2d recomputed (their definition) vs RMSD_results.txt: largest absolute difference (cm)",
        f"{100 * repro['max_abs_diff_m']:.2g}" if repro["n_published"] else "—", "—",
        f"within {100 * repro['tol_m']:.0f} cm",
        ("agree" if repro["agree"] else "DISAGREE") if repro["n_published"] else "no published values")
    ratio_rule = "95 % block bootstrap of the ratio: below 1 better, above 1 worse"
    for pick, f in picks.items():
        for c in f["cases"]:
            add(f"{c['case']}: {c['method']} ({PICKS[pick]}) / authors LS, RMSE_2d on {c['n']} common epochs "
                f"({c['n_blocks']} blocks)", f"{c['ratio']:.2f}", iv(c["lo"], c["hi"], ".2f"), ratio_rule,
                c["verdict"])
        if f["n_cases"]:
            sd = f" (sd {f['sd_ratio']:.2f})" if np.isfinite(f["sd_ratio"]) else ""
            add(f"ours ({PICKS[pick]}) / authors LS over {f['n_cases']} case(s): mean ratio", f"{f['mean_ratio']:.2f}{sd}",
                f"range {f['min_ratio']:.2f}–{f['max_ratio']:.2f}", "count of the per-case verdicts",
                f"better {f['n_better']}, worse {f['n_worse']}, no verdict {f['n_no_verdict']}, not significant "
                f"{f['n_cases'] - f['n_better'] - f['n_worse'] - f['n_no_verdict']}")
    for r in static["rows"]:
        add(f"{r['case']}: {r['method']} / raw LS, RMSE_2d (static bias-vs-distance model on the dynamic ranges)",
            f"{r['ratio']:.3f}", iv(r["lo"], r["hi"], ".3f"), "95 % interval below 1 helps, above 1 hurts",
            r["verdict"])
    if static["n"]:
        add("does the static range model help on every (case, model) scored?", f"helps on {static['n_helps']} of "
            f"{static['n']}", "—", "yes only if it helps on every one", static["answer"])
    return pd.DataFrame(rows)


#: Data label suffix of rows that are numbers of the authors' estimates (their LS.csv / ESKF.csv): *external*.
EXTERNAL = " (external: authors' estimates)"


def summary_rows(comparison, summary) -> None:
    """Headline numbers into a :class:`uwbwb.metrics.Summary`, ``data=hanyang-outdoor-uwb/<case>`` per case.

    Numbers of the authors' estimates — published, recomputed by our metric code, and their LS on a pair's
    epochs — are kind ``input`` (they are not the output of a method of ours) with the data label
    ``hanyang-outdoor-uwb/<case>`` + :data:`EXTERNAL`. Our method's RMSE_2d and the ratio ours / theirs
    are ``reproduced``."""
    repro = comparison.reproduction
    for r in repro.itertuples(index=False):
        if r.metric != "RMSE 2-D":
            continue
        if np.isfinite(r.published_m):
            summary.add(quantity=f"authors {r.method} RMSE_2d, published", value=r.published_m, unit="m",
                        data=r.data + EXTERNAL, kind="input")
        summary.add(quantity=f"authors {r.method} RMSE_2d, recomputed (their definition)", value=r.reproduced_m,
                    unit="m", data=r.data + EXTERNAL, kind="input",
                    paper_value=r.published_m if np.isfinite(r.published_m) else None)
    ratios = comparison.ratios
    theirs_added = set()
    for pick, what in (("best", "best on the scored case"), ("chosen", "picked on the tuning case")):
        if not len(ratios) or pick not in ratios:
            continue
        for r in ratios[ratios[pick].astype(bool)].itertuples(index=False):
            on = f"epochs of {r.method} ∩ authors LS"
            summary.add(quantity=f"RMSE_2d, our ranges-only method {what} ({r.method}, {on})",
                        value=r.rmse_2d_m, unit="m", data=r.data, kind="reproduced")
            if (r.data, on) not in theirs_added:
                theirs_added.add((r.data, on))
                summary.add(quantity=f"RMSE_2d, authors LS ({on})", value=r.authors_ls_rmse_2d_m, unit="m",
                            data=r.data + EXTERNAL, kind="input")
            summary.add(quantity=f"RMSE_2d ratio ours ({what}) / authors LS", value=r.ratio, unit="", data=r.data,
                        kind="reproduced")
