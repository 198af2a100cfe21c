"""Extended Kalman filtering: one generic filter over any measurement model, and its TDoA form.

The generic filter (:class:`Ekf`) takes a transition model giving ``F(dt)``, ``Q(dt)``
(every :mod:`uwbwb.models.motion` model fits) and a measurement model that linearises
each epoch's measurement at the prior mean, returning :class:`Linearisation`
``(z, h(x⁻), H, R)``. Prediction and update are the textbook steps::

    x⁻ = F x,  P⁻ = F P Fᵀ + Q
    y = z − h(x⁻),  S = H P⁻ Hᵀ + R,  G = P⁻ Hᵀ S⁻¹,  x = x⁻ + G y,
    P = (I − G H) P⁻ (I − G H)ᵀ + G R Gᵀ              (Joseph form)

both through :mod:`uwbwb.filters.kalman`, the one edge that touches filterpy. A run keeps
priors *and* posteriors (:class:`KalmanRun`), so the Rauch–Tung–Striebel smoother, NEES
and NIS consistency work on any filter built this way; :meth:`KalmanRun.to_estimates`
gives the package's common result type :class:`~uwbwb.types.Estimates`.

Gating is a policy injected with ``gate=`` (:mod:`uwbwb.filters.gating`): no gate, χ² per
epoch, χ² per measurement or anchor dropping, each with its ``max_gated`` release rule, or the
robust (M-estimation) update :class:`~uwbwb.filters.gating.Robust`, alone or after one of those
gates (``Robust(gate=...)``). The
older ``gate_prob=`` / ``max_gated=`` settings still work and stand for
:class:`~uwbwb.filters.gating.ChiSquareEpoch` (``gate_prob = 0.9999`` by default: an epoch
whose NIS exceeds the 0.9999 quantile of χ²(m) is rejected, prediction only, status
``GATED``) or, for ``gate_prob=None``, :class:`~uwbwb.filters.gating.NoGate` (every
measurement used, however far from the prediction).

:class:`TdoaEkf` is the TDoA filter of notebook 03 (thesis eqs 1–10): this filter with the
TDoA measurement adapter :class:`TdoaMeasurement` and, by default, the
:class:`~uwbwb.filters.gating.AnchorDropping` gate, which drops single anchors before giving
up an epoch.

Modules
-------
:mod:`.core` (:class:`Ekf`, :class:`KalmanRun`, :class:`Linearisation`, the model protocols,
:func:`nis_consistency`), :mod:`.tdoa` (:class:`TdoaEkf`, :class:`TdoaMeasurement`),
:mod:`.kernels` (:meth:`TdoaEkf.run`'s compiled loop, twin of :meth:`Ekf.run`) and
:mod:`.ranges` (:class:`RangeMeasurement`: the ranges themselves as the measurement); every name importable from
here.
"""

from ..gating import UpdateInfo
from .core import Ekf, KalmanRun, Linearisation, MeasurementModel, TransitionModel
from ...metrics import nis_consistency
from .ranges import RangeMeasurement
from .tdoa import TdoaEkf, TdoaMeasurement

__all__ = ["Ekf", "KalmanRun", "Linearisation", "MeasurementModel", "TransitionModel", "UpdateInfo",
           "nis_consistency", "RangeMeasurement", "TdoaEkf", "TdoaMeasurement"]
