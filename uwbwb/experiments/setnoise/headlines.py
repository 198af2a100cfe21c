"""Notebook 01's real-data summary rows and the checks the method must pass (looser under FAST).

The synthetic rows are :func:`.study.headline_rows`; :func:`real_rows` adds the real-data rows
(raw error, coverage and each filter's improvement per range variant, all *reproduced*), and
:func:`checks` raises ``AssertionError`` naming the first check that fails. The set shares, raw
errors and fix counts are targets and inputs: nothing here asserts the paper's value on them.
"""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd

from .real import RealStudy
from .study import BASE_KF, BASE_PF, RAW, REPRODUCED, SET_KF, SET_KF_POOLED, SET_PF

__all__ = ["checks", "real_rows"]


def real_rows(real_band: pd.DataFrame, studies: Mapping[str, RealStudy], data_label: str) -> list[dict]:
    """Summary rows of the real run: per range variant the raw error, the coverage and each filter's
    improvement in the 30–50 cm/s band.

    ``real_band`` is indexed by ``(variant, filter)`` with ``error_cm`` and ``improvement_pct``.
    """
    rows = []
    for variant in studies:
        b = real_band.loc[variant]
        rows.append(dict(quantity=f"real data, {variant} ranges: raw error, mean of tags",
                         value=b.loc[RAW, "error_cm"], unit="cm", data=data_label, kind=REPRODUCED))
        rows.append(dict(quantity=f"real data, {variant} ranges: coverage of the test epochs",
                         value=100 * studies[variant].coverage().loc["test", "coverage"], unit="%",
                         data=data_label, kind=REPRODUCED))
        for name in (SET_PF, BASE_PF, SET_KF, SET_KF_POOLED):
            rows.append(dict(quantity=f"real data, {variant} ranges: {name} improvement over raw, sigma_d 30-50 cm/s",
                             value=b.loc[name, "improvement_pct"], unit="%", data=data_label, kind=REPRODUCED))
    return rows


def checks(*, shares: Mapping, improvement: pd.DataFrame, off_improvement: pd.DataFrame,
           band_table: pd.DataFrame, gap: pd.DataFrame, resampler: Mapping, real_band: pd.DataFrame,
           studies: Mapping[str, RealStudy], fast: bool) -> None:
    """What the method must do; raises ``AssertionError`` with the failing quantity.

    ``improvement``/``off_improvement``: band improvements of the mean recording per filter (paper's
    track, second track); ``band_table``: band errors per recording and filter (cm); ``gap``:
    :func:`.study.pf_kf_gap`; ``resampler``: :func:`.study.resampler_check`. The PF–KF tolerance is
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
    assert abs(resampler["diff_cm"]) < 4 * resampler["se_diff_cm"] + 0.3, resampler
    for variant in studies:
        raw = real_band.loc[(variant, RAW), "error_cm"]
        assert 0 < raw < 50, f"real data, {variant} ranges: raw error {raw} cm"
        assert real_band.loc[(variant, SET_KF_POOLED), "error_cm"] < 1.2 * raw, \
            f"real data, {variant} ranges: pooled set-noise KF far worse than raw"
        cov = studies[variant].coverage()
        assert cov.loc["test", "coverage"] > 0.5, cov
