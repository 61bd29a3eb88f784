"""Initial contacts from the doubly wavelet-filtered acceleration: Shin-improved (zero crossings) and HKLee-improved
(morphological closing minus opening), the two alternative contact detectors of the Mobilise-D pipeline (mobgap's
``IcdShinImproved`` / ``IcdHKLeeImproved``; the Mobilise-D cadence is computed from them).

Sources. Shin & Park 2011, "Adaptive step length estimation algorithm using optimal parameters and movement status
awareness", Med Eng Phys 33:1064, doi:10.1016/j.medengphy.2011.04.009 (steps at the zero crossings of the filtered
acceleration norm). Lee, Hwang, Lee, Kim & Jeong 2010, "Computational methods to detect step events for normal and
pathological gait evaluation using accelerometer", Electron Lett 46:1185, doi:10.1049/el.2010.1863 (steps where the
morphological closing of the acceleration exceeds its opening). Paraschiv-Ionescu, Soltani & Aminian 2020, IEEE EMBC
2020:4596, doi:10.1109/EMBC44109.2020.9176281 ("improved" versions: the common pre-filtering chain below); both are
described and validated as cadence algorithms CADB / CADC in Micó-Amigo et al. 2023, J NeuroEng Rehabil 20:78,
doi:10.1186/s12984-023-01198-5 (Table 2, Additional file 1) and Kirk et al. 2024, Sci Rep 14:1754 (real-world
validation). mobgap 1.2.0 (Apache-2.0) implements both after the consortium's MATLAB; this is our re-implementation,
not a copy.

Pre-filtering chain (a = acceleration norm |acc| or the vertical acceleration; the source runs at 40 Hz, the
window lengths below are its sample counts at 40 Hz turned into seconds):

  (1) x1 = SavGol_[0.525 s, order 7](a)                      (21 samples, polynomial order 7)
  (2) x2 = bandpass_[0.15, 3.14 Hz](x1)                      (EPFL dedrift + gait filter, same band as _icd_ionescu)
  (3) x3 = CWT_gaus2(x2) ∝ d²/dt² (G_σw * x2)                 (scale 10 at 40 Hz: g(u) = exp(-u²) at u = t/s is a
                                                              Gaussian of σw = s/√2 = 0.177 s; two integrations by
                                                              parts as in _icd_ionescu Eq. (3))
  (4) x4 = SavGol_[0.275 s, order 5](x3)                     (11 samples, order 5)
  (5) x5 = CWT_gaus2(x4) ∝ d²/dt² (G_σw * x4)
  (6) y  = G_σg * x5, σg = √(2² + 2² + 3²) / 40 s = 0.103 s   (three Gaussian smoothings of σ 2, 2, 3 samples at 40 Hz
                                                              compose into one of the root-sum-square σ)

The chain is linear and time-invariant, so y ∝ d⁴/dt⁴ of the band-passed, smoothed signal: a band-pass centred near
the step frequency whose sign and scale (the pywt wavelet's −√s normalisation, twice) do not move a zero crossing or
the place where closing exceeds opening.

Shin-improved: (S) initial contacts = the negative→positive zero crossings of y, placed by linear interpolation
between the two samples (Shin & Park 2011; sub-sample position as mobgap).

HKLee-improved (Lee et al. 2010's morphological step detection): (H1) C = closing of y with a flat structuring
element of 0.267 s (32 samples at 120 Hz, the source's upsampled rate), (H2) O = opening of C with one of 0.15 s
(18 samples at 120 Hz), (H3) R = C - O; one initial contact per run of R > 0 at least two samples long, at the
maximum of R in the run. (Step numbers (1)-(6), (S), (H1)-(H3) are ours, in the order of the consortium's
implementation as described by Micó-Amigo et al. 2023, Additional file 1.)

Deviations: (a) our own rate, time constants in seconds (no 40 Hz resampling, no 120 Hz upsampling for HKLee);
(b) a 2nd-order zero-phase Butterworth band-pass instead of the EPFL FIR + IIR dedrift (as ``_icd_ionescu``);
(c) edges are reflected instead of wrap-padded; (d) the delay between these events and the heel strike is left to
the pipeline's constant ``ic_offset_s`` (chosen by cross-validation, validation/provenance.toml); (e) optional
amplitude gate ``min_height`` (0 = off, the source).
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.ndimage import gaussian_filter1d, grey_closing, grey_opening
from scipy.signal import savgol_filter

from stridelab.estimators.trunk_gait._filters import butter_filtfilt
from stridelab.estimators.trunk_gait._icd_ionescu import IONESCU_BAND_HZ

SOURCE_RATE_HZ = 40.0                               # the rate the source's sample counts refer to
SAVGOL_1 = (21 / SOURCE_RATE_HZ, 7)                 # (window s, polynomial order), step (1)
SAVGOL_2 = (11 / SOURCE_RATE_HZ, 5)                 # step (4)
CWT_SIGMA_S = 10 / np.sqrt(2) / SOURCE_RATE_HZ      # gaus2 at scale 10 as a Gaussian σ, steps (3) and (5): 0.177 s
FINAL_SIGMA_S = np.sqrt(2 ** 2 + 2 ** 2 + 3 ** 2) / SOURCE_RATE_HZ   # step (6): 0.103 s
HKLEE_CLOSING_S = 32 / 120.0                        # Lee 2010 structuring elements at the source's 120 Hz
HKLEE_OPENING_S = 18 / 120.0


def _savgol(x: np.ndarray, window_s: float, order: int, fs_hz: float) -> np.ndarray:
    w = max(order + 2, int(round(window_s * fs_hz)))
    w += (w + 1) % 2                                 # odd window
    if w > len(x):
        return x
    return savgol_filter(x, w, order, mode="interp")


def cwt_chain_signal(a: np.ndarray, fs_hz: float, *, cwt_sigma_s: float = CWT_SIGMA_S,
                     final_sigma_s: float = FINAL_SIGMA_S) -> np.ndarray:
    """y of steps (1)-(6) for the signal ``a`` (N,) (acceleration norm or vertical acceleration, m/s²)."""
    x = np.asarray(a, float)
    n = len(x)
    x = _savgol(x, *SAVGOL_1, fs_hz)
    x = butter_filtfilt(2, (IONESCU_BAND_HZ[0], min(IONESCU_BAND_HZ[1], 0.45 * fs_hz)), "bandpass", fs_hz, x,
                        padlen=min(n - 1, int(round(3 * fs_hz))))
    x = gaussian_filter1d(x, cwt_sigma_s * fs_hz, order=2, mode="reflect") * fs_hz ** 2
    x = _savgol(x, *SAVGOL_2, fs_hz)
    x = gaussian_filter1d(x, cwt_sigma_s * fs_hz, order=2, mode="reflect") * fs_hz ** 2
    return gaussian_filter1d(x, final_sigma_s * fs_hz, mode="reflect")


@njit(cache=True)
def rising_zero_crossings(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(positions, heights): sub-sample positions (float sample indices) of the negative→positive zero crossings
    of ``y``, i + y[i] / (y[i] - y[i + 1]) for y[i] < 0 ≤ y[i + 1] (linear interpolation), and the height of the
    positive lobe each one opens (max of y up to the next crossing)."""
    n = len(y)
    out = np.empty(n // 2 + 1)
    hgt = np.empty(n // 2 + 1)
    k = 0
    for i in range(n - 1):
        if y[i] < 0.0 <= y[i + 1]:
            out[k] = i + y[i] / (y[i] - y[i + 1])
            h = y[i + 1]
            j = i + 1
            while j < n and y[j] >= 0.0:
                if y[j] > h:
                    h = y[j]
                j += 1
            hgt[k] = h
            k += 1
    return out[:k], hgt[:k]


@njit(cache=True)
def run_maxima(r: np.ndarray, min_len: int, min_height: float = 0.0) -> np.ndarray:
    """Index of the maximum of ``r`` in every run of consecutive samples with r > 0 at least ``min_len`` long whose
    maximum is at least ``min_height``."""
    n = len(r)
    out = np.empty(n // 2 + 1, np.int64)
    k = 0
    i = 0
    while i < n:
        if r[i] > 0.0:
            j = i
            m = i
            while j < n and r[j] > 0.0:
                if r[j] > r[m]:
                    m = j
                j += 1
            if j - i >= min_len and r[m] >= min_height:
                out[k] = m
                k += 1
            i = j
        else:
            i += 1
    return out[:k]


def _min_length_ok(a: np.ndarray, fs_hz: float) -> bool:
    return len(a) >= max(16, int(round(0.5 * fs_hz)))      # the source returns nothing below 0.5 s


def detect_initial_contacts_shin(a: np.ndarray, fs_hz: float, *, min_step_s: float = 0.0,
                                 min_height: float = 0.0) -> np.ndarray:
    """Float sample positions of initial contacts (Shin-improved, steps (1)-(6), (S)) in one gait sequence from
    ``a`` (N,) m/s² (acceleration norm or vertical acceleration). ``min_step_s`` > 0: of two crossings closer
    than that, the first stays (0 = every crossing, as the source). ``min_height`` > 0 (deviation): a crossing counts only when the
    positive lobe it opens reaches that many standard deviations of y over the sequence (standing still before
    and after a walk inside a gait sequence gives small crossings of sensor noise and filter ringing)."""
    if not _min_length_ok(a, fs_hz):
        return np.empty(0)
    y = np.ascontiguousarray(cwt_chain_signal(a, fs_hz))
    ic, h = rising_zero_crossings(y)
    if min_height > 0:
        ic = ic[h >= min_height * float(y.std())]
    return _thin(ic, min_step_s * fs_hz)


def detect_initial_contacts_hklee(a: np.ndarray, fs_hz: float, *, min_step_s: float = 0.0,
                                  min_height: float = 0.0) -> np.ndarray:
    """Sample indices of initial contacts (HKLee-improved, steps (1)-(6), (H1)-(H3)) in one gait sequence from
    ``a`` (N,) m/s² (acceleration norm or vertical acceleration); ``min_step_s`` as ``detect_initial_contacts_shin``;
    ``min_height`` > 0 (deviation): a run counts only when its maximum of R reaches that many standard deviations
    of y over the sequence."""
    if not _min_length_ok(a, fs_hz):
        return np.empty(0, np.int64)
    y = cwt_chain_signal(a, fs_hz)
    c = grey_closing(y, size=max(2, int(round(HKLEE_CLOSING_S * fs_hz))), mode="reflect")
    o = grey_opening(c, size=max(2, int(round(HKLEE_OPENING_S * fs_hz))), mode="reflect")
    ic = run_maxima(np.ascontiguousarray(c - o), 2, min_height * float(y.std()))
    return _thin(ic, min_step_s * fs_hz).astype(np.int64)


def _thin(ic: np.ndarray, min_gap: float) -> np.ndarray:
    if min_gap <= 0 or len(ic) < 2:
        return ic
    keep = [0]
    for i in range(1, len(ic)):
        if ic[i] - ic[keep[-1]] >= min_gap:
            keep.append(i)
    return ic[np.array(keep)]


@njit(cache=True)
def refine_to_peaks(idx: np.ndarray, vs: np.ndarray, half: int, min_gap: int) -> np.ndarray:
    """Each index of ``idx`` (sorted) moved to the argmax of ``vs`` within [i - half, i + half]; of two refined
    indices closer than ``min_gap`` the first stays. Used to time the contacts that an amplitude-free detector
    counts by the upward-acceleration peak (the double-support rebound, Zijlstra & Hof 2003) of ``_icd``."""
    n = len(vs)
    out = np.empty(len(idx), np.int64)
    k = 0
    for i in idx:
        lo = max(0, i - half)
        hi = min(n, i + half + 1)
        if hi <= lo:
            continue
        m = lo
        for j in range(lo, hi):
            if vs[j] > vs[m]:
                m = j
        if k > 0 and m - out[k - 1] < min_gap:
            continue
        out[k] = m
        k += 1
    return out[:k]
