"""State layout of the kinematic models, and the protocol every member of the family follows.

A kinematic state is a vector of positions and their time derivatives. Its
:class:`StateLayout` names every component with its unit (``"x_m"``, ``"vx_mps"``,
``"ax_mps2"``) in the order the vector holds them. The models of
:mod:`uwbwb.models.motion` stack their states *derivative-major*,

.. math::

    x = [p_x, p_y, (p_z), v_x, v_y, (v_z), (a_x, \\dots)],

so the position is ``x[..., :dim]`` whatever the model.

:class:`KinematicModel` is the protocol of the family (``n_x``, ``layout``,
``F(dt)``, ``Q(dt)``, ``step``, ``sample_path``); the members and their formulas
are listed in :mod:`uwbwb.models.motion`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["StateLayout", "KinematicModel", "DERIVATIVES"]

#: Label prefix and unit suffix of the derivatives a kinematic state may hold (position first).
DERIVATIVES: tuple[tuple[str, str], ...] = (("", "_m"), ("v", "_mps"), ("a", "_mps2"))
_AXES = "xyz"


def _parse(label: str) -> tuple[int, int] | None:
    """``(derivative, axis)`` of a kinematic label such as ``"vy_mps"``, or None for any other label."""
    for k, (prefix, unit) in enumerate(DERIVATIVES):
        name = label[len(prefix):-len(unit)] if label.startswith(prefix) and label.endswith(unit) else ""
        if name in tuple(_AXES) and label == f"{prefix}{name}{unit}":
            return k, _AXES.index(name)
    return None


def _one_two_three(value) -> bool:
    """``value`` is the integer 1, 2 or 3 (not a float, not a bool)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value in (1, 2, 3)


@dataclass(frozen=True)
class StateLayout:
    """Names and order of the components of a kinematic state.

    Attributes
    ----------
    labels
        One name per state component, with its unit: ``"x_m"`` (position),
        ``"vx_mps"`` (velocity), ``"ax_mps2"`` (acceleration) for axes ``x, y, z``.
    dim
        Number of position coordinates (1, 2 or 3); ``labels`` must hold the
        positions of the first ``dim`` axes.
    """

    labels: tuple[str, ...]
    dim: int

    def __post_init__(self):
        labels = tuple(str(v) for v in self.labels)
        object.__setattr__(self, "labels", labels)
        if not _one_two_three(self.dim):
            raise ValueError(f"StateLayout.dim must be 1, 2 or 3, got {self.dim!r}")
        if len(set(labels)) != len(labels):
            raise ValueError(f"StateLayout labels must be distinct, got {labels!r}")
        bad = [v for v in labels if _parse(v) is None or _parse(v)[1] >= self.dim]
        if bad:
            raise ValueError(f"StateLayout: {bad} are not kinematic labels of a {self.dim}-D state "
                             f"(expected e.g. 'x_m', 'vx_mps', 'ax_mps2')")
        missing = [f"{a}_m" for a in _AXES[: self.dim] if f"{a}_m" not in labels]
        if missing:
            raise ValueError(f"StateLayout: the position components {missing} are missing from {labels!r}")

    @classmethod
    def kinematic(cls, dim: int, order: int) -> "StateLayout":
        """Layout of ``order`` derivative blocks (1: position; 2: + velocity; 3: + acceleration) in ``dim`` axes,
        derivative-major (``x, y, vx, vy``)."""
        for name, value in (("order", order), ("dim", dim)):
            if not _one_two_three(value):
                raise ValueError(f"StateLayout.kinematic: {name} must be 1, 2 or 3, got {value!r}")
        pairs = [(k, a) for k in range(order) for a in range(dim)]
        return cls(tuple(f"{DERIVATIVES[k][0]}{_AXES[a]}{DERIVATIVES[k][1]}" for k, a in pairs), dim)

    @property
    def n_x(self) -> int:
        """State size."""
        return len(self.labels)

    def index(self, labels) -> tuple[int, ...]:
        """Positions of ``labels`` in the state."""
        try:
            return tuple(self.labels.index(v) for v in labels)
        except ValueError:
            raise ValueError(f"StateLayout: {list(labels)} are not all in {self.labels!r}") from None

    def _derivative_index(self, k: int) -> tuple[int, ...] | None:
        prefix, unit = DERIVATIVES[k]
        want = [f"{prefix}{a}{unit}" for a in _AXES[: self.dim]]
        return self.index(want) if all(v in self.labels for v in want) else None

    @property
    def pos_index(self) -> tuple[int, ...]:
        """State components that are the position, in axis order (``Ekf``'s ``pos_index``)."""
        return self._derivative_index(0)

    @property
    def vel_index(self) -> tuple[int, ...] | None:
        """State components that are the velocity, in axis order; None when the state has no velocity."""
        return self._derivative_index(1)


@runtime_checkable
class KinematicModel(Protocol):
    """What every kinematic model of :mod:`uwbwb.models.motion` gives (simulators and filters rely on it).

    ``F(dt_s)`` and ``Q(dt_s)`` take a scalar or an array of step lengths (seconds) and return
    ``(..., n_x, n_x)``; ``step`` moves states ``(..., n_x)`` over one step drawing the driving
    noise from ``rng``; ``sample_path`` draws a whole path ``(T, n_x)`` at times ``t_s``.
    """

    @property
    def n_x(self) -> int: ...

    @property
    def layout(self) -> StateLayout: ...

    def F(self, dt_s) -> np.ndarray: ...

    def Q(self, dt_s) -> np.ndarray: ...

    def step(self, x: np.ndarray, dt_s, *, rng: np.random.Generator) -> np.ndarray: ...

    def sample_path(self, x0: np.ndarray, t_s: np.ndarray, *, rng: np.random.Generator) -> np.ndarray: ...
