"""Numba kernel of the decoupled complementary filter (see :mod:`._dcf`). Arrays, floats and ints only.

State vector layout (float64, length ``STATE_LEN``); all quaternions [w x y z]:

====  ============================================================================
0:4   q_gyr   strap-down quaternion, sensor -> quasi-inertial frame I
4:8   q_acc   inclination correction, I -> E6 (6D earth frame, heading arbitrary)
8     delta   heading offset about ENU z, E6 -> E (rad)
9:12  acc_lp  low-passed accelerometer in frame I (m/s²)
12:15 gyr_lp  low-passed raw gyro (rad/s), rest detector and rest bias
15:18 acc_lp2 low-passed raw accelerometer (m/s²), rest detector
18:21 bias    gyro bias estimate, sensor frame (rad/s)
21    n_acc   number of accelerometer samples used so far (initial averaging)
22    rest_t  time the rest condition has held (s)
23    n_mag   number of magnetometer updates so far
24    mag_norm_ref  reference field norm (µT, 0 = unknown)
25    mag_dip_ref   reference dip angle (rad)
26    mag_rej_t     time the current magnetic rejection has lasted (s)
27    n_samples     samples processed
28    rest_flag     1 when the last sample was at rest
29:35 acc biquad delay states (z1 xyz, z2 xyz), 2nd-order Butterworth in frame I
35    bias_p  variance of the rest-bias estimate per axis, (rad/s)² (< 0 = not initialised; Kalman mode)
36    mag_ok_t      time since the last rejected magnetometer sample (s)
37    head_p        variance of the heading offset delta, rad² (< 0 = not initialised; heading Kalman mode)
38    cand_norm     candidate reference field norm (µT; new-field acceptance)
39    cand_dip      candidate reference dip (rad)
40    cand_t        time (while rotating) the field has stayed with the candidate (s)
41:45 hi_theta      hard-iron model θ = (b_x, b_y, b_z, c): |m|² = 2 m·b + c, c = R² − |b|² (µT, µT²)
45:61 hi_P          its RLS covariance, 4×4 row-major (< 0 in [45] = not initialised)
61    hi_res2       low-passed squared a-priori residual of the norm model, µT²
62    hi_t          time the hard-iron model has been updated (s, while rotating)
====  ============================================================================
"""
from __future__ import annotations

import numpy as np
from numba import njit

STATE_LEN = 63


def initial_state() -> np.ndarray:
    s = np.zeros(STATE_LEN)
    s[0] = 1.0
    s[4] = 1.0
    s[35] = -1.0
    s[36] = 1e9
    s[37] = -1.0
    s[45] = -1.0
    return s


@njit(cache=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True, inline="always")
def _qrot(w, x, y, z, v0, v1, v2):
    return ((1 - 2 * (y * y + z * z)) * v0 + 2 * (x * y - w * z) * v1 + 2 * (x * z + w * y) * v2,
            2 * (x * y + w * z) * v0 + (1 - 2 * (x * x + z * z)) * v1 + 2 * (y * z - w * x) * v2,
            2 * (x * z - w * y) * v0 + 2 * (y * z + w * x) * v1 + (1 - 2 * (x * x + y * y)) * v2)


@njit(cache=True)
def dcf_series(gyr, acc, mag, use_mag, dt, coef, s, out_q, out_rest, out_magrej, out_mag):
    """Run the filter over (N, 3) arrays from state ``s`` (updated in place). ``out_mag`` (N, 3) receives the
    magnetometer sample as used (hard-iron offset removed when the fit is settled; NaN where there is none).

    coef = (k_acc, k_mag, k_rest_lp, rest_gyr_th, rest_acc_th, rest_min_s, k_bias_motion, bias_max,
            mag_norm_th, mag_dip_th, mag_rej_max_s, k_mag_ref, n_acc_init, n_mag_init,
            b0, b1, b2, a1, a2,   -- 2nd-order Butterworth low-pass (k_acc unused when b0 > 0)
            bias_p0, bias_v, bias_w_rest,   -- rest-bias Kalman filter (bias_w_rest <= 0: bias = low-pass at rest)
            mag_settle_s,   -- after a rejected magnetometer sample, accepted ones are used only after this long
            head_q0, head_kappa², head_r, inv_rate_ref²,   -- heading Kalman filter (head_r <= 0: fixed gain k_mag):
                P += (q0 + κ²|ω|²) dt per sample; a magnetometer sample has variance r (1 + |ω|²/ω_ref²) / dt
            mag_new_s, mag_new_min_gyr,   -- new-field acceptance (mag_new_s <= 0: off)
            hi_lambda, hi_min_gyr, hi_p0_b, hi_res_th2, hi_k_res, hi_min_t, hi_p_th, hi_b_min²)   -- online hard-iron (hi_lambda <= 0: off)
    """
    k_acc = coef[0]
    k_mag = coef[1]
    k_rl = coef[2]
    rest_g = coef[3]
    rest_a = coef[4]
    rest_min = coef[5]
    k_bm = coef[6]
    bmax = coef[7]
    m_nth = coef[8]
    m_dth = coef[9]
    m_rmax = coef[10]
    k_mref = coef[11]
    n_ainit = coef[12]
    n_minit = coef[13]
    b0, b1, b2, a1, a2 = coef[14], coef[15], coef[16], coef[17], coef[18]
    bp0, bv, bw = coef[19], coef[20], coef[21]
    m_settle = coef[22]
    hq0, hk2, hr, irr2 = coef[23], coef[24], coef[25], coef[26]
    m_new, m_new_g = coef[27], coef[28]
    hi_lam, hi_g, hi_p0, hi_rth2, hi_kr, hi_tmin, hi_pth = coef[29], coef[30], coef[31], coef[32], coef[33], coef[34], coef[35]
    hi_bmin2 = coef[36]
    phi = np.empty(4)
    pphi = np.empty(4)
    if s[37] < 0.0:
        s[37] = 2.5                                   # (≈ 90°)²: the first samples set the heading
    if s[35] < 0.0:
        s[35] = bp0
    qg0, qg1, qg2, qg3 = s[0], s[1], s[2], s[3]
    qa0, qa1, qa2, qa3 = s[4], s[5], s[6], s[7]
    delta = s[8]
    for i in range(gyr.shape[0]):
        gx, gy, gz = gyr[i, 0], gyr[i, 1], gyr[i, 2]
        ax, ay, az = acc[i, 0], acc[i, 1], acc[i, 2]
        gyr_ok = gx == gx and gy == gy and gz == gz
        acc_ok = ax == ax and ay == ay and az == az
        # ---- rest detection and rest bias (low-pass deviations, as VQF) ----
        rest = False
        if gyr_ok and acc_ok:
            if s[27] == 0:
                s[12], s[13], s[14] = gx, gy, gz
                s[15], s[16], s[17] = ax, ay, az
            s[12] += k_rl * (gx - s[12])
            s[13] += k_rl * (gy - s[13])
            s[14] += k_rl * (gz - s[14])
            s[15] += k_rl * (ax - s[15])
            s[16] += k_rl * (ay - s[16])
            s[17] += k_rl * (az - s[17])
            dg = (gx - s[12]) ** 2 + (gy - s[13]) ** 2 + (gz - s[14]) ** 2
            da = (ax - s[15]) ** 2 + (ay - s[16]) ** 2 + (az - s[17]) ** 2
            gl = s[12] ** 2 + s[13] ** 2 + s[14] ** 2
            if dg < rest_g * rest_g and da < rest_a * rest_a and gl < bmax * bmax * 4.0:
                s[22] += dt
            else:
                s[22] = 0.0
            if bw > 0.0 and s[35] < bp0:           # random-walk bias: the variance grows in motion and at rest
                s[35] += bv
            if s[22] >= rest_min:
                rest = True
                if bw > 0.0:                         # Kalman update towards the low-passed gyro (isotropic P)
                    kk = s[35] / (s[35] + bw)
                    for j in range(3):
                        s[18 + j] += kk * (s[12 + j] - s[18 + j])
                        if s[18 + j] > bmax:
                            s[18 + j] = bmax
                        elif s[18 + j] < -bmax:
                            s[18 + j] = -bmax
                    s[35] -= kk * s[35]
                else:
                    s[18], s[19], s[20] = s[12], s[13], s[14]
        else:
            s[22] = 0.0
        out_rest[i] = rest
        # ---- strap-down integration with bias-corrected rate ----
        w2 = 0.0
        if gyr_ok:
            wx, wy, wz = gx - s[18], gy - s[19], gz - s[20]
            w2 = wx * wx + wy * wy + wz * wz
            n = np.sqrt(w2)
            if n > 1e-15:
                sn = np.sin(0.5 * n * dt) / n
                c = np.cos(0.5 * n * dt)
                qg0, qg1, qg2, qg3 = _qmul(qg0, qg1, qg2, qg3, c, wx * sn, wy * sn, wz * sn)
                nn = 1.0 / np.sqrt(qg0 * qg0 + qg1 * qg1 + qg2 * qg2 + qg3 * qg3)
                qg0, qg1, qg2, qg3 = qg0 * nn, qg1 * nn, qg2 * nn, qg3 * nn
        # ---- inclination: low-pass acc in frame I, level it completely (VQF basic scheme) ----
        if acc_ok:
            aix, aiy, aiz = _qrot(qg0, qg1, qg2, qg3, ax, ay, az)
            s[21] += 1.0
            if s[21] < n_ainit or b0 <= 0.0:
                k = k_acc
                if s[21] < n_ainit:
                    k = 1.0 / s[21]                  # running mean during the first tau_acc
                s[9] += k * (aix - s[9])
                s[10] += k * (aiy - s[10])
                s[11] += k * (aiz - s[11])
                if s[21] >= n_ainit - 1.0:           # hand over to the biquad in steady state
                    for j in range(3):
                        s[32 + j] = s[9 + j] * (b2 - a2)
                        s[29 + j] = s[9 + j] * (1.0 - b0)
            else:
                for j in range(3):
                    x = aix if j == 0 else (aiy if j == 1 else aiz)
                    y = b0 * x + s[29 + j]
                    s[29 + j] = b1 * x - a1 * y + s[32 + j]
                    s[32 + j] = b2 * x - a2 * y
                    s[9 + j] = y
            ex, ey, ez = _qrot(qa0, qa1, qa2, qa3, s[9], s[10], s[11])
            en = np.sqrt(ex * ex + ey * ey + ez * ez)
            if en > 1e-9:
                ex, ey, ez = ex / en, ey / en, ez / en
                cw = np.sqrt(max(0.0, (ez + 1.0) * 0.5))
                if cw > 1e-6:
                    c0, c1, c2 = cw, 0.5 * ey / cw, -0.5 * ex / cw
                else:
                    c0, c1, c2 = 0.0, 1.0, 0.0
                qa0, qa1, qa2, qa3 = _qmul(c0, c1, c2, 0.0, qa0, qa1, qa2, qa3)
                nn = 1.0 / np.sqrt(qa0 * qa0 + qa1 * qa1 + qa2 * qa2 + qa3 * qa3)
                qa0, qa1, qa2, qa3 = qa0 * nn, qa1 * nn, qa2 * nn, qa3 * nn
                # motion bias: the correction rotation (earth) seen in the sensor frame feeds the bias
                if k_bm > 0.0 and not rest and s[21] >= n_ainit:
                    q0, q1, q2, q3 = _qmul(qa0, qa1, qa2, qa3, qg0, qg1, qg2, qg3)
                    # correction rotation vector (earth) ≈ 2*(c1, c2, 0); into sensor frame by q6^T
                    rx, ry, rz = _qrot(q0, -q1, -q2, -q3, 2.0 * c1, 2.0 * c2, 0.0)
                    s[18] -= k_bm * rx / dt
                    s[19] -= k_bm * ry / dt
                    s[20] -= k_bm * rz / dt
                    for j in range(18, 21):
                        if s[j] > bmax:
                            s[j] = bmax
                        elif s[j] < -bmax:
                            s[j] = -bmax
        # 6D quaternion
        q0, q1, q2, q3 = _qmul(qa0, qa1, qa2, qa3, qg0, qg1, qg2, qg3)
        rej = False
        # ---- heading from the magnetometer with disturbance rejection (norm + dip) ----
        if hr > 0.0:
            s[37] += (hq0 + hk2 * w2) * dt
        if use_mag:
            mx, my, mz = mag[i, 0], mag[i, 1], mag[i, 2]
            if mx == mx and my == my and mz == mz:
                if hi_lam > 0.0:
                    mx, my, mz = _hard_iron(s, mx, my, mz, w2, dt, hi_lam, hi_g, hi_p0, hi_rth2, hi_kr, hi_tmin,
                                            hi_pth, hi_bmin2, phi, pphi)
            out_mag[i, 0], out_mag[i, 1], out_mag[i, 2] = mx, my, mz
            if mx == mx and my == my and mz == mz:
                hx, hy, hz = _qrot(q0, q1, q2, q3, mx, my, mz)
                nm = np.sqrt(hx * hx + hy * hy + hz * hz)
                if nm > 1e-9:
                    dip = np.arcsin(max(-1.0, min(1.0, hz / nm)))
                    if s[24] == 0.0:
                        s[24] = nm
                        s[25] = dip
                    dev_n = abs(nm - s[24]) / s[24]
                    dev_d = abs(dip - s[25])
                    if dev_n > m_nth or dev_d > m_dth:
                        rej = True
                        s[36] = 0.0
                        s[26] += dt
                        if s[26] > m_rmax:               # a lasting new field: accept it as reference
                            s[24] = nm
                            s[25] = dip
                            s[26] = 0.0
                            rej = False
                    else:
                        s[26] = 0.0
                        s[36] += dt
                        if s[36] < m_settle:             # the edge of a disturbance: not used yet
                            rej = True
                        else:
                            s[24] += k_mref * (nm - s[24])
                            s[25] += k_mref * (dip - s[25])
                    if m_new > 0.0:                      # new-field acceptance (VQF): a field that stays consistent
                        if s[38] > 0.0 and abs(nm - s[38]) < m_nth * s[38] and abs(dip - s[39]) < m_dth:
                            if w2 >= m_new_g * m_new_g:  # ... while the sensor rotates is a clean field
                                s[40] += dt
                            s[38] += k_mref * (nm - s[38])
                            s[39] += k_mref * (dip - s[39])
                            if rej and s[40] >= m_new:
                                s[24] = s[38]
                                s[25] = s[39]
                                s[26] = 0.0
                                s[36] = m_settle
                                rej = False
                        else:
                            s[38] = nm
                            s[39] = dip
                            s[40] = 0.0
                    if not rej:
                        ang = np.arctan2(hx, hy) - delta
                        ang = (ang + np.pi) % (2.0 * np.pi) - np.pi
                        s[23] += 1.0
                        if hr > 0.0:
                            rr = hr * (1.0 + w2 * irr2) / dt
                            km = s[37] / (s[37] + rr)
                            s[37] -= km * s[37]
                        else:
                            km = k_mag
                            if s[23] < n_minit:
                                km = max(k_mag, 1.0 / s[23])
                        delta += km * ang
                        delta = (delta + np.pi) % (2.0 * np.pi) - np.pi
        out_magrej[i] = rej
        cd, sd = np.cos(0.5 * delta), np.sin(0.5 * delta)
        o0, o1, o2, o3 = _qmul(cd, 0.0, 0.0, sd, q0, q1, q2, q3)
        if o0 < 0.0:
            o0, o1, o2, o3 = -o0, -o1, -o2, -o3
        out_q[i, 0] = o0
        out_q[i, 1] = o1
        out_q[i, 2] = o2
        out_q[i, 3] = o3
        s[27] += 1.0
        s[28] = 1.0 if rest else 0.0
    s[0], s[1], s[2], s[3] = qg0, qg1, qg2, qg3
    s[4], s[5], s[6], s[7] = qa0, qa1, qa2, qa3
    s[8] = delta


@njit(cache=True)
def _hard_iron(s, mx, my, mz, w2, dt, lam, min_g, p0_b, res_th2, k_res, t_min, p_th, b_min2, phi, pphi):
    """Online hard-iron offset b (sensor frame, µT) of a magnet that moves with the sensor, and the corrected field.

    Model (sphere fit, linear in θ = (b, c)): |m|² = 2 m·b + c with c = R² − |b|² (Vasconcelos et al. 2011, IEEE
    TIM 60(2):370, eq. 9-10, its linear least-squares form), estimated by recursive least squares with forgetting
    factor λ (Ljung 1999 §11.2), updated only while the sensor rotates faster than ``min_g`` rad/s (at rest the
    model is not observable). The offset is removed only once the model has been updated ``t_min`` s, its offset
    variance is below ``p_th`` µT² on every axis and the low-passed a-priori residual of the norm model is below
    ``√res_th2`` µT and the offset exceeds ``√b_min2`` µT (below that it is a calibration residual the fit cannot tell
    from noise) (a field that does not move with the sensor, e.g. a magnet on the table, leaves a large residual:
    then the raw field goes on to the norm/dip rejection unchanged)."""
    if s[45] < 0.0:                                  # initialise: no offset, c from the first sample
        for k in range(16):
            s[45 + k] = 0.0
        s[45] = p0_b
        s[50] = p0_b
        s[55] = p0_b
        s[60] = p0_b * (4.0 * (mx * mx + my * my + mz * mz)) ** 2 / max(mx * mx + my * my + mz * mz, 1e-9)
        s[41], s[42], s[43] = 0.0, 0.0, 0.0
        s[44] = mx * mx + my * my + mz * mz
        s[61] = 1e9
        s[62] = 0.0
    y = mx * mx + my * my + mz * mz
    wt = 1.0 / (2.0 * np.sqrt(y) + 1e-9)              # rows weighted so that the residual is a norm error in µT
    phi[0], phi[1], phi[2], phi[3] = 2.0 * mx * wt, 2.0 * my * wt, 2.0 * mz * wt, wt
    e = (y - (2.0 * mx * s[41] + 2.0 * my * s[42] + 2.0 * mz * s[43] + s[44])) * wt
    if w2 >= min_g * min_g:
        den = lam
        for r in range(4):
            acc = 0.0
            for c in range(4):
                acc += s[45 + 4 * r + c] * phi[c]
            pphi[r] = acc
            den += phi[r] * acc
        for r in range(4):
            s[41 + r] += pphi[r] / den * e
        for r in range(4):
            for c in range(4):
                s[45 + 4 * r + c] = (s[45 + 4 * r + c] - pphi[r] * pphi[c] / den) / lam
        for r in range(3):                            # bounded covariance: no wind-up in unexcited directions
            if s[45 + 5 * r] > p0_b:
                s[45 + 5 * r] = p0_b
        s[62] += dt
        if s[61] > 1e8:
            s[61] = e * e
        s[61] += k_res * (e * e - s[61])
        if s[61] > 2.25 * res_th2 and s[45] + s[50] + s[55] < 0.03 * p0_b:
            # the model stopped fitting (a magnet was attached or moved): covariance reset (Goodwin & Sin 1984
            # §3.7), so the fit re-converges within seconds of rotation instead of the forgetting time
            for k in range(16):
                s[45 + k] = 0.0
            s[45] = p0_b
            s[50] = p0_b
            s[55] = p0_b
            s[60] = p0_b * 16.0 * y
            s[62] = 0.0
    if (s[62] >= t_min and s[61] < res_th2 and s[45] < p_th and s[50] < p_th and s[55] < p_th
            and s[41] * s[41] + s[42] * s[42] + s[43] * s[43] > b_min2):
        return mx - s[41], my - s[42], mz - s[43]
    return mx, my, mz


@njit(cache=True)
def strapdown_series(gyr, bias, dt, out_q):
    """q_k = q_{k-1} ⊗ exp((ω_k − b_k) dt / 2) from identity (out_q[0] after the first step); NaN gyro holds."""
    q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
    for i in range(gyr.shape[0]):
        wx, wy, wz = gyr[i, 0] - bias[i, 0], gyr[i, 1] - bias[i, 1], gyr[i, 2] - bias[i, 2]
        if wx == wx and wy == wy and wz == wz:
            n = np.sqrt(wx * wx + wy * wy + wz * wz)
            if n > 1e-15:
                sn = np.sin(0.5 * n * dt) / n
                c = np.cos(0.5 * n * dt)
                q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, c, wx * sn, wy * sn, wz * sn)
                nn = 1.0 / np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
                q0, q1, q2, q3 = q0 * nn, q1 * nn, q2 * nn, q3 * nn
        out_q[i, 0] = q0
        out_q[i, 1] = q1
        out_q[i, 2] = q2
        out_q[i, 3] = q3
