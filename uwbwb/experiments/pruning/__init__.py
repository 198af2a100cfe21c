"""Notebook 02: trajectory estimation by NLS with pruning heuristics (Zupanec et al.).

``study`` runs the synthetic comparisons;
``scoring`` holds the estimator names and the tables (coverage beside accuracy); ``real`` runs the
LIAS static poses and dynamic pieces, ``sections`` the notebook's LIAS sections in one call each;
``figures`` draws them; ``panels`` backs the notebook's widgets and writes the notes under them;
``headlines`` declares the summary rows and the checks; ``exercises`` checks the notebook's
exercises; ``verdicts`` computes the comparison with the paper from the run's tables (``verdict_table``).
"""

from . import exercises, headlines, panels
from .figures import (HEURISTIC_MARKERS, error_cdf_by_heuristic, heuristic_color, plot_coverage,
                      plot_error_cdf_percentile, plot_error_histogram, plot_hanyang, plot_polar_errors,
                      plot_robust_mean_cloud, plot_segment_fits)
from .headlines import Results, headline_rows
from .panels import PieceExplorer, TourExplorer
from .real import DynamicResult, StaticResult, run_dynamic_segments, run_static_poses
from .scoring import (ESTIMATORS, LABELS, MIN_SEGMENT_RANGES, PAPER_RANKING, POINT, epoch_summary, hanyang_table,
                      heuristic_summary, rank_heuristics, wins_table)
from .sections import LiasDynamic, LiasStatic, lias_dynamic, lias_static
from .verdicts import comparison_facts, verdict_table
from .study import (EXCESS_FACTORS, SyntheticConfig, SyntheticResult, loso_calibrations, nlos_excess_sensitivity,
                    outlier_free_control, range_error_stats, run_recordings, run_synthetic, run_tour, segment_ranges,
                    sensitivity)

__all__ = [
    "ESTIMATORS", "EXCESS_FACTORS", "HEURISTIC_MARKERS", "LABELS", "MIN_SEGMENT_RANGES", "PAPER_RANKING", "POINT", "DynamicResult",
    "LiasDynamic", "LiasStatic", "PieceExplorer", "Results", "StaticResult", "SyntheticConfig", "SyntheticResult",
    "TourExplorer", "comparison_facts", "epoch_summary", "error_cdf_by_heuristic",
    "exercises", "hanyang_table", "headline_rows", "headlines", "heuristic_color", "heuristic_summary",
    "lias_dynamic", "lias_static", "loso_calibrations", "nlos_excess_sensitivity", "outlier_free_control", "panels", "plot_coverage",
    "plot_error_cdf_percentile", "plot_error_histogram", "plot_hanyang", "plot_polar_errors",
    "plot_robust_mean_cloud", "plot_segment_fits", "range_error_stats", "rank_heuristics",
    "run_dynamic_segments", "run_recordings", "run_static_poses", "run_synthetic", "run_tour", "segment_ranges",
    "sensitivity", "verdict_table", "wins_table",
]
