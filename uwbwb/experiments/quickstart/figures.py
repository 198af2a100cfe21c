"""Figures of notebook 00; every builder takes ``ax=`` and returns the Axes."""

from __future__ import annotations

from ... import plotting


def plot_error_cdfs(errors: dict, tag: str, ax=None):
    """Error CDF of one tag for every variant (``errors`` as returned by ``compare_calibration``)."""
    ax = plotting.error_cdf({v: errors[v][tag] for v in errors}, ax=ax, nan="omit")
    ax.set_title(f"tag {tag}")
    return ax
