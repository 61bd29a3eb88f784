"""IMU signal synthesis from exact kinematics, and the sensor error model.

Signals: gyr = body-frame angular velocity of the sensor frame (vee(Rᵀ Ṙ)), acc = specific force in
the sensor frame Rᵀ(a + [0, 0, 9.81]), mag = Rᵀ B(p) in µT. Derivatives by central differences of
the continuous-time kinematic model with a tiny step (h = 0.25 ms, truncation error ~1e-4 m/s²),
so the signals are exact up to that error and consistent with the reference poses.

Sensor frame = segment frame ⊗ mounting rotation ⊗ wobble(t) (soft tissue / strap: a small rotation
and translation proportional to the segment's acceleration in the segment frame).

Errors (spec/foot_papers.md A7.3, Yun et al. 2012 Table II as the base): measured = M (I + S) true +
bias (+ random-walk bias for the gyro) + white noise, with S a per-axis scale factor error, M an axis
misalignment (non-orthogonality) and per-axis constant biases; magnetometer with hard-iron offset.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._rotations import quat_from_matrix, quat_from_rotvec, quat_mul, quat_to_matrix
from stridelab.studies.manifest import SensorModelSpec

G = 9.81
FD_STEP_S = 2.5e-4

#: strap / soft-tissue wobble scale per placement (thigh = 1)
WOBBLE_SCALE = {"pelvis": 0.5, "thigh_left": 1.0, "thigh_right": 1.0, "shank_left": 0.6, "shank_right": 0.6,
                "foot_left": 0.15, "foot_right": 0.15, "chest": 0.4}


def rotmat_from_rotvec(rv):
    return quat_to_matrix(quat_from_rotvec(rv))


def vee_rate(R_minus, R0, R_plus, h):
    """Body angular velocity from three orientations (central difference)."""
    W = np.swapaxes(R0, -1, -2) @ ((R_plus - R_minus) / (2.0 * h))
    return 0.5 * np.stack([W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], -1)


def random_rotation(rng: np.random.Generator, lo_deg: float, hi_deg: float) -> np.ndarray:
    """Rotation matrix about a uniformly random axis by an angle uniform in [lo, hi] degrees."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    ang = np.deg2rad(rng.uniform(lo_deg, hi_deg))
    return rotmat_from_rotvec(axis * ang)


@dataclass(frozen=True)
class SensorErrors:
    """Constant errors of one physical IMU (drawn once per session). Matrices map true -> measured."""
    acc_matrix: np.ndarray
    acc_bias: np.ndarray
    gyr_matrix: np.ndarray
    gyr_bias: np.ndarray
    mag_matrix: np.ndarray
    mag_bias: np.ndarray
    wobble_rot: np.ndarray      # (3, 3) rad per (m/s²) of segment acceleration (segment frame)
    wobble_pos: np.ndarray      # (3, 3) m per (m/s²)

    @classmethod
    def draw(cls, rng: np.random.Generator, spec: SensorModelSpec, placement: str) -> "SensorErrors":
        def matrix(scale_pct, mis_deg):
            S = np.diag(1.0 + rng.normal(0.0, scale_pct / 100.0, 3))
            M = np.eye(3) + np.deg2rad(mis_deg) * rng.normal(size=(3, 3)) * (1.0 - np.eye(3))
            return M @ S
        k = WOBBLE_SCALE.get(placement, 0.5)
        C1 = rng.normal(size=(3, 3)) / np.sqrt(3.0)
        C2 = rng.normal(size=(3, 3)) / np.sqrt(3.0)
        return cls(acc_matrix=matrix(spec.scale_factor_pct, spec.axis_misalignment_deg),
                   acc_bias=rng.normal(0.0, spec.acc_bias_m_s2, 3),
                   gyr_matrix=matrix(spec.scale_factor_pct, spec.axis_misalignment_deg),
                   gyr_bias=rng.normal(0.0, np.deg2rad(spec.gyr_bias_deg_s), 3),
                   mag_matrix=matrix(spec.scale_factor_pct, spec.axis_misalignment_deg),
                   mag_bias=rng.normal(0.0, spec.mag_bias_uT, 3),
                   wobble_rot=C1 * k * np.deg2rad(spec.wobble_deg_per_g) / G,
                   wobble_pos=C2 * k * spec.wobble_mm_per_g * 1e-3 / G)


class MagneticEnvironment:
    """Earth field plus magnetic dipoles (µT, ENU). ``floor`` dipoles (rebar) just under the floor give
    disturbances that are strong near the feet and fade with height; a few ``objects`` above the floor
    add localised disturbances."""

    def __init__(self, spec: SensorModelSpec, rng: np.random.Generator, area=((-4.0, 3.0), (-3.0, 15.0))):
        dip = np.deg2rad(spec.earth_dip_deg)
        self.earth = spec.earth_field_uT * np.array([0.0, np.cos(dip), -np.sin(dip)])
        n_floor = 60
        (x0, x1), (y0, y1) = area
        floor = np.column_stack([rng.uniform(x0, x1, n_floor), rng.uniform(y0, y1, n_floor),
                                 np.full(n_floor, -0.06)])
        # moment so that the field 0.15 m above a dipole is about mag_disturbance_uT (B ≈ 2e-7 m / r³ T)
        r = 0.21
        m_floor = spec.mag_disturbance_uT * 1e-6 * r ** 3 / 2e-7
        mf = rng.normal(size=(n_floor, 3))
        mf *= (m_floor * rng.uniform(0.3, 1.5, n_floor) / np.linalg.norm(mf, axis=1))[:, None]
        objects = np.array([[x1 - 0.5, 0.5 * (y0 + y1), 0.8], [x0 + 0.8, y1 - 2.0, 0.5]])
        mo = rng.normal(size=(2, 3))
        mo *= (spec.mag_disturbance_uT * 1e-6 * 1.0 ** 3 / 2e-7 * 2.0 / np.linalg.norm(mo, axis=1))[:, None]
        self.loc = np.vstack([floor, objects])
        self.moment = np.vstack([mf, mo]) if spec.mag_disturbance_uT > 0 else np.zeros((n_floor + 2, 3))

    def field(self, p: np.ndarray) -> np.ndarray:
        """(N, 3) µT at positions ``p`` (N, 3)."""
        out = np.tile(self.earth, (p.shape[0], 1))
        if not np.any(self.moment):
            return out
        for i in range(0, p.shape[0], 4096):
            r = p[i:i + 4096, None, :] - self.loc[None]
            d = np.linalg.norm(r, axis=-1, keepdims=True)
            rh = r / d
            mdotr = np.sum(self.moment[None] * rh, -1, keepdims=True)
            B = 1e-7 * (3.0 * mdotr * rh - self.moment[None]) / d ** 3
            out[i:i + 4096] += 1e6 * B.sum(1)
        return out


@dataclass
class TrueImu:
    """Error-free IMU signals and the true sensor pose (N samples)."""
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray | None
    pos: np.ndarray
    quat: np.ndarray


def true_imu(pose5, offset, R_mount, errors: SensorErrors | None, mag_env: MagneticEnvironment | None,
             h: float = FD_STEP_S) -> TrueImu:
    """Exact IMU signals of a sensor on a segment.

    ``pose5`` = (pos (5, N, 3), R (5, N, 3, 3)) of the segment at times t + j h, j = -2..2.
    ``offset`` sensor position in the segment frame, ``R_mount`` segment -> sensor rotation
    (sensor frame = segment frame · R_mount), ``errors`` for the wobble (None = rigid).
    """
    pos, R = pose5
    acc_seg = (pos[2:] - 2.0 * pos[1:-1] + pos[:-2]) / h ** 2          # at j = -1, 0, +1
    Rj = R[1:4]
    pj = pos[1:4]
    if errors is not None and (np.any(errors.wobble_rot) or np.any(errors.wobble_pos)):
        a_loc = np.einsum("jnki,jnk->jni", Rj, acc_seg)
        w = a_loc @ errors.wobble_rot.T
        d = a_loc @ errors.wobble_pos.T
        Rs = Rj @ R_mount @ rotmat_from_rotvec(w)
        ps = pj + np.einsum("jnik,jnk->jni", Rj, offset + d)
    else:
        Rs = Rj @ R_mount
        ps = pj + np.einsum("jnik,k->jni", Rj, offset)
    gyr = vee_rate(Rs[0], Rs[1], Rs[2], h)
    a_w = (ps[2] - 2.0 * ps[1] + ps[0]) / h ** 2
    a_w[:, 2] += G
    acc = np.einsum("nki,nk->ni", Rs[1], a_w)
    mag = None
    if mag_env is not None:
        mag = np.einsum("nki,nk->ni", Rs[1], mag_env.field(ps[1]))
    return TrueImu(acc=acc, gyr=gyr, mag=mag, pos=ps[1], quat=quat_from_matrix(Rs[1]))


def apply_errors(sig: TrueImu, err: SensorErrors, spec: SensorModelSpec, rng: np.random.Generator,
                 rate_hz: float, gyr_bias_start: np.ndarray | None = None):
    """Measured (acc, gyr, mag) from true signals; returns also the gyro bias at the end (random walk)."""
    n = sig.acc.shape[0]
    ns = spec.noise_scale
    acc = sig.acc @ err.acc_matrix.T + err.acc_bias + rng.normal(0.0, spec.acc_noise_m_s2 * ns, (n, 3)) \
        if ns > 0 else sig.acc @ err.acc_matrix.T + err.acc_bias
    b0 = err.gyr_bias if gyr_bias_start is None else gyr_bias_start
    rw = np.deg2rad(spec.gyr_bias_rw_deg_s_sqrt_s) * np.sqrt(1.0 / rate_hz)
    bias = b0 + (np.cumsum(rng.normal(0.0, rw, (n, 3)), axis=0) if rw > 0 else 0.0)
    gyr = sig.gyr @ err.gyr_matrix.T + bias
    if ns > 0:
        gyr = gyr + rng.normal(0.0, spec.gyr_noise_rad_s * ns, (n, 3))
    mag = None
    if sig.mag is not None:
        mag = sig.mag @ err.mag_matrix.T + err.mag_bias
        if ns > 0:
            mag = mag + rng.normal(0.0, spec.mag_noise_uT * ns, (n, 3))
    end_bias = bias[-1] if np.ndim(bias) == 2 else np.asarray(b0)
    return acc, gyr, mag, end_bias


def noisy_pose(pos, R, spec: SensorModelSpec, rng: np.random.Generator):
    """Optical reference: position (N, 3) and quaternion (N, 4) with white marker noise."""
    n = pos.shape[0]
    q = quat_from_matrix(R)
    if spec.optical_pos_noise_m > 0:
        pos = pos + rng.normal(0.0, spec.optical_pos_noise_m, (n, 3))
    if spec.optical_rot_noise_deg > 0:
        q = quat_mul(q, quat_from_rotvec(rng.normal(0.0, np.deg2rad(spec.optical_rot_noise_deg), (n, 3))))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return pos, q
