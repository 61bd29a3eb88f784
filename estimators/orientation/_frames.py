"""The one fixed rotation between the NED frame of the papers and StrideLab's ENU frame (STYLE.md P6)."""
from __future__ import annotations

import numpy as np

from stridelab.estimators.quaternion import quat_mul

SQRT_HALF = float(np.sqrt(0.5))
#: rotates NED-frame vectors into ENU (180° about [1, 1, 0]/√2): x_E = y_N, y_E = x_N, z_E = -z_N
Q_ENU_NED = np.array([0.0, SQRT_HALF, SQRT_HALF, 0.0])


def ned_to_enu(q_ned: np.ndarray) -> np.ndarray:
    """Sensor→NED quaternion(s) to sensor→ENU: ``q_ENU = Q_ENU_NED ⊗ q_NED``."""
    return quat_mul(Q_ENU_NED, q_ned)


def enu_to_ned(q_enu: np.ndarray) -> np.ndarray:
    """Inverse of :func:`ned_to_enu` (Q_ENU_NED is its own inverse up to sign)."""
    return quat_mul(Q_ENU_NED * np.array([1.0, -1.0, -1.0, -1.0]), q_enu)
