"""Decoupled complementary filter (DCF): StrideLab's default orientation estimator.

Structure after the basic VQF of Laidig & Seel 2023 (doi:10.1016/j.inffus.2022.10.014), our own
implementation (numba, :mod:`._dcf_kernel`), with the thesis checklist items added (spec
thesis_orientation.md §7 C7-C9, C14):

1. strap-down integration of the bias-corrected gyro into a quasi-inertial frame I;
2. inclination: the accelerometer is rotated into I and low-passed there (time constant
   ``tau_acc_s``; linear accelerations average out because velocity stays bounded); the 6D attitude is
   levelled so that the low-passed vector points up (ENU z). Attitude never sees the magnetometer (C7);
3. heading: one angle ``delta`` about ENU z, pulled towards the magnetometer's horizontal direction; the gain
   is that of a scalar Kalman filter (default ``mag_gain="kalman"``): the heading variance grows with the
   rotation the gyro integrates and each magnetometer sample's variance grows with the rotation rate (the
   magnetometer lags the gyro), so right after a rest the gyro is trusted and after long fast movement the
   magnetometer; ``mag_gain="fixed"`` is VQF's first-order gain 1/``tau_mag_s``. Samples whose field norm
   or dip angle deviate from the learnt reference are rejected (C8, norm + dip); a deviation lasting
   ``mag_reject_max_s`` becomes the new reference (moving to a new place). Without a magnetometer (6D)
   the heading follows the gyro;
4. gyro bias: at rest (deviations of gyro and acc from their 0.5-s low-pass below
   ``rest_gyr_rad_s`` / ``rest_acc_m_s2`` for ``rest_min_s``) a random-walk Kalman update pulls the bias
   towards the low-passed gyro (static bias removal, thesis finding 2a; VQF's rest-bias estimation), so
   the onset of a movement, still counted as rest by the causal detector, barely moves it
   (``rest_bias="lowpass"``: bias := low-passed gyro, the earlier scheme); in motion the inclination
   correction, seen in the sensor frame, can feed the bias (``bias_tau_motion_s``, off by default).

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

from stridelab.estimators.orientation._dcf_kernel import STATE_LEN, dcf_series, initial_state, strapdown_series
from stridelab.estimators.orientation._types import OnlineFilter, OrientationResult
from stridelab.estimators.orientation._yun_cf import _check_inputs
from stridelab.estimators.quaternion import quat_conj, quat_mul, quat_normalize, quat_rotate


@dataclass(frozen=True)
class DCFParams:
    """Parameters of the decoupled complementary filter (rate independent, SI units).

    tau_acc_s: time constant of the accelerometer low-pass in the quasi-inertial frame, s (VQF: 3 s).
    tau_mag_s: time constant of the heading correction with ``mag_gain="fixed"``, s (VQF: 9 s; in that mode 25 s
        is the leave-one-group-out choice on BROAD; unused by the default ``mag_gain="kalman"``).
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
    rest_bias: how rest updates the bias: ``"lowpass"`` (bias := the 0.5-s low-passed gyro at every rest sample)
        or ``"kalman"`` (random-walk bias, Kalman update towards the low-passed gyro, as VQF's rest-bias
        estimation, Laidig & Seel 2023 §3.4: the first rest converges within seconds, later rests average over
        ~``bias_forgetting_s`` · (σ_rest/σ_drift)², so the onset of a movement that the causal rest detector still
        counts as rest barely moves the bias).
    bias_sigma_init_rad_s: initial std of the bias estimate (Kalman mode), rad/s (VQF: 0.5°/s).
    bias_sigma_drift_rad_s, bias_forgetting_s: the bias variance grows by σ_drift² in bias_forgetting_s (VQF:
        0.1°/s in 100 s).
    bias_sigma_rest_rad_s: steady-state std of the bias while at rest (VQF: 0.03°/s).
    mag_settle_s: after a rejected magnetometer sample, accepted samples are used (and update the reference) only
        once the field has stayed within the thresholds this long, s (the edges of a disturbance are disturbed
        too; VQF: magMinUndisturbedTime 0.5 s; 0 = off).
    mag_gain: ``"fixed"`` (first-order gain 1/``tau_mag_s``) or ``"kalman"``: a scalar Kalman filter of the heading
        offset whose variance grows with the rotation the gyro integrates (scale-factor / misalignment error
        ``heading_kappa`` per rad, plus ``heading_q0_rad2_s``) and whose magnetometer samples have the noise
        density ``mag_noise_rad2_s`` growing with the rate (``mag_rate_ref_rad_s``; the magnetometer lags the gyro
        by 15-27 ms on BROAD, so its heading error grows with |ω|). Right after a rest the heading trusts the gyro;
        after long fast movement it leans on the magnetometer. In steady motion at rate ω the time constant is
        ≈ √(r / (κ²ω²)) (r = 0.0054 rad²·s, κ = 0.005: 15 s at 1 rad/s). ``tau_mag_s`` is then unused.
    mag_new_s: new-field acceptance (VQF's magNewTime, Laidig & Seel 2023 §3.5): while samples are rejected, a field
        whose norm and dip stay within the thresholds of a running candidate for this long — counted only while the
        sensor rotates faster than ``mag_new_min_gyr_rad_s`` (a magnet moving with the sensor changes the norm as it
        rotates; a new clean environment does not) — becomes the reference, s (0 = off).
    hard_iron: estimate online the offset of a magnet that moves with the sensor (hard iron: the phone's vibration
        motor, a magnet on the strap; BROAD trials 32/34 are such an offset: 58 µT at 1 cm, 14 µT at 3 cm, residual
        0.8 µT) by recursive least squares on the norm model |m − b| = R, and remove it once the model is settled
        (see :func:`._dcf_kernel._hard_iron`); a field that does not move with the sensor fails the model and goes to
        the norm/dip rejection unchanged.
    hard_iron_tau_s: forgetting time of the hard-iron fit, counted over rotating samples, s.
    hard_iron_min_gyr_rad_s: the fit is updated only while the sensor rotates faster than this, rad/s.
    hard_iron_sigma0_ut: prior std of each offset component, µT (also the bound of its variance).
    hard_iron_res_ut: the offset is removed only while the low-passed RMS residual of the norm model is below this, µT.
    hard_iron_res_tau_s: time constant of that residual low-pass (over rotating samples), s.
    hard_iron_min_s: ... and only after the fit has been updated this long, s.
    hard_iron_sigma_ut: ... and only while each offset component's RLS std is below this (µT per unit norm noise).
    hard_iron_min_ut: ... and only when the offset is larger than this, µT (a calibrated sensor's own residual offset,
        ≈ 1 µT on BROAD's undisturbed trials, is not worth the noise of its estimate).
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
    rest_bias: str = "kalman"
    bias_sigma_init_rad_s: float = 0.0087
    bias_sigma_drift_rad_s: float = 0.0017
    bias_forgetting_s: float = 100.0
    bias_sigma_rest_rad_s: float = 0.00052
    mag_settle_s: float = 0.5
    mag_gain: str = "kalman"
    heading_kappa: float = 0.005
    heading_q0_rad2_s: float = 2.7e-7
    mag_noise_rad2_s: float = 0.02
    mag_rate_ref_rad_s: float = 3.0
    mag_new_s: float = 0.0
    mag_new_min_gyr_rad_s: float = 0.35
    hard_iron: bool = True
    hard_iron_tau_s: float = 20.0
    hard_iron_min_gyr_rad_s: float = 0.5
    hard_iron_sigma0_ut: float = 100.0
    hard_iron_res_ut: float = 2.0
    hard_iron_res_tau_s: float = 2.0
    hard_iron_min_s: float = 5.0
    hard_iron_sigma_ut: float = 0.3
    hard_iron_min_ut: float = 3.0

    def __post_init__(self):
        if self.rest_bias not in ("lowpass", "kalman"):
            raise ValueError(f"DCFParams.rest_bias must be 'lowpass' or 'kalman', got {self.rest_bias!r}")
        if self.mag_gain not in ("fixed", "kalman"):
            raise ValueError(f"DCFParams.mag_gain must be 'fixed' or 'kalman', got {self.mag_gain!r}")


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
        max(1.0, params.mag_init_s * sampling_rate_hz), *_butter2(params.tau_acc_s, sampling_rate_hz),
        *_rest_bias_kf(params, dt), params.mag_settle_s, *_heading_kf(params),
        params.mag_new_s, params.mag_new_min_gyr_rad_s, *_hard_iron_coef(params, dt)], dtype=np.float64)


def _hard_iron_coef(params: DCFParams, dt: float) -> tuple[float, ...]:
    """(λ, ω_min, P0, residual threshold², k_residual, t_min, P threshold, minimum offset²) of the hard-iron fit; λ = 0: off."""
    if not params.hard_iron:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return (1.0 - dt / params.hard_iron_tau_s, params.hard_iron_min_gyr_rad_s, params.hard_iron_sigma0_ut ** 2,
            params.hard_iron_res_ut ** 2, _gain(params.hard_iron_res_tau_s, dt), params.hard_iron_min_s,
            params.hard_iron_sigma_ut ** 2, params.hard_iron_min_ut ** 2)


def _heading_kf(params: DCFParams) -> tuple[float, float, float, float]:
    """(q0, κ², r, 1/ω_ref²) of the heading Kalman filter; r = 0 selects the fixed gain."""
    if params.mag_gain != "kalman":
        return 0.0, 0.0, 0.0, 0.0
    return (params.heading_q0_rad2_s, params.heading_kappa ** 2, params.mag_noise_rad2_s,
            1.0 / params.mag_rate_ref_rad_s ** 2)


def _rest_bias_kf(params: DCFParams, dt: float) -> tuple[float, float, float]:
    """(P0, V, W) of the rest-bias Kalman filter; W = 0 selects the low-pass mode. The measurement noise W is
    chosen so that the steady-state variance at rest is σ_rest² (W = p²/V + p, p = σ_rest², as VQF)."""
    if params.rest_bias != "kalman":
        return 0.0, 0.0, 0.0
    v = params.bias_sigma_drift_rad_s ** 2 * dt / params.bias_forgetting_s
    p = params.bias_sigma_rest_rad_s ** 2
    return params.bias_sigma_init_rad_s ** 2, v, p * p / v + p


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
        m_out = np.full((n, 3), np.nan)
        dcf_series(gyr, acc, m, use_mag, 1.0 / self.sampling_rate_hz, self._coef, self._state, q, rest, rej, m_out)
        return OrientationResult(quat=q, gain=np.where(rej, 0.0, 1.0 / max(self.params.tau_mag_s, 1e-9)),
                                 still=rest, mag_used=use_mag, params=self.params,
                                 mag_sensor=m_out if use_mag else None)


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
    tau_mag_s: zero-phase low-pass time constant of the heading offset, s (60 s: leave-one-group-out on BROAD,
        tuned_gains.json, validation/provenance.toml).
    mag_norm_rel: reject magnetometer samples whose norm deviates from the recording's median by more than this.
    mag_dip_deg: ... or whose dip deviates from the median dip by more than this, degrees.
    mag_margin_s: every rejected stretch longer than 0.5 s is widened by this on both sides (approaching disturbances), s.
    mag_rate_ref_rad_s: each magnetometer sample is weighted by 1 / (1 + |ω|² / ω_ref²) in the heading low-pass (its
        heading error grows with the rate, see ``DCFParams.mag_gain``); ≥ 1e6 = equal weights.
    """
    online: DCFParams = DCFParams()
    tau_acc_s: float = 3.0
    tau_mag_s: float = 60.0
    mag_norm_rel: float = 0.1
    mag_dip_deg: float = 10.0
    mag_margin_s: float = 2.0
    mag_rate_ref_rad_s: float = 3.0


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
    filt = DCFFilter(params.online, sampling_rate_hz=float(sampling_rate_hz))
    on = filt.update_batch(gyr, acc, mag)
    return dcf_offline_from_online(gyr, acc, mag, on, filt.state[18:21].copy(), sampling_rate_hz=sampling_rate_hz,
                                   params=params)


def dcf_offline_from_online(gyr, acc, mag, on: OrientationResult, final_bias, *, sampling_rate_hz: float,
                            params: DCFOfflineParams = DCFOfflineParams()) -> OrientationResult:
    """Steps 1-3 of :func:`dcf_offline` from the causal filter's result ``on`` (run with ``params.online``) and its
    final bias estimate (rad/s, used when no rest was found): lets a parameter search reuse one causal run."""
    n = gyr.shape[0]
    fs = float(sampling_rate_hz)
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
        bias[:] = final_bias
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
        # 3. heading offset, from the magnetometer as the causal filter used it (hard-iron offset removed)
        if on.mag_sensor is not None:
            mag = on.mag_sensor
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
            w = 1.0
            if np.isfinite(params.mag_rate_ref_rad_s) and params.mag_rate_ref_rad_s < 1e6:
                w2 = np.sum((np.nan_to_num(gyr) - bias) ** 2, axis=1)
                w = (1.0 / (1.0 + w2 / params.mag_rate_ref_rad_s ** 2))[:, None]
            # weighted zero-phase mean of the heading direction (the weights' own low-pass cancels in atan2)
            c = _zero_phase_lp(w * np.column_stack([np.cos(d[:, 0]), np.sin(d[:, 0])]), params.tau_mag_s, fs)
            delta = np.arctan2(c[:, 1], c[:, 0])
        else:
            delta = np.zeros(n)
        q = quat_mul(np.column_stack([np.cos(delta / 2), np.zeros(n), np.zeros(n), np.sin(delta / 2)]), q6)
    q = q * np.where(q[:, :1] < 0, -1.0, 1.0)
    return OrientationResult(quat=q, gain=np.where(rej, 0.0, 1.0 / params.tau_mag_s), still=on.still,
                             mag_used=mag is not None, params=params)
