"""Factored Quaternion Algorithm (FQA): static orientation from gravity and the magnetic field.

Yun, Bachmann, McGhee, "A simplified quaternion-based algorithm for orientation estimation from
earth gravity and magnetic field measurements", IEEE TIM 57(3):638–650, 2008 (ref. [26] of Yun et
al. 2012); steps as in spec/foot_papers.md A2. The maths runs in NED as in the paper
(x = magnetic north, z down); the public function returns sensor→ENU quaternions.

Deviations: sgn(0) = +1; when cos θ < 1e-6 roll is set to 0 (the 2008 paper's singularity
avoidance is not described in [Y]); when the levelled field has no horizontal part the azimuth is 0.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from stridelab.estimators.orientation._frames import ned_to_enu
from stridelab.estimators.quaternion import quat_mul_1


@njit(cache=True)
def _half(c, s):
    """(cos(x/2), sin(x/2)) from (cos x, sin x) with sgn(0) = +1 (spec A2, steps 2, 3, 5)."""
    c = min(1.0, max(-1.0, c))
    sg = 1.0 if s >= 0.0 else -1.0
    return np.sqrt((1.0 + c) / 2.0), sg * np.sqrt((1.0 - c) / 2.0)


@njit(cache=True)
def fqa_tilt_1(ax, ay, az):
    """Elevation ⊗ roll quaternion q_e ⊗ q_r (NED) from a normalised accelerometer vector (A2 steps 2-3)."""
    s_t = min(1.0, max(-1.0, ax))
    c_t = np.sqrt(max(0.0, 1.0 - s_t * s_t))
    ce, se = _half(c_t, s_t)
    q_e = np.array([ce, 0.0, se, 0.0])
    if c_t > 1e-6:
        cr, sr = _half(-az / c_t, -ay / c_t)
    else:
        cr, sr = 1.0, 0.0
    q_r = np.array([cr, sr, 0.0, 0.0])
    return quat_mul_1(q_e, q_r)


@njit(cache=True)
def fqa_azimuth_1(q_tilt, mx, my, mz, nx, ny):
    """Azimuth quaternion q_a (NED) from the magnetometer levelled by q_tilt (A2 steps 4-5); (ok, q_a)."""
    # em = q_tilt ⊗ m ⊗ q_tilt*  (vector part)
    w, x, y, z = q_tilt[0], q_tilt[1], q_tilt[2], q_tilt[3]
    ex = (1 - 2 * (y * y + z * z)) * mx + 2 * (x * y - w * z) * my + 2 * (x * z + w * y) * mz
    ey = 2 * (x * y + w * z) * mx + (1 - 2 * (x * x + z * z)) * my + 2 * (y * z - w * x) * mz
    h = np.sqrt(ex * ex + ey * ey)
    if h < 1e-9:
        return False, np.array([1.0, 0.0, 0.0, 0.0])
    Mx, My = ex / h, ey / h
    c_p = Mx * nx + My * ny
    s_p = -My * nx + Mx * ny
    ca, sa = _half(c_p, s_p)
    return True, np.array([ca, 0.0, 0.0, sa])


@njit(cache=True)
def fqa_ned_1(a, m, nx, ny):
    """q_s = q_a ⊗ q_e ⊗ q_r (sensor→NED) from accelerometer a and magnetometer m (any scale)."""
    na = np.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
    qt = fqa_tilt_1(a[0] / na, a[1] / na, a[2] / na)
    ok, qa = fqa_azimuth_1(qt, m[0], m[1], m[2], nx, ny)
    return quat_mul_1(qa, qt)


@njit(cache=True)
def _fqa_series(acc, mag, nx, ny, out):
    for i in range(acc.shape[0]):
        q = fqa_ned_1(acc[i], mag[i], nx, ny)
        out[i] = q / np.sqrt(np.sum(q * q))


def fqa(acc: np.ndarray, mag: np.ndarray, *, declination_rad: float = 0.0) -> np.ndarray:
    """Static sensor→ENU orientation per sample from acc (m/s², specific force) and mag (any unit).

    ``declination_rad`` (east positive) rotates the reference from magnetic to true north
    (spec A2: N = [cos D, sin D]); 0 means ENU's y axis is magnetic north. Returns (N, 4) [w x y z].
    """
    acc = np.ascontiguousarray(acc, dtype=np.float64).reshape(-1, 3)
    mag = np.ascontiguousarray(mag, dtype=np.float64).reshape(-1, 3)
    if acc.shape != mag.shape:
        raise ValueError(f"fqa: acc {acc.shape} and mag {mag.shape} must have the same shape (N, 3)")
    out = np.empty((acc.shape[0], 4))
    _fqa_series(acc, mag, np.cos(declination_rad), np.sin(declination_rad), out)
    return ned_to_enu(out)
