"""One common bound per recording, against which every method is placed.

Each method's *own* bound (:meth:`~.interface.Estimator.bound`) uses that method's own
measurement and motion model with its own tuning: RMSE / own bound near 1 says the method
does what its model promises (a consistency check), but the ratios of two methods are not
comparable — a method with a poor model has a loose bound and looks "efficient".

The **common bound** is the same for every method on a recording:

* *motion model*: of the random-walk, random-force and random-jerk models
  (:mod:`uwbwb.models.motion`) with driving noise on the grid :data:`REFERENCE_GRIDS`, the one
  with the highest likelihood of the **calibration** part's truth at the board's epochs
  (:func:`uwbwb.bounds.motion_log_likelihood`; the truth observed with white noise
  :data:`TRUTH_SIGMA_M`, an assumption; one free parameter per model, so the likelihoods are
  compared directly);
* *measurements*: every range of the scoring part at the calibrated per-anchor range noise
  (the robust σ — 1.4826 × the median absolute deviation — of the calibration residuals), **treated
  as Gaussian** and unbiased after the calibration (an assumption: real range errors have heavier
  tails and biases that the MAD σ leaves out) — the range information, which holds all the TDoA
  information and the common offset besides;
* *bound*: the posterior CRLB (Tichavský recursion, :func:`uwbwb.bounds.tracking_bound`) of
  that model, with the range information **evaluated along the one realised true track** of the
  scoring part (the range Jacobians at the true positions; not averaged over the model's random
  tracks), from a prior of 1 m per axis in position and 1 unit in each higher derivative at the
  tag's first epoch, horizontal block.

It bounds **causal** estimators only (filters: epochs up to the current one) that know the fitted
motion prior and the Gaussian range noise. A smoother (the windowed NLS fits each window to later
ranges as well) and a method with other information (the UWB/INS filters also use an IMU) may
legitimately go below it; so may any method on a track smoother than the fitted prior, or where the
ranges are less noisy than the calibration's MAD σ.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from .. import bounds
from ..models.motion import make_motion_model
from ..types import Recording
from .interface import _range_information
from .protocol import Calibration

__all__ = ["MIN_STRETCH_EPOCHS", "MIN_TRUTH_EPOCHS", "NO_COMMON_BOUND", "REFERENCE", "REFERENCE_GRIDS", "TRUTH_SIGMA_M",
           "common_bound", "fit_reference_motion"]

#: Key of the common bound's motion model in :attr:`Calibration.tuned`.
REFERENCE = "common bound"
#: Driving-noise grids (model units m/s, m/s², m/s³) searched for the common bound's motion model.
REFERENCE_GRIDS = {"RW": np.geomspace(0.01, 10.0, 13), "RF": np.geomspace(0.01, 50.0, 13),
                   "RJ": np.geomspace(0.01, 500.0, 13)}
#: Observation noise of the truth assumed when fitting the motion model, metres (an assumption:
#: motion capture is good to millimetres; a larger value favours smoother models).
TRUTH_SIGMA_M = 0.005
#: The motion model is fitted on stretches of truth longer than :data:`MIN_STRETCH_EPOCHS` epochs (split at truth gaps),
#: at least :data:`MIN_TRUTH_EPOCHS` epochs in all; with fewer there is no common bound.
MIN_STRETCH_EPOCHS, MIN_TRUTH_EPOCHS = 5, 10
#: What a board without a common bound says, in one line.
NO_COMMON_BOUND = (f"No common bound: the calibration part has fewer than {MIN_TRUTH_EPOCHS} epochs of truth in "
                   f"stretches longer than {MIN_STRETCH_EPOCHS} epochs, too few to fit its motion model.")


def _truth_runs(rec: Recording, tag: str, cal: Calibration) -> list[tuple[np.ndarray, np.ndarray]]:
    """Contiguous stretches of truth at the tag's epochs (split at truth gaps), ``(t_s, pos_m)``."""
    t = rec.ranges[tag].t_s
    pos = rec.truth_at(tag, t, cal.dim)
    ok = np.all(np.isfinite(pos), axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(int), [0]])))
    return [(t[a:b], pos[a:b]) for a, b in zip(edges[::2], edges[1::2]) if b - a > MIN_STRETCH_EPOCHS]


def fit_reference_motion(rec: Recording, tags: Sequence[str], cal: Calibration,
                         grids: Mapping[str, Sequence[float]] | None = None) -> dict:
    """Choose the common bound's motion model on the calibration part ``rec`` (module docstring).

    Returns
    -------
    dict
        ``model`` and ``sigma_w`` chosen; ``loglik_per_epoch`` per model (at its best σ_w) and
        ``sigma_w_per_model``; ``n_epochs`` used. Empty with fewer than :data:`MIN_TRUTH_EPOCHS` epochs of truth
        (:data:`NO_COMMON_BOUND`).
    """
    grids = REFERENCE_GRIDS if grids is None else grids
    runs = [r for t in tags for r in _truth_runs(rec, t, cal)]
    n = sum(r[0].size for r in runs)
    if n < MIN_TRUTH_EPOCHS:
        return {}
    dt = 1.0 / cal.rate_hz
    best = {}
    for name, grid in grids.items():
        models = [make_motion_model(name, sigma=float(s), dt_s=dt, dim=cal.dim) for s in grid]
        ll = sum(bounds.motion_log_likelihood(models, t, p, TRUTH_SIGMA_M, skip=3) for t, p in runs)
        k = int(np.argmax(ll))
        best[name] = (float(grid[k]), float(ll[k]) / n)
    model = max(best, key=lambda m: best[m][1])
    return {"model": model, "sigma_w": best[model][0], "n_epochs": int(n),
            "loglik_per_epoch": {m: v[1] for m, v in best.items()},
            "sigma_w_per_model": {m: v[0] for m, v in best.items()}}


def common_bound(rec: Recording, tag: str, cal: Calibration) -> bounds.Bound | None:
    """The common bound along ``tag``'s epochs of the scoring part ``rec`` (None if ``cal`` has no model).

    The recursion runs over every epoch of the tag (from the first with truth); epochs without
    truth carry no information and get NaN.
    """
    p = cal.params(REFERENCE)
    if "model" not in p:
        return None
    log = rec.ranges_of(tag, cal.range_calibration)
    info, have = _range_information(rec, tag, cal, log)
    C = np.full((len(log), cal.dim, cal.dim), np.nan)
    kind = f"PCRLB {p['model']} (common)"
    if have.any():
        motion = make_motion_model(p["model"], sigma=p["sigma_w"], dt_s=1.0 / cal.rate_hz, dim=cal.dim)
        k0 = int(np.flatnonzero(have)[0])
        C[k0:] = bounds.tracking_bound(motion, log.t_s[k0:], info[k0:], motion.initial_covariance(1.0, 1.0, 1.0))
        C[~have] = np.nan
    return bounds.Bound(log.t_s, C, kind)
