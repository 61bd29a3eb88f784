"""Hand-made trunk signals of known answer (shared by the trunk-gait tests; not the simulator)."""
from __future__ import annotations

import numpy as np

G = 9.80665


def walking_body(duration_s: float, *, fs: float = 100.0, step_s: float = 0.55, amp: float = 2.0,
                 rest_s: float = 0.0, seed: int = 0):
    """(acc_body (N, 3) with columns [anterior, up, right] incl. gravity on up, gyr_body (N, 3), ic_s (K,),
    left (K,) bool). Walking between rest_s and rest_s + duration_s; the upward acceleration peaks at each
    initial contact, the forward acceleration follows its rate of change (inverted pendulum), the
    medio-lateral acceleration and the roll rate alternate with the side; the yaw rate (about up) is positive
    before a right and negative before a left contact."""
    rng = np.random.default_rng(seed)
    n = int(round((duration_s + 2 * rest_s) * fs))
    t = np.arange(n) / fs
    ic = np.arange(rest_s + step_s / 2, rest_s + duration_s, step_s)
    left = np.arange(len(ic)) % 2 == 0
    up = np.zeros(n)
    ant = np.zeros(n)
    ml = np.zeros(n)
    roll = np.zeros(n)
    walking = (t >= rest_s) & (t < rest_s + duration_s)
    phase = 2 * np.pi * (t - ic[0]) / step_s
    up[walking] = amp * np.cos(phase[walking])
    ant[walking] = -0.5 * amp * np.sin(phase[walking])              # ~ d(up)/dt: forward acc leads
    yaw = np.zeros(n)
    for k, t_ic in enumerate(ic):              # per step: the pelvis turns its swing side forward before contact
        sgn = 1.0 if left[k] else -1.0
        m = (t >= t_ic) & (t < t_ic + step_s)
        u = (t[m] - t_ic) / step_s
        ml[m] = -0.8 * sgn * np.sin(np.pi * u)
        roll[m] = 0.3 * sgn * np.sin(np.pi * u)
        m = (t >= t_ic - step_s / 2) & (t < t_ic + step_s / 2) & walking
        yaw[m] = -0.4 * sgn * np.cos(np.pi * (t[m] - t_ic) / step_s)   # > 0 (counter-clockwise) before a right IC
    acc = np.column_stack([ant, up + G, ml]) + rng.normal(0, 0.05, (n, 3))
    gyr = np.column_stack([roll, yaw, np.zeros(n)]) + rng.normal(0, 0.005, (n, 3))
    return acc, gyr, ic, left


def rot(axis: str, deg: float) -> np.ndarray:
    a = np.deg2rad(deg)
    c, s = np.cos(a), np.sin(a)
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]
