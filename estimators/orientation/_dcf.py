"""Decoupled complementary filter (DCF): StrideLab's default orientation estimator.

Structure after the basic VQF of Laidig & Seel 2023 (doi:10.1016/j.inffus.2022.10.014), our own
implementation (numba, :mod:`._dcf_kernel`), with the thesis checklist items added (spec
thesis_orientation.md §7 C7-C9, C14):

1. strap-down integration of the bias-corrected gyro into a quasi-inertial frame I;
2. inclination: the accelerometer is rotated into I and low-passed there (time constant
   ``tau_acc_s``; linear accelerations average out because velocity stays bounded); the 6D attitude is
   levelled so that the low-passed vector points up (ENU z). Attitude never sees the magnetometer (C7);
3. heading: one angle ``delta`` about ENU z, pulled towards the magnetometer's horizontal direction
   with a first-order gain (``tau_mag_s``); samples whose field norm or dip angle deviate from the learnt
   reference are rejected (C8, norm + dip); a deviation lasting ``mag_reject_max_s`` becomes the new
   reference (moving to a new place). Without a magnetometer (6D) the heading follows the gyro;
4. gyro bias: at rest (deviations of gyro and acc from their 0.5-s low-pass below
   ``rest_gyr_rad_s`` / ``rest_acc_m_s2`` for ``rest_min_s``) the bias is the low-passed gyro (static
   bias removal, thesis finding 2a); in motion the inclination correction, seen in the sensor frame,
   feeds the bias slowly (``k_bias_motion``, a PI-CF integral term, spec §2.4).

Gap handling: a NaN gyro sample holds the attitude; a NaN acc / mag sample skips its correction; the
filter continues after the gap. A saturated gyro (clipped rate) makes the strap-down fall behind; the
accelerometer / magnetometer corrections pull it back with their time constants — we do not detect
clipping. Recordings shorter than 1 s raise ValueError.

Offline (``dcf_offline``): the same filter run forwards and backwards in time (time-reversed, negated
gyro) with the two estimates averaged, weighted by how long each direction has had to converge.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.orientation._dcf_kernel import STATE_LEN, dcf_series, initial_state, strapdown_series
from estimators.orientation._types import OnlineFilter, OrientationResult
from estimators.orientation._yun_cf import _check_inputs
from estimators.quaternion import quat_conj, quat_mul, quat_normalize, quat_rotate


@dataclass(frozen=True)
class DCFParams:
    """Parameters of the decoupled complementary filter (rate independent, SI units).

    tau_acc_s: time constant of the accelerometer low-pass in the quasi-inertial frame, s (VQF: 3 s).
    tau_mag_s: time constant of the heading correction, s (VQF: 9 s; 25 s chosen by leave-trials-out
        cross-validation on BROAD, see tuned_gains.json: indoor fields are inhomogeneous, a slower heading
        correction averages the local field errors while the bias-corrected gyro stays accurate).
    rest_gyr_rad_s: rest when the gyro deviates from its 0.5-s low-pass by less than this, rad/s (2°/s).
    rest_acc_m_s2: ... and the accelerometer from its low-pass by less than this, m/s².
    rest_min_s: duration the rest condition must hold before the bias is taken from the gyro, s.
    bias_tau_motion_s: time constant of the bias integral in motion, s (0 or inf = off).
    bias_max_rad_s: the bias estimate is clipped to ± this, rad/s (2°/s).
    mag_norm_rel: reject a magnetometer sample whose norm deviates by more than this fraction.
    mag_dip_deg: ... or whose dip angle deviates by more than this, degrees.
    mag_reject_max_s: a rejection lasting longer than this adopts the current field as reference, s.
    mag_ref_tau_s: time constant with which accepted samples update the norm/dip reference, s.
    mag_init_s: the heading converges by running mean during the first ``mag_init_s`` of valid samples.
    """
    tau_acc_s: float = 3.0
    tau_mag_s: float = 25.0
    rest_gyr_rad_s: float = 0.035
    rest_acc_m_s2: float = 0.5
    rest_min_s: float = 1.5
    bias_tau_motion_s: float = 0.0
    bias_max_rad_s: float = 0.035
    mag_norm_rel: float = 0.1
    mag_dip_deg: float = 10.0
    mag_reject_max_s: float = 60.0
    mag_ref_tau_s: float = 20.0
    mag_init_s: float = 3.0


def _gain(tau_s: float, dt: float) -> float:
    """First-order low-pass gain k = 1 − exp(−dt/τ) (0 for τ ≤ 0 or inf means 'off')."""
    if not np.isfinite(tau_s) or tau_s <= 0:
        return 0.0
    return float(1.0 - np.exp(-dt / tau_s))


def dcf_coefficients(params: DCFParams, sampling_rate_hz: float) -> np.ndarray:
    """Rate-dependent coefficients of the kernel (see :func:`._dcf_kernel.dcf_series`)."""
    dt = 1.0 / sampling_rate_hz
    kb = _gain(params.bias_tau_motion_s, dt) if params.bias_tau_motion_s > 0 else 0.0
    return np.array([
        _gain(params.tau_acc_s, dt), _gain(params.tau_mag_s, dt), _gain(0.5, dt),
        params.rest_gyr_rad_s, params.rest_acc_m_s2, params.rest_min_s, kb * dt,
        params.bias_max_rad_s, params.mag_norm_rel, np.radians(params.mag_dip_deg), params.mag_reject_max_s,
        _gain(params.mag_ref_tau_s, dt), max(1.0, params.tau_acc_s * sampling_rate_hz),
        max(1.0, params.mag_init_s * sampling_rate_hz), *_butter2(params.tau_acc_s, sampling_rate_hz)],
        dtype=np.float64)


def _butter2(tau_s: float, sampling_rate_hz: float) -> tuple[float, float, float, float, float]:
    """2nd-order Butterworth low-pass (b0, b1, b2, a1, a2), cut-off f_c = √2 / (2π τ) as in VQF
    (bilinear transform with pre-warping, the same as scipy.signal.butter(2, f_c, fs=...))."""
    fc = np.sqrt(2.0) / (2.0 * np.pi * tau_s)
    c = np.tan(np.pi * fc / sampling_rate_hz)
    d = c * c + np.sqrt(2.0) * c + 1.0
    b0 = c * c / d
    return b0, 2.0 * b0, b0, 2.0 * (c * c - 1.0) / d, (1.0 - np.sqrt(2.0) * c + c * c) / d


class DCFFilter(OnlineFilter):
    """Online decoupled complementary filter. ``state`` is a plain (STATE_LEN,) array you can copy and restore;
    ``update_batch`` on consecutive chunks gives exactly the result of one call on the whole recording."""

    STATE_SIZE = STATE_LEN

    def __init__(self, params: DCFParams = DCFParams(), *, sampling_rate_hz: float):
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)
        self._coef = dcf_coefficients(params, self.sampling_rate_hz)
        self._state = initial_state()

    def update_batch(self, gyr, acc, mag=None) -> OrientationResult:
        gyr, acc, mag = self._chunk(gyr, acc, mag)
        n = gyr.shape[0]
        use_mag = mag is not None
        m = mag if use_mag else np.empty((n, 3))
        q = np.empty((n, 4))
        rest = np.empty(n, dtype=np.bool_)
        rej = np.empty(n, dtype=np.bool_)
        dcf_series(gyr, acc, m, use_mag, 1.0 / self.sampling_rate_hz, self._coef, self._state, q, rest, rej)
        return OrientationResult(quat=q, gain=np.where(rej, 0.0, 1.0 / max(self.params.tau_mag_s, 1e-9)),
                                 still=rest, mag_used=use_mag, params=self.params)


def dcf(gyr, acc, mag=None, *, sampling_rate_hz: float, params: DCFParams = DCFParams()) -> OrientationResult:
    """Orientation (sensor→ENU, [w x y z]) by the decoupled complementary filter, causal (online).

    gyr (N, 3) rad/s, acc (N, 3) m/s² specific force, mag (N, 3) µT or None (6D). ``gain`` in the result
    is the heading-correction rate 1/τ_mag (1/s), 0 where the magnetometer was rejected; ``still`` marks rest.
    """
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    return DCFFilter(params, sampling_rate_hz=sampling_rate_hz).update_batch(gyr, acc, mag)


def _blend(qf: np.ndarray, qb: np.ndarray, wf: np.ndarray) -> np.ndarray:
    """Normalised weighted quaternion average (sign-aligned), weights wf for qf and 1 − wf for qb."""
    sgn = np.where(np.sum(qf * qb, axis=1) < 0, -1.0, 1.0)[:, None]
    q = wf[:, None] * qf + (1.0 - wf[:, None]) * qb * sgn
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def _zero_phase_lp(x: np.ndarray, tau_s: float, sampling_rate_hz: float) -> np.ndarray:
    """Zero-phase (forward-backward) 2nd-order Butterworth low-pass along axis 0, cut-off √2/(2π τ)."""
    from scipy.signal import butter, sosfiltfilt
    fc = np.sqrt(2.0) / (2.0 * np.pi * tau_s)
    sos = butter(2, min(fc, 0.45 * sampling_rate_hz), fs=sampling_rate_hz, output="sos")
    return sosfiltfilt(sos, x, axis=0, padtype="even", padlen=min(len(x) - 1, int(3 * tau_s * sampling_rate_hz)))


def keep_long_runs(mask: np.ndarray, min_len: int) -> np.ndarray:
    """The runs of True of at least ``min_len`` samples (a 1-D morphological opening with a flat
    structure of that length, as ``scipy.ndimage.binary_opening``, in O(N) instead of O(N·min_len))."""
    mask = np.asarray(mask, dtype=bool)
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    out = np.zeros_like(mask)
    for a, b in zip(edges[::2], edges[1::2]):
        if b - a >= min_len:
            out[a:b] = True
    return out


def dilate(mask: np.ndarray, m: int) -> np.ndarray:
    """True wherever a True lies within ± m samples (``binary_dilation`` with ``ones(2m+1)``), O(N)."""
    c = np.r_[0, np.cumsum(np.asarray(mask, dtype=np.int64))]
    n = len(mask)
    idx = np.arange(n)
    return c[np.minimum(idx + m + 1, n)] - c[np.maximum(idx - m, 0)] > 0


def _fill_nan(x: np.ndarray) -> np.ndarray:
    """Linear interpolation over NaN rows (edges held); all-NaN columns become 0."""
    x = x.copy()
    idx = np.arange(len(x))
    for j in range(x.shape[1]):
        ok = np.isfinite(x[:, j])
        x[:, j] = np.interp(idx, idx[ok], x[ok, j]) if ok.any() else 0.0
    return x


@dataclass(frozen=True)
class DCFOfflineParams:
    """Parameters of the batch (non-causal) DCF.

    online: the causal filter run first (rest detection, bias at rest, fallback bias).
    tau_acc_s: zero-phase low-pass time constant of the accelerometer in the strap-down frame, s.
    tau_mag_s: zero-phase low-pass time constant of the heading offset, s (60 s: leave-trials-out CV on BROAD,
        tuned_gains.json).
    mag_norm_rel: reject magnetometer samples whose norm deviates from the recording's median by more than this.
    mag_dip_deg: ... or whose dip deviates from the median dip by more than this, degrees.
    mag_margin_s: every rejected stretch longer than 0.5 s is widened by this on both sides (approaching disturbances), s.
    """
    online: DCFParams = DCFParams()
    tau_acc_s: float = 3.0
    tau_mag_s: float = 60.0
    mag_norm_rel: float = 0.1
    mag_dip_deg: float = 10.0
    mag_margin_s: float = 2.0


def dcf_offline(gyr, acc, mag=None, *, sampling_rate_hz: float,
                params: DCFOfflineParams = DCFOfflineParams()) -> OrientationResult:
    """Batch (non-causal) DCF: the causal filter's three steps with zero-phase filters.

    1. gyro bias: the causal filter detects rest; the bias is the gyro mean over each rest period,
       linearly interpolated in time between rest periods (held before the first / after the last);
       without any rest the causal filter's final bias is used;
    2. strap-down integration of the bias-free gyro (frame I); accelerometer rotated into I, low-passed
       with a zero-phase Butterworth (no lag), each sample levelled so that it points up (6D);
    3. magnetometer rotated with the 6D attitude; samples whose norm / dip deviate from the recording's
       median are rejected (the heading offset is interpolated across them); the heading offset
       atan2(m_x, m_y) is unwrapped and zero-phase low-passed; 6D (mag=None): heading from the gyro.
    """
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    n = gyr.shape[0]
    fs = float(sampling_rate_hz)
    filt = DCFFilter(params.online, sampling_rate_hz=fs)
    on = filt.update_batch(gyr, acc, mag)
    # 1. bias per rest period, interpolated
    rest = on.still & np.all(np.isfinite(gyr), axis=1)
    edges = np.flatnonzero(np.diff(np.r_[0, rest.astype(np.int8), 0]))
    centres, values = [], []
    for a, b in zip(edges[::2], edges[1::2]):
        centres.append(0.5 * (a + b - 1))
        values.append(np.mean(gyr[a:b], axis=0))
    bias = np.empty((n, 3))
    if centres:
        idx = np.arange(n)
        for j in range(3):
            bias[:, j] = np.interp(idx, centres, [v[j] for v in values])
    else:
        bias[:] = filt.state[18:21]
    # 2. strap-down and zero-phase inclination
    qg = np.empty((n, 4))
    strapdown_series(gyr, bias, 1.0 / fs, qg)
    # start frame I at the causal filter's attitude after its first second, so the levelling corrections stay small
    # (a full levelling of an arbitrary tilt is singular for an upside-down start)
    k0 = min(n - 1, int(fs))
    qg = quat_normalize(quat_mul(quat_mul(on.quat[k0], quat_conj(qg[k0])), qg))
    a_i = _fill_nan(quat_rotate(qg, acc))
    a_lp = _zero_phase_lp(a_i, params.tau_acc_s, fs)
    e = a_lp / np.linalg.norm(a_lp, axis=1, keepdims=True)
    cw = np.sqrt(np.clip((e[:, 2] + 1.0) * 0.5, 0.0, 1.0))
    cws = np.maximum(cw, 1e-6)
    q_acc = np.column_stack([cw, 0.5 * e[:, 1] / cws, -0.5 * e[:, 0] / cws, np.zeros(n)])
    q_acc[cw <= 1e-6] = [0.0, 1.0, 0.0, 0.0]
    q6 = quat_normalize(quat_mul(q_acc, qg))
    if mag is None:
        q = q6
        rej = np.zeros(n, dtype=bool)
    else:
        # 3. heading offset
        h = quat_rotate(q6, mag)
        nm = np.linalg.norm(h, axis=1)
        dip = np.arcsin(np.clip(h[:, 2] / np.where(nm > 0, nm, np.nan), -1, 1))
        ok = np.isfinite(nm) & (nm > 0) & (on.gain > 0)         # the causal filter's rejection (learnt reference)
        if ok.any():
            ok &= (np.abs(nm - np.nanmedian(nm[ok])) <= params.mag_norm_rel * np.nanmedian(nm[ok]))
        if ok.any():
            ok &= np.abs(dip - np.nanmedian(dip[ok])) <= np.radians(params.mag_dip_deg)
        if params.mag_margin_s > 0 and (~ok).any():   # widen each rejected stretch: its edges are disturbed too
            m = max(1, int(params.mag_margin_s * fs))
            long_rej = keep_long_runs(~ok, max(1, int(0.5 * fs)))      # ≥ 0.5 s
            ok &= ~dilate(long_rej, m)
        rej = ~ok
        if ok.sum() >= 2:
            d = np.full(n, np.nan)
            d[ok] = np.unwrap(np.arctan2(h[ok, 0], h[ok, 1]))
            d = _fill_nan(d[:, None])
            c = _zero_phase_lp(np.column_stack([np.cos(d[:, 0]), np.sin(d[:, 0])]), params.tau_mag_s, fs)
            delta = np.arctan2(c[:, 1], c[:, 0])
        else:
            delta = np.zeros(n)
        q = quat_mul(np.column_stack([np.cos(delta / 2), np.zeros(n), np.zeros(n), np.sin(delta / 2)]), q6)
    q = q * np.where(q[:, :1] < 0, -1.0, 1.0)
    return OrientationResult(quat=q, gain=np.where(rej, 0.0, 1.0 / params.tau_mag_s), still=on.still,
                             mag_used=mag is not None, params=params)
