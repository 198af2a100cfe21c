"""Notebook 02: trajectory estimation by NLS with pruning heuristics (Zupanec et al.).

``study`` runs the comparisons (synthetic cafeteria, LIAS static poses and dynamic
pieces, Hanyang static files) and backs the notebook's panels; ``figures`` draws them;
``discussion`` writes the comparison with the paper from the run's tables.
"""

from .discussion import discussion_facts, discussion_markdown
from .figures import (HEURISTIC_MARKERS, error_cdf_by_heuristic, heuristic_color, plot_coverage,
                      plot_error_cdf_percentile, plot_error_histogram, plot_hanyang, plot_polar_errors,
                      plot_robust_mean_cloud, plot_segment_fits)
from .study import (ESTIMATORS, LABELS, MIN_SEGMENT_RANGES, PAPER_RANKING, POINT, DynamicResult, PieceExplorer,
                    StaticResult, SyntheticConfig, SyntheticResult, TourExplorer, epoch_summary,
                    hanyang_table, headline_rows, heuristic_summary, loso_calibrations, outlier_free_control,
                    range_error_stats, rank_heuristics, run_dynamic_segments, run_recordings,
                    run_static_poses, run_synthetic, run_tour, segment_ranges, sensitivity, wins_table)

__all__ = [
    "ESTIMATORS", "HEURISTIC_MARKERS", "LABELS", "MIN_SEGMENT_RANGES", "PAPER_RANKING", "POINT", "DynamicResult",
    "PieceExplorer", "StaticResult", "SyntheticConfig", "SyntheticResult", "TourExplorer",
    "discussion_facts", "discussion_markdown", "epoch_summary", "error_cdf_by_heuristic", "hanyang_table",
    "headline_rows", "heuristic_color", "heuristic_summary", "loso_calibrations", "outlier_free_control",
    "plot_coverage", "plot_error_cdf_percentile", "plot_error_histogram", "plot_hanyang", "plot_polar_errors",
    "plot_robust_mean_cloud", "plot_segment_fits", "range_error_stats", "rank_heuristics",
    "run_dynamic_segments", "run_recordings", "run_static_poses", "run_synthetic", "run_tour", "segment_ranges",
    "sensitivity", "wins_table",
]
