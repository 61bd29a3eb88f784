"""Thesis ch. 7 detectors: lying transitions (§7.2.4), StSi/SiSt (§7.2.5), steps, walking bouts and walking
modality (§7.2.6). Sample-level signals in, sample indices / seconds out; few candidates, so the loops here
run over events, never over samples (the sample work is vectorised or numba)."""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy import signal

from stridelab.estimators.activity._signals import (chest_height_change_m, cumulative_svm_sign, runs, vertical_acc_g)
from stridelab.estimators.activity._types import (DOWN, LEVEL, LYSI, SILY, SIST, STSI, UP, ActivityParams, Bouts,
                                        Transitions)


@njit(cache=True)
def _hysteresis(x, lo, hi, init):
    """State flips to 1 when x > hi and back to 0 when x < lo (one pass)."""
    out = np.empty(x.shape[0], dtype=np.bool_)
    s = init
    for i in range(x.shape[0]):
        if s:
            if x[i] < lo:
                s = False
        elif x[i] > hi:
            s = True
        out[i] = s
    return out


@njit(cache=True)
def _walk_to_minimum(theta, i, step, limit, tol):
    """Move from i in direction ``step`` while θ keeps decreasing (spec §4.3 step 3: strictly, tol = 0; with
    tol > 0 a rise of less than tol degrees above the lowest value so far does not stop the search); returns
    the lowest sample visited; ≤ limit samples."""
    n = theta.shape[0]
    best = i
    k = 0
    j = i
    while k < limit:
        nj = j + step
        if nj < 0 or nj >= n:
            break
        if tol == 0.0:
            if not theta[nj] < theta[j]:
                break
        elif theta[nj] > theta[best] + tol:
            break
        j = nj
        if theta[j] < theta[best]:
            best = j
        k += 1
    return best


def lying_state(theta_deg: np.ndarray, p: ActivityParams) -> np.ndarray:
    """(N,) bool: trunk inclination beyond ``lying_deg`` with ± ``lying_hysteresis_deg`` hysteresis."""
    th = np.ascontiguousarray(theta_deg, dtype=np.float64)
    if th.size == 0:
        return np.zeros(0, dtype=bool)
    return _hysteresis(th, p.lying_deg - p.lying_hysteresis_deg, p.lying_deg + p.lying_hysteresis_deg,
                       bool(th[0] > p.lying_deg))


def detect_transitions(theta_deg, ga, acc, sec_static, sec_ga, fs: float, p: ActivityParams,
                       lying: np.ndarray | None = None, return_candidates: bool = False):
    """SiLy/LySi (70° crossings, direction from the sign of the GA_v gradient, static frontal-gravity
    confirmation) and StSi/SiSt (20° excursions, ΔY (Eq. 55-56) ≥ dy_fraction × thigh, sign of the cumulative
    SVM integral (Eq. 57) or of ΔY). All inputs in the analysis frame (x frontal, y vertical, z lateral), in g
    and degrees.

    With ``return_candidates`` also returns every sit/stand candidate excursion (a ``Transitions`` with the
    kind its ΔY / CI sign gives, accepted or not) and a bool mask of the accepted ones, for the posture-sequence
    check of the timeline (``sitstand_resolve``)."""
    n = theta_deg.shape[0]
    ts, kinds, t0s, t1s, dys = [], [], [], [], []
    if lying is None:
        lying = lying_state(theta_deg, p)
    n_sec = sec_static.shape[0]
    if p.side_lying:
        horiz = np.hypot(sec_ga[:, 0], sec_ga[:, 2])
    else:
        horiz = np.abs(sec_ga[:, 0])
    lying_ok = sec_static & (horiz >= p.lying_static_g)
    # -- lying transitions: flips of the hysteresis state, instant = the nearest 70° crossing
    flips = np.flatnonzero(np.diff(lying.astype(np.int8))) + 1
    above = theta_deg > p.lying_deg
    search = int(round(p.static_search_s))
    for i in flips:
        j = i
        while j > 0 and above[j - 1] == above[i]:
            j -= 1
        j = max(j, 0)
        grad = float(ga[min(j + 1, n - 1), 1] - ga[max(j - 1, 0), 1])
        kind = SILY if grad < 0 else LYSI              # GA_v falling (θ rising) -> sit-to-lie
        s = int(j / fs)
        win = lying_ok[s:min(n_sec, s + search + 1)] if kind == SILY else lying_ok[max(0, s - search):s + 1]
        if not win.any():
            continue                                    # unknown movement (thesis: e.g. bending far forward)
        ts.append(j / fs); kinds.append(kind); t0s.append(j / fs); t1s.append(j / fs); dys.append(np.nan)
    # -- sit/stand: excursions above 20° that stay below 70°
    if p.dy_source == "ga":
        a_v = vertical_acc_g(ga[:, 0], ga[:, 1])
    else:
        a_v = None
    limit = int(round(p.minima_search_s * fs))
    max_len = p.max_transition_s * fs
    c_t, c_k, c_0, c_1, c_dy, c_ok = [], [], [], [], [], []
    starts, ends = runs(theta_deg > p.sitstand_deg)
    for a, b in zip(starts, ends):
        if b - a > max_len or a == 0 or b >= n:
            continue
        if lying[a:b].any() or theta_deg[a:b].max() >= p.lying_deg:
            continue
        t_s = _walk_to_minimum(theta_deg, a, -1, limit, p.minima_tolerance_deg)
        t_e = _walk_to_minimum(theta_deg, b - 1, 1, limit, p.minima_tolerance_deg)
        if t_e - t_s < 3:
            continue
        dy = _window_dy(acc, ga, a_v, t_s, t_e, fs, p.dy_source)
        pad = int(round(p.dy_pad_s * fs))
        if pad > 0:                 # the θ minima can cut the chest motion (e.g. a window starting mid-rise)
            i0, i1 = max(0, t_s - pad), min(n - 1, t_e + pad)
            if _quiet(acc, i0, t_s, p.static_std_g) and _quiet(acc, t_e, i1, p.static_std_g):
                dy2 = _window_dy(acc, ga, a_v, i0, i1, fs, p.dy_source)
                if abs(dy2) > abs(dy):
                    dy = dy2
        ok = abs(dy) >= p.dy_fraction * p.thigh_length_m   # else bowing, squat, reaching: not a sit/stand
        svm = np.linalg.norm(ga[t_s:t_e + 1], axis=1) - 1.0
        sign = cumulative_svm_sign(svm) if p.sitstand_sign == "ci" else (1 if dy > 0 else -1)
        kind = STSI if sign < 0 else SIST
        c_t.append(0.5 * (t_s + t_e) / fs); c_k.append(kind); c_0.append(t_s / fs); c_1.append(t_e / fs)
        c_dy.append(dy); c_ok.append(ok)
        if ok:
            ts.append(0.5 * (t_s + t_e) / fs); kinds.append(kind); t0s.append(t_s / fs); t1s.append(t_e / fs)
            dys.append(dy)
    order = np.argsort(np.asarray(ts, dtype=np.float64), kind="stable")
    f = lambda v, dt=np.float64: np.asarray(v, dtype=dt)[order]  # noqa: E731
    tr = Transitions(t_s=f(ts), kind=f(kinds, np.int8), start_s=f(t0s), end_s=f(t1s), dy_m=f(dys))
    if not return_candidates:
        return tr
    g = lambda v, dt=np.float64: np.asarray(v, dtype=dt)  # noqa: E731  (excursions come in time order)
    cand = Transitions(t_s=g(c_t), kind=g(c_k, np.int8), start_s=g(c_0), end_s=g(c_1), dy_m=g(c_dy))
    return tr, cand, np.asarray(c_ok, dtype=bool)


def _quiet(acc, i0, i1, std_g):
    """No walking-like movement in samples [i0, i1): std of ‖a‖ below ``std_g`` (the ΔY padding must
    start and end at rest, or the mean-removed double integral drifts)."""
    if i1 - i0 < 2:
        return True
    return float(np.linalg.norm(acc[i0:i1], axis=1).std()) < std_g


def _window_dy(acc, ga, a_v, i0, i1, fs, source="raw"):
    """ΔY (Eq. 56) over samples [i0, i1] from a vertical acceleration:

    ``"ga"``: a_vg from the GA components (Eq. 55, ``a_v`` given, thesis); ``"raw"``: the raw acc projected on
    the GA direction (raw form of Eq. 55); ``"norm"``: ‖a‖ (extension). ‖g + d‖ = g + d·ĝ + O(|d⊥|²/2g), so
    ‖a‖ − g is the vertical acceleration to first order without any orientation estimate: no lag of the causal
    GA filter (which tilts the projection by up to 10-15° while the trunk leans 30°, i.e. a spurious −(1 − cos δ)
    g ≈ −0.03 g, as large as the transition acceleration itself) and no sensitivity to the mounting; the
    second-order term is < 0.015 m/s² for a 0.5 m/s² horizontal acceleration. Constant offsets are removed with
    the window mean (Eq. 56)."""
    if source == "norm":
        x = acc[i0:i1 + 1]
        av = np.sqrt(np.einsum("ij,ij->i", x, x))
    elif a_v is None:
        g = ga[i0:i1 + 1]
        av = np.einsum("ij,ij->i", acc[i0:i1 + 1], g) / np.linalg.norm(g, axis=1)
    else:
        av = a_v[i0:i1 + 1]
    return chest_height_change_m(av, fs)[0]


def step_signal(acc_g: np.ndarray, ga: np.ndarray, fs: float, p: ActivityParams,
                mag: np.ndarray | None = None) -> np.ndarray:
    """Signal whose positive peaks are steps (in g).

    ``svm_walk_source="ga"``: thesis Eq. 57, SVM = ‖GA‖ − g. ``"raw"``: ‖a‖ − 1 g low-passed at
    ``step_lowpass_hz``. ``"vertical"`` (default): the raw acceleration projected on the GA gravity direction
    (the raw-component form of Eq. 55, a_v = a·GA/‖GA‖ − 1 g), band-passed ``step_highpass_hz``–
    ``step_lowpass_hz`` (2nd-order Butterworth, causal): orientation-free like ‖a‖, free of the horizontal
    sway at the stride frequency and of static offsets (an imperfect auto-calibration)."""
    if p.svm_walk_source == "ga":
        return np.sqrt(np.einsum("ij,ij->i", ga, ga)) - 1.0
    if p.svm_walk_source == "vertical":
        from stridelab.estimators.activity._kernels import vertical_projection
        x = vertical_projection(np.ascontiguousarray(acc_g), np.ascontiguousarray(ga))
        if x.size == 0:
            return x
        hi = min(p.step_lowpass_hz, 0.45 * fs)
        sos = signal.butter(2, [p.step_highpass_hz, hi], btype="bandpass", fs=fs, output="sos")
        return signal.sosfilt(sos, x - x[0])                   # zero state = steady state of a constant start
    if mag is None:
        mag = np.sqrt(np.einsum("ij,ij->i", acc_g, acc_g)) - 1.0
    sos = signal.butter(2, min(p.step_lowpass_hz, 0.45 * fs), fs=fs, output="sos")
    zi = signal.sosfilt_zi(sos) * (mag[0] if mag.size else 0.0)
    return signal.sosfilt(sos, mag, zi=zi)[0] if mag.size else mag


def step_threshold(svm: np.ndarray, fs: float, p: ActivityParams) -> np.ndarray | float:
    """Step peak height threshold: ``step_threshold_g`` (thesis: one predefined threshold), or with
    ``step_relative > 0`` (extension) the larger of it and ``step_relative`` × the local step amplitude
    √2 · RMS(step signal) over ``step_rms_window_s`` — adapts to a slow, weak or asymmetric gait."""
    if p.step_relative <= 0 or svm.size == 0:
        return p.step_threshold_g
    from stridelab.estimators.activity._kernels import step_threshold_kernel
    w = max(3, int(round(p.step_rms_window_s * fs)))
    # np.maximum(thr, k·√max(uniform_filter1d(svm², w, mode="nearest"), 0)) with k = step_relative·√2, in one pass
    return step_threshold_kernel(np.ascontiguousarray(svm, dtype=np.float64), w, float(p.step_threshold_g),
                                 float(p.step_relative * np.sqrt(2.0)))


def detect_steps(svm: np.ndarray, fs: float, p: ActivityParams) -> np.ndarray:
    """Positive step-signal peaks above the (fixed or adaptive, ``step_threshold``) threshold, at least
    ``step_min_interval_s`` apart (sample indices)."""
    if svm.size < 3:
        return np.zeros(0, dtype=np.int64)
    from stridelab.estimators.activity._kernels import prominent_peaks
    h = step_threshold(svm, fs, p)
    pk, _ = signal.find_peaks(svm, height=h, distance=max(1, int(p.step_min_interval_s * fs)))
    # find_peaks(prominence=...) applies the prominence last, after height and distance: the same selection
    pk = pk.astype(np.int64)
    return pk[prominent_peaks(np.ascontiguousarray(svm, dtype=np.float64), pk, 0.5 * p.step_threshold_g)]


def group_bouts(peaks: np.ndarray, fs: float, p: ActivityParams) -> list[np.ndarray]:
    """Runs of ≥ ``min_bout_steps`` successive peaks with intervals in [min, max] step duration."""
    if peaks.size < p.min_bout_steps:
        return []
    d = np.diff(peaks) / fs
    ok = (d >= p.step_min_interval_s) & (d <= p.step_max_interval_s)
    out = []
    for a, b in zip(*runs(ok)):              # peaks a..b (b = last interval index + 1)
        if b - a + 1 >= p.min_bout_steps:
            out.append(peaks[a:b + 1])
    return out


def classify_bouts(groups: list[np.ndarray], theta_deg: np.ndarray, ga: np.ndarray, fs: float,
                   p: ActivityParams) -> tuple[Bouts, np.ndarray, np.ndarray]:
    """Upright check, level vs stairs and up vs down (§7.2.6). Returns (bouts, step samples, step class).

    ``stairs_mode="thesis"``: per bout, non-level if var(GA_v) > stairs_var_g2, then up if the area under
    GA_f per second (mean GA_f) > stairs_up_gf_g. ``"relative"`` (extension): per step, stairs if the local
    cadence (median of 5 intervals) is below ``stairs_cadence_ratio`` × the recording's median walking
    cadence; up if the lean over those steps exceeds the median walking lean by ``stairs_lean_deg``; the bout
    is split where the modality changes.
    """
    kept = []
    for g in groups:
        if theta_deg[g[0]:g[-1] + 1].mean() <= p.upright_deg:
            kept.append(g)
    empty = Bouts(*(np.zeros(0) for _ in range(2)), np.zeros(0, np.int64), np.zeros(0, np.int8),
                  *(np.zeros(0) for _ in range(3)))
    if not kept:
        return empty, np.zeros(0, np.int64), np.zeros(0, np.int8)
    def lean(a: int, b: int) -> np.ndarray:                    # forward lean + (spec §4.2: GA_f = −g sin θ),
        return np.degrees(np.arctan2(-ga[a:b, 0], ga[a:b, 1]))  # only where there are bouts (not the whole day)

    pieces = []                                                # (peaks, modality)
    if p.stairs_mode == "thesis":
        for g in kept:
            seg = ga[g[0]:g[-1] + 1]
            if seg[:, 1].var() > p.stairs_var_g2:
                pieces.append((g, UP if -seg[:, 0].mean() > p.stairs_up_gf_g else DOWN))
            else:
                pieces.append((g, LEVEL))
    else:
        all_int = np.concatenate([np.diff(g) for g in kept]) / fs
        ref_int = float(np.median(all_int))
        ref_lean = float(np.median(np.concatenate([lean(g[0], g[-1] + 1) for g in kept])))
        for g in kept:
            d = np.diff(g) / fs
            dd = np.concatenate([d[:1], d])                  # interval ending at each step (first: next one)
            k = min(5, dd.size)
            loc = _rolling_median(dd, k)
            stairs = ref_int / loc < p.stairs_cadence_ratio
            cl = np.concatenate([[0.0], np.cumsum(lean(g[0], g[-1] + 1))])
            j = g - g[0]                                      # mean lean over each step interval (not at the
            ls = (cl[j[1:]] - cl[j[:-1]]) / np.maximum(np.diff(j), 1)   # peak: the lean oscillates per step)
            lean_loc = _rolling_median(np.concatenate([ls[:1], ls]), k)
            mod = np.where(stairs, np.where(lean_loc - ref_lean > p.stairs_lean_deg, UP, DOWN), LEVEL)
            mod = _smooth_labels(mod.astype(np.int8), 5)
            cut = np.flatnonzero(np.diff(mod)) + 1
            for sub, m in zip(np.split(g, cut), np.split(mod, cut)):
                pieces.append((sub, int(m[0])))
    st, en, ns, mo, cad, vg, gf = [], [], [], [], [], [], []
    for g, m in pieces:
        half = 0.5 * (float(np.median(np.diff(g))) if g.size > 1 else fs * 0.5)
        a, b = (g[0] - half) / fs, (g[-1] + half) / fs
        st.append(max(a, 0.0)); en.append(b); ns.append(g.size); mo.append(m)
        cad.append(60.0 * g.size / max(b - a, 1e-9))
        seg = ga[g[0]:g[-1] + 1]
        vg.append(float(seg[:, 1].var())); gf.append(float(seg[:, 0].mean()))
    bouts = Bouts(np.asarray(st), np.asarray(en), np.asarray(ns, np.int64), np.asarray(mo, np.int8),
                  np.asarray(cad), np.asarray(vg), np.asarray(gf))
    steps = np.concatenate([g for g, _ in pieces])
    smod = np.concatenate([np.full(g.size, m, np.int8) for g, m in pieces])
    return bouts, steps, smod


def _rolling_median(x: np.ndarray, k: int) -> np.ndarray:
    if x.size <= 1 or k <= 1:
        return x.astype(np.float64)
    from numpy.lib.stride_tricks import sliding_window_view
    h = k // 2
    xp = np.concatenate([np.full(h, x[0]), x, np.full(k - 1 - h, x[-1])])
    return np.median(sliding_window_view(xp, k), axis=1)


def _smooth_labels(m: np.ndarray, k: int) -> np.ndarray:
    """Majority vote over k neighbours (removes one- or two-step modality flips)."""
    if m.size <= 2:
        return m
    from numpy.lib.stride_tricks import sliding_window_view
    h = k // 2
    xp = np.concatenate([np.full(h, m[0]), m, np.full(k - 1 - h, m[-1])])
    w = sliding_window_view(xp, min(k, xp.size))
    counts = np.stack([(w == c).sum(axis=1) for c in (LEVEL, UP, DOWN)], axis=1)
    return np.asarray((LEVEL, UP, DOWN), np.int8)[np.argmax(counts, axis=1)]
