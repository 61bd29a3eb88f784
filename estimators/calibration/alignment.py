"""Alignment of IMU data with an optical reference (accuracy studies).

* :func:`body_rate_from_quat`: angular velocity in the body frame from an orientation series.
* :func:`sync_by_angular_rate`: time offset between IMU and reference by cross-correlating the
  angular-rate norms (frame-independent, so it works before any rotation is known).
* :func:`imu_to_cluster_rotation`: the constant rotation from the IMU frame to the marker-cluster
  frame from simultaneous angular velocities (Kabsch / Wahba least squares, heading-free).
* :func:`constant_offset_rotation`: the chordal-mean constant rotation between two orientation
  series (e.g. a reference segment and a calibrated IMU segment).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stridelab.estimators.quaternion import quat_conj, quat_mul, quat_to_matrix, quat_to_rotvec


def body_rate_from_quat(quat: np.ndarray, *, sampling_rate_hz: float) -> np.ndarray:
    """(N, 3) body-frame angular velocity, rad/s, of a (N, 4) body→earth quaternion series
    (central differences of ``q_k* ⊗ q_{k+1}``; first and last rows repeat their neighbour)."""
    q = np.asarray(quat, float)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 2:
        raise ValueError(f"quat must be (N, 4) with N ≥ 2, got {q.shape}")
    step = quat_to_rotvec(quat_mul(quat_conj(q[:-1]), q[1:])) * sampling_rate_hz    # rate between k and k+1
    w = np.empty((q.shape[0], 3))
    w[1:-1] = 0.5 * (step[:-1] + step[1:])
    w[0], w[-1] = step[0], step[-1]
    return w


@dataclass(frozen=True)
class SyncResult:
    """lag_s: add to the reference time to align it with the IMU (``t_imu = t_ref + lag_s``);
    lag_samples: the same in (fractional) samples; peak_corr: normalised correlation at the lag."""
    lag_s: float
    lag_samples: float
    peak_corr: float


def sync_by_angular_rate(gyr_imu: np.ndarray, gyr_ref: np.ndarray, *, sampling_rate_hz: float,
                         max_lag_s: float = 5.0) -> SyncResult:
    """Time offset between an IMU and a reference by cross-correlation of angular-rate norms.

    Both on the same sampling rate; ``gyr_ref`` can come from :func:`body_rate_from_quat` of the
    optical segment or cluster orientation. Sub-sample lag by parabolic interpolation of the peak.
    A positive lag means the reference events occur ``lag_s`` earlier in its own sample index,
    i.e. ``imu[k] ≈ ref[k - lag]``.
    """
    a = np.linalg.norm(np.nan_to_num(np.asarray(gyr_imu, float)), axis=1)
    b = np.linalg.norm(np.nan_to_num(np.asarray(gyr_ref, float)), axis=1)
    a, b = a - a.mean(), b - b.mean()
    n = max(a.size, b.size)
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    xc = np.fft.irfft(np.fft.rfft(a, nfft) * np.conj(np.fft.rfft(b, nfft)), nfft)
    max_lag = int(min(max_lag_s * sampling_rate_hz, n - 1))
    lags = np.arange(-max_lag, max_lag + 1)
    vals = xc[lags % nfft]
    i = int(np.argmax(vals))
    frac = 0.0
    if 0 < i < vals.size - 1:
        y0, y1, y2 = vals[i - 1], vals[i], vals[i + 1]
        den = y0 - 2 * y1 + y2
        frac = 0.5 * (y0 - y2) / den if den != 0 else 0.0
    norm = np.sqrt(np.sum(a ** 2) * np.sum(b ** 2))
    lag = lags[i] + frac
    return SyncResult(lag_s=float(lag / sampling_rate_hz), lag_samples=float(lag),
                      peak_corr=float(vals[i] / norm) if norm > 0 else 0.0)


def imu_to_cluster_rotation(gyr_imu: np.ndarray, gyr_cluster: np.ndarray) -> np.ndarray:
    """``R_C_S`` (3×3) with ``ω_cluster ≈ R_C_S ω_imu``, least squares over time-aligned samples.

    Both angular velocities in their own body frames (rad/s); the gyro bias should be removed or the
    motion rich enough that it does not matter. Needs rotation about at least two axes.
    """
    A = np.asarray(gyr_imu, float)
    B = np.asarray(gyr_cluster, float)
    ok = np.all(np.isfinite(A), axis=1) & np.all(np.isfinite(B), axis=1)
    A, B = A[ok], B[ok]
    H = A.T @ B
    s = np.linalg.svd(H, compute_uv=False)
    if s.size < 3 or s[1] < 1e-6 * max(s[0], 1e-12):
        raise ValueError("imu_to_cluster_rotation: motion about fewer than two axes, rotation is not observable")
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    return Vt.T @ np.diag([1.0, 1.0, d]) @ U.T


def constant_offset_rotation(quat_a: np.ndarray, quat_b: np.ndarray) -> np.ndarray:
    """Chordal mean of ``q_a* ⊗ q_b`` as a 3×3 matrix ``R_A_B`` (constant rotation between two frames
    rigidly attached to one body, both series mapping into the same earth frame)."""
    d = quat_mul(quat_conj(np.asarray(quat_a, float)), np.asarray(quat_b, float))
    d = d[np.all(np.isfinite(d), axis=1)]
    d = d * np.where(d @ d[0] < 0, -1.0, 1.0)[:, None]
    M = d.T @ d
    w, v = np.linalg.eigh(M)
    return quat_to_matrix(v[:, -1])


def apply_lag(t_ref_s: np.ndarray, sync: SyncResult) -> np.ndarray:
    """Reference time stamps shifted onto the IMU clock."""
    return np.asarray(t_ref_s, float) + sync.lag_s


__all__ = ["body_rate_from_quat", "sync_by_angular_rate", "SyncResult", "imu_to_cluster_rotation",
           "constant_offset_rotation", "apply_lag"]
