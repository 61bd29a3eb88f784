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

With ``s_mag`` the magnetometer disturbance ``Δ_M = | ‖m‖ − ‖m_0‖ | / ‖m_0‖`` switches too and the level is
the larger of the two (Th. Eq 23: the first gain only when Δ_A < S_A AND Δ_M < S_M). Madgwick's gyro-drift
term ζ (paper eq. 47-48) and static gyro-bias removal from the initial window (thesis C1) are optional.
Online classes :class:`MadgwickFilter` / :class:`MahonyFilter` carry a plain state array (chunked = whole).

Deviations: initial attitude = FQA of the first 0.5 s (paper: identity, slow convergence); output in ENU
(the maths is frame-free here: gravity reference +z, field reference north = +y); NaN samples hold the
attitude (gyro) or skip the correction (acc / mag). Defaults are the papers' typical values; gains tuned on
BROAD by particle swarm are the presets ``MADGWICK_BROAD_VST2`` / ``MAHONY_BROAD_VST2`` (tuned_gains.json,
estimators ``madgwick_tuned`` / ``mahony_tuned``); these filters are not the project default.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from stridelab.estimators.orientation._dcf_kernel import _qmul, _qrot
from stridelab.estimators.orientation._fqa import fqa
from stridelab.estimators.orientation._fullstate_kernel import _level
from stridelab.estimators.orientation._types import OnlineFilter, OrientationResult
from stridelab.estimators.orientation._yun_cf import _check_inputs

G = 9.81


@dataclass(frozen=True)
class MadgwickParams:
    """Madgwick filter parameters.

    beta_levels_rad_s: gradient gains β per switching level, rad/s (one value = fixed gain; paper ≈ 0.041).
    s_acc_g: thresholds on Δ_A = | ‖a‖ − g | / g, in g (len = levels − 1, increasing).
    s_mag: thresholds on Δ_M = | ‖m‖ − ‖m_0‖ | / ‖m_0‖ (‖m_0‖: mean field norm of the initial window),
        fractions of the field norm; empty = the switch looks at Δ_A only. The level is the larger of the
        two (Th. Eq 23: level 0 only when Δ_A < S_A AND Δ_M < S_M).
    zeta_rad_s: gyro-drift gain ζ of Madgwick's bias compensation, rad/s (0 = off, the paper's IMU form).
    static_bias: subtract the mean gyro of the initial window when the sensor is still there (thesis C1).
    init_s: initial attitude from the FQA of the mean of the first ``init_s`` seconds.
    """
    beta_levels_rad_s: tuple[float, ...] = (0.041,)
    s_acc_g: tuple[float, ...] = ()
    s_mag: tuple[float, ...] = ()
    zeta_rad_s: float = 0.0
    static_bias: bool = False
    init_s: float = 0.5


@dataclass(frozen=True)
class MahonyParams:
    """Mahony filter parameters.

    kp_levels_per_s: proportional gains k_p per switching level, 1/s (one value = fixed gain; typical 1.0).
    ki_per_s2: integral (gyro bias) gain k_i, 1/s² (0 = off).
    s_acc_g: thresholds on Δ_A in g (len = levels − 1, increasing).
    s_mag: thresholds on Δ_M in fractions of the initial field norm (empty = Δ_A only); see MadgwickParams.
    static_bias: subtract the mean gyro of the initial window when the sensor is still there (thesis C1).
    init_s: initial attitude from the FQA of the mean of the first ``init_s`` seconds.
    """
    kp_levels_per_s: tuple[float, ...] = (1.0,)
    ki_per_s2: float = 0.0
    s_acc_g: tuple[float, ...] = ()
    s_mag: tuple[float, ...] = ()
    static_bias: bool = False
    init_s: float = 0.5


#: online state layout: 0:4 q [w x y z] sensor→ENU, 4:7 Madgwick gyro-drift estimate ω_b / Mahony integral
#: term (rad/s), 7 initialised flag, 8 initial field norm ‖m_0‖ (input units, 0 = unknown), 9:12 static gyro
#: bias subtracted from every sample (rad/s)
STATE_LEN = 12


@njit(cache=True)
def _series(gyr, acc, mag, use_mag, dt, gains, thr, thr_m, ki, zeta, mahony, s, out_q, out_gain):
    """Run Madgwick (mahony=False) or Mahony over (N, 3) arrays from state ``s`` (updated in place)."""
    w0, w1, w2, w3 = s[0], s[1], s[2], s[3]
    ix, iy, iz = s[4], s[5], s[6]                # Mahony integral term / Madgwick drift estimate ω_b
    m_ref = s[8]
    sbx, sby, sbz = s[9], s[10], s[11]
    use_thr_m = thr_m.shape[0] > 0 and m_ref > 0.0
    for i in range(gyr.shape[0]):
        gx, gy, gz = gyr[i, 0] - sbx, gyr[i, 1] - sby, gyr[i, 2] - sbz
        if not (gx == gx and gy == gy and gz == gz):
            gx, gy, gz = 0.0, 0.0, 0.0
        ax, ay, az = acc[i, 0], acc[i, 1], acc[i, 2]
        na = np.sqrt(ax * ax + ay * ay + az * az)
        k = 0.0
        c0, c1, c2, c3 = 0.0, 0.0, 0.0, 0.0          # Madgwick gradient
        ex, ey, ez = 0.0, 0.0, 0.0                  # Mahony error
        if na == na and na > 1e-9:
            lv = _level(abs(na - G) / G, thr)
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
                    if use_thr_m:
                        lm = _level(abs(nm - m_ref) / m_ref, thr_m)
                        if lm > lv:
                            lv = lm
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
            elif use_thr_m:
                lm = thr_m.shape[0]                  # no field: treat as disturbed
                if lm > lv:
                    lv = lm
            k = gains[lv]
        out_gain[i] = k
        if mahony:
            ix += ki * ex * dt
            iy += ki * ey * dt
            iz += ki * ez * dt
            gx, gy, gz = gx + k * ex + ix, gy + k * ey + iy, gz + k * ez + iz
            d0, d1, d2, d3 = _qmul(w0, w1, w2, w3, 0.0, gx, gy, gz)
            w0, w1, w2, w3 = w0 + 0.5 * dt * d0, w1 + 0.5 * dt * d1, w2 + 0.5 * dt * d2, w3 + 0.5 * dt * d3
        else:
            nc = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3)
            if nc > 1e-12 and k > 0.0:
                c0, c1, c2, c3 = c0 / nc, c1 / nc, c2 / nc, c3 / nc
            else:
                c0, c1, c2, c3 = 0.0, 0.0, 0.0, 0.0
            if zeta > 0.0:
                # gyro drift (Madgwick 2011 eq. 47-48): ω_ε = 2 q* ⊗ q̇_ε, ω_b += ζ ω_ε T
                e0, e1, e2, e3 = _qmul(w0, -w1, -w2, -w3, c0, c1, c2, c3)
                ix += 2.0 * zeta * e1 * dt
                iy += 2.0 * zeta * e2 * dt
                iz += 2.0 * zeta * e3 * dt
                gx, gy, gz = gx - ix, gy - iy, gz - iz
            d0, d1, d2, d3 = _qmul(w0, w1, w2, w3, 0.0, gx, gy, gz)
            w0 += dt * (0.5 * d0 - k * c0)
            w1 += dt * (0.5 * d1 - k * c1)
            w2 += dt * (0.5 * d2 - k * c2)
            w3 += dt * (0.5 * d3 - k * c3)
        nn = 1.0 / np.sqrt(w0 * w0 + w1 * w1 + w2 * w2 + w3 * w3)
        w0, w1, w2, w3 = w0 * nn, w1 * nn, w2 * nn, w3 * nn
        sg = 1.0 if w0 >= 0 else -1.0
        out_q[i, 0] = sg * w0
        out_q[i, 1] = sg * w1
        out_q[i, 2] = sg * w2
        out_q[i, 3] = sg * w3
    s[0], s[1], s[2], s[3] = w0, w1, w2, w3
    s[4], s[5], s[6] = ix, iy, iz


def _initial(acc, mag, n_init):
    a = np.nanmean(acc[:n_init], axis=0)
    if not np.all(np.isfinite(a)):
        a = np.nanmean(acc, axis=0)
    m = np.nanmean(mag[:n_init], axis=0) if mag is not None else np.full(3, np.nan)
    if not (np.all(np.isfinite(m)) and np.linalg.norm(m) > 0):   # 6D: tilt only, heading 0 is arbitrary
        ref = np.array([0.0, 1.0, 0.0]) if abs(a[1]) < 0.9 * np.linalg.norm(a) else np.array([1.0, 0, 0])
        m = np.cross(a, np.cross(ref, a)) + 0.0
    return fqa(a[None], m[None])[0]


def initial_state(gyr, acc, mag, sampling_rate_hz, init_s, static_bias) -> np.ndarray:
    """Filter state from the first ``init_s`` seconds: FQA attitude, field norm, static gyro bias (C1)."""
    n0 = max(1, int(init_s * sampling_rate_hz))
    s = np.zeros(STATE_LEN)
    s[:4] = _initial(acc, mag, n0)
    s[7] = 1.0
    if mag is not None:
        nm = np.linalg.norm(mag[:n0], axis=1)
        nm = nm[np.isfinite(nm)]
        s[8] = float(nm.mean()) if len(nm) else 0.0
    if static_bias:
        w = gyr[:n0]
        w = w[np.all(np.isfinite(w), axis=1)]
        if len(w):
            mw = w.mean(axis=0)
            if np.abs(w - mw).max() < 0.05 and np.linalg.norm(mw) < 0.1:   # still: ≤ 3°/s wobble
                s[9:12] = mw
    return s


def _gain_arrays(gains, thr, thr_m):
    gains = np.asarray(gains, dtype=np.float64)
    thr = np.asarray(thr, dtype=np.float64)
    thr_m = np.asarray(thr_m, dtype=np.float64)
    if (len(gains) < 1 or len(thr) != len(gains) - 1 or np.any(np.diff(thr) <= 0)
            or (len(thr_m) and (len(thr_m) != len(thr) or np.any(np.diff(thr_m) <= 0)))):
        raise ValueError(f"need len(s_acc_g) = len(gain levels) − 1 increasing thresholds, and s_mag empty or of "
                         f"the same length; got gains {tuple(gains)}, s_acc_g {tuple(thr)}, s_mag {tuple(thr_m)}")
    return gains, thr, thr_m


class _SwitchingFilter(OnlineFilter):
    """Online Madgwick / Mahony: ``state`` is a plain (12,) array (layout: ``STATE_LEN`` comment) you can
    copy and restore; it is initialised from the first ``init_s`` seconds of the first chunk, so chunked =
    whole when that chunk is at least ``init_s`` long (tested)."""
    _mahony = False
    STATE_SIZE = STATE_LEN

    def __init__(self, params, *, sampling_rate_hz: float):
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)
        g = params.kp_levels_per_s if self._mahony else params.beta_levels_rad_s
        self._arrays = _gain_arrays(g, params.s_acc_g, params.s_mag)

    def update_batch(self, gyr, acc, mag=None) -> OrientationResult:
        gyr, acc, mag = self._chunk(gyr, acc, mag)
        n = gyr.shape[0]
        p = self.params
        if self._state[7] == 0.0:
            self._state = initial_state(gyr, acc, mag, self.sampling_rate_hz, p.init_s, p.static_bias)
        out_q = np.empty((n, 4))
        out_g = np.empty(n)
        gains, thr, thr_m = self._arrays
        ki = p.ki_per_s2 if self._mahony else 0.0
        zeta = 0.0 if self._mahony else p.zeta_rad_s
        _series(gyr, acc, mag if mag is not None else np.empty((n, 3)), mag is not None, 1.0 / self.sampling_rate_hz,
                gains, thr, thr_m, float(ki), float(zeta), self._mahony, self._state, out_q, out_g)
        return OrientationResult(quat=out_q, gain=out_g, still=np.zeros(n, dtype=bool), mag_used=mag is not None,
                                 params=p)


class MadgwickFilter(_SwitchingFilter):
    """Online Madgwick filter (see module doc); ``update_batch(gyr, acc, mag=None) -> OrientationResult``."""
    _mahony = False

    def __init__(self, params: MadgwickParams = MadgwickParams(), *, sampling_rate_hz: float):
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)


class MahonyFilter(_SwitchingFilter):
    """Online Mahony filter (see module doc); ``update_batch(gyr, acc, mag=None) -> OrientationResult``."""
    _mahony = True

    def __init__(self, params: MahonyParams = MahonyParams(), *, sampling_rate_hz: float):
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)


def madgwick(gyr, acc, mag=None, *, sampling_rate_hz: float, params: MadgwickParams = MadgwickParams()
             ) -> OrientationResult:
    """Madgwick MARG/IMU filter (see module doc). ``gain`` in the result is the β in force (rad/s)."""
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    return MadgwickFilter(params, sampling_rate_hz=sampling_rate_hz).update_batch(gyr, acc, mag)


def mahony(gyr, acc, mag=None, *, sampling_rate_hz: float, params: MahonyParams = MahonyParams()
           ) -> OrientationResult:
    """Mahony explicit complementary filter (see module doc). ``gain`` in the result is the k_p in force (1/s)."""
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    return MahonyFilter(params, sampling_rate_hz=sampling_rate_hz).update_batch(gyr, acc, mag)


#: Gains tuned by particle swarm on the 15 BROAD trials (tuned_gains.json "madgwick_pso" / "mahony_pso", 
#: "adaptive": 3-level switch on Δ_A and Δ_M, thesis VST2; static gyro bias removal). Hand-held IMU, 9D; not
#: tuned per placement (foot, shank, ...).
MADGWICK_BROAD_VST2 = MadgwickParams(beta_levels_rad_s=(0.02238, 0.0001269, 0.01888), s_acc_g=(0.402, 0.5),
                                     s_mag=(0.09817, 0.5), zeta_rad_s=2.676e-06, static_bias=True, init_s=0.5)
MAHONY_BROAD_VST2 = MahonyParams(kp_levels_per_s=(1.281, 0.005269, 0.07299), ki_per_s2=1e-06,
                                 s_acc_g=(0.02035, 0.4798), s_mag=(0.08951, 0.4007), static_bias=True, init_s=0.5)


def madgwick_tuned(gyr, acc, mag=None, *, sampling_rate_hz: float) -> OrientationResult:
    """Madgwick with the BROAD-tuned 3-level switching gains (``MADGWICK_BROAD_VST2``)."""
    return madgwick(gyr, acc, mag, sampling_rate_hz=sampling_rate_hz, params=MADGWICK_BROAD_VST2)


def mahony_tuned(gyr, acc, mag=None, *, sampling_rate_hz: float) -> OrientationResult:
    """Mahony with the BROAD-tuned 3-level switching gains (``MAHONY_BROAD_VST2``)."""
    return mahony(gyr, acc, mag, sampling_rate_hz=sampling_rate_hz, params=MAHONY_BROAD_VST2)
