"""Calibration accuracy: helical angle between estimated and reference sensor-to-segment rotations."""
from __future__ import annotations

import numpy as np


def helical_angle_deg(R_ref: np.ndarray, R_est: np.ndarray) -> np.ndarray:
    """Helical (geodesic) angle in degrees between rotation matrices (thesis Eq. 19).

    ``θ = acos((trace(R_ref^T R_est) − 1) / 2)``; broadcasts over leading axes of ``(..., 3, 3)``.
    """
    R_ref = np.asarray(R_ref, float)
    R_est = np.asarray(R_est, float)
    tr = np.einsum("...ji,...ji->...", R_ref, R_est)
    return np.degrees(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))
