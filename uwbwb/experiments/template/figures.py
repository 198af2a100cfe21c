"""The template's figures (each takes ``ax=`` and returns the Axes; colours from :mod:`uwbwb.plotting`)."""

from __future__ import annotations

from ... import metrics, plotting
from .study import Results

__all__ = ["paths_figure", "cdf_figure"]


def paths_figure(res: Results, ax=None):
    """Truth and both methods' tracks on the floor plan."""
    tracks = {"truth": res.truth_m, **{m: e.pos_m for m, e in res.estimates.items()}}
    ax = plotting.trajectories(tracks, ax, anchors=res.config.anchors)
    ax.set_title(f"{res.t_s.size} epochs of one walk (seed {res.seed})")
    return ax


def cdf_figure(res: Results, ax=None):
    """Error CDFs on the common epochs (each point a distinct epoch of the one walk)."""
    scores = metrics.score_epochs(res.errors_m)
    ax = plotting.error_cdf({s.name: s.common_m for s in scores}, ax, unit="cm")
    ax.set_title(f"{scores['LS'].n_common} common epochs (distinct, one walk)")
    return ax
