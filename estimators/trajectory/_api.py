"""Public API of the foot trajectory: zero-velocity detection and the ESKF + ZUPT + RTS smoother."""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from stridelab.estimators.trajectory._eskf import GRAVITY, eskf_rts_kernel
from stridelab.estimators.trajectory._saturation import repair_gyro_saturation

__all__ = ["ZuptParams", "TRAJECTORY_ZUPT", "detect_zupt", "gait_cycle_period", "stance_gyro_bias", "rest_gyro_bias", "sensor_gravity", "EskfParams", "TrajectoryResult", "eskf_trajectory", "check_foot_imu"]


@dataclass(frozen=True)
class ZuptParams:
    """Zero-velocity (stance) detector (spec B6.3 windowed tests, made adaptive for issue 15, Z1–Z4 below).

    Motion statistic per sample (gyro and specific-force deviation on one scale, rad/s), a window maximum:
        m_k = max over the centred window of  max(|ω_j|, | |f_j| − g_s | / κ),  κ = acc_tolerance / θ_lo   (Z1)
        g_s = the sensor's own gravity reading: median |f| over the samples still by (Z1) with g = 9.81 and
        the fixed threshold (a miscalibrated accelerometer reads 10.3 m/s² at rest, Voisard left MTw)     (Z2)
    Adaptive threshold: with n_k = min and M_k = max of m over ±``adapt_window_s`` around k (the quietest and
    the fastest moment of the surrounding stride),
        θ_k = clip(β · n_k, θ_lo, θ_hi)  if M_k ≥ ρ · n_k  else θ_lo,    stance_k = m_k ≤ θ_k             (Z3)
    so walking (n ≈ 0.02–0.1 rad/s) keeps θ ≈ θ_lo while running and stairs, whose foot never gets as still
    (n ≈ 0.3–1 rad/s), get a proportionally higher threshold; θ_hi keeps swing from ever being stance, and the
    contrast test (ρ = 10: a gait cycle's swing peak is an order of magnitude above its stance minimum; a
    priori) keeps motion without a gait cycle (random shaking) from raising it. θ_lo also adapts to the sensor
    noise: θ_lo = clip(4 σ_w, θ, 2θ) with θ = gyr_threshold_rad_s and σ_w the gyro-norm std in the quietest
    ``adapt_window_s`` of the recording (at most doubled: a recording that is never quiet is not "noise").  (Z4)
    ``adaptive=False`` gives the fixed detector (θ_k = θ_lo = gyr_threshold_rad_s, g = 9.81 unless given).

    gyr_threshold_rad_s: θ_lo (0.3 rad/s; before issue 15 0.6, the foot-IMU literature default).
    acc_tolerance_m_s2: κ·θ_lo (1.25 m/s²: κ = 2.5/0.6, the ratio of the pre-issue-15 defaults).
    θ_lo = 0.3, θ_hi = 3.0, β = 3: chosen by leave-one-trial-out on the 28 PyShoe Vicon trials
        (``stridelab bench trajectory --pyshoe``; docs/gait.md "Parameters and how they were chosen").
    window_s: centred window length (0.05 s).  min_stance_s: shorter still runs are dropped (the class default
        0.05 s is the gait events' detector, ``FootParams.trajectory.zupt``; the foot trajectory's own default is
        ``EskfParams.zupt``, ``TRAJECTORY_ZUPT``: 0.1 s, chosen by leave-one-trial-out on PyShoe).
    adaptive: Z2–Z4 on.  adapt_ratio: β.  adapt_max_rad_s: θ_hi.  adapt_window_s: half-width of the n_k window
    (also the fallback of ``cycle_window``).  adapt_contrast: ρ.
    cycle_window: (Z5, issue 43) besides (Z3), the quietest window of every gait cycle is stance when it is below
        the physical bound θ_hi:
            P_k = local stride period: lag of the first autocorrelation peak of |ω| in 0.4–2.5 s that reaches
                  0.8 × the highest one with r ≥ 0.3, over 8 s blocks (hop 4 s); no such peak → no gait there,
            k is its cycle's quietest sample iff m_k = min of m over ±½P_k (one period holds one stance of this
                  foot) and m_k ≤ θ_hi ; stance ∪= the ``window_s`` window around each such k                  (Z5)
        Why: (Z3) compares each sample with the quietest stance within ±1 s; in running (P ≈ 0.7 s) that is the
        quietest of about three stances, and the less quiet ones fail β·n_k: 50 of 218 oracle still phases
        (PyShoe's zv_shoe_opt, runs ≥ 3 samples) of the 8 PyShoe running trials had no stance sample (the issue
        counted 54 of 191 on its held-back trials); with (Z5) 9 of 218. θ_hi = 3 rad/s is the bound: the foot rolls
        over at most about 30° in a 0.2 s running stance (≈ 2.6 rad/s), so a cycle whose quietest window turns
        faster has no stance to give. Chosen on by leave-one-trial-out (validation/provenance.toml).
    """
    gyr_threshold_rad_s: float = 0.3
    acc_tolerance_m_s2: float = 1.25
    window_s: float = 0.05
    min_stance_s: float = 0.05
    adaptive: bool = True
    adapt_ratio: float = 3.0
    adapt_max_rad_s: float = 3.0
    adapt_window_s: float = 1.0
    adapt_contrast: float = 10.0
    cycle_window: bool = True


@njit(cache=True)
def _window_max(x, half):
    n = x.shape[0]
    out = np.empty(n)
    for i in range(n):
        lo = max(0, i - half)
        hi = min(n, i + half + 1)
        m = x[lo]
        for j in range(lo + 1, hi):
            if x[j] > m:
                m = x[j]
        out[i] = m
    return out


@njit(cache=True)
def _drop_short(mask, min_len):
    n = mask.shape[0]
    i = 0
    while i < n:
        if mask[i]:
            j = i
            while j < n and mask[j]:
                j += 1
            if j - i < min_len:
                for t in range(i, j):
                    mask[t] = False
            i = j
        else:
            i += 1


@njit(cache=True)
def _window_min(x, half):
    n = x.shape[0]
    out = np.empty(n)
    # van Herk / Gil-Werman would be O(N); blocks of 2·half+1 with prefix/suffix minima
    w = 2 * half + 1
    pre = np.empty(n)
    suf = np.empty(n)
    for i in range(n):
        pre[i] = x[i] if i % w == 0 else min(pre[i - 1], x[i])
    for i in range(n - 1, -1, -1):
        suf[i] = x[i] if (i % w == w - 1 or i == n - 1) else min(suf[i + 1], x[i])
    for i in range(n):
        lo = max(0, i - half)
        hi = min(n - 1, i + half)
        out[i] = min(suf[lo], pre[hi])
    return out


@njit(cache=True)
def _window_min_var(x, half):
    """min of x over [i − half_i, i + half_i] (variable half-width, O(N·h))."""
    n = x.shape[0]
    out = np.empty(n)
    for i in range(n):
        lo = max(0, i - half[i])
        hi = min(n, i + half[i] + 1)
        m = x[lo]
        for j in range(lo + 1, hi):
            if x[j] < m:
                m = x[j]
        out[i] = m
    return out


CYCLE_MIN_S, CYCLE_MAX_S, CYCLE_BLOCK_S, CYCLE_MIN_R = 0.4, 2.5, 8.0, 0.3


def gait_cycle_period(gyr: np.ndarray, *, sampling_rate_hz: float) -> np.ndarray:
    """(Z5) local stride period P_k (s) per sample, NaN where no gait cycle is found: the lag of the first
    autocorrelation peak of |ω| in 0.4–2.5 s that reaches 0.8 × the highest one and r ≥ 0.3, over 8 s blocks
    (hop 4 s; each sample takes the block whose centre is nearest)."""
    fs = float(sampling_rate_hz)
    w = np.linalg.norm(np.asarray(gyr, float), axis=1)
    w = np.where(np.isfinite(w), w, 0.0)
    n = len(w)
    out = np.full(n, np.nan)
    blk = int(round(CYCLE_BLOCK_S * fs))
    lo, hi = int(round(CYCLE_MIN_S * fs)), int(round(CYCLE_MAX_S * fs))
    if n < 2 * lo:
        return out
    starts = list(range(0, max(1, n - blk + 1), max(1, blk // 2)))
    if starts[-1] + blk < n:
        starts.append(max(0, n - blk))
    centres, periods = [], []
    for s0 in starts:
        x = w[s0:s0 + blk] - w[s0:s0 + blk].mean()
        m = len(x)
        den = float(np.dot(x, x))
        per = np.nan
        if den > 0 and m > lo + 2:
            top = min(hi, m - 2)
            f = np.fft.rfft(x, 2 * m)
            ac = np.fft.irfft(f * np.conj(f))[:top + 2] / den
            ac = ac * m / (m - np.arange(top + 2))          # unbiased: a lag of half the block counts fully
            pk = [k for k in range(max(lo, 1), top + 1) if ac[k] >= ac[k - 1] and ac[k] >= ac[k + 1]
                  and ac[k] >= CYCLE_MIN_R]
            if pk:
                best = max(ac[k] for k in pk)
                per = next(k for k in pk if ac[k] >= 0.8 * best) / fs
        centres.append(s0 + min(blk, n - s0) / 2)
        periods.append(per)
    centres = np.asarray(centres)
    idx = np.abs(np.arange(n)[:, None] - centres[None, :]).argmin(axis=1) if len(centres) < 64 else \
        np.clip(np.searchsorted((centres[1:] + centres[:-1]) / 2, np.arange(n)), 0, len(centres) - 1)
    out[:] = np.asarray(periods)[idx]
    return out


def _motion_statistic(gyr, acc, g, params: ZuptParams, fs: float) -> np.ndarray:
    """(Z1) m_k in rad/s (non-finite samples count as moving)."""
    kappa = params.acc_tolerance_m_s2 / params.gyr_threshold_rad_s
    w = np.linalg.norm(gyr, axis=1)
    a = np.abs(np.linalg.norm(acc, axis=1) - g) / kappa
    m = np.maximum(w, a)
    m = np.where(np.isfinite(m), m, np.inf)
    half = max(0, int(round(params.window_s * fs / 2)))
    return _window_max(m, half)


def sensor_gravity(gyr: np.ndarray, acc: np.ndarray, *, sampling_rate_hz: float,
                   params: "ZuptParams | None" = None) -> float:
    """(Z2) the accelerometer's own reading of gravity (m/s²): median |f| over the still samples by the fixed
    detector; 9.81 when fewer than 0.2 s are still."""
    p = params or ZuptParams()
    still = _motion_statistic(gyr, acc, GRAVITY, p, sampling_rate_hz) <= p.gyr_threshold_rad_s
    if still.sum() < 0.2 * sampling_rate_hz:
        return GRAVITY
    return float(np.median(np.linalg.norm(acc[still], axis=1)))


def detect_zupt(gyr: np.ndarray, acc: np.ndarray, *, sampling_rate_hz: float,
                params: ZuptParams = ZuptParams(), gravity: float | None = None) -> np.ndarray:
    """(N,) bool: samples where the foot is at rest (stance), (Z1)–(Z4) in :class:`ZuptParams`.

    ``gravity``: the sensor's gravity reading (Z2); None = estimated here (adaptive) or 9.81 (fixed)."""
    gyr = np.asarray(gyr, float)
    acc = np.asarray(acc, float)
    fs = float(sampling_rate_hz)
    n = gyr.shape[0]
    if n == 0:
        return np.zeros(0, bool)
    if not params.adaptive:
        mask = _motion_statistic(gyr, acc, GRAVITY if gravity is None else gravity, params, fs) \
            <= params.gyr_threshold_rad_s
    else:
        g = sensor_gravity(gyr, acc, sampling_rate_hz=fs, params=params) if gravity is None else gravity
        m = _motion_statistic(gyr, acc, g, params, fs)
        half = max(1, int(round(params.adapt_window_s * fs)))
        nk = _window_min(m, half)
        mk = _window_max(m, half)
        w = np.linalg.norm(gyr, axis=1)
        wq = _window_max(np.where(np.isfinite(w), w, np.inf), half // 2)
        k = int(np.argmin(wq))                                # quietest window of the recording (Z4)
        seg = w[max(0, k - half // 2):k + half // 2 + 1]
        sd = float(np.std(seg[np.isfinite(seg)])) if np.isfinite(seg).sum() > 2 else 0.0
        lo = params.gyr_threshold_rad_s * min(max(1.0, 4.0 * sd / params.gyr_threshold_rad_s), 2.0)
        thr = np.where(mk >= params.adapt_contrast * nk,
                       np.clip(params.adapt_ratio * nk, lo, max(lo, params.adapt_max_rad_s)), lo)
        mask = m <= thr
    mask = np.ascontiguousarray(mask, dtype=np.bool_)
    _drop_short(mask, max(1, int(round(params.min_stance_s * fs))))
    if params.adaptive and params.cycle_window:                                        # (Z5)
        per = gait_cycle_period(gyr, sampling_rate_hz=fs)
        if np.isfinite(per).any():
            hk = np.where(np.isfinite(per), np.round(0.5 * per * fs), 0).astype(np.int64)
            quietest = np.isfinite(per) & (m <= _window_min_var(m, hk)) & (m <= params.adapt_max_rad_s)
            hw = max(0, int(round(params.window_s * fs / 2)))
            mask |= _window_max(quietest.astype(float), hw) > 0
    return mask


#: the foot trajectory's stance detector (``EskfParams.zupt``), its own instance: the ``ZuptParams`` defaults but a
#: minimum stance of 0.1 s, chosen by the trajectory's leave-one-trial-out (``PYSHOE_GRID`` x 0.05 / 0.1 / 0.15 s,
#: 28/28 folds; validation/provenance.toml). The gait events keep theirs (``GAIT_ZUPT``, 0.05 s, in
#: ``FootParams.trajectory``); the gait stage stores the trajectory on this one (``foot_trajectory``, K4), so the
#: trajectory bench's shipped_defaults are what the pipeline stores (tests/pipeline/test_stage_bench_agreement.py)
TRAJECTORY_ZUPT = ZuptParams(min_stance_s=0.1)


@dataclass(frozen=True)
class EskfParams:
    """Error-state Kalman filter with ZUPT and RTS smoother (equations E1–E7 in ``_eskf``).

    acc_noise_m_s2: per-sample accelerometer white-noise std σ_a (Q_v = (σ_a T)²).
    gyr_noise_rad_s: per-sample gyroscope white-noise std σ_g (Q_θ = (σ_g T)²).
    acc_noise_rel, gyr_noise_rel: c_a, c_g of (E4b): extra std proportional to ``| |f| − g |`` (impacts: clipped
        and under-sampled, their integral barely known) and to the angular rate ``|ω|`` (gyro scale-factor and
        cross-axis errors, 1–3 % on MEMS data sheets, and what the saturation repair cannot restore grow with the
        rate). Issue 43: c_g 0.01 → 0.03, chosen by leave-one-trial-out over ``PYSHOE_GRID``. With c_g = 0.01 the
        smoother blamed a running stride's velocity error on the 60–100 m/s² impacts and large swing
        accelerations (c_a term) and put the correction there, hardly moving the position; the rate term lets it
        blame the attitude during fast rotation, where running errs. c_a 0.3 → 0.15 (issue 43, second grid:
        leave-one-trial-out over ``PYSHOE_GRID``; 0.15 had been held back because it broke the gaitmap walk's
        stride-length target, which the midpoint attitude rule (E1c) removed: 1.7 cm there with 0.15).
    impact_window_s: the c_a term uses the largest ``| |f| − g |`` within ±impact_window_s/2 of each sample (E4c):
        a heel-strike transient lasts about 20–30 ms (Whittle, *Gait Analysis*, heel-strike transient) and is
        under-sampled at 100–200 Hz, so the sampled peak says *that* an impact happened, not on which of its
        samples the integration error was made. 0.03 s is that physiological duration, not fitted; on the gaitmap
        walk any window of 1–5 samples each side lowers the stride-length MAE (scan in docs/gait.md).
    pos_noise_m: per-sample position process noise std (keeps P regular for the smoother; tiny).
    zupt_noise_m_s: σ_z of the zero-velocity pseudo-measurement (Duong & Suh Table 1: 0.01 m/s).
    zupt_lever_m: r_lever of (E5b): during heel/toe rocker a point 0.1 m (half a foot) from the contact moves at
        |ω|·r, so a ZUPT is only as certain as that (0.1 m chosen from foot geometry, not fitted).
    estimate_biases: 15 states (+ b_a, b_g) instead of 9; slower, helps long stance-free stretches.
    acc_bias_rw, gyr_bias_rw: bias random-walk densities (m/s²/√s, rad/s/√s) when ``estimate_biases``.
    init_att_std_rad, init_acc_bias_m_s2, init_gyr_bias_rad_s: initial standard deviations.
    smooth: run the RTS backward pass (False: forward filter only, the causal variant).
    repair_saturation: rebuild clipped gyro peaks and raise σ_g there (``_saturation`` S1–S4).
    normalise_gravity: scale the accelerometer by 9.81 / g_s (g_s = its own reading at rest, ZuptParams Z2)
        against a scale-factor error. Off by default: leave-one-trial-out on PyShoe (g_s 9.79–9.83) cannot tell
        the two apart and the simpler option is kept; on the gaitmap walk (g_s 9.85/9.81) it shortens strides.
        The ZUPT detector always uses g_s (Z2).
    gyro_bias: "none" (default) or "stances": subtract a constant gyro bias estimated as the per-axis median of
        the gyro over the quiet cores of *all* detected stance runs (samples with |ω| ≤ θ_lo; at least
        ``GYRO_BIAS_MIN_S`` = 2 s in ≥ 5 runs, else no bias) — (E1b). Issue 43: the former option
        ``initial_gyro_bias`` took the mean of the first stance run (≤ 1 s), which held the foot's settling
        rotation, not the bias (up to 0.6 °/s of yaw drift on slow PyShoe trials); removed. Chosen by
        leave-one-trial-out (``PYSHOE_GRID``; validation/provenance.toml).
        "rest" (issue 43, third round): the mean gyro over the recording's rests, every ``REST_WINDOW_S`` = 2 s
        window in which the rate never exceeds ``REST_MAX_RAD_S`` = 0.05 rad/s (the sensor is at rest: no foot
        settles, rolls or sways that slowly for 2 s; a still MEMS gyro's 2 s maximum is about 4 σ of its noise,
        0.03 rad/s for PyShoe's MicroStrain); no rest, no bias — (E1d). A genuine rest reads the bias alone; a
        stance core does not (it rolls). Both numbers a priori. Not the default: leave-one-trial-out over
        ``PYSHOE_GRID`` prefers it in 28/28 folds by a tie (cross-validated mean −0.2 mm, median +0.8 mm, below
        the spread of the bias estimate itself), and ties keep "none" (validation/provenance.toml).
    stance_height_var: σ_h² (m²) of the flat-floor stance-height update (E5c): at each stance sample the
        pseudo-measurement z = p_z,0 − p̂_z (the foot stands at the height of its first stance; Duong & Suh 2015
        "zero velocity + height updating", their B6.4 baseline, 1e-4 m²). 0 = off (default): it is only true on
        a flat floor (no stairs, ramps); it removes the height drift of 10–15 mm per stride on flat walks.
    noise_model: "global" (default; E4b on every sample) or "phase" (E4d, issue 43): "phase" leaves the impact
        term c_a·| |f| − g | out at stance samples (the foot is still by the detector) and adds σ += L_j on samples
        of an accelerometer axis on a plateau near full scale (saturation). Not chosen: leave-one-trial-out kept
        "global" in 28/28 folds (grid mean 2-D ARMSE 0.0916 vs 0.0925 m; PyShoe's accelerometer never clips).
    attitude_rule: "midpoint" (default, issue 43) or "euler" (before). (E1) with ω_k over [t_k, t_k+1] (forward
        Euler) leaves the attitude half a sample behind the accelerometer sample it rotates in (E2): the sum
        Σ T ω(t_k) telescopes to the integral up to t_K − T/2. "midpoint" propagates with ω(t_k + T/2) = ½(ω_k +
        ω_k+1) (E1c), so R(q_k) and f_k belong to the same instant. During swing |ω| ≈ 5–10 rad/s and |f| ≈
        20–40 m/s², so half a sample at 200 Hz turns f by 1–3 % of its size: PyShoe's walking strides came out
        2–4 % short and rose 10–15 mm each (issue 43). A numerical-analysis choice (a priori), not tuned.
    gyro_delay_s: d of (E1c): the accelerometer sample k is paired with the gyro at t_k + d (d > 0: the gyro's
        digital filter delays it by d more than the accelerometer's). Sensor-specific (filter group delays);
        the default is chosen by leave-one-trial-out over ``PYSHOE_GRID`` (validation/provenance.toml).
    zupt: the stance detector parameters of the trajectory: ``TRAJECTORY_ZUPT``, its own frozen instance (issue 43,
        fourth round), not the ``ZuptParams`` class default that the gait events keep (``FootParams.trajectory``
        pins those): the two are chosen by different cross-validations (PyShoe trajectory error here, Voisard
        event timing there), so a value one of them picks must not move the other. It differs from the class
        default in ``min_stance_s`` only (0.1 s, chosen by leave-one-trial-out over ``PYSHOE_GRID``;
        validation/provenance.toml).
    """
    acc_noise_m_s2: float = 0.5
    gyr_noise_rad_s: float = 0.02
    acc_noise_rel: float = 0.15
    gyr_noise_rel: float = 0.03
    impact_window_s: float = 0.03
    pos_noise_m: float = 1e-5
    zupt_noise_m_s: float = 0.01
    zupt_lever_m: float = 0.1
    estimate_biases: bool = False
    acc_bias_rw: float = 1e-3
    gyr_bias_rw: float = 1e-4
    init_att_std_rad: float = 0.02
    init_acc_bias_m_s2: float = 0.1
    init_gyr_bias_rad_s: float = 0.01
    smooth: bool = True
    repair_saturation: bool = True
    normalise_gravity: bool = False
    gyro_bias: str = "none"
    zupt: ZuptParams = TRAJECTORY_ZUPT
    noise_model: str = "global"
    stance_height_var: float = 0.0
    attitude_rule: str = "midpoint"
    gyro_delay_s: float = 0.0025
    zaru: bool = False


def _acc_clip_noise(acc: np.ndarray) -> np.ndarray:
    """(E4d) saturation term: an accelerometer axis on a plateau near full scale (``_saturation.plateau_runs``,
    the gyro rule S1–S2 applied to |f_j| with ω_min → 4 g) reads at most its range, the true value is unknown
    above it: σ += L_j (the size of the reading itself) on those samples; 0 elsewhere."""
    from stridelab.estimators.trajectory._saturation import N_MIN_RUNS, plateau_runs
    out = np.zeros(acc.shape[0])
    for j in range(acc.shape[1]):
        a = np.abs(acc[:, j])
        fin = np.isfinite(a)
        if not fin.any():
            continue
        L = float(a[fin].max())
        if L < 4.0 * GRAVITY:
            continue
        runs = plateau_runs(a, L)
        if len(runs) >= N_MIN_RUNS:
            for s0, e0 in runs:
                out[s0:e0] += L
    return out


@dataclass(frozen=True)
class TrajectoryResult:
    """Foot trajectory, one row per input sample (NaN before the first stance, where the filter starts).

    pos: (N, 3) m, ENU-like world (z up, yaw of the first stance = 0, origin = sensor at the first stance).
    vel: (N, 3) m/s.  quat: (N, 4) [w x y z] sensor→world.  bias: (N, 6) b_a (m/s²), b_g (rad/s).
    zupt: (N,) bool stance samples used as zero-velocity updates.
    start_idx: first filtered sample (−1 when no stance was found).
    status: "ok" | "no_stance".
    """
    pos: np.ndarray
    vel: np.ndarray
    quat: np.ndarray
    bias: np.ndarray
    zupt: np.ndarray
    start_idx: int
    status: str
    params: EskfParams
    sensor_gravity_m_s2: float = GRAVITY
    gyro_clipped_axes: tuple = ()


REST_WINDOW_S = 2.0
REST_MAX_RAD_S = 0.05
GYRO_BIAS_MIN_S = 2.0
GYRO_BIAS_MIN_RUNS = 5


def stance_gyro_bias(gyr: np.ndarray, zupt: np.ndarray, *, sampling_rate_hz: float,
                     quiet_rad_s: float = 0.3) -> np.ndarray:
    """(E1b) constant gyro bias (3,) rad/s: per-axis median of ω over the stance samples with |ω| ≤ ``quiet_rad_s``
    (the quiet cores of foot flat), from at least ``GYRO_BIAS_MIN_S`` s in ≥ ``GYRO_BIAS_MIN_RUNS`` stance runs;
    zeros otherwise. The median over many stances cancels the signed roll-over of single stances; one stance
    (the former 1 s estimate) cannot tell its settling rotation from a bias."""
    gyr = np.asarray(gyr, float)
    zupt = np.asarray(zupt, bool)
    d = np.diff(np.concatenate([[0], zupt.astype(np.int8), [0]]))
    quiet = zupt & (np.linalg.norm(gyr, axis=1) <= quiet_rad_s) & np.all(np.isfinite(gyr), axis=1)
    n_runs = sum(1 for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)) if quiet[a:b].any())
    if quiet.sum() < GYRO_BIAS_MIN_S * sampling_rate_hz or n_runs < GYRO_BIAS_MIN_RUNS:
        return np.zeros(3)
    return np.median(gyr[quiet], axis=0)


def rest_gyro_bias(gyr: np.ndarray, *, sampling_rate_hz: float, window_s: float = REST_WINDOW_S,
                   max_rad_s: float = REST_MAX_RAD_S) -> np.ndarray:
    """(E1d) constant gyro bias (3,) rad/s from the recording's rests: the per-axis mean of ω over every sample
    that lies in some window of ``window_s`` whose largest |ω| is ≤ ``max_rad_s`` (the sensor is still, so the
    gyro reads its bias plus noise; all rests together, not one window: a 2 s window alone leaves about
    ±1 mrad/s, i.e. ±3°/min of yaw); zeros when there is no such window (no rest, no estimate: a foot in
    stance rolls)."""
    gyr = np.asarray(gyr, float)
    w = np.linalg.norm(gyr, axis=1)
    w = np.where(np.isfinite(w), w, np.inf)
    n_w = int(round(window_s * sampling_rate_hz))
    if n_w < 2 or len(w) < n_w:
        return np.zeros(3)
    still = np.lib.stride_tricks.sliding_window_view(w, n_w).max(axis=1) <= max_rad_s   # window starting at i
    if not still.any():
        return np.zeros(3)
    rest = np.zeros(len(w), bool)
    for i in np.flatnonzero(still):
        rest[i:i + n_w] = True
    return gyr[rest].mean(axis=0)


def check_foot_imu(gyr, acc, sampling_rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Validate shapes, rate and units (P12); return float64 C-contiguous copies."""
    gyr = np.ascontiguousarray(gyr, dtype=float)
    acc = np.ascontiguousarray(acc, dtype=float)
    if gyr.ndim != 2 or gyr.shape[1] != 3 or acc.shape != gyr.shape:
        raise ValueError(f"gyr and acc must both be (N, 3) arrays; got {gyr.shape} and {acc.shape}")
    if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
        raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
    if len(acc):
        g = float(np.nanmedian(np.linalg.norm(acc, axis=1)))
        if 0.5 < g < 2.0:
            raise ValueError(f"acc median norm is {g:.2f}: looks like g, expected m/s² (multiply by 9.80665)")
        if np.nanpercentile(np.abs(gyr), 99) > 35.0:
            raise ValueError("gyr looks like deg/s, expected rad/s (use np.deg2rad)")
    return gyr, acc


def _level_quat(f: np.ndarray) -> np.ndarray:
    """Quaternion (yaw 0 in the sense of the shortest rotation) that maps the mean specific force ``f`` onto +z."""
    u = f / np.linalg.norm(f)
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(u, z))
    axis = np.cross(u, z)
    s = np.linalg.norm(axis)
    if s < 1e-12:
        return np.array([1.0, 0.0, 0.0, 0.0]) if c > 0 else np.array([0.0, 1.0, 0.0, 0.0])
    ang = np.arctan2(s, c)
    axis = axis / s
    return np.concatenate([[np.cos(ang / 2)], np.sin(ang / 2) * axis])


def _attitude_gyro(gyr: np.ndarray, params: EskfParams, fs: float) -> np.ndarray:
    """(E1c) the angular rate that propagates the attitude from t_k to t_k+1: ω(t_k + s T) with s = ½ ("midpoint")
    or 0 ("euler") plus d·fs (``gyro_delay_s``), linearly interpolated between samples (held at the ends)."""
    if params.attitude_rule not in ("midpoint", "euler"):
        raise ValueError(f"attitude_rule must be 'midpoint' or 'euler', got {params.attitude_rule!r}")
    if not np.isfinite(params.gyro_delay_s):
        raise ValueError(f"gyro_delay_s must be finite, got {params.gyro_delay_s}")
    shift = (0.5 if params.attitude_rule == "midpoint" else 0.0) + params.gyro_delay_s * fs
    n = gyr.shape[0]
    if shift == 0.0 or n < 2:
        return gyr
    t = np.arange(n, dtype=float)
    return np.ascontiguousarray(np.column_stack([np.interp(t + shift, t, gyr[:, j]) for j in range(3)]))


def _same_filter(a: EskfParams, b: EskfParams) -> bool:
    """True when two parameter sets give the same filter for the same stance mask: they differ at most in the
    detector's minimum stance duration, which acts only through the mask (``_drop_short`` in ``detect_zupt``)."""
    return a == replace(b, zupt=replace(b.zupt, min_stance_s=a.zupt.min_stance_s))


def eskf_trajectory(gyr: np.ndarray, acc: np.ndarray, *, sampling_rate_hz: float,
                    params: EskfParams = EskfParams(), zupt: np.ndarray | None = None,
                    reuse: "TrajectoryResult | None" = None) -> TrajectoryResult:
    """Foot position, velocity and attitude by ESKF + ZUPT + RTS (module ``_eskf`` equations E1–E7).

    gyr (N, 3) rad/s, acc (N, 3) m/s² specific force (any mounting). ``zupt`` (N,) bool overrides the detector.
    No stance → a warning and ``status="no_stance"`` with all-NaN arrays (no invented trajectory).
    ``reuse``: a result of this function on the *same* gyr, acc and rate (the caller's promise); when its stance
    mask and filter parameters equal this call's (they may differ in ``zupt.min_stance_s`` only), its arrays are
    returned instead of running the filter again (the same numbers: the filter is deterministic), with ``params``.
    """
    gyr, acc = check_foot_imu(gyr, acc, sampling_rate_hz)
    n_s = gyr.shape[0]
    extra_g = np.zeros(n_s)
    clipped = ()
    if params.repair_saturation and n_s:
        gyr, extra_g, cl = repair_gyro_saturation(gyr)
        clipped = tuple(int(j) for j in np.flatnonzero(cl))
    g_s = GRAVITY
    if params.normalise_gravity and n_s:
        g_s = sensor_gravity(gyr, acc, sampling_rate_hz=sampling_rate_hz, params=params.zupt)
        acc = acc * (GRAVITY / g_s)
    if zupt is None:
        zupt = detect_zupt(gyr, acc, sampling_rate_hz=sampling_rate_hz, params=params.zupt, gravity=GRAVITY) \
            if n_s else np.zeros(0, bool)
    zupt = np.ascontiguousarray(zupt, dtype=np.bool_)
    if zupt.shape != (n_s,):
        raise ValueError(f"zupt must be (N,) bool with N = {n_s}; got {zupt.shape}")
    if reuse is not None and reuse.zupt.shape == zupt.shape and np.array_equal(reuse.zupt, zupt) \
            and _same_filter(reuse.params, params):
        return replace(reuse, params=params)
    nan3 = np.full((n_s, 3), np.nan)
    if not zupt.any():
        warnings.warn("eskf_trajectory: no stance (zero-velocity) sample detected; no trajectory computed",
                      stacklevel=2)
        return TrajectoryResult(nan3, nan3.copy(), np.full((n_s, 4), np.nan), np.full((n_s, 6), np.nan), zupt, -1,
                                "no_stance", params, g_s, clipped)
    k0 = int(np.argmax(zupt))
    k1 = k0
    lim = min(n_s, k0 + int(round(1.0 * sampling_rate_hz)))
    while k1 < lim and zupt[k1]:
        k1 += 1
    f0 = acc[k0:k1].mean(axis=0)
    if params.gyro_bias not in ("none", "stances", "rest"):
        raise ValueError(f"gyro_bias must be 'none', 'stances' or 'rest', got {params.gyro_bias!r}")
    if params.noise_model not in ("phase", "global"):
        raise ValueError(f"noise_model must be 'phase' or 'global', got {params.noise_model!r}")
    bg0 = stance_gyro_bias(gyr, zupt, sampling_rate_hz=sampling_rate_hz, quiet_rad_s=params.zupt.gyr_threshold_rad_s) \
        if params.gyro_bias == "stances" else \
        rest_gyro_bias(gyr, sampling_rate_hz=sampling_rate_hz) if params.gyro_bias == "rest" else np.zeros(3)
    q0 = _level_quat(f0)
    T = 1.0 / sampling_rate_hz
    ns = 15 if params.estimate_biases else 9
    qd = np.zeros(ns)
    qd[0:3] = params.pos_noise_m ** 2
    qd[3:6] = (params.acc_noise_m_s2 * T) ** 2
    qd[6:9] = (params.gyr_noise_rad_s * T) ** 2
    p0 = np.zeros(ns)
    p0[0:3] = 1e-8
    p0[3:6] = 1e-6
    p0[6:9] = params.init_att_std_rad ** 2
    if ns == 15:
        qd[9:12] = params.acc_bias_rw ** 2 * T
        qd[12:15] = params.gyr_bias_rw ** 2 * T
        p0[9:12] = params.init_acc_bias_m_s2 ** 2
        p0[12:15] = params.init_gyr_bias_rad_s ** 2
    pos, vel = nan3, nan3.copy()
    quat = np.full((n_s, 4), np.nan)
    bias = np.full((n_s, 6), np.nan)
    dev = np.abs(np.linalg.norm(acc, axis=1) - GRAVITY)
    half = int(round(0.5 * params.impact_window_s * sampling_rate_hz))
    if half > 0:
        dev = _window_max(dev, half)                                                     # (E4c)
    c_a = params.acc_noise_rel
    if params.noise_model == "phase":                                                    # (E4d)
        sig_a = params.acc_noise_m_s2 + c_a * dev * ~zupt + _acc_clip_noise(acc)
    else:
        sig_a = params.acc_noise_m_s2 + c_a * dev
    sig_g = params.gyr_noise_rad_s + params.gyr_noise_rel * np.linalg.norm(gyr, axis=1) + extra_g      # (S4)
    gyr_att = _attitude_gyro(gyr, params, sampling_rate_hz)                              # (E1c)
    if params.zaru and not params.estimate_biases:
        raise ValueError("zaru=True needs estimate_biases=True (the zero angular-rate update observes the gyro bias)")
    sig_zaru = np.where(zupt, params.gyr_noise_rad_s + np.linalg.norm(gyr, axis=1), 0.0) if params.zaru \
        else np.zeros(0)                                                                 # (E5d)
    eskf_rts_kernel(gyr_att, acc, zupt, T, k0, q0, bg0, ns, qd, sig_a, sig_g, p0, params.zupt_noise_m_s + params.zupt_lever_m * np.linalg.norm(gyr, axis=1), params.smooth,
                    pos, vel, quat, bias, float(params.stance_height_var), gyr, np.ascontiguousarray(sig_zaru))
    return TrajectoryResult(pos, vel, quat, bias, zupt, k0, "ok", params, g_s, clipped)
