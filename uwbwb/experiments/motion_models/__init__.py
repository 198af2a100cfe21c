"""Notebook 03 (De Angelis, paper 002): TDoA EKF with random-walk / random-force / random-jerk models.

``study`` calibrates and runs the estimators (``results``: its methods, the registry's estimators on
pseudo-TDoAs, and what one tag-run gives),
``real`` runs the real-data sections, ``headlines`` declares the summary rows and the checks,
``seeds`` runs the synthetic tables over several test seeds (a verdict per pair), ``figures`` draws,
``panels`` is the explorer's back end, ``exercises`` the checked exercises. The notebook imports this package
as ``mm``.
"""

from . import exercises, headlines, panels, real, results, seeds
from .figures import calibration_figure, cdf_figure, covariance_figure, paths_figure, scenario_figure
from .headlines import Results, SIGMA_KIND, checks, headline_rows
from .results import METHODS, MODELS, PAPER_METHODS_CEP95, PAPER_MODELS_CEP95, PAPER_SIGMA, ekf_name, ranking
from .seeds import MODEL_PAIRS, seed_study
from .study import Study, estimate, ranging_summary, run_study, synthetic_acquisition, tag_runs

__all__ = [
    "METHODS", "MODEL_PAIRS", "MODELS", "PAPER_METHODS_CEP95", "PAPER_MODELS_CEP95", "PAPER_SIGMA", "Results",
    "SIGMA_KIND", "Study", "calibration_figure", "cdf_figure", "checks", "covariance_figure", "ekf_name", "estimate",
    "exercises", "headline_rows", "headlines", "panels", "paths_figure", "ranging_summary", "ranking", "real",
    "results", "run_study", "scenario_figure", "seed_study", "seeds", "synthetic_acquisition", "tag_runs",
]
