"""Motion models driven by continuous-time white noise, shared by simulators and filters.

Three kinematic models of increasing order, as in De Angelis (thesis summary,
eqs 11–18, after Li & Jilkov's survey of maneuvering-target models):

=========================  ======  ==========================  ================  ==============
model                      order   state per axis              white noise on    PSD ``q`` unit
=========================  ======  ==========================  ================  ==============
:class:`RandomWalk` (RW)   1       position                    velocity          m²/s
:class:`RandomForce` (RF)  2       position, velocity          acceleration      m²/s³
:class:`RandomJerk` (RJ)   3       position, velocity, accel.  jerk              m²/s⁵
=========================  ======  ==========================  ================  ==============

Each is the ``n``-fold integral of a white process ``w(t)`` with (two-sided)
power spectral density ``q`` per axis, ``E[w(t) w(s)] = q δ(t − s)``. Over a
step ``dt`` the exact discretisation gives, per axis,

.. math::

    F_{ij} = \\frac{dt^{j-i}}{(j-i)!}\\ (j \\ge i), \\qquad
    Q_{ij} = q\\,\\frac{dt^{2n-1-i-j}}{(2n-1-i-j)\\,(n-1-i)!\\,(n-1-j)!},

i.e. ``Q = q dt`` (RW), ``q [[dt³/3, dt²/2], [dt²/2, dt]]`` (RF) and
``q [[dt⁵/20, dt⁴/8, dt³/6], [dt⁴/8, dt³/3, dt²/2], [dt³/6, dt²/2, dt]]`` (RJ).
The thesis' eq. (17) ``F_3`` is the RJ transition above.

States are stacked derivative-major, ``[p (dim), v (dim), a (dim)]``, so the
position is always ``x[..., :dim]`` whatever the model. ``dim`` is 2 or 3.

Driving-noise "variances" as the thesis reports them (its Table 1, in m/s,
m/s² and m/s³) are standard deviations of the driving process over one filter
step. We relate them to the PSD by ``q = σ_w² · dt`` (the variance of the white
process averaged over ``dt`` is ``q / dt``); for the random walk this makes
``Q = σ_v² dt²`` exactly the thesis' eq. (12). See :meth:`MotionModel.from_sigma`.

:class:`VelocityKick` is the discrete-time constant-velocity model of Banerjee et al.
(paper 000, eq. 3): the velocity changes by an independent ``N(0, σ_d²)`` at every step,
whatever its length, after the position has moved with the old velocity.

One family
----------
All five models below are members of one family: they follow the protocol
:class:`~uwbwb.models.layout.KinematicModel` — ``n_x``, ``layout`` (a
:class:`~uwbwb.models.layout.StateLayout`: the labels of the state, ``pos_index``,
``vel_index``, permutations to other orders), ``F(dt)`` and ``Q(dt)`` vectorised over
``dt``, ``step(x, dt, rng=)`` and ``sample_path(x0, t_s, rng=)`` — and stack their
states derivative-major. They are different models, not one formula: the first three
integrate continuous-time white noise (``Q`` as above), the two discrete ones draw one
random kick per step: a velocity change whatever the step's length (:class:`VelocityKick`),
an acceleration held over the step (:class:`ReceiverMotion`).

=======================  ====  =============  ======================================  ===================================
model                    dim   state          ``Q`` over a step ``dt``                parameter (unit)
=======================  ====  =============  ======================================  ===================================
:class:`RandomWalk`      2, 3  ``[p]``        ``q dt``                                ``psd_m2ps`` (m²/s)
:class:`RandomForce`     2, 3  ``[p, v]``     ``q [[dt³/3, dt²/2], [dt²/2, dt]]``     ``psd_m2ps3`` (m²/s³)
:class:`RandomJerk`      2, 3  ``[p, v, a]``  ``q`` × the RJ matrix above             ``psd_m2ps5`` (m²/s⁵)
:class:`VelocityKick`    2, 3  ``[p, v]``     ``diag(0, σ_d²)`` for any ``dt``        ``sigma_d_mps`` (m/s)
:class:`ReceiverMotion`  3     ``[p, v]``     ``G diag(σ²) Gᵀ``, ``G = [dt²/2; dt]``  ``sigma_acc_mps2`` (m/s², per axis)
=======================  ====  =============  ======================================  ===================================

:class:`ReceiverMotion` (paper 003, section 4.2) is the discrete white-noise-acceleration
model: an acceleration ``a ~ N(0, diag σ²)`` held constant over each step, with its own
``σ`` per axis (it is also importable from :mod:`uwbwb.models.doppler`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, make_dataclass, replace
from math import factorial
from typing import ClassVar

import numba
import numpy as np
from .layout import StateLayout


__all__ = ["MotionModel", "RandomWalk", "RandomForce", "RandomJerk", "MOTION_MODELS", "make_motion_model",
           "transition_1d", "noise_1d", "VelocityKick", "ReceiverMotion"]


def transition_1d(order: int, dt_s) -> np.ndarray:
    """Per-axis transition of an ``order``-fold integrator, shape ``(..., order, order)``.

    ``F[i, j] = dt^(j−i) / (j−i)!`` for ``j ≥ i``, 0 below the diagonal.
    ``dt_s`` may be a scalar or an array of step lengths (seconds).
    """
    dt = np.asarray(dt_s, float)[..., None, None]
    i, j = np.indices((order, order))
    k = np.clip(j - i, 0, None)
    fact = np.array([factorial(int(m)) for m in k.ravel()], float).reshape(k.shape)
    return np.where(j >= i, dt ** k / fact, 0.0)


def noise_1d(order: int, dt_s) -> np.ndarray:
    """Per-axis discrete process noise for unit PSD, shape ``(..., order, order)``.

    ``Q[i, j] = dt^p / (p (n−1−i)! (n−1−j)!)`` with ``p = 2n − 1 − i − j``:
    the covariance accumulated over ``dt`` by white noise of unit PSD driving
    the ``order``-th derivative.
    """
    dt = np.asarray(dt_s, float)[..., None, None]
    n = order
    i, j = np.indices((n, n))
    p = 2 * n - 1 - i - j
    denom = p * np.array([factorial(n - 1 - a) * factorial(n - 1 - b) for a, b in zip(i.ravel(), j.ravel())],
                         float).reshape(p.shape)
    return dt ** p / denom


def _per_axis(block: np.ndarray, dim: int) -> np.ndarray:
    """Kronecker product ``block ⊗ I_dim`` over the last two axes (derivative-major stacking)."""
    n = block.shape[-1]
    eye = np.eye(dim)
    full = block[..., :, None, :, None] * eye[:, None, :]
    return full.reshape(block.shape[:-2] + (n * dim, n * dim))


#: Abbreviation and white-driven quantity of the model of each order (thesis eqs 11–18).
_KINDS = {1: ("RW", "velocity"), 2: ("RF", "acceleration"), 3: ("RJ", "jerk")}
_SUPERSCRIPT = {1: "", 2: "²", 3: "³", 5: "⁵"}


def _describe(order: int) -> tuple[str, str, str, str, str]:
    """``(abbreviation, driven, psd_field, psd_unit, sigma_unit)`` of the model of ``order``.

    The PSD ``q`` of the white ``order``-th derivative has unit m²/s^(2·order − 1); its
    standard deviation over a step, m/s^order.
    """
    p = 2 * order - 1
    return (*_KINDS[order], "psd_m2ps" + (str(p) if p > 1 else ""), "m²/s" + _SUPERSCRIPT[p],
            "m/s" + _SUPERSCRIPT[order])


def _check_parameters(model, field: str, value: float) -> None:
    """A model's ``dim`` is 2 or 3 and its noise parameter ``field`` (value ``value``) is finite and >= 0."""
    if model.dim not in (2, 3):
        raise ValueError(f"{type(model).__name__}.dim must be 2 or 3, got {model.dim!r}")
    if not np.isfinite(value) or value < 0:
        raise ValueError(f"{type(model).__name__}.{field} must be finite and >= 0, got {value!r}")


class _Kinematic:
    """What every member of the family derives from its ``order`` (derivative blocks) and ``dim``:
    the state size and its declared layout, derivative-major ``[p (dim), v (dim), a (dim)][: n_x]``."""

    order: ClassVar[int]
    dim: int

    @property
    def n_x(self) -> int:
        """State size, ``order · dim``."""
        return self.order * self.dim

    @property
    def layout(self) -> StateLayout:
        """The state's layout (:class:`~uwbwb.models.layout.StateLayout`), derivative-major."""
        return StateLayout.kinematic(self.dim, self.order)

    @property
    def state_labels(self) -> tuple[str, ...]:
        """Column names of the state, e.g. ``("x_m", "y_m", "vx_mps", "vy_mps")`` (``layout.labels``)."""
        return self.layout.labels


class MotionModel(_Kinematic):
    """Common behaviour of the white-noise-driven kinematic models.

    Subclasses are frozen dataclasses with one PSD field (named with its unit)
    and ``dim``. Class attributes describe the model: ``order`` (number of
    derivative blocks in the state), ``abbreviation`` ("RW", "RF", "RJ"),
    ``driven`` (the quantity that is white), ``psd_unit`` and ``sigma_unit``, all
    derived from ``order`` when the subclass is defined.

    Attributes
    ----------
    dim
        Number of position coordinates (2 or 3).
    """

    order: ClassVar[int]
    abbreviation: ClassVar[str]
    driven: ClassVar[str]
    psd_field: ClassVar[str]
    psd_unit: ClassVar[str]
    sigma_unit: ClassVar[str]
    dim: int

    def __init_subclass__(cls, **kwargs):
        """Describe a subclass from its ``order``: name, driven quantity, PSD field and units."""
        super().__init_subclass__(**kwargs)
        cls.abbreviation, cls.driven, cls.psd_field, cls.psd_unit, cls.sigma_unit = _describe(cls.order)

    def __post_init__(self):
        self._validate()

    def _validate(self):
        _check_parameters(self, self.psd_field, self.psd)

    # ----------------------------------------------------------- description
    @property
    def psd(self) -> float:
        """Spectral density ``q`` of the white driving noise per axis (unit: :attr:`psd_unit`)."""
        return float(getattr(self, self.psd_field))

    def with_psd(self, psd: float):
        """The same model with another PSD."""
        return replace(self, **{self.psd_field: float(psd)})

    @classmethod
    def from_sigma(cls, sigma: float, dt_s: float, dim: int = 2):
        """Model whose driving process has standard deviation ``sigma`` over a step ``dt_s``.

        ``q = sigma² · dt_s``; ``sigma`` is in :attr:`sigma_unit` (m/s, m/s², m/s³),
        the unit of the thesis' Table 1.
        """
        if sigma < 0 or dt_s <= 0:
            raise ValueError(f"sigma must be >= 0 and dt_s > 0, got {sigma!r}, {dt_s!r}")
        return cls(**{cls.psd_field: float(sigma) ** 2 * float(dt_s), "dim": dim})

    def sigma(self, dt_s: float) -> float:
        """Driving-process standard deviation over a step ``dt_s``, ``sqrt(q / dt_s)`` (:attr:`sigma_unit`)."""
        return float(np.sqrt(self.psd / dt_s))

    def __str__(self) -> str:
        return f"{self.abbreviation} (q = {self.psd:.3g} {self.psd_unit}, {self.dim}-D)"

    # ----------------------------------------------------------- matrices
    def F(self, dt_s) -> np.ndarray:
        """State transition over ``dt_s`` seconds, shape ``(..., n_x, n_x)``."""
        return _per_axis(transition_1d(self.order, dt_s), self.dim)

    def Q(self, dt_s) -> np.ndarray:
        """Process-noise covariance over ``dt_s`` seconds, shape ``(..., n_x, n_x)`` (SI units of the state)."""
        return self.psd * _per_axis(noise_1d(self.order, dt_s), self.dim)

    def Q_sqrt(self, dt_s) -> np.ndarray:
        """A square root ``L`` of :meth:`Q` (``L Lᵀ = Q``), shape ``(..., n_x, n_x)``.

        Computed from the scaling ``Q(dt) = q dt · D Q(1) D`` with
        ``D = diag(dt^(n−1−i))``, which stays exact where a Cholesky factorisation
        of ``Q(dt)`` itself would be ill-conditioned (tiny ``dt``, high order).
        """
        dt = np.asarray(dt_s, float)
        n = self.order
        L1 = np.linalg.cholesky(noise_1d(n, 1.0))
        scale = dt[..., None] ** (n - 1 - np.arange(n)) * np.sqrt(self.psd * dt)[..., None]   # (..., n)
        return _per_axis(scale[..., :, None] * L1, self.dim)

    def G(self, dt_s) -> np.ndarray:
        """Input matrix for a piecewise-constant input on the driven derivative, shape ``(..., n_x, dim)``.

        ``G[k] = dt^(n−k) / (n−k)!`` per axis (RW: ``dt``; RF: ``dt²/2, dt``;
        RJ: ``dt³/6, dt²/2, dt``). The simulators use it for steering commands.
        """
        dt = np.asarray(dt_s, float)[..., None]
        n = self.order
        g = np.stack([dt[..., 0] ** (n - k) / factorial(n - k) for k in range(n)], axis=-1)  # (..., n)
        return (g[..., :, None, None] * np.eye(self.dim)).reshape(g.shape[:-1] + (n * self.dim, self.dim))

    @property
    def H_pos(self) -> np.ndarray:
        """Selection matrix of the position, shape ``(dim, n_x)``."""
        return np.eye(self.dim, self.n_x)

    def position(self, x: np.ndarray) -> np.ndarray:
        """Positions from states: ``x[..., :dim]`` (metres)."""
        return np.asarray(x)[..., : self.dim]

    def velocity(self, x: np.ndarray) -> np.ndarray | None:
        """Velocities from states (m/s), or None for the random walk (no velocity state)."""
        return None if self.order < 2 else np.asarray(x)[..., self.dim: 2 * self.dim]

    # ----------------------------------------------------------- states
    def initial_state(self, pos_m, vel_mps=None, acc_mps2=None) -> np.ndarray:
        """Stack a state vector ``(n_x,)`` from its parts (missing derivatives are zero)."""
        parts = [np.asarray(pos_m, float)]
        for k, v in enumerate((vel_mps, acc_mps2)[: self.order - 1]):
            parts.append(np.zeros(self.dim) if v is None else np.asarray(v, float))
        x = np.concatenate(parts)
        if x.shape != (self.n_x,):
            raise ValueError(f"{self.abbreviation}: parts give a state of shape {x.shape}, expected ({self.n_x},)")
        return x

    def initial_covariance(self, pos_sigma_m: float = 1.0, vel_sigma_mps: float = 1.0,
                           acc_sigma_mps2: float = 1.0) -> np.ndarray:
        """Diagonal prior covariance ``(n_x, n_x)`` from per-axis standard deviations."""
        sig = np.array([pos_sigma_m, vel_sigma_mps, acc_sigma_mps2][: self.order], float)
        return np.diag(np.repeat(sig ** 2, self.dim))

    def step(self, x: np.ndarray, dt_s, *, rng: np.random.Generator | None) -> np.ndarray:
        """One step of the model for states ``(..., n_x)``: ``F x + L ε``, ``ε ~ N(0, I)``, ``L Lᵀ = Q``.

        ``dt_s`` is a scalar or an array broadcastable with ``x[..., 0]`` (seconds); ``L`` is
        :meth:`Q_sqrt`. The standard normals are drawn with the broadcast shape of the states,
        ``(..., n_x)``; ``rng=None`` moves the states without noise (``F x``).
        """
        x = np.asarray(x, float)
        out = np.einsum("...ij,...j->...i", self.F(dt_s), x)
        if rng is None:
            return out
        eps = rng.standard_normal(out.shape)
        return out + np.einsum("...ij,...j->...i", self.Q_sqrt(dt_s), eps)

    def sample_path(self, x0: np.ndarray, t_s: np.ndarray, *, rng: np.random.Generator,
                    u: np.ndarray | None = None) -> np.ndarray:
        """Draw states at ``t_s`` from the model: ``x_{k+1} = F x_k + G u_k + w_k``, ``w_k ~ N(0, Q)``.

        Parameters
        ----------
        x0
            State at ``t_s[0]``, shape ``(n_x,)``.
        t_s
            Times, shape ``(T,)``, seconds, strictly increasing.
        u
            Optional piecewise-constant input on the driven derivative, shape
            ``(T − 1, dim)`` (held over each step).

        Returns
        -------
        ndarray, shape ``(T, n_x)``
        """
        t_s = np.asarray(t_s, float)
        dt = np.diff(t_s)
        if np.any(dt <= 0):
            raise ValueError("sample_path: t_s must be strictly increasing")
        F = self.F(dt)
        w = np.einsum("tij,tj->ti", self.Q_sqrt(dt), rng.standard_normal((dt.size, self.n_x)))
        if u is not None:
            w = w + np.einsum("tij,tj->ti", self.G(dt), np.asarray(u, float))
        x = np.empty((t_s.size, self.n_x))
        x[0] = x0
        for k in range(dt.size):
            x[k + 1] = F[k] @ x[k] + w[k]
        return x


def _kinematic_model(name: str, order: int, default_psd: float, summary: str) -> type[MotionModel]:
    """The frozen dataclass of one order: its PSD field (named by :meth:`MotionModel.__init_subclass__`) and ``dim``."""
    cls = make_dataclass(name, [(_describe(order)[2], float, field(default=default_psd)), ("dim", int, field(default=2))],
                         bases=(MotionModel,), namespace={"order": order, "__module__": __name__}, frozen=True)
    cls.__doc__ = (f"{summary}\n\n    ``{cls.psd_field}`` is the spectral density ``q`` of the white {cls.driven}, "
                   f"{cls.psd_unit}; ``Q`` follows :func:`noise_1d`.\n    ")
    return cls


RandomWalk = _kinematic_model("RandomWalk", 1, 0.07, "Random walk (RW): position state, white velocity (thesis eqs 11–12).")
RandomForce = _kinematic_model("RandomForce", 2, 0.1,
                               "Random force (RF): constant velocity with white acceleration (thesis eqs 13–14).")
RandomJerk = _kinematic_model("RandomJerk", 3, 0.1,
                              "Random jerk (RJ): constant acceleration with white jerk (thesis eqs 15–18).")


#: The three models by their abbreviation.
MOTION_MODELS: dict[str, type[MotionModel]] = {"RW": RandomWalk, "RF": RandomForce, "RJ": RandomJerk}


def make_motion_model(name: str, *, sigma: float, dt_s: float, dim: int = 2) -> MotionModel:
    """Model ``"RW" | "RF" | "RJ"`` with driving std ``sigma`` over steps of ``dt_s``.

    See :meth:`MotionModel.from_sigma` for the convention ``q = sigma² · dt_s``.
    """
    try:
        cls = MOTION_MODELS[name.upper()]
    except KeyError:
        raise ValueError(f"unknown motion model {name!r}; choose one of {list(MOTION_MODELS)}") from None
    return cls.from_sigma(sigma, dt_s, dim)


@dataclass(frozen=True)
class VelocityKick(_Kinematic):
    """Constant velocity with a random velocity change per step (paper 000, eq. 3).

    Between fixes ``T`` seconds apart, per axis::

        p ← p + T v,    v ← v + N(0, σ_d²)

    so ``σ_d`` is the standard deviation of the velocity change *per step* (m/s), not a
    spectral density: ``F(T)`` is the constant-velocity transition and
    ``Q = diag(0, σ_d²)`` per axis for any ``T``. States are derivative-major like the other
    models here, ``[p (dim), v (dim)]``.

    The set-noise filters (:mod:`uwbwb.filters.setnoise`) use this object: the particle
    filter's reference steps through :meth:`step`, the Kalman filter through :meth:`F` and
    :meth:`Q`; their batched kernels are tested against it.

    Attributes
    ----------
    sigma_d_mps
        Standard deviation of the velocity change per step, m/s (>= 0).
    dim
        Number of position coordinates (2 or 3).
    """

    sigma_d_mps: float = 0.3
    dim: int = 2

    order: ClassVar[int] = 2
    abbreviation: ClassVar[str] = "CV"

    def __post_init__(self):
        _check_parameters(self, "sigma_d_mps", self.sigma_d_mps)

    def F(self, dt_s) -> np.ndarray:
        """State transition over steps ``dt_s`` (scalar or array), shape ``(..., n_x, n_x)``."""
        return _per_axis(transition_1d(2, dt_s), self.dim)

    def Q(self, dt_s) -> np.ndarray:
        """Process noise ``diag(0, σ_d²)`` per axis, shape ``(..., n_x, n_x)`` (independent of ``dt_s``)."""
        dt = np.asarray(dt_s, float)
        block = np.zeros(dt.shape + (2, 2))
        block[..., 1, 1] = self.sigma_d_mps ** 2
        return _per_axis(block, self.dim)

    @property
    def H_pos(self) -> np.ndarray:
        """Selection matrix of the position, shape ``(dim, n_x)``."""
        return np.eye(self.dim, self.n_x)

    def position(self, x: np.ndarray) -> np.ndarray:
        """Positions from states ``(..., n_x)``: ``x[..., :dim]`` (metres)."""
        return np.asarray(x)[..., : self.dim]

    def velocity(self, x: np.ndarray) -> np.ndarray:
        """Velocities from states: ``x[..., dim:]`` (m/s)."""
        return np.asarray(x)[..., self.dim:]

    def initial_state(self, pos_m, vel_mps=None) -> np.ndarray:
        """State ``(n_x,)`` from a position and a velocity (zero if not given)."""
        v = np.zeros(self.dim) if vel_mps is None else np.asarray(vel_mps, float)
        x = np.concatenate([np.asarray(pos_m, float), v])
        if x.shape != (self.n_x,):
            raise ValueError(f"VelocityKick: parts give a state of shape {x.shape}, expected ({self.n_x},)")
        return x

    def propagate(self, x: np.ndarray, dt_s, dv_mps) -> np.ndarray:
        """Eq. 3 with given velocity changes: ``p + dt v`` and ``v + dv`` for states ``(..., n_x)``.

        ``dv_mps`` has shape ``(..., dim)`` (broadcastable to the states' velocities).
        """
        x = np.array(x, float, copy=True)
        d = self.dim
        x[..., :d] += dt_s * x[..., d:]
        x[..., d:] += dv_mps
        return x

    def step(self, x: np.ndarray, dt_s, *, rng: np.random.Generator | None) -> np.ndarray:
        """Eq. 3 with ``dv ~ N(0, σ_d²)`` per axis for states ``(..., n_x)`` (e.g. particles ``(..., K, n_x)``);
        ``rng=None`` moves the states without a kick, as every member of the family does.

        The standard normals are drawn axis-major, shape ``(dim, ...)``, the order the batched
        particle-filter kernel draws them in.
        """
        x = np.asarray(x, float)
        if rng is None:
            return self.propagate(x, dt_s, 0.0)
        w = np.moveaxis(rng.standard_normal((self.dim,) + x.shape[:-1]), 0, -1)
        return self.propagate(x, dt_s, self.sigma_d_mps * w)

    def sample_path(self, x0: np.ndarray, t_s: np.ndarray, *, rng: np.random.Generator) -> np.ndarray:
        """States ``(T, n_x)`` at ``t_s`` from ``x0``, one :meth:`step` per interval."""
        return _sample_by_steps(self, x0, t_s, rng)


def _sample_by_steps(model, x0, t_s, rng) -> np.ndarray:
    """A path ``(T, n_x)`` of a discrete model: ``x[k + 1] = model.step(x[k], t[k + 1] − t[k], rng=rng)``."""
    t_s = np.asarray(t_s, float)
    dt = np.diff(t_s)
    if np.any(dt <= 0):
        raise ValueError(f"{type(model).__name__}.sample_path: t_s must be strictly increasing")
    x = np.empty((t_s.size, model.n_x))
    x[0] = x0
    for k in range(dt.size):
        x[k + 1] = model.step(x[k], dt[k], rng=rng)
    return x


@dataclass(frozen=True)
class ReceiverMotion(_Kinematic):
    """Section 4.2's receiver motion (paper 003): position moves with velocity, velocity takes random kicks.

    Interpretation: the "random variation" of σ 2 m/s² (x, y) and 0.2 m/s² (z) is
    an acceleration held constant over each step between chirps (discrete white
    noise acceleration), so over ``dt`` the state ``[X, V]`` gets
    ``Δx = v dt + a dt²/2``, ``Δv = a dt``, ``a ~ N(0, diag σ²)``. The state is
    derivative-major, ``[x, y, z, vx, vy, vz]`` (:attr:`layout`).

    Attributes
    ----------
    sigma_acc_mps2
        Per-axis acceleration standard deviation, shape ``(3,)``, m/s².
    """

    sigma_acc_mps2: tuple[float, float, float] = (2.0, 2.0, 0.2)

    dim: ClassVar[int] = 3
    order: ClassVar[int] = 2
    abbreviation: ClassVar[str] = "DWNA"

    def __post_init__(self):
        try:
            s = tuple(float(v) for v in self.sigma_acc_mps2)
        except (TypeError, ValueError):
            s = ()
        if len(s) != 3 or not all(np.isfinite(v) and v >= 0 for v in s):
            raise ValueError(f"sigma_acc_mps2 must be three finite values >= 0 (m/s²), got {self.sigma_acc_mps2!r}")
        object.__setattr__(self, "sigma_acc_mps2", s)

    def F(self, dt_s) -> np.ndarray:
        """Transition over ``dt_s``, shape ``(..., 6, 6)``."""
        if np.ndim(dt_s) == 0:                       # one step (the EKF's case): no broadcasting
            F = np.eye(6)
            F[0, 3] = F[1, 4] = F[2, 5] = float(dt_s)
            return F
        dt = np.asarray(dt_s, float)[..., None, None]
        eye = np.eye(3)
        top = np.concatenate([np.broadcast_to(eye, dt.shape[:-2] + (3, 3)), dt * eye], axis=-1)
        bottom = np.concatenate([np.zeros(dt.shape[:-2] + (3, 3)), np.broadcast_to(eye, dt.shape[:-2] + (3, 3))],
                                axis=-1)
        return np.concatenate([top, bottom], axis=-2)

    def Q(self, dt_s) -> np.ndarray:
        """Process noise ``G diag(σ²) Gᵀ`` with ``G = [dt²/2 I; dt I]``, shape ``(..., 6, 6)``."""
        s2 = np.diag(np.square(self.sigma_acc_mps2))
        if np.ndim(dt_s) == 0:                       # one step: the same blocks without broadcasting
            dt = float(dt_s)
            Q = np.empty((6, 6))
            Q[:3, :3], Q[:3, 3:] = dt ** 4 / 4 * s2, dt ** 3 / 2 * s2
            Q[3:, :3], Q[3:, 3:] = dt ** 3 / 2 * s2, dt ** 2 * s2
            return Q
        dt = np.asarray(dt_s, float)[..., None, None]
        return np.concatenate([np.concatenate([dt ** 4 / 4 * s2, dt ** 3 / 2 * s2], axis=-1),
                               np.concatenate([dt ** 3 / 2 * s2, dt ** 2 * s2], axis=-1)], axis=-2)

    def propagate(self, x: np.ndarray, dt_s, *, rng: np.random.Generator | None) -> np.ndarray:
        """Move states ``(..., 6)`` over ``dt_s`` (scalar or broadcastable); ``rng=None``: no noise."""
        x = np.asarray(x, float)
        batch = x.shape[:-1]
        noise = np.zeros(batch + (3,)) if rng is None else rng.standard_normal(batch + (3,))
        dt = np.broadcast_to(np.asarray(dt_s, float), batch)
        out = np.empty(x.shape)
        _propagate_rows(np.ascontiguousarray(x).reshape(-1, 6), noise.reshape(-1, 3), np.ravel(dt),
                        np.asarray(self.sigma_acc_mps2), out.reshape(-1, 6))
        return out

    def step(self, x: np.ndarray, dt_s, *, rng: np.random.Generator | None) -> np.ndarray:
        """The family's name for :meth:`propagate` (same draws, same numbers)."""
        return self.propagate(x, dt_s, rng=rng)

    def sample_path(self, x0: np.ndarray, t_s: np.ndarray, *, rng: np.random.Generator) -> np.ndarray:
        """States ``(T, 6)`` at ``t_s`` from ``x0``, one :meth:`propagate` per interval."""
        return _sample_by_steps(self, x0, t_s, rng)


@numba.njit(cache=True, nogil=True)
def _propagate_rows(x, noise, dt, sigma, out):
    """:meth:`ReceiverMotion.propagate` on rows ``(N, 6)`` with their standard normals ``(N, 3)`` and steps ``(N,)``:
    per axis ``a = noise · σ``, ``p + v dt + a dt²/2`` and ``v + a dt``, the operations of its NumPy definition in
    its order (no noise: ``noise`` all zeros, ``a = 0``)."""
    for n in range(x.shape[0]):
        h = dt[n]
        for c in range(3):
            a = noise[n, c] * sigma[c]
            out[n, c] = x[n, c] + x[n, 3 + c] * h + 0.5 * a * h * h
            out[n, 3 + c] = x[n, 3 + c] + a * h
