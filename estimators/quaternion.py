"""Quaternion algebra in the one StrideLab convention.

Hamilton product, scalar-first ``[w, x, y, z]``; ``q`` maps sensor-frame vectors into the earth
frame: ``v_E = q ⊗ [0, v_S] ⊗ q*`` (DESIGN.md "Conventions"). All functions accept a single
quaternion ``(4,)`` or a stack ``(N, 4)`` and broadcast like NumPy. Scalar ``_1`` variants are
numba kernels for use inside other kernels.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "quat_mul", "quat_conj", "quat_normalize", "quat_rotate", "quat_from_rotvec",
    "quat_to_rotvec", "quat_to_matrix", "quat_from_matrix", "quat_from_axis_angle",
    "quat_angle_deg", "quat_mul_1", "quat_rotate_1", "quat_exp_step_1", "quat_to_matrix_1",
]


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` of ``(..., 4)`` arrays."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate ``q*`` (the inverse for unit quaternions)."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion(s); raises ValueError on a zero-norm quaternion."""
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("quat_normalize: zero-norm quaternion (expected non-zero [w, x, y, z])")
    return q / n


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix ``R`` (sensor→earth, ``v_E = R v_S``) of shape ``(..., 3, 3)``."""
    w, x, y, z = np.moveaxis(quat_normalize(q), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate sensor-frame vector(s) ``v`` (..., 3) into the earth frame: ``q ⊗ v ⊗ q*``."""
    return np.einsum("...ij,...j->...i", quat_to_matrix(q), np.asarray(v, dtype=float))


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Quaternion with ``w >= 0`` from rotation matrix/matrices ``(..., 3, 3)`` (Shepperd's method)."""
    R = np.asarray(R, dtype=float)
    shape = R.shape[:-2]
    R = R.reshape(-1, 3, 3)
    q = np.empty((R.shape[0], 4))
    tr = np.trace(R, axis1=1, axis2=2)
    diag = np.stack([R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    case = np.where(tr > diag.max(axis=1), 3, diag.argmax(axis=1))
    for c in range(4):
        m = case == c
        if not np.any(m):
            continue
        r = R[m]
        if c == 3:
            s = 2.0 * np.sqrt(1.0 + tr[m])
            q[m] = np.stack([0.25 * s, (r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s,
                             (r[:, 1, 0] - r[:, 0, 1]) / s], axis=1)
        else:
            i, j, k = c, (c + 1) % 3, (c + 2) % 3
            s = 2.0 * np.sqrt(1.0 + r[:, i, i] - r[:, j, j] - r[:, k, k])
            out = np.empty((r.shape[0], 4))
            out[:, 0] = (r[:, k, j] - r[:, j, k]) / s
            out[:, 1 + i] = 0.25 * s
            out[:, 1 + j] = (r[:, j, i] + r[:, i, j]) / s
            out[:, 1 + k] = (r[:, k, i] + r[:, i, k]) / s
            q[m] = out
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return quat_normalize(q).reshape(*shape, 4)


def quat_from_rotvec(rv: np.ndarray) -> np.ndarray:
    """Quaternion of rotation vector(s) ``rv`` (axis × angle in rad), shape ``(..., 3)``."""
    rv = np.asarray(rv, dtype=float)
    ang = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * ang
    # sin(a/2)/a with its limit 1/2 at a = 0
    k = np.where(ang > 1e-12, np.sin(half) / np.where(ang > 1e-12, ang, 1.0), 0.5 - ang**2 / 48.0)
    return np.concatenate([np.cos(half), rv * k], axis=-1)


def quat_from_axis_angle(axis, angle_rad) -> np.ndarray:
    """Quaternion rotating by ``angle_rad`` about the (normalised) ``axis``."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    return quat_from_rotvec(axis * np.asarray(angle_rad, dtype=float)[..., None])


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector(s) (rad) of quaternion(s), using the shorter rotation (angle ≤ π)."""
    q = quat_normalize(q)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(s, q[..., :1])
    k = np.where(s > 1e-12, ang / np.where(s > 1e-12, s, 1.0), 2.0)
    return v * k


def quat_angle_deg(q: np.ndarray) -> np.ndarray:
    """Rotation angle in degrees (0..180) of quaternion(s), e.g. of an error quaternion."""
    q = quat_normalize(q)
    return np.degrees(2.0 * np.arccos(np.clip(np.abs(q[..., 0]), 0.0, 1.0)))


# ---- scalar numba kernels (arrays of shape (4,) / (3,)) -------------------------------------

@njit(cache=True, fastmath=False)
def quat_mul_1(p, q):
    """Hamilton product of two (4,) quaternions (numba kernel)."""
    out = np.empty(4)
    out[0] = p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3]
    out[1] = p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2]
    out[2] = p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1]
    out[3] = p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]
    return out


@njit(cache=True, fastmath=False)
def quat_rotate_1(q, v):
    """Rotate a (3,) sensor-frame vector into the earth frame with (4,) quaternion q (numba kernel)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out = np.empty(3)
    out[0] = (1 - 2 * (y * y + z * z)) * v[0] + 2 * (x * y - w * z) * v[1] + 2 * (x * z + w * y) * v[2]
    out[1] = 2 * (x * y + w * z) * v[0] + (1 - 2 * (x * x + z * z)) * v[1] + 2 * (y * z - w * x) * v[2]
    out[2] = 2 * (x * z - w * y) * v[0] + 2 * (y * z + w * x) * v[1] + (1 - 2 * (x * x + y * y)) * v[2]
    return out


@njit(cache=True, fastmath=False)
def quat_exp_step_1(q, gx, gy, gz, dt):
    """Strapdown step ``q ⊗ exp(ω dt / 2)`` for a body rate held constant over ``dt`` (numba kernel)."""
    n = np.sqrt(gx * gx + gy * gy + gz * gz)
    ang = 0.5 * n * dt
    if n > 1e-15:
        s = np.sin(ang) / n
    else:
        s = 0.5 * dt
    d = np.empty(4)
    d[0] = np.cos(ang)
    d[1] = gx * s
    d[2] = gy * s
    d[3] = gz * s
    out = quat_mul_1(q, d)
    nrm = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    return out / nrm


@njit(cache=True, fastmath=False)
def quat_to_matrix_1(q, R):
    """Rotation matrix of a (4,) unit quaternion written into the (3, 3) array ``R`` (numba kernel)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = 1 - 2 * (x * x + y * y)
