"""Initial contacts and their side from the trunk, within one gait sequence (body-frame signals).

Initial contacts: McCamley et al. 2012, "An enhanced estimate of initial contact and final contact instants of time
using lower trunk inertial sensor data", Gait Posture 36:316, doi:10.1016/j.gaitpost.2012.02.019: the vertical
acceleration is integrated and differentiated with a Gaussian continuous wavelet; initial contacts are the
extrema of that signal. Integrating and then differentiating with a first-derivative-of-Gaussian wavelet equals
Gaussian smoothing of the vertical acceleration, which is what we do (σ = ``ic_smooth_s``). Deviation: our vertical
axis points up (McCamley's acceleration is taken positive downwards), so the initial contact is a *maximum* of
the upward acceleration (the double-support rebound of the centre of mass, Zijlstra & Hof 2003); a constant offset
``ic_offset_s`` maps that peak to the heel strike (chosen by cross-validation, validation/provenance.toml).
Peaks are kept at least ``ic_min_step_s`` apart and with a prominence of at least ``ic_prominence`` standard
deviations of the smoothed signal in the sequence (robust to the small accelerations of slow walking at 0.3 m/s,
where an absolute threshold would fail).

Side: McCamley et al. 2012 assign the side from the sign of the angular velocity about the vertical axis around
each initial contact. The pelvis rotates its swing side forward before heel strike, so the yaw rate (about *up*,
right-hand rule: counter-clockwise seen from above, low-passed at ``side_lowpass_hz``) read ``side_lag_s`` from the
contact (negative = before) is positive before a *right* initial contact. Single votes agree with the references
in about 80 % of contacts on the Voisard L5 trials and on the Mobilise-D lab trials alike (the roll rate, which
we tried first, agreed in 91 % on Voisard but in 10 % on Mobilise-D: not a placement-independent cue). Because
steps alternate, each run of regularly spaced contacts gets the alternating labelling that agrees with most votes
(Ullrich et al. 2022, Sensors 22:6463, doi:10.3390/s22176463, use the same alternation after their classifier),
which corrects isolated wrong votes.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d
from scipy.signal import find_peaks, sosfiltfilt

from estimators.trunk_gait._filters import butter_sos


def detect_initial_contacts(v_up: np.ndarray, fs_hz: float, *, smooth_s: float, min_step_s: float,
                            prominence: float, local_window_s: float = 0.0) -> np.ndarray:
    """Sample indices of initial-contact peaks of the upward acceleration ``v_up`` (N,) m/s² (gravity removed).

    The prominence threshold is ``prominence`` × the standard deviation of the smoothed signal over the sequence,
    or, with ``local_window_s`` > 0, over a centred window of that length (slow turning steps keep their peaks
    between faster straight steps)."""
    if len(v_up) < 3:
        return np.empty(0, np.int64)
    vs = gaussian_filter1d(v_up, smooth_s * fs_hz, mode="nearest")
    sd = float(vs.std())
    if sd <= 0:
        return np.empty(0, np.int64)
    peaks, props = find_peaks(vs, distance=max(1, int(round(min_step_s * fs_hz))), prominence=0.0)
    if local_window_s > 0:
        w = max(3, int(round(local_window_s * fs_hz)))
        m1 = uniform_filter1d(vs, w, mode="nearest")
        m2 = uniform_filter1d(vs * vs, w, mode="nearest")
        ref = np.sqrt(np.maximum(m2 - m1 * m1, 0.0))[peaks]
    else:
        ref = sd
    return peaks[props["prominences"] >= prominence * ref].astype(np.int64)


def regular_runs(ic_s: np.ndarray, *, max_step_s: float) -> np.ndarray:
    """Run id per contact: a new run starts where the step time exceeds ``max_step_s`` (a missed step or a pause),
    so alternation of sides is only assumed inside a run."""
    if len(ic_s) == 0:
        return np.empty(0, np.int64)
    return np.r_[0, np.cumsum(np.diff(ic_s) > max_step_s)].astype(np.int64)


def assign_sides(yaw_rate: np.ndarray, fs_hz: float, ic_idx: np.ndarray, runs: np.ndarray, *, lag_s: float,
                 lowpass_hz: float) -> np.ndarray:
    """Boolean (K,) True = left for initial contacts ``ic_idx`` (sample indices into ``yaw_rate``, rad/s about up)."""
    k = len(ic_idx)
    if k == 0:
        return np.zeros(0, bool)
    if len(yaw_rate) > 12:
        sos = butter_sos(2, min(lowpass_hz, 0.45 * fs_hz), "lowpass", fs_hz)
        r = sosfiltfilt(sos, yaw_rate, padlen=min(len(yaw_rate) - 1, 3 * 6))
    else:
        r = yaw_rate
    at = np.clip(ic_idx + int(round(lag_s * fs_hz)), 0, len(r) - 1)
    vote = -np.sign(r[at])                                    # +1 = left: negative yaw rate before a left contact
    left = np.empty(k, bool)
    for run in np.unique(runs):
        m = np.flatnonzero(runs == run)
        alt = np.where(np.arange(len(m)) % 2 == 0, 1.0, -1.0)
        phase = 1.0 if float(vote[m] @ alt) >= 0 else -1.0
        left[m] = alt * phase > 0
    return left
