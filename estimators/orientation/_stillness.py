"""Stance / rest detection for gain switching when no gait phase is given.

Yun et al. 2012 Sec. II-C (spec/foot_papers.md A4): a two-state machine on the angular-rate norm
with a threshold and a consecutive-sample counter, so that momentary dips or spikes do not switch
the state. Here the rest condition also requires the accelerometer norm to be close to gravity
(a foot in stance or a still segment), which the foot-only paper did not need.
"""
from __future__ import annotations

import numpy as np
from numba import njit

GRAVITY = 9.81


@njit(cache=True, inline="always")
def fsm_step(state, count, c, gamma):
    """One sample of the A4 consecutive-count FSM: leave the current state (rest / motion) after ``gamma``
    consecutive samples whose rest condition ``c`` disagrees with it. Returns (state, count)."""
    count = count + 1 if c != state else 0
    if count >= gamma:
        return not state, 0
    return state, count


@njit(cache=True)
def _fsm(rest_cond, gamma, out):
    """Consecutive-count FSM (A4 pseudo-code, real-time: transitions reported Γ samples late)."""
    state = True          # start in stance (recordings start at rest, spec A7.2 sequencing)
    count = 0
    for i in range(rest_cond.shape[0]):
        state, count = fsm_step(state, count, rest_cond[i], gamma)
        out[i] = state


def detect_rest(gyr: np.ndarray, acc: np.ndarray, *, sampling_rate_hz: float, gyr_threshold_rad_s: float,
                acc_tolerance_m_s2: float, min_duration_s: float) -> np.ndarray:
    """(N,) bool: True where the sensor is at rest / in stance, by the A4 state machine.

    A sample satisfies the rest condition when ``|ω| ≤ gyr_threshold_rad_s`` and
    ``| |a| − g | ≤ acc_tolerance_m_s2``; the state changes after ``min_duration_s`` of consecutive
    samples contradicting it (Γ_th = round(min_duration_s · rate), at least 1). NaN samples count as motion.
    """
    w = np.linalg.norm(gyr, axis=1)
    a = np.abs(np.linalg.norm(acc, axis=1) - GRAVITY)
    cond = (w <= gyr_threshold_rad_s) & (a <= acc_tolerance_m_s2)
    out = np.empty(len(cond), dtype=np.bool_)
    _fsm(cond, max(1, int(round(min_duration_s * sampling_rate_hz))), out)
    return out
