"""The TDoA EKF of notebook 03 (thesis eqs 1–10): :class:`~uwbwb.filters.ekf.Ekf` with the TDoA measurement adapter."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...models.motion import MotionModel
from ...models.tdoa import TdoaModel
from ...types import TdoaLog
from ...validate import number
from ..gating import AnchorDropping, GatePolicy, gate_from_prob
from ..kalman import Gaussian
from ..tdoa_ls import tdoa_least_squares
from . import kernels
from .core import _DEFAULT_GATE, Ekf, KalmanRun, Linearisation


@dataclass(frozen=True)
class TdoaMeasurement:
    """The TDoA measurement model as :class:`Ekf` sees it (thesis eqs 3–4).

    One epoch's measurement is ``(tdoa_row_m, ref)``: a row of
    :attr:`~uwbwb.types.TdoaLog.tdoa_m` and its reference anchor (−1: nothing measured).
    The model (:meth:`~uwbwb.models.tdoa.TdoaModel.epoch`) is linearised at the position
    part of the state; its Jacobian is lifted to the full state with the motion model's
    ``H_pos``.

    Attributes
    ----------
    model
        TDoA model (anchors, noise, reference correlation).
    motion
        Motion model giving the state layout (its ``dim`` must equal ``model.dim``).
    """

    model: TdoaModel
    motion: MotionModel

    def __post_init__(self):
        if self.motion.dim != self.model.dim:
            raise ValueError(f"motion model is {self.motion.dim}-D but the measurement model is "
                             f"{self.model.dim}-D")

    @staticmethod
    def epochs(log: TdoaLog) -> list[tuple[np.ndarray, int]]:
        """The measurements of a log, one ``(tdoa_row_m, ref)`` per epoch."""
        return list(zip(log.tdoa_m, log.ref.tolist()))

    def terms(self, x: np.ndarray, row: np.ndarray, ref: int, anchors: np.ndarray) -> Linearisation:
        """Linearisation using anchors ``anchors`` (``ref`` among them) with reference ``ref``."""
        z, h, H_pos, R, _ = self.model.epoch(row, self.motion.position(x), ref, anchors)
        return Linearisation(z, h, H_pos @ self.motion.H_pos, R)

    def linearise(self, x: np.ndarray, measurement) -> Linearisation | None:
        """All measured anchors of the epoch, or None if fewer than two were measured."""
        row, ref = measurement
        row = np.asarray(row, float)
        anchors = np.flatnonzero(np.isfinite(row))
        if ref < 0 or anchors.size < 2:
            return None
        return self.terms(x, row, int(ref), anchors)

    def components(self, measurement) -> np.ndarray:
        """The measured anchors of the epoch (sorted indices): what an anchor-dropping gate drops."""
        return np.flatnonzero(np.isfinite(np.asarray(measurement[0], float)))

    def linearise_components(self, x: np.ndarray, measurement, keep: np.ndarray) -> Linearisation:
        """Linearisation from anchors ``keep`` only (at least two); if the epoch's reference is
        not among them, the first of ``keep`` becomes the reference."""
        row, ref = measurement
        keep = np.asarray(keep)
        ref = int(ref) if np.any(keep == int(ref)) else int(keep[0])
        return self.terms(x, np.asarray(row, float), ref, keep)


@dataclass(frozen=True, init=False)
class TdoaEkf(Ekf):
    """TDoA extended Kalman filter with a white-noise-driven motion model (thesis eqs 1–10).

    :class:`Ekf` with the :class:`TdoaMeasurement` adapter. Prediction (eqs 5–6, with the
    covariance propagation written correctly as ``A P Aᵀ + Q``; the thesis prints
    ``AᵀPA + Q``)::

        x⁻ = F(dt) x,        P⁻ = F(dt) P F(dt)ᵀ + Q(dt)

    with ``F``, ``Q`` from a :mod:`uwbwb.models.motion` model. Update (eqs 7–9) with the
    TDoA model linearised at the prior (eqs 3–4), in Joseph form; the estimate is the
    posterior mean (eq. 10). A run keeps priors and posteriors (:class:`KalmanRun`), so
    :meth:`KalmanRun.smooth` and :meth:`KalmanRun.nees` apply.

    Gating: by default :class:`~uwbwb.filters.gating.AnchorDropping` — if the NIS of an
    epoch exceeds the ``gate_prob`` quantile of χ²(m), the anchor whose removal lowers the
    NIS most is dropped (re-referencing if it was the reference) and the test repeated,
    until the epoch passes or fewer than ``min_tdoa`` TDoAs remain, in which case the epoch
    is gated (prediction only). After ``max_skipped`` consecutive gated epochs the next one
    is used ungated. Any other policy can be given as ``gate=``.

    Parameters
    ----------
    motion
        Motion model (its ``dim`` must equal ``measurement.dim``).
    measurement
        TDoA measurement model (anchors, noise, reference correlation); the filter's
        ``measurement`` attribute is its :class:`TdoaMeasurement` adapter.
    gate_prob
        χ² gate probability. The default 0.9999 rejects one consistent epoch in ten
        thousand and any absurd TDoA (a tracking filter should not follow one bad
        measurement kilometres away). ``None`` means *no gate*: every TDoA is used,
        however absurd.
    min_tdoa
        Fewest TDoAs an update may use after gating; default ``dim``.
    max_skipped
        Consecutive epochs the gate may skip before the next one is used ungated.
    init_pos_sigma_m, init_vel_sigma_mps, init_acc_sigma_mps2
        Prior standard deviations at initialisation (per axis).
    gate
        Gate policy (:mod:`uwbwb.filters.gating`) instead of the anchor-dropping gate that
        ``gate_prob``, ``min_tdoa`` and ``max_skipped`` describe.
    """

    min_tdoa: int | None = None
    init_pos_sigma_m: float = 1.0
    init_vel_sigma_mps: float = 1.0
    init_acc_sigma_mps2: float = 1.0

    def __init__(self, motion: MotionModel, measurement: TdoaModel, gate_prob: float | None = 0.9999,
                 min_tdoa: int | None = None, max_skipped: int = 10, init_pos_sigma_m: float = 1.0,
                 init_vel_sigma_mps: float = 1.0, init_acc_sigma_mps2: float = 1.0, gate: GatePolicy | None = None):
        if min_tdoa is not None and min_tdoa < 1:
            raise ValueError("min_tdoa must be >= 1")
        if not isinstance(max_skipped, (int, np.integer)) or max_skipped < 0:
            raise ValueError("max_skipped must be >= 0")
        if gate is None:
            gate = gate_from_prob(gate_prob, max_skipped, "TdoaEkf", kind=AnchorDropping,
                                  min_rows=min_tdoa if min_tdoa is not None else measurement.dim)
        elif (gate_prob, max_skipped) != _DEFAULT_GATE:
            raise ValueError("TdoaEkf: give the gate either as gate= or as gate_prob=/max_skipped=, not both")
        for name, sigma in (("init_pos_sigma_m", init_pos_sigma_m), ("init_vel_sigma_mps", init_vel_sigma_mps),
                            ("init_acc_sigma_mps2", init_acc_sigma_mps2)):
            number(name, sigma, minimum=0.0, strict_minimum=True)
        d = motion.dim
        fields = dict(transition=motion, measurement=TdoaMeasurement(measurement, motion),
                      pos_index=tuple(range(d)), vel_index=tuple(range(d, 2 * d)) if motion.order >= 2 else None,
                      gate_prob=getattr(gate, "prob", None), max_gated=gate.max_gated, gate=gate, min_tdoa=min_tdoa,
                      init_pos_sigma_m=init_pos_sigma_m, init_vel_sigma_mps=init_vel_sigma_mps,
                      init_acc_sigma_mps2=init_acc_sigma_mps2)
        for k, v in fields.items():
            object.__setattr__(self, k, v)
        self.__post_init__()

    @property
    def motion(self) -> MotionModel:
        """The motion model (the filter's transition)."""
        return self.transition

    @property
    def tdoa_model(self) -> TdoaModel:
        """The TDoA measurement model."""
        return self.measurement.model

    @property
    def name(self) -> str:
        return f"EKF-{self.motion.abbreviation}"

    def init(self, pos_m: np.ndarray, vel_mps: np.ndarray | None = None) -> Gaussian:
        """Initial state at ``pos_m`` (velocity and acceleration zero unless given)."""
        m = self.motion
        return Gaussian(m.initial_state(pos_m, vel_mps),
                        m.initial_covariance(self.init_pos_sigma_m, self.init_vel_sigma_mps,
                                             self.init_acc_sigma_mps2))

    def run(self, log: TdoaLog, *, x0: Gaussian | None = None, name: str | None = None) -> KalmanRun:
        """Filter a whole recording.

        Parameters
        ----------
        log
            TDoAs per epoch; the filter steps from epoch to epoch (``dt`` from ``log.t_s``).
        x0
            Initial state at ``log.t_s[0]``. Default: at the first epoch with a
            valid LS fix (:func:`~uwbwb.filters.tdoa_ls.tdoa_least_squares`), with
            zero velocity/acceleration and the ``init_*_sigma`` prior; that
            epoch's TDoAs then update this weak prior. Earlier epochs have no estimate.
        name
            Label of the result (default ``"EKF-RW"`` etc.).

        Returns
        -------
        KalmanRun
        """
        if log.n_anchors != self.tdoa_model.n_anchors:
            raise ValueError(f"TdoaEkf.run: log has {log.n_anchors} anchors, the model {self.tdoa_model.n_anchors}")
        T, start = len(log), 0
        if x0 is None:
            start, x0 = T, self.init(np.zeros(self.motion.dim))       # no LS fix: no estimate anywhere
            for lo in range(0, T, 64):
                ls = tdoa_least_squares(log.select(slice(lo, lo + 64)), self.tdoa_model)
                if ls.ok.any():
                    k = int(np.flatnonzero(ls.ok)[0])
                    start, x0 = lo + k, self.init(ls.pos_m[k])
                    break
        name = name or self.name
        fast = kernels.run(self, log.t_s, log.tdoa_m, log.ref, x0, start, name) if self.compiled else None
        return fast if fast is not None else super().run(log.t_s, TdoaMeasurement.epochs(log), x0, start=start,
                                                           name=name)

    @property
    def compiled(self) -> bool:
        """Whether :meth:`run` takes the compiled loop (:mod:`.kernels`: the Python :meth:`Ekf.run`'s
        decisions, its numbers to rounding, within its twin's stated tolerance): a gate the kernel
        :func:`takes <.kernels.takes>`, the batch update (not ``sequential``) and the TDoA measurement of a
        :class:`MotionModel`. Any other filter runs the Python loop."""
        return (kernels.takes(self.gate) and not self.sequential
                and type(self.measurement) is TdoaMeasurement and isinstance(self.measurement.motion, MotionModel))
