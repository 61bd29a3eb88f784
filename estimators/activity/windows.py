"""Window features for a learned chest-activity classifier (project extension, not in the thesis).

Pure functions: a chest accelerometer recording in, one row of features per non-overlapping window out.
Everything that adapts to the participant is computed from that participant's **unlabelled** signal only
(auto-calibration from still windows, its own walking posture found from gait-like windows, its own noise
floor, its own cadence), so a model trained on other participants can be applied to a new one without any of
its labels. Used by ``stridelab bench activity`` (method ``learned_loso``, leave-one-subject-out on the UCI
chest set); the pipeline's activity stage does not use it (see docs/activity.md).

Units: input m/s²; internally g (1 g = 9.80665 m/s²); angles in degrees, frequencies in Hz, amplitudes as
log10 of g (so ``-2`` = 10 mg). Windows start at sample 0 and have ``round(window_s * fs)`` samples; a trailing
partial window is dropped (same windows as ``stridelab.validation.bench.activity.window_confusion``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft
from scipy import signal

from stridelab.estimators.activity._kernels import acf_at_lag
from stridelab.estimators.activity import _window_kernels as WK
from stridelab.estimators.activity._signals import CALIBRATION_WINDOW_S, autocalibrate, calibration_from_windows

__all__ = ["WindowFeatures", "FEATURE_NAMES", "window_features", "gait_windows", "walking_reference",
           "standing_reference", "posture_clusters", "lean_deg", "add_context", "calibrated_g", "GAIT_BAND_HZ",
           "moving_fraction"]

G = 9.80665
#: cadence band (steps/s) of gait-like windows used to find the participant's own walking posture
GAIT_BAND_HZ = (1.4, 2.4)
#: lean from the walking posture beyond which a window is lying and left out of the still-posture references
#: (thesis lying threshold, spec §4.3)
LYING_DEG = 70.0
_EPS = 1e-6

#: columns of ``WindowFeatures.x`` (before ``add_context``)
FEATURE_NAMES = (
    "lean_walk_deg",      # angle between the window's mean acc direction and the participant's walking posture
    "lean_stand_deg",     # ... and the participant's standing posture (still windows next to walking)
    "lean_upright_deg",   # angle to the participant's upright still posture cluster (``posture_clusters``)
    "lean_other_deg",     # angle to its other (leaning) still posture cluster
    "posture_margin_deg", # lean_other_deg − lean_upright_deg (> 0: closer to the upright cluster)
    "cluster_sep_deg",    # angle between the two still posture clusters (small: one posture only)
    "log_dyn",            # log10 RMS of the 0.3-20 Hz acc (vector norm of the three high-passed axes), g
    "log_dyn_rel_floor",  # log_dyn minus the participant's noise floor (5th percentile of log_dyn)
    "log_dyn_rel_gait",   # log_dyn minus the participant's median log_dyn over gait-like windows
    "log_sway_deg",       # log10 std of the 1 Hz low-passed tilt angle inside the window (postural sway), deg
    "log_low",            # log10 RMS of the vertical acc in 0.1-0.5 Hz (slow trunk motion), g
    "log_mid",            # ... 0.5-1.4 Hz
    "log_step",           # ... 1.4-2.4 Hz (step band)
    "log_high",           # ... 2.4-6 Hz
    "step_frac",          # fraction of the 0.3-6 Hz vertical power inside the cadence band
    "cadence_hz",         # dominant frequency of the vertical acc in 0.5-3.5 Hz
    "cadence_rel",        # cadence_hz / participant's median cadence over gait-like windows
    "step_regularity",    # autocorrelation of the vertical acc at one step period (1 / cadence)
    "stride_regularity",  # ... at two step periods (one stride)
    "vert_horiz_ratio",   # log10 of RMS vertical / RMS horizontal dynamic acc
    "log_jerk",           # log10 RMS of the derivative of the acc norm, g/s
    "gait_like",          # 1 if the window is gait-like (see ``gait_windows``)
)


@dataclass(frozen=True)
class WindowFeatures:
    """``x`` (W, F) features named by ``names``; ``gait`` (W,) bool gait-like windows; ``walk_ref`` and
    ``stand_ref`` unit vectors (sensor frame) of the participant's walking and standing posture;
    ``window_samples`` samples per window; ``calibration`` the auto-calibration status."""
    x: np.ndarray
    names: tuple
    gait: np.ndarray
    walk_ref: np.ndarray
    stand_ref: np.ndarray
    window_samples: int
    calibration: str


def calibrated_g(acc_m_s2: np.ndarray, fs: float) -> tuple[np.ndarray, str]:
    """Acc in g after the estimators' auto-calibration from still 10-s windows (sphere fit when the still
    orientations cover the sphere, else a common gain so that still windows read 1 g). Unlabelled."""
    a, cal, _ = _calibrated_g(acc_m_s2, fs, None)
    return a, cal


def _calibrated_g(acc_m_s2: np.ndarray, fs: float, w: int | None):
    """``calibrated_g`` (``autocalibrate`` on its 10-s windows, bit for bit), and with ``w`` also the means of the
    calibrated acc over windows of ``w`` samples (None without)."""
    acc = np.ascontiguousarray(acc_m_s2, dtype=np.float64)
    wc = int(round(CALIBRATION_WINDOW_S * fs))          # autocalibrate's windows
    if acc.ndim != 2 or acc.shape[1] != 3 or wc <= 0 or acc.shape[0] < wc:
        a = acc / G
        cal = autocalibrate(a, fs)
        if cal.status != "none":
            a = (a - cal.offset_g) * cal.gain
        return a, cal.status, (None if w is None else _windows(a, w).mean(axis=1))
    a, m_w, s_w = WK.scaled_window_mean_std(acc, G, wc)
    cal = calibration_from_windows(m_w, s_w)
    if cal.status == "none":
        return a, cal.status, (None if w is None else (m_w if w == wc else WK.window_mean(a, w)))
    c, m = WK.affine_window_mean(a, np.asarray(cal.offset_g, np.float64), np.asarray(cal.gain, np.float64),
                                 w if w is not None else wc)
    return c, cal.status, (None if w is None else m)


def _windows(x: np.ndarray, w: int) -> np.ndarray:
    n = x.shape[0] // w
    return x[: n * w].reshape((n, w) + x.shape[1:])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS)


def lean_deg(directions: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Angle (deg) between each row of ``directions`` (W, 3) and the unit vector ``ref``."""
    return np.degrees(np.arccos(np.clip(_unit(directions) @ _unit(ref), -1.0, 1.0)))


def gait_windows(step_frac: np.ndarray, log_step: np.ndarray, cadence_hz: np.ndarray, *,
                 min_frac: float = 0.4, min_log_rms: float = -1.3) -> np.ndarray:
    """Gait-like windows without labels: dominant vertical frequency inside ``GAIT_BAND_HZ``, at least
    ``min_frac`` of the 0.3-6 Hz vertical power in that band and a step-band RMS ≥ 10**``min_log_rms`` g (50 mg).
    """
    lo, hi = GAIT_BAND_HZ
    return (cadence_hz >= lo) & (cadence_hz <= hi) & (step_frac >= min_frac) & (log_step >= min_log_rms)


def walking_reference(directions: np.ndarray, gait: np.ndarray, dyn: np.ndarray) -> np.ndarray:
    """The participant's upright walking posture: normalised median of the window mean directions over
    gait-like windows (≥ 3 needed), else over the 10 % most active windows, else over all windows."""
    d = _unit(directions)
    if gait.sum() >= 3:
        sel = gait
    elif d.shape[0] >= 10:
        sel = dyn >= np.percentile(dyn, 90)
    else:
        sel = np.ones(d.shape[0], bool)
    return _unit(np.median(d[sel], axis=0))


def standing_reference(directions: np.ndarray, gait: np.ndarray, still: np.ndarray, walk_ref: np.ndarray,
                       reach: int = 2) -> np.ndarray:
    """The participant's standing posture: median direction of still windows at most ``reach`` windows from a
    gait-like window (walking starts and ends in standing); the walking posture if there are fewer than 3."""
    near = np.convolve(gait.astype(float), np.ones(2 * reach + 1), mode="same") > 0
    sel = near & still & ~gait
    if sel.sum() < 3:
        return _unit(walk_ref)
    return _unit(np.median(_unit(directions[sel]), axis=0))


def posture_clusters(directions: np.ndarray, still: np.ndarray, walk_ref: np.ndarray,
                     iterations: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Two still-posture clusters of one participant, without labels: 2-medians of the still windows' unit
    directions (assignment by the larger cosine), started at the walking posture and at the still window at
    the 90th percentile of the lean from it. Returns (upright centre, other centre); the upright one is the
    cluster started at the walking posture. A sitting and a standing period give two clusters tens of degrees
    apart; with a single posture the centres are a few degrees apart (``cluster_sep_deg`` tells the model).
    Fewer than 4 still windows: both centres are the walking posture."""
    ref = _unit(walk_ref)
    ds = _unit(directions[still])
    if ds.shape[0] < 4:
        return ref, ref
    le = lean_deg(ds, ref)
    i0 = int(np.argsort(le)[min(ds.shape[0] - 1, int(0.9 * ds.shape[0]))])
    c = np.vstack([ref, ds[i0]])
    a = np.zeros(ds.shape[0], dtype=np.int64)
    for _ in range(iterations):
        a_new = np.argmax(ds @ c.T, axis=1)
        c = np.vstack([_unit(np.median(ds[a_new == k], axis=0)) if (a_new == k).any() else c[k] for k in range(2)])
        if np.array_equal(a_new, a):
            break
        a = a_new
    return c[0], c[1]


def _acf_at(v: np.ndarray, lag: np.ndarray) -> np.ndarray:
    """Normalised autocorrelation of each row of ``v`` (W, n) at the per-row integer ``lag`` (0 where the lag
    is not in 1..n-1)."""
    return acf_at_lag(np.ascontiguousarray(v, dtype=np.float64), np.asarray(lag, dtype=np.int64), _EPS)


def _bins(f: np.ndarray, lo: float, hi: float, closed: bool = False) -> tuple[int, int]:
    """[start, stop) of the frequency bins with lo ≤ f < hi (≤ hi when ``closed``): ``f`` increases."""
    idx = np.flatnonzero((f >= lo) & ((f <= hi) if closed else (f < hi)))
    return (int(idx[0]), int(idx[-1]) + 1) if idx.size else (0, 0)


def _band_spectrum(v: np.ndarray, fs: float, nfft: int, detrend: str, bands, peak: tuple | None = None):
    """Powers in ``bands`` ((lo, hi) Hz, lo ≤ f < hi) of the one-sided PSD of each row of ``v`` (W, n), with a
    boxcar window, zero-padded to ``nfft`` (what ``scipy.signal.periodogram(v, fs, nfft=nfft, axis=1,
    detrend=detrend)`` returns, equal to rounding): (W, len(bands)); with ``peak`` = (lo, hi) also the frequency
    of the largest PSD bin with lo ≤ f ≤ hi per row. The PSD itself is never stored (``_window_kernels.spectrum_bands``)."""
    X = sfft.rfft(signal.detrend(v, axis=1, type=detrend), n=nfft, axis=1)
    f = sfft.rfftfreq(nfft, 1.0 / fs)
    rng = np.array([_bins(f, lo, hi) for lo, hi in bands], dtype=np.int64).reshape(-1, 2)
    p0, p1 = _bins(f, *peak, closed=True) if peak is not None else (0, 1)
    if p1 <= p0:
        raise ValueError(f"window_features: no frequency bin in {peak} Hz at fs = {fs} Hz")
    # one-sided: every bin but DC (and Nyquist for an even nfft) doubled
    power, k = WK.spectrum_bands(X, 1.0 / (fs * v.shape[1]), (nfft + 1) // 2, rng[:, 0].copy(), rng[:, 1].copy(),
                                 p0, p1)
    return (power, f[p0:p1][k]) if peak is not None else power


def window_features(acc_m_s2: np.ndarray, sampling_rate_hz: float, window_s: float = 10.0) -> WindowFeatures:
    """Per-window features (see ``FEATURE_NAMES``) of one participant's recording (N, 3) m/s².

    Steps: auto-calibrate (``calibrated_g``); per window the mean acc direction (gravity), the vertical
    dynamic acc (projection of the 0.3-20 Hz acc on that direction) and its periodogram (zero-padded to
    0.05 Hz); gait-like windows (``gait_windows``) give the walking posture and the participant's typical
    cadence and gait intensity; still windows (dynamic RMS below the participant's 40th percentile) next to
    gait give the standing posture; two still-posture clusters (``posture_clusters``; still = not gait-like and
    dynamic RMS < 10**0.8 × the noise floor) give the lean to the upright and to the leaning still posture. Deterministic; raises ``ValueError`` on fewer than one window.
    """
    fs = float(sampling_rate_hz)
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    if acc.ndim != 2 or acc.shape[1] != 3 or not np.all(np.isfinite(acc)):
        raise ValueError("window_features: acc must be a finite (N, 3) array in m/s²")
    w = int(round(window_s * fs))
    if w < 8 or acc.shape[0] < w:
        raise ValueError(f"window_features: need at least one {window_s} s window ({w} samples), got {acc.shape[0]}")
    a, cal_status, mean = _calibrated_g(acc, fs, w)
    hi_cut = min(20.0, 0.45 * fs)
    sos_hp = signal.butter(2, [0.3, hi_cut], "bandpass", fs=fs, output="sos")
    sos_lp1 = signal.butter(2, 1.0, "lowpass", fs=fs, output="sos")
    dyn_full = signal.sosfiltfilt(sos_hp, a, axis=0)
    lp_full = signal.sosfiltfilt(sos_lp1, a, axis=0)

    A = _windows(a, w)                                 # (W, w, 3)
    D = _windows(dyn_full, w)
    LP = _windows(lp_full, w)
    u = _unit(mean)                                    # window gravity direction (mean = A.mean(axis=1))
    vert = np.einsum("wnk,wk->wn", D, u)               # vertical dynamic acc (g)
    # mean squares per window of the dynamic, horizontal (D − vert u) and vertical acc and of the jerk of ‖A‖
    dyn_ms, horiz_ms, vert_ms, jerk_ms = WK.window_mean_squares(a, dyn_full, vert, u, w, fs)
    dyn_rms = np.sqrt(dyn_ms)
    log_dyn = np.log10(dyn_rms + _EPS)

    nfft = max(w, int(2 ** np.ceil(np.log2(fs / 0.05))))
    bp, cadence = _band_spectrum(vert, fs, nfft, "constant", [(0.5, 1.4), GAIT_BAND_HZ, (2.4, 6.0), (0.3, 6.0)],
                                 peak=(0.5, 3.5))  # cadence: dominant frequency in 0.5-3.5 Hz
    vert_lp = np.einsum("wnk,wk->wn", A, u)            # for the slow band (includes < 0.3 Hz)
    low = _band_spectrum(vert_lp, fs, nfft, "linear", [(0.1, 0.5)])[:, 0]
    f = sfft.rfftfreq(nfft, 1.0 / fs)
    df = f[1] - f[0]
    rms = lambda p: np.log10(np.sqrt(p * df) + _EPS)  # noqa: E731  (one-sided PSD summed over a band -> RMS)
    log_low = rms(low)
    log_mid = rms(bp[:, 0])
    log_step = rms(bp[:, 1])
    log_high = rms(bp[:, 2])
    step_frac = bp[:, 1] / np.maximum(bp[:, 3], _EPS)
    lag = np.round(fs / np.maximum(cadence, 0.5)).astype(int)
    step_reg = _acf_at(vert, lag)
    stride_reg = _acf_at(vert, 2 * lag)
    vh = np.log10((np.sqrt(vert_ms) + _EPS) / (np.sqrt(horiz_ms) + _EPS))
    log_jerk = np.log10(np.sqrt(jerk_ms) + _EPS)
    # postural sway: tilt of the 1 Hz low-passed direction against the window mean direction
    tilt = np.degrees(np.arccos(np.clip(np.einsum("wnk,wk->wn", _unit(LP), u), -1.0, 1.0)))
    log_sway = np.log10(tilt.std(axis=1) + 1e-3)

    gait = gait_windows(step_frac, log_step, cadence)
    walk_ref = walking_reference(u, gait, dyn_rms)
    lean_w = lean_deg(u, walk_ref)
    # lying (trunk beyond the thesis' 70°, Eq. 54) is neither of the upright still postures: a 24 h day with a
    # night in bed would otherwise make "lying" the second still-posture cluster
    upright = lean_w <= LYING_DEG
    still = (log_dyn <= np.percentile(log_dyn, 40)) & ~gait & upright    # for the standing reference
    stand_ref = standing_reference(u, gait, still, walk_ref)
    lean_s = lean_deg(u, stand_ref)
    floor = np.percentile(log_dyn, 5)
    c_up, c_other = posture_clusters(u, ~gait & (log_dyn - floor < 0.8) & upright, walk_ref)
    lean_up = lean_deg(u, c_up)
    lean_other = lean_deg(u, c_other)
    sep = float(lean_deg(c_other[None, :], c_up)[0])
    gait_level = np.median(log_dyn[gait]) if gait.sum() >= 3 else np.percentile(log_dyn, 90)
    cad_ref = np.median(cadence[gait]) if gait.sum() >= 3 else float(np.mean(GAIT_BAND_HZ))

    x = np.column_stack([lean_w, lean_s, lean_up, lean_other, lean_other - lean_up, np.full(lean_w.shape, sep), log_dyn, log_dyn - floor, log_dyn - gait_level,
                         log_sway, log_low, log_mid, log_step, log_high, step_frac, cadence, cadence / cad_ref,
                         step_reg, stride_reg, vh, log_jerk, gait.astype(float)])
    return WindowFeatures(x=x, names=FEATURE_NAMES, gait=gait, walk_ref=walk_ref, stand_ref=stand_ref,
                          window_samples=w, calibration=cal_status)


def add_context(x: np.ndarray, names: tuple, half_widths: tuple = (1, 3)) -> tuple[np.ndarray, tuple]:
    """Temporal context: append, for each half width h, the mean of every feature over windows i−h..i+h
    (truncated at the recording's ends). Activities last minutes, so the neighbours' features are evidence
    for the current window. Returns (W, F × (1 + len(half_widths))) and the extended names (``name@±h``)."""
    x = np.asarray(x, dtype=np.float64)
    cs = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    n = x.shape[0]
    cols, out_names = [x], list(names)
    for h in half_widths:
        lo = np.clip(np.arange(n) - h, 0, n)
        hi = np.clip(np.arange(n) + h + 1, 0, n)
        cols.append((cs[hi] - cs[lo]) / (hi - lo)[:, None])
        out_names += [f"{nm}@±{h}" for nm in names]
    return np.hstack(cols), tuple(out_names)


def moving_fraction(acc_m_s2: np.ndarray, sampling_rate_hz: float, window_s: float, gait_level_g: float,
                    rel: float = 0.2) -> np.ndarray:
    """(W,) fraction of the 1-s chunks of each window (same windows as ``window_features``) whose 0.3-20 Hz
    acc RMS (vector norm, g, after ``calibrated_g``) is at least ``rel`` × ``gait_level_g``, the participant's
    typical walking intensity (``10 ** median(log_dyn)`` over its gait-like windows). A person walking or
    climbing stairs moves in nearly every second at about that level; standing or sitting still stays far
    below it (a few mg against ≈ 0.2 g). Used to check labels against the signal (``stridelab.validation.bench.activity``).
    """
    fs = float(sampling_rate_hz)
    w = int(round(window_s * fs))
    k = max(1, int(round(fs)))
    a, _ = calibrated_g(acc_m_s2, fs)
    sos = signal.butter(2, [0.3, min(20.0, 0.45 * fs)], "bandpass", fs=fs, output="sos")
    d = signal.sosfiltfilt(sos, a, axis=0)
    n_win = d.shape[0] // w
    m = w // k
    chunks = d[: n_win * w].reshape(n_win, w, 3)[:, : m * k].reshape(n_win, m, k, 3)
    rms = np.sqrt((chunks ** 2).sum(axis=3).mean(axis=2))
    return (rms >= rel * float(gait_level_g)).mean(axis=1)
