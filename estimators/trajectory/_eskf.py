"""Offline error-state Kalman filter with zero-velocity updates and an RTS smoother (foot strapdown, ENU).

Model (error = truth − estimate, world-frame attitude error ``R_true = (I + [δθ×]) R̂``):

    nominal   q_{k+1} = q_k ⊗ exp((ω_k − b_g) T / 2)                                   (E1)
              ω_k here is the caller's rate for [t_k, t_k+1]: ω(t_k + T/2) (midpoint rule, issue 43; the
              wrapper interpolates, ``_api._attitude_gyro``) so q_k and f_k in (E2) are one instant    (E1c)
              a_k = R(q_k)(f_k − b_a) − g e_z ;  p_{k+1} = p_k + T v_k + ½T² a_k ;  v_{k+1} = v_k + T a_k   (E2)
    error     δp' = δv ;  δv' = −[(R(f − b_a))×] δθ − R δb_a ;  δθ' = −R δb_g ;  δb' = w_b    (E3)
              Φ_k = I + F_k T ;  Q_k = diag(σ_p², (σ_a,k T)², (σ_g,k T)², σ_ba,rw² T, σ_bg,rw² T)  (E4)
              σ_a,k = σ_a + c_a·| |f_k| − g | ,  σ_g,k = σ_g + c_g·|ω_k|   (signal-proportional error:      (E4b)
              scale factor, cross-axis, clipped or under-sampled impacts; the smoother then puts the
              velocity correction where the error was made — at heel-strike impacts — not spread over the swing)
              | |f_k| − g | in (E4b) is the maximum over ±w/2 around k, w = 30 ms (heel-strike transient     (E4c)
              duration): an under-sampled impact's integration error is not only on its peak sample
    ZUPT      z = 0 − v̂_k = H δx + n ,  H = [0 I 0 0 0] ,  R = σ_z,k² I  (at detected stance samples) (E5)
              σ_z,k = σ_z + r_lever·|ω_k|: a foot point r_lever from the rolling contact moves at |ω|·r (E5b)
    height    optional, flat floor: z = 0 − p̂_z,k = δp_z + n_h, R = σ_h² at stance samples after the ZUPT
              (the first stance is z = 0; Duong & Suh 2015 "height updating", spec B6.4); off by default (E5c)
    update    Joseph form; inject p,v,b additively, q ← quat(δθ) ⊗ q ; reset δx = 0          (E6)
    RTS       δs_k = P_f,k Φ_k' P_p,k+1⁻¹ (δs_{k+1} + δu_{k+1}),  δu = the update injected at k+1   (E7)
              smoothed nominal x_s,k = x_f,k ⊕ δs_k (only the mean is smoothed; P_s is not formed)

State size 9 (p, v, δθ) or 15 (+ accelerometer and gyroscope bias) — ``estimate_biases``.
The state is 0 before the first stance sample ``k0``: the filter is initialised there (attitude levelled on
gravity, yaw 0, gyroscope bias ``bg0``: zero, the all-stance median of ``_api.stance_gyro_bias`` (E1b) or the
mean over the rests of ``_api.rest_gyro_bias`` (E1d)), so a recording that starts mid-swing is handled.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from stridelab.estimators.quaternion import quat_exp_step_1, quat_mul_1, quat_to_matrix_1

GRAVITY = 9.81


@njit(cache=True)
def _quat_small(dth):
    """Unit quaternion of a small rotation vector (exact exp map)."""
    a = np.sqrt(dth[0] ** 2 + dth[1] ** 2 + dth[2] ** 2)
    out = np.empty(4)
    out[0] = np.cos(0.5 * a)
    s = np.sin(0.5 * a) / a if a > 1e-15 else 0.5
    out[1] = dth[0] * s
    out[2] = dth[1] * s
    out[3] = dth[2] * s
    return out


@njit(cache=True)
def _build_phi(q, f, ba, bg, T, n, Phi, R):
    """Φ = I + F T of (E3)/(E4) into ``Phi`` (n × n), using rotation workspace ``R``."""
    quat_to_matrix_1(q, R)
    for i in range(n):
        for j in range(n):
            Phi[i, j] = 0.0
        Phi[i, i] = 1.0
    a0 = R[0, 0] * (f[0] - ba[0]) + R[0, 1] * (f[1] - ba[1]) + R[0, 2] * (f[2] - ba[2])
    a1 = R[1, 0] * (f[0] - ba[0]) + R[1, 1] * (f[1] - ba[1]) + R[1, 2] * (f[2] - ba[2])
    a2 = R[2, 0] * (f[0] - ba[0]) + R[2, 1] * (f[1] - ba[1]) + R[2, 2] * (f[2] - ba[2])
    for i in range(3):
        Phi[i, 3 + i] = T
    # δv' = −[a×] δθ ;  −[a×] = [[0, a2, −a1], [−a2, 0, a0], [a1, −a0, 0]]
    Phi[3, 7] = T * a2
    Phi[3, 8] = -T * a1
    Phi[4, 6] = -T * a2
    Phi[4, 8] = T * a0
    Phi[5, 6] = T * a1
    Phi[5, 7] = -T * a0
    if n == 15:
        for i in range(3):
            for j in range(3):
                Phi[3 + i, 9 + j] = -T * R[i, j]
                Phi[6 + i, 12 + j] = -T * R[i, j]


@njit(cache=True)
def _propagate_cov(P, Phi, Qd, n, tmp, out):
    """out = Φ P Φ' + Q (dense, n ≤ 15)."""
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                if Phi[i, k] != 0.0:
                    s += Phi[i, k] * P[k, j]
            tmp[i, j] = s
    for i in range(n):
        for j in range(i, n):
            s = 0.0
            for k in range(n):
                if Phi[j, k] != 0.0:
                    s += tmp[i, k] * Phi[j, k]
            out[i, j] = s
            out[j, i] = s
        out[i, i] += Qd[i]


@njit(cache=True)
def _cholesky_solve(A, b, n, L, y):
    """Solve A y = b for a symmetric positive (semi)definite A (tiny diagonal jitter); result in ``y``."""
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                L[i, i] = np.sqrt(max(s, 1e-30))
            else:
                L[i, j] = s / L[j, j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * y[k]
        y[i] = s / L[i, i]


@njit(cache=True)
def _inject(d, n, p, v, q, ba, bg):
    """(E6) the error-state correction ``d`` (n,) into the nominal state: p, v (and b_a, b_g when n = 15) additively
    in place, q ← quat(δθ) ⊗ q normalised; returns q."""
    for i in range(3):
        p[i] += d[i]
        v[i] += d[3 + i]
    q = quat_mul_1(_quat_small(d[6:9]), q)
    q = q / np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    if n == 15:
        for i in range(3):
            ba[i] += d[9 + i]
            bg[i] += d[12 + i]
    return q


@njit(cache=True)
def _scalar_inject(P, n, idx, y, r2, tmp, K, p, v, q, ba, bg, dx):
    """(E5c, E5d) one scalar measurement y = δx[idx] + noise (variance r2): Kalman update of P (optimal-gain form,
    symmetrised), the correction K·y injected into the nominal state (E6) and added to ``dx``; returns q."""
    Sh = P[idx, idx] + r2
    for i in range(n):
        K[i, 0] = P[i, idx] / Sh
    for i in range(n):
        for j in range(i, n):
            tmp[i, j] = P[i, j] - K[i, 0] * P[idx, j]
    for i in range(n):
        for j in range(i, n):
            P[i, j] = tmp[i, j]
            P[j, i] = tmp[i, j]
    d = np.zeros(n)
    for i in range(n):
        d[i] = K[i, 0] * y
        dx[i] += d[i]
    return _inject(d, n, p, v, q, ba, bg)


@njit(cache=True)
def eskf_rts_kernel(gyr, acc, zupt, T, k0, q0, bg0, n, qd, sig_a, sig_g, p0_diag, sig_z, smooth,
                    pos, vel, quat, bias, var_h, gyr_meas, sig_zaru):
    """Forward ESKF (E1–E6) from sample ``k0`` then RTS (E7) back to ``k0``; writes pos, vel, quat, bias (N, ·).

    Rows before ``k0`` are left untouched (the caller fills them with NaN). ``qd`` (n,) is the diagonal of Q_k,
    ``p0_diag`` (n,) of P_0. ``bias`` is (N, 6): b_a, b_g. ``sig_a``, ``sig_g`` (N,) are the per-sample
    accelerometer / gyroscope noise std (E4 with a signal-dependent σ); they overwrite ``qd[3:9]`` per sample.
    """
    N = gyr.shape[0]
    M = N - k0
    Pf = np.zeros((M, n, n))
    dU = np.zeros((M, n))
    P = np.zeros((n, n))
    for i in range(n):
        P[i, i] = p0_diag[i]
    Phi = np.zeros((n, n))
    tmp = np.zeros((n, n))
    Pp = np.zeros((n, n))
    R = np.zeros((3, 3))
    q = q0.copy()
    p = np.zeros(3)
    v = np.zeros(3)
    ba = np.zeros(3)
    bg = bg0.copy()
    S = np.zeros((3, 3))
    Sinv = np.zeros((3, 3))
    K = np.zeros((n, 3))
    dx = np.zeros(n)
    for k in range(k0, N):
        m = k - k0
        if k > k0:
            # ---- time update with sample k−1 (E1, E2, E4)
            _build_phi(q, acc[k - 1], ba, bg, T, n, Phi, R)
            for i in range(3):
                qd[3 + i] = (sig_a[k - 1] * T) ** 2
                qd[6 + i] = (sig_g[k - 1] * T) ** 2
            _propagate_cov(P, Phi, qd, n, tmp, Pp)
            for i in range(n):
                for j in range(n):
                    P[i, j] = Pp[i, j]
            a = np.empty(3)
            for i in range(3):
                a[i] = R[i, 0] * (acc[k - 1, 0] - ba[0]) + R[i, 1] * (acc[k - 1, 1] - ba[1]) + \
                    R[i, 2] * (acc[k - 1, 2] - ba[2])
            a[2] -= GRAVITY
            for i in range(3):
                p[i] += T * v[i] + 0.5 * T * T * a[i]
                v[i] += T * a[i]
            q = quat_exp_step_1(q, gyr[k - 1, 0] - bg[0], gyr[k - 1, 1] - bg[1], gyr[k - 1, 2] - bg[2], T)
        for i in range(n):
            dx[i] = 0.0
        if zupt[k]:
            r2 = sig_z[k] * sig_z[k]
            # ---- ZUPT (E5, E6): S = P_vv + R, K = P[:, v] S⁻¹
            for i in range(3):
                for j in range(3):
                    S[i, j] = P[3 + i, 3 + j]
                S[i, i] += r2
            det = (S[0, 0] * (S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]) - S[0, 1] * (S[1, 0] * S[2, 2] - S[1, 2] * S[2, 0])
                   + S[0, 2] * (S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0]))
            Sinv[0, 0] = (S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]) / det
            Sinv[0, 1] = (S[0, 2] * S[2, 1] - S[0, 1] * S[2, 2]) / det
            Sinv[0, 2] = (S[0, 1] * S[1, 2] - S[0, 2] * S[1, 1]) / det
            Sinv[1, 0] = (S[1, 2] * S[2, 0] - S[1, 0] * S[2, 2]) / det
            Sinv[1, 1] = (S[0, 0] * S[2, 2] - S[0, 2] * S[2, 0]) / det
            Sinv[1, 2] = (S[0, 2] * S[1, 0] - S[0, 0] * S[1, 2]) / det
            Sinv[2, 0] = (S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0]) / det
            Sinv[2, 1] = (S[0, 1] * S[2, 0] - S[0, 0] * S[2, 1]) / det
            Sinv[2, 2] = (S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]) / det
            for i in range(n):
                for j in range(3):
                    K[i, j] = P[i, 3] * Sinv[0, j] + P[i, 4] * Sinv[1, j] + P[i, 5] * Sinv[2, j]
            for i in range(n):
                dx[i] = -(K[i, 0] * v[0] + K[i, 1] * v[1] + K[i, 2] * v[2])
            # Joseph form with H = [0 I 0]: P ← (I−KH) P (I−KH)' + K R K'
            for i in range(n):
                for j in range(n):
                    tmp[i, j] = P[i, j] - (K[i, 0] * P[3, j] + K[i, 1] * P[4, j] + K[i, 2] * P[5, j])
            for i in range(n):
                for j in range(i, n):
                    s = tmp[i, j] - (tmp[i, 3] * K[j, 0] + tmp[i, 4] * K[j, 1] + tmp[i, 5] * K[j, 2])
                    s += r2 * (K[i, 0] * K[j, 0] + K[i, 1] * K[j, 1] + K[i, 2] * K[j, 2])
                    P[i, j] = s
                    P[j, i] = s
            q = _inject(dx, n, p, v, q, ba, bg)
            if var_h > 0.0:
                # ---- flat-floor stance height (E5c): z = 0 − p̂_z = δp_z + n_h (first stance at z = 0)
                q = _scalar_inject(P, n, 2, -p[2], var_h, tmp, K, p, v, q, ba, bg, dx)
            if n == 15 and sig_zaru.shape[0] > 0 and sig_zaru[k] > 0.0:
                # ---- zero angular rate (E5d): z = ω_k − b̂_g = δb_g + n, R = σ_zaru,k²
                #      (sequential scalar updates)
                r2z = sig_zaru[k] * sig_zaru[k]
                for j in range(3):
                    q = _scalar_inject(P, n, 12 + j, gyr_meas[k, j] - bg[j], r2z, tmp, K, p, v, q, ba, bg, dx)
        for i in range(n):
            dU[m, i] = dx[i]
            for j in range(n):
                Pf[m, i, j] = P[i, j]
        for i in range(3):
            pos[k, i] = p[i]
            vel[k, i] = v[i]
            bias[k, i] = ba[i]
            bias[k, 3 + i] = bg[i]
        for i in range(4):
            quat[k, i] = q[i]
    if not smooth or M < 2:
        return
    # ---- RTS backward pass on the mean (E7)
    ds = np.zeros(n)
    rhs = np.zeros(n)
    y = np.zeros(n)
    L = np.zeros((n, n))
    for k in range(N - 2, k0 - 1, -1):
        m = k - k0
        for i in range(3):
            ba[i] = bias[k, i]
            bg[i] = bias[k, 3 + i]
        _build_phi(quat[k], acc[k], ba, bg, T, n, Phi, R)
        for i in range(3):
            qd[3 + i] = (sig_a[k] * T) ** 2
            qd[6 + i] = (sig_g[k] * T) ** 2
        _propagate_cov(Pf[m], Phi, qd, n, tmp, Pp)
        for i in range(n):
            rhs[i] = ds[i] + dU[m + 1, i]
        _cholesky_solve(Pp, rhs, n, L, y)
        # ds_k = P_f Φ' y
        for i in range(n):
            s = 0.0
            for j in range(n):
                if Phi[j, i] != 0.0:
                    s += Phi[j, i] * y[j]
            rhs[i] = s
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += Pf[m, i, j] * rhs[j]
            ds[i] = s
        # Φ_k above used the filtered sample k; only now is sample k replaced by its smoothed value
        _apply(ds, k, n, pos, vel, quat, bias)


@njit(cache=True)
def _apply(ds, k, n, pos, vel, quat, bias):
    for i in range(3):
        pos[k, i] += ds[i]
        vel[k, i] += ds[3 + i]
    qn = quat_mul_1(_quat_small(ds[6:9]), quat[k])
    nr = np.sqrt(qn[0] ** 2 + qn[1] ** 2 + qn[2] ** 2 + qn[3] ** 2)
    for i in range(4):
        quat[k, i] = qn[i] / nr
    if n == 15:
        for i in range(3):
            bias[k, i] += ds[9 + i]
            bias[k, 3 + i] += ds[12 + i]
