"""Yun et al. 2012 stance/swing state machine and zero-velocity update (spec/foot_papers.md A4, A5).

FSM (A4): two states on |ω| with threshold Ω_th and a consecutive-sample counter Γ_th (Y3: reset on violation):
    STANCE → SWING after Γ_th samples with |ω| > Ω_th; swing start back-dated to k − Γ_th + 1 (FIFO 1)      (Y-A4a)
    SWING → STANCE after Γ_th samples with |ω| ≤ Ω_th; swing end back-dated to k − Γ_th (FIFO 2)            (Y-A4b)
``phase`` is the real-time (delayed) state that would drive the filter gain; ``swings`` are back-dated segments.
ZVU (A5, eqs. 5–10), per swing segment i0..i1 (n = i1 − i0, trapezoid, Y4):
    a_m = R(q̂) a^b − g e_z (ENU, eq. 5–6);  v_{j+1} = v_j + T/2 (a_m,j + a_m,j+1),  v_0 = 0                  (7)
    v̂_j = v_j − (j/n) v_n   (linear drift, eq. 8–10);   p_{j+1} = p_j + T/2 (v̂_j + v̂_{j+1})
and during stance v̂ = 0, p̂ held.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from stridelab.estimators.quaternion import quat_rotate

__all__ = ["YunFsmParams", "YunPhases", "yun_stance_fsm", "ZvuResult", "yun_zvu", "yun_foot_trajectory"]

GRAVITY = 9.81


@dataclass(frozen=True)
class YunFsmParams:
    """Stance/swing FSM (spec A4, defaults Y2).

    omega_threshold_rad_s: Ω_th (1.0 rad/s; any value in ≈ (0.05, 3.5) separates Table I phases).
    count_s: Γ_th as a duration (0.06 s = 3 samples at 50 Hz); must not exceed the pre-swing (0.1 s).
    """
    omega_threshold_rad_s: float = 1.0
    count_s: float = 0.06


@dataclass(frozen=True)
class YunPhases:
    """phase (N,) bool real-time STANCE flag (delayed by Γ_th); stance (N,) bool back-dated offline phase;
    swings (S, 2) int64 back-dated swing segments [first, last] sample (inclusive)."""
    phase: np.ndarray
    stance: np.ndarray
    swings: np.ndarray


@njit(cache=True)
def _fsm(w, thr, gamma, phase, seg):
    state = 1
    cnt = 0
    ns = 0
    start = 0
    for k in range(w.shape[0]):
        if state == 1:
            cnt = cnt + 1 if w[k] > thr else 0
            if cnt >= gamma:
                state = 0
                cnt = 0
                start = k - gamma + 1
        else:
            cnt = cnt + 1 if w[k] <= thr else 0
            if cnt >= gamma:
                state = 1
                cnt = 0
                seg[ns, 0] = start
                seg[ns, 1] = k - gamma
                ns += 1
        phase[k] = state == 1
    return ns


def yun_stance_fsm(gyr: np.ndarray, *, sampling_rate_hz: float, params: YunFsmParams = YunFsmParams()) -> YunPhases:
    """Run the A4 state machine on the gyro (N, 3) rad/s. A swing still open at the end is not emitted."""
    w = np.linalg.norm(np.asarray(gyr, float), axis=1)
    w = np.where(np.isfinite(w), w, np.inf)
    gamma = max(1, int(round(params.count_s * sampling_rate_hz)))
    phase = np.empty(len(w), np.bool_)
    seg = np.zeros((len(w) // 2 + 1, 2), np.int64)
    ns = _fsm(w, params.omega_threshold_rad_s, gamma, phase, seg)
    seg = seg[:ns].copy()
    stance = np.ones(len(w), bool)
    for a, b in seg:
        stance[a:b + 1] = False
    if len(w) and not phase[-1]:          # open swing at the end: not stance, no segment
        last = seg[-1, 1] + 1 if ns else 0
        tail = np.flatnonzero(w[last:] > params.omega_threshold_rad_s)
        if len(tail):
            stance[last + tail[0]:] = False
    return YunPhases(phase=phase, stance=stance, swings=seg)


@dataclass(frozen=True)
class ZvuResult:
    """pos, vel (N, 3) m, m/s in ENU (eq. 5–10); acc_motion (N, 3) a_m; swings (S, 2) used; status."""
    pos: np.ndarray
    vel: np.ndarray
    acc_motion: np.ndarray
    swings: np.ndarray
    status: str


@njit(cache=True)
def _zvu(am, seg, T, pos, vel):
    n = am.shape[0]
    p = np.zeros(3)
    last = 0
    for s in range(seg.shape[0]):
        i0, i1 = seg[s, 0] - 1, seg[s, 1] + 1          # one stance sample (v = 0) on each side (A4 pad)
        i0 = max(i0, 0)
        i1 = min(i1, n - 1)
        for k in range(last, i0 + 1):                   # stance: hold
            for a in range(3):
                pos[k, a] = p[a]
                vel[k, a] = 0.0
        m = i1 - i0
        v = np.zeros((m + 1, 3))
        for j in range(m):
            for a in range(3):
                v[j + 1, a] = v[j, a] + 0.5 * T * (am[i0 + j, a] + am[i0 + j + 1, a])
        for j in range(m + 1):
            for a in range(3):
                v[j, a] -= (j / m) * v[m, a] if m > 0 else 0.0
        for j in range(1, m + 1):
            for a in range(3):
                p[a] += 0.5 * T * (v[j - 1, a] + v[j, a])
                pos[i0 + j, a] = p[a]
                vel[i0 + j, a] = v[j, a]
        last = i1
    for k in range(last, n):
        for a in range(3):
            pos[k, a] = p[a]
            vel[k, a] = 0.0


def yun_zvu(acc: np.ndarray, quat: np.ndarray, swings: np.ndarray, *, sampling_rate_hz: float) -> ZvuResult:
    """Velocity and position by the zero-velocity update with linear drift removal per swing (A5, eq. 5–10).

    acc (N, 3) m/s² specific force, quat (N, 4) sensor→ENU, swings (S, 2) back-dated segments from the FSM.
    """
    acc = np.asarray(acc, float)
    am = quat_rotate(np.asarray(quat, float), acc) - np.array([0.0, 0.0, GRAVITY])
    n = len(acc)
    pos, vel = np.zeros((n, 3)), np.zeros((n, 3))
    seg = np.ascontiguousarray(swings, dtype=np.int64).reshape(-1, 2)
    _zvu(np.ascontiguousarray(am), seg, 1.0 / sampling_rate_hz, pos, vel)
    return ZvuResult(pos, vel, am, seg, "ok" if len(seg) else "no_swing")


def yun_foot_trajectory(gyr, acc, mag=None, *, sampling_rate_hz: float, fsm: YunFsmParams = YunFsmParams(),
                        cf_params=None, realtime_gain: bool = True):
    """Yun's full pipeline (Fig. 2): FSM → adaptive-gain CF (``stridelab.estimators.orientation.yun_cf``) → ZVU.

    ``realtime_gain``: the gain follows the delayed real-time phase (paper); False uses the back-dated phase.
    Returns (ZvuResult, OrientationResult, YunPhases).
    """
    from stridelab.estimators.orientation import YunCFParams, yun_cf
    ph = yun_stance_fsm(gyr, sampling_rate_hz=sampling_rate_hz, params=fsm)
    ori = yun_cf(gyr, acc, mag, sampling_rate_hz=sampling_rate_hz, params=cf_params or YunCFParams(),
                 stance=ph.phase if realtime_gain else ph.stance)
    return yun_zvu(acc, ori.quat, ph.swings, sampling_rate_hz=sampling_rate_hz), ori, ph
