"""Notebook 00 (quickstart): the room's recordings, raw multilateration and range calibration.

:mod:`.study` loads the data and scores multilateration before and after a range
calibration fitted on the static poses, :func:`.study.verdicts` says per tag whether calibration helps
(a block-bootstrap interval) and :mod:`.panels` is the widget's back end.
"""

from . import exercises, panels
from .study import VARIANTS, compare_calibration, headline_rows, load, multilaterate_tags, verdicts

__all__ = ["VARIANTS", "compare_calibration", "exercises", "headline_rows", "load", "multilaterate_tags", "panels",
           "verdicts"]
