"""Every estimator of the package on the same recording, with the same calibration, against the
Cramér–Rao bounds (notebook 06 and ``python -m uwbwb score``).

* :mod:`.protocol` — the fair protocol: calibration part / scoring part, one shared calibration;
* :mod:`.interface` — the estimator interface and the pieces every adapter shares;
* :mod:`.estimators` — the adapters of every method (LS, TDoA, EKFs, UWB/INS, external estimates);
* :mod:`.setnoise_nls` — the set-noise filters and the windowed trajectory NLS as adapters;
* :mod:`.board` — scoring, the table, Markdown/CSV output;
* :mod:`.figures` — error CDFs, RMSE vs bound, error over time with the bound's band;
* :mod:`.synthetic` — a run whose truth and noise are known exactly;
* :mod:`.sources` — recordings named on the command line;
* :mod:`.reference` — the common bound (one per recording, the same for every method);
* :mod:`.checks` — is a recording scorable (measured vs predicted ranges, with a diagnosis);
* :mod:`.verdicts` — verdict tables computed from differences with block-bootstrap intervals;
* :mod:`.teaching` — notebook 06's class-size board and panel;
* :mod:`.exercises` — notebook 06's checked exercises on the synthetic hall.
"""

from .board import Board, Entry, calibrate, score
from .estimators import ExternalEstimates, default_estimators
from .interface import BaseEstimator, Estimator
from .reference import common_bound
from .protocol import Calibration, fit_calibration, split_in_time

__all__ = ["BaseEstimator", "Board", "Calibration", "Entry", "Estimator", "ExternalEstimates", "calibrate",
           "common_bound", "default_estimators",
           "fit_calibration", "score", "split_in_time"]
