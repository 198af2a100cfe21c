"""Every estimator of the package on the same recording, with the same calibration, against the
Cramér–Rao bound (notebook 06 and ``python -m uwbwb score``).

* :mod:`.protocol` — the fair protocol: calibration part / scoring part, one shared calibration;
* :mod:`.estimators` — the estimator interface and the adapters of every method;
* :mod:`.board` — scoring, the table, Markdown/CSV output;
* :mod:`.figures` — error CDFs, RMSE vs bound, error over time with the bound's band;
* :mod:`.synthetic` — a run whose truth and noise are known exactly;
* :mod:`.sources` — recordings named on the command line.
"""

from .board import Board, Entry, calibrate, score, score_recording
from .estimators import BaseEstimator, Estimator, default_estimators
from .protocol import Calibration, between, fit_calibration, split_in_time, thin

__all__ = ["BaseEstimator", "Board", "Calibration", "Entry", "Estimator", "calibrate", "default_estimators",
           "between", "fit_calibration", "score", "score_recording", "split_in_time", "thin"]
