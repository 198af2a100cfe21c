"""Notebook 03's headline rows for the reproduction summary, each with its kind (*reproduced* or
*target*) and, for the synthetic re-creation, the thesis' value beside it.
"""

from __future__ import annotations

from typing import Iterable, Mapping

import numpy as np

from ... import metrics
from ...models.motion import MOTION_MODELS
from .results import MODELS, PAPER_METHODS_CEP95, PAPER_MODELS_CEP95, PAPER_SIGMA, TagResults, ekf_name

__all__ = ["SIGMA_KIND", "record", "sigma_rows", "summary_rows"]

#: Kind of each calibrated driving σ in the summary. The simulated targets move at a speed
#: chosen equal to the thesis' random-walk σ (0.83 m/s walking, 1 m/s AGV; the thesis gives no
#: speeds), so the calibrated RW σ lands near the thesis' value by construction: a *target*.
SIGMA_KIND = {"RW": "target", "RF": "reproduced", "RJ": "reproduced"}


def sigma_rows(best: Mapping[str, float], scenario: str) -> list[dict]:
    """Summary rows of the calibrated driving σ of one synthetic scenario (``"office"``/``"agv"``), with kind."""
    return [{"quantity": f"driving sigma {m} ({scenario})", "value": float(best[m]),
             "unit": MOTION_MODELS[m].sigma_unit, "data": "synthetic", "paper_value": PAPER_SIGMA[scenario][m],
             "kind": SIGMA_KIND[m]} for m in MODELS if m in best]


def summary_rows(results: Iterable[TagResults], *, data: str, label: str = "{run} {tag} {method}",
                 paper: bool = False) -> list[dict]:
    """Headline rows of test results: CEP95 on common epochs, coverage, mean NIS/dof (all *reproduced*).

    Parameters
    ----------
    results
        Test results.
    data
        Summary ``data`` label (``"synthetic"`` or ``"dataset/recording"``).
    label
        Format of the quantity's name with fields ``run``, ``tag``, ``method``.
    paper
        Attach the thesis' CEP95 (Tables 2–5) where ``(run, tag)`` is one of its rows;
        for the AGV runs the random-walk EKF also gets a row against Table 5, which
        disagrees with Table 4 on acquisition 1 tag 1.
    """
    rows = []
    for res in results:
        key = (res.run.name, res.run.tag)
        c, cov = res.cep95(), res.coverage()
        nis = res.nis()["mean_nis_over_dof"]

        def name(method):
            return label.format(run=res.run.name, tag=res.run.tag, method=method)

        for meth in c:
            pv = None
            if paper:
                pv = PAPER_METHODS_CEP95.get(key, {}).get(meth, PAPER_MODELS_CEP95.get(key, {}).get(meth))
            rows.append({"quantity": f"CEP95 {name(meth)}", "value": c[meth], "unit": "m", "data": data,
                         "paper_value": pv, "kind": "reproduced"})
        if paper and key[0].startswith("agv") and key in PAPER_MODELS_CEP95:
            rows.append({"quantity": f"CEP95 {name('EKF-RW')} (vs thesis Table 5)", "value": c["EKF-RW"],
                         "unit": "m", "data": data, "paper_value": PAPER_MODELS_CEP95[key]["EKF-RW"],
                         "kind": "reproduced"})
        for meth in c:
            rows.append({"quantity": f"coverage {name(meth)}", "value": 100 * cov[meth], "unit": "%", "data": data,
                         "paper_value": None, "kind": "reproduced"})
        for m, v in nis.items():
            if np.isfinite(v):
                rows.append({"quantity": f"mean NIS/dof {name(ekf_name(m))}", "value": float(v), "unit": "",
                             "data": data, "paper_value": None, "kind": "reproduced"})
    return rows


def record(summary: metrics.Summary, rows: Iterable[dict]) -> None:
    """Add :func:`summary_rows` / :func:`sigma_rows` rows to a :class:`~uwbwb.metrics.Summary`."""
    for r in rows:
        summary.add(**r)
