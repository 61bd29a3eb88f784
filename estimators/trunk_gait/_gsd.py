"""Gait-sequence detection from the acceleration norm: windows with enough movement and a step periodicity.

Iluz et al. 2014, "Automated detection of missteps during community ambulation in patients with Parkinson's
disease", J NeuroEng Rehabil 11:48, doi:10.1186/1743-0003-11-48 (3 s windows, 50 % overlap, walking when the
signal is both strong and periodic in the gait band), with the periodicity measured, as in Moe-Nilssen &
Helbostad 2004 (J Biomech 37:121, doi:10.1016/S0021-9290(03)00233-1), by the unbiased autocorrelation at the
step lag. Deviations: the frame-free acceleration norm (the sensor orientation is not yet known) decimated to
about 25 Hz; windows overlap by ``1 - hop/window`` (finer than 50 %) so sequence edges are within ``hop``.

Two ways for a window to be walking (docs/trunk_gait.md, "Gait-sequence detection"):

* **strong**: SD of the norm ≥ ``min_std_m_s2`` and autocorrelation ≥ ``min_autocorr`` (as before; tuned on
  healthy walkers);
* **slow** (periodicity-led, for the weak trunk accelerations of slow and aided walking): the norm band-passed to
  Iluz's gait band (0.5-3 Hz, ``GAIT_BAND_HZ``: sway, breathing and posture drift below, tremor and typing above)
  has an SD ≥ ``slow_min_std_m_s2`` (an amplitude floor above sensor noise and quiet standing) and its
  autocorrelation at the step lag reaches ``slow_min_autocorr`` (stricter than the strong rule: at this amplitude
  only a clear step rhythm counts). ``slow_min_std_m_s2`` = inf turns it off (the detector before issue 42's
  slow-walking round).
"""
from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from stridelab.estimators.trunk_gait._filters import butter_filtfilt
from stridelab.estimators.trunk_gait._types import TrunkGaitParams

GSD_RATE_HZ = 25.0
STEP_LAG_S = (0.25, 1.6)   # plausible step times: cadence 37.5-240 steps/min (slow pathological to running)
GAIT_BAND_HZ = (0.5, 3.0)  # Iluz 2014 as implemented by Mobilise-D (mobgap GsdIluz pre-filter: 0.5-3 Hz band-pass)
_DEFAULTS = TrunkGaitParams()


def _decimate_norm(acc: np.ndarray, fs_hz: float) -> tuple[np.ndarray, float]:
    q = max(1, int(round(fs_hz / GSD_RATE_HZ)))
    norm = np.sqrt(np.einsum("ij,ij->i", acc, acc))
    n = (len(norm) // q) * q
    if n == 0:
        return norm[:0], fs_hz / q
    return norm[:n].reshape(-1, q).mean(axis=1), fs_hz / q


def _window_sd(x: np.ndarray, starts: np.ndarray, w: int) -> np.ndarray:
    """Standard deviation of x[s:s + w] for every start s, from running sums (O(N))."""
    c1 = np.r_[0.0, np.cumsum(x - x.mean())]
    c2 = np.r_[0.0, np.cumsum((x - x.mean()) ** 2)]
    m1 = (c1[starts + w] - c1[starts]) / w
    return np.sqrt(np.maximum((c2[starts + w] - c2[starts]) / w - m1 * m1, 0.0))


def _step_autocorr(x: np.ndarray, starts: np.ndarray, w: int, fs_d: float) -> np.ndarray:
    """Largest unbiased autocorrelation (Moe-Nilssen & Helbostad 2004 Eq. 1) at a step lag (``STEP_LAG_S``) of each
    window x[s:s + w], normalised by the window's variance."""
    if len(starts) == 0:
        return np.empty(0)
    win = sliding_window_view(x, w)[starts]
    win = win - win.mean(axis=1, keepdims=True)
    nfft = 1 << int(np.ceil(np.log2(2 * w)))
    spec = np.fft.rfft(win, n=nfft, axis=1)
    ac = np.fft.irfft(spec * np.conj(spec), n=nfft, axis=1)[:, :w]
    lag_lo = max(1, int(round(STEP_LAG_S[0] * fs_d)))
    lag_hi = min(w - 2, int(round(STEP_LAG_S[1] * fs_d)))
    unbiased = ac[:, lag_lo:lag_hi + 1] / (w - np.arange(lag_lo, lag_hi + 1))       # Moe-Nilssen 2004 Eq. 1
    return unbiased.max(axis=1) / np.maximum(ac[:, 0] / w, 1e-12)


def detect_gait_sequences(acc: np.ndarray, fs_hz: float, *, window_s: float, hop_s: float, min_std_m_s2: float,
                          min_autocorr: float, merge_gap_s: float,
                          slow_min_std_m_s2: float = _DEFAULTS.gsd_slow_min_std_m_s2,
                          slow_min_autocorr: float = _DEFAULTS.gsd_slow_min_autocorr) -> np.ndarray:
    """(G, 2) int sample indices [start, end) of gait sequences in ``acc`` (N, 3) m/s² sampled at ``fs_hz``.

    A window is walking by the strong rule (``min_std_m_s2``, ``min_autocorr`` on the norm) or by the slow rule
    (``slow_min_std_m_s2``, ``slow_min_autocorr`` on the norm band-passed to ``GAIT_BAND_HZ``); see the module
    docstring. The slow-rule defaults are ``TrunkGaitParams``'."""
    x, fs_d = _decimate_norm(acc, fs_hz)
    w = int(round(window_s * fs_d))
    hop = max(1, int(round(hop_s * fs_d)))
    if len(x) < w or w < 8:
        return np.empty((0, 2), np.int64)
    # window SD from running sums (O(N)); the autocorrelation only where it can be walking
    starts_all = np.arange(0, len(x) - w + 1, hop)
    walking = np.zeros(len(starts_all), bool)
    cand = np.flatnonzero(_window_sd(x, starts_all, w) >= min_std_m_s2)
    walking[cand] = _step_autocorr(x, starts_all[cand], w, fs_d) >= min_autocorr
    if np.isfinite(slow_min_std_m_s2) and GAIT_BAND_HZ[1] < fs_d / 2 and len(x) > 27:
        xb = butter_filtfilt(2, GAIT_BAND_HZ, "bandpass", fs_d, x - x.mean())
        rest = np.flatnonzero(~walking)
        cand = rest[_window_sd(xb, starts_all[rest], w) >= slow_min_std_m_s2]
        walking[cand] = _step_autocorr(xb, starts_all[cand], w, fs_d) >= slow_min_autocorr
    if not walking.any():
        return np.empty((0, 2), np.int64)
    starts = starts_all[walking]
    # union of [start, start + w) intervals, merging gaps shorter than merge_gap_s
    gap = int(round(merge_gap_s * fs_d))
    ends = starts + w
    new = np.r_[True, starts[1:] > np.maximum.accumulate(ends)[:-1] + gap]
    idx = np.flatnonzero(new)
    seq_start = starts[idx]
    seq_end = np.maximum.reduceat(ends, idx)
    q = fs_hz / fs_d
    out = np.column_stack([np.rint(seq_start * q), np.minimum(np.rint(seq_end * q), len(acc))]).astype(np.int64)
    return out
