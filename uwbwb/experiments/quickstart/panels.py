"""Back end of notebook 00's widget: multilateration against motion capture in a time window.

:func:`explorer` returns a :class:`uwbwb.widgets.Panel` over a tag, the ranges (raw or
calibrated) and a window of the run; the fixes of every tag and variant are computed once, and
each (tag, variant) track and its errors are cached.
"""

from __future__ import annotations

import functools

import matplotlib.pyplot as plt

from ... import metrics, plotting, widgets
from ...calibration import RangeCalibration
from ...types import Recording
from .study import multilaterate_tags

__all__ = ["Explorer", "explorer"]


class Explorer:
    """Fixes of every tag of ``rec`` (tag heights ``heights``, metres) with raw and calibrated ranges, and the
    panel's render."""

    def __init__(self, rec: Recording, heights, calibration: RangeCalibration):
        self.rec = rec
        self.fixes = {v: multilaterate_tags(self.rec, tag_height_m=heights, calibration=c)
                      for v, c in (("raw", None), ("calibrated", calibration))}
        self.span_s = float(self.rec.ranges[self.rec.tags[0]].t_s[-1])
        self.track = functools.lru_cache(maxsize=None)(self._track)

    def _track(self, tag: str, variant: str):
        """``(Trajectory of the fixes, ErrorSeries against the truth)`` of one tag and variant."""
        est = self.fixes[variant][tag].to_trajectory(self.rec.ranges[tag].t_s, name=variant)
        return est, metrics.errors_vs_truth(est, self.rec.truth[tag])

    def render(self, tag: str, variant: str, start_s: float, window_s: float):
        """Figure of the window and its readout (fixes, CEP50, CEP95)."""
        est, err = self.track(tag, variant)
        end_s = start_s + window_s
        fig, ax = plt.subplots(figsize=(5.5, 4.2))
        plotting.trajectories({"truth": self.rec.truth[tag].between(start_s, end_s),
                               variant: est.between(start_s, end_s)}, ax=ax, anchors=self.rec.anchors)
        ax.set_title(f"tag {tag}, {variant} ranges, {start_s:g}–{end_s:g} s")
        e = err.err_m[(err.t_s >= start_s) & (err.t_s < end_s)]
        if e.size == 0:
            ax.text(0.5, 0.5, "no fix in this window", transform=ax.transAxes, ha="center")
            return fig, {"fixes in window": 0}
        return fig, {"fixes in window": e.size, "CEP50 (m)": metrics.cep50(e), "CEP95 (m)": metrics.cep95(e)}


def explorer(rec: Recording, heights, calibration: RangeCalibration) -> widgets.Panel:
    """Widget: a tag's fixes (raw or calibrated ranges) against motion capture in a time window."""
    ex = Explorer(rec, heights, calibration)
    tags = list(ex.rec.tags)
    return widgets.Panel("Multilateration vs motion capture", {
        "tag": widgets.dropdown("tag", tags, tags[0]),
        "variant": widgets.dropdown("ranges", ["raw", "calibrated"], "raw"),
        "start_s": widgets.float_slider("start", 0.0, 0.0, max(ex.span_s - 5.0, 1.0), 1.0, unit="s"),
        "window_s": widgets.float_slider("window", 20.0, 5.0, 120.0, 5.0, unit="s"),
    }, ex.render)
