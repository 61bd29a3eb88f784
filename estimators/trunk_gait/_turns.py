"""Turns from the yaw rate of a trunk sensor (El-Gohary et al. 2014).

El-Gohary et al. 2014, "Continuous monitoring of turning in patients with movement disability", Sensors 14:356,
doi:10.3390/s140100356: the angular velocity about the vertical axis is low-passed (1.5 Hz), turns are
candidate segments whose peak rate exceeds 15 deg/s, bounded where the rate falls below 5 deg/s; segments of the
same direction closer than 50 ms are merged; a turn has an angle of at least 45 deg and lasts 0.5-10 s.
Deviation: El-Gohary use a lumbar sensor's orientation (Kalman filter) to get the vertical rate; we project the
gyroscope onto the gravity-aligned vertical of each gait sequence (tilt < 30 deg makes the difference small).
"""
from __future__ import annotations

import numpy as np

from stridelab.estimators.trunk_gait._filters import butter_filtfilt
from stridelab.estimators.trunk_gait._types import Turns

EMPTY_TURNS = Turns(start_s=np.empty(0), end_s=np.empty(0), angle_deg=np.empty(0), peak_rate_deg_s=np.empty(0))


def detect_turns(yaw_rate_rad_s: np.ndarray, fs_hz: float, *, t0_s: float, lowpass_hz: float, min_peak_deg_s: float,
                 edge_deg_s: float, min_angle_deg: float, min_s: float, max_s: float) -> Turns:
    """Turns in one segment; times are ``t0_s`` + sample / ``fs_hz``."""
    n = len(yaw_rate_rad_s)
    if n < 16:
        return EMPTY_TURNS
    w = np.rad2deg(butter_filtfilt(2, min(lowpass_hz, 0.45 * fs_hz), "lowpass", fs_hz, yaw_rate_rad_s,
                                   padlen=min(n - 1, 15)))
    active = np.abs(w) >= edge_deg_s
    sign = np.sign(w)
    # segments of constant sign above the edge threshold
    brk = np.r_[True, (active[1:] != active[:-1]) | (sign[1:] != sign[:-1])]
    starts = np.flatnonzero(brk)
    ends = np.r_[starts[1:], n]
    keep = active[starts]
    starts, ends = starts[keep], ends[keep]
    if len(starts) == 0:
        return EMPTY_TURNS
    # merge same-direction segments separated by < 50 ms
    gap = int(round(0.05 * fs_hz))
    ms, me = [starts[0]], [ends[0]]
    for s, e in zip(starts[1:], ends[1:]):
        if s - me[-1] <= gap and sign[s] == sign[ms[-1]]:
            me[-1] = e
        else:
            ms.append(s)
            me.append(e)
    ms, me = np.asarray(ms), np.asarray(me)
    csum = np.r_[0.0, np.cumsum(w)] / fs_hz
    angle = csum[me] - csum[ms]
    peak = np.maximum.reduceat(np.abs(w), ms)
    dur = (me - ms) / fs_hz
    ok = (peak >= min_peak_deg_s) & (np.abs(angle) >= min_angle_deg) & (dur >= min_s) & (dur <= max_s)
    return Turns(start_s=t0_s + ms[ok] / fs_hz, end_s=t0_s + me[ok] / fs_hz, angle_deg=angle[ok],
                 peak_rate_deg_s=peak[ok])
