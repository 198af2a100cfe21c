"""Models shared by simulators and estimators: motion models and measurement models."""

from . import ranging

__all__ = ["ranging"]
