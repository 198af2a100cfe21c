"""The Hanyang outdoor dynamic runs: the dataset authors' LS/ESKF reproduced and put on our board.

``study`` reproduces the authors' RMSEs with the package's metric code, scores every method of the
board on each case (tuned on another case) beside the authors' estimates (*external* rows), and
tests the static part's range model on the dynamic runs; ``facts`` turns the numbers into the
verdict table the notebooks print.
"""

from .authors import (AUTHORS_TAG_HEIGHT_M, AUTHORS_Z_LIMIT_M, AuthorsEstimator, WINDOW_RULES, authors_errors,
                      authors_estimators, authors_window, read_rmsd_results, reproduce_authors)
from .estimators import PrunedNls, StaticModelLs, StaticRangeModel, static_range_model
from .pairs import ablation, held_errors, pair_errors
from .study import (CaseComparison, FAST_SPAN_S, board_epochs, case_board, compare_cases, load_pair,
                    pick_on_tuning_case, ratio_table, static_model_effect, study_estimators, tuning_case)

__all__ = ["AUTHORS_TAG_HEIGHT_M", "AUTHORS_Z_LIMIT_M", "FAST_SPAN_S", "WINDOW_RULES", "AuthorsEstimator",
           "CaseComparison", "PrunedNls", "StaticModelLs", "StaticRangeModel", "authors_errors", "authors_estimators", "authors_window",
           "board_epochs", "case_board", "compare_cases", "held_errors",
           "load_pair", "pair_errors", "pick_on_tuning_case", "ratio_table",
           "read_rmsd_results", "reproduce_authors", "static_model_effect", "static_range_model",
           "study_estimators", "tuning_case"]
from . import facts
from .sections import Section, motion_section, pruning_section, scoreboard_section

__all__ += ["Section", "ablation", "facts", "motion_section", "pruning_section", "scoreboard_section"]
