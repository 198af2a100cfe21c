"""Range geometry: predicted ranges, frame rotations, multilateration and dilution of precision.

TDoA measurements (range differences and their covariance) live in :mod:`uwbwb.models.tdoa`.

Conventions
-----------
* Anchors are ``(n_anchors, 3)`` in metres (``(n_anchors, 2)`` is accepted for a
  purely planar problem).
* Ranges are time-major ``(T, n_anchors)`` with NaN for "no measurement".
* ``dim=2`` solves for the horizontal position ``(x, y)`` of a tag whose height
  ``z_m`` is known (scalar or ``(T,)``); the anchors stay 3-D, so the height
  difference to each anchor is part of the range model
  ``r_i = sqrt(|p - a_i,xy|^2 + (z - a_i,z)^2)``. ``dim=3`` solves for
  ``(x, y, z)``.

Multilateration reports, per epoch, whether it produced a position
(:class:`Status`). Epochs with too few ranges, with an ambiguous anchor geometry
or that did not converge get status codes and NaN positions -- never an
exception from the batch API and never a silent guess.

Modules
-------
:mod:`.multilateration` (:func:`multilaterate`, :func:`linear_multilaterate`,
:func:`multilaterate_one`, :func:`gdop`, :class:`MultilaterationResult`, :class:`Status`),
:mod:`.solvers` (the batched least-squares problem and its Gauss--Newton / trust-region
solvers, :data:`RCOND`), :mod:`.tracks` (:func:`yaw_rotation`, :func:`point_fixes`,
:func:`line_fit`, :func:`straight_segments`). The range model itself, :func:`ranges` and
:func:`range_jacobian`, is :mod:`uwbwb.models.ranging`'s, re-exported here.
"""

from ..models.ranging import range_jacobian, ranges
from .multilateration import MultilaterationResult, Status, gdop, linear_multilaterate, multilaterate, multilaterate_one
from .solvers import RCOND  # noqa: F401 (public constant of uwbwb.geometry)
from .tracks import line_fit, point_fixes, straight_segments, yaw_rotation

__all__ = [
    "MultilaterationResult", "Status", "gdop", "line_fit", "linear_multilaterate", "multilaterate",
    "multilaterate_one", "point_fixes", "range_jacobian", "ranges", "straight_segments", "yaw_rotation",
]
