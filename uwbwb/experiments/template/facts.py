"""The template's numbers and computed verdicts: :func:`facts` turns :class:`~.study.Results` into a
flat ``dict`` (the words around its verdicts are the notebook's, written by hand).

Rules
-----
* Accuracy is the RMSE on the epochs **both** methods cover (common epochs); each method's coverage
  (share of all epochs with an estimate) stands beside it.
* EKF vs LS: ``ΔRMSE = RMSE(EKF-RF) − RMSE(LS)`` on the common epochs, with a 95 % block-bootstrap
  interval (the package's one rule, :func:`uwbwb.metrics.block_bootstrap_difference`: blocks follow the
  autocorrelation of the paired errors, drawn with replacement, the two methods' errors kept paired).
  Interval entirely below 0 → ``"better"``; entirely above 0 → ``"worse"``; otherwise
  ``"no significant difference"``; fewer than :data:`uwbwb.metrics.MIN_BLOCKS` blocks → ``"no interval"``.
* NIS: the EKF's mean NIS per degree of freedom over its updates inside :data:`NIS_BAND` →
  ``"consistent"``, else ``"inconsistent"``.
"""

from __future__ import annotations

import numpy as np

from ... import metrics
from ...metrics import interval_side
from .study import Results

__all__ = ["NIS_BAND", "facts", "nis_verdict", "verdict"]

#: Mean NIS/dof band of a consistent filter.
NIS_BAND = (0.5, 2.0)


def verdict(lo_m: float, hi_m: float) -> str:
    """The EKF against LS from the interval of ΔRMSE (module docstring)."""
    return {"below": "better", "above": "worse", "contains": "no significant difference"}.get(
        interval_side(lo_m, hi_m), "no interval")


def nis_verdict(mean_nis_per_dof: float) -> str:
    return "consistent" if interval_side(*NIS_BAND, mean_nis_per_dof) == "contains" else "inconsistent"


def facts(res: Results) -> dict:
    """The numbers and verdicts of one study.

    Returns
    -------
    dict
        ``fast``, ``seed``, ``n_epochs``, ``n_common``, ``coverage[<method>]`` (0–1), ``rmse_m[<method>]``
        (common epochs), ``diff_m``, ``lo_m``, ``hi_m`` (ΔRMSE EKF-RF − LS and its interval), ``verdict``,
        ``nis_per_dof`` (mean over the EKF's updates), ``nis_verdict``, ``sigma_range_m``, ``driving_sigma_mps2``.
    """
    scores = metrics.score_epochs(res.errors_m)          # every method on the common epochs, coverage beside
    f = {"fast": res.fast, "seed": res.seed, "n_epochs": int(res.t_s.size), "n_common": scores["LS"].n_common,
         "sigma_range_m": res.config.sigma_range_m, "driving_sigma_mps2": res.config.driving_sigma_mps2}
    for s in scores:
        f[f"coverage[{s.name}]"] = s.coverage
        f[f"rmse_m[{s.name}]"] = s.stats(common={"rmse": metrics.rmse})["rmse"]
    d = metrics.block_bootstrap_difference(scores["EKF-RF"].common_m, scores["LS"].common_m,   # the package's one rule
                                           rng=np.random.default_rng(res.seed))
    f.update(diff_m=d["diff_m"], lo_m=d["lo_m"], hi_m=d["hi_m"], verdict=verdict(d["lo_m"], d["hi_m"]))
    nis = res.nis_per_dof[np.isfinite(res.nis_per_dof)]
    f["nis_per_dof"] = float(nis.mean()) if nis.size else np.nan
    f["nis_verdict"] = nis_verdict(f["nis_per_dof"])
    return f

