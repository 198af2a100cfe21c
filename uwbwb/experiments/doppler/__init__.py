"""Notebook 04 (paper 003): study (what the notebook computes), figures, facts (numbers, computed verdicts and the
verdict tables), headlines, panels, exercises."""

from . import exercises, facts, figures, headlines, panels, study

__all__ = ["exercises", "facts", "figures", "headlines", "panels", "study"]
