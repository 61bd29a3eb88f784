"""Initial contacts as the minima of the wavelet-smoothed vertical jerk between its zero crossings (McCamley et al.
2012 as modified by Paraschiv-Ionescu et al. 2020; mobgap's ``IcdIonescu``).

Sources. McCamley et al. 2012, Gait Posture 36:316, doi:10.1016/j.gaitpost.2012.02.019 (integrate the vertical
acceleration, differentiate it with a Gaussian continuous wavelet transform, initial contacts at the extrema);
Paraschiv-Ionescu, Soltani & Aminian 2020, "Real-world speed estimation using single trunk IMU: methodological
challenges for impaired gait patterns", IEEE EMBC 2020:4596, doi:10.1109/EMBC44109.2020.9176281 (band-pass
0.15-3.14 Hz, cumulative integral, CWT with the second derivative of a Gaussian (``gaus2``) at scale 9 samples
at 40 Hz, one initial contact per negative lobe of that signal: the minimum between a positive-to-negative and
the next negative-to-positive zero crossing). mobgap 1.2.0 ``IcdIonescu`` (Apache-2.0) implements the same; this is
our re-implementation, not a copy.

What is computed (a = vertical acceleration, up positive, gravity removed):

  (1) x = bandpass_[0.15, 3.14 Hz](a)                                   (Paraschiv-Ionescu 2020, pre-filter)
  (2) X(t) = ∫ x dt                                                       (McCamley 2012, step 1)
  (3) W(t) = CWT_gaus2(X)(t) ∝ ∫ X(τ) g''((τ - t)/s) dτ = s² ∫ X''(τ) g((τ - t)/s) dτ = s² (G_σ * x')(t)
      with g(u) = exp(-u²): two integrations by parts turn the second-derivative wavelet on the integral into a
      Gaussian of σ = s/√2 on the derivative of the acceleration (the jerk). We compute W directly as the
      first-derivative-of-Gaussian filter of x (``scipy.ndimage.gaussian_filter1d(order=1)``), σ =
      ``sigma_s``: s = 9 samples at 40 Hz gives σ = 0.159 s.
  (4) initial contacts = argmin W over each interval [positive→negative crossing, next negative→positive
      crossing) of W minus its mean (Paraschiv-Ionescu 2020; mobgap ``_find_minima_between_zero_crossings``).

Deviations: (a) we work at the recording's own rate (time constants in seconds) instead of resampling to 40 Hz;
(b) the band-pass is a 2nd-order zero-phase Butterworth instead of EPFL's FIR ("EpflGaitFilter", same band) and
dedrift IIR; (c) a lobe counts only when its depth is at least ``min_depth`` × the standard deviation of W in the
sequence (0 = every lobe, as the source) and lobes closer than ``min_step_s`` keep the deeper one: standing sway
and the jerk's small oscillations around a slow step otherwise give extra contacts; (d) the source's delay between
the jerk minimum and the heel strike is left to the pipeline's constant ``ic_offset_s`` (chosen by
cross-validation, validation/provenance.toml). Unlike a prominence threshold on the acceleration peak this counts
one contact per step cycle whatever its amplitude, which keeps the small first, last and turning steps.
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.ndimage import gaussian_filter1d

from stridelab.estimators.trunk_gait._filters import butter_filtfilt

IONESCU_BAND_HZ = (0.15, 3.14)      # Paraschiv-Ionescu et al. 2020 pre-filter band
IONESCU_SIGMA_S = 9 / 40 / np.sqrt(2)   # their gaus2 scale (9 samples at 40 Hz) as a Gaussian σ, Eq. (3): 0.159 s


def ionescu_signal(v_up: np.ndarray, fs_hz: float, *, sigma_s: float = IONESCU_SIGMA_S,
                   band_hz: tuple[float, float] = IONESCU_BAND_HZ) -> np.ndarray:
    """W of Eqs. (1)-(3): the band-passed vertical acceleration's Gaussian-smoothed derivative, mean removed."""
    n = len(v_up)
    hi = min(band_hz[1], 0.45 * fs_hz)
    x = butter_filtfilt(2, (band_hz[0], hi), "bandpass", fs_hz, np.asarray(v_up, float),
                        padlen=min(n - 1, int(round(3 * fs_hz))))
    w = gaussian_filter1d(x, sigma_s * fs_hz, order=1, mode="nearest") * fs_hz
    return w - w.mean()


@njit(cache=True)
def lobe_minima(w: np.ndarray, min_depth: float, min_gap: int) -> np.ndarray:
    """Index of the minimum of every negative lobe of ``w`` (from a positive→negative to the next negative→positive
    crossing; a lobe still open at the end is not counted, as the source), kept when its value is ≤ -``min_depth``;
    of two minima closer than ``min_gap`` samples the deeper one stays."""
    n = len(w)
    out = np.empty(n // 2 + 1, np.int64)
    k = 0
    i = 1
    while i < n:
        if w[i - 1] >= 0.0 and w[i] < 0.0:          # entering a negative lobe
            j = i
            m = i
            while j < n and w[j] < 0.0:
                if w[j] < w[m]:
                    m = j
                j += 1
            if j >= n:
                break
            if -w[m] >= min_depth:
                if k > 0 and m - out[k - 1] < min_gap:
                    if w[m] < w[out[k - 1]]:
                        out[k - 1] = m
                else:
                    out[k] = m
                    k += 1
            i = j
        i += 1
    return out[:k]


def detect_initial_contacts_ionescu(v_up: np.ndarray, fs_hz: float, *, sigma_s: float = IONESCU_SIGMA_S,
                                    min_depth: float = 0.0, min_step_s: float = 0.25) -> np.ndarray:
    """Sample indices of initial contacts in one gait sequence from the upward acceleration ``v_up`` (N,) m/s²
    (gravity removed), Eqs. (1)-(4); ``min_depth`` in standard deviations of W over the sequence."""
    if len(v_up) < max(16, int(round(4 * sigma_s * fs_hz))):
        return np.empty(0, np.int64)
    w = ionescu_signal(v_up, fs_hz, sigma_s=sigma_s)
    sd = float(w.std())
    if not np.isfinite(sd) or sd <= 0:
        return np.empty(0, np.int64)
    return lobe_minima(np.ascontiguousarray(w), min_depth * sd, max(1, int(round(min_step_s * fs_hz))))
