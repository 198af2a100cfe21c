"""Doppler-period measurement model of independent ultrasonic beacons (paper 003, eq 1).

A beacon at ``T`` chirps every ``P`` seconds (each beacon has its own period).
A receiver at ``X`` moving with velocity ``V`` sees the period stretched by
``ΔP``; eq 1 of McCarthy et al. relates the two:

.. math::

    \\frac{\\Delta P}{P + \\Delta P}\\, v_s = \\frac{X - T}{\\lVert X - T\\rVert}\\cdot V = u\\cdot V,
    \\qquad\\text{so}\\qquad
    \\Delta P = P\\,\\frac{r}{1 - r},\\quad r = \\frac{u\\cdot V}{v_s}.

Moving away from a beacon (``u·V > 0``) lengthens its period. ``v_s`` is the
speed of sound (default: dry air at 20 °C, :func:`speed_of_sound_mps`).

A measured ``ΔP`` is the difference of two arrival times one period apart, so
it describes the receiver *averaged over that period* (section 2.2). With
``lag_s`` the model evaluates eq 1 at ``X − lag·V`` — the position half a
period earlier when ``lag = P/2``, i.e. at the middle of the measured period
under constant velocity. ``lag = 0`` is the paper's instantaneous reading.

Section 5 of the paper proposes adding pseudo-ranges from a model of each
beacon's transmission clock; :meth:`DopplerModel.pseudo_range_m` is that
measurement, ``‖X − T‖``.

One :class:`DopplerModel` is used by the Monte Carlo sampler
(:mod:`uwbwb.sampling`), the chirp simulator (:mod:`uwbwb.sim.chirps`) and both
filters (:mod:`uwbwb.filters.doppler`); the receiver's motion model,
:class:`~uwbwb.models.motion.ReceiverMotion`, is a member of the kinematic family of
:mod:`uwbwb.models.motion` and importable from here too. The filters wrap the measurement
rows (:meth:`DopplerModel.measurement_rows`) in their own types, so this module imports
nothing above the models layer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..types import Anchors
from ..validate import integer, number

__all__ = ["speed_of_sound_mps", "DopplerModel", "cubic_layout", "lab_layout", "beacon_periods_s", "REFERENCE_POS_M",
           "REFERENCE_VEL_MPS"]

#: Reference pair of section 3.1 (metres, metres per second).
REFERENCE_POS_M = np.array([-0.5, 0.5, 0.4])
REFERENCE_VEL_MPS = np.array([0.5, 0.7, 0.1])


def speed_of_sound_mps(temperature_c: float = 20.0) -> float:
    """Speed of sound in dry air, ``331.3 √(1 + θ / 273.15)`` m/s (343.2 m/s at 20 °C)."""
    temperature_c = number("temperature_c", temperature_c, minimum=-273.15, strict_minimum=True)
    return float(331.3 * np.sqrt(1.0 + temperature_c / 273.15))


def beacon_periods_s(n: int, first_s: float = 0.501, step_s: float = 0.006) -> np.ndarray:
    """Unique beacon periods ``first + i·step`` (default 501, 507, … ms; mean ≈ 520 ms for 8 beacons)."""
    n = integer("n", n, minimum=1)
    first_s = number("first_s", first_s, minimum=0.0, strict_minimum=True)
    step_s = number("step_s", step_s, minimum=0.0)
    return first_s + step_s * np.arange(n)


def cubic_layout() -> Anchors:
    """Section 3.1's cube: beacons on the corners of a 4 m cube centred at the origin.

    Beacon ``i`` has coordinates ``(±2, ±2, ±2)`` with the bits of ``i`` giving
    the signs of x, y, z (z fastest), so beacon 0 is (−2, −2, −2), beacon 1 is
    (−2, −2, 2) and beacon 7 is (2, 2, 2), the paper's order.
    """
    pos = np.array([[x, y, z] for x in (-2.0, 2.0) for y in (-2.0, 2.0) for z in (-2.0, 2.0)])
    return Anchors(tuple(f"b{i}" for i in range(8)), pos)


def lab_layout() -> Anchors:
    """A reconstruction of the paper's lab (section 3.3): 8 beacons on walls and ceiling.

    The paper gives no coordinates, only "on the walls and ceiling" with "only a
    small variation in the Z-coordinates". Assumption: a 6 m × 5 m room centred at
    the origin, ceiling at z = 1.5 m; four irregularly placed ceiling beacons and
    four high on the walls (z 1.1–1.3 m), so the z spread is 0.4 m.
    """
    pos = np.array([[-1.5, -1.2, 1.5], [1.4, -1.0, 1.5], [-1.0, 1.3, 1.5], [1.6, 1.1, 1.5],
                    [-3.0, 0.3, 1.2], [3.0, -0.4, 1.25], [0.5, -2.5, 1.1], [-0.6, 2.5, 1.3]])
    return Anchors(tuple(f"b{i}" for i in range(8)), pos)


@dataclass(frozen=True)
class DopplerModel:
    """Eq 1 for a set of beacons with their periods, and its noise.

    Attributes
    ----------
    beacons
        Beacon positions (``n`` beacons).
    period_s
        Nominal period of each beacon, shape ``(n,)``, seconds, all distinct.
    v_s_mps
        Speed of sound, m/s.
    sigma_t_s
        Standard deviation of the timing jitter of one chirp arrival, seconds
        (the lab's 1–2 cm of ranging noise is 30–60 µs at 343 m/s).
    lag
        Where in the measured period eq 1 is evaluated, as a fraction of the period
        before the arrival that closes it: 0 = at the arrival (the paper's
        instantaneous reading), 0.5 = the middle of the period.
    sigma_model_mps
        Filters only (an assumption, not a property of the hardware): how far the
        radial speed averaged over a period may differ from eq 1 evaluated at one
        state, m/s. The receiver turns and accelerates within a period (half a
        second), which a single state cannot express; this term adds
        ``(P σ_model / v_s)²`` to the variance of each ΔP. The simulator ignores it.
    """

    beacons: Anchors
    period_s: np.ndarray
    v_s_mps: float = speed_of_sound_mps(20.0)
    sigma_t_s: float = 0.015 / speed_of_sound_mps(20.0)
    lag: float = 0.5
    sigma_model_mps: float = 0.1

    def __post_init__(self):
        if not isinstance(self.beacons, Anchors):
            raise ValueError(f"beacons must be Anchors, got {type(self.beacons).__name__}")
        P = np.array(self.period_s, float, copy=True)
        if P.shape != (len(self.beacons),):
            raise ValueError(f"period_s must have shape ({len(self.beacons)},), got {P.shape}")
        if not np.all(np.isfinite(P)) or np.any(P <= 0):
            raise ValueError(f"periods must be finite and > 0, got {P}")
        if np.unique(P).size != P.size:
            raise ValueError("beacon periods must be distinct (the period identifies the beacon)")
        P.setflags(write=False)
        object.__setattr__(self, "period_s", P)
        object.__setattr__(self, "v_s_mps", number("v_s_mps", self.v_s_mps, minimum=0.0, strict_minimum=True))
        object.__setattr__(self, "sigma_t_s", number("sigma_t_s", self.sigma_t_s, minimum=0.0))
        object.__setattr__(self, "sigma_model_mps", number("sigma_model_mps", self.sigma_model_mps, minimum=0.0))
        object.__setattr__(self, "lag", number("lag", self.lag, minimum=0.0, maximum=1.0))

    @classmethod
    def for_layout(cls, beacons: Anchors, **kwargs) -> "DopplerModel":
        """Model with the default periods 501, 507, … ms (:func:`beacon_periods_s`)."""
        return cls(beacons, beacon_periods_s(len(beacons)), **kwargs)

    @property
    def n_beacons(self) -> int:
        return len(self.beacons)

    def sigma_dp_s(self, beacon=None) -> np.ndarray:
        """Standard deviation the filters give one ΔP of ``beacon`` (all beacons if None), seconds.

        ``√(2 σ_t² + (P σ_model / v_s)²)``: timing jitter of the two arrivals plus the
        model error of reading a period average as one state (:attr:`sigma_model_mps`).
        """
        _, P = self._select(beacon)
        return np.sqrt(2.0 * self.sigma_t_s ** 2 + (P * self.sigma_model_mps / self.v_s_mps) ** 2)

    @property
    def sigma_m(self) -> float:
        """Timing jitter expressed as a distance, ``v_s σ_t`` (metres)."""
        return self.v_s_mps * self.sigma_t_s

    # ------------------------------------------------------------------ eq 1
    def _select(self, beacon):
        T = self.beacons.pos_m if beacon is None else self.beacons.pos_m[np.asarray(beacon)]
        P = self.period_s if beacon is None else self.period_s[np.asarray(beacon)]
        return T, P

    def delta_p(self, pos_m, vel_mps, beacon=None, *, instantaneous: bool = True) -> np.ndarray:
        """Period shift ``ΔP`` of eq 1, seconds.

        Parameters
        ----------
        pos_m, vel_mps
            Receiver position and velocity, shape ``(..., 3)``.
        beacon
            None: every beacon, result ``(..., n)``. An integer array broadcastable
            with ``pos_m[..., 0]``: that beacon per row, result ``(...)``.
        instantaneous
            True evaluates eq 1 at ``pos_m`` (section 3's sampling). False applies
            :attr:`lag`: eq 1 at ``pos_m − lag·P·vel_mps`` (a period that ended at
            the state's time, measured under constant velocity).
        """
        X = np.asarray(pos_m, float)
        V = np.asarray(vel_mps, float)
        T, P = self._select(beacon)
        if beacon is None:
            X, V = X[..., None, :], V[..., None, :]
        lagged = not instantaneous and self.lag
        # one axis at a time (long loops, not (..., 3) blocks), summed in np.sum's order: (d0 V0 + d1 V1) + d2 V2
        d = [(X[..., c] - self.lag * P * V[..., c] if lagged else X[..., c]) - T[..., c] for c in range(3)]
        r = (d[0] * V[..., 0] + d[1] * V[..., 1] + d[2] * V[..., 2]) / (
            np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * self.v_s_mps)
        return P * r / (1.0 - r)

    def jacobian(self, pos_m, vel_mps, beacon=None, *, instantaneous: bool = True) -> np.ndarray:
        """Derivative of :meth:`delta_p` w.r.t. the state ``[X, V]``, shape ``(..., n or -, 6)``.

        With ``d = X − T``, ``ρ = ‖d‖``, ``u = d / ρ`` and ``r = u·V / v_s``:
        ``∂ΔP/∂r = P / (1 − r)²``, ``∂r/∂X = (I − u uᵀ) V / (ρ v_s)``,
        ``∂r/∂V = u / v_s`` (plus ``−lag·P ∂r/∂X`` through the lagged position).
        """
        X = np.asarray(pos_m, float)
        V = np.asarray(vel_mps, float)
        T, P = self._select(beacon)
        if beacon is None:
            X, V = X[..., None, :], V[..., None, :]
        lagged = (not instantaneous) and self.lag
        if lagged:
            X = X - (self.lag * P)[..., None] * V
        d = X - T
        rho = np.linalg.norm(d, axis=-1, keepdims=True)
        u = d / rho
        uv = np.sum(u * V, axis=-1, keepdims=True)
        r = uv / self.v_s_mps
        dr_dx = (V - uv * u) / (rho * self.v_s_mps)
        dr_dv = u / self.v_s_mps
        if lagged:
            dr_dv = dr_dv - (self.lag * P)[..., None] * dr_dx
        scale = P[..., None] / (1.0 - r) ** 2
        return np.concatenate([scale * dr_dx, scale * dr_dv], axis=-1)

    def pseudo_range_m(self, pos_m, beacon=None) -> np.ndarray:
        """Range ``‖X − T‖`` (metres): the pseudo-range a beacon-clock model gives (section 5)."""
        X = np.asarray(pos_m, float)
        T, _ = self._select(beacon)
        if beacon is None:
            X = X[..., None, :]
        d = [X[..., c] - T[..., c] for c in range(3)]            # as delta_p: one axis at a time
        return np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])

    def distance_m(self, dp_a_s, dp_b_s) -> np.ndarray:
        """Section 3's δ as a distance: ``v_s ‖ΔP_a − ΔP_b‖`` over the last axis, metres.

        The paper says δ is expressed in cm "by dividing by the speed of sound"; a
        time becomes a distance by *multiplying* by it, which is what is done here.
        """
        diff = np.asarray(dp_a_s, float) - np.asarray(dp_b_s, float)
        return self.v_s_mps * np.linalg.norm(diff, axis=-1)

    def measurement_rows(self, x: np.ndarray, measurement):
        """One chirp's measurement rows at state ``x = [X, V]`` (6,): ``(z, h(x), H, R)`` or None.

        ``measurement`` is ``(beacon, dp_s, range_m)``: the beacon index (−1: none),
        the measured ΔP (NaN: none) and a pseudo-range (NaN: none). Uses the lagged
        model (:attr:`lag`). ``z``, ``h`` have shape ``(m,)``, ``H`` ``(m, 6)``, ``R``
        ``(m, m)`` with ``m`` ≤ 2; None when nothing usable was measured. The EKF's
        adapter is :class:`uwbwb.filters.doppler.DopplerMeasurement`.
        """
        beacon, dp_s, range_m = measurement
        beacon = int(beacon)
        if beacon < 0:
            return None
        if beacon >= self.n_beacons:
            raise ValueError(f"beacon must be -1 or an index below {self.n_beacons}, got {beacon}")
        x = np.asarray(x, float)
        if x.shape != (6,):
            raise ValueError(f"x must be a state [X, V] of shape (6,), got {x.shape}")
        z, h, H, R = [], [], [], []
        if np.isfinite(dp_s):
            b = np.array(beacon)
            z.append(float(dp_s))
            h.append(float(self.delta_p(x[:3], x[3:], b, instantaneous=False)))
            H.append(self.jacobian(x[:3], x[3:], b, instantaneous=False))
            R.append(float(self.sigma_dp_s(b)) ** 2)
        if np.isfinite(range_m):
            d = x[:3] - self.beacons.pos_m[beacon]
            rho = float(np.linalg.norm(d))
            z.append(float(range_m))
            h.append(rho)
            H.append(np.concatenate([d / rho, np.zeros(3)]))
            R.append(self.sigma_m ** 2)
        if not z:
            return None
        return np.array(z), np.array(h), np.array(H), np.diag(R)

    def log_likelihood(self, pos_m, vel_mps, beacon, dp_s, *, range_m=None) -> np.ndarray:
        """Gaussian log-likelihood of one measured ΔP (and optionally a pseudo-range) per row.

        ``ΔP ~ N(h(X, V), σ_ΔP²)`` (:meth:`sigma_dp_s`) with the lagged model; a pseudo-range
        ``~ N(‖X − T‖, (v_s σ_t)²)``. Shapes broadcast like :meth:`delta_p` with a beacon.
        """
        s = self.sigma_dp_s(beacon)
        if np.any(s <= 0):
            raise ValueError("log_likelihood needs sigma_t_s > 0 or sigma_model_mps > 0")
        y = (np.asarray(dp_s, float) - self.delta_p(pos_m, vel_mps, beacon, instantaneous=False)) / s
        ll = -0.5 * y * y - np.log(s * np.sqrt(2 * np.pi))
        if range_m is not None:
            sr = self.sigma_m
            yr = (np.asarray(range_m, float) - self.pseudo_range_m(pos_m, beacon)) / sr
            ll = ll - 0.5 * yr * yr - np.log(sr * np.sqrt(2 * np.pi))
        return ll
