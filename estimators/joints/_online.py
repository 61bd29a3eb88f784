"""Joint angles of one joint for a few samples at a time, compiled: the per-frame path of a live session.

Same mathematics as :func:`stridelab.estimators.joints.joint_angles_deg` applied to the calibrated segment orientations
(``segment_orientations``): ``q_AF = normalise(q_S ⊗ q_S←AF)`` (thesis Eq. 17), ``R_rel = R_P^T R_D``, Z–X–Y
Cardan angles (spec §5.3) times the clinical sign table. The NumPy version costs about 0.3 ms per call
whatever the number of samples (array set-up); a live session calls it once per frame and joint, so this
kernel does the same in a few microseconds. Equal to the NumPy path to floating-point rounding (tested,
``tests/estimators/joints/test_online.py``).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from stridelab.estimators.joints._jcs import sign_table


@njit(cache=True)
def _qmul_norm(q, r, out):
    w = q[0] * r[0] - q[1] * r[1] - q[2] * r[2] - q[3] * r[3]
    x = q[0] * r[1] + q[1] * r[0] + q[2] * r[3] - q[3] * r[2]
    y = q[0] * r[2] - q[1] * r[3] + q[2] * r[0] + q[3] * r[1]
    z = q[0] * r[3] + q[1] * r[2] - q[2] * r[1] + q[3] * r[0]
    n = np.sqrt(w * w + x * x + y * y + z * z)
    out[0], out[1], out[2], out[3] = w / n, x / n, y / n, z / n


@njit(cache=True)
def _angles_kernel(q_prox, q_dist, r_prox, r_dist, sign, out):
    p = np.empty(4)
    d = np.empty(4)
    for i in range(q_prox.shape[0]):
        _qmul_norm(q_prox[i], r_prox, p)
        _qmul_norm(q_dist[i], r_dist, d)
        # q = conj(p) ⊗ d
        w = p[0] * d[0] + p[1] * d[1] + p[2] * d[2] + p[3] * d[3]
        x = p[0] * d[1] - p[1] * d[0] - p[2] * d[3] + p[3] * d[2]
        y = p[0] * d[2] + p[1] * d[3] - p[2] * d[0] - p[3] * d[1]
        z = p[0] * d[3] - p[1] * d[2] + p[2] * d[1] - p[3] * d[0]
        s = 2.0 / (w * w + x * x + y * y + z * z)
        r01 = s * (x * y - w * z)
        r11 = 1.0 - s * (x * x + z * z)
        r20 = s * (x * z - w * y)
        r21 = s * (y * z + w * x)
        r22 = 1.0 - s * (x * x + y * y)
        b = 1.0 if r21 > 1.0 else (-1.0 if r21 < -1.0 else r21)      # clip; NaN stays NaN
        out[i, 0] = np.degrees(np.arctan2(-r01, r11)) * sign[0]
        out[i, 1] = np.degrees(np.arcsin(b)) * sign[1]
        out[i, 2] = np.degrees(np.arctan2(-r20, r22)) * sign[2]


def calibrated_joint_angles_deg(q_prox_sensor: np.ndarray, q_dist_sensor: np.ndarray, r_prox: np.ndarray,
                                r_dist: np.ndarray, *, joint: str, side: str) -> np.ndarray:
    """(n, 3) clinical angles [FE, AA, IE] in degrees of one joint from *sensor* orientations.

    q_prox_sensor, q_dist_sensor: (n, 4) [w x y z] sensor → ENU; r_prox, r_dist: (4,) ``quat_sensor_af`` of
    the two IMUs' calibrations. NaN rows (a lost sample) give NaN angles.
    """
    qp = np.ascontiguousarray(q_prox_sensor, dtype=np.float64).reshape(-1, 4)
    qd = np.ascontiguousarray(q_dist_sensor, dtype=np.float64).reshape(-1, 4)
    if qp.shape != qd.shape:
        raise ValueError(f"q_prox_sensor {qp.shape} and q_dist_sensor {qd.shape} must both be (n, 4)")
    out = np.empty((qp.shape[0], 3))
    _angles_kernel(qp, qd, np.ascontiguousarray(r_prox, dtype=np.float64),
                   np.ascontiguousarray(r_dist, dtype=np.float64), sign_table(joint, side), out)
    return out
