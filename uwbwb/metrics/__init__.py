"""Position errors, their distribution (ECDF, CEP, RMSE), filter consistency (NEES, NIS χ² test)
and the reproduction summary table.

* :mod:`.errors` — per-epoch errors, ECDF, CEP, RMSE, :func:`epoch_summary` (accuracy on common epochs,
  coverage beside it), :func:`block_bootstrap_difference` (paired RMSE difference with its interval: the one
  interval rule for a difference on a time series, blocks by :func:`block_ids`), :func:`interval_side` (the one rule
  from an interval to a verdict), :func:`tied_ranks` (the one tie-aware ranking from decided pairs); its
  docstring states the missing-value and quantile rules.
* :mod:`.scoring` — :func:`score_epochs` (per-method errors on one epoch grid → :class:`EpochScores`:
  each method's own epochs, the common epochs, coverage and the statistics asked for on either),
  :func:`pool_scores` (grids pooled per method), :func:`errors_on_grid` (own time grids → one grid).
* :mod:`.consistency` — :func:`nees` and :func:`nis_consistency`, the one place where a filter's
  covariances are held to its errors and innovations.
* :mod:`.summary` — :class:`Summary` (headline numbers of a notebook, each with its kind and mode) and
  :class:`Headline` (one summary row declared as data).
"""

from .consistency import nees, nis_consistency
from .errors import (MIN_BLOCKS, ErrorSeries, _errors, block_bootstrap_difference, block_ids, cep, cep50, cep95, ecdf,
                     epoch_summary, error_stats, errors_vs_truth, interval_side, position_error_m, rmse,
                     seeds_interval, tied_ranks)
from .scoring import EpochScores, MethodEpochs, errors_on_grid, pool_scores, score_epochs
from .summary import Headline, Summary, interval_rows, interval_text

__all__ = [
    "ErrorSeries", "Summary", "cep", "cep50", "cep95", "ecdf", "epoch_summary", "error_stats", "errors_vs_truth",
    "nees", "nis_consistency", "position_error_m", "rmse", "block_bootstrap_difference", "block_ids", "MIN_BLOCKS",
    "interval_rows", "interval_side", "interval_text", "seeds_interval", "tied_ranks",
    "Headline", "EpochScores", "MethodEpochs", "errors_on_grid", "pool_scores", "score_epochs",
]
