"""Notebook 01's real-data summary rows and the checks the method must pass (looser under FAST).

The synthetic rows are :func:`headline_rows` (without ``improvement``: the synthetic numbers aimed at or
taken from the paper alone); :func:`real_rows` adds the real-data rows
(raw error, coverage and each filter's improvement per range variant, all *reproduced*), and
:func:`checks` raises ``AssertionError`` naming the first check that fails. The set shares, raw
errors and fix counts are targets and inputs: nothing here asserts the paper's value on them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from ...metrics import interval_side
from .real import RealStudy
from .study import BASE_KF, BASE_PF, PAPER, RAW, SET_KF, SET_KF_POOLED, SET_PF

__all__ = ["checks", "headline_rows", "real_rows", "verdicts"]


def real_rows(real_band: pd.DataFrame, studies: Mapping[str, RealStudy], data_label: str) -> list[dict]:
    """Summary rows of the real run: per range variant the raw error, the coverage and each filter's
    improvement in the 30–50 cm/s band.

    ``real_band`` is indexed by ``(variant, filter)`` with ``error_cm`` and ``improvement_pct``.
    """
    rows = []
    for variant in studies:
        b = real_band.loc[variant]
        rows.append(dict(quantity=f"real data, {variant} ranges: raw error, mean of tags",
                         value=b.loc[RAW, "error_cm"], unit="cm", data=data_label, kind="reproduced"))
        rows.append(dict(quantity=f"real data, {variant} ranges: coverage of the test epochs",
                         value=100 * studies[variant].coverage().loc["test", "coverage"], unit="%",
                         data=data_label, kind="reproduced"))
        for name in (SET_PF, BASE_PF, SET_KF, SET_KF_POOLED):
            rows.append(dict(quantity=f"real data, {variant} ranges: {name} improvement over raw, sigma_d 30-50 cm/s",
                             value=b.loc[name, "improvement_pct"], unit="%", data=data_label, kind="reproduced"))
    return rows


def checks(*, shares: Mapping, improvement: pd.DataFrame, off_improvement: pd.DataFrame,
           band_table: pd.DataFrame, gap: pd.DataFrame, resampler: Mapping[str, pd.DataFrame], real_band: pd.DataFrame,
           studies: Mapping[str, RealStudy], fast: bool) -> None:
    """What the method must do; raises ``AssertionError`` with the failing quantity.

    ``improvement``/``off_improvement``: band improvements of the mean recording per filter (paper's
    track, second track); ``band_table``: band errors per recording and filter (cm); ``gap``:
    :func:`.diagnostics.pf_kf_gap`; ``resampler``: as in :func:`verdicts`. The PF–KF tolerance is
    3 cm under ``fast`` and 1 cm otherwise.
    """
    assert shares["n_sets"] > 1 and shares["top1_share"] < 1, f"no set switching at the Fig. 3 location: {shares}"
    assert improvement.loc[SET_PF, "improvement_pct"] > 0 and improvement.loc[SET_KF, "improvement_pct"] > 0, \
        f"set-noise filters do not improve on raw: {improvement}"
    assert improvement.loc[SET_KF, "improvement_pct"] >= improvement.loc[BASE_KF, "improvement_pct"] - 2, \
        f"set-noise KF worse than the baseline KF: {improvement}"
    assert off_improvement.loc[BASE_KF, "improvement_pct"] > 0, "smoothing must help on the second track too"
    pf_kf = abs(band_table.loc["mean", SET_PF] - band_table.loc["mean", SET_KF])
    assert pf_kf < (3.0 if fast else 1.0), f"set-noise PF and KF differ by {pf_kf:.2f} cm in the band"
    assert gap["rms_gap_m"].iloc[-1] < 0.5 * gap["rms_gap_m"].iloc[0], f"PF does not approach the KF as K grows: {gap}"
    (ea, sa), (eb, sb) = (_mean(t, SET_PF) for t in resampler.values())
    assert abs(ea - eb) < 4 * np.hypot(sa, sb) + 0.3, f"the resamplers differ: {ea:.2f} against {eb:.2f} cm"
    for variant in studies:
        raw = real_band.loc[(variant, RAW), "error_cm"]
        assert 0 < raw < 50, f"real data, {variant} ranges: raw error {raw} cm"
        assert real_band.loc[(variant, SET_KF_POOLED), "error_cm"] < 1.2 * raw, \
            f"real data, {variant} ranges: pooled set-noise KF far worse than raw"
        cov = studies[variant].coverage()
        assert cov.loc["test", "coverage"] > 0.5, cov


# --------------------------------------------------------------------------- the synthetic rows

def headline_rows(*, shares: dict, table1: pd.DataFrame, improvement: pd.DataFrame | None = None,
                  off_improvement: pd.DataFrame | None = None) -> list[dict]:
    """Summary rows of the synthetic part of notebook 01, each with its ``kind``.

    Parameters
    ----------
    shares, table1
        :func:`set_shares` at the Fig. 3 location and :func:`table1`.
    improvement
        Band improvements of the mean over recordings, indexed by filter, columns
        ``improvement_pct, improvement_cm`` (:func:`band_summary` rows of ``"mean"``); None: the *target* and
        *input* rows alone (none of them a reproduction: the simulator's selection defaults were chosen so that
        the Fig. 3 location's set shares resemble Fig. 4, its error defaults so that the raw errors resemble
        Table I, and the fix counts follow from the track, the speeds and the fix rate taken from the paper).
    off_improvement
        The same for the off-calibration track, or None.

    Returns
    -------
    list of dict
        Keyword arguments of :meth:`uwbwb.metrics.Summary.add` without ``data``.
    """
    rows = []
    for i, r in table1.reset_index(drop=True).iterrows():
        paper = "paper_raw_error_cm" in r and not pd.isna(r.get("paper_raw_error_cm"))
        speed = f" ({int(r['paper_speed_cmps'])} cm/s)" if paper else ""
        rows.append(dict(quantity=f"raw error, recording {i + 1}{speed}", value=r["raw_error_cm"], unit="cm",
                         paper_value=r["paper_raw_error_cm"] if paper else None, kind="target"))
        rows.append(dict(quantity=f"fixes, recording {i + 1}", value=r["n_fixes"], unit="",
                         paper_value=r["paper_n_fixes"] if paper else None, kind="input"))
    rows.append(dict(quantity="top-5 set share at the Fig. 3 location", value=100 * shares["top5_share"], unit="%",
                     paper_value=PAPER["top5_share_pct"], kind="target"))
    rows.append(dict(quantity="top set share at the Fig. 3 location (paper: below 45 %)",
                     value=100 * shares["top1_share"], unit="%", paper_value=None, kind="target"))
    for name in (SET_PF, BASE_PF, SET_KF, BASE_KF, SET_KF_POOLED) if improvement is not None else ():
        paper = name == SET_PF
        rows.append(dict(quantity=f"{name} improvement over raw, sigma_d 30-50 cm/s, mean of 5 recordings",
                         value=improvement.loc[name, "improvement_pct"], unit="%",
                         paper_value=PAPER["improvement_pct"] if paper else None, kind="reproduced"))
        rows.append(dict(quantity=f"{name} improvement over raw (cm), sigma_d 30-50 cm/s, mean of 5 recordings",
                         value=improvement.loc[name, "improvement_cm"], unit="cm",
                         paper_value=PAPER["improvement_cm"] if paper else None, kind="reproduced"))
    if off_improvement is not None:
        for name in (SET_PF, BASE_PF, SET_KF, BASE_KF):
            rows.append(dict(quantity=f"{name} improvement over raw, sigma_d 30-50 cm/s, track away from "
                                      "calibration locations", value=off_improvement.loc[name, "improvement_pct"],
                             unit="%", paper_value=None, kind="reproduced"))
    return rows


# --------------------------------------------------------------------------- verdicts

#: The interval of every verdict row: ±2 Monte Carlo standard errors over the PF's trials.
VERDICT_RULE_SE = 2.0


def _mean(band: pd.DataFrame, name: str) -> tuple[float, float]:
    """``(error_cm, se_cm)`` of ``name`` in the ``"mean"`` row of a :func:`.study.band_summary` table."""
    row = band[(band["recording"] == "mean") & (band["filter"] == name)].iloc[0]
    return float(row["error_cm"]), float(row["se_cm"])


def verdicts(band: pd.DataFrame, off_band: pd.DataFrame, resampler: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """Notebook 01's claims as a table: ``claim, paper, ours, low, high, rule, verdict``.

    ``band``, ``off_band``: :func:`.study.band_summary` of the sweeps on the paper's track and away from the
    calibration locations; ``resampler``: resampler → :func:`.study.band_summary` of the set-noise PF on one
    recording (two resamplers; the row compares the first with the second).
    Every interval is ours ± :data:`VERDICT_RULE_SE` Monte Carlo standard errors over the PF's trials (the
    Kalman filters and the raw fixes have none): it covers the particle filter's randomness, not the draw
    of the simulated recordings. A difference between two estimators takes the standard error of a
    difference of independent means, an upper bound here (the filters share their draws within a trial).
    Two Kalman filters compared with each other have no Monte Carlo noise, so no interval and no verdict
    (*exact filters*); with one trial per point no row has an interval.
    Rules: a paper value *agrees* when it lies in the interval, else *differs*; a difference "A vs B: error
    reduction" (B's error minus A's) is *better* (A better) or *worse* when its interval excludes 0, else *not
    significant*.
    """
    raw, _ = _mean(band, RAW)
    pf, pf_se = _mean(band, SET_PF)
    kf, _ = _mean(band, SET_KF)
    paper_rule, diff_rule = "paper in interval", "difference excludes 0"
    claims = [("set-noise PF improvement over raw, σ_d 30-50 cm/s, mean of recordings (%)", PAPER["improvement_pct"],
               100 * (raw - pf) / raw, 100 * pf_se / raw, paper_rule),
              ("set-noise PF improvement over raw, σ_d 30-50 cm/s, mean of recordings (cm)", PAPER["improvement_cm"],
               raw - pf, pf_se, paper_rule)]
    for label, data in (("paper's track", band), ("track away from calibration", off_band)):
        for a, b in ((SET_PF, BASE_PF), (SET_KF, BASE_KF)):
            (ea, sa), (eb, sb) = _mean(data, a), _mean(data, b)
            claims.append((f"{a} vs {b}: error reduction, σ_d 30-50 cm/s, {label} (cm)", np.nan, eb - ea,
                           float(np.hypot(sa, sb)), diff_rule))
    claims.append((f"{SET_KF} vs {SET_PF}: error reduction, σ_d 30-50 cm/s, paper's track (cm)", np.nan, pf - kf, pf_se,
                   diff_rule))
    (a, (ea, sa)), (b, (eb, sb)) = ((r, _mean(t, SET_PF)) for r, t in resampler.items())
    claims.append((f"{a} vs {b} resampling: set-noise PF error reduction, {resampler[a]['recording'].iloc[0]} (cm)",
                   np.nan, eb - ea, float(np.hypot(sa, sb)), diff_rule))
    rows = []
    for claim, paper, ours, se, rule in claims:
        lo, hi = ours - VERDICT_RULE_SE * se, ours + VERDICT_RULE_SE * se
        if not np.isfinite(se):
            verdict = "no interval (fewer than two trials)"
        elif se == 0:
            verdict = "exact filters: no Monte Carlo interval"
        elif rule == paper_rule:
            verdict = {"contains": "agrees", "above": "differs: ours larger",
                       "below": "differs: ours smaller"}[interval_side(lo, hi, paper)]
        else:
            verdict = {"above": "better", "below": "worse", "contains": "not significant"}[interval_side(lo, hi)]
        rows.append({"claim": claim, "paper": paper, "ours": ours, "low": lo, "high": hi, "rule": rule,
                     "verdict": verdict})
    return pd.DataFrame(rows)
