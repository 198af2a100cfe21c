"""Back end of the template's slider panel: the settings it offers, the cached study behind each
setting, and what one setting draws and its verdicts.

The callback of a panel built with :mod:`uwbwb.widgets` calls :func:`draw` and :func:`readout`; both
recompute only through :func:`run`, which is cached on the (frozen, hashable) setting, so moving a
slider back is instant and a headless run gives the same numbers.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import matplotlib.pyplot as plt

from ... import validate
from .facts import facts, verdict_table
from .figures import cdf_figure, paths_figure
from .study import FAST, FULL, Results, run_study

__all__ = ["DRIVING_SIGMAS_MPS2", "RANGE_SIGMAS_M", "run", "draw", "readout"]

#: Driving σ of the EKF offered by the slider (m/s²).
DRIVING_SIGMAS_MPS2 = (0.1, 0.3, 0.5, 1.0, 2.0)
#: Range noise σ offered by the slider (m).
RANGE_SIGMAS_M = (0.05, 0.10, 0.20)


@lru_cache(maxsize=32)
def run(driving_sigma_mps2: float, sigma_range_m: float, *, seed: int = 0, fast: bool = True) -> Results:
    """The study at one setting (cached)."""
    validate.number("driving_sigma_mps2", driving_sigma_mps2, minimum=0.0, strict_minimum=True)
    validate.number("sigma_range_m", sigma_range_m, minimum=0.0, strict_minimum=True)
    cfg = replace(FAST if fast else FULL, driving_sigma_mps2=float(driving_sigma_mps2),
                  sigma_range_m=float(sigma_range_m))
    return run_study(fast=fast, seed=seed, config=cfg)


def readout(driving_sigma_mps2: float, sigma_range_m: float, *, seed: int = 0, fast: bool = True):
    """The verdict table of one setting (:func:`.facts.verdict_table`)."""
    return verdict_table(facts(run(driving_sigma_mps2, sigma_range_m, seed=seed, fast=fast)))


def draw(driving_sigma_mps2: float, sigma_range_m: float, *, seed: int = 0, fast: bool = True, axes=None):
    """Paths and error CDFs of one setting into ``axes`` (two Axes; a new figure if None). Returns the Axes."""
    if axes is None:
        _, axes = plt.subplots(1, 2, figsize=(10, 4))
    res = run(driving_sigma_mps2, sigma_range_m, seed=seed, fast=fast)
    paths_figure(res, axes[0])
    cdf_figure(res, axes[1])
    return axes
