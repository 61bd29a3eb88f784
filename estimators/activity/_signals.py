"""Signals of thesis ch. 7 (Eq. 54-57), the elliptic GA filter, auto-calibration, upright reference,
per-second aggregation and non-wear detection. Vectorised NumPy/SciPy; inputs in g."""
from __future__ import annotations

import numpy as np
from scipy import signal

from stridelab.estimators.activity._types import AccCalibration


def ga_filter_sos(sampling_rate_hz: float, cutoff_hz: float = 0.25, ripple_db: float = 0.01,
                  stop_db: float = 100.0) -> np.ndarray:
    """2nd-order elliptic IIR low-pass of the thesis (§7.2.3; spec §4.2), as second-order sections.

    MATLAB ``ellip(2, 0.01, 100, 0.25/(fs/2))``; at fs = 100 Hz b = [6.2996e-4, 1.2213e-3, 6.2996e-4],
    a = [1, −1.92994, 0.93242].
    """
    if sampling_rate_hz <= 2 * cutoff_hz:
        raise ValueError(f"sampling_rate_hz={sampling_rate_hz} too low for a {cutoff_hz} Hz low-pass")
    return signal.ellip(2, ripple_db, stop_db, cutoff_hz, fs=sampling_rate_hz, output="sos")


def gravitational_component(acc_g: np.ndarray, sampling_rate_hz: float, *, mode: str = "lfilter",
                            cutoff_hz: float = 0.25, ripple_db: float = 0.01, stop_db: float = 100.0,
                            order: str = "scipy") -> np.ndarray:
    """GA: the elliptic low-pass of each axis, started in steady state on the first sample (spec §4.2:
    a zero-state start reads θ ≈ 90° for the first seconds). ``mode``: "lfilter" causal, "filtfilt" zero phase.
    ``order="C"``: the result C-ordered (the same values; SciPy returns the transpose of a C-ordered (3, N) array)."""
    sos = ga_filter_sos(sampling_rate_hz, cutoff_hz, ripple_db, stop_db)
    x = np.asarray(acc_g, dtype=np.float64)
    if x.shape[0] == 0:
        return x.copy()
    if mode == "filtfilt":
        if x.shape[0] <= 3 * 6:
            return np.repeat(x.mean(axis=0, keepdims=True), x.shape[0], axis=0)
        return signal.sosfiltfilt(sos, x, axis=0)
    zi = signal.sosfilt_zi(sos)[:, :, None] * x[0][None, None, :]   # (n_sections, 2, 3)
    y = signal.sosfilt(sos, x, axis=0, zi=zi)[0]
    return np.ascontiguousarray(y) if order == "C" else y


def ga_dc_gain(sampling_rate_hz: float, cutoff_hz: float = 0.25, ripple_db: float = 0.01,
               stop_db: float = 100.0) -> float:
    """DC gain of the GA filter (0.99885 for the thesis design: −0.01 dB ripple at DC)."""
    sos = ga_filter_sos(sampling_rate_hz, cutoff_hz, ripple_db, stop_db)
    return float(np.prod(sos[:, :3].sum(axis=1) / sos[:, 3:].sum(axis=1)))


def inclination_deg(ga_v_g: np.ndarray, dc_gain: float = 1.0) -> np.ndarray:
    """Trunk inclination θ = arccos(GA_v / g), Eq. 54 (argument divided by the DC gain and clipped to [−1, 1])."""
    return np.degrees(np.arccos(np.clip(np.asarray(ga_v_g) / dc_gain, -1.0, 1.0)))


def vertical_acc_g(ga_f: np.ndarray, ga_v: np.ndarray) -> np.ndarray:
    """Vertical acceleration in the global frame, Eq. 55: a_vg = −GA_f sin θ_s + GA_v cos θ_s with the
    signed inclination θ_s = atan2(−GA_f, GA_v) (spec §4.2 item 3); equals 1 g at rest for any sagittal tilt."""
    th = np.arctan2(-ga_f, ga_v)
    return -ga_f * np.sin(th) + ga_v * np.cos(th)


def svm_g(ga: np.ndarray) -> np.ndarray:
    """Signal vector magnitude from the GA components, Eq. 57: SVM = ‖GA‖ − g (in g)."""
    return np.sqrt(np.einsum("ij,ij->i", ga, ga)) - 1.0


def chest_height_change_m(a_v_g: np.ndarray, sampling_rate_hz: float) -> tuple[float, float]:
    """ΔY = ∬ a_vg dt dt over the window, Eq. 56, the window's mean removed first (thesis: limits drift);
    trapezoidal integration. Returns (ΔY at the window end, peak-to-peak displacement), m."""
    a = (np.asarray(a_v_g, dtype=np.float64) - np.mean(a_v_g)) * 9.80665
    if a.shape[0] < 3:
        return 0.0, 0.0
    dt = 1.0 / sampling_rate_hz
    v = np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
    return float(y[-1]), float(y.max() - y.min())


def cumulative_svm_sign(svm: np.ndarray) -> int:
    """Sign of the dominant extremum of CI(t) = ∫ SVM dτ over the transition (thesis §7.2.5, spec AMBIG 7.C4):
    −1 → StSi (negative then positive SVM lobe), +1 → SiSt."""
    ci = np.cumsum(np.asarray(svm) - 0.0)
    if ci.size == 0:
        return 0
    i = int(np.argmax(np.abs(ci)))
    return int(np.sign(ci[i]))


# ---- per-second aggregation ----------------------------------------------------------------

def second_index(n: int, sampling_rate_hz: float) -> tuple[np.ndarray, int]:
    """Sample -> whole second from the start, and the number of seconds (a partial last second counts)."""
    idx = (np.arange(n) / sampling_rate_hz).astype(np.int64)
    return idx, int(idx[-1]) + 1 if n else 0


def per_second_mean(x: np.ndarray, sec: np.ndarray, n_sec: int, counts: np.ndarray) -> np.ndarray:
    """Mean of ``x`` (N,) or (N, k) per second via bincount."""
    if x.ndim == 1:
        return np.bincount(sec, weights=x, minlength=n_sec) / counts
    return np.column_stack([np.bincount(sec, weights=x[:, i], minlength=n_sec) / counts for i in range(x.shape[1])])


def per_second_std(x: np.ndarray, sec: np.ndarray, n_sec: int, counts: np.ndarray) -> np.ndarray:
    m = np.bincount(sec, weights=x, minlength=n_sec) / counts
    m2 = np.bincount(sec, weights=x * x, minlength=n_sec) / counts
    return np.sqrt(np.maximum(m2 - m * m, 0.0))


# ---- auto-calibration ----------------------------------------------------------------------

#: window of the auto-calibration's still periods (s)
CALIBRATION_WINDOW_S = 10.0


def autocalibrate(acc_g: np.ndarray, sampling_rate_hz: float, *, window_s: float = CALIBRATION_WINDOW_S,
                  still_std_g: float = 0.013, min_windows: int = 10, coverage_g: float = 0.3,
                  enabled: bool = True) -> AccCalibration:
    """Per-axis gain and offset from still periods (extension; van Hees et al. 2014,
    doi:10.1152/japplphysiol.00421.2014): 10-s windows with every axis std < ``still_std_g`` are assumed to
    read 1 g; iteratively fit ``(x − o)·s`` to their projection on the unit sphere.

    The 6-parameter fit needs still orientations on both sides of every axis (|mean| > ``coverage_g`` in
    both signs), which a day with lying postures gives; otherwise (e.g. a lab session upright only) only a
    common gain ``1 / median ‖x‖`` is estimated (``status="gain_only"``), which sets the scale but leaves
    offsets (documented limitation).
    """
    x = np.asarray(acc_g, dtype=np.float64)
    w = int(round(window_s * sampling_rate_hz))
    nw = x.shape[0] // w if w > 0 else 0
    if not enabled or nw == 0:
        return calibration_from_windows(np.zeros((0, 3)), np.zeros((0, 3)), enabled=False)
    blk = x[: nw * w].reshape(nw, w, 3)
    return calibration_from_windows(blk.mean(axis=1), blk.std(axis=1), still_std_g=still_std_g,
                                    min_windows=min_windows, coverage_g=coverage_g)


def calibration_from_windows(mean: np.ndarray, std: np.ndarray, *, still_std_g: float = 0.013,
                             min_windows: int = 10, coverage_g: float = 0.3, enabled: bool = True) -> AccCalibration:
    """``autocalibrate`` on precomputed window means and standard deviations, (W, 3) each, in g."""
    eye = AccCalibration(offset_g=np.zeros(3), gain=np.ones(3), status="none", n_still=0, rms_error_g=float("nan"))
    if not enabled or mean.shape[0] == 0:
        return eye
    still = np.all(std < still_std_g, axis=1) & np.all(np.isfinite(mean), axis=1)
    m = mean[still]
    if m.shape[0] < min_windows:
        return eye
    # thin out: a night of lying gives thousands of identical windows; keep unique orientations equally weighted
    key = np.round(m / 0.02).astype(np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    m = m[np.sort(first)]
    covered = np.all((m > coverage_g).any(axis=0) & (m < -coverage_g).any(axis=0))
    if not covered or m.shape[0] < min_windows:
        g = float(np.median(np.linalg.norm(m, axis=1)))
        gain = np.full(3, 1.0 / g)
        res = np.linalg.norm(m * gain, axis=1) - 1.0
        return AccCalibration(offset_g=np.zeros(3), gain=gain, status="gain_only", n_still=int(still.sum()),
                              rms_error_g=float(np.sqrt(np.mean(res ** 2))))
    off, gain = np.zeros(3), np.ones(3)
    for _ in range(50):
        c = (m - off) * gain
        target = c / np.linalg.norm(c, axis=1, keepdims=True)
        new_off, new_gain = np.empty(3), np.empty(3)
        for k in range(3):        # target_k = gain_k * (m_k − off_k): least squares in m_k
            A = np.column_stack([m[:, k], np.ones(m.shape[0])])
            (a, b), *_ = np.linalg.lstsq(A, target[:, k], rcond=None)
            new_gain[k], new_off[k] = a, -b / a
        done = np.max(np.abs(new_off - off)) < 1e-6 and np.max(np.abs(new_gain - gain)) < 1e-6
        off, gain = new_off, new_gain
        if done:
            break
    res = np.linalg.norm((m - off) * gain, axis=1) - 1.0
    return AccCalibration(offset_g=off, gain=gain, status="sphere_fit", n_still=int(still.sum()),
                          rms_error_g=float(np.sqrt(np.mean(res ** 2))))


# ---- frame alignment ----------------------------------------------------------------------

def rotation_to_y(u: np.ndarray) -> np.ndarray:
    """(3, 3) rotation R with R @ u = +y along the shortest arc; for u ≈ −y the rotation is 180° about the
    sensor x axis (the chest normal), i.e. an upside-down sensor on the sternum keeps its frontal axis."""
    u = np.asarray(u, dtype=np.float64) / np.linalg.norm(u)
    y = np.array([0.0, 1.0, 0.0])
    c = float(u @ y)
    if c < -1.0 + 1e-9:
        return np.diag([1.0, -1.0, -1.0])
    v = np.cross(u, y)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half-open [start, end) index runs where ``mask`` is True."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    d = np.diff(m.astype(np.int8))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def nonwear_seconds(sec_sum_g: np.ndarray, sec_sumsq_g2: np.ndarray, counts: np.ndarray, *, std_g: float,
                    noise_factor: float, min_s: float) -> tuple[np.ndarray, float]:
    """Non-wear (extension; after van Hees et al. 2013, doi:10.1371/journal.pone.0061691): runs of at least
    ``min_s`` seconds made of whole minutes in which **every** axis' standard deviation over the minute is
    below a threshold, in any orientation. Inputs: per-second sums and sums of squares of each axis (S, 3),
    in g and g², and the samples per second (S,).

    Threshold: ``std_g`` if ``noise_factor`` is 0, else ``noise_factor`` × the recording's own noise floor
    (5th percentile over minutes of the smallest-axis std), capped at ``std_g``. On the sternum breathing tilts
    the sensor by about a degree, which a worn sensor shows on at least one axis even in a still sleeper or
    sitter, while a sensor put down shows only its noise. The minute-aligned edges are refined to the second
    (a second joins when every axis' 1-s std is below the threshold). Returns (mask (S,), threshold g)."""
    n = sec_sum_g.shape[0]
    if n == 0:
        return np.zeros(0, dtype=bool), float(std_g)
    k = 60
    nb = n // k
    if nb == 0:
        return np.zeros(n, dtype=bool), float(std_g)
    c = counts[: nb * k].reshape(nb, k).sum(axis=1)[:, None]
    m1 = sec_sum_g[: nb * k].reshape(nb, k, 3).sum(axis=1) / c
    m2 = sec_sumsq_g2[: nb * k].reshape(nb, k, 3).sum(axis=1) / c
    sd_min = np.sqrt(np.maximum(m2 - m1 * m1, 0.0))                   # (nb, 3) per-minute std
    thr = float(std_g)
    if noise_factor > 0:
        floor = float(np.percentile(sd_min.min(axis=1), 5))
        thr = min(thr, noise_factor * floor) if floor > 0 else thr
    still_min = np.all(sd_min < thr, axis=1)
    still = np.zeros(n, dtype=bool)
    still[: nb * k] = np.repeat(still_min, k)
    cs = np.maximum(counts, 1.0)[:, None]
    mu = sec_sum_g / cs
    sd_sec = np.sqrt(np.maximum(sec_sumsq_g2 / cs - mu * mu, 0.0))
    sec_still = np.all(sd_sec < thr, axis=1)
    out = np.zeros(n, dtype=bool)
    for a, b in zip(*runs(still)):
        if b - a >= min_s:
            while a > 0 and sec_still[a - 1]:          # refine the minute-aligned edges to the second
                a -= 1
            while b < n and sec_still[b]:
                b += 1
            out[a:b] = True
    return out, thr
