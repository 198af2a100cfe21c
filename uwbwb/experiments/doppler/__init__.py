"""Notebook 04 (paper 003): study (what the notebook computes), figures, facts + discussion, headlines, panels."""

from . import discussion, facts, figures, headlines, panels, study

__all__ = ["discussion", "facts", "figures", "headlines", "panels", "study"]
