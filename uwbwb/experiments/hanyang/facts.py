"""Verdicts of the Hanyang study, computed from its tables: ``*_facts`` return the numbers and the rule,
``*_sentence`` write them out. The thresholds are the rules below, never tuned to a run.

* Reproduction (:func:`reproduction_facts`): the authors' numbers are *reproduced* when every
  recomputed RMSE is within :data:`REPRO_TOL_M` of their ``RMSD_results.txt``.
* Ours vs theirs per case (:func:`ratio_facts`), on the epochs both covered: ``better`` when the 95 %
  block-bootstrap interval of RMSE(ours) / RMSE(their LS) lies below 1, ``worse`` when above 1, else
  ``not significant``; with fewer than :data:`~.study.MIN_BLOCKS` independent blocks (block length from
  the autocorrelation of the paired difference, :func:`~.study.block_length_s`) no verdict is given.
* Static range model (:func:`static_facts`): ``helps`` on a case when the interval of
  RMSE(LS on statically corrected ranges) / RMSE(raw LS) lies below 1, ``hurts`` above 1, else
  ``no clear effect``; the answer to "does it help?" is *yes* only if it helps on every case scored.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .study import MIN_BLOCKS

__all__ = ["NO_VERDICT", "REPRO_TOL_M", "interval_verdict", "pair_verdict", "ratio_facts", "ratio_sentence", "reproduction_facts",
           "reproduction_sentence", "sensitivity_sentence", "static_facts", "static_sentence", "summary_rows"]

#: Largest difference between our recomputation and the authors' published RMSE called agreement, m.
REPRO_TOL_M = 0.01


def interval_verdict(lo: float, hi: float, low: str, high: str, neither: str) -> str:
    """``low`` if the interval lies below 1, ``high`` if above, ``neither`` otherwise (or ``"no interval"``)."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "no interval"
    if hi < 1.0:
        return low
    if lo > 1.0:
        return high
    return neither


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


def reproduction_sentence(f: dict) -> str:
    if not f["n_published"]:
        return "No RMSD_results.txt to compare with: the authors' numbers are recomputed but not checked."
    verb = "agree with" if f["agree"] else "DISAGREE with"
    return (f"Recomputed with the workbench's metric code, the authors' RMSE and RMSE_2d on {f['n_cases']} case(s) "
            f"{verb} their RMSD_results.txt: largest difference {f['max_abs_diff_m'] * 100:.2g} cm "
            f"(rule: within {f['tol_m'] * 100:.0f} cm).")


def ratio_facts(ratios: pd.DataFrame, pick: str = "best") -> dict:
    """Per case, our ranges-only method marked ``pick`` (``"best"``: lowest RMSE on the scored case;
    ``"chosen"``: best on the case it was tuned on) against the authors' LS, and the spread across cases."""
    best = ratios[ratios[pick].astype(bool)] if len(ratios) and pick in ratios else ratios.iloc[:0]
    cases = []
    for r in best.itertuples(index=False):
        cases.append({"case": r.case, "method": r.method, "ratio": float(r.ratio), "lo": float(r.ratio_lo),
                      "hi": float(r.ratio_hi), "ours_m": float(r.rmse_2d_m), "theirs_m": float(r.authors_ls_rmse_2d_m),
                      "coverage": float(r.coverage), "coverage_theirs": float(r.coverage_authors_ls),
                      "n": int(r.n), "n_blocks": int(r.n_blocks), "block_s": float(r.block_s),
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


_PICKS = {"best": "Our best ranges-only method (picked on the scored case itself: optimistic)",
          "chosen": "Our ranges-only method picked on the tuning case alone (tuned on the first half of its "
                    "window, picked by the lowest ratio to the authors' LS on the second half: nothing of the "
                    "scored case enters the pick)"}


def ratio_sentence(f: dict) -> str:
    if not f["n_cases"]:
        return (f"{_PICKS[f['pick']]}: no case to report (the pick needs the board of the tuning case too)"
                if f["pick"] == "chosen" else "No case had both our methods and the authors' LS on common epochs.")
    per = "; ".join(f"{c['case']}: {c['method']} {c['ours_m']:.2f} m vs their LS {c['theirs_m']:.2f} m on the "
                    f"{c['n']} epochs both covered (coverage ours {c['coverage']:.0%}, theirs {c['coverage_theirs']:.0%}), "
                    f"ratio {c['ratio']:.2f} [{c['lo']:.2f}, {c['hi']:.2f}] ({c['n_blocks']} blocks of "
                    f"{c['block_s']:.1f} s) — {c['verdict']}" for c in f["cases"])
    spread = (f", sd {f['sd_ratio']:.2f}" if np.isfinite(f["sd_ratio"]) else "")
    return (f"{_PICKS[f['pick']]} against the authors' LS, RMSE_2d — {per}. Across {f['n_cases']} case(s) the ratio "
            f"ours/theirs is {f['mean_ratio']:.2f} on average{spread} (range {f['min_ratio']:.2f}–{f['max_ratio']:.2f}); "
            f"better on {f['n_better']}, worse on {f['n_worse']}, no verdict on {f['n_no_verdict']}, not "
            f"distinguishable on {f['n_cases'] - f['n_better'] - f['n_worse'] - f['n_no_verdict']}.")


def sensitivity_sentence(ratios: pd.DataFrame, pick: str = "chosen") -> str:
    """How the ratio of the ``pick`` rows moves with the reference clock offset changed by ±0.1 s and against
    the authors' LS with its latency removed (columns of :func:`~.study.ratio_table`, where present)."""
    rows = ratios[ratios[pick].astype(bool)] if len(ratios) and pick in ratios else ratios.iloc[:0]
    if not len(rows):
        return "No sensitivity check to report."
    parts = []
    for r in rows.to_dict("records"):
        bits = [f"{r['ratio']:.2f} as scored"]
        if np.isfinite(r.get("ratio_dt-0.1s", np.nan)) and np.isfinite(r.get("ratio_dt+0.1s", np.nan)):
            bits.append(f"{r['ratio_dt-0.1s']:.2f} / {r['ratio_dt+0.1s']:.2f} with the reference clock offset "
                        f"moved by −0.1 / +0.1 s")
        if np.isfinite(r.get("nolat_ratio", np.nan)):
            bits.append(f"{r['nolat_ratio']:.2f} against their LS with its output latency removed")
        parts.append(f"{r['case']} ({r['method']}): " + ", ".join(bits))
    return ("Sensitivity of the ratio ours/theirs (the loader's clock registration and the board's own clock "
            "check differ by about 0.1 s) — " + "; ".join(parts) + ".")


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


def static_sentence(f: dict) -> str:
    if not f["n"]:
        return "The static range model was not applied (no static files, or no case scored)."
    per = "; ".join(f"{r['case']}, {r['method']}: ×{r['ratio']:.3f} [{r['lo']:.3f}, {r['hi']:.3f}] ({r['verdict']})"
                    for r in f["rows"])
    return (f"Does calibrating the dynamic ranges with the static bias-vs-distance help? **{f['answer']}**. "
            f"RMSE_2d of LS on statically corrected ranges relative to raw LS — {per}. It helps on {f['n_helps']} "
            f"and hurts on {f['n_hurts']} of {f['n']} (case, model) pairs.")


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
