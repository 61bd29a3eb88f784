"""The thesis' 13-state full-state filters: robust EKF "Nazarahari(2021)" and linear KF "Nazarahari(2020)".

Nazarahari 2021 PhD thesis ch. 5 (journal: Nazarahari & Rouhani, Information Fusion 76:8-23, 2021,
doi:10.1016/j.inffus.2021.04.009); spec/thesis_orientation.md §5.1-5.3 and §8. State
``[q, a, b_G, d]``: orientation (sensor→ENU), external acceleration (g), gyro bias (rad/s), magnetic
disturbance (field-norm units); both sensors' AR(1)/random-walk models of Th. Eqs 2, 4, 6; 2-level
(or n-level) switching of σ_G on |y_G|, σ_A on Δ_A, σ_M on Δ_M (Th. Eqs 48-50, strict ``<``).

* :func:`robust_ekf` — EKF on ``[y_A, y_M]`` with the H∞-type covariance update of Th. Eq 47, computed in
  the equivalent information form ``(P⁺)⁻¹ = (P⁻)⁻¹ + HᵀR⁻¹H − γ⁻² I`` (``gamma = inf`` is the plain EKF).
  When ``(P_ekf)⁻¹ − γ⁻² I`` is not positive definite the step falls back to the EKF update and is counted
  (A18; ``n_robust_fallback`` in the result).
* :func:`full_state_lkf` — LKF whose measurement is the state after one gradient step (Th. Eq 32) and whose
  R is the sensor noise propagated through that step (Th. Eqs 35-37). ``literal=True`` replicates the
  thesis as printed; the default applies the corrections of spec §8 A1/A2 (below).

Units inside: acc in g (divided by the norm measured in the initial window, spec §1.3), mag divided by its
norm in the initial window, so ``S_A`` is in g and ``S_M`` in fractions of the field norm. Earth field
reference ``m = (0, m_N, m_U)`` from the initial window (ENU, magnetic north = +y; spec A5 in ENU).

Deviations (all from spec §8): exact quaternion exponential for the mean, Jacobians of Eq 39-40 with the
exact exponential for the q block (A15); σ = standard deviation (A14); P0 = p0·I (A6); initial q from the
FQA of the mean of the first ``init_s`` seconds; the initial gyro bias is the mean gyro of that window when
the sensor is still there (static bias removal, C1), else 0. LKF default (``literal=False``): z is built
from the prediction x⁻ (A2), the covariance is propagated with the EKF Jacobian (A1), and the bias rows,
which carry no information (z_b ≡ x̄_b with zero noise), are dropped from the measurement — otherwise they
pin b to its prior whatever the coupling; the d rows are dropped in 6D for the same reason.
Gaps: NaN gyro holds the attitude (prediction with ω = 0), NaN acc skips the update, NaN mag updates with
acc only; 6D (mag=None): acc-only update, heading from the gyro.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from stridelab.estimators.orientation._fqa import fqa
from stridelab.estimators.orientation._fullstate_kernel import I_FALLBACK, NX, STATE_LEN, ekf_series, lkf_series
from stridelab.estimators.orientation._types import OnlineFilter, OrientationResult
from stridelab.estimators.orientation._yun_cf import _check_inputs
from stridelab.estimators.quaternion import quat_rotate

__all__ = ["RobustEKFParams", "FullStateLKFParams", "FullStateResult", "RobustEKFFilter", "FullStateLKFFilter",
           "robust_ekf", "full_state_lkf", "full_state_lkf_literal"]

G = 9.81
#: extra entries after the kernel state: initialised flag, acc norm ref, mag norm ref, earth field (3)
_EXTRA = 6
FILTER_STATE_LEN = STATE_LEN + _EXTRA


@dataclass(frozen=True)
class RobustEKFParams:
    """Robust EKF parameters (SI / g / field-norm units; rate independent except the σ's of R, which are
    per-sample measurement noise like in the thesis).

    sigma_gyr_rad_s: gyro noise σ_G per switching level (Q quaternion block, Th. Eq 28), rad/s.
    s_gyr_rad_s: thresholds on |y_G| between the σ_G levels, rad/s (len = levels − 1).
    sigma_acc_g: accelerometer noise σ_A per level (R), g.
    s_acc_g: thresholds on Δ_A = | |y_A| − 1 | between the σ_A levels, g.
    sigma_mag: magnetometer noise σ_M per level (R), fractions of the field norm.
    s_mag: thresholds on Δ_M = | |y_M| − 1 |, fractions of the field norm.
    tau_ext_acc_s: time constant of the AR(1) external acceleration, s (c_a = exp(−T/τ)).
    tau_mag_dist_s: time constant of the AR(1) magnetic disturbance, s (c_d = exp(−T/τ)).
    sigma_ext_acc_g: driving noise of a, g/√s (Q = σ² T).
    sigma_bias_rad_s: random-walk noise of the gyro bias, rad/s/√s.
    sigma_mag_dist: driving noise of d, field-norm/√s.
    p0: initial covariance P0 = p0·I (A6).
    gamma: H∞ bound γ (Th. Eq 46-47); ``math.inf`` = plain EKF. 30 inflates P mildly; below ≈ 10 the
        heading variance (weakly observed through the magnetometer) blows up on BROAD (A18 fallbacks).
    init_s: initial attitude, references and static gyro bias from the first ``init_s`` seconds.
    static_bias: take the initial bias from that window when the sensor is still in it (C1).
    """
    sigma_gyr_rad_s: tuple[float, ...] = (0.005, 0.05)
    s_gyr_rad_s: tuple[float, ...] = (1.0,)
    sigma_acc_g: tuple[float, ...] = (0.05, 0.5)
    s_acc_g: tuple[float, ...] = (0.05,)
    sigma_mag: tuple[float, ...] = (0.3, 3.0)
    s_mag: tuple[float, ...] = (0.1,)
    tau_ext_acc_s: float = 0.05
    tau_mag_dist_s: float = 5.0
    sigma_ext_acc_g: float = 0.5
    sigma_bias_rad_s: float = 1e-4
    sigma_mag_dist: float = 0.05
    p0: float = 1e-3
    gamma: float = 30.0
    init_s: float = 0.5
    static_bias: bool = True


@dataclass(frozen=True)
class FullStateLKFParams:
    """Full-state LKF parameters: the fields of :class:`RobustEKFParams` without ``gamma``, plus

    mu: learning rate μ of the gradient step that forms the measurement (Th. Eq 32).
    literal: replicate the thesis as printed (True) or apply spec §8 A1/A2 (False, default).
    """
    sigma_gyr_rad_s: tuple[float, ...] = (0.005, 0.05)
    s_gyr_rad_s: tuple[float, ...] = (1.0,)
    sigma_acc_g: tuple[float, ...] = (0.2, 2.0)
    s_acc_g: tuple[float, ...] = (0.05,)
    sigma_mag: tuple[float, ...] = (0.5, 5.0)
    s_mag: tuple[float, ...] = (0.1,)
    tau_ext_acc_s: float = 0.05
    tau_mag_dist_s: float = 5.0
    sigma_ext_acc_g: float = 0.5
    sigma_bias_rad_s: float = 1e-4
    sigma_mag_dist: float = 0.05
    p0: float = 1e-3
    mu: float = 0.25
    literal: bool = False
    init_s: float = 0.5
    static_bias: bool = True


@dataclass(frozen=True)
class FullStateResult(OrientationResult):
    """:class:`OrientationResult` plus the full state (one row per sample).

    gain: σ_A in force (g) — the accelerometer trust level chosen by the switch.
    gyr_bias: (N, 3) estimated gyro bias, rad/s, sensor frame.
    ext_acc: (N, 3) estimated external (non-gravitational) acceleration, m/s², sensor frame.
    mag_dist: (N, 3) estimated magnetic disturbance, in the unit of the input mag, sensor frame.
    levels: (N, 3) int8 switching levels of (σ_G, σ_A, σ_M).
    n_robust_fallback: steps where the robust update did not exist and the EKF update was used (A18).
    """
    gyr_bias: np.ndarray = field(default=None)
    ext_acc: np.ndarray = field(default=None)
    mag_dist: np.ndarray = field(default=None)
    levels: np.ndarray = field(default=None)
    n_robust_fallback: int = 0


def _levels(lv, th, name):
    lv = np.asarray(lv, dtype=np.float64)
    th = np.asarray(th, dtype=np.float64)
    if lv.ndim != 1 or len(lv) < 1 or len(th) != len(lv) - 1 or np.any(np.diff(th) <= 0) or np.any(lv <= 0):
        raise ValueError(f"{name}: need ≥ 1 positive level and len(levels) − 1 increasing thresholds; "
                         f"got levels {tuple(lv)}, thresholds {tuple(th)}")
    return lv, th


def _coef(p, dt, last):
    ca = math.exp(-dt / p.tau_ext_acc_s) if p.tau_ext_acc_s > 0 else 0.0
    cd = math.exp(-dt / p.tau_mag_dist_s) if p.tau_mag_dist_s > 0 else 0.0
    return np.array([ca, cd, p.sigma_ext_acc_g ** 2 * dt, p.sigma_bias_rad_s ** 2 * dt, p.sigma_mag_dist ** 2 * dt,
                     last])


class _FullStateFilter(OnlineFilter):
    """Online filter: ``state`` is a plain (FILTER_STATE_LEN,) array (x, P, counters, references); it is
    initialised from the first ``init_s`` seconds of the first chunk; chunked = whole (tested)."""

    STATE_SIZE = FILTER_STATE_LEN

    def __init__(self, params, *, sampling_rate_hz: float):
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)
        self._sg = _levels(params.sigma_gyr_rad_s, params.s_gyr_rad_s, "sigma_gyr_rad_s / s_gyr_rad_s")
        self._sa = _levels(params.sigma_acc_g, params.s_acc_g, "sigma_acc_g / s_acc_g")
        self._sm = _levels(params.sigma_mag, params.s_mag, "sigma_mag / s_mag")

    def _initialise(self, gyr, acc, mag):
        p = self.params
        n0 = max(1, int(round(p.init_s * self.sampling_rate_hz)))
        a = np.nanmean(acc[:n0], axis=0)
        if not np.all(np.isfinite(a)):
            a = np.nanmean(acc, axis=0)
        g_ref = float(np.linalg.norm(a))
        m = np.nanmean(mag[:n0], axis=0) if mag is not None else np.full(3, np.nan)
        use_m = bool(np.all(np.isfinite(m))) and np.linalg.norm(m) > 0
        if use_m:
            q0 = fqa(a[None], m[None])[0]
            h = quat_rotate(q0, m)
            m_ref = np.array([0.0, math.hypot(h[0], h[1]), h[2]])
            m_norm = float(np.linalg.norm(m))
            m_ref /= np.linalg.norm(m_ref)
        else:
            # tilt only (arbitrary heading): FQA with a synthetic field perpendicular to gravity
            ref = np.array([0.0, 1.0, 0.0]) if abs(a[1]) < 0.9 * g_ref else np.array([1.0, 0.0, 0.0])
            q0 = fqa(a[None], np.cross(a, np.cross(ref, a))[None])[0]
            m_ref, m_norm = np.array([0.0, 1.0, 0.0]), 1.0
        s = self._state
        s[:] = 0.0
        s[:4] = q0 / np.linalg.norm(q0)
        if p.static_bias:
            w = gyr[:n0]
            w = w[np.all(np.isfinite(w), axis=1)]
            if len(w):
                mw = w.mean(axis=0)
                if np.abs(w - mw).max() < 0.05 and np.linalg.norm(mw) < 0.1:
                    s[7:10] = mw
        s[NX:NX + NX * NX] = (p.p0 * np.eye(NX)).ravel()
        s[STATE_LEN] = 1.0
        s[STATE_LEN + 1] = g_ref
        s[STATE_LEN + 2] = m_norm
        s[STATE_LEN + 3:STATE_LEN + 6] = m_ref

    def _run(self, kernel, last, extra, gyr, acc, mag) -> FullStateResult:
        gyr, acc, mag = self._chunk(gyr, acc, mag)
        n = gyr.shape[0]
        use_mag = mag is not None
        if self._state[STATE_LEN] == 0.0:
            self._initialise(gyr, acc, mag)
        s = self._state
        g_ref, m_norm, m_ref = s[STATE_LEN + 1], s[STATE_LEN + 2], s[STATE_LEN + 3:STATE_LEN + 6].copy()
        ks = s[:STATE_LEN].copy()
        q = np.empty((n, 4))
        aux = np.empty((n, 9))
        lv = np.empty((n, 3), dtype=np.int8)
        dt = 1.0 / self.sampling_rate_hz
        coef = _coef(self.params, dt, last)
        kernel(gyr, acc / g_ref, mag / m_norm if use_mag else np.empty((n, 3)), use_mag, dt, coef, *extra,
               self._sg[0], self._sg[1], self._sa[0], self._sa[1], self._sm[0], self._sm[1], m_ref, ks, q, aux, lv)
        s[:STATE_LEN] = ks
        sa = self._sa[0]
        return FullStateResult(quat=q, gain=sa[lv[:, 1]], still=np.zeros(n, dtype=bool), mag_used=use_mag,
                               params=self.params, gyr_bias=aux[:, 3:6], ext_acc=aux[:, 0:3] * g_ref,
                               mag_dist=aux[:, 6:9] * m_norm, levels=lv, n_robust_fallback=int(ks[I_FALLBACK]))


class RobustEKFFilter(_FullStateFilter):
    """Online robust EKF (see module doc): ``update_batch(gyr, acc, mag=None) -> FullStateResult``."""

    def __init__(self, params: RobustEKFParams = RobustEKFParams(), *, sampling_rate_hz: float):
        if not params.gamma > 0:
            raise ValueError(f"gamma must be > 0 (math.inf = plain EKF), got {params.gamma}")
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)

    def update_batch(self, gyr, acc, mag=None) -> FullStateResult:
        gi2 = 0.0 if math.isinf(self.params.gamma) else self.params.gamma ** -2
        return self._run(ekf_series, gi2, (), gyr, acc, mag)


class FullStateLKFFilter(_FullStateFilter):
    """Online full-state LKF (see module doc): ``update_batch(gyr, acc, mag=None) -> FullStateResult``."""

    def __init__(self, params: FullStateLKFParams = FullStateLKFParams(), *, sampling_rate_hz: float):
        if not params.mu > 0:
            raise ValueError(f"mu must be > 0, got {params.mu}")
        super().__init__(params, sampling_rate_hz=sampling_rate_hz)

    def update_batch(self, gyr, acc, mag=None) -> FullStateResult:
        return self._run(lkf_series, self.params.mu, (bool(self.params.literal),), gyr, acc, mag)


def robust_ekf(gyr, acc, mag=None, *, sampling_rate_hz: float, params: RobustEKFParams = RobustEKFParams()
               ) -> FullStateResult:
    """Orientation (sensor→ENU, [w x y z]) by the thesis' full-state robust EKF (module doc).

    gyr (N, 3) rad/s, acc (N, 3) m/s², mag (N, 3) any unit or None (6D). Returns a :class:`FullStateResult`.
    """
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    return RobustEKFFilter(params, sampling_rate_hz=sampling_rate_hz).update_batch(gyr, acc, mag)


def full_state_lkf(gyr, acc, mag=None, *, sampling_rate_hz: float,
                   params: FullStateLKFParams = FullStateLKFParams()) -> FullStateResult:
    """Orientation by the thesis' full-state linear KF, corrected per spec §8 A1/A2 (module doc)."""
    gyr, acc, mag = _check_inputs(gyr, acc, mag, sampling_rate_hz)
    return FullStateLKFFilter(params, sampling_rate_hz=sampling_rate_hz).update_batch(gyr, acc, mag)


#: the literal thesis LKF (Th. Eqs 26-37 as printed) with the default gains of :class:`FullStateLKFParams`
LITERAL_LKF = replace(FullStateLKFParams(), literal=True)


def full_state_lkf_literal(gyr, acc, mag=None, *, sampling_rate_hz: float,
                           params: FullStateLKFParams = LITERAL_LKF) -> FullStateResult:
    """The full-state LKF exactly as printed in the thesis (for replication; b_G never updates, A1)."""
    return full_state_lkf(gyr, acc, mag, sampling_rate_hz=sampling_rate_hz, params=params)

