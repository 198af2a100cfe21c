"""The EKF's epoch loop compiled for the TDoA measurement (:meth:`~.tdoa.TdoaEkf.run`) and the range
measurement (:func:`~.ranges.run_ranges`), for the gates :class:`NoGate`, :class:`ChiSquareEpoch`,
:class:`ChiSquarePerMeasurement` and :class:`AnchorDropping`, and :class:`Robust` screening with one of them,
with the batch update. Declared twin: the Python :meth:`~.core.Ekf.run` (``uwbwb/filters/twins.py``).

Each epoch repeats the Python steps in their order: the prediction of
:func:`~uwbwb.filters.kalman.predict` (``F x``, ``(F P) Fᵀ + Q``, symmetrised), the linearisation of
:meth:`~uwbwb.models.tdoa.TdoaModel.epoch` or of :class:`~.ranges.RangeMeasurement`, the gate's decision
(``(H P) Hᵀ + R`` and ``yᵀ S⁻¹ y`` as :mod:`~uwbwb.filters.gating` forms them) and filterpy's Joseph-form update as
:func:`~uwbwb.filters.kalman.update` calls it (``y = (z − h + H x) − H x``, ``S = H (P Hᵀ) + R``,
``K = P Hᵀ S⁻¹``, ``P = ((I − K H) P) (I − K H)ᵀ + (K R) Kᵀ``, symmetrised; NIS with the symmetrised
``S``), for :class:`Robust` its passes (:meth:`Robust.update`: that update from the prior with ``R`` scaled by
the weights of the residuals over ``√S_ii``, ``S = (H P) Hᵀ + R`` symmetrised). Products are plain loops and
``S⁻¹`` an LU factorisation with partial pivoting, where the Python path calls BLAS and LAPACK: the same
operations, summed in another order, so the results agree to a few units in the last place, not bit for bit
(a Robust pass that stops because its weights equal the last pass's may then stop one pass apart, where the
posterior is the same to rounding). Where the Python path would raise (a non-finite
state, an innovation covariance that is not positive definite, a singular matrix) the kernel stops
and :func:`run` returns None: the Python run then decides.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ...types import EstimateStatus
from ..gating import AnchorDropping, ChiSquareEpoch, ChiSquarePerMeasurement, NoGate, Robust, _chi2_ppf
from .core import KalmanRun

#: The gate policies the kernel runs, by its code for them, alone or as a :class:`Robust` update's screening gate
#: (any other policy keeps the Python path).
GATE_KINDS = {NoGate: 0, ChiSquareEpoch: 1, ChiSquarePerMeasurement: 2, AnchorDropping: 3}
#: :class:`Robust` weights the kernel computes, by its code for them (0: no reweighting).
ROBUST_KINDS = {"huber": 1, "cauchy": 2}


def takes(gate) -> bool:
    """Whether the kernel runs the gate policy ``gate``: one of :data:`GATE_KINDS`, or a :class:`Robust` update
    screening with one."""
    return type(gate.gate if type(gate) is Robust else gate) in GATE_KINDS


def run(ekf, t_s, rows, refs, x0, start: int, name: str) -> KalmanRun | None:
    """:meth:`~.core.Ekf.run` of ``ekf`` on epochs at ``t_s`` from epoch ``start`` (prior ``x0``), compiled:
    ``rows`` the TDoAs of a :class:`~.tdoa.TdoaEkf` with ``refs`` their reference anchors, or (``refs`` None)
    the ranges of an :class:`~.core.Ekf` with a :class:`~.ranges.RangeMeasurement`. None where the Python run
    must decide: a gate it does not :func:`take <takes>`, the sequential update, an input :meth:`~.core.Ekf.run`
    refuses, or an epoch where the kernel stopped (see the module)."""
    t_s = np.asarray(t_s, float)
    T, n = t_s.size, x0.x.size
    if (not takes(ekf.gate) or ekf.sequential or (T > 1 and np.any(np.diff(t_s) <= 0))
            or n != ekf.transition.n_x or not 0 <= start <= T or len(rows) != T):
        return None
    xm, Pm = np.full((T, n), np.nan), np.full((T, n, n), np.nan)
    xp, Pp = np.full((T, n), np.nan), np.full((T, n, n), np.nan)
    F = np.full((T, n, n), np.nan)
    nis, dof, n_rej = np.full(T, np.nan), np.zeros(T, int), np.zeros(T, int)
    status = np.full(T, EstimateStatus.NO_ESTIMATE, np.int8)
    if start < T:
        dt = np.diff(t_s[start:])
        # writable C-ordered copies throughout: one compiled signature whatever the caller's arrays
        F_all = np.array(ekf.transition.F(dt), float, order="C").reshape(-1, n, n)
        Q_all = np.array(ekf.transition.Q(dt), float, order="C").reshape(-1, n, n)
        F[start], F[start + 1:] = np.eye(n), F_all
        robust, m, ranges = ekf.gate, ekf.measurement, refs is None
        gate = robust.gate if type(robust) is Robust else robust
        robust = (ROBUST_KINDS[robust.kind], robust.k, robust.iterations) if gate is not robust else (0, np.inf, 0)
        if ranges:                        # RangeMeasurement: anchors, σ, tag height of a 2-D model
            model = (m.anchors_m, m.sigma_m, np.nan if m.z_m is None else m.z_m, m.motion.dim, False)
            refs = np.full(T, -1)
        else:
            m = ekf.tdoa_model
            model = (m.anchor_pos_m, m.sigma_m, m.z_m, m.dim, m.correlated)
        prob = getattr(gate, "prob", None)
        thr = np.array([np.nan] + [float(_chi2_ppf(prob, k)) if prob is not None else np.inf
                                   for k in range(1, len(model[0]) + 1)])
        settings = np.array([GATE_KINDS[type(gate)], getattr(gate, "min_rows", 1), gate.max_gated, model[3],
                             model[4], start, EstimateStatus.UPDATED, EstimateStatus.PREDICTED,
                             EstimateStatus.GATED, ranges, robust[0], robust[2]], np.int64)
        try:
            _loop((F_all, Q_all), (np.array(rows, float, order="C"), np.array(refs, np.int64)),
                  (np.array(model[0], float, order="C"), np.array(model[1] ** 2, float), thr, float(robust[1])),
                  float(model[2]), settings, np.array(x0.x, float), np.array(x0.P, float, order="C"),
                  (xm, Pm, xp, Pp, nis, dof, n_rej, status))
        except FloatingPointError:
            return None
    return KalmanRun(t_s.copy(), xm, Pm, xp, Pp, F, nis, dof, status, ekf.pos_index, ekf.vel_index, name, n_rej)


@numba.njit(cache=True, nogil=True)
def _loop(steps, epochs, model, z_m, settings, x, P, outputs):
    """The epochs ``start..T−1`` of :meth:`~.core.Ekf.run` with the TDoA or range measurement and a gate of
    :data:`GATE_KINDS`. ``steps = (F_all, Q_all)``, ``epochs = (tdoa_m, ref)`` or ``(range_m, −1)``,
    ``model = (anchors, σ², χ² quantiles by degrees of freedom, Robust's k)``, ``settings`` = (gate kind,
    min_rows, max_gated, dim, correlated, start, UPDATED, PREDICTED, GATED, ranges, robust kind of
    :data:`ROBUST_KINDS` or 0, Robust's iterations); outputs written in place. Raises
    FloatingPointError where the Python path would raise (or meets a NaN statistic)."""
    F_all, Q_all = steps
    tdoa, refs = epochs
    anchors, var, thr, k_robust = model
    xm, Pm, xp, Pp, nis_o, dof_o, rej_o, status_o = outputs
    kind, min_rows, max_gated, dim, correlated = settings[0], settings[1], settings[2], settings[3], settings[4] != 0
    start, updated, predicted, gated_st, ranges = settings[5], settings[6], settings[7], settings[8], settings[9] != 0
    robust = (settings[10], k_robust, settings[11])
    T, n_a = tdoa.shape
    n = x.size
    comp = np.empty(n_a, np.int64)
    keep = np.empty(n_a, np.int64)
    sub = np.empty(n_a, np.int64)
    z, h, H, R = np.empty(n_a), np.empty(n_a), np.zeros((n_a, n)), np.empty((n_a, n_a))
    z2, h2, H2, R2 = np.empty(n_a), np.empty(n_a), np.zeros((n_a, n)), np.empty((n_a, n_a))
    run = 0                                     # consecutive gated epochs
    for k in range(start, T):
        if k > start:
            x, P = _predict(x, P, F_all[k - start - 1], Q_all[k - start - 1])
        xm[k], Pm[k] = x, P
        row, ref = tdoa[k], refs[k]
        nc = 0
        for j in range(n_a):
            if np.isfinite(row[j]):
                comp[nc] = j
                nc += 1
        nis, dof, rej, st = np.nan, 0, 0, predicted
        if (nc >= 1) if ranges else (ref >= 0 and nc >= 2):
            if not (ranges or 0 <= ref < n_a and np.isfinite(row[ref])) or not (np.isfinite(x).all()
                                                                               and np.isfinite(P).all()):
                raise FloatingPointError("the Python path decides")
            m = _linearise(x, row, ref, comp, nc, anchors, var, z_m, dim, correlated, ranges, z, h, H, R)
            st, dof = updated, m
            if run >= max_gated:                # released: the plain update
                x, P, nis = _update(x, P, z, h, H, R, m)
            elif kind == 0:
                x, P, nis = _use(x, P, z, h, H, R, m, robust, np.inf)
            elif kind == 1:                     # ChiSquareEpoch: the update's (Robust: the innovation's) NIS decides
                xn, Pn, nis = _use(x, P, z, h, H, R, m, robust, thr[m])
                if nis > thr[m]:
                    st, dof = gated_st, 0
                else:
                    x, P = xn, Pn
            elif kind == 2:                     # ChiSquarePerMeasurement: y_i² / S_ii, S = (H P) Hᵀ + R
                HP = _mul(H, P, m, n, n)
                w = 0
                for a in range(m):
                    acc = 0.0
                    for c in range(n):
                        acc += HP[a, c] * H[a, c]
                    s = acc + R[a, a]
                    y = z[a] - h[a]
                    if y * y / s <= thr[1]:
                        keep[w] = a
                        w += 1
                if w == m:
                    x, P, nis = _use(x, P, z, h, H, R, m, robust, np.inf)
                elif w < min_rows:
                    nis, st, dof, rej = _nis(P, z, h, H, R, m), gated_st, 0, m
                else:
                    for a in range(w):
                        z2[a], h2[a], H2[a] = z[keep[a]], h[keep[a]], H[keep[a]]
                        for b in range(w):
                            R2[a, b] = R[keep[a], keep[b]]
                    x, P, nis = _use(x, P, z2, h2, H2, R2, w, robust, np.inf)
                    dof, rej = w, m - w
            else:                               # AnchorDropping: drop the anchor whose removal lowers the NIS most
                nk = nc
                keep[:nk] = comp[:nc]
                drop = False
                while True:
                    v = _nis(P, z, h, H, R, m)
                    if not np.isfinite(v):
                        raise FloatingPointError("the Python path decides")
                    if v <= thr[m]:
                        break
                    if m - 1 < max(min_rows, 1):
                        drop = True
                        rej += nk
                        break
                    best, best_i = np.inf, -1
                    for i in range(nk):
                        ns = 0
                        for j in range(nk):
                            if j != i:
                                sub[ns] = keep[j]
                                ns += 1
                        m2 = _linearise(x, row, _reference(ref, sub, ns), sub, ns, anchors, var, z_m, dim,
                                        correlated, ranges, z2, h2, H2, R2)
                        v = _nis(P, z2, h2, H2, R2, m2)
                        if not np.isfinite(v):
                            raise FloatingPointError("the Python path decides")
                        if best_i < 0 or v < best:
                            best, best_i = v, i
                    for j in range(best_i, nk - 1):
                        keep[j] = keep[j + 1]
                    nk -= 1
                    m = _linearise(x, row, _reference(ref, keep, nk), keep, nk, anchors, var, z_m, dim, correlated,
                                   ranges, z, h, H, R)
                    rej += 1
                if drop:
                    st, dof = gated_st, 0
                else:
                    x, P, nis = _use(x, P, z, h, H, R, m, robust, np.inf)
                    dof = m
        run = run + 1 if st == gated_st else 0
        xp[k], Pp[k], nis_o[k], dof_o[k], rej_o[k], status_o[k] = x, P, nis, dof, rej, st


@numba.njit(cache=True, nogil=True)
def _use(x, P, z, h, H, R, m, robust, limit):
    """The update a gate lets through: :func:`_update`, or (``robust = (kind, k, iterations)``, kind ≠ 0)
    :meth:`Robust.update`'s passes. Returns the posterior and the NIS, for Robust that of the innovation
    (``y = z − h``, ``S = (H P) Hᵀ + R`` symmetrised) and the prior itself where that NIS is above ``limit``."""
    kind, k, iterations = robust
    if kind == 0:
        return _update(x, P, z, h, H, R, m)
    n = x.size
    S = _mul_t(_mul(H, P, m, n, n), H, m, n, m)
    _add_into(S, R, m, m)
    S = _symmetric(S)
    y, scale = np.empty(m), np.empty(m)
    for a in range(m):
        y[a], scale[a] = z[a] - h[a], math.sqrt(S[a, a])
    nis = _quadratic(S, y, m)
    if nis > limit:
        return x, P, nis
    xn, Pn = x, P
    w, w_last, Rw = np.empty(m), np.empty(m), np.empty((m, m))
    for it in range(iterations):
        for a in range(m):                      # r = (y − H (x_j − x⁻)) / √S_ii and its weight
            acc = 0.0
            for b in range(n):
                acc += H[a, b] * (xn[b] - x[b])
            r = abs((y[a] - acc) / scale[a])
            if kind == 2:
                w[a] = 1.0 / (1.0 + (r / k) * (r / k))
            else:
                w[a] = k / r if r > k else 1.0
        if it > 0 and (w == w_last).all():
            break                               # the same weights would give the same posterior again
        for a in range(m):                      # R · outer(d, d), d = 1 / √w
            for b in range(m):
                Rw[a, b] = R[a, b] * ((1.0 / math.sqrt(w[a])) * (1.0 / math.sqrt(w[b])))
        if not np.isfinite(Rw).all():
            raise FloatingPointError("an inflated R that is not finite: the Python path decides")
        xn, Pn, _ = _update(x, P, z, h, H, Rw, m)
        w_last[:] = w
    return xn, Pn, nis


@numba.njit(cache=True, nogil=True)
def _reference(ref, keep, nk):
    """:meth:`~.tdoa.TdoaMeasurement.linearise_components`' reference: ``ref`` if kept, else the first kept."""
    for j in range(nk):
        if keep[j] == ref:
            return ref
    return keep[0]


@numba.njit(cache=True, nogil=True)
def _linearise(x, row, ref, keep, nk, anchors, var, z_m, dim, correlated, ranges, z, h, H, R):
    """:meth:`~uwbwb.models.tdoa.TdoaModel.epoch` from anchors ``keep[:nk]`` (``ref`` among them) at the
    position ``x[:dim]``, lifted to the state (``H_pos = [I 0 …]``): ``z, h, H, R`` in place; returns ``m``.
    ``ranges``: :class:`~.ranges.RangeMeasurement`'s instead (``h_i = |p − a_i|``, ``R = diag(σ_i²)``)."""
    p = np.empty(3)
    p[0], p[1] = x[0], x[1]
    p[2] = x[2] if dim == 3 else z_m
    if ranges:
        for i in range(nk):
            j = keep[i]
            d = p - anchors[j]
            r = math.sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2])   # np.linalg.norm's order
            z[i], h[i] = row[j], r
            H[i] = 0.0
            for c in range(dim):
                H[i, c] = d[c] / max(r, 1e-9)
            R[i, :nk] = 0.0
            R[i, i] = var[j]
        return nk
    dr = p - anchors[ref]
    rr = math.sqrt((dr[0] * dr[0] + dr[2] * dr[2]) + dr[1] * dr[1])   # numpy's einsum order for three terms
    sr = max(rr, 1e-12)
    m = 0
    for i in range(nk):
        j = keep[i]
        if j == ref:
            continue
        d = p - anchors[j]
        r = math.sqrt((d[0] * d[0] + d[2] * d[2]) + d[1] * d[1])
        s = max(r, 1e-12)
        z[m] = row[j] - row[ref]
        h[m] = r - rr
        H[m] = 0.0
        for c in range(dim):
            H[m, c] = d[c] / s - dr[c] / sr
        for b in range(m + 1):
            off = var[ref] if correlated else 0.0
            R[m, b] = R[b, m] = off
        R[m, m] = var[j] + var[ref]
        m += 1
    return m


@numba.njit(cache=True, nogil=True)
def _mul(A, B, m, l, n):
    """``A[:m, :l] @ B[:l, :n]``."""
    C = np.empty((m, n))
    for a in range(m):
        for c in range(n):
            acc = 0.0
            for b in range(l):
                acc += A[a, b] * B[b, c]
            C[a, c] = acc
    return C


@numba.njit(cache=True, nogil=True)
def _mul_t(A, B, m, l, n):
    """``A[:m, :l] @ B[:n, :l]ᵀ``."""
    C = np.empty((m, n))
    for a in range(m):
        for c in range(n):
            acc = 0.0
            for b in range(l):
                acc += A[a, b] * B[c, b]
            C[a, c] = acc
    return C


@numba.njit(cache=True, nogil=True)
def _symmetric(P):
    n = P.shape[0]
    S = np.empty((n, n))
    for a in range(n):
        for b in range(n):
            S[a, b] = 0.5 * (P[a, b] + P[b, a])
    return S


@numba.njit(cache=True, nogil=True)
def _predict(x, P, F, Q):
    """:func:`~uwbwb.filters.kalman.predict`: ``F x``, ``(F P) Fᵀ + Q`` symmetrised."""
    n = x.size
    xn = np.empty(n)
    for a in range(n):
        acc = 0.0
        for b in range(n):
            acc += F[a, b] * x[b]
        xn[a] = acc
    FPF = _mul_t(_mul(F, P, n, n, n), F, n, n, n)
    _add_into(FPF, Q, n, n)
    return xn, _symmetric(FPF)


@numba.njit(cache=True, nogil=True)
def _lu(A, m):
    """LU factorisation with partial pivoting of ``A[:m, :m]`` (LAPACK ``getf2``'s steps), a copy; raises
    FloatingPointError for a zero pivot (numpy's ``LinAlgError``)."""
    LU = np.empty((m, m))
    for i in range(m):
        for c in range(m):
            LU[i, c] = A[i, c]
    piv = np.empty(m, np.int64)
    for j in range(m):
        p = j
        for i in range(j + 1, m):
            if abs(LU[i, j]) > abs(LU[p, j]):
                p = i
        piv[j] = p
        if LU[p, j] == 0.0:
            raise FloatingPointError("singular matrix: the Python path decides")
        if p != j:
            for c in range(m):
                LU[j, c], LU[p, c] = LU[p, c], LU[j, c]
        inv = 1.0 / LU[j, j]
        for i in range(j + 1, m):
            LU[i, j] *= inv
            for c in range(j + 1, m):
                LU[i, c] -= LU[i, j] * LU[j, c]
    return LU, piv


@numba.njit(cache=True, nogil=True)
def _lu_solve(LU, piv, b):
    """``A⁻¹ b`` in place from :func:`_lu`."""
    m = b.size
    for j in range(m):
        b[j], b[piv[j]] = b[piv[j]], b[j]
    for i in range(m):
        for c in range(i):
            b[i] -= LU[i, c] * b[c]
    for i in range(m - 1, -1, -1):
        for c in range(i + 1, m):
            b[i] -= LU[i, c] * b[c]
        b[i] /= LU[i, i]


@numba.njit(cache=True, nogil=True)
def _quadratic(S, y, m):
    """``yᵀ S⁻¹ y``."""
    LU, piv = _lu(S, m)
    w = y.copy()
    _lu_solve(LU, piv, w)
    acc = 0.0
    for a in range(m):
        acc += y[a] * w[a]
    return acc


@numba.njit(cache=True, nogil=True)
def _nis(P, z, h, H, R, m):
    """The gates' epoch NIS: ``y = z − h``, ``S = (H P) Hᵀ + R``, ``yᵀ S⁻¹ y``."""
    n = P.shape[0]
    S = _mul_t(_mul(H, P, m, n, n), H, m, n, m)
    _add_into(S, R, m, m)
    y = np.empty(m)
    for a in range(m):
        y[a] = z[a] - h[a]
    return _quadratic(S, y, m)


@numba.njit(cache=True, nogil=True)
def _update(x, P, z, h, H, R, m):
    """:func:`~uwbwb.filters.kalman.update` with ``h_x = h``: the posterior ``(x, P)`` and its NIS. Raises
    FloatingPointError where that function raises (``S`` not positive definite)."""
    n = x.size
    y = np.empty(m)
    for a in range(m):                          # y = (z − h + H x) − H x, as filterpy sees z − h
        acc = 0.0
        for b in range(n):
            acc += H[a, b] * x[b]
        y[a] = ((z[a] - h[a]) + acc) - acc
    PHT = _mul_t(P, H, n, n, m)
    S = _mul(H, PHT, m, n, m)
    _add_into(S, R, m, m)
    Ss = _symmetric(S)
    for i in range(m):                          # Cholesky of the symmetric part: positive definite?
        for j in range(i + 1):
            acc = Ss[i, j]
            for c in range(j):
                acc -= Ss[i, c] * Ss[j, c]
            if i == j:
                if not acc > 0.0:
                    raise FloatingPointError("S not positive definite: the Python path decides")
                Ss[i, i] = math.sqrt(acc)
            else:
                Ss[i, j] = acc / Ss[j, j]
    LU, piv = _lu(S, m)
    SI = np.empty((m, m))
    col = np.empty(m)
    for c in range(m):                          # S⁻¹, column by column
        for a in range(m):
            col[a] = 0.0
        col[c] = 1.0
        _lu_solve(LU, piv, col)
        for a in range(m):
            SI[a, c] = col[a]
    K = _mul(PHT, SI, n, m, m)
    xn = np.empty(n)
    for a in range(n):
        acc = 0.0
        for e in range(m):
            acc += K[a, e] * y[e]
        xn[a] = x[a] + acc
    IKH = _mul(K, H, n, m, n)
    for a in range(n):
        for b in range(n):
            IKH[a, b] = (1.0 if a == b else 0.0) - IKH[a, b]
    A = _mul(IKH, P, n, n, n)
    KR = _mul(K, R, n, m, m)
    Pn = np.empty((n, n))
    for a in range(n):                          # ((I − K H) P) (I − K H)ᵀ + (K R) Kᵀ
        for b in range(n):
            t1 = 0.0
            for c in range(n):
                t1 += A[a, c] * IKH[b, c]
            t2 = 0.0
            for e in range(m):
                t2 += KR[a, e] * K[b, e]
            Pn[a, b] = t1 + t2
    return xn, _symmetric(Pn), _quadratic(_symmetric(S), y, m)


@numba.njit(cache=True, nogil=True)
def _add_into(A, B, m, n):
    """``A[:m, :n] += B[:m, :n]``."""
    for a in range(m):
        for b in range(n):
            A[a, b] += B[a, b]
