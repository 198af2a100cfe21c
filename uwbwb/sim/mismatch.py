"""Model mismatch for the robot re-creation of paper 004: the world ≠ the filters' noise model.

In :mod:`uwbwb.sim.robot` the simulator and the tight filter share **one** noise model: the IMU
errors are drawn from the same :class:`~uwbwb.models.imu.ImuErrorModel` the filter's Q comes
from, the TDoAs from the same :class:`~uwbwb.models.tdoa.TdoaModel` its R comes from. A filter
that wins there may win only because its model is exactly right. A :class:`Mismatch` keeps the
filters' model (the *nominal* :class:`~uwbwb.sim.robot.RobotConfig`) and changes the world the
simulator draws from (:meth:`Mismatch.world`). Every value below is an **assumption** chosen to
probe one model error at a time, not taken from the paper.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from .robot import RobotConfig

__all__ = ["Mismatch", "CASES", "case"]


@dataclass(frozen=True)
class Mismatch:
    """One way in which the simulated world departs from the filters' model.

    Attributes
    ----------
    name
        Short label (the row of the mismatch table).
    imu_scale
        Every IMU error (noise densities, bias spreads and random walks) of the world is this
        multiple of the modelled one.
    uwb_sigma_scale
        The world's arrival-time noise σ is this multiple of the modelled one.
    range_bias_sigma_m, range_bias_tau_s
        Time-correlated range bias per station (first-order Gauss–Markov), m and s; 0: none.
    outlier_rate, outlier_excess_m
        Multipath of the world (base rate per station and epoch, excess range drawn
        uniformly in ``(low, high)``, m); None keeps the nominal value.
    """

    name: str
    imu_scale: float = 1.0
    uwb_sigma_scale: float = 1.0
    range_bias_sigma_m: float = 0.0
    range_bias_tau_s: float = 30.0
    outlier_rate: float | None = None
    outlier_excess_m: tuple | None = None

    def __post_init__(self):
        for k in ("imu_scale", "uwb_sigma_scale"):
            if not getattr(self, k) > 0:
                raise ValueError(f"Mismatch.{k} must be > 0, got {getattr(self, k)!r}")

    @property
    def matched(self) -> bool:
        """True when the world is the model (no field departs from the nominal)."""
        return (self.imu_scale == 1 and self.uwb_sigma_scale == 1 and self.range_bias_sigma_m == 0
                and self.outlier_rate is None and self.outlier_excess_m is None)

    def world(self, model: RobotConfig) -> RobotConfig:
        """The simulator's configuration: ``model`` with this mismatch applied."""
        kw = dict(imu=model.imu if self.imu_scale == 1 else model.imu.scaled(self.imu_scale),
                  sigma_toa_m=model.sigma_toa_m * self.uwb_sigma_scale,
                  range_bias_sigma_m=self.range_bias_sigma_m, range_bias_tau_s=self.range_bias_tau_s)
        if self.outlier_rate is not None:
            kw["outlier_rate"] = self.outlier_rate
        if self.outlier_excess_m is not None:
            kw["outlier_excess_m"] = tuple(self.outlier_excess_m)
        return replace(model, **kw)


#: The mismatch axis of notebook 05 (assumptions, one model error each).
CASES = (
    Mismatch("matched"),
    Mismatch("IMU 3× worse", imu_scale=3.0),
    Mismatch("IMU 10× worse", imu_scale=10.0),
    Mismatch("UWB σ 2×", uwb_sigma_scale=2.0),
    Mismatch("range bias GM 5 cm, 30 s", range_bias_sigma_m=0.05, range_bias_tau_s=30.0),
    Mismatch("small frequent multipath", outlier_rate=0.15, outlier_excess_m=(0.05, 0.3)),
    Mismatch("multipath up to 12 m", outlier_excess_m=(0.3, 12.0)),
)


def case(name: str) -> Mismatch:
    """The case of :data:`CASES` called ``name`` (ValueError listing the names otherwise)."""
    for c in CASES:
        if c.name == name:
            return c
    raise ValueError(f"unknown mismatch case {name!r}; known: {[c.name for c in CASES]}")
