"""Madgwick (2011) and Mahony (2008) filters with the thesis' 2/3-level gain switching.

Madgwick, Harrison, Vaidyanathan, ICORR 2011, doi:10.1109/ICORR.2011.5975346 — gradient descent on
``f = [R(q)ᵀ ĝ − â, R(q)ᵀ b − m̂]`` with the earth field reference ``b`` recomputed each step from
``h = q ⊗ m̂ ⊗ q*`` as ``b = (0, √(h_x² + h_y²), h_z)`` (ENU: north is +y). This is the paper's
reference field (horizontal magnitude, vertical part), not the factor-2 variant of some codes.
Mahony, Hamel, Pflimlin, IEEE TAC 53(5), 2008 — explicit complementary filter with the same
reference vectors, proportional gain k_p and integral (bias) gain k_i.
Gain switching: Nazarahari 2021 ch. 4 (spec/thesis_orientation.md §4.3-4.4): the level is chosen by
``Δ_A = | ‖a‖ − g | / g`` against thresholds ``s_acc_g`` (strict ``<``, Th. Eq 23): level 0 (the first gain)
when Δ_A < s_acc_g[0], level 1 when s_acc_g[0] ≤ Δ_A < s_acc_g[1], ... (2 levels = 1 threshold, VST1;
3 levels = 2 nested thresholds, VST2).

Deviations: initial attitude = FQA of the first 0.5 s (paper: identity, slow convergence); output in ENU
(the maths is frame-free here: gravity reference +z, field reference north = +y); NaN samples hold the
attitude (gyro) or skip the correction (acc / mag). Gains were not tuned on BROAD (defaults below are
the papers' typical values); these filters are not the project default.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from estimators.orientation._dcf_kernel import _qmul, _qrot
from estimators.orientation._fqa import fqa
from estimators.orientation._types import OrientationResult
from estimators.orientation._yun_cf import _check_inputs

G = 9.81


@dataclass(frozen=True)
class MadgwickParams:
    """Madgwick filter parameters.

    beta_levels_rad_s: gradient gains β per switching level, rad/s (one value = fixed gain; paper ≈ 0.041).
    s_acc_g: thresholds on Δ_A = | ‖a‖ − g | / g, in g (len = levels − 1, increasing).
    init_s: initial attitude from the FQA of the mean of the first ``init_s`` seconds.
    """
    beta_levels_rad_s: tuple[float, ...] = (0.041,)
    s_acc_g: tuple[float, ...] = ()
    init_s: float = 0.5


@dataclass(frozen=True)
class MahonyParams:
    """Mahony filter parameters.

    kp_levels_per_s: proportional gains k_p per switching level, 1/s (one value = fixed gain; typical 1.0).
    ki_per_s2: integral (gyro bias) gain k_i, 1/s² (0 = off).
    s_acc_g: thresholds on Δ_A in g (len = levels − 1, increasing).
    init_s: initial attitude from the FQA of the mean of the first ``init_s`` seconds.
    """
    kp_levels_per_s: tuple[float, ...] = (1.0,)
    ki_per_s2: float = 0.0
    s_acc_g: tuple[float, ...] = ()
    init_s: float = 0.5


@njit(cache=True)
def _level(delta, thr):
    lv = 0
    for j in range(thr.shape[0]):
        if delta >= thr[j]:
            lv = j + 1
    return lv


@njit(cache=True)
def _series(gyr, acc, mag, use_mag, dt, q0, gains, thr, ki, mahony, out_q, out_gain):
    w0, w1, w2, w3 = q0[0], q0[1], q0[2], q0[3]
    ix, iy, iz = 0.0, 0.0, 0.0                      # Mahony integral (bias) term
    for i in range(gyr.shape[0]):
        gx, gy, gz = gyr[i, 0], gyr[i, 1], gyr[i, 2]
        if not (gx == gx and gy == gy and gz == gz):
            gx, gy, gz = 0.0, 0.0, 0.0
        ax, ay, az = acc[i, 0], acc[i, 1], acc[i, 2]
        na = np.sqrt(ax * ax + ay * ay + az * az)
        k = 0.0
        c0, c1, c2, c3 = 0.0, 0.0, 0.0, 0.0          # Madgwick gradient
        ex, ey, ez = 0.0, 0.0, 0.0                  # Mahony error
        if na == na and na > 1e-9:
            k = gains[_level(abs(na - G) / G, thr)]
            ax, ay, az = ax / na, ay / na, az / na
            # predicted gravity direction in the sensor frame: R(q)^T (0,0,1)
            vx, vy, vz = _qrot(w0, -w1, -w2, -w3, 0.0, 0.0, 1.0)
            fx, fy, fz = vx - ax, vy - ay, vz - az
            # p = q* ⊗ (0, d) with d = (0,0,1); gradient g_k = 2 f·vec(p ⊗ e_k)
            p0, p1, p2, p3 = _qmul(w0, -w1, -w2, -w3, 0.0, 0.0, 0.0, 1.0)
            c0 += 2 * (fx * p1 + fy * p2 + fz * p3)
            c1 += 2 * (fx * p0 + fy * p3 - fz * p2)
            c2 += 2 * (-fx * p3 + fy * p0 + fz * p1)
            c3 += 2 * (fx * p2 - fy * p1 + fz * p0)
            ex += ay * vz - az * vy
            ey += az * vx - ax * vz
            ez += ax * vy - ay * vx
            if use_mag:
                mx, my, mz = mag[i, 0], mag[i, 1], mag[i, 2]
                nm = np.sqrt(mx * mx + my * my + mz * mz)
                if nm == nm and nm > 1e-9:
                    mx, my, mz = mx / nm, my / nm, mz / nm
                    hx, hy, hz = _qrot(w0, w1, w2, w3, mx, my, mz)
                    bx, by, bz = 0.0, np.sqrt(hx * hx + hy * hy), hz
                    vx, vy, vz = _qrot(w0, -w1, -w2, -w3, bx, by, bz)
                    fx, fy, fz = vx - mx, vy - my, vz - mz
                    p0, p1, p2, p3 = _qmul(w0, -w1, -w2, -w3, 0.0, bx, by, bz)
                    c0 += 2 * (fx * p1 + fy * p2 + fz * p3)
                    c1 += 2 * (fx * p0 + fy * p3 - fz * p2)
                    c2 += 2 * (-fx * p3 + fy * p0 + fz * p1)
                    c3 += 2 * (fx * p2 - fy * p1 + fz * p0)
                    ex += my * vz - mz * vy
                    ey += mz * vx - mx * vz
                    ez += mx * vy - my * vx
        out_gain[i] = k
        if mahony:
            ix += ki * ex * dt
            iy += ki * ey * dt
            iz += ki * ez * dt
            gx, gy, gz = gx + k * ex + ix, gy + k * ey + iy, gz + k * ez + iz
            d0, d1, d2, d3 = _qmul(w0, w1, w2, w3, 0.0, gx, gy, gz)
            w0, w1, w2, w3 = w0 + 0.5 * dt * d0, w1 + 0.5 * dt * d1, w2 + 0.5 * dt * d2, w3 + 0.5 * dt * d3
        else:
            d0, d1, d2, d3 = _qmul(w0, w1, w2, w3, 0.0, gx, gy, gz)
            nc = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3)
            if nc > 1e-12 and k > 0.0:
                c0, c1, c2, c3 = c0 / nc, c1 / nc, c2 / nc, c3 / nc
            else:
                c0, c1, c2, c3 = 0.0, 0.0, 0.0, 0.0
            w0 += dt * (0.5 * d0 - k * c0)
            w1 += dt * (0.5 * d1 - k * c1)
            w2 += dt * (0.5 * d2 - k * c2)
            w3 += dt * (0.5 * d3 - k * c3)
        nn = 1.0 / np.sqrt(w0 * w0 + w1 * w1 + w2 * w2 + w3 * w3)
        w0, w1, w2, w3 = w0 * nn, w1 * nn, w2 * nn, w3 * nn
        s = 1.0 if w0 >= 0 else -1.0
        out_q[i, 0] = s * w0
        out_q[i, 1] = s * w1
        out_q[i, 2] = s * w2
        out_q[i, 3] = s * w3


def _initial(acc, mag, n_init):
    a = np.nanmean(acc[:n_init], axis=0)
    if mag is None:
        m = np.array([0.0, 1.0, 0.0])
        m = np.cross(a, np.cross(m if abs(a[1]) < 0.9 * np.linalg.norm(a) else np.array([1.0, 0, 0]), a))
        m = m + 0.0
    else:
        m = np.nanmean(mag[:n_init], axis=0)
    q = fqa(a[None], m[None])[0]
    if mag is None:                              # 6D: keep the tilt only, heading 0 is arbitrary
        return q
    return q


def _run(gyr, acc, mag, sampling_rate_hz, gains, thr, ki, mahony, init_s, params):
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    gains = np.asarray(gains, dtype=np.float64)
    thr = np.asarray(thr, dtype=np.float64)
    if len(thr) != len(gains) - 1 or np.any(np.diff(thr) <= 0):
        raise ValueError(f"need len(s_acc_g) = len(gain levels) − 1 and increasing thresholds; got {gains}, {thr}")
    n = gyr.shape[0]
    q0 = _initial(acc, mag, max(1, int(init_s * sampling_rate_hz)))
    out_q = np.empty((n, 4))
    out_g = np.empty(n)
    _series(gyr, acc, mag if mag is not None else np.empty((n, 3)), mag is not None, 1.0 / sampling_rate_hz, q0,
            gains, thr, float(ki), mahony, out_q, out_g)
    return OrientationResult(quat=out_q, gain=out_g, still=np.zeros(n, dtype=bool), mag_used=mag is not None,
                             params=params)


def madgwick(gyr, acc, mag=None, *, sampling_rate_hz: float, params: MadgwickParams = MadgwickParams()
             ) -> OrientationResult:
    """Madgwick MARG/IMU filter (see module doc). ``gain`` in the result is the β in force (rad/s)."""
    return _run(gyr, acc, mag, sampling_rate_hz, params.beta_levels_rad_s, params.s_acc_g, 0.0, False,
                params.init_s, params)


def mahony(gyr, acc, mag=None, *, sampling_rate_hz: float, params: MahonyParams = MahonyParams()
           ) -> OrientationResult:
    """Mahony explicit complementary filter (see module doc). ``gain`` in the result is the k_p in force (1/s)."""
    return _run(gyr, acc, mag, sampling_rate_hz, params.kp_levels_per_s, params.s_acc_g, params.ki_per_s2, True,
                params.init_s, params)
