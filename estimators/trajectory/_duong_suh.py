"""Duong & Suh 2015: foot pose from an IMU and two downward-looking distance sensors (21- and 9-state filters).

P. D. Duong, Y. S. Suh, "Foot Pose Estimation Using an Inertial Sensor Unit and Two Distance Sensors",
Sensors 15 (2015) 15888–15902, doi:10.3390/s150715888. Spec: ``spec/foot_papers.md`` Part B (B3–B7).
World z up, floor = plane z = 0. Quaternion Hamilton ``[w x y z]`` body→world, ``R = C(q)'`` (spec §0).

Error state (eq. 7), 0-based: q̄ 0:3 (body-frame half-angle, q = q̂ ⊗ [1; q̄]), r̄ 3:6, v̄ 6:9,
r̄_A 9:12, r̄_B 12:15, n̄_A 15:18, n̄_B 18:21 (the 9-state filter keeps 0:9, calibration fixed).

    nominal   q̂ ← q̂ ⊗ exp(y_g T) ;  a = R y_a − g e3 ;  r̂ ← r̂ + T v̂ + ½T² a ;  v̂ ← v̂ + T a          (DS1, B4)
    A         q̄' = −[y_g×] q̄ ;  r̄' = v̄ ;  v̄' = −2 R [y_a×] q̄ ;  calibration' = 0                    (DS2, B5)
              Φ = I + A T + ½(A T)² ;  Q = G Q_c G' T: Q_q̄ = ¼ σ_g² T I, Q_v̄ = σ_a² T I              (DS3, D2)
    distance  z̃_A = e3'(r̂ + R(r̂_A + n̂_A z_A))  (0 for a flat floor at z = 0)                            (DS4, eq. 13)
              H_A = e3'[2R[(r̂_A + n̂_A z_A)×], −I, 0, −R, 0, −R z_A, 0] ;  R_A = (e3'R n̂_A)² σ_d²      (DS5, eq. 14)
              used when 0 < z ≤ max_range, finite, beam downward (e3'R n̂ < −cos 70°), |z̃| ≤ gate·√S  (D7, D12)
    unit n    z_c = (1 − n̂'n̂)/2 = n̂' n̄ + v_c  (21-state)                                              (DS6, eq. 18)
    baseline  z_AB − ‖r̂_A − r̂_B‖ = u'(r̄_A − r̄_B) + v_AB,  u = (r̂_A − r̂_B)/‖·‖  (21-state, optional)  (DS7, eq. 20)
    ZUPT      −v̂ = v̄ + v_zero at detected stance samples                                               (DS8, eq. 23)
    update    sequential scalar updates (independent noises), Joseph form, then inject and reset      (DS9, B6.5)

Order per sample k: updates with the measurements of k, output, then propagate with the IMU sample k.
Deviations: the ZUPT detector is :func:`stridelab.estimators.trajectory.detect_zupt` (the paper's thresholds are not given,
D3); the initial attitude covariance puts the Table-1 tilt variance on the two horizontal body axes found from
gravity (the paper's body x points down; yaw variance 0), so any mounting works; n̂ is renormalised after each
injection (D6); a 3σ innovation gate rejects a beam that hits the other foot or an obstacle (D12).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from numba import njit

from stridelab.estimators.quaternion import quat_exp_step_1, quat_mul_1, quat_to_matrix_1
from stridelab.estimators.trajectory._api import ZuptParams

GRAVITY = 9.81

__all__ = ["RangeGeometry", "DuongSuhParams", "DuongSuhResult", "duong_suh_trajectory", "TABLE1_GEOMETRY",
           "EQ24_GEOMETRY", "geometry_from_stance",
           "duong_suh_params_from_dict", "UNKNOWN_GEOMETRY_CALIB_VAR"]

#: calibration-state variance (m², per component) when the mounting is only guessed (geometry_from_stance):
#: 5 cm σ, the size of a shoe's lever arms, instead of Table 1's 1 mm for a ruler-measured geometry
UNKNOWN_GEOMETRY_CALIB_VAR = 0.0025


@dataclass(frozen=True)
class RangeGeometry:
    """Distance-sensor mounting in IMU (body) coordinates: lever arms r_a, r_b (m) from the IMU to each sensor,
    unit beam directions n_a, n_b. Tuples so the params stay hashable."""
    r_a: tuple = (-0.008, 0.080, 0.0)
    r_b: tuple = (-0.006, -0.062, 0.0)
    n_a: tuple = (1.0, 0.0, 0.0)
    n_b: tuple = (1.0, 0.0, 0.0)

    def as_array(self) -> np.ndarray:
        """(4, 3): r_a, r_b, n_a, n_b."""
        return np.array([self.r_a, self.r_b, self.n_a, self.n_b], float)

    @classmethod
    def from_array(cls, g: np.ndarray) -> "RangeGeometry":
        g = np.asarray(g, float)
        return cls(*(tuple(float(v) for v in g[i]) for i in range(4)))


#: Table 1 of [D] (initial values; body x toward the floor) and the eq. (24) calibration from their walking trial
TABLE1_GEOMETRY = RangeGeometry()
EQ24_GEOMETRY = RangeGeometry(r_a=(-0.0124, 0.0806, 0.0), r_b=(-0.0033, -0.0611, -0.0006),
                              n_a=(1.0, 0.0001, 0.0), n_b=(1.0, 0.0002, -0.0001))


@dataclass(frozen=True)
class DuongSuhParams:
    """Parameters of the Duong & Suh filters (Table 1 of [D] unless said otherwise).

    estimate_calibration: 21 states (on-line calibration of the sensor geometry) or 9 states (geometry fixed).
    gyr_noise_var, acc_noise_var: Q_c, continuous-time intensities (rad²/s, m²/s³) as in spec D2 (0.00017, 0.0083).
    range_noise_var: σ_d² of a distance reading (0.0004 m²).  zupt_noise_var: 1e-4 (m/s)².
    unit_constraint_var: 1e-7 (eq. 18).  baseline_var: 1e-6 m² (eq. 20).
    baseline_m: ruler distance between the sensors z_AB (0.142 m in [D]); None = no baseline row.
    init_tilt_var: variance of each horizontal attitude error component (0.001, half-angle²).
    init_height_var: variance of the initial height (0.0001 m²).  init_calib_var: 1e-6 per calibration component.
    max_range_m: readings above this are ignored (VL6180: 0.20 m).  min_beam_down: beam used only when
        −e3'R n̂ ≥ this (cos 70° ≈ 0.342).  gate_sigma: innovation gate in σ (D12; 0 = off, the default: on the
        platform simulator a 3σ gate locked a drifted left foot out for seconds, 25 mm vs 8 mm RMS without it).
    gate_max_rejections: after this many consecutive gated readings of one sensor the next one is accepted
        (a filter that drifted away must not lock itself out; 10 readings = 0.3 s at 33.3 Hz).
    use_ranges: False gives the paper's "K.F. (zero velocity updating)" baseline.
    height_update_var: > 0 adds, at every stance sample, z_h = r_z,0 − r̂_z (flat floor: the stance height is the
        initial one), the paper's "zero velocity + height updating" baseline (B6.4, D10: 1e-4 m²); 0 = off.
    zupt: stance detector parameters.
    """
    estimate_calibration: bool = True
    gyr_noise_var: float = 0.00017
    acc_noise_var: float = 0.0083
    range_noise_var: float = 0.0004
    zupt_noise_var: float = 1e-4
    unit_constraint_var: float = 1e-7
    baseline_var: float = 1e-6
    baseline_m: float | None = 0.142
    init_tilt_var: float = 0.001
    init_height_var: float = 0.0001
    init_calib_var: float = 1e-6
    max_range_m: float = 0.20
    min_beam_down: float = 0.3420201433256687
    gate_sigma: float = 0.0
    gate_max_rejections: int = 10
    use_ranges: bool = True
    height_update_var: float = 0.0
    zupt: ZuptParams = ZuptParams()


@dataclass(frozen=True)
class DuongSuhResult:
    """Foot trajectory from the Duong & Suh filter, one row per IMU sample (NaN before the first stance).

    pos (N, 3) m (z = height of the IMU above the floor when ranges were used), vel (N, 3) m/s, quat (N, 4)
    [w x y z] body→world; zupt (N,) bool; range_used (N, 2) bool (A, B readings accepted); range_rejected (N, 2)
    bool (present but out of range, beam not downward or gated); geometry: the final calibration (the input one
    for the 9-state filter); start_idx; status "ok" | "no_stance" | "no_valid_range" (ranges given but none
    usable: the result is the ZUPT-only filter); notes; used_fraction: share of the samples carrying a reading
    (finite or +inf) whose reading was used (NaN without readings).
    """
    pos: np.ndarray
    vel: np.ndarray
    quat: np.ndarray
    zupt: np.ndarray
    range_used: np.ndarray
    range_rejected: np.ndarray
    geometry: RangeGeometry
    start_idx: int
    status: str
    notes: tuple = ()
    used_fraction: float = float("nan")


@njit(cache=True)
def _scalar_update(P, dx, h, y, r, ns, Ph):
    """One scalar measurement y = h·δx + v, var r (DS9): sequential update of δx and P (Joseph-equivalent form
    P − K S K' for the optimal gain, symmetrised)."""
    for i in range(ns):
        s = 0.0
        for j in range(ns):
            s += P[i, j] * h[j]
        Ph[i] = s
    S = r
    innov = y
    for i in range(ns):
        S += h[i] * Ph[i]
        innov -= h[i] * dx[i]
    for i in range(ns):
        dx[i] += Ph[i] / S * innov
    for i in range(ns):
        for j in range(i, ns):
            v = P[i, j] - Ph[i] * Ph[j] / S
            P[i, j] = v
            P[j, i] = v
    return S


@njit(cache=True)
def _range_row(R, rs, ns_vec, z, ns, sens, h):
    """(DS4–DS5): fills h (ns,) for sensor ``sens`` (0 = A, 1 = B); returns e3'R(rs + ns z) (without r̂_z)."""
    for i in range(ns):
        h[i] = 0.0
    a0 = rs[0] + ns_vec[0] * z
    a1 = rs[1] + ns_vec[1] * z
    a2 = rs[2] + ns_vec[2] * z
    # 2 e3'R [a×]: e3'R = R[2, :];  (row)·[a×] = row × ... : (r·[a×])_j = Σ_i r_i [a×]_ij
    r0, r1, r2 = R[2, 0], R[2, 1], R[2, 2]
    h[0] = 2.0 * (r1 * a2 - r2 * a1)
    h[1] = 2.0 * (r2 * a0 - r0 * a2)
    h[2] = 2.0 * (r0 * a1 - r1 * a0)
    h[5] = -1.0
    if ns == 21:
        off_r = 9 + 3 * sens
        off_n = 15 + 3 * sens
        for j in range(3):
            h[off_r + j] = -R[2, j]
            h[off_n + j] = -R[2, j] * z
    return r0 * a0 + r1 * a1 + r2 * a2


@njit(cache=True)
def ds_kernel(gyr, acc, rng, zupt, T, k0, q0, r0, ns, P0, qg, qa, var_d, var_z, var_c, var_ab, z_ab, max_range,
              min_down, gate, gate_max, use_ranges, var_h, geom, pos, vel, quat, used, rejected):
    """Forward Duong & Suh filter (DS1–DS9) from sample k0; writes pos/vel/quat/used/rejected rows k0… and the
    final geometry into ``geom`` (4, 3) in place."""
    n = gyr.shape[0]
    P = P0.copy()
    q = q0.copy()
    r = r0.copy()
    v = np.zeros(3)
    R = np.zeros((3, 3))
    dx = np.zeros(ns)
    h = np.zeros(ns)
    Ph = np.zeros(ns)
    M = np.zeros((9, 9))
    Phi = np.zeros((9, 9))
    tmp = np.zeros((9, ns))
    n_gated = np.zeros(2, np.int64)
    for k in range(k0, n):
        quat_to_matrix_1(q, R)
        for i in range(ns):
            dx[i] = 0.0
        any_upd = False
        if zupt[k]:
            for ax in range(3):
                for i in range(ns):
                    h[i] = 0.0
                h[6 + ax] = 1.0
                _scalar_update(P, dx, h, -v[ax], var_z, ns, Ph)
            if var_h > 0:                                      # B6.4 height-update baseline
                for i in range(ns):
                    h[i] = 0.0
                h[5] = 1.0
                _scalar_update(P, dx, h, r0[2] - r[2], var_h, ns, Ph)
            any_upd = True
        if use_ranges:
            got = False
            for sens in range(2):
                z = rng[k, sens]
                if not np.isfinite(z):
                    continue
                nvec = geom[2 + sens]
                down = -(R[2, 0] * nvec[0] + R[2, 1] * nvec[1] + R[2, 2] * nvec[2])
                if z <= 0.0 or z > max_range or down < min_down:
                    rejected[k, sens] = True
                    continue
                hz = _range_row(R, geom[sens], nvec, z, ns, sens, h)
                zt = r[2] + hz                                    # (DS4) ideally 0
                S = var_d * down * down
                for i in range(ns):
                    for j in range(ns):
                        S += h[i] * P[i, j] * h[j]
                innov = zt
                for i in range(ns):
                    innov -= h[i] * dx[i]
                if gate > 0 and innov * innov > gate * gate * S and n_gated[sens] < gate_max:
                    rejected[k, sens] = True
                    n_gated[sens] += 1
                    continue
                n_gated[sens] = 0
                _scalar_update(P, dx, h, zt, var_d * down * down, ns, Ph)
                used[k, sens] = True
                got = True
            if got and ns == 21:
                for sens in range(2):                          # (DS6) unit beam vectors
                    nvec = geom[2 + sens]
                    for i in range(ns):
                        h[i] = 0.0
                    nn = 0.0
                    for j in range(3):
                        h[15 + 3 * sens + j] = nvec[j]
                        nn += nvec[j] * nvec[j]
                    _scalar_update(P, dx, h, 0.5 * (1.0 - nn), var_c, ns, Ph)
                if z_ab > 0:                                   # (DS7) baseline
                    d0 = geom[0, 0] - geom[1, 0]
                    d1 = geom[0, 1] - geom[1, 1]
                    d2 = geom[0, 2] - geom[1, 2]
                    L = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                    if L > 1e-9:
                        for i in range(ns):
                            h[i] = 0.0
                        h[9], h[10], h[11] = d0 / L, d1 / L, d2 / L
                        h[12], h[13], h[14] = -d0 / L, -d1 / L, -d2 / L
                        _scalar_update(P, dx, h, z_ab - L, var_ab, ns, Ph)
            any_upd = any_upd or got
        if any_upd:                                            # inject and reset (DS9)
            dq = np.array([1.0, dx[0], dx[1], dx[2]])
            q = quat_mul_1(q, dq)
            q /= math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
            for j in range(3):
                r[j] += dx[3 + j]
                v[j] += dx[6 + j]
            if ns == 21:
                for s4 in range(4):
                    for j in range(3):
                        geom[s4, j] += dx[9 + 3 * s4 + j]
                for sens in range(2):
                    nn = math.sqrt(geom[2 + sens, 0] ** 2 + geom[2 + sens, 1] ** 2 + geom[2 + sens, 2] ** 2)
                    for j in range(3):
                        geom[2 + sens, j] /= nn
            quat_to_matrix_1(q, R)
        for j in range(3):
            pos[k, j] = r[j]
            vel[k, j] = v[j]
        for j in range(4):
            quat[k, j] = q[j]
        if k == n - 1:
            break
        # propagate (DS1–DS3) with sample k
        gx, gy, gz = gyr[k, 0], gyr[k, 1], gyr[k, 2]
        fx, fy, fz = acc[k, 0], acc[k, 1], acc[k, 2]
        a0 = R[0, 0] * fx + R[0, 1] * fy + R[0, 2] * fz
        a1 = R[1, 0] * fx + R[1, 1] * fy + R[1, 2] * fz
        a2 = R[2, 0] * fx + R[2, 1] * fy + R[2, 2] * fz - GRAVITY
        for i in range(9):
            for j in range(9):
                M[i, j] = 0.0
        # −[ω×] T
        M[0, 1] = gz * T
        M[0, 2] = -gy * T
        M[1, 0] = -gz * T
        M[1, 2] = gx * T
        M[2, 0] = gy * T
        M[2, 1] = -gx * T
        for j in range(3):
            M[3 + j, 6 + j] = T
        # −2 R [f×] T ; [f×] = [[0,−fz,fy],[fz,0,−fx],[−fy,fx,0]]
        for i in range(3):
            c0 = R[i, 1] * fz - R[i, 2] * fy
            c1 = -R[i, 0] * fz + R[i, 2] * fx
            c2 = R[i, 0] * fy - R[i, 1] * fx
            M[6 + i, 0] = -2.0 * T * c0
            M[6 + i, 1] = -2.0 * T * c1
            M[6 + i, 2] = -2.0 * T * c2
        for i in range(9):
            for j in range(9):
                s = 0.0
                for m in range(9):
                    s += M[i, m] * M[m, j]
                Phi[i, j] = M[i, j] + 0.5 * s + (1.0 if i == j else 0.0)
        # P_nav,all ← Φ P_nav,all ; then P_nav,nav ← (Φ P) Φ' ; P_cal,nav mirrored
        for i in range(9):
            for j in range(ns):
                s = 0.0
                for m in range(9):
                    s += Phi[i, m] * P[m, j]
                tmp[i, j] = s
        for i in range(9):
            for j in range(ns):
                P[i, j] = tmp[i, j]
        for i in range(9):
            for j in range(9):
                s = 0.0
                for m in range(9):
                    s += tmp[i, m] * Phi[j, m]
                P[i, j] = s
        for i in range(9):
            for j in range(9, ns):
                P[j, i] = P[i, j]
        for j in range(3):
            P[j, j] += 0.25 * qg * T
            P[6 + j, 6 + j] += qa * T
        for i in range(9):
            for j in range(i + 1, 9):
                s = 0.5 * (P[i, j] + P[j, i])
                P[i, j] = s
                P[j, i] = s
        # nominal (DS1)
        for j in range(3):
            aj = a0 if j == 0 else (a1 if j == 1 else a2)
            r[j] += T * v[j] + 0.5 * T * T * aj
            v[j] += T * aj
        q = quat_exp_step_1(q, gx, gy, gz, T)


def _level_quat(f: np.ndarray) -> np.ndarray:
    from stridelab.estimators.trajectory._api import _level_quat as lq
    return lq(f)


def duong_suh_trajectory(gyr: np.ndarray, acc: np.ndarray, ranges: np.ndarray | None, *, sampling_rate_hz: float,
                         geometry: RangeGeometry = TABLE1_GEOMETRY, params: DuongSuhParams = DuongSuhParams(),
                         zupt: np.ndarray | None = None, initial_quat: np.ndarray | None = None,
                         initial_height_m: float | None = None) -> DuongSuhResult:
    """Foot trajectory by the Duong & Suh 21-state (``params.estimate_calibration``) or 9-state filter.

    gyr (N, 3) rad/s, acc (N, 3) m/s²; ``ranges`` (N, 2) m on the IMU sample grid: columns A, B, NaN where no
    reading at that sample (the 33.3 Hz sensors give every third sample); +inf (REP-117: beyond the maximum) and
    NaN are ignored. ``geometry``: the sensor mounting in body coordinates (initial value for the 21-state filter).
    The filter starts at the first stance sample with the attitude levelled on gravity (yaw 0) unless
    ``initial_quat`` is given, at height ``initial_height_m`` or else from the distance readings of that stance
    (B5 "Initialisation"), or 0 without any.
    """
    from stridelab.estimators.trajectory._api import check_foot_imu, detect_zupt
    gyr, acc = check_foot_imu(gyr, acc, sampling_rate_hz)
    n = gyr.shape[0]
    if ranges is None:
        rng = np.full((n, 2), np.nan)
    else:
        rng = np.ascontiguousarray(ranges, dtype=float)
        if rng.shape != (n, 2):
            raise ValueError(f"ranges must be (N, 2) on the IMU grid with N = {n} (columns A, B); got {rng.shape}")
    if zupt is None:
        zupt = detect_zupt(gyr, acc, sampling_rate_hz=sampling_rate_hz, params=params.zupt) if n else np.zeros(0, bool)
    zupt = np.ascontiguousarray(zupt, dtype=np.bool_)
    if zupt.shape != (n,):
        raise ValueError(f"zupt must be (N,) bool with N = {n}; got {zupt.shape}")
    nan3 = np.full((n, 3), np.nan)
    flags = np.zeros((n, 2), np.bool_)
    if not zupt.any():
        warnings.warn("duong_suh_trajectory: no stance (zero-velocity) sample detected; no trajectory computed",
                      stacklevel=2)
        return DuongSuhResult(nan3, nan3.copy(), np.full((n, 4), np.nan), zupt, flags, flags.copy(), geometry, -1,
                              "no_stance", ("no stance period detected",))
    T = 1.0 / sampling_rate_hz
    k0 = int(np.argmax(zupt))
    k1 = k0
    while k1 < n and zupt[k1] and k1 - k0 < int(round(sampling_rate_hz)):
        k1 += 1
    q0 = np.asarray(initial_quat, float) if initial_quat is not None else _level_quat(acc[k0:k1].mean(axis=0))
    q0 = q0 / np.linalg.norm(q0)
    from stridelab.estimators.quaternion import quat_to_matrix
    R0 = quat_to_matrix(q0)
    geom = geometry.as_array().copy()
    notes = []
    use = bool(params.use_ranges and np.isfinite(rng).any())
    if initial_height_m is None:
        hs = []
        if use:
            for s in range(2):
                z = rng[k0:k1, s]
                z = z[np.isfinite(z) & (z > 0) & (z <= params.max_range_m)]
                if len(z):
                    hs.append(-(R0[2] @ (geom[s] + geom[2 + s] * float(np.median(z)))))
        h0 = float(np.mean(hs)) if hs else 0.0
        if use and not hs:
            notes.append("no valid distance reading at the first stance: initial height 0")
    else:
        h0 = float(initial_height_m)
    ns = 21 if params.estimate_calibration else 9
    P0 = np.zeros((ns, ns))
    up_b = R0[2]                                 # world up in body coordinates
    P0[0:3, 0:3] = params.init_tilt_var * (np.eye(3) - np.outer(up_b, up_b))
    P0[5, 5] = params.init_height_var
    if ns == 21:
        P0[9:21, 9:21] = params.init_calib_var * np.eye(12)
    pos, vel = nan3, nan3.copy()
    quat = np.full((n, 4), np.nan)
    used, rejected = flags, flags.copy()
    ds_kernel(gyr, acc, rng, zupt, T, k0, q0, np.array([0.0, 0.0, h0]), ns, P0, params.gyr_noise_var,
              params.acc_noise_var, params.range_noise_var, params.zupt_noise_var, params.unit_constraint_var,
              params.baseline_var, float(params.baseline_m or 0.0), params.max_range_m, params.min_beam_down,
              params.gate_sigma, params.gate_max_rejections, use, params.height_update_var, geom, pos, vel, quat,
              used, rejected)
    status = "ok"
    if params.use_ranges and ranges is not None and not used.any():
        status = "no_valid_range"
        notes.append("distance sensors present but no reading usable (out of range, saturated or not downward): "
                     "ZUPT-only trajectory")
    have = (~np.isnan(rng)).any(axis=1)
    frac = float(used.any(axis=1).sum() / have.sum()) if have.any() else float("nan")
    return DuongSuhResult(pos, vel, quat, zupt, used, rejected, RangeGeometry.from_array(geom), k0, status,
                          tuple(notes), frac)


def geometry_from_stance(acc: np.ndarray, zupt: np.ndarray) -> RangeGeometry | None:
    """Initial sensor geometry when the mounting is unknown: both beams along −gravity of the first stance run
    (beams perpendicular to the sole, foot flat), lever arms 0 (the 21-state filter then estimates them; the
    vertical lever between IMU and sensors stays unobservable, so absolute heights carry that offset — give the
    measured geometry when it matters). None without stance."""
    zupt = np.asarray(zupt, bool)
    if not zupt.any():
        return None
    k0 = int(np.argmax(zupt))
    k1 = k0
    while k1 < len(zupt) and zupt[k1]:
        k1 += 1
    up = np.asarray(acc, float)[k0:k1].mean(axis=0)
    down = tuple(float(v) for v in -up / np.linalg.norm(up))
    return RangeGeometry(r_a=(0.0, 0.0, 0.0), r_b=(0.0, 0.0, 0.0), n_a=down, n_b=down)


def duong_suh_params_from_dict(d: dict) -> DuongSuhParams:
    """:class:`DuongSuhParams` from its ``dataclasses.asdict`` form (unknown keys raise ``TypeError``)."""
    d = dict(d)
    zupt = ZuptParams(**d.pop("zupt", {}))
    return DuongSuhParams(zupt=zupt, **d)
