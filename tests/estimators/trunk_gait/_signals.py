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


def pendulum_walk(speed_m_s: float, step_s: float, *, leg_m: float = 0.85, n_steps: int = 40,
                  double_support: float = 0.35, vertical_scale: float = 1.0, sway_m: float = 0.03,
                  speed_swing: float = 0.1, step_cv: float = 0.0, asymmetry: float = 0.0, rest_s: float = 5.0,
                  fs: float = 100.0, noise_m_s2: float = 0.02, seed: int = 0):
    """(acc_body (N, 3) [anterior, up, right] incl. gravity, gyr_body (N, 3), ic_s (K,), walk (start_s, end_s)) of a
    slow walk from its own mechanical model (not from the estimators): the trunk moves forward at ``speed_m_s``
    (± ``speed_swing`` per step) and vaults over each stance foot on an inverted pendulum of length ``leg_m``
    (single support: height sqrt(l² - x²), x the forward distance from the stance foot); during the double support
    that follows each initial contact (``double_support`` x ``step_s``: slow and hemiparetic walking spend a third
    or more of each step on both feet) the trunk's vertical velocity turns from falling to rising at a constant
    upward acceleration (a cubic Hermite between the two arcs, the same height and vertical speed at both ends).
    ``step_cv``: step times vary at random by this coefficient of variation (each step keeps the speed, so its
    length varies too); ``asymmetry``: every other step (the paretic side) is that fraction longer in time and
    length. ``vertical_scale`` < 1 shrinks the vertical excursion (weight borne through a walking aid). The trunk sways
    ``sway_m`` to the side of the stance foot (stride period). Standing still for ``rest_s`` before and after;
    white sensor noise."""
    rng = np.random.default_rng(seed)
    v = speed_m_s
    Ts = step_s * (1 + step_cv * rng.standard_normal(n_steps)) * np.where(np.arange(n_steps) % 2, 1 + asymmetry, 1.0)
    Ts = np.clip(Ts, 0.3 * step_s, None)
    ic = rest_s + np.r_[0.0, np.cumsum(Ts)]
    n = int(round((ic[-1] + rest_s) * fs))
    t = np.arange(n) / fs
    z = np.full(n, leg_m)
    for k in range(n_steps + 1):
        T = Ts[min(k, n_steps - 1)]
        d = double_support * T
        a = v * (T - d) / 2                    # forward distance from the stance foot at the end of single support
        z0 = np.sqrt(leg_m ** 2 - a ** 2)
        Tp = Ts[k - 1] if k > 0 else T          # the arc that ended at this contact
        ap = v * (Tp - double_support * Tp) / 2
        c_in, c_out = v * ap / np.sqrt(leg_m ** 2 - ap ** 2), v * a / z0      # falling / rising vertical speed
        c_in = c_in if k > 0 else 0.0           # the first step starts from standing
        zp = np.sqrt(leg_m ** 2 - ap ** 2)
        u = t - ic[k]
        m = (u >= 0) & (u < d)                 # double support: cubic Hermite from (zp, -c_in) to (z0, +c_out)
        s = u[m] / d
        h00, h10, h01, h11 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s, -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
        if k == n_steps:                       # the closing double support: come to rest at the stance height
            z[m] = h00 * zp + h10 * d * (-c_in) + h01 * leg_m
            z[ic[k] + d <= t] = leg_m
            continue
        z[m] = h00 * zp + h10 * d * (-c_in) + h01 * z0 + h11 * d * c_out
        m = (u >= d) & (u < T)                 # single support over the new stance foot
        x = v * (u[m] - d) - a
        z[m] = np.sqrt(leg_m ** 2 - x ** 2)
    z[t < ic[0]] = z[np.searchsorted(t, ic[0])]
    z0 = leg_m
    T = step_s
    z = z0 + vertical_scale * (z - z0)
    up = np.gradient(np.gradient(z, 1 / fs), 1 / fs)
    walking = (t >= ic[0]) & (t < ic[-1])
    ant = np.where(walking, v * speed_swing * 2 * np.pi / T * np.cos(2 * np.pi * (t - ic[0]) / T), 0.0)
    ml = np.where(walking, -sway_m * (np.pi / T) ** 2 * np.sin(np.pi * (t - ic[0]) / T), 0.0)
    acc = np.column_stack([ant, up + G, ml]) + rng.normal(0, noise_m_s2, (n, 3))
    yaw = np.where(walking, 0.15 * np.cos(np.pi * (t - ic[0]) / T), 0.0)     # pelvic rotation, stride period
    gyr = np.column_stack([np.zeros(n), yaw, np.zeros(n)]) + rng.normal(0, 0.005, (n, 3))
    return acc, gyr, ic, (ic[0], ic[-1])


def standing_sway(duration_s: float, *, fs: float = 100.0, sway_m: float = 0.01, breath_m_s2: float = 0.03,
                  noise_m_s2: float = 0.02, seed: int = 0):
    """(acc_body (N, 3), gyr_body (N, 3)) of quiet standing: the trunk sways as low-pass (< 1 Hz) random motion of
    about ``sway_m`` (anterior and lateral), breathing at 0.25 Hz, slow lean changes that tilt gravity by a few
    degrees, white sensor noise."""
    from scipy.signal import butter, sosfiltfilt
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * fs))
    t = np.arange(n) / fs
    sos = butter(2, 1.0, "low", fs=fs, output="sos")
    pos = sosfiltfilt(sos, rng.normal(0, 1, (n, 2)), axis=0)
    pos *= sway_m / pos.std(axis=0)
    lin = np.gradient(np.gradient(pos, 1 / fs, axis=0), 1 / fs, axis=0)
    tilt = sosfiltfilt(butter(2, 0.1, "low", fs=fs, output="sos"), rng.normal(0, 1, n))
    tilt *= np.deg2rad(3.0) / tilt.std()
    acc = np.column_stack([lin[:, 0] + G * np.sin(tilt), G * np.cos(tilt) + breath_m_s2 * np.sin(2 * np.pi * 0.25 * t),
                           lin[:, 1]]) + rng.normal(0, noise_m_s2, (n, 3))
    gyr = np.column_stack([np.zeros(n), np.zeros(n), np.gradient(tilt, 1 / fs)]) + rng.normal(0, 0.005, (n, 3))
    return acc, gyr


def sit_to_stand(n_reps: int = 5, *, period_s: float = 3.0, fs: float = 100.0, lean_deg: float = 40.0,
                 rest_s: float = 5.0, noise_m_s2: float = 0.02, seed: int = 0):
    """(acc_body (N, 3), gyr_body (N, 3)) of repeated sit-to-stand and back (the five-times sit-to-stand test,
    one cycle per ``period_s``): in each half cycle the trunk leans forward by ``lean_deg`` and back (gravity
    turns in the body frame) while the pelvis rises (or sinks) by 0.45 m along a minimum-jerk path; seated
    (``rest_s``) before and after."""
    rng = np.random.default_rng(seed)
    n = int(round((2 * rest_s + n_reps * period_s) * fs))
    t = np.arange(n) / fs
    h = np.zeros(n)
    lean = np.zeros(n)
    half = period_s / 2
    for k in range(n_reps):
        for j, sgn in ((0, 1.0), (1, -1.0)):
            t0 = rest_s + k * period_s + j * half
            u = np.clip((t - t0) / half, 0, 1)
            mj = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5               # minimum-jerk 0 -> 1
            h += sgn * 0.45 * np.where(t >= t0, mj, 0.0)
            lean += np.where((t >= t0) & (t < t0 + half), np.sin(np.pi * u) ** 2, 0.0)
    lean = np.deg2rad(lean_deg) * lean
    up_lin = np.gradient(np.gradient(h, 1 / fs), 1 / fs)
    acc = np.column_stack([G * np.sin(lean), (G + up_lin) * np.cos(lean), np.zeros(n)]) + rng.normal(0, noise_m_s2,
                                                                                                   (n, 3))
    gyr = np.column_stack([np.zeros(n), np.zeros(n), np.gradient(lean, 1 / fs)]) + rng.normal(0, 0.005, (n, 3))
    return acc, gyr
