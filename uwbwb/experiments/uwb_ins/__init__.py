"""Notebook 05 (paper 004, UWB/INS fusion): :mod:`.study` (what the notebook runs),
:mod:`.ablation` (what each ingredient adds, over seeds and model-mismatch cases),
:mod:`.facts` (the verdicts, computed), :mod:`.headlines` (summary rows and checks),
:mod:`.realdata` (the real-data tables, read from the scoreboard),
:mod:`.figures` (the paper's figures and ours)."""

from . import ablation, facts, headlines, realdata, study

__all__ = ["ablation", "facts", "headlines", "realdata", "study"]
