"""Compiled kernels of the tight and the loose filter. Declared twins: :func:`_tight_loop` must equal
:meth:`~.tight.TightEskf.run_reference` and :func:`_loose_loop` :meth:`~.loose.LooseFilter.run_reference`
to rounding; :func:`_reset_block`, :func:`_skew_into`
equal their :mod:`uwbwb.models.ins` definitions (tests/filters/test_eskf.py). The attitude
injection :func:`~uwbwb.models.ins._exp_left_nb` is not a twin: it is compiled from the scalar
quaternion code the per-step path runs."""

from __future__ import annotations

import math

import numba
import numpy as np

from ...models.ins import _dcm_nb, _exp_left_nb, coast, propagate
from ..ekf.kernels import _predict, _update
from ..kalman import _sequential
from .common import LOST_BUILD_S


# ====================================================================== tight, compiled
@numba.njit(cache=True, nogil=True)
def _skew_into(v, S):
    S[0, 0], S[0, 1], S[0, 2] = 0.0, -v[2], v[1]
    S[1, 0], S[1, 1], S[1, 2] = v[2], 0.0, -v[0]
    S[2, 0], S[2, 1], S[2, 2] = -v[1], v[0], 0.0


@numba.njit(cache=True, nogil=True)
def _reset_block(phi):
    """The attitude block of :func:`~uwbwb.models.ins.reset_jacobian`, ``(3, 3)``."""
    th = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    S = np.empty((3, 3))
    _skew_into(phi, S)
    if th < 1e-6:
        a, b = 0.5 - th * th / 24.0, 1.0 / 6.0 - th * th / 120.0
    else:
        a, b = (1 - math.cos(th)) / th ** 2, (th - math.sin(th)) / th ** 3
    return np.eye(3) + (a * S + b * (S @ S))


@numba.njit(cache=True, nogil=True)
def _reset_covariance(P, Gt):
    """``P ← G P Gᵀ`` in place, with ``G`` the identity but for the attitude block ``Gt``."""
    rows = np.empty((3, 15))
    for a in range(3):
        for b in range(15):
            rows[a, b] = Gt[a, 0] * P[6, b] + Gt[a, 1] * P[7, b] + Gt[a, 2] * P[8, b]
    P[6:9, :] = rows
    cols = np.empty((15, 3))
    for a in range(15):
        for b in range(3):
            cols[a, b] = P[a, 6] * Gt[b, 0] + P[a, 7] * Gt[b, 1] + P[a, 8] * Gt[b, 2]
    P[:, 6:9] = cols


#: Names of the entries of :func:`_tight_loop`'s ``scalars`` (float64) and ``ints`` (int64) arrays.
SCALARS = ("bias_m", "r_scale", "gate1", "gate_yaw_var", "heading_known_var", "iterate_sigma_m", "iter_tol",
           "coast_acc_var", "coast_rate_var", "sig_yaw", "height_m", "sig_height")
INTS = ("kind", "correlated", "max_gated", "max_iter", "use_height", "feedback", "st_updated", "st_gated",
        "st_predicted")


@numba.njit(cache=True, nogil=True)
def _tight_loop(timeline, epochs, scalars, ints, vectors, nav, P, outputs):
    """:meth:`TightEskf.run` compiled: the same steps as its reference loop, epoch after epoch.
    Its declared twin is :meth:`~.tight.TightEskf.run_reference` (equal to rounding, tested).

    Arguments, bundled: ``timeline = (t, acc, gyro, tl_idx, ep_of, coasting)`` (the merged time
    line, the timeline index and epoch of each epoch in order, the IMU-gap steps); ``epochs =
    (rows, refs, fix_tag, yaw_meas)`` (per UWB epoch); ``scalars`` and ``ints``: the settings named
    by :data:`SCALARS` and :data:`INTS`; ``vectors = (anchors, var_m, p_lost, lever, qrate, g_n)``;
    ``nav = (p, v, q, ba, bg)`` and ``P`` (worked on in place); ``outputs = (pos_o, vel_o, quat_o,
    ba_o, bg_o, P_o, cov_o, nis_o, dof_o, gated_o, status_o)``.

    Per epoch (timeline index ``tl_idx[e]``, epoch ``ep_of[e]``): :func:`propagate` from the last
    epoch and one predict ``dx ← Φ dx``, ``P ← Φ P Φᵀ + Q`` (symmetrised); the epoch's TDoAs
    (``kind`` 1, :meth:`TdoaModel.epoch` with the lever-arm Jacobian) or ranges (``kind`` 2,
    :meth:`RangeUpdate.linearise`, both :func:`_uwb_rows`), the lost-lock inflation ``P += diag(p_lost)``,
    the χ² gate, the heading and height pseudo-measurements; :func:`~uwbwb.filters.kalman._sequential`,
    iterated (relinearised UWB rows) while the prior tag σ exceeds ``iterate_sigma_m``; injection and reset. ``p, v, q, ba, bg, P`` are
    worked on in place; outputs go to row ``ep_of[e]`` of the ``*_o`` arrays. Returns 0, or the
    error code of ``_sequential``. Tested equal to the reference loop and to the model functions.
    """
    t, acc, gyro, tl_idx, ep_of, coasting = timeline
    rows, refs, fix_tag, yaw_meas = epochs
    anchors, var_m, p_lost, lever, qrate, g_n = vectors
    p, v, q, ba, bg = nav
    pos_o, vel_o, quat_o, ba_o, bg_o, P_o, cov_o, nis_o, dof_o, gated_o, status_o = outputs
    bias_m, r_scale, gate1, gate_yaw_var = scalars[0], scalars[1], scalars[2], scalars[3]
    heading_known_var, iterate_sigma_m, iter_tol, coast_acc_var = scalars[4], scalars[5], scalars[6], scalars[7]
    coast_rate_var, sig_yaw, height_m, sig_height = scalars[8], scalars[9], scalars[10], scalars[11]
    kind, correlated, max_gated, max_iter = ints[0], ints[1] != 0, ints[2], ints[3]
    use_height, feedback, st_updated, st_gated, st_predicted = ints[4] != 0, ints[5] != 0, ints[6], ints[7], ints[8]
    n_a = anchors.shape[0]
    m_max = n_a + 2
    dx = np.zeros(15)
    C = np.empty((3, 3))
    Sl = np.empty((3, 3))
    Phi = np.empty((15, 15))
    Qacc = np.empty((15, 15))
    z = np.empty(m_max)
    h = np.empty(m_max)
    H = np.zeros((m_max, 15))
    Rd = np.empty(m_max)
    keep = np.empty(m_max, np.bool_)
    hp = np.empty(3)
    z2 = np.empty(m_max)
    h2 = np.empty(m_max)
    H2 = np.zeros((m_max, 15))
    Rd2 = np.empty(m_max)
    gated_run, clean_run = 0, 0
    engaged = P[8, 8] <= heading_known_var
    last = 0
    for e in range(tl_idx.size):
        i, k = tl_idx[e], ep_of[e]
        if i > last:
            Phi[:, :] = 0.0
            Qacc[:, :] = 0.0
            for j in range(15):
                Phi[j, j] = 1.0
            j0 = last                           # runs of IMU steps and of coast steps (IMU gaps)
            while j0 < i:
                j1 = j0 + 1
                while j1 < i and coasting[j1 + 1] == coasting[j0 + 1]:
                    j1 += 1
                if coasting[j0 + 1]:
                    coast(p, v, t, j0, j1, qrate, coast_acc_var, coast_rate_var, Phi, Qacc)
                else:
                    propagate(p, v, q, ba, bg, t, acc, gyro, j0, j1, g_n, qrate, Phi, Qacc)
                j0 = j1
            dx = Phi @ dx
            P = Phi @ P @ Phi.T + Qacc
            P = 0.5 * (P + P.T)
        last = i
        _dcm_nb(q, C)
        cl = C @ lever
        _skew_into(cl, Sl)                      # J_tag = [I, 0, −[C l ×], 0, 0]
        tag = p + cl
        Jt = np.zeros((3, 15))
        for a in range(3):
            Jt[a, a] = 1.0
            for b in range(3):
                Jt[a, 6 + b] = -Sl[a, b]
        far = math.sqrt(np.trace(Jt @ P @ Jt.T)) > iterate_sigma_m   # the propagated prior, before any lost-lock inflation
        # ---- UWB rows (z, h, H) and their noise (diagonal Rd; TDoA adds the reference's variance)
        n_gated, uwb_used = 0, 0
        row = rows[k]
        m, lin, var_ref = _uwb_rows(kind, row, refs[k], anchors, var_m, bias_m, tag, Sl, z, h, H, Rd, hp)
        m_lin = m
        off = 0.0                               # R = (diag(Rd) + var_ref 1 1ᵀ) r_scale, or its diagonal
        if lin:
            if gated_run >= max_gated:          # lock lost: admit it, then re-acquire ungated
                ms = 0.0
                for a in range(m):
                    ya = z[a] - h[a] - H[a] @ dx
                    ms += ya * ya
                ms /= m
                for a in range(15):
                    if a < 3:
                        P[a, a] += p_lost[a] + ms
                    elif a < 6:
                        P[a, a] += p_lost[a] + ms / LOST_BUILD_S ** 2
                    else:
                        P[a, a] += p_lost[a]
            for a in range(m):
                Rd[a] = (Rd[a] + var_ref) * r_scale
            if correlated:
                off = var_ref * r_scale
            n_fail = 0
            for a in range(m):
                Hdx = H[a] @ dx
                y = z[a] - h[a] - Hdx
                s = H[a] @ P @ H[a] + Rd[a]
                test = y * y / s <= gate1
                keep[a] = test if (engaged and gated_run < max_gated) else True
                if not test:
                    n_fail += 1
                h[a] += Hdx
            if not engaged:                     # start-up: is the heading resolved?
                clean_run = clean_run + 1 if 2 * n_fail < m else 0
                engaged = clean_run >= max_gated and P[8, 8] <= gate_yaw_var
            w = 0
            for a in range(m):                  # the kept rows first, in order
                if keep[a]:
                    z[w], h[w], Rd[w] = z[a], h[a], Rd[a]
                    H[w] = H[a]
                    w += 1
            n_gated = m - w
            uwb_used = w
            m = w
            lost = n_gated >= uwb_used and feedback
            gated_run = gated_run + 1 if (n_gated > 0 and lost) else 0
        n_uwb = m
        # ---- heading and height pseudo-measurements
        if np.isfinite(yaw_meas[k]) and sig_yaw > 0:
            c0, c1, c2 = C[0, 0], C[1, 0], C[2, 0]
            den = c0 ** 2 + c1 ** 2
            H[m] = 0.0
            H[m, 6], H[m, 7], H[m, 8] = (-c0 * c2 + c1 * 0.0) / den, (-c0 * 0.0 + c1 * -c2) / den, \
                (-c0 * -c0 + c1 * c1) / den
            a = yaw_meas[k] - math.atan2(C[1, 0], C[0, 0])
            z[m] = (a + np.pi) % (2 * np.pi) - np.pi
            h[m] = H[m] @ dx
            Rd[m] = sig_yaw ** 2
            m += 1
        if use_height:
            H[m] = 0.0
            H[m, 2] = 1.0
            for b in range(3):
                H[m, 6 + b] = -Sl[2, b]
            z[m] = height_m
            h[m] = tag[2] + H[m] @ dx
            Rd[m] = sig_height ** 2
            m += 1
        nis, dof = np.nan, 0
        if m:
            R = np.zeros((m, m))
            for a in range(m):
                R[a, a] = Rd[a]
                if a < n_uwb:
                    for b in range(n_uwb):
                        if b != a:
                            R[a, b] = off
            y = z[:m] - h[:m]
            nis_parts = np.empty(m)
            iterate = uwb_used > 0 and far
            dx0, P0 = dx.copy(), P.copy()
            code = _sequential(dx, P, y, H[:m].copy(), R, nis_parts)
            if code:
                return code
            if iterate:                         # iterated update (IEKF): relinearise the UWB rows
                nis_it = np.empty(m)
                for it in range(max_iter - 1):
                    d = dx.copy()
                    if it == 0 and np.isfinite(fix_tag[k, 0]):   # start at the snapshot fix
                        d[:] = dx0
                        for a in range(3):
                            d[a] = fix_tag[k, a] - tag[a] + Sl[a, 0] * dx0[6] + Sl[a, 1] * dx0[7] + Sl[a, 2] * dx0[8]
                    tag_i = tag + d[0:3] - Sl @ d[6:9]
                    _uwb_rows(kind, row, refs[k], anchors, var_m, bias_m, tag_i, Sl, z2, h2, H2, Rd2, hp)
                    w = 0
                    for a in range(m_lin):
                        if keep[a]:
                            h[w] = h2[a] + H2[a] @ (dx0 - d)
                            H[w] = H2[a]
                            w += 1
                    y = z[:m] - h[:m]
                    dx[:] = dx0
                    P[:, :] = P0
                    code = _sequential(dx, P, y, H[:m].copy(), R, nis_it)
                    if code:
                        return code
                    step = 0.0
                    for a in range(3):
                        step = max(step, abs(dx[a] - d[a]))
                    if step < iter_tol:
                        break
            P = 0.5 * (P + P.T)
            if uwb_used:
                nis = nis_parts[:uwb_used].sum()
            dof = uwb_used
        # ---- closed loop: inject and reset; open loop: report nominal ⊕ δx
        qo = q.copy()
        if feedback:
            p += dx[0:3]
            v += dx[3:6]
            _exp_left_nb(dx[6:9], q)
            ba += dx[9:12]
            bg += dx[12:15]
            _reset_covariance(P, _reset_block(dx[6:9]))
            dx[:] = 0.0
            qo[:] = q
        else:
            _exp_left_nb(dx[6:9], qo)
        _dcm_nb(qo, C)
        clo = C @ lever
        _skew_into(clo, Sl)
        for a in range(3):
            pos_o[k, a] = p[a] + dx[a] + clo[a]
            vel_o[k, a] = v[a] + dx[3 + a]
            ba_o[k, a] = ba[a] + dx[9 + a]
            bg_o[k, a] = bg[a] + dx[12 + a]
        quat_o[k] = qo
        P_o[k] = P
        Jo = np.zeros((3, 15))
        for a in range(3):
            Jo[a, a] = 1.0
            for b in range(3):
                Jo[a, 6 + b] = -Sl[a, b]
        cov_o[k] = Jo @ P @ Jo.T
        nis_o[k], dof_o[k], gated_o[k] = nis, dof, n_gated
        status_o[k] = st_updated if uwb_used else (st_gated if n_gated else st_predicted)
    return 0


@numba.njit(cache=True, nogil=True)
def _uwb_rows(kind, row, ref, anchors, var_m, bias_m, tag, Sl, z, h, H, Rd, hp):
    """One epoch's UWB rows at tag position ``tag``: ``z``, ``h``, ``H`` (with the lever-arm
    columns from ``Sl = [C l ×]``) and the per-row variance ``Rd`` (without the reference's);
    TDoAs (``kind`` 1, :meth:`TdoaModel.epoch`) or ranges (``kind`` 2, :meth:`RangeUpdate.linearise`).
    Returns ``(m, linearised, var_ref)``."""
    n_a = anchors.shape[0]
    m, lin, var_ref = 0, False, 0.0
    if kind == 1:
        n_fin = 0
        for j in range(n_a):
            if np.isfinite(row[j]):
                n_fin += 1
        if ref >= 0 and n_fin >= 2:
            lin = True
            dr = tag - anchors[ref]
            rr = math.sqrt(dr[0] * dr[0] + dr[1] * dr[1] + dr[2] * dr[2])
            ur = dr / max(rr, 1e-12)
            var_ref = var_m[ref]
            for j in range(n_a):
                if j == ref or not np.isfinite(row[j]):
                    continue
                d = tag - anchors[j]
                r = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                u = d / max(r, 1e-12)
                z[m] = row[j] - row[ref]
                h[m] = r - rr
                for a in range(3):
                    hp[a] = u[a] - ur[a]
                Rd[m] = var_m[j]
                m += 1
                _fill_row(H, m - 1, hp, Sl)
    elif kind == 2:
        for j in range(n_a):
            if not np.isfinite(row[j]):
                continue
            lin = True
            d = tag - anchors[j]
            r = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            rm = max(r, 1e-9)
            for a in range(3):
                hp[a] = d[a] / rm
            z[m] = row[j] - bias_m
            h[m] = r
            Rd[m] = var_m[j]
            m += 1
            _fill_row(H, m - 1, hp, Sl)
    return m, lin, var_ref


@numba.njit(cache=True, nogil=True)
def _fill_row(H, a, hp, Sl):
    """Row ``a`` of ``H = ∂h/∂p · J_tag``: ``hp`` on δp and ``−hp [C l ×]`` on δθ."""
    H[a] = 0.0
    for b in range(3):
        H[a, b] = hp[b]
        H[a, 6 + b] = -(hp[0] * Sl[0, b] + hp[1] * Sl[1, b] + hp[2] * Sl[2, b])


# ====================================================================== loose, compiled
#: Names of the entries of :func:`_loose_loop`'s ``scalars`` (float64) and ``ints`` (int64) arrays.
LOOSE_SCALARS = ("attitude_tau_s", "q_scale", "height_m", "coast_acc_var", "gate_pos", "gate_full")
LOOSE_INTS = ("dim", "vel_window", "gated", "max_gated", "use_height", "feedback", "st_updated", "st_gated",
              "st_predicted")


@numba.njit(cache=True, nogil=True)
def _loose_loop(timeline, epochs, scalars, ints, vectors, nav, P, outputs):
    """:meth:`LooseFilter.run` compiled: the steps of its reference loop, sample after sample.
    Its declared twin is :meth:`~.loose.LooseFilter.run_reference` (equal to rounding, tested).

    Arguments, bundled: ``timeline = (t, acc, gyro, ep_at, coasting)`` (the merged time line, the
    epoch at each of its points or −1, the IMU-gap steps); ``epochs = (t_ep, fix, has, yaw_meas)``
    (per UWB epoch: time, fix ``(T, 3)``, whether it has one, heading); ``scalars`` and ``ints``: the
    settings named by :data:`LOOSE_SCALARS` and :data:`LOOSE_INTS` (``gate_pos``, ``gate_full``: the
    χ² thresholds of a position and a position + velocity epoch; ``gated`` 0 for
    :class:`~uwbwb.filters.gating.NoGate`, 1 for :class:`~uwbwb.filters.gating.ChiSquareEpoch`);
    ``vectors = (q_diag, R, p_lost, lever, g_n, g_up)`` (``Q`` per second of step before ``q_scale``,
    ``R``, :meth:`~.loose.LooseFilter.lost_lock_variance` without the innovation); ``nav = (p, v, q)``
    and ``P`` (worked on in place); ``outputs = (pos_o, vel_o, quat_o, ba_o, bg_o, P_o, cov_o, nis_o,
    dof_o, gated_o, status_o)``.

    Per sample: :func:`propagate` one IMU step without biases (or :func:`coast` inside an IMU gap,
    whose position/velocity noise is carried to the epoch), the height held for ``dim`` 2. Per
    epoch: the complementary levelling and heading correction (:func:`_exp_left_nb`), the predict
    of eq. 5 (:func:`~uwbwb.filters.ekf.kernels._predict`), the fix and differenced velocity of
    eq. 6 with the lost-lock inflation and the epoch gate, filterpy's batch update as
    :func:`~uwbwb.filters.ekf.kernels._update` forms it (its NIS), feedback or not. Raises
    FloatingPointError where the Python loop would raise (a non-finite measurement, ``S`` not
    positive definite): the caller then runs the Python loop, which decides.
    """
    t, acc, gyro, ep_at, coasting = timeline
    t_ep, fix, has, yaw_meas = epochs
    q_diag, R, p_lost, lever, g_n, g_up = vectors
    p, v, q = nav
    pos_o, vel_o, quat_o, ba_o, bg_o, P_o, cov_o, nis_o, dof_o, gated_o, status_o = outputs
    tau, q_scale, height_m = scalars[0], scalars[1], scalars[2]
    acc_var, gate_pos, gate_full = scalars[3], scalars[4], scalars[5]
    d, W, gated, max_gated, use_height = ints[0], ints[1], ints[2] != 0, ints[3], ints[4] != 0
    feedback, st_updated, st_gated, st_predicted = ints[5] != 0, ints[6], ints[7], ints[8]
    n = 2 * d
    dx = np.zeros(n)
    no_bias, no_q = np.zeros(3), np.zeros(15)
    Phi_s, Q_s = np.zeros((15, 15)), np.zeros((15, 15))    # propagate's 15-state pieces: not used here
    Phi_c, Q_c = np.eye(15), np.zeros((15, 15))            # coast accumulators since the last epoch
    coasted = False
    blk = np.empty(n, np.int64)
    for a in range(d):
        blk[a], blk[d + a] = a, 3 + a
    C = np.empty((3, 3))
    A = np.empty((n, n))
    Q = np.empty((n, n))
    H = np.zeros((n, n))
    for a in range(n):
        H[a, a] = 1.0
    z = np.empty(n)
    h = np.empty(n)
    z_pos = np.empty(d)
    corr = np.empty(3)
    hist_t, hist_p, n_hist = np.empty(W + 2), np.empty((W + 2, 3)), 0   # the fixes of the velocity window
    gated_y, gated_run = np.empty((max_gated + 1, 3)), 0                 # position innovations of a gated run
    last_t, started = 0.0, False
    for i in range(t.size):
        if i > 0 and coasting[i]:               # inside an IMU gap: nothing measured the motion
            coast(p, v, t, i - 1, i, no_q, acc_var, 0.0, Phi_c, Q_c)
            coasted = True
        elif i > 0:
            propagate(p, v, q, no_bias, no_bias, t, acc, gyro, i - 1, i, g_n, no_q, Phi_s, Q_s)
            if coasted:                         # carry the coast noise to the epoch (F of a step)
                dt = t[i] - t[i - 1]
                for a in range(3):
                    for b in range(15):
                        Q_c[a, b] += dt * Q_c[3 + a, b]
                for a in range(15):
                    for b in range(3):
                        Q_c[a, b] += dt * Q_c[a, 3 + b]
            if d == 2 and use_height:
                _dcm_nb(q, C)
                p[2], v[2] = height_m - (C @ lever)[2], 0.0
        k = ep_at[i]
        if k < 0:
            continue
        T_s = t[i] - last_t if started else 0.0
        last_t, started = t[i], True
        # attitude: complementary levelling (+ heading)
        _dcm_nb(q, C)
        gain = min(1.0, T_s / tau) if T_s > 0 else 0.0
        if gain > 0:
            fn = C @ acc[i]
            if np.isfinite(fn[0]) and np.isfinite(fn[1]) and np.isfinite(fn[2]):
                u = fn / max(math.sqrt(fn @ fn), 1e-9)
                corr[0] = gain * (u[1] * g_up[2] - u[2] * g_up[1])
                corr[1] = gain * (u[2] * g_up[0] - u[0] * g_up[2])
                corr[2] = gain * (u[0] * g_up[1] - u[1] * g_up[0])
            else:                               # inside an IMU gap: no specific force to level with
                corr[:] = 0.0
            if np.isfinite(yaw_meas[k]):
                a = yaw_meas[k] - math.atan2(C[1, 0], C[0, 0])
                corr[2] += gain * ((a + np.pi) % (2 * np.pi) - np.pi)
            _exp_left_nb(corr, q)
        # predict (eq. 5)
        A[:, :] = 0.0
        Q[:, :] = 0.0
        for a in range(n):
            A[a, a] = 1.0
            Q[a, a] = q_diag[a] * (T_s * q_scale)
        for a in range(d):
            A[a, d + a] = T_s
        if coasted:
            for a in range(n):
                for b in range(n):
                    Q[a, b] += Q_c[blk[a], blk[b]]
            Phi_c[:, :] = np.eye(15)
            Q_c[:, :] = 0.0
            coasted = False
        dx, P = _predict(dx, P, A, Q)
        _dcm_nb(q, C)
        cl = C @ lever
        nis, dof, status, n_gated = np.nan, 0, st_predicted, 0
        if has[k]:
            # the fix (eq. 6) and, over a full window, the differenced velocity
            hist_t[n_hist] = t_ep[k]
            hist_p[n_hist] = fix[k]
            n_hist += 1
            for a in range(d):
                z_pos[a] = p[a] + cl[a] - fix[k, a]
                z[a] = z_pos[a]
            m = d
            if n_hist > W and t_ep[k] - hist_t[n_hist - 1 - W] < 1.0:
                span = t_ep[k] - hist_t[n_hist - 1 - W]
                for a in range(d):
                    z[d + a] = v[a] - (hist_p[n_hist - 1, a] - hist_p[n_hist - 1 - W, a]) / span
                m = n
            for a in range(m):
                if not np.isfinite(z[a]):
                    raise FloatingPointError("non-finite measurement: the Python path decides")
            if 0 < gated_run >= max_gated and _consistent_nb(gated_y, gated_run, d):
                ms = 0.0                        # lock lost (the gated fixes agree): admit it, re-acquire
                for a in range(d):
                    y = z_pos[a] - dx[a]
                    ms += y * y
                ms /= d
                for a in range(n):
                    P[a, a] += p_lost[a] + (ms if a < d else ms / LOST_BUILD_S ** 2)
            for a in range(m):
                h[a] = dx[a]                    # H δx, H the identity's first m rows
            x_post, P_post, nis_e = _update(dx, P, z, h, H, R, m)
            if gated and gated_run < max_gated and nis_e > (gate_pos if m == d else gate_full):
                n_hist -= 1                     # a gated fix does not enter the velocity difference
                for a in range(d):
                    gated_y[gated_run, a] = z_pos[a] - dx[a]
                gated_run += 1
                status, n_gated = st_gated, 1
            else:
                gated_run = 0
                dx, P = x_post, P_post
                nis, dof, status = nis_e, m, st_updated
            if n_hist > W + 1:                  # keep the last W + 1 fixes
                for j in range(W + 1):
                    hist_t[j] = hist_t[j + n_hist - W - 1]
                    hist_p[j] = hist_p[j + n_hist - W - 1]
                n_hist = W + 1
        if feedback:                            # closed loop: correct the INS; open loop: report INS − δx
            for a in range(d):
                p[a] -= dx[a]
                v[a] -= dx[d + a]
        for a in range(3):
            pos_o[k, a], vel_o[k, a] = p[a], v[a]
        if feedback:
            dx[:] = 0.0
        else:
            for a in range(d):
                pos_o[k, a] -= dx[a]
                vel_o[k, a] -= dx[d + a]
        for a in range(3):
            pos_o[k, a] += cl[a]
        quat_o[k] = q
        ba_o[k] = 0.0
        bg_o[k] = 0.0
        P_o[k] = P
        for a in range(d):
            for b in range(d):
                cov_o[k, a, b] = P[a, b]
        nis_o[k], dof_o[k], gated_o[k], status_o[k] = nis, dof, n_gated, status
    return 0


@numba.njit(cache=True, nogil=True)
def _consistent_nb(y, n, d):
    """:func:`~.loose._consistent` of the first ``n`` rows of ``y`` (``d`` columns)."""
    if n == 0:
        return False
    mm = 0.0
    for a in range(d):
        acc = 0.0
        for j in range(n):
            acc += y[j, a]
        mean = acc / n
        mm += mean * mean
    step2 = 0.0
    if n > 1:
        for j in range(n - 1):
            s = 0.0
            for a in range(d):
                e = y[j + 1, a] - y[j, a]
                s += e * e
            step2 += s
        step2 /= n - 1
    return mm > step2
