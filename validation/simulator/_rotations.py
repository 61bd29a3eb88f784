"""Rotation helpers of the simulator, written for it (issue 16: the ground truth uses no estimator code).

Conventions of DESIGN.md: Hamilton quaternions, scalar first ``[w, x, y, z]``; ``q`` rotates body-frame vectors
into the earth frame (ENU). Matrix and rotation-vector conversions are SciPy's ``Rotation`` (an independent,
well-tested implementation; ``scalar_first=True``), quaternions returned with ``w >= 0`` where a matrix is the input.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["quat_from_matrix", "quat_to_matrix", "quat_from_rotvec", "quat_to_rotvec", "quat_mul", "quat_conj",
           "quat_from_axis_angle", "body_rate_from_quat"]


def _batch(a, tail: tuple[int, ...]):
    a = np.asarray(a, float)
    return a.reshape((-1,) + tail), a.shape[:a.ndim - len(tail)]


def quat_from_matrix(R) -> np.ndarray:
    """``(..., 3, 3)`` rotation matrices -> ``(..., 4)`` quaternions with ``w >= 0``."""
    r, shape = _batch(R, (3, 3))
    return Rotation.from_matrix(r).as_quat(canonical=True, scalar_first=True).reshape(shape + (4,))


def quat_to_matrix(q) -> np.ndarray:
    """``(..., 4)`` quaternions (normalised here) -> ``(..., 3, 3)`` matrices."""
    r, shape = _batch(q, (4,))
    return Rotation.from_quat(r, scalar_first=True).as_matrix().reshape(shape + (3, 3))


def quat_from_rotvec(rv) -> np.ndarray:
    """``(..., 3)`` rotation vectors (rad) -> ``(..., 4)`` quaternions ``[cos(θ/2), sin(θ/2) u]``."""
    r, shape = _batch(rv, (3,))
    return Rotation.from_rotvec(r).as_quat(scalar_first=True).reshape(shape + (4,))


def quat_to_rotvec(q) -> np.ndarray:
    """``(..., 4)`` -> ``(..., 3)`` rotation vectors, angle in [0, π]."""
    r, shape = _batch(q, (4,))
    return Rotation.from_quat(r, scalar_first=True).as_rotvec().reshape(shape + (3,))


def quat_mul(a, b) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` (broadcasting over leading axes)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def quat_conj(q) -> np.ndarray:
    q = np.asarray(q, float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_from_axis_angle(axis, angle) -> np.ndarray:
    """Rotation by ``angle`` (rad, scalar or (N,)) about the unit-normalised ``axis`` (3,)."""
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    ang = np.asarray(angle, float)
    return np.concatenate([np.cos(ang / 2)[..., None], np.sin(ang / 2)[..., None] * u], axis=-1)


def body_rate_from_quat(q, sampling_rate_hz: float) -> np.ndarray:
    """Body-frame angular velocity (rad/s) of an orientation series ``q`` (N, 4), N >= 2: the rotation vector of
    ``q[k-1]* ⊗ q[k+1]`` over the two sample intervals between them (central), one-sided at the ends."""
    q = np.asarray(q, float)
    fs = float(sampling_rate_hz)
    w = np.empty((len(q), 3))
    w[1:-1] = quat_to_rotvec(quat_mul(quat_conj(q[:-2]), q[2:])) * fs / 2.0
    w[0] = quat_to_rotvec(quat_mul(quat_conj(q[0]), q[1])) * fs
    w[-1] = quat_to_rotvec(quat_mul(quat_conj(q[-2]), q[-1])) * fs
    return w
