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

from stridelab.estimators.orientation._fqa import fqa_azimuth_1, fqa_tilt_1
from stridelab.estimators.orientation._frames import ned_to_enu
from stridelab.estimators.orientation._stillness import detect_rest, fsm_step
from stridelab.estimators.orientation._types import OnlineFilter, OrientationResult
from stridelab.estimators.quaternion import quat_exp_step_1, quat_mul_1


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
    step = max(1, n // 20000)                    # unit heuristics on ≤ 20 000 evenly spread samples (speed)
    g = np.nanmedian(np.linalg.norm(acc[::step], axis=1))
    if 0.5 < g < 2.0:
        raise ValueError(f"acc median norm is {g:.2f}: looks like g, expected m/s² (multiply by 9.80665)")
    if np.nanpercentile(np.abs(gyr[::step]), 99) > 35.0:
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
    # one fused online kernel (rest FSM + filter); identical numbers to detect_rest + _yun_series (tested)
    return YunCFFilter(params, sampling_rate_hz=sampling_rate_hz).update_batch(gyr, acc, mag, stance)


#: online state layout: 0:4 q̂ sensor→NED [w x y z], 4 rest-FSM state (1 = stance), 5 FSM counter,
#: 6 initialised flag
YUN_STATE_LEN = 7


@njit(cache=True)
def _yun_online_series(gyr, acc, mag, use_mag, stance_in, use_stance_in, dt, k_s, k_d, nx, ny, rest_g, rest_a,
                       gamma, s, out_q, out_gain, out_still):
    """Fused online kernel: the A4 rest FSM (when no stance is given) and the A3 (ii) filter, scalar maths,
    no per-sample allocation in motion. Same numbers as ``detect_rest`` + ``_yun_series``."""
    q0, q1, q2, q3 = s[0], s[1], s[2], s[3]
    state = s[4] > 0.5
    count = int(s[5])
    qv = np.empty(4)
    for i in range(gyr.shape[0]):
        gx, gy, gz = gyr[i, 0], gyr[i, 1], gyr[i, 2]
        ax, ay, az = acc[i, 0], acc[i, 1], acc[i, 2]
        if use_stance_in:
            still = stance_in[i]
        else:
            c = (np.sqrt(gx * gx + gy * gy + gz * gz) <= rest_g) and \
                (abs(np.sqrt(ax * ax + ay * ay + az * az) - 9.81) <= rest_a)
            state, count = fsm_step(state, count, c, gamma)
            still = state
        out_still[i] = still
        out_q[i, 0], out_q[i, 1], out_q[i, 2], out_q[i, 3] = q0, q1, q2, q3
        k = k_s if still else k_d
        out_gain[i] = k
        if gx == gx and gy == gy and gz == gz:
            n = np.sqrt(gx * gx + gy * gy + gz * gz)
            ang = 0.5 * n * dt
            sn = np.sin(ang) / n if n > 1e-15 else 0.5 * dt
            d0, d1, d2, d3 = np.cos(ang), gx * sn, gy * sn, gz * sn
            r0 = q0 * d0 - q1 * d1 - q2 * d2 - q3 * d3
            r1 = q0 * d1 + q1 * d0 + q2 * d3 - q3 * d2
            r2 = q0 * d2 - q1 * d3 + q2 * d0 + q3 * d1
            r3 = q0 * d3 + q1 * d2 - q2 * d1 + q3 * d0
            nr = np.sqrt(r0 ** 2 + r1 ** 2 + r2 ** 2 + r3 ** 2)
            r0, r1, r2, r3 = r0 / nr, r1 / nr, r2 / nr, r3 / nr
        else:
            r0, r1, r2, r3 = q0, q1, q2, q3
        if k > 0.0 and ax == ax and ay == ay and az == az:
            m = mag[i]
            mag_ok = use_mag and m[0] == m[0] and m[1] == m[1] and m[2] == m[2]
            qv[0], qv[1], qv[2], qv[3] = q0, q1, q2, q3
            ok, qs = _static_q(acc[i], m, mag_ok, qv, nx, ny)
            if ok:
                if qs[0] * q0 + qs[1] * q1 + qs[2] * q2 + qs[3] * q3 < 0.0:
                    qs = -qs
                r0 = r0 + dt * k * (qs[0] - q0)
                r1 = r1 + dt * k * (qs[1] - q1)
                r2 = r2 + dt * k * (qs[2] - q2)
                r3 = r3 + dt * k * (qs[3] - q3)
        nn = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
        q0, q1, q2, q3 = r0 / nn, r1 / nn, r2 / nn, r3 / nn
    s[0], s[1], s[2], s[3] = q0, q1, q2, q3
    s[4] = 1.0 if state else 0.0
    s[5] = count


class YunCFFilter(OnlineFilter):
    """Online Yun complementary filter: ``state`` is a plain (7,) array (``YUN_STATE_LEN`` layout) you can
    copy and restore; initialised from the first ``init_s`` seconds of the first chunk; chunked = whole."""

    STATE_SIZE = YUN_STATE_LEN

    def __init__(self, params: YunCFParams = YunCFParams(), *, sampling_rate_hz: float):
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)

    def update_batch(self, gyr, acc, mag=None, stance=None) -> OrientationResult:
        gyr, acc, mag = self._chunk(gyr, acc, mag)
        n = gyr.shape[0]
        if stance is not None:
            stance = np.ascontiguousarray(stance, dtype=np.bool_)
            if stance.shape != (n,):
                raise ValueError(f"stance must be a (N,) bool array with N = {n}; got {stance.shape}")
        p = self.params
        nx, ny = np.cos(p.declination_rad), np.sin(p.declination_rad)
        if self._state[6] == 0.0:
            self._state[:4] = initial_attitude_ned(acc, mag, max(1, int(p.init_s * self.sampling_rate_hz)), nx, ny)
            self._state[4] = 1.0                    # start in stance (A7.2)
            self._state[5] = 0.0
            self._state[6] = 1.0
        out_q = np.empty((n, 4))
        out_gain = np.empty(n)
        still = np.empty(n, dtype=np.bool_)
        _yun_online_series(gyr, acc, mag if mag is not None else np.full((n, 3), np.nan), mag is not None,
                           stance if stance is not None else np.zeros(1, dtype=np.bool_), stance is not None,
                           1.0 / self.sampling_rate_hz, p.k_stance_per_s, p.k_swing_per_s, nx, ny, p.rest_gyr_rad_s,
                           p.rest_acc_m_s2, max(1, int(round(p.rest_min_s * self.sampling_rate_hz))), self._state,
                           out_q, out_gain, still)
        return OrientationResult(quat=ned_to_enu(out_q), gain=out_gain, still=still, mag_used=mag is not None,
                                 params=p)
