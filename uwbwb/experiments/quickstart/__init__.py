"""Notebook 00 (quickstart): the room's recordings, raw multilateration and range calibration.

:mod:`.study` loads the data and scores multilateration before and after a range
calibration fitted on the static poses, :mod:`.figures` draws the error CDFs and
:mod:`.discussion` words what the run shows and :mod:`.panels` is the widget's back end.
"""

from . import exercises, panels
from .discussion import discussion_markdown
from .figures import plot_error_cdfs
from .study import (VARIANTS, QuickstartData, calibrate, compare_calibration, headline_rows, load,
                    multilaterate_tags, tag_errors)

__all__ = ["VARIANTS", "exercises", "QuickstartData", "calibrate", "compare_calibration", "discussion_markdown",
           "headline_rows", "load", "multilaterate_tags", "panels", "plot_error_cdfs", "tag_errors"]
