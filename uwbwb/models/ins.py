"""Strapdown inertial navigation in a local level frame, and its error-state model (paper 004, eq. 3).

Frames and conventions (all explicit, all tested)
--------------------------------------------------
* **Navigation frame** ``n``: local level, fixed to the room, ``"ENU"`` (x east,
  y north, z up; gravity ``g_n = [0, 0, −g]``) or ``"NED"`` (``g_n = [0, 0, +g]``).
* **Body frame** ``b``: the IMU's axes after :class:`~uwbwb.models.imu.ImuConvention`
  has rotated the sensor axes into it.
* **Attitude**: unit quaternion ``q = [w, x, y, z]`` (scalar first, Hamilton
  product) rotating body vectors into the navigation frame, ``v_n = C(q) v_b``.
  :func:`quat_convert` changes to and from the scalar-last order other libraries use.
* **Euler angles** (:func:`euler_from_dcm`): ``C = Rz(yaw) Ry(pitch) Rx(roll)``;
  in ENU yaw is measured counter-clockwise from east.

Mechanization (eq. 3, ``X_{k+1} = f_ins(X_k, U_k)``) over one interval
``[t_k, t_{k+1}]`` with specific force ``f`` and angular rate ``ω`` sampled at
both ends (second order, trapezoidal)::

    q_{k+1} = q_k ⊗ Exp(½ (ω_k + ω_{k+1}) Δt)
    v_{k+1} = v_k + ½ (C_k f_k + C_{k+1} f_{k+1}) Δt + g_n Δt
    p_{k+1} = p_k + ½ (v_k + v_{k+1}) Δt

The global error is ``O(Δt²)`` (tested by halving ``Δt``).

**Earth rate is neglected.** Ω_ie = 7.3e-5 rad/s = 15 °/h. A MEMS gyro's
residual bias is 10–1000 °/h and its angle random walk alone exceeds what Earth
rate adds over the minutes of a room-scale run; the Coriolis term ``2 Ω × v``
at 1 m/s is 1.5e-4 m/s², about 1 mm of position over 60 s even uncorrected;
transport rate over a room is nil. A tactical IMU would need Ω_ie in both the
mechanization and the error model; the UWB updates absorb it here.

Error state (15, navigation-frame attitude error)::

    δx = [δp (3), δv (3), δθ (3), δb_a (3), δb_g (3)],
    C_true = Exp(δθ) Ĉ,  p_true = p̂ + δp,  v_true = v̂ + δv,  b_true = b̂ + δb

with continuous dynamics (``f̂ = f̃ − b̂_a``, ``ω̂ = ω̃ − b̂_g``)::

    δṗ = δv
    δv̇ = −[Ĉ f̂ ×] δθ − Ĉ δb_a − Ĉ n_a
    δθ̇ = −Ĉ δb_g − Ĉ n_g
    δḃ_a = n_ba,  δḃ_g = n_bg

discretised as ``F = I + A Δt`` and ``Q = G Q_c Gᵀ Δt`` (isotropic noises make
``Q`` independent of the attitude). After a correction ``δx̂`` is injected into
the nominal state the error is reset to zero and the covariance transformed by
``P ← G P Gᵀ`` with ``G = blockdiag(I₆, J_l(δθ̂) ≈ I + ½[δθ̂ ×], I₆)``
(:func:`reset_jacobian`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

__all__ = [
    "GRAVITY_MPS2", "N_ERR", "Mechanization", "NavState", "dcm_from_euler", "dcm_to_quat", "euler_from_dcm",
    "error_transition", "inject", "quat_convert", "quat_from_rotvec", "quat_multiply", "quat_to_dcm",
    "quat_to_rotvec", "reset_jacobian", "skew", "yaw_jacobian", "propagate", "coast", "coast_transition",
    "InsErrorTransition",
]

#: Standard gravity, m/s².
GRAVITY_MPS2 = 9.80665
#: Size of the error state [δp, δv, δθ, δb_a, δb_g].
N_ERR = 15
P_, V_, TH_, BA_, BG_ = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)


# --------------------------------------------------------------------------- rotations

def skew(v) -> np.ndarray:
    """Cross-product matrix ``[v ×]``, shape ``(..., 3, 3)``."""
    v = np.asarray(v, float)
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def quat_multiply(p, q) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` of scalar-first quaternions, shape ``(..., 4)``."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], -1)


def quat_from_rotvec(rv) -> np.ndarray:
    """``Exp(rv)``: rotation vector (rad, shape ``(..., 3)``) to a scalar-first unit quaternion."""
    rv = np.asarray(rv, float)
    a = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * a
    # sin(a/2)/a, with its Taylor series near 0
    k = np.where(a > 1e-8, np.sin(half) / np.where(a > 1e-8, a, 1.0), 0.5 - a * a / 48.0)
    return np.concatenate([np.cos(half), k * rv], -1)


def quat_to_rotvec(q) -> np.ndarray:
    """``Log(q)``: scalar-first unit quaternion to a rotation vector (rad), shortest rotation."""
    q = np.asarray(q, float)
    q = np.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(s, q[..., :1])
    k = np.where(s > 1e-12, ang / np.where(s > 1e-12, s, 1.0), 2.0 / np.maximum(q[..., :1], 1e-300))
    return k * v


def quat_to_dcm(q) -> np.ndarray:
    """Rotation matrix ``C`` (body → navigation) of a scalar-first quaternion, shape ``(..., 3, 3)``."""
    q = np.asarray(q, float)
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def dcm_to_quat(C) -> np.ndarray:
    """Scalar-first unit quaternion (``w >= 0``) of rotation matrices ``(..., 3, 3)``."""
    C = np.asarray(C, float)
    tr = np.trace(C, axis1=-2, axis2=-1)
    cand = np.stack([1 + tr, 1 + 2 * C[..., 0, 0] - tr, 1 + 2 * C[..., 1, 1] - tr, 1 + 2 * C[..., 2, 2] - tr], -1)
    i = np.argmax(cand, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(cand, i[..., None], -1)[..., 0], 1e-300))
    d = [C[..., 2, 1] - C[..., 1, 2], C[..., 0, 2] - C[..., 2, 0], C[..., 1, 0] - C[..., 0, 1]]
    o = [C[..., 0, 1] + C[..., 1, 0], C[..., 0, 2] + C[..., 2, 0], C[..., 1, 2] + C[..., 2, 1]]
    rows = [np.stack([s, d[0] / s, d[1] / s, d[2] / s], -1),
            np.stack([d[0] / s, s, o[0] / s, o[1] / s], -1),
            np.stack([d[1] / s, o[0] / s, s, o[2] / s], -1),
            np.stack([d[2] / s, o[1] / s, o[2] / s, s], -1)]
    q = 0.5 * np.choose(i[..., None], rows)
    return np.where(q[..., :1] < 0, -q, q)


def quat_convert(q, src: str, dst: str) -> np.ndarray:
    """Reorder quaternion components between ``"wxyz"`` (scalar first, ours) and ``"xyzw"`` (scalar last)."""
    for name, order in (("src", src), ("dst", dst)):
        if order not in ("wxyz", "xyzw"):
            raise ValueError(f"quat_convert: {name} order must be 'wxyz' or 'xyzw', got {order!r}")
    q = np.asarray(q, float)
    if q.shape[-1] != 4:
        raise ValueError(f"quat_convert: quaternions need 4 components, got shape {q.shape}")
    if src == dst:
        return q.copy()
    return np.roll(q, -1 if src == "wxyz" else 1, axis=-1)


def dcm_from_euler(roll_rad, pitch_rad, yaw_rad) -> np.ndarray:
    """``C = Rz(yaw) Ry(pitch) Rx(roll)``, shape ``(..., 3, 3)``."""
    r, p, y = (np.asarray(a, float) for a in (roll_rad, pitch_rad, yaw_rad))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
        np.stack([-sp, cp * sr, cp * cr], -1)], -2)


def euler_from_dcm(C) -> np.ndarray:
    """``[roll, pitch, yaw]`` (rad), shape ``(..., 3)``, inverse of :func:`dcm_from_euler`."""
    C = np.asarray(C, float)
    return np.stack([np.arctan2(C[..., 2, 1], C[..., 2, 2]),
                     -np.arcsin(np.clip(C[..., 2, 0], -1.0, 1.0)),
                     np.arctan2(C[..., 1, 0], C[..., 0, 0])], -1)


def yaw_jacobian(C) -> np.ndarray:
    """``∂yaw/∂δθ`` (shape ``(3,)``) for the navigation-frame attitude error ``C = Exp(δθ) Ĉ``."""
    c = np.asarray(C, float)[:, 0]
    S = _skew3(c)
    return (-c[0] * S[1] + c[1] * S[0]) / (c[0] ** 2 + c[1] ** 2)


# --------------------------------------------------------------------------- mechanization

def _dcm(q) -> np.ndarray:
    """:func:`quat_to_dcm` of one unit quaternion, with scalar arithmetic (the per-step path)."""
    w, x, y, z = q.tolist()
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _skew3(v) -> np.ndarray:
    """:func:`skew` of one 3-vector (the per-step path)."""
    a, b, c = v.tolist()
    return np.array([[0.0, -c, b], [c, 0.0, -a], [-b, a, 0.0]])


def _exp_quat3(a, b, c):
    """``Exp([a, b, c])``: the unit quaternion (w, x, y, z) of one rotation vector (series near zero
    angle). Plain scalar arithmetic: the per-step path calls it, and compiled it is
    :func:`_exp_quat3_nb`."""
    ang = math.sqrt(a * a + b * b + c * c)
    k = math.sin(0.5 * ang) / ang if ang > 1e-8 else 0.5 - ang * ang / 48.0
    return math.cos(0.5 * ang), k * a, k * b, k * c


def _qmul(a, b):
    """Hamilton product ``a ⊗ b`` of two (w, x, y, z) tuples, not normalised. Plain scalar
    arithmetic: the per-step path calls it, and compiled it is :func:`_qmul_nb`."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


def _exp_quat(rv) -> tuple[float, float, float, float]:
    """``Exp(rv)``: the unit quaternion (w, x, y, z) of one rotation vector (:func:`_exp_quat3`)."""
    return _exp_quat3(*rv.tolist())


def _exp_left(rv, q) -> np.ndarray:
    """``Exp(rv) ⊗ q`` for one rotation vector and quaternion, normalised (the per-step path)."""
    out = np.array(_qmul(_exp_quat(rv), q.tolist()))
    return out / math.sqrt(out @ out)


def _yaw(C) -> float:
    return math.atan2(C[1, 0], C[0, 0])


def _rotate(q, rv) -> np.ndarray:
    """``q ⊗ Exp(rv)`` for one quaternion and rotation vector, normalised (the per-step path)."""
    out = np.array(_qmul(q.tolist(), _exp_quat(rv)))
    return out / math.sqrt(out @ out)


@dataclass(frozen=True)
class NavState:
    """Position ``(3,)`` m, velocity ``(3,)`` m/s, attitude quaternion ``[w, x, y, z]`` (body → nav)."""

    pos_m: np.ndarray
    vel_mps: np.ndarray
    quat: np.ndarray

    def __post_init__(self):
        for name, n in (("pos_m", 3), ("vel_mps", 3), ("quat", 4)):
            a = np.array(getattr(self, name), float)
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise ValueError(f"NavState.{name} must be {n} finite numbers, got {a!r}")
            if name == "quat":
                norm = np.linalg.norm(a)
                if abs(norm - 1.0) > 1e-6:
                    raise ValueError(f"NavState.quat must be a unit quaternion [w, x, y, z], |q| = {norm:g}")
                a = a / norm
            a.setflags(write=False)
            object.__setattr__(self, name, a)


@dataclass(frozen=True)
class Mechanization:
    """Strapdown navigation equations in a local level frame (eq. 3).

    Attributes
    ----------
    frame
        ``"ENU"`` or ``"NED"``.
    gravity_mps2
        Magnitude of gravity, m/s² (constant over a room).
    """

    frame: str = "ENU"
    gravity_mps2: float = GRAVITY_MPS2

    def __post_init__(self):
        if self.frame not in ("ENU", "NED"):
            raise ValueError(f"Mechanization.frame must be 'ENU' or 'NED', got {self.frame!r}")
        if not 9.0 < self.gravity_mps2 < 10.5:
            raise ValueError(f"Mechanization.gravity_mps2 = {self.gravity_mps2!r} m/s² is not Earth gravity "
                             "(accelerations in g must be converted by ImuConvention first)")

    @property
    def g_n(self) -> np.ndarray:
        """Gravity vector in the navigation frame, m/s²."""
        return np.array([0.0, 0.0, -self.gravity_mps2 if self.frame == "ENU" else self.gravity_mps2])

    def step(self, pos, vel, quat, f0, f1, w0, w1, dt_s: float):
        """One interval of the trapezoidal mechanization (module docstring).

        ``f0, f1`` (m/s²) and ``w0, w1`` (rad/s): body-frame specific force and
        angular rate at the interval's start and end, shape ``(3,)``. Returns
        ``(pos, vel, quat, C0, C1)`` with ``C0, C1`` the attitude matrices at
        both ends.
        """
        C0 = _dcm(quat)
        q1 = _rotate(quat, 0.5 * (w0 + w1) * dt_s)
        C1 = _dcm(q1)
        v1 = vel + (0.5 * dt_s) * (C0 @ f0 + C1 @ f1) + self.g_n * dt_s
        p1 = pos + (0.5 * dt_s) * (vel + v1)
        return p1, v1, q1, C0, C1

    def integrate(self, t_s, acc_mps2, gyro_radps, x0: NavState):
        """Dead reckoning from ``x0`` at ``t_s[0]`` through all samples.

        Parameters
        ----------
        t_s
            Sample times, shape ``(T,)``, s.
        acc_mps2, gyro_radps
            Body-frame specific force and angular rate, shape ``(T, 3)``, SI.
        x0
            State at ``t_s[0]``.

        Returns
        -------
        pos_m (T, 3), vel_mps (T, 3), quat (T, 4)
        """
        t = np.asarray(t_s, float)
        f = np.asarray(acc_mps2, float)
        w = np.asarray(gyro_radps, float)
        if f.shape != (t.size, 3) or w.shape != (t.size, 3):
            raise ValueError(f"integrate: need acc and gyro of shape ({t.size}, 3), got {f.shape}, {w.shape}")
        pos, vel, quat = (np.empty((t.size, n)) for n in (3, 3, 4))
        pos[0], vel[0], quat[0] = x0.pos_m, x0.vel_mps, x0.quat
        dt = np.diff(t)
        for k in range(t.size - 1):
            pos[k + 1], vel[k + 1], quat[k + 1], _, _ = self.step(pos[k], vel[k], quat[k], f[k], f[k + 1], w[k],
                                                                 w[k + 1], dt[k])
        return pos, vel, quat


# --------------------------------------------------------------------------- error state

def error_dynamics(C, f_b) -> np.ndarray:
    """Continuous error dynamics ``A`` (15 × 15) at attitude ``C`` and bias-corrected specific force ``f_b``."""
    A = np.zeros((N_ERR, N_ERR))
    A[P_, V_] = np.eye(3)
    A[V_, TH_] = -skew(C @ f_b)
    A[V_, BA_] = -C
    A[TH_, BG_] = -C
    return A


def error_transition(C, f_b, dt_s: float) -> np.ndarray:
    """Discrete error transition ``F = I + A Δt + ½ (A Δt)²`` over one IMU interval, shape ``(15, 15)``.

    Written out block by block (``A²`` has only three non-zero blocks), so no 15 × 15
    product is formed per step; equal to the expression above (tested).
    """
    S = _skew3(C @ f_b)
    F = np.eye(N_ERR)
    h = 0.5 * dt_s * dt_s
    F[P_, V_] = dt_s * np.eye(3)
    F[V_, TH_] = -dt_s * S
    F[V_, BA_] = -dt_s * C
    F[TH_, BG_] = -dt_s * C
    F[P_, TH_] = -h * S
    F[P_, BA_] = -h * C
    F[V_, BG_] = h * (S @ C)
    return F


def inject(pos, vel, quat, b_a, b_g, dx):
    """Nominal state after adding the error estimate ``dx (15,)``: returns ``(pos, vel, quat, b_a, b_g)``."""
    return pos + dx[P_], vel + dx[V_], _exp_left(dx[TH_], quat), b_a + dx[BA_], b_g + dx[BG_]


def reset_jacobian(dtheta_rad) -> np.ndarray:
    """``G = ∂δx⁺/∂δx`` of the reset after injecting attitude correction ``δθ̂`` (15 × 15).

    With ``C = Exp(δθ) Ĉ`` and ``Ĉ⁺ = Exp(δθ̂) Ĉ`` the new error is
    ``δθ⁺ = Log(Exp(δθ) Exp(−δθ̂))``; linearised about the estimate
    (``δθ = δθ̂ + ε``) it is ``J_l(δθ̂) ε`` with the left Jacobian of SO(3)

    .. math::  J_l(φ) = I + \\frac{1 - \\cos θ}{θ^2}[φ×] + \\frac{θ - \\sin θ}{θ^3}[φ×]^2,\\quad θ = |φ|,

    whose first-order form is the usual ``I + ½ [δθ̂ ×]``. Every other block is the identity.
    """
    phi = np.asarray(dtheta_rad, float)
    th = math.sqrt(float(phi @ phi))
    S = _skew3(phi)
    if th < 1e-6:
        a, b = 0.5 - th * th / 24.0, 1.0 / 6.0 - th * th / 120.0
    else:
        a, b = (1 - math.cos(th)) / th ** 2, (th - math.sin(th)) / th ** 3
    G = np.eye(N_ERR)
    G[TH_, TH_] += a * S + b * S @ S
    return G


# --------------------------------------------------------------------------- compiled propagation

_exp_quat3_nb = numba.njit(cache=True, nogil=True)(_exp_quat3)
_qmul_nb = numba.njit(cache=True, nogil=True)(_qmul)


@numba.njit(cache=True, nogil=True)
def _unit_into(o, q):
    """Write the 4-tuple ``o`` normalised into ``q`` (compiled; scalar norm)."""
    nq = math.sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2] + o[3] * o[3])
    q[0], q[1], q[2], q[3] = o[0] / nq, o[1] / nq, o[2] / nq, o[3] / nq


@numba.njit(cache=True, nogil=True)
def _exp_left_nb(rv, q):
    """:func:`_exp_left` (``Exp(rv) ⊗ q``, normalised), compiled, in place on ``q``."""
    _unit_into(_qmul_nb(_exp_quat3_nb(rv[0], rv[1], rv[2]), (q[0], q[1], q[2], q[3])), q)


@numba.njit(cache=True, nogil=True)
def _dcm_nb(q, C):
    w, x, y, z = q[0], q[1], q[2], q[3]
    C[0, 0] = 1 - 2 * (y * y + z * z)
    C[0, 1] = 2 * (x * y - w * z)
    C[0, 2] = 2 * (x * z + w * y)
    C[1, 0] = 2 * (x * y + w * z)
    C[1, 1] = 1 - 2 * (x * x + z * z)
    C[1, 2] = 2 * (y * z - w * x)
    C[2, 0] = 2 * (x * z - w * y)
    C[2, 1] = 2 * (y * z + w * x)
    C[2, 2] = 1 - 2 * (x * x + y * y)


@numba.njit(cache=True, nogil=True)
def propagate(pos, vel, quat, b_a, b_g, t, acc, gyro, i0, i1, g_n, qrate, Phi, Qacc):
    """Mechanization and error-covariance pieces from sample ``i0`` to ``i1`` (compiled).

    The same equations as :meth:`Mechanization.step` and :func:`error_transition` (tested
    equal), for the IMU steps between two UWB epochs: the nominal state is advanced in place
    (``pos, vel, quat``) and ``Phi ← F Phi``, ``Qacc ← F Qacc Fᵀ + diag(qrate) Δt`` per step.
    ``acc``/``gyro`` are raw samples; the biases ``b_a``, ``b_g`` are removed here.
    """
    C0 = np.empty((3, 3))
    C1 = np.empty((3, 3))
    F = np.eye(15)
    for i in range(i0 + 1, i1 + 1):
        dt = t[i] - t[i - 1]
        f0 = acc[i - 1] - b_a
        f1 = acc[i] - b_a
        rv = 0.5 * (gyro[i - 1] + gyro[i] - 2.0 * b_g) * dt
        _dcm_nb(quat, C0)
        _unit_into(_qmul_nb((quat[0], quat[1], quat[2], quat[3]), _exp_quat3_nb(rv[0], rv[1], rv[2])), quat)
        _dcm_nb(quat, C1)
        cf0 = C0 @ f0
        v1 = vel + 0.5 * dt * (cf0 + C1 @ f1) + g_n * dt
        pos += 0.5 * dt * (vel + v1)
        vel[:] = v1
        # F = I + AΔt + ½(AΔt)², blocks as in error_transition
        h = 0.5 * dt * dt
        S = np.zeros((3, 3))
        S[0, 1], S[0, 2], S[1, 0] = -cf0[2], cf0[1], cf0[2]
        S[1, 2], S[2, 0], S[2, 1] = -cf0[0], -cf0[1], cf0[0]
        SC = S @ C0
        F[:, :] = 0.0
        for j in range(15):
            F[j, j] = 1.0
        for a in range(3):
            F[a, 3 + a] = dt
            for b in range(3):
                F[3 + a, 6 + b] = -dt * S[a, b]
                F[3 + a, 9 + b] = -dt * C0[a, b]
                F[6 + a, 12 + b] = -dt * C0[a, b]
                F[a, 6 + b] = -h * S[a, b]
                F[a, 9 + b] = -h * C0[a, b]
                F[3 + a, 12 + b] = h * SC[a, b]
        Phi[:, :] = F @ Phi
        Qacc[:, :] = F @ Qacc @ F.T
        for j in range(15):
            Qacc[j, j] += qrate[j] * dt


def coast_transition(dt_s: float, qrate, acc_sigma_mps2: float, rate_sigma_radps: float):
    """Error transition and process noise of one step **without IMU samples** (a coast across an
    IMU gap), ``(F, Q)`` each ``(15, 15)``.

    Nothing measured the motion, so the nominal state keeps its velocity and attitude
    (``p += v Δt``) and the covariance says what that can cost: ``F = I`` but ``δp += δv Δt``;
    ``Q = diag(qrate) Δt`` plus an unknown navigation-frame acceleration of PSD
    ``acc_sigma_mps2² · 1 s`` (white-noise acceleration: ``σ²Δt³/3``, ``σ²Δt²/2``, ``σ²Δt`` in the
    position/velocity blocks) and an unknown rotation of PSD ``rate_sigma_radps² · 1 s`` on
    ``δθ``. Both σ are assumptions of the caller (:class:`~uwbwb.filters.eskf.TightEskf`).
    """
    F = np.eye(N_ERR)
    F[P_, V_] = dt_s * np.eye(3)
    a2 = acc_sigma_mps2 ** 2
    Q = np.diag(np.asarray(qrate, float) * dt_s)
    Q[P_, P_] += a2 * dt_s ** 3 / 3 * np.eye(3)
    Q[P_, V_] += a2 * dt_s ** 2 / 2 * np.eye(3)
    Q[V_, P_] += a2 * dt_s ** 2 / 2 * np.eye(3)
    Q[V_, V_] += a2 * dt_s * np.eye(3)
    Q[TH_, TH_] += rate_sigma_radps ** 2 * dt_s * np.eye(3)
    return F, Q


@dataclass(frozen=True, eq=False)
class InsErrorTransition:
    """The error-state transition model of a strapdown INS: ``(F, Q)`` of one step of the 15-state
    error ``δx = [δp, δv, δθ, δb_a, δb_g]`` (module docstring), for a step measured by the IMU
    (:meth:`step`) and for a coast across an IMU gap (:meth:`coast`). An error-state filter
    predicts with them, ``δx⁻ = F δx``, ``P⁻ = F P Fᵀ + Q`` (:func:`~uwbwb.filters.kalman.predict`),
    after moving its nominal state with :class:`Mechanization`. Its matrices depend on the nominal
    state, so it gives them per step (``step(C, f_b, dt)``) rather than as the ``F(dt)``, ``Q(dt)`` of
    a kinematic model: it is not a transition model for :class:`~uwbwb.filters.ekf.Ekf`. Compared
    by identity (it holds an array).

    Attributes
    ----------
    qrate_per_s
        Diagonal of ``G Q_c Gᵀ`` per second, ``(15,)``: the white-noise PSDs of the accelerometer
        ((m/s²)²·s on δv, per second of step), the gyro (rad²/s on δθ) and the bias random walks
        (on δb_a, δb_g); zero on δp. Isotropic noises make it independent of the attitude.
    coast_acc_sigma_mps2, coast_rate_sigma_radps
        The unknown acceleration and rotation rate assumed during a coast, as white noise of PSD
        ``σ² · 1 s`` (:func:`coast_transition`).
    """

    qrate_per_s: np.ndarray
    coast_acc_sigma_mps2: float = 1.0
    coast_rate_sigma_radps: float = 0.2

    n_x = N_ERR

    def __post_init__(self):
        q = np.array(self.qrate_per_s, float)
        if q.shape != (N_ERR,) or not np.all(np.isfinite(q)) or np.any(q < 0):
            raise ValueError(f"InsErrorTransition.qrate_per_s must be {N_ERR} finite non-negative numbers, "
                             f"got {q.shape} values" + (f", minimum {np.nanmin(q):g}" if q.size else ""))
        for name in ("coast_acc_sigma_mps2", "coast_rate_sigma_radps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                    or not (math.isfinite(v) and v >= 0):
                raise ValueError(f"InsErrorTransition.{name} must be a finite number >= 0, got {v!r}")
        q.setflags(write=False)
        object.__setattr__(self, "qrate_per_s", q)

    def step(self, C, f_b, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """``(F, Q)`` of one IMU interval from the nominal attitude ``C`` (body → navigation, at
        the interval's start) and bias-corrected specific force ``f_b`` (m/s², there):
        ``F = I + A Δt + ½ (A Δt)²`` (:func:`error_transition`), ``Q = diag(qrate) Δt``."""
        return error_transition(C, f_b, dt_s), np.diag(self.qrate_per_s * dt_s)

    def coast(self, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """``(F, Q)`` of one step without IMU samples (:func:`coast_transition` with this model's
        assumptions)."""
        return coast_transition(dt_s, self.qrate_per_s, self.coast_acc_sigma_mps2, self.coast_rate_sigma_radps)


@numba.njit(cache=True, nogil=True)
def coast(pos, vel, t, i0, i1, qrate, acc_var, rate_var, Phi, Qacc):
    """:func:`coast_transition` over the steps ``i0 → i1`` (compiled): ``pos += vel Δt`` in place,
    ``Phi ← F Phi``, ``Qacc ← F Qacc Fᵀ + Q`` per step (``acc_var``, ``rate_var``: the σ² of the
    assumed acceleration and rotation PSDs)."""
    F = np.eye(15)
    for i in range(i0 + 1, i1 + 1):
        dt = t[i] - t[i - 1]
        for a in range(3):
            pos[a] += vel[a] * dt
            F[a, 3 + a] = dt
        Phi[:, :] = F @ Phi
        Qacc[:, :] = F @ Qacc @ F.T
        for j in range(15):
            Qacc[j, j] += qrate[j] * dt
        for a in range(3):
            Qacc[a, a] += acc_var * dt ** 3 / 3
            Qacc[a, 3 + a] += acc_var * dt ** 2 / 2
            Qacc[3 + a, a] += acc_var * dt ** 2 / 2
            Qacc[3 + a, 3 + a] += acc_var * dt
            Qacc[6 + a, 6 + a] += rate_var * dt
