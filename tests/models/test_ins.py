"""Strapdown mechanization and its error model, tested the way INS libraries test theirs:
analytic trajectory -> ideal IMU -> integrated back; stationary run; linearised error
propagation against the nonlinear integrator; Jacobians against finite differences; reset."""

import numpy as np
import pytest

from uwbwb.models import ins
from uwbwb.models.ins import (Mechanization, NavState, dcm_from_euler, dcm_to_quat, euler_from_dcm,
                              quat_convert, quat_from_rotvec, quat_multiply, quat_to_dcm, quat_to_rotvec)


# ----------------------------------------------------------------- an analytic 3-D trajectory

def analytic(t):
    """Position, velocity, acceleration (ENU) and Euler angles with rates, closed form."""
    w = 2 * np.pi / 20.0
    pos = np.stack([3 * np.cos(w * t), 2 * np.sin(w * t), 1 + 0.3 * np.sin(2 * w * t)], -1)
    vel = np.stack([-3 * w * np.sin(w * t), 2 * w * np.cos(w * t), 0.6 * w * np.cos(2 * w * t)], -1)
    acc = np.stack([-3 * w * w * np.cos(w * t), -2 * w * w * np.sin(w * t), -1.2 * w * w * np.sin(2 * w * t)], -1)
    eul = np.stack([0.2 * np.sin(0.7 * t), 0.15 * np.cos(0.5 * t), 0.8 * t + 0.3 * np.sin(0.3 * t)], -1)
    deul = np.stack([0.14 * np.cos(0.7 * t), -0.075 * np.sin(0.5 * t), 0.8 + 0.09 * np.cos(0.3 * t)], -1)
    return pos, vel, acc, eul, deul


def ideal_imu(t, g=ins.GRAVITY_MPS2):
    pos, vel, acc, eul, deul = analytic(t)
    C = dcm_from_euler(eul[:, 0], eul[:, 1], eul[:, 2])
    r, p = eul[:, 0], eul[:, 1]
    # body rates from Euler-angle rates for C = Rz Ry Rx
    wb = np.stack([deul[:, 0] - np.sin(p) * deul[:, 2],
                   np.cos(r) * deul[:, 1] + np.sin(r) * np.cos(p) * deul[:, 2],
                   -np.sin(r) * deul[:, 1] + np.cos(r) * np.cos(p) * deul[:, 2]], -1)
    f_b = np.einsum("tji,tj->ti", C, acc + [0, 0, g])
    return pos, vel, C, f_b, wb


def _run(rate_hz, duration_s):
    t = np.arange(0, duration_s + 1e-9, 1 / rate_hz)
    pos, vel, C, f_b, wb = ideal_imu(t)
    x0 = NavState(pos[0], vel[0], dcm_to_quat(C[0]))
    p, v, q = Mechanization().integrate(t, f_b, wb, x0)
    att = np.linalg.norm(quat_to_rotvec(quat_multiply(q, dcm_to_quat(np.swapaxes(C, 1, 2)))), axis=1)
    return np.abs(p - pos).max(), np.abs(v - vel).max(), att.max()


def test_body_rates_from_euler_rates_match_the_attitude_derivative():
    t = np.array([1.3, 7.1])
    _, _, C, _, wb = ideal_imu(t)
    h = 1e-6
    Cp, Cm = ideal_imu(t + h)[2], ideal_imu(t - h)[2]
    Omega = np.einsum("tji,tjk->tik", C, (Cp - Cm) / (2 * h))   # Cᵀ Ċ = [ω ×]
    np.testing.assert_allclose(Omega, ins.skew(wb), atol=1e-8)


def test_analytic_trajectory_is_integrated_back_over_a_long_run():
    # 120 s, ~110 m of travel, 24 000 steps: the residual is the scheme's O(Δt²) truncation
    # (next test), 0.03 % of the distance travelled
    dp, dv, da = _run(200.0, 120.0)
    assert dp < 0.04 and dv < 1e-3 and da < 1e-5, (dp, dv, da)


def test_mechanization_error_is_second_order_in_the_step():
    e1 = _run(50.0, 60.0)
    e2 = _run(100.0, 60.0)
    ratios = np.array(e1) / np.array(e2)
    assert np.all((ratios > 3.0) & (ratios < 5.5)), ratios


def test_stationary_ideal_imu_does_not_drift():
    t = np.arange(0, 300.0, 0.01)
    C = dcm_from_euler(0.1, -0.05, 1.0)
    f_b = np.tile(C.T @ [0, 0, ins.GRAVITY_MPS2], (t.size, 1))
    x0 = NavState([1.0, 2.0, 0.5], np.zeros(3), dcm_to_quat(C))
    p, v, q = Mechanization().integrate(t, f_b, np.zeros((t.size, 3)), x0)
    assert np.abs(p - x0.pos_m).max() < 1e-6 and np.abs(v).max() < 1e-8
    np.testing.assert_allclose(quat_to_dcm(q[-1]), C, atol=1e-12)


def test_ned_frame_has_gravity_down_positive_and_rejects_other_frames():
    assert Mechanization("NED").g_n[2] > 0 and Mechanization("ENU").g_n[2] < 0
    with pytest.raises(ValueError, match="ENU"):
        Mechanization("ECEF")
    with pytest.raises(ValueError, match="in g"):
        Mechanization(gravity_mps2=1.0)


def test_quaternion_order_and_rotation_helpers(rng):
    rv = rng.normal(0, 1, (50, 3))
    q = quat_from_rotvec(rv)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    C = quat_to_dcm(q)
    np.testing.assert_allclose(np.einsum("tij,tkj->tik", C, C), np.broadcast_to(np.eye(3), C.shape), atol=1e-12)
    np.testing.assert_allclose(quat_to_dcm(dcm_to_quat(C)), C, atol=1e-12)
    small = rv / np.linalg.norm(rv, axis=1, keepdims=True) * np.minimum(np.linalg.norm(rv, axis=1), 3.0)[:, None]
    np.testing.assert_allclose(quat_to_rotvec(quat_from_rotvec(small)), small, atol=1e-9)
    # scalar-last round trip, and a 90° yaw reads the same either way
    np.testing.assert_allclose(quat_convert(quat_convert(q, "wxyz", "xyzw"), "xyzw", "wxyz"), q)
    yaw90 = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    np.testing.assert_allclose(quat_convert(yaw90, "wxyz", "xyzw"), [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    np.testing.assert_allclose(quat_to_dcm(yaw90) @ [1, 0, 0], [0, 1, 0], atol=1e-12)  # east -> north
    with pytest.raises(ValueError, match="wxyz"):
        quat_convert(q, "xyz", "wxyz")
    # composition: C(p ⊗ q) = C(p) C(q)
    np.testing.assert_allclose(quat_to_dcm(quat_multiply(q[:-1], q[1:])), C[:-1] @ C[1:], atol=1e-12)
    eul = euler_from_dcm(dcm_from_euler(0.3, -0.2, 2.5))
    np.testing.assert_allclose(eul, [0.3, -0.2, 2.5])


def test_navstate_rejects_non_unit_quaternion():
    with pytest.raises(ValueError, match="unit quaternion"):
        NavState(np.zeros(3), np.zeros(3), [1.0, 0.2, 0.0, 0.0])


def _nominal_after(x, f, w, dt, n):
    p, v, q = x
    mech = Mechanization()
    for _ in range(n):
        p, v, q, _, _ = mech.step(p, v, q, f, f, w, w, dt)
    return p, v, q


def test_linearised_error_propagation_matches_the_nonlinear_integrator(rng):
    """Perturb the true state and biases; compare the true error after 1 s with F δx."""
    dt, n = 0.01, 100
    q0 = dcm_to_quat(dcm_from_euler(0.1, -0.2, 0.7))
    x_true = (np.array([1.0, 2.0, 0.3]), np.array([0.3, -0.1, 0.0]), q0)
    f_true, w_true = np.array([0.4, -0.2, 9.9]), np.array([0.05, -0.02, 0.3])
    dx0 = np.concatenate([[0.02, -0.01, 0.01], [0.01, 0.02, -0.01], [2e-3, -1e-3, 3e-3],
                          [0.01, -0.02, 0.015], [2e-4, 1e-4, -3e-4]])
    # estimate = truth minus the error; the estimate's bias is wrong by δb
    q_est = quat_multiply(quat_from_rotvec(-dx0[6:9]), q0)
    x_est = (x_true[0] - dx0[:3], x_true[1] - dx0[3:6], q_est)
    ba_err, bg_err = dx0[9:12], dx0[12:15]
    # the IMU measures f + b; the estimate removes b̂ = b − δb, so it sees f + δb
    pt, vt, qt = _nominal_after(x_true, f_true, w_true, dt, n)
    pe, ve, qe = _nominal_after(x_est, f_true + ba_err, w_true + bg_err, dt, n)
    err = np.concatenate([pt - pe, vt - ve, quat_to_rotvec(quat_multiply(qt, np.array([1, -1, -1, -1]) * qe))])
    F = np.eye(15)
    p, v, q = x_est
    for _ in range(n):
        C = quat_to_dcm(q)
        F = ins.error_transition(C, f_true + ba_err, dt) @ F
        p, v, q, _, _ = Mechanization().step(p, v, q, f_true + ba_err, f_true + ba_err, w_true + bg_err,
                                             w_true + bg_err, dt)
    pred = (F @ dx0)[:9]
    scale = np.abs(err).max()
    np.testing.assert_allclose(pred, err, atol=0.02 * scale)


def test_error_dynamics_jacobian_against_finite_differences(rng):
    """A from differentiating the true-state derivative with respect to each error component."""
    C_hat = dcm_from_euler(0.2, -0.1, 1.1)
    f_hat = np.array([0.3, -0.5, 9.7])
    w_hat = np.array([0.1, 0.2, -0.3])

    def derivatives(dx):
        # true state's velocity and attitude-error rates implied by error dx (nominal held fixed)
        C = quat_to_dcm(quat_from_rotvec(dx[6:9])) @ C_hat
        f = f_hat - dx[9:12]
        w = w_hat - dx[12:15]
        vdot_true = C @ f
        # δθ̇ from Ċ = C [ω×] and nominal Ĉ̇ = Ĉ[ω̂×]: [δθ̇×] = Ċ Cᵀ − Exp(δθ) Ĉ̇ Ĉᵀ Exp(δθ)ᵀ
        Cdot = C @ ins.skew(w)
        E = quat_to_dcm(quat_from_rotvec(dx[6:9]))
        M = Cdot @ C.T - E @ (C_hat @ ins.skew(w_hat) @ C_hat.T) @ E.T
        thdot = np.array([M[2, 1], M[0, 2], M[1, 0]])
        return np.concatenate([dx[3:6], vdot_true - C_hat @ f_hat, thdot])

    A = ins.error_dynamics(C_hat, f_hat)
    eps = 1e-7
    J = np.column_stack([(derivatives(eps * e) - derivatives(-eps * e)) / (2 * eps) for e in np.eye(15)])
    np.testing.assert_allclose(A[:9], J, atol=1e-6)


def test_yaw_jacobian_against_finite_differences():
    C = dcm_from_euler(0.3, -0.2, 2.0)
    eps = 1e-7
    J = [(euler_from_dcm(quat_to_dcm(quat_from_rotvec(eps * e)) @ C)[2]
          - euler_from_dcm(quat_to_dcm(quat_from_rotvec(-eps * e)) @ C)[2]) / (2 * eps) for e in np.eye(3)]
    np.testing.assert_allclose(ins.yaw_jacobian(C), J, atol=1e-7)


def test_reset_transforms_the_covariance_by_G_P_Gt(rng):
    """Monte Carlo: the exact post-reset attitude errors have covariance G P Gᵀ, not P."""
    dth_hat = np.array([0.3, -0.2, 0.4])
    P = np.diag([0.02, 0.01, 0.015]) ** 2
    dth = rng.multivariate_normal(dth_hat, P, size=200_000)
    after = quat_to_rotvec(quat_multiply(quat_from_rotvec(dth), quat_from_rotvec(-dth_hat)))
    emp = np.cov(after.T)
    G = ins.reset_jacobian(dth_hat)[6:9, 6:9]
    GPG = G @ P @ G.T
    assert np.abs(emp - GPG).max() < 0.2 * np.abs(emp - P).max()
    np.testing.assert_allclose(emp, GPG, rtol=0.02, atol=2e-6)
    G1 = np.eye(3) + 0.5 * ins.skew(dth_hat)             # the first-order form
    assert np.abs(emp - G1 @ P @ G1.T).max() < np.abs(emp - P).max()
    np.testing.assert_allclose(after.mean(0), 0.0, atol=1e-3)


def test_inject_then_reset_keeps_zero_mean_error():
    p, v, q = np.zeros(3), np.zeros(3), dcm_to_quat(dcm_from_euler(0, 0, 0.5))
    dx = np.arange(15) * 0.01
    p1, v1, q1, ba, bg = ins.inject(p, v, q, np.zeros(3), np.zeros(3), dx)
    np.testing.assert_allclose(np.concatenate([p1, v1, ba, bg]), np.concatenate([dx[:6], dx[9:]]))
    np.testing.assert_allclose(quat_to_rotvec(quat_multiply(q1, q * [1, -1, -1, -1])), dx[6:9], atol=1e-12)


def test_block_transition_equals_the_matrix_series(rng):
    C = dcm_from_euler(0.2, -0.3, 1.0)
    f = np.array([0.5, -0.2, 9.6])
    dt = 0.05
    Adt = ins.error_dynamics(C, f) * dt
    np.testing.assert_allclose(ins.error_transition(C, f, dt), np.eye(15) + Adt + 0.5 * Adt @ Adt, atol=1e-14)


def test_error_transition_model_gives_the_step_and_coast_matrices(rng):
    """:class:`InsErrorTransition` is :func:`error_transition` with ``diag(qrate) Δt`` for an IMU
    step and :func:`coast_transition` for a coast, to the bit; bad settings are refused."""
    qrate = np.abs(rng.standard_normal(ins.N_ERR)) * 1e-4
    qrate[:3] = 0.0
    model = ins.InsErrorTransition(qrate, coast_acc_sigma_mps2=0.7, coast_rate_sigma_radps=0.1)
    C = quat_to_dcm(quat_from_rotvec(rng.standard_normal(3)))
    f_b = np.array([0.3, -0.2, 9.8])
    F, Q = model.step(C, f_b, 0.01)
    assert F.tobytes() == ins.error_transition(C, f_b, 0.01).tobytes()
    assert Q.tobytes() == np.diag(qrate * 0.01).tobytes()
    Fc, Qc = model.coast(0.25)
    want_F, want_Q = ins.coast_transition(0.25, qrate, 0.7, 0.1)
    assert Fc.tobytes() == want_F.tobytes() and Qc.tobytes() == want_Q.tobytes()
    assert model.n_x == ins.N_ERR
    with pytest.raises(ValueError, match="qrate_per_s"):
        ins.InsErrorTransition(np.ones(9))
    with pytest.raises(ValueError, match="coast_acc_sigma_mps2"):
        ins.InsErrorTransition(qrate, coast_acc_sigma_mps2=-1.0)
