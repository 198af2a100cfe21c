"""Notebook 04 (paper 003): study (what the notebook computes), figures, facts + discussion, headlines, panels,
exercises."""

from . import discussion, exercises, facts, figures, headlines, panels, study

__all__ = ["discussion", "exercises", "facts", "figures", "headlines", "panels", "study"]
