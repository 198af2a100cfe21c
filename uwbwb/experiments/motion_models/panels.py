"""Back end of notebook 03's explorer panel: which runs, tags and reference anchors it offers, the
cached filter run behind every setting, and the figure and readout of one setting.

The panel offers only what the data has: one entry per (run, tag) of the test results it is built
from, and reference anchors from 0 to the smallest anchor count among them minus one, so every
value offered is valid on every run (none is clamped behind the student's back).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Iterable

import matplotlib.pyplot as plt

from ... import validate
from .exercises import WINDOW_S, window
from .figures import cdf_figure, paths_figure
from .results import MODELS, TagResults, ekf_name
from .study import Study, estimate

__all__ = ["Explorer", "GATES", "MODEL_LABELS"]

#: χ² gate choices of the panel (0: off).
GATES = {"off": 0.0, "99.9 %": 0.999, "99 %": 0.99}
#: Motion-model choices of the panel.
MODEL_LABELS = {"random walk (RW)": "RW", "random force (RF)": "RF", "random jerk (RJ)": "RJ"}


class Explorer:
    """The runs of some studies' test results, each filtered on its first ``window_s`` seconds.

    Parameters
    ----------
    studies
        :class:`~.study.Study` objects; every test result of each becomes one choice
        ``"<run> / <tag>"`` (with the range-noise fit of its tag).
    window_s
        Seconds of each run filtered (from its first epoch).
    """

    def __init__(self, studies: Iterable[Study], *, window_s: float = WINDOW_S):
        self.window_s = validate.number("window_s", window_s, minimum=0.0, strict_minimum=True)
        self.runs = {}
        for study in studies:
            for res in study.results:
                self.runs[res.run.key] = (window(res.run, self.window_s), study.calibration.sigma(res.run.tag))
        if not self.runs:
            raise ValueError("studies: no test result to explore")

    @property
    def choices(self) -> list[str]:
        """The ``"<run> / <tag>"`` entries, in the studies' order."""
        return list(self.runs)

    @property
    def max_ref(self) -> int:
        """Largest reference-anchor index valid on every run (smallest anchor count − 1)."""
        return min(len(run.anchors) for run, _ in self.runs.values()) - 1

    @lru_cache(maxsize=64)
    def estimate(self, key: str, model: str, sigma: float, ref: int, gate: float, correlated: bool) -> TagResults:
        """LS, raw output and the EKF with ``model`` at driving σ ``sigma`` on run ``key`` (cached).

        Raises
        ------
        ValueError
            ``key`` not offered, ``model`` unknown, or ``ref`` not an anchor index of every run.
        """
        run, sigma_m = self.runs[validate.choice("key", key, self.runs)]
        validate.choice("model", model, MODELS)
        ref = validate.integer("ref", ref, minimum=0, maximum=self.max_ref)
        return estimate(run, sigma_m, {model: float(sigma)}, ref=ref, gate_prob=float(gate) or None,
                        correlated=bool(correlated), models=(model,))

    def readout(self, key, model, sigma, ref, gate, correlated) -> dict:
        """Headline numbers of one setting (CEP95 on common epochs, coverage, NIS)."""
        est = self.estimate(key, model, sigma, ref, gate, correlated)
        name, c = ekf_name(model), est.cep95()
        nis = est.nis().loc[name]
        return {"run / tag": est.run.key, f"CEP95 {name} (m)": c[name], "CEP95 LS (m)": c["LS"],
                "CEP95 raw (m)": c["raw"], "epochs scored (%)": 100 * est.coverage()["common"],
                "mean NIS / dof": nis["mean_nis_over_dof"], "NIS verdict": nis["verdict"],
                "anchors gated out": int(nis["n_rejected"])}

    def render(self, key, model, sigma, ref, gate, correlated):
        """``(figure, readout)`` for :class:`uwbwb.widgets.Panel`: paths with anchors, and error CDFs."""
        est = self.estimate(key, model, sigma, ref, gate, correlated)
        name = ekf_name(model)
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
        paths_figure(est, (name, "LS"), ax=axes[0])
        axes[0].set_title(f"{est.run.key}: first {self.window_s:g} s, reference anchor {ref}")
        cdf_figure(est, (name, "LS", "raw"), ax=axes[1])
        fig.tight_layout()
        return fig, self.readout(key, model, sigma, ref, gate, correlated)
