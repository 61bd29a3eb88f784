"""Numba kernels of the thesis' 13-state full-state filters (see :mod:`._fullstate`).

State ``x = [q(4) [w x y z] sensor→ENU, a(3) external acceleration (g, sensor frame), b(3) gyro bias
(rad/s), d(3) magnetic disturbance (field-norm units, sensor frame)]`` (Th. Eq 26, spec §5.1).
Measurements: ``y_A = acc / g_ref`` (g units) and ``y_M = mag / |m_ref|`` (spec §1.3); model
``h(x) = [a + R(q)ᵀ e_z ; d + R(q)ᵀ m]`` with the ENU reference field ``m = (m_x, m_y, m_z)`` (Th. Eq 31/42,
spec §1.2, written in the thesis' polynomial form so the Jacobians below are exact).

Kernel state vector (float64, ``STATE_LEN``): ``0:13 x``, ``13:182 P`` (13×13 row-major), ``182`` number of
robust-update fallbacks (A18), ``183`` samples processed.

Everything here takes arrays, floats and ints only (STYLE P5); no per-sample allocation.
"""
from __future__ import annotations

import numpy as np
from numba import njit

NX = 13
STATE_LEN = NX + NX * NX + 2
I_FALLBACK = NX + NX * NX
I_COUNT = I_FALLBACK + 1
#: project P through the normalisation Jacobian after each update (off: measured worse on BROAD, 2.84° vs
#: 2.39° mean on 5 trials for the plain EKF; the q-scale direction then absorbs part of the |y_A| deviation)
PROJECT_NORM = False


# ---------------------------------------------------------------- model functions (also used by tests)

@njit(cache=True)
def h_model(x, m, out):
    """h(x) = [a + R(q)ᵀ e_z ; d + R(q)ᵀ m] (6,), Th. Eq 31/42 in the printed polynomial form."""
    q0, q1, q2, q3 = x[0], x[1], x[2], x[3]
    mx, my, mz = m[0], m[1], m[2]
    out[0] = x[4] + 2.0 * (q1 * q3 - q0 * q2)
    out[1] = x[5] + 2.0 * (q0 * q1 + q2 * q3)
    out[2] = x[6] + 2.0 * (0.5 - q1 * q1 - q2 * q2)
    out[3] = x[10] + 2.0 * mx * (0.5 - q2 * q2 - q3 * q3) + 2.0 * my * (q0 * q3 + q1 * q2) \
        + 2.0 * mz * (q1 * q3 - q0 * q2)
    out[4] = x[11] + 2.0 * mx * (q1 * q2 - q0 * q3) + 2.0 * my * (0.5 - q1 * q1 - q3 * q3) \
        + 2.0 * mz * (q0 * q1 + q2 * q3)
    out[5] = x[12] + 2.0 * mx * (q0 * q2 + q1 * q3) + 2.0 * my * (q2 * q3 - q0 * q1) \
        + 2.0 * mz * (0.5 - q1 * q1 - q2 * q2)


@njit(cache=True)
def h_jac_q(x, m, out):
    """∂h/∂q (6, 4): rows 0-2 H_A, rows 3-5 H_M (Th. Eqs 33, 43-44). The a and d columns are I3."""
    q0, q1, q2, q3 = x[0], x[1], x[2], x[3]
    mx, my, mz = m[0], m[1], m[2]
    out[0, 0] = -2 * q2
    out[0, 1] = 2 * q3
    out[0, 2] = -2 * q0
    out[0, 3] = 2 * q1
    out[1, 0] = 2 * q1
    out[1, 1] = 2 * q0
    out[1, 2] = 2 * q3
    out[1, 3] = 2 * q2
    out[2, 0] = 0.0
    out[2, 1] = -4 * q1
    out[2, 2] = -4 * q2
    out[2, 3] = 0.0
    out[3, 0] = 2 * (my * q3 - mz * q2)
    out[3, 1] = 2 * (my * q2 + mz * q3)
    out[3, 2] = 2 * (-2 * mx * q2 + my * q1 - mz * q0)
    out[3, 3] = 2 * (-2 * mx * q3 + my * q0 + mz * q1)
    out[4, 0] = 2 * (-mx * q3 + mz * q1)
    out[4, 1] = 2 * (mx * q2 - 2 * my * q1 + mz * q0)
    out[4, 2] = 2 * (mx * q1 + mz * q3)
    out[4, 3] = 2 * (-mx * q0 - 2 * my * q3 + mz * q2)
    out[5, 0] = 2 * (mx * q2 - my * q1)
    out[5, 1] = 2 * (mx * q3 - my * q0 - 2 * mz * q1)
    out[5, 2] = 2 * (mx * q0 + my * q3 - 2 * mz * q2)
    out[5, 3] = 2 * (mx * q1 + my * q2)


@njit(cache=True)
def omega_matrix(wx, wy, wz, out):
    """Ω(ω) of Th. Eq 27 (4×4): Ω(ω) q = ½ q ⊗ (0, ω)."""
    out[0, 0] = 0.0
    out[0, 1] = -0.5 * wx
    out[0, 2] = -0.5 * wy
    out[0, 3] = -0.5 * wz
    out[1, 0] = 0.5 * wx
    out[1, 1] = 0.0
    out[1, 2] = 0.5 * wz
    out[1, 3] = -0.5 * wy
    out[2, 0] = 0.5 * wy
    out[2, 1] = -0.5 * wz
    out[2, 2] = 0.0
    out[2, 3] = 0.5 * wx
    out[3, 0] = 0.5 * wz
    out[3, 1] = 0.5 * wy
    out[3, 2] = -0.5 * wx
    out[3, 3] = 0.0


@njit(cache=True)
def xi_matrix(q, out):
    """Ξ(q) of Th. Eq 28 (4×3) = −∂(q ⊗ (0, ω))/∂ω."""
    out[0, 0] = q[1]
    out[0, 1] = q[2]
    out[0, 2] = q[3]
    out[1, 0] = -q[0]
    out[1, 1] = q[3]
    out[1, 2] = -q[2]
    out[2, 0] = -q[3]
    out[2, 1] = -q[0]
    out[2, 2] = q[1]
    out[3, 0] = q[2]
    out[3, 1] = -q[1]
    out[3, 2] = -q[0]


@njit(cache=True)
def f_taylor(x, y_gyr, dt, ca, cd, out):
    """Process model with the 2nd-order Taylor exponential of Th. Eq 38 (the form Eq 39-40 linearise):
    q⁺ = (I + ΩT + ½Ω²T²) q with ω = y_G − b; a ← c_a a; b ← b; d ← c_d d. (No normalisation.)"""
    wx, wy, wz = y_gyr[0] - x[7], y_gyr[1] - x[8], y_gyr[2] - x[9]
    om = np.empty((4, 4))
    omega_matrix(wx, wy, wz, om)
    c = 1.0 - (wx * wx + wy * wy + wz * wz) * dt * dt / 8.0          # Ω² = −|ω|²/4 I
    for r in range(4):
        s = c * x[r]
        for k in range(4):
            s += dt * om[r, k] * x[k]
        out[r] = s
    for r in range(3):
        out[4 + r] = ca * x[4 + r]
        out[7 + r] = x[7 + r]
        out[10 + r] = cd * x[10 + r]


@njit(cache=True)
def process_jac(x, y_gyr, dt, ca, cd, exact, out):
    """A_k = ∂f/∂x (13×13), Th. Eq 39-40: q-block exp(ΩT) (exact, or 2nd-order Taylor if not ``exact``),
    F_bk = (T²/4) q ωᵀ + (T/2) Ξ(q) in the q-b block, c_a I, I, c_d I on the diagonal."""
    for r in range(NX):
        for k in range(NX):
            out[r, k] = 0.0
    wx, wy, wz = y_gyr[0] - x[7], y_gyr[1] - x[8], y_gyr[2] - x[9]
    om = np.empty((4, 4))
    omega_matrix(wx, wy, wz, om)
    nw = np.sqrt(wx * wx + wy * wy + wz * wz)
    if exact:
        ang = 0.5 * nw * dt
        cth = np.cos(ang)
        sth = 2.0 * np.sin(ang) / nw if nw > 1e-15 else dt
    else:
        cth = 1.0 - nw * nw * dt * dt / 8.0
        sth = dt
    for r in range(4):
        for k in range(4):
            out[r, k] = sth * om[r, k]
        out[r, r] += cth
    xi = np.empty((4, 3))
    xi_matrix(x, xi)
    w = (wx, wy, wz)
    for r in range(4):
        for k in range(3):
            out[r, 7 + k] = dt * dt / 4.0 * x[r] * w[k] + dt / 2.0 * xi[r, k]
    for r in range(3):
        out[4 + r, 4 + r] = ca
        out[7 + r, 7 + r] = 1.0
        out[10 + r, 10 + r] = cd


@njit(cache=True)
def _fill_A_q(x, wx, wy, wz, dt, A, xi):
    """Rows 0-3 of A_k in place (columns 0-3: exact exp(Ω T); 7-9: F_bk) and Ξ(q) into xi; no allocation.
    Same numbers as :func:`process_jac` with ``exact=True``; rows 4-12 are constant (set once)."""
    nw = np.sqrt(wx * wx + wy * wy + wz * wz)
    ang = 0.5 * nw * dt
    c = np.cos(ang)
    k = 2.0 * np.sin(ang) / nw if nw > 1e-15 else dt
    hx, hy, hz = 0.5 * k * wx, 0.5 * k * wy, 0.5 * k * wz
    A[0, 0], A[0, 1], A[0, 2], A[0, 3] = c, -hx, -hy, -hz
    A[1, 0], A[1, 1], A[1, 2], A[1, 3] = hx, c, hz, -hy
    A[2, 0], A[2, 1], A[2, 2], A[2, 3] = hy, -hz, c, hx
    A[3, 0], A[3, 1], A[3, 2], A[3, 3] = hz, hy, -hx, c
    xi_matrix(x, xi)
    a = dt * dt / 4.0
    b = dt / 2.0
    for r in range(4):
        A[r, 7] = a * x[r] * wx + b * xi[r, 0]
        A[r, 8] = a * x[r] * wy + b * xi[r, 1]
        A[r, 9] = a * x[r] * wz + b * xi[r, 2]


# ---------------------------------------------------------------- small dense linear algebra

@njit(cache=True)
def _cholesky(a, n):
    """In-place lower Cholesky of the leading n×n block of a; False if not positive definite."""
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= a[j, k] * a[j, k]
        if not (s > 0.0):
            return False
        d = np.sqrt(s)
        a[j, j] = d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / d
    return True


@njit(cache=True)
def _chol_solve_rows(L, n, B, m):
    """Solve (L Lᵀ) X = B in place for B (n × m) (first n rows, first m columns); row operations so the
    inner loop runs over contiguous columns."""
    for i in range(n):
        for k in range(i):
            lik = L[i, k]
            for c in range(m):
                B[i, c] -= lik * B[k, c]
        d = 1.0 / L[i, i]
        for c in range(m):
            B[i, c] *= d
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            lki = L[k, i]
            for c in range(m):
                B[i, c] -= lki * B[k, c]
        d = 1.0 / L[i, i]
        for c in range(m):
            B[i, c] *= d


@njit(cache=True)
def _predict_cov(P, A, qsel_cols, Qd, Qq, T1, out):
    """out = A P Aᵀ + Q exploiting A's structure: rows 0-3 dense over columns 0-3 and 7-9 (qsel_cols),
    other rows diagonal. Qq (4×4) is the quaternion block of Q, Qd (13,) the diagonal of the rest."""
    nc = qsel_cols.shape[0]
    # T1 = A P
    for r in range(4):
        for c in range(NX):
            s = 0.0
            for t in range(nc):
                k = qsel_cols[t]
                s += A[r, k] * P[k, c]
            T1[r, c] = s
    for r in range(4, NX):
        a = A[r, r]
        for c in range(NX):
            T1[r, c] = a * P[r, c]
    # out = T1 Aᵀ
    for r in range(NX):
        for c in range(4):
            s = 0.0
            for t in range(nc):
                k = qsel_cols[t]
                s += T1[r, k] * A[c, k]
            out[r, c] = s
        for c in range(4, NX):
            out[r, c] = T1[r, c] * A[c, c]
    for r in range(4):
        for c in range(4):
            out[r, c] += Qq[r, c]
    for r in range(4, NX):
        out[r, r] += Qd[r]
    for r in range(NX):                                  # symmetrise
        for c in range(r + 1, NX):
            v = 0.5 * (out[r, c] + out[c, r])
            out[r, c] = v
            out[c, r] = v


@njit(cache=True)
def _level(delta, thr):
    """Switching level: 0 when delta < thr[0], 1 when thr[0] ≤ delta < thr[1], ... (Th. Eq 23, 48-50)."""
    lv = 0
    for j in range(thr.shape[0]):
        if delta >= thr[j]:
            lv = j + 1
    return lv


@njit(cache=True)
def _propagate_mean(x, wx, wy, wz, dt, ca, cd):
    """Exact quaternion exponential for the mean (spec A15), then AR(1) decays."""
    nw = np.sqrt(wx * wx + wy * wy + wz * wz)
    ang = 0.5 * nw * dt
    c = np.cos(ang)
    s = np.sin(ang) / nw if nw > 1e-15 else 0.5 * dt
    d1, d2, d3 = wx * s, wy * s, wz * s
    q0, q1, q2, q3 = x[0], x[1], x[2], x[3]
    x[0] = q0 * c - q1 * d1 - q2 * d2 - q3 * d3
    x[1] = q0 * d1 + q1 * c + q2 * d3 - q3 * d2
    x[2] = q0 * d2 - q1 * d3 + q2 * c + q3 * d1
    x[3] = q0 * d3 + q1 * d2 - q2 * d1 + q3 * c
    for r in range(3):
        x[4 + r] *= ca
        x[10 + r] *= cd


@njit(cache=True)
def _normalise_q(x):
    n = np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
    x[0] /= n
    x[1] /= n
    x[2] /= n
    x[3] /= n


@njit(cache=True)
def _project_norm(x, P, T1):
    """Covariance through the normalisation q ← q/|q| (Jacobian N = I − q qᵀ at |q| = 1): the variance along
    q, which no measurement or process model constrains, is removed. Off by default (PROJECT_NORM)."""
    for c in range(NX):                                   # T1[0:4] = N P[0:4, :]
        v = x[0] * P[0, c] + x[1] * P[1, c] + x[2] * P[2, c] + x[3] * P[3, c]
        for r in range(4):
            T1[r, c] = P[r, c] - x[r] * v
    for r in range(4):
        for c in range(NX):
            P[r, c] = T1[r, c]
    for r in range(NX):                                   # P[:, 0:4] = P[:, 0:4] Nᵀ
        v = x[0] * P[r, 0] + x[1] * P[r, 1] + x[2] * P[r, 2] + x[3] * P[r, 3]
        for c in range(4):
            P[r, c] -= v * x[c]
    for r in range(NX):
        for c in range(r + 1, NX):
            v = 0.5 * (P[r, c] + P[c, r])
            P[r, c] = v
            P[c, r] = v


@njit(cache=True)
def _write_out(i, x, out_q, out_aux):
    s = 1.0 if x[0] >= 0.0 else -1.0
    for r in range(4):
        out_q[i, r] = s * x[r]
    for r in range(9):
        out_aux[i, r] = x[4 + r]


# ---------------------------------------------------------------- robust EKF (Nazarahari 2021)

@njit(cache=True)
def ekf_series(gyr, acc, mag, use_mag, dt, coef, sg_lv, sg_th, sa_lv, sa_th, sm_lv, sm_th, mref, s,
               out_q, out_aux, out_lv):
    """Robust EKF over (N, 3) arrays (acc in g, mag in field-norm units) from kernel state ``s`` (in place).

    coef = (c_a, c_d, q_a, q_b, q_d, gamma_inv2): AR(1) decays per sample, process-noise variances per
    sample of a, b, d, and γ⁻² (0 = plain EKF). *_lv / *_th: switching levels and thresholds of σ_G
    (on |y_G|), σ_A (on Δ_A) and σ_M (on Δ_M). out_aux (N, 9) = [a, b, d]; out_lv (N, 3) int levels.
    """
    ca, cd, qa, qb, qd, gi2 = coef[0], coef[1], coef[2], coef[3], coef[4], coef[5]
    x = s[:NX]
    P = s[NX:NX + NX * NX].reshape(NX, NX)
    A = np.zeros((NX, NX))
    T1 = np.empty((NX, NX))
    Pn = np.empty((NX, NX))
    Qq = np.empty((4, 4))
    Qd = np.zeros(NX)
    xi = np.empty((4, 3))
    Hq = np.empty((6, 4))
    hx = np.empty(6)
    PHt = np.empty((NX, 6))
    S = np.empty((6, 6))
    K = np.empty((NX, 6))
    nu = np.empty(6)
    yg = np.empty(3)
    B = np.empty((NX, NX))
    qcols = np.array([0, 1, 2, 3, 7, 8, 9])
    for r in range(3):
        Qd[4 + r] = qa
        Qd[7 + r] = qb
        Qd[10 + r] = qd
        A[4 + r, 4 + r] = ca
        A[7 + r, 7 + r] = 1.0
        A[10 + r, 10 + r] = cd
    for i in range(gyr.shape[0]):
        gx, gy, gz = gyr[i, 0], gyr[i, 1], gyr[i, 2]
        if not (gx == gx and gy == gy and gz == gz):
            gx, gy, gz = x[7], x[8], x[9]                       # NaN gyro: hold the attitude
        yg[0], yg[1], yg[2] = gx, gy, gz
        lg = _level(np.sqrt(gx * gx + gy * gy + gz * gz), sg_th)
        sig_g = sg_lv[lg]
        # --- predict (Th. Eq 26, 28, 39-40)
        _fill_A_q(x, gx - x[7], gy - x[8], gz - x[9], dt, A, xi)
        cq = dt * dt / 4.0 * sig_g * sig_g
        for r in range(4):
            for c in range(4):
                Qq[r, c] = cq * (xi[r, 0] * xi[c, 0] + xi[r, 1] * xi[c, 1] + xi[r, 2] * xi[c, 2])
        _propagate_mean(x, gx - x[7], gy - x[8], gz - x[9], dt, ca, cd)
        _predict_cov(P, A, qcols, Qd, Qq, T1, Pn)
        # --- update (Th. Eqs 41-45, 47)
        ax, ay, az = acc[i, 0], acc[i, 1], acc[i, 2]
        la, lm = 0, 0
        nm = 0
        if ax == ax and ay == ay and az == az:
            nm = 3
            la = _level(abs(np.sqrt(ax * ax + ay * ay + az * az) - 1.0), sa_th)
            if use_mag:
                mx, my, mz = mag[i, 0], mag[i, 1], mag[i, 2]
                if mx == mx and my == my and mz == mz:
                    nm = 6
                    lm = _level(abs(np.sqrt(mx * mx + my * my + mz * mz) - 1.0), sm_th)
        out_lv[i, 0] = lg
        out_lv[i, 1] = la
        out_lv[i, 2] = lm
        if nm > 0:
            h_model(x, mref, hx)
            h_jac_q(x, mref, Hq)
            nu[0], nu[1], nu[2] = ax - hx[0], ay - hx[1], az - hx[2]
            if nm == 6:
                nu[3], nu[4], nu[5] = mag[i, 0] - hx[3], mag[i, 1] - hx[4], mag[i, 2] - hx[5]
            # PHt = P Hᵀ: H row j = [Hq[j], I (a cols 4-6 for j<3, d cols 10-12 for j>=3)]
            for r in range(NX):
                for j in range(nm):
                    o = 4 + j if j < 3 else 7 + j
                    PHt[r, j] = Pn[r, 0] * Hq[j, 0] + Pn[r, 1] * Hq[j, 1] + Pn[r, 2] * Hq[j, 2] \
                        + Pn[r, 3] * Hq[j, 3] + Pn[r, o]
            ra = sa_lv[la] * sa_lv[la]
            rm = sm_lv[lm] * sm_lv[lm]
            for j in range(nm):
                o = 4 + j if j < 3 else 7 + j
                for c in range(nm):
                    S[j, c] = Hq[j, 0] * PHt[0, c] + Hq[j, 1] * PHt[1, c] + Hq[j, 2] * PHt[2, c] \
                        + Hq[j, 3] * PHt[3, c] + PHt[o, c]
                S[j, j] += ra if j < 3 else rm
            if _cholesky(S, nm):
                # K = PHt S⁻¹  ->  Kᵀ = S⁻¹ PHtᵀ
                for r in range(NX):
                    for j in range(nm):
                        K[r, j] = PHt[r, j]
                # solve row-wise: for each r, solve S k = PHt[r]
                for r in range(NX):
                    for j in range(nm):
                        v = K[r, j]
                        for k in range(j):
                            v -= S[j, k] * K[r, k]
                        K[r, j] = v / S[j, j]
                    for j in range(nm - 1, -1, -1):
                        v = K[r, j]
                        for k in range(j + 1, nm):
                            v -= S[k, j] * K[r, k]
                        K[r, j] = v / S[j, j]
                for r in range(NX):
                    v = 0.0
                    for j in range(nm):
                        v += K[r, j] * nu[j]
                    x[r] += v
                # plain EKF covariance: P = Pn − K PHtᵀ
                for r in range(NX):
                    for c in range(r, NX):
                        v = Pn[r, c]
                        for j in range(nm):
                            v -= K[r, j] * PHt[c, j]
                        Pn[r, c] = v
                        Pn[c, r] = v
                if gi2 > 0.0:
                    # robust (H∞) update, information form (spec §5.3, A18):
                    # P⁺ = (P_ekf⁻¹ − γ⁻² I)⁻¹ = (I − γ⁻² P_ekf)⁻¹ P_ekf
                    for r in range(NX):
                        for c in range(NX):
                            B[r, c] = -gi2 * Pn[r, c]
                        B[r, r] += 1.0
                    if _cholesky(B, NX):
                        for r in range(NX):
                            for c in range(NX):
                                T1[r, c] = Pn[r, c]
                        _chol_solve_rows(B, NX, T1, NX)
                        for r in range(NX):
                            for c in range(r, NX):
                                v = 0.5 * (T1[r, c] + T1[c, r])
                                Pn[r, c] = v
                                Pn[c, r] = v
                    else:
                        s[I_FALLBACK] += 1.0
                _normalise_q(x)
                if PROJECT_NORM:
                    _project_norm(x, Pn, T1)
        for r in range(NX):
            for c in range(NX):
                P[r, c] = Pn[r, c]
        s[I_COUNT] += 1.0
        _write_out(i, x, out_q, out_aux)


# ---------------------------------------------------------------- full-state LKF (Nazarahari 2020)

@njit(cache=True)
def lkf_series(gyr, acc, mag, use_mag, dt, coef, literal, sg_lv, sg_th, sa_lv, sa_th, sm_lv, sm_th, mref, s,
               out_q, out_aux, out_lv):
    """Full-state linear KF, H = I on the "measured state" z = x̄ − μ Jᵀ(x̄) f(x̄) (Th. Eq 32, 35-37).

    literal=True: x̄ = x⁺_k (previous posterior), covariance propagated with the block-diagonal F and every
    state measured (b included, so b never changes: spec A1/A2). literal=False (default): x̄ = x⁻_{k+1},
    covariance propagated with the EKF Jacobian A_k (q–b coupling F_bk), and the b rows, which carry no
    information (z_b ≡ x̄_b), dropped from the measurement so the q innovation corrects b through P_qb.
    coef = (c_a, c_d, q_a, q_b, q_d, mu). Other arguments as :func:`ekf_series`.
    """
    ca, cd, qa, qb, qd, mu = coef[0], coef[1], coef[2], coef[3], coef[4], coef[5]
    x = s[:NX]
    P = s[NX:NX + NX * NX].reshape(NX, NX)
    A = np.zeros((NX, NX))
    T1 = np.empty((NX, NX))
    Pn = np.empty((NX, NX))
    Qq = np.empty((4, 4))
    Qd = np.zeros(NX)
    xi = np.empty((4, 3))
    Hq = np.empty((6, 4))
    hx = np.empty(6)
    f = np.empty(6)
    z = np.empty(NX)
    xb = np.empty(NX)
    R = np.zeros((NX, NX))
    S = np.empty((NX, NX))
    Kt = np.empty((NX, NX))
    yg = np.empty(3)
    obs = np.empty(NX, dtype=np.int64)
    qcols = np.array([0, 1, 2, 3, 7, 8, 9])
    for r in range(3):
        Qd[4 + r] = qa
        Qd[7 + r] = qb
        Qd[10 + r] = qd
    for i in range(gyr.shape[0]):
        gx, gy, gz = gyr[i, 0], gyr[i, 1], gyr[i, 2]
        if not (gx == gx and gy == gy and gz == gz):
            gx, gy, gz = x[7], x[8], x[9]
        yg[0], yg[1], yg[2] = gx, gy, gz
        lg = _level(np.sqrt(gx * gx + gy * gy + gz * gz), sg_th)
        sig_g = sg_lv[lg]
        for r in range(NX):
            xb[r] = x[r]                                    # x⁺_k, the literal measurement base
        process_jac(x, yg, dt, ca, cd, True, A)
        if literal:
            for r in range(4):
                for k in range(3):
                    A[r, 7 + k] = 0.0                       # F of Th. Eq 26: block diagonal
        xi_matrix(x, xi)
        cq = dt * dt / 4.0 * sig_g * sig_g
        for r in range(4):
            for c in range(4):
                Qq[r, c] = cq * (xi[r, 0] * xi[c, 0] + xi[r, 1] * xi[c, 1] + xi[r, 2] * xi[c, 2])
        _propagate_mean(x, gx - x[7], gy - x[8], gz - x[9], dt, ca, cd)
        _predict_cov(P, A, qcols, Qd, Qq, T1, Pn)
        if not literal:
            for r in range(NX):
                xb[r] = x[r]                                # x⁻_{k+1} (spec A2 default)
        ax, ay, az = acc[i, 0], acc[i, 1], acc[i, 2]
        la, lm = 0, 0
        nm = 0
        if ax == ax and ay == ay and az == az:
            nm = 3
            la = _level(abs(np.sqrt(ax * ax + ay * ay + az * az) - 1.0), sa_th)
            if use_mag:
                mx, my, mz = mag[i, 0], mag[i, 1], mag[i, 2]
                if mx == mx and my == my and mz == mz:
                    nm = 6
                    lm = _level(abs(np.sqrt(mx * mx + my * my + mz * mz) - 1.0), sm_th)
        out_lv[i, 0] = lg
        out_lv[i, 1] = la
        out_lv[i, 2] = lm
        if nm > 0:
            h_model(xb, mref, hx)
            h_jac_q(xb, mref, Hq)
            f[0], f[1], f[2] = hx[0] - ax, hx[1] - ay, hx[2] - az
            if nm == 6:
                f[3], f[4], f[5] = hx[3] - mag[i, 0], hx[4] - mag[i, 1], hx[5] - mag[i, 2]
            # z = x̄ − μ Jᵀ f (Th. Eq 32)
            for r in range(NX):
                z[r] = xb[r]
            for r in range(4):
                v = 0.0
                for j in range(nm):
                    v += Hq[j, r] * f[j]
                z[r] -= mu * v
            for j in range(3):
                z[4 + j] -= mu * f[j]
            if nm == 6:
                for j in range(3):
                    z[10 + j] -= mu * f[3 + j]
            # R = μ² Jᵀ Σ J (Th. Eq 35-37)
            ra = mu * mu * sa_lv[la] * sa_lv[la]
            rm = mu * mu * sm_lv[lm] * sm_lv[lm] if nm == 6 else 0.0
            for r in range(NX):
                for c in range(NX):
                    R[r, c] = 0.0
            for r in range(4):
                for c in range(4):
                    v = 0.0
                    for j in range(3):
                        v += ra * Hq[j, r] * Hq[j, c]
                    if nm == 6:
                        for j in range(3, 6):
                            v += rm * Hq[j, r] * Hq[j, c]
                    R[r, c] = v
                for j in range(3):
                    R[r, 4 + j] = ra * Hq[j, r]
                    R[4 + j, r] = ra * Hq[j, r]
                    if nm == 6:
                        R[r, 10 + j] = rm * Hq[3 + j, r]
                        R[10 + j, r] = rm * Hq[3 + j, r]
            for j in range(3):
                R[4 + j, 4 + j] = ra
                R[10 + j, 10 + j] = rm
            # observed components
            no = 0
            for r in range(NX):
                if literal or (r < 7) or (r >= 10 and nm == 6):
                    obs[no] = r
                    no += 1
            for u in range(no):
                for v2 in range(no):
                    S[u, v2] = Pn[obs[u], obs[v2]] + R[obs[u], obs[v2]]
            if _cholesky(S, no):
                # Kᵀ = S⁻¹ P[obs, :]
                for u in range(no):
                    for c in range(NX):
                        Kt[u, c] = Pn[obs[u], c]
                _chol_solve_rows(S, no, Kt, NX)
                for r in range(NX):
                    v = 0.0
                    for u in range(no):
                        v += Kt[u, r] * (z[obs[u]] - x[obs[u]])
                    T1[0, r] = v
                for r in range(NX):
                    x[r] += T1[0, r]
                # P = Pn − K P[obs, :]   (K = Ktᵀ)
                for r in range(NX):
                    for c in range(r, NX):
                        v = Pn[r, c]
                        for u in range(no):
                            v -= Kt[u, r] * Pn[obs[u], c]
                        T1[r, c] = v
                for r in range(NX):
                    for c in range(r, NX):
                        Pn[r, c] = T1[r, c]
                        Pn[c, r] = T1[r, c]
                _normalise_q(x)
                if PROJECT_NORM:
                    _project_norm(x, Pn, T1)
        for r in range(NX):
            for c in range(NX):
                P[r, c] = Pn[r, c]
        s[I_COUNT] += 1.0
        _write_out(i, x, out_q, out_aux)
