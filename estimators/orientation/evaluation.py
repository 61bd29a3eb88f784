"""Orientation error against a reference (BROAD protocol; Laidig et al. 2021, spec thesis §8 A9-ii).

The error quaternion is taken in the earth frame, ``e = q_est ⊗ q_ref*`` (both sensor→ENU), and split
into a rotation about ENU z (heading) and the rest (inclination):

* total       = 2·acos|e_w|                 (quaternion angle distance)
* heading     = 2·atan(|e_z| / |e_w|)       (angle of the z-twist of e)
* inclination = 2·acos √(e_w² + e_z²)       (angle of the swing of e, i.e. tilt error)

Errors are RMS over a mask (BROAD: ``movement``) in degrees; samples where either quaternion is NaN
are left out. No alignment or heading offset is removed: a 9D estimate is scored against the ENU
reference as it stands.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.quaternion import quat_conj, quat_mul

__all__ = ["OrientationError", "orientation_error_deg", "orientation_rmse_deg"]


def orientation_error_deg(q_est: np.ndarray, q_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample (total, heading, inclination) errors in degrees, each (N,); NaN where an input is NaN."""
    q_est = np.asarray(q_est, dtype=float)
    q_ref = np.asarray(q_ref, dtype=float)
    if q_est.shape != q_ref.shape or q_est.shape[-1] != 4:
        raise ValueError(f"q_est {q_est.shape} and q_ref {q_ref.shape} must both be (N, 4) [w x y z]")
    e = quat_mul(q_est, quat_conj(q_ref))
    e = e / np.linalg.norm(e, axis=-1, keepdims=True)
    w = np.abs(e[..., 0])
    z = np.abs(e[..., 3])
    total = np.degrees(2.0 * np.arccos(np.clip(w, 0.0, 1.0)))
    heading = np.degrees(2.0 * np.arctan2(z, w))
    inclination = np.degrees(2.0 * np.arccos(np.clip(np.sqrt(e[..., 0] ** 2 + e[..., 3] ** 2), 0.0, 1.0)))
    return total, heading, inclination


@dataclass(frozen=True)
class OrientationError:
    """RMS errors in degrees over the scored samples, and how many samples were scored."""
    total_rmse_deg: float
    heading_rmse_deg: float
    inclination_rmse_deg: float
    n_scored: int


def orientation_rmse_deg(q_est: np.ndarray, q_ref: np.ndarray, mask: np.ndarray | None = None) -> OrientationError:
    """RMS (total, heading, inclination) error in degrees over ``mask`` (bool (N,); None = all samples).

    Raises ValueError when no sample is left to score (all masked or NaN).
    """
    total, heading, incl = orientation_error_deg(q_est, q_ref)
    ok = np.isfinite(total)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != total.shape:
            raise ValueError(f"mask {mask.shape} must match the quaternions' sample count {total.shape}")
        ok &= mask
    n = int(ok.sum())
    if n == 0:
        raise ValueError("no sample to score: every sample is masked out or NaN")

    def rms(x):
        return float(np.sqrt(np.mean(x[ok] ** 2)))

    return OrientationError(rms(total), rms(heading), rms(incl), n)
