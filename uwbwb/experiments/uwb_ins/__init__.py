"""Notebook 05 (paper 004, UWB/INS fusion): :mod:`.study` (what the notebook runs),
:mod:`.figures` (the paper's figures and ours), :mod:`.discussion` (comparison with the paper)."""

from . import study

__all__ = ["study"]
