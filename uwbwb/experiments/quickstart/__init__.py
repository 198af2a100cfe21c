"""Notebook 00 (quickstart): the room's recordings, raw multilateration and range calibration.

:mod:`.study` loads the data and scores multilateration before and after a range
calibration fitted on the static poses, :mod:`.figures` draws the error CDFs,
:func:`.study.verdicts` says per tag whether calibration helps (a block-bootstrap interval) and
:mod:`.panels` is the widget's back end.
"""

from . import exercises, panels
from .figures import plot_error_cdfs
from .study import (VARIANTS, QuickstartData, calibrate, compare_calibration, headline_rows, load,
                    multilaterate_tags, tag_errors, verdicts)

__all__ = ["VARIANTS", "exercises", "QuickstartData", "calibrate", "compare_calibration", "headline_rows", "load",
           "multilaterate_tags", "panels", "plot_error_cdfs", "tag_errors", "verdicts"]
