"""Notebook 03 (De Angelis, paper 002): TDoA EKF with random-walk / random-force / random-jerk models.

``study`` calibrates and runs the estimators (``results``: what one tag-run gives and the tables),
``real`` runs the real-data sections, ``headlines`` declares the summary rows and the checks,
``seeds`` runs the synthetic tables over several test seeds (a verdict per pair), ``figures`` draws,
``panels`` is the explorer's back end, ``exercises`` the checked exercises. The notebook imports this package
as ``mm``.
"""

from . import exercises, panels, real, seeds
from .figures import calibration_figure, cdf_figure, covariance_figure, paths_figure, scenario_figure
from .headlines import Results, SIGMA_KIND, checks, headline_rows, record, sigma_rows, summary_rows
from .results import (METHODS, MODELS, PAPER_METHODS_CEP95, PAPER_MODELS_CEP95, PAPER_SIGMA, TagResults, cep95_table,
                      coverage_table, ekf_name, nis_table, paper_table, ranking)
from .seeds import MODEL_PAIRS, SEED_PAIRS, SEED_RULE, SeedStudy, scoring_seeds, seed_rows, seed_study
from .study import (Study, estimate, ranging_summary, run_study, synthetic_acquisition, tag_runs,
                    tdoa_noise_check)

__all__ = [
    "METHODS", "MODEL_PAIRS", "MODELS", "PAPER_METHODS_CEP95", "PAPER_MODELS_CEP95",
    "PAPER_SIGMA", "Results", "SEED_PAIRS", "SEED_RULE", "SIGMA_KIND", "SeedStudy", "Study", "TagResults",
    "calibration_figure", "cdf_figure", "cep95_table", "checks", "covariance_figure",
    "coverage_table", "ekf_name", "estimate", "exercises", "headline_rows",
    "nis_table", "panels", "paper_table", "paths_figure", "ranging_summary", "ranking", "real",
    "record", "run_study", "scenario_figure", "scoring_seeds", "seed_rows", "seed_study", "seeds",
    "sigma_rows", "summary_rows", "synthetic_acquisition", "tag_runs", "tdoa_noise_check",
]
