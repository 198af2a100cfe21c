"""The Hanyang outdoor dynamic runs: the dataset authors' LS/ESKF reproduced and put on our board.

``authors`` reproduces the authors' RMSEs with the package's metric code and puts their estimates on a board
(*external* rows); ``study`` scores every method of the board on each case (tuned on another case) beside them,
every comparison of two methods a row of the board's :func:`uwbwb.scoreboard.verdicts.difference_table`;
``sections`` is what notebooks 02, 03 and 06 show.
"""

from .authors import reproduce_authors
from .study import DECLARED_METHOD, case_board, declared_method_table
from .sections import motion_section, pruning_section, scoreboard_section
from . import sections

__all__ = ["DECLARED_METHOD", "case_board", "declared_method_table", "motion_section", "pruning_section",
           "reproduce_authors", "scoreboard_section", "sections"]
