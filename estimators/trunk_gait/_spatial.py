"""Step and stride length by the inverted-pendulum model of Zijlstra & Hof 2003.

Zijlstra & Hof 2003, "Assessment of spatio-temporal gait parameters from trunk accelerations during human walking",
Gait Posture 18:1, doi:10.1016/S0966-6362(02)00190-X: the vertical trunk acceleration is double-integrated
(4th-order zero-lag Butterworth high-pass at 0.1 Hz before and after each integration, their §2.3), the vertical
excursion h of each step (max - min between two initial contacts) gives the step length
``2 * sqrt(2 l h - h²)`` (their Eq. 1, l = pendulum length = leg length), multiplied by a correction factor K
(their 1.25; ours chosen by cross-validation, validation/provenance.toml). Stride length = sum of two steps.
Deviation: the position is detrended linearly between consecutive contacts before the excursion is taken, so
integration drift (large after a sit-to-stand or during turns) does not inflate h.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from stridelab.estimators.trunk_gait._filters import butter_filtfilt


def vertical_position(v_up: np.ndarray, fs_hz: float, highpass_hz: float) -> np.ndarray:
    """(N,) vertical position, m, from the upward acceleration (m/s², gravity removed) of one gait sequence."""
    if len(v_up) < 16:
        return np.zeros(len(v_up))
    pad = min(len(v_up) - 1, int(3 * fs_hz))
    dt = 1.0 / fs_hz

    def hp(x):
        return butter_filtfilt(4, highpass_hz, "highpass", fs_hz, x, padlen=pad)
    vel = hp(cumulative_trapezoid(hp(v_up), dx=dt, initial=0.0))
    return hp(cumulative_trapezoid(vel, dx=dt, initial=0.0))


def _row_nanmedian(w: np.ndarray) -> np.ndarray:
    """``np.nanmedian(w, axis=1)`` for rows with at least one finite value, by one sort (NaNs sort last): the
    numpy function takes a masked-array path per call that cost a quarter of the 24 h day's CPU time."""
    srt = np.sort(w, axis=1)
    k = np.sum(np.isfinite(w), axis=1)
    r = np.arange(len(w))
    return 0.5 * (srt[r, (k - 1) // 2] + srt[r, k // 2])


def hampel(x: np.ndarray, half_width: int, n_sigma: float, groups: np.ndarray | None = None) -> np.ndarray:
    """Hampel identifier (Pearson et al. 2016, "Generalized Hampel filters", EURASIP J Adv Signal Process 2016:87,
    doi:10.1186/s13634-016-0383-6): a value further than ``n_sigma`` × 1.4826 × MAD from the median of the
    ``2 half_width + 1`` values around it is replaced by that median. Windows are cut at the edges and do not
    cross ``groups`` (runs of regular steps); NaNs are ignored. Soltani et al. 2021 (IEEE TNSRE 29:1955,
    doi:10.1109/TNSRE.2021.3111681) smooth the pendulum step lengths this way (a missed contact, a turning or a
    shuffling step gives one implausible step among regular ones). Deviation: the MAD is floored at 1 % of the
    median."""
    x = np.asarray(x, float)
    n = len(x)
    if half_width <= 0 or n < 3:
        return x.copy()
    g = np.zeros(n, np.int64) if groups is None else np.asarray(groups)
    j = np.arange(n)[:, None] + np.arange(-half_width, half_width + 1)[None, :]
    inside = (j >= 0) & (j < n)
    jc = np.clip(j, 0, n - 1)
    w = np.where(inside & (g[jc] == g[:, None]), x[jc], np.nan)
    ok = np.isfinite(x) & (np.sum(np.isfinite(w), axis=1) >= 3)
    out = x.copy()
    if not ok.any():
        return out
    med = _row_nanmedian(w[ok])
    # scale floor 1 % of the median (deviation): with equal neighbours the MAD is 0 and every other value would
    # count as an outlier
    mad = np.maximum(_row_nanmedian(np.abs(w[ok] - med[:, None])), 0.01 * np.abs(med))
    bad = np.abs(x[ok] - med) > n_sigma * 1.4826 * mad
    out[np.flatnonzero(ok)[bad]] = med[bad]
    return out


def step_lengths(pos: np.ndarray, ic_idx: np.ndarray, leg_length_m: float, correction: float) -> np.ndarray:
    """(K-1,) step length, m, between consecutive initial contacts (Zijlstra & Hof 2003 Eq. 1 × K)."""
    if len(ic_idx) < 2:
        return np.empty(0)
    idx = np.asarray(ic_idx, np.int64)
    # the trunk is at the same height at consecutive contacts (same phase of the step): remove the straight line
    # between them (drift left by the integration) before taking the excursion (deviation from the paper)
    k = np.searchsorted(idx, np.arange(idx[0], idx[-1]), side="right") - 1
    i0, i1 = idx[k], idx[k + 1]
    t = np.arange(idx[0], idx[-1])
    line = pos[i0] + (pos[i1] - pos[i0]) * (t - i0) / np.maximum(i1 - i0, 1)
    d = np.zeros(len(pos))
    d[idx[0]:idx[-1]] = pos[idx[0]:idx[-1]] - line
    h = (np.maximum.reduceat(d, idx) - np.minimum.reduceat(d, idx))[:-1]       # excursion over [IC_i, IC_i+1)
    h = np.minimum(h, leg_length_m)
    return correction * 2.0 * np.sqrt(np.maximum(2.0 * leg_length_m * h - h * h, 0.0))


def step_tilt_deg(acc_body: np.ndarray, ic_idx: np.ndarray) -> np.ndarray:
    """(K-1,) angle, deg, between each step's mean specific force (``acc_body`` (N, 3), body frame of the gait
    sequence, y = its mean up) and that up direction: how far the trunk leans away from its walking posture.

    The inverted pendulum holds for an upright trunk rising and falling over the stance foot. Where the trunk leans
    well away from the sequence's walking posture — the first strides out of a chair, still bent forward while
    rising (sit-to-walk), or stooping — its vertical movement is the transition's, not the pendulum's, and Eq. 1
    returns long strides for what are short ones (Mobilise-D HA-001 Test11: the strides of two sit-to-walk starts
    lean 15-18° and come out at 1.4-2.3 m against INDIP's 0.2-0.3 m; walking strides lean a median 1°, 99 % under
    6° on the Voisard trials). ``_pipeline.bout_spatial`` can leave such strides out of the bout values
    (``sl_max_tilt_deg``)."""
    idx = np.asarray(ic_idx, np.int64)
    if len(idx) < 2:
        return np.empty(0)
    s = np.add.reduceat(np.asarray(acc_body, float), idx, axis=0)[:-1]      # sums over [IC_i, IC_i+1)
    n = np.maximum(np.linalg.norm(s, axis=1), 1e-12)
    return np.degrees(np.arccos(np.clip(s[:, 1] / n, -1.0, 1.0)))


def step_heading_change(yaw_rate: np.ndarray, fs_hz: float, ic_idx: np.ndarray) -> np.ndarray:
    """(K-1,) heading change, rad, attributed to each step between consecutive initial contacts.

    ``yaw_rate``: (N,) angular rate about the vertical, rad/s. The pelvis turns back and forth once per stride
    (about ±5° in straight walking), so a single step's heading change is mostly that sway; over a whole stride
    it cancels. Each step therefore gets half the heading change of the strides that contain it (the mean of
    [IC_i-1, IC_i+1] and [IC_i, IC_i+2] where they exist; a lone step keeps its own change)."""
    idx = np.asarray(ic_idx, np.int64)
    k = len(idx)
    if k < 2:
        return np.empty(0)
    psi = np.concatenate([[0.0], np.cumsum(np.asarray(yaw_rate, float)) / fs_hz])
    h = psi[np.clip(idx, 0, len(yaw_rate))]              # heading at each contact (rad, arbitrary origin)
    if k == 2:
        return np.array([h[1] - h[0]])
    stride = (h[2:] - h[:-2]) / 2.0                       # stride j covers steps j and j+1 (K-2 strides)
    acc = np.zeros(k - 1)
    cnt = np.zeros(k - 1)
    acc[:-1] += stride
    cnt[:-1] += 1
    acc[1:] += stride
    cnt[1:] += 1
    return acc / cnt


def turn_shortened(step_m: np.ndarray, heading_change_rad: np.ndarray, per_rad: float) -> np.ndarray:
    """Step lengths of turning steps shortened: ``step / (1 + per_rad · |Δψ|)``.

    The pendulum model assumes straight progression: in a turn the feet take short, partly sideways or pivoting
    steps while the trunk still rises and falls by nearly a full step's excursion, so Eq. 1 overestimates them
    (on the Voisard U-turns by a median of about 29 % relative to straight strides; docs/trunk_gait.md).
    ``per_rad`` (``sl_turn_per_rad``) is an empirical factor chosen by cross-validation (no published value);
    0 turns the correction off."""
    if per_rad <= 0:
        return np.asarray(step_m, float)
    return np.asarray(step_m, float) / (1.0 + per_rad * np.abs(np.asarray(heading_change_rad, float)))
