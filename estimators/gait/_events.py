"""Real-time initial/terminal contact (IC/TC) detection on the foot pitch signal (Nazarahari 2021, ch. 6).

Spec: ``spec/thesis_calib_gait_posture.md`` §3.2–3.3 (Algorithm 1), §9.2. Signal (Eq. 52, normative §3.2):

    s_k = e_z · (R_k u_S)        u_S = foot anterior axis in sensor coordinates, horizontal at stance     (P1)

so s = −sin(pitch): s > 0 toes up (IC region, local maximum), s < 0 toes down (TC region, local minimum).

Rules at sample k (candidate extremum j = k − 1, look-ahead 1 sample, Algorithm 1):
    local min at j:  s_j < s_{j−i} ∀ i = 1…N_w,  s_j < s_{j+1},  #{s_{j−i} < s_{j−i−1}} ≥ ⌈0.8 N_w⌉      (R1)
    TC at k:  flag = 0,  k − TC_last > N_ref,  s_k < T,  local min at k−1                                   (R2)
    IC at k:  flag = 1,  k − IC_last > N_ref,  s_k > T,  local max at k−1                                   (R3)
with T = −0.2, N_ref = N_w = round(0.15 f_s) (15 at 100 Hz), strict TC → IC → TC alternation (flag).

Extension when a stance mask is given (batch ``foot_kinematics`` passes its zero-velocity samples; not in the
thesis, off without a mask):
    (R4) a foot lifted *flat* (turning, side or shuffling step, the first step out of quiet standing) has no
    push-off, so s never passes below T and (R2) finds no TC; strict alternation then also blocks the next heel
    strike. If, while flag = 0, the foot has stood still for ≥ N_ref samples in a stance run that began after the
    last IC (or anywhere before the first IC) and then left it (sample e,
    first moving sample), a local maximum at j = k − 1 (R1, reversed) with s_k > T and
    s_j > s_e + M_ic (M_ic = 0.05 ≈ 3° toes up above the pitch held at the lift: a few times the stance pitch noise,
    σ ≈ 0.01, so that the normal heel-off → push-off fall of s can never satisfy it) is a heel strike: TC at e
    (foot-off without push-off, reported late, at k) then IC at j. Causal; the alternation is kept.

One numba step function works on a state vector; :class:`GaitEventDetector` calls it per pushed sample and
:func:`detect_ic_tc` calls it in a compiled loop, so streaming and batch are identical by construction (tested).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = ["IcTcParams", "GaitEvents", "GaitEventDetector", "detect_ic_tc", "pitch_signal", "refine_toe_off",
           "refine_heel_strike"]


@dataclass(frozen=True)
class IcTcParams:
    """Parameters of Algorithm 1 in seconds (rate-independent; spec §3.3 scaling rule).

    threshold: T on s = −sin(pitch) (−0.2 ≈ 11.5° toes down).
    refractory_s: same-type events must be more than this apart (0.15 s = 15 samples at 100 Hz).
    lookback_s: look-back window N_w for the extremum (0.15 s).
    trend_fraction: share of monotone pairs required in the look-back window (0.8).
    flat_lift_margin: M_ic of (R4), only used with a stance mask.
    """
    threshold: float = -0.2
    refractory_s: float = 0.15
    lookback_s: float = 0.15
    trend_fraction: float = 0.8
    flat_lift_margin: float = 0.05


@dataclass(frozen=True)
class GaitEvents:
    """Events of one foot, sample indices into the input.

    ic_idx, tc_idx: (K,) int64 event = the extremum sample k−1 (best estimate of the contact instant).
    ic_detect_idx, tc_detect_idx: (K,) int64 detection sample k (when a streaming detector knows it; +1).
    tc_pitch_min_idx: None for Algorithm 1's own events; when ``foot_kinematics`` refined the TCs to the toe-off
        (batch step T1, ``refine_toe_off``) ``tc_idx`` holds the refined TCs and this the thesis' plain TCs.
    ic_pitch_max_idx: the same for the ICs: None, or the pitch maxima when ``foot_kinematics`` moved the ICs to
        the loading rotation (batch step H1, ``refine_heel_strike``).
    """
    ic_idx: np.ndarray
    tc_idx: np.ndarray
    ic_detect_idx: np.ndarray
    tc_detect_idx: np.ndarray
    params: IcTcParams
    tc_pitch_min_idx: np.ndarray | None = None
    ic_pitch_max_idx: np.ndarray | None = None


# state layout: [k, flag, last_tc, last_ic, n_filled, head, stance_run, stance_start, exit_k];
# ring buffer of length n_w + 3 and the float state [s at exit] kept separately
_K, _FLAG, _LTC, _LIC, _FILL, _HEAD, _RUN, _RSTART, _EXIT = range(9)


@njit(cache=True)
def _is_ext(buf, head, L, n_w, need, sign):
    """(R1) on the ring buffer: ``buf[(head-1) % L]`` = s_k = s_{j+1}, ``buf[(head-2) % L]`` = s_j."""
    sk = buf[(head - 1) % L]
    sj = buf[(head - 2) % L]
    if not sign * (sk - sj) > 0:
        return False
    for i in range(1, n_w + 1):
        if not sign * (buf[(head - 2 - i) % L] - sj) > 0:
            return False
    cnt = 0
    for i in range(1, n_w + 1):
        if sign * (buf[(head - 3 - i) % L] - buf[(head - 2 - i) % L]) > 0:
            cnt += 1
    return cnt >= need


@njit(cache=True)
def _step(state, fstate, buf, s, stance, thr, n_ref, n_w, need, margin):
    """Push one sample; returns 0 (none), 1 (TC at k), 2 (IC at k) or 3 (TC at ``state[_EXIT]`` and IC at k).
    Rules (R2), (R3); (R4) when ``stance`` (−1 = unknown, 0 = moving, 1 = still) is ever ≥ 0."""
    L = buf.shape[0]
    state[_K] += 1
    k = state[_K]
    buf[state[_HEAD]] = s
    state[_HEAD] = (state[_HEAD] + 1) % L
    # (R4) bookkeeping: a stance run of >= n_ref samples that began after the last IC, then left at k
    if stance == 1:
        if state[_RUN] == 0:
            state[_RSTART] = k
        state[_RUN] += 1
    elif stance == 0:
        if state[_RUN] >= n_ref and state[_RSTART] > state[_LIC] - 1 and state[_FLAG] == 0:
            state[_EXIT] = k
            fstate[0] = s
        state[_RUN] = 0
    if state[_FILL] < L:
        state[_FILL] += 1
        if state[_FILL] < L:
            return 0
    head = state[_HEAD]
    if not np.isfinite(s):
        return 0
    if state[_FLAG] == 0 and (state[_LTC] < 0 or k - state[_LTC] > n_ref) and s < thr and \
            _is_ext(buf, head, L, n_w, need, 1.0):
        state[_LTC] = k
        state[_FLAG] = 1
        state[_EXIT] = -1
        return 1
    if state[_FLAG] == 1 and (state[_LIC] < 0 or k - state[_LIC] > n_ref) and s > thr and \
            _is_ext(buf, head, L, n_w, need, -1.0):
        state[_LIC] = k
        state[_FLAG] = 0
        state[_EXIT] = -1
        return 2
    if state[_FLAG] == 0 and state[_EXIT] > state[_LIC] and k - state[_EXIT] > n_ref and s > thr and \
            buf[(head - 2) % L] > fstate[0] + margin and _is_ext(buf, head, L, n_w, need, -1.0):
        state[_LTC] = state[_EXIT]
        state[_LIC] = k
        return 3
    return 0


@njit(cache=True)
def _run(sig, stance, state, fstate, buf, thr, n_ref, n_w, need, margin, out, exit_k):
    for i in range(sig.shape[0]):
        out[i] = _step(state, fstate, buf, sig[i], stance[i], thr, n_ref, n_w, need, margin)
        if out[i] == 3:
            exit_k[i] = state[_LTC]


def _coeffs(params: IcTcParams, sampling_rate_hz: float) -> tuple[int, int, int]:
    if not sampling_rate_hz > 0:
        raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
    n_w = max(2, int(round(params.lookback_s * sampling_rate_hz)))
    n_ref = max(1, int(round(params.refractory_s * sampling_rate_hz)))
    return n_ref, n_w, int(math.ceil(params.trend_fraction * n_w - 1e-9))


class GaitEventDetector:
    """Streaming IC/TC detector of one foot: ``push(s_k)`` → ``None`` or ``("TC"|"IC", k_detect, k_extremum)``.

    ``push(s_k, stance)`` with ``stance`` True/False (foot still at k) also applies (R4); then a push can return
    two events ``[("TC", k, e), ("IC", k, k − 1)]`` (the flat-lift TC at the lift sample e, known only now).
    The state (``state``, ``fstate``, ``buf``) is plain arrays that can be copied and restored (chunked = whole).
    """

    def __init__(self, *, sampling_rate_hz: float, params: IcTcParams = IcTcParams()):
        self.params = params
        self._n_ref, self._n_w, self._need = _coeffs(params, sampling_rate_hz)
        self.state = np.array([-1, 0, -1, -1, 0, 0, 0, -1, -1], dtype=np.int64)
        self.fstate = np.zeros(1)
        self.buf = np.zeros(self._n_w + 3)

    def push(self, s: float, stance: bool | None = None):
        """Feed one sample of s = −sin(pitch) (and optionally whether the foot is still); returns the event(s)
        detected at this sample, if any."""
        st = -1 if stance is None else int(bool(stance))
        r = _step(self.state, self.fstate, self.buf, float(s), st, self.params.threshold, self._n_ref, self._n_w,
                  self._need, self.params.flat_lift_margin)
        if r == 0:
            return None
        k = int(self.state[_K])
        if r == 3:
            return [("TC", k, int(self.state[_LTC])), ("IC", k, k - 1)]
        return ("TC" if r == 1 else "IC", k, k - 1)


def detect_ic_tc(s: np.ndarray, *, sampling_rate_hz: float, params: IcTcParams = IcTcParams(),
                 stance: np.ndarray | None = None) -> GaitEvents:
    """Batch Algorithm 1 over the whole pitch signal ``s`` (N,); equals :class:`GaitEventDetector` sample by sample.

    ``stance`` (N,) bool (foot still, e.g. the zero-velocity samples) enables (R4); None = thesis Algorithm 1 only.
    """
    s = np.ascontiguousarray(s, dtype=float)
    if s.ndim != 1:
        raise ValueError(f"s must be a 1-D pitch signal, got shape {s.shape}")
    if stance is None:
        st = np.full(len(s), -1, dtype=np.int8)
    else:
        st = np.asarray(stance, dtype=bool)
        if st.shape != s.shape:
            raise ValueError(f"stance must have the shape of s {s.shape}, got {st.shape}")
        st = st.astype(np.int8)
    det = GaitEventDetector(sampling_rate_hz=sampling_rate_hz, params=params)
    out = np.zeros(len(s), dtype=np.int8)
    exit_k = np.full(len(s), -1, dtype=np.int64)
    _run(s, st, det.state, det.fstate, det.buf, params.threshold, det._n_ref, det._n_w, det._need,
         params.flat_lift_margin, out, exit_k)
    tc_det = np.flatnonzero((out == 1) | (out == 3))
    tc = np.where(out[tc_det] == 3, exit_k[tc_det], tc_det - 1)
    ic = np.flatnonzero((out == 2) | (out == 3))
    return GaitEvents(ic_idx=ic - 1, tc_idx=tc, ic_detect_idx=ic, tc_detect_idx=tc_det, params=params)


def pitch_signal(quat: np.ndarray, anterior_axis_sensor: np.ndarray) -> np.ndarray:
    """(P1): s_k = e_z · (R_k u_S) for quat (N, 4) sensor→world and the anterior axis u_S (3,) in sensor coords."""
    q = np.asarray(quat, dtype=float)
    u = np.asarray(anterior_axis_sensor, dtype=float)
    u = u / np.linalg.norm(u)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    # third row of R(q)
    return 2 * (x * z - w * y) * u[0] + 2 * (y * z + w * x) * u[1] + (1 - 2 * (x * x + y * y)) * u[2]


@njit(cache=True)
def _toe_off_kernel(w_ml, tc, lo, fs, n_win, frac, out):
    n = w_ml.shape[0]
    for e in range(tc.shape[0]):
        j = tc[e]
        out[e] = j
        a = max(lo[e], j - n_win, 1)
        if j - a < 2 or j + 1 >= n:
            continue
        # plantarflexion deceleration -dω_ml/dt (central difference) over [a, j]
        pk = 0.0
        ip = -1
        for k in range(a, j + 1):
            d = -(w_ml[k + 1] - w_ml[k - 1]) * 0.5 * fs
            if np.isfinite(d) and d > pk:
                pk = d
                ip = k
        if ip < 0:
            continue
        k = ip
        while k > a and -(w_ml[k + 1] - w_ml[k - 1]) * 0.5 * fs > frac * pk:
            k -= 1
        out[e] = k


def refine_toe_off(gyr: np.ndarray, tc_idx: np.ndarray, mediolateral_axis: np.ndarray, *, sampling_rate_hz: float,
                   onset_fraction: float = 0.2, window_s: float = 0.15,
                   lower_bound: np.ndarray | None = None) -> np.ndarray:
    """Batch toe-off refinement (T1) of Algorithm 1's TCs (pitch minima); returns the refined TC samples.

        ω_ml = ω · m_S   (m_S = foot mediolateral axis in sensor coordinates, pointing left: + = toes-down rotation)
        a_k = −(ω_ml,k+1 − ω_ml,k−1) f_s / 2   (plantarflexion deceleration)
        TC' = last sample k ≤ argmax a over [j − W, j] with a_k ≤ f · max a   (onset of the deceleration)     (T1)

    Biomechanics: while the toe is on the ground the ankle plantarflexors rotate the foot about the forefoot
    (heel rise, forefoot rocker) and the plantarflexion rate stays high; at toe-off the ground contact that drives it
    ends and the swinging leg dorsiflexes the foot, so the plantarflexion rate collapses to zero within a few tens of
    ms, and the pitch minimum j (Algorithm 1's TC) is the *end* of that deceleration. Toe-off = the last sample of
    contact = the onset of the deceleration. f = 0.2 (a conventional onset fraction of the peak, a priori) and
    W = 0.15 s (Algorithm 1's look-back window). ``lower_bound`` (per TC) keeps TC' after e.g. the previous IC.
    Uses only the raw gyroscope and the axis (no lever arm, no integrated velocity).
    """
    gyr = np.asarray(gyr, dtype=float)
    tc = np.ascontiguousarray(tc_idx, dtype=np.int64)
    m = np.asarray(mediolateral_axis, dtype=float)
    m = m / np.linalg.norm(m)
    w_ml = np.ascontiguousarray(gyr @ m)
    lo = np.zeros(len(tc), np.int64) if lower_bound is None else np.ascontiguousarray(lower_bound, dtype=np.int64)
    out = np.empty(len(tc), np.int64)
    _toe_off_kernel(w_ml, tc, lo, float(sampling_rate_hz), int(round(window_s * sampling_rate_hz)),
                    float(onset_fraction), out)
    return out


@njit(cache=True)
def _heel_strike_kernel(w_ml, ic, hi, n_win, frac, out):
    n = w_ml.shape[0]
    for e in range(ic.shape[0]):
        j = ic[e]
        out[e] = j
        b = min(hi[e], j + n_win, n - 1)
        if j < 0 or b <= j:
            continue
        pk = 0.0
        for k in range(j, b + 1):
            if np.isfinite(w_ml[k]) and w_ml[k] > pk:
                pk = w_ml[k]
        if pk <= 0.0:
            continue
        for k in range(j, b + 1):
            if w_ml[k] >= frac * pk:
                out[e] = k
                break


def refine_heel_strike(gyr: np.ndarray, ic_idx: np.ndarray, mediolateral_axis: np.ndarray, *,
                       sampling_rate_hz: float, onset_fraction: float = 0.5, window_s: float = 0.15,
                       upper_bound: np.ndarray | None = None) -> np.ndarray:
    """Batch heel-strike refinement (H1) of ICs at pitch maxima; returns the refined IC samples.

        ω_ml = ω · m_S   (m_S = foot mediolateral axis in sensor coordinates, pointing left: + = toes-down rotation)
        IC' = first k in [j, j + W] with ω_ml,k ≥ f · max(ω_ml over [j, j + W])   (j = the pitch maximum)     (H1)

    Biomechanics: at the pitch maximum j (Algorithm 1's IC, ω_ml = 0) the foot stops dorsiflexing; the heel
    contact then starts the loading rotation (heel rocker: the forefoot falls to the ground, ω_ml rises to its
    peak and falls to zero at foot flat). Which instant of that rise a reference calls "heel strike" is the
    reference's definition (docs/gait.md "Which instant is initial contact"): on Voisard et al.'s annotations
    (IMU algorithms checked by hand) the heel strike is 26 ms after j on average, near f = 0.5 of the rise; on the
    gaitmap walk's optical reference (marker-derived IC) j itself is 6 ms late. f and whether H1 runs at all
    (``FootParams.heel_strike_fraction``) are chosen by leave-one-subject-out (``stridelab bench gait``);
    W = 0.15 s as T1 (a priori). No rise (max ω_ml ≤ 0: a flat or forefoot landing) leaves j. ``upper_bound``
    (per IC) keeps IC' at or before e.g. the next TC. Uses only the raw gyroscope and the axis.
    """
    gyr = np.asarray(gyr, dtype=float)
    ic = np.ascontiguousarray(ic_idx, dtype=np.int64)
    m = np.asarray(mediolateral_axis, dtype=float)
    m = m / np.linalg.norm(m)
    w_ml = np.ascontiguousarray(gyr @ m)
    hi = np.full(len(ic), len(w_ml) - 1, np.int64) if upper_bound is None else \
        np.ascontiguousarray(upper_bound, dtype=np.int64)
    out = np.empty(len(ic), np.int64)
    _heel_strike_kernel(w_ml, ic, hi, int(round(window_s * sampling_rate_hz)), float(onset_fraction), out)
    return out
