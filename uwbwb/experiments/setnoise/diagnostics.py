"""Notebook 01's diagnostics of the synthetic study: one run of every estimator (Fig. 8), the set-noise PF
approaching the exact KF as K grows, and how well each noise model's σ explains the fix residuals."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...filters import setnoise as filt
from ...models.setnoise import SetNoiseModel
from ...types import SetFixLog
from .study import BASE_KF, BASE_PF, RAW, SET_KF, SET_PF, _noise

__all__ = ["FACILITY_WIDE", "PAPER_SIGMA_RULE", "POOLED_SIGMA_RULE", "pf_kf_gap", "residual_table", "trace"]


# --------------------------------------------------------------------------- Fig. 8 and PF → KF

def trace(log: SetFixLog, model: SetNoiseModel, sigma_d_mps: float, *, rng: np.random.Generator,
          n_particles: int = 1000, ess_fraction: float = 0.5) -> dict:
    """One run of every estimator on one recording (Fig. 8).

    Returns
    -------
    dict
        name → estimated positions ``(T, 2)``, metres, for ``truth``, ``raw`` and the four filters.
    """
    mu, sd = _noise(log, model)
    x0 = log.truth_m[0]
    pf = filt.pf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps, rng=rng, n_particles=n_particles,
                       ess_fraction=ess_fraction)
    kf = filt.kf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps)
    return {"truth": log.truth_m, RAW: log.pos_m, BASE_PF: pf.pos_m[0, 0, 0], SET_PF: pf.pos_m[1, 0, 0],
            BASE_KF: kf.pos_m[0, 0], SET_KF: kf.pos_m[1, 0]}


def pf_kf_gap(log: SetFixLog, model: SetNoiseModel, sigma_d_mps: float, n_particles=(30, 100, 300, 1000, 3000),
              *, n_trials: int = 10, rng: np.random.Generator) -> pd.DataFrame:
    """How far the set-noise PF is from the exact set-noise KF, against K.

    Returns
    -------
    DataFrame
        ``n_particles, rms_gap_m`` (RMS over trials and fixes of PF − KF position),
        ``pf_error_m`` (mean error of the PF), ``kf_error_m``.
    """
    mu, sd, _ = model.lookup(log.set_id)
    x0 = log.truth_m[0]
    kf = filt.kf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps)
    rows = []
    for K in n_particles:
        pf = filt.pf_sweep(log.t_s, log.pos_m, mu, sd, x0, sigma_d_mps, rng=rng, n_trials=n_trials,
                           n_particles=int(K))
        gap = pf.pos_m[0, :, 0] - kf.pos_m[0]
        rows.append({"n_particles": int(K), "rms_gap_m": float(np.sqrt(np.mean(np.sum(gap ** 2, axis=-1)))),
                     "pf_error_m": float(pf.mean_error_m(log.truth_m).mean()),
                     "kf_error_m": float(kf.mean_error_m(log.truth_m)[0])})
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------- consistency of the noise models

#: Row labels of :func:`residual_table`.
FACILITY_WIDE, PAPER_SIGMA_RULE, POOLED_SIGMA_RULE = "facility-wide", "set-noise (paper σ)", "set-noise (pooled σ)"


def residual_table(logs, model: SetNoiseModel, pooled: SetNoiseModel) -> pd.DataFrame:
    """Mean squared normalised fix residuals ``((z − x − μ)/σ)²`` of the facility-wide, paper-σ and pooled-σ models
    (1 when σ is right).

    Returns
    -------
    DataFrame
        Rows :data:`FACILITY_WIDE`, :data:`PAPER_SIGMA_RULE`, :data:`POOLED_SIGMA_RULE`;
        one column per log (1 where σ is right, above 1 where the model is overconfident).
    """
    models = {FACILITY_WIDE: model.facility_only(), PAPER_SIGMA_RULE: model, POOLED_SIGMA_RULE: pooled}
    out = {}
    for log in logs:
        looked_up = {name: m.lookup(log.set_id)[:2] for name, m in models.items()}
        out[log.name] = {name: float(np.mean(((log.error_m - mu) / sd) ** 2)) for name, (mu, sd) in looked_up.items()}
    return pd.DataFrame(out)
