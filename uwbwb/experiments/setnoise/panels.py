"""Back end of notebook 01's widget: the set-noise PF explorer (Fig. 8 style).

:class:`Explorer` holds the recordings the panel offers (the synthetic ones on the paper's track,
those away from the calibration locations, and each tag of the real run), runs every estimator
once per setting (cached) and draws the first 200 fixes; :meth:`Explorer.panel` builds the widget.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np

from ... import widgets
from ...models.setnoise import SetNoiseModel
from ...types import SetFixLog
from .figures import plot_trace
from .diagnostics import trace
from .study import BASE_PF, RAW, SET_KF, SET_PF

__all__ = ["Explorer"]


class Explorer:
    """Every estimator on one recording at one setting (cached), its mean errors and its figure; ``logs`` is
    ``{label: (recording, set-noise model)}``."""

    def __init__(self, logs: Mapping[str, tuple[SetFixLog, SetNoiseModel]]):
        self.logs = dict(logs)
        self.run = functools.lru_cache(maxsize=64)(self._run)

    def _run(self, recording: str, sigma_d_cmps: float, n_particles: int, ess_fraction: float, seed: int):
        """``(estimates, {"<estimator> mean error (cm)": value})`` of one setting."""
        log, model = self.logs[recording]
        est = trace(log, model, sigma_d_cmps / 100, rng=np.random.default_rng(seed), n_particles=n_particles,
                    ess_fraction=ess_fraction)
        return est, {f"{name} mean error (cm)": 100 * float(np.linalg.norm(e - log.truth_m, axis=1).mean())
                     for name, e in est.items() if name != "truth"}

    def readout(self, values: Mapping) -> dict:
        """The mean errors of the panel's current ``values``."""
        return self.run(values["recording"], values["sigma_d_cmps"], values["n_particles"],
                        values["ess_fraction"], values["seed"])[1]

    def render(self, recording: str, sigma_d_cmps: float, n_particles: int, ess_fraction: float, seed: int):
        est, errors = self.run(recording, sigma_d_cmps, n_particles, ess_fraction, seed)
        fig, ax = plt.subplots(figsize=(11, 4))
        plot_trace(est, ax=ax, index=slice(0, 200), names=(RAW, BASE_PF, SET_PF, SET_KF))
        ax.set_title(f"{recording}, σ_d = {sigma_d_cmps:.3g} cm/s, K = {n_particles}")
        fig.tight_layout()
        return fig, errors

    def panel(self, *, n_particles: int, seed: int) -> widgets.Panel:
        """Widget over recording, σ_d, K, the ESS threshold and the seed (starting on the second recording)."""
        names = list(self.logs)
        return widgets.Panel("Set-noise PF explorer (Fig. 8 style)", {
            "recording": widgets.dropdown("recording", names, names[min(1, len(names) - 1)]),
            "sigma_d_cmps": widgets.float_slider("σ_d", 6.0, 1.0, 100.0, 0.05, log=True, unit="cm/s"),
            "n_particles": widgets.int_slider("particles K", n_particles, 50, 5000, 50),
            "ess_fraction": widgets.float_slider("resample when ESS <", 0.5, 0.0, 1.0, 0.05, unit="× K"),
            "seed": widgets.seed_box(seed),
        }, self.render)
