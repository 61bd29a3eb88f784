"""Yun adaptive-gain quaternion complementary filter (FQA static branch + gyro integration).

Yun, Calusdian, Bachmann, McGhee, "Estimation of human foot motion during normal walking using
inertial and magnetic sensor measurements", IEEE TIM 61(7), 2012, doi:10.1109/TIM.2011.2179830;
spec/foot_papers.md A2-A4. Discrete form (ii) of A3:

    q̂_{k+1} = normalize( q̂_k ⊗ exp(ω_k T / 2) + T·k_k·(±q_s,k − q̂_k) )           (eq. 2, A3 (ii))

with q_s from the FQA (A2) and k = k_s in stance, k_d in swing (Table II: 1.05 and 0 s⁻¹). The
phase comes from ``stance`` when the caller has one (gait phase), else from the rest detector of
:mod:`._stillness` (spec A4 state machine on |ω| and |a|).

Deviations: the maths runs in NED like the paper and the output is re-referenced to ENU by one
fixed rotation; initial attitude is the FQA of the mean of the first ``init_s`` seconds (paper:
not stated); without a magnetometer (6D) the FQA azimuth is replaced by the current heading
estimate, so only tilt is corrected and heading follows the gyro; a NaN gyro sample holds the
attitude, a NaN accelerometer sample skips the correction, a NaN magnetometer sample uses the 6D
correction.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from estimators.orientation._fqa import fqa_azimuth_1, fqa_tilt_1
from estimators.orientation._frames import ned_to_enu
from estimators.orientation._stillness import detect_rest
from estimators.orientation._types import OrientationResult
from estimators.quaternion import quat_exp_step_1, quat_mul_1


@dataclass(frozen=True)
class YunCFParams:
    """Parameters of the Yun complementary filter (all rate-independent).

    k_stance_per_s: gain k_s in stance / at rest, 1/s (Table II: 1.05).
    k_swing_per_s: gain k_d in swing / motion, 1/s (Table II: 0.0, pure gyro integration).
    rest_gyr_rad_s: rest detector angular-rate threshold Ω_th, rad/s (spec A4 suggests 0.6-1.0 for
        feet; 0.5 keeps thighs and trunk from being declared still while walking).
    rest_acc_m_s2: rest detector tolerance on | |a| − g |, m/s².
    rest_min_s: consecutive time Γ_th·T before the state switches, s (A4: 60 ms; must stay below
        the pre-swing duration, see A4 "design constraint").
    init_s: initial attitude from the FQA of the mean of the first ``init_s`` seconds.
    declination_rad: magnetic declination (east +); 0 means ENU y = magnetic north.
    """
    k_stance_per_s: float = 1.05
    k_swing_per_s: float = 0.0
    rest_gyr_rad_s: float = 0.5
    rest_acc_m_s2: float = 0.6
    rest_min_s: float = 0.06
    init_s: float = 0.5
    declination_rad: float = 0.0


@njit(cache=True)
def _yaw_ned(q):
    """Heading ψ of a sensor→NED quaternion (ZYX convention of the FQA factorisation)."""
    return np.arctan2(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3]))


@njit(cache=True)
def _static_q(a, m, use_mag, q_cur, nx, ny):
    """q_s of A2 (9D), or tilt with the current heading (6D); (ok, q)."""
    na = np.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
    if not (na > 1e-9):
        return False, q_cur
    qt = fqa_tilt_1(a[0] / na, a[1] / na, a[2] / na)
    ok = False
    if use_mag:
        ok, qa = fqa_azimuth_1(qt, m[0], m[1], m[2], nx, ny)
    if not ok:
        # 6D: keep the heading of the current estimate: yaw of q_cur relative to the tilt
        psi = _yaw_ned(q_cur)
        qa = np.array([np.cos(psi / 2.0), 0.0, 0.0, np.sin(psi / 2.0)])
    return True, quat_mul_1(qa, qt)


@njit(cache=True)
def _yun_series(gyr, acc, mag, use_mag, stance, dt, k_s, k_d, nx, ny, q0, out_q, out_gain):
    q = q0.copy()
    for i in range(gyr.shape[0]):
        out_q[i] = q
        k = k_s if stance[i] else k_d
        out_gain[i] = k
        g = gyr[i]
        if g[0] == g[0] and g[1] == g[1] and g[2] == g[2]:          # not NaN
            qn = quat_exp_step_1(q, g[0], g[1], g[2], dt)
        else:
            qn = q.copy()
        if k > 0.0:
            a = acc[i]
            if a[0] == a[0] and a[1] == a[1] and a[2] == a[2]:
                m = mag[i]
                mag_ok = use_mag and m[0] == m[0] and m[1] == m[1] and m[2] == m[2]
                ok, qs = _static_q(a, m, mag_ok, q, nx, ny)
                if ok:
                    if qs[0] * q[0] + qs[1] * q[1] + qs[2] * q[2] + qs[3] * q[3] < 0.0:
                        qs = -qs                                      # same hemisphere as q̂ (A3)
                    qn = qn + dt * k * (qs - q)
        q = qn / np.sqrt(np.sum(qn * qn))


def _check_inputs(gyr, acc, mag, sampling_rate_hz):
    gyr = np.ascontiguousarray(gyr, dtype=np.float64)
    acc = np.ascontiguousarray(acc, dtype=np.float64)
    if gyr.ndim != 2 or gyr.shape[1] != 3 or acc.shape != gyr.shape:
        raise ValueError(f"gyr and acc must both be (N, 3) arrays; got {gyr.shape} and {acc.shape}")
    if not sampling_rate_hz or sampling_rate_hz <= 0:
        raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
    n = gyr.shape[0]
    if n < sampling_rate_hz:
        raise ValueError(f"recording of {n} samples is shorter than one second at {sampling_rate_hz:g} Hz; "
                         f"orientation filters need at least 1 s to initialise")
    if mag is not None:
        mag = np.ascontiguousarray(mag, dtype=np.float64)
        if mag.shape != gyr.shape:
            raise ValueError(f"mag must be (N, 3) like gyr; got {mag.shape}")
    g = np.nanmedian(np.linalg.norm(acc, axis=1))
    if 0.5 < g < 2.0:
        raise ValueError(f"acc median norm is {g:.2f}: looks like g, expected m/s² (multiply by 9.80665)")
    if np.nanpercentile(np.abs(gyr), 99) > 35.0:
        raise ValueError("gyr looks like deg/s (99th percentile > 35), expected rad/s (use np.deg2rad)")
    return gyr, acc, mag


def initial_attitude_ned(acc, mag, n_init, nx, ny):
    """Sensor→NED attitude from the mean of the first n_init finite samples (FQA, or tilt-only)."""
    a = np.nanmean(acc[:n_init], axis=0)
    if not np.all(np.isfinite(a)):
        a = np.nanmean(acc, axis=0)
    m = np.nanmean(mag[:n_init], axis=0) if mag is not None else np.full(3, np.nan)
    use = bool(np.all(np.isfinite(m)))
    ok, q = _static_q(a, m if use else np.zeros(3), use, np.array([1.0, 0.0, 0.0, 0.0]), nx, ny)
    return q / np.linalg.norm(q)


def yun_cf(gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None = None, *, sampling_rate_hz: float,
           params: YunCFParams = YunCFParams(), stance: np.ndarray | None = None) -> OrientationResult:
    """Orientation of an IMU by the Yun adaptive-gain complementary filter.

    gyr (N, 3) rad/s, acc (N, 3) m/s² (specific force), mag (N, 3) any unit or None (6D),
    stance (N,) bool gait phase (optional; else the rest detector decides). Returns an
    :class:`OrientationResult` with quat (N, 4) [w x y z] sensor→ENU.
    """
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    n = gyr.shape[0]
    if stance is None:
        still = detect_rest(gyr, acc, sampling_rate_hz=sampling_rate_hz, gyr_threshold_rad_s=params.rest_gyr_rad_s,
                            acc_tolerance_m_s2=params.rest_acc_m_s2, min_duration_s=params.rest_min_s)
    else:
        still = np.asarray(stance, dtype=bool)
        if still.shape != (n,):
            raise ValueError(f"stance must be a (N,) bool array with N = {n}; got {still.shape}")
    nx, ny = np.cos(params.declination_rad), np.sin(params.declination_rad)
    q0 = initial_attitude_ned(acc, mag, max(1, int(params.init_s * sampling_rate_hz)), nx, ny)
    out_q = np.empty((n, 4))
    out_gain = np.empty(n)
    _yun_series(gyr, acc, mag if mag is not None else np.full((n, 3), np.nan), mag is not None,
                np.ascontiguousarray(still), 1.0 / sampling_rate_hz, params.k_stance_per_s, params.k_swing_per_s,
                nx, ny, q0, out_q, out_gain)
    return OrientationResult(quat=ned_to_enu(out_q), gain=out_gain, still=still, mag_used=mag is not None,
                             params=params)
