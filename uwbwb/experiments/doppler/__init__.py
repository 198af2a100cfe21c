"""Notebook 04 (paper 003): study (what the notebook computes), figures, discussion."""

from . import discussion, figures, study

__all__ = ["discussion", "figures", "study"]
