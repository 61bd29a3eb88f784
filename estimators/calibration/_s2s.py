"""Sensor-to-segment calibration of one IMU (Nazarahari 2021 ch. 3, Eq. 14-16; spec §2.2).

Frames (spec §0.1-0.2): ``S`` = sensor frame after the mounting permutation ``P_mount``
(x ≈ anterior, y ≈ up, z ≈ right), ``VF`` = vertical frame after Eq. 14, ``AF`` = ISB anatomical
frame (x anterior, y superior, z right, both legs). ``R_A_B`` maps B-frame vectors into A
(``v_A = R_A_B v_B``; its columns are B's axes written in A).

Step 1 (Eq. 14): y_VF = mean standing specific force; z_VF = e_x × y_VF; x_VF = y_VF × z_VF.
Step 2 (Eq. 15): PCA of the horizontal (x, z) VF components of the movement angular velocity;
the principal axis becomes z_AF with a non-negative z_VF component (|γ| ≤ 90°).
Step 3 (Eq. 16): R_S_AF = R_S_VF · R_VF_AF.
"""
from __future__ import annotations

import numpy as np

#: reject a vertical calibration when sensor x is closer than this to vertical (spec §2.2 guard)
DEGENERATE_X_VERTICAL_DEG = 20.0


class CalibrationError(ValueError):
    """The calibration cannot be computed from these inputs (the message says why and what to do)."""


def _unit(v: np.ndarray, what: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n < 1e-12:
        raise CalibrationError(f"{what}: zero or non-finite vector, cannot normalise")
    return v / n


def vertical_calibration(acc_stand: np.ndarray) -> np.ndarray:
    """``R_S_VF`` (3×3, columns = VF axes in S) from quiet-standing specific force (Eq. 14).

    acc_stand: (N, 3) m/s², sensor frame after ``P_mount``. Raises :class:`CalibrationError` when
    sensor x is within 20° of vertical (fix the mounting permutation) or when the data are empty.
    """
    a = np.asarray(acc_stand, dtype=float)
    if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] == 0:
        raise CalibrationError(f"acc_stand must be (N, 3) with N > 0, got shape {a.shape}")
    y = _unit(np.nanmean(a, axis=0), "mean standing acceleration")
    ang = np.degrees(np.arccos(np.clip(abs(y[0]), 0.0, 1.0)))
    if ang < DEGENERATE_X_VERTICAL_DEG:
        raise CalibrationError(
            f"sensor x axis is {ang:.1f}° from vertical during standing (need ≥ {DEGENERATE_X_VERTICAL_DEG:.0f}°): "
            "the mounting permutation is wrong; give a P_mount that makes sensor x point anterior")
    z = _unit(np.cross([1.0, 0.0, 0.0], y), "z_VF")
    x = np.cross(y, z)
    return np.column_stack([x, y, z])


def heading_calibration(gyr_move: np.ndarray, R_S_VF: np.ndarray, *, main_axis: str = "z"
                        ) -> tuple[np.ndarray, float, float]:
    """``(R_VF_AF, planarity, gamma_deg)`` from movement angular velocity (Eq. 15, PCA).

    gyr_move: (N, 3) rad/s, sensor frame. main_axis: ``"z"`` for hip flexion/extension and
    straight walking (principal axis → z_AF), ``"x"`` for hip abduction/adduction (→ x_AF, spec §2.2
    variant). planarity = λ1 / (λ1 + λ2) of the 2×2 covariance (explained variance of the principal
    axis). The result does not depend on the eigenvector sign or column order (U-CAL-3).
    """
    w = np.asarray(gyr_move, dtype=float)
    if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 3:
        raise CalibrationError(f"gyr_move must be (N, 3) with N ≥ 3, got shape {w.shape}")
    w = w[np.all(np.isfinite(w), axis=1)]
    if w.shape[0] < 3:
        raise CalibrationError("gyr_move has fewer than 3 finite samples")
    w_vf = w @ R_S_VF                         # rows = (R_VF_S w)^T
    Q = w_vf[:, [0, 2]]
    Q = Q - Q.mean(axis=0)
    C = (Q.T @ Q) / max(Q.shape[0] - 1, 1)
    evals, evecs = np.linalg.eigh(C)
    total = float(evals.sum())
    if total <= 1e-12:
        raise CalibrationError("no rotation in the movement window (angular velocity variance is zero)")
    p = evecs[:, -1]
    planarity = float(evals[-1] / total)
    y = np.array([0.0, 1.0, 0.0])
    if main_axis == "z":
        if p[1] < 0:
            p = -p
        z = np.array([p[0], 0.0, p[1]])
        x = np.cross(y, z)
        gamma = np.degrees(np.arctan2(p[0], p[1]))
    elif main_axis == "x":
        if p[0] < 0:
            p = -p
        x = np.array([p[0], 0.0, p[1]])
        z = np.cross(x, y)
        gamma = np.degrees(np.arctan2(-p[1], p[0]))
    else:
        raise ValueError(f"main_axis must be 'z' (hip FE, walking) or 'x' (hip AA), got {main_axis!r}")
    return np.column_stack([x, y, z]), planarity, float(gamma)


def calibrate_imu(acc_stand: np.ndarray, gyr_move: np.ndarray, *, main_axis: str = "z"
                  ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Full calibration of one IMU: ``(R_S_AF, R_S_VF, planarity, gamma_deg)`` (Eq. 14-16)."""
    R_S_VF = vertical_calibration(acc_stand)
    R_VF_AF, planarity, gamma = heading_calibration(gyr_move, R_S_VF, main_axis=main_axis)
    return R_S_VF @ R_VF_AF, R_S_VF, planarity, gamma


def frame_from_vertical_and_lateral(y_S: np.ndarray, z_hint_S: np.ndarray) -> np.ndarray:
    """``R_S_AF`` with y_AF = ``y_S`` and z_AF = the part of ``z_hint_S`` orthogonal to it."""
    y = _unit(np.asarray(y_S, float), "vertical axis")
    zh = np.asarray(z_hint_S, float)
    z = _unit(zh - y * float(zh @ y), "lateral axis (parallel to vertical?)")
    x = np.cross(y, z)
    return np.column_stack([x, y, z])


def pelvis_from_thighs(acc_stand_pelvis: np.ndarray, R_G_S_pelvis: np.ndarray,
                       R_G_AF_thighs: list[np.ndarray]) -> np.ndarray:
    """Pelvis ``R_S_AF`` (spec 7.A7 [CHOICE], non-thesis): vertical from standing (Eq. 14), z_AF = the
    horizontal projection of the mean of the thigh z_AF axes at the same standing instant.

    R_G_S_pelvis: (3, 3) mean pelvis sensor orientation over the standing window; R_G_AF_thighs:
    (3, 3) mean thigh anatomical orientations over the same window (their heading must agree with
    the pelvis sensor's: 9D orientation or a common heading reference).
    """
    R_S_VF = vertical_calibration(acc_stand_pelvis)
    y_S = R_S_VF[:, 1]
    z_G = np.mean([R[:, 2] for R in R_G_AF_thighs], axis=0)
    z_S = R_G_S_pelvis.T @ z_G
    return frame_from_vertical_and_lateral(y_S, z_S)


def pelvis_from_sway(acc_stand_pelvis: np.ndarray, acc_walk_pelvis: np.ndarray, *,
                     sampling_rate_hz: float, band_hz: tuple[float, float] = (0.5, 1.5)) -> np.ndarray:
    """Pelvis ``R_S_AF`` fallback (spec 7.A7): vertical from standing; z_AF = principal axis of the
    horizontal pelvis acceleration band-passed at the stride frequency (medio-lateral sway), signed
    to keep a non-negative z_VF component (sensor x roughly anterior)."""
    from scipy.signal import butter, sosfiltfilt
    R_S_VF = vertical_calibration(acc_stand_pelvis)
    a = np.asarray(acc_walk_pelvis, float)
    if a.shape[0] < int(3 * sampling_rate_hz):
        raise CalibrationError("pelvis sway calibration needs ≥ 3 s of walking")
    trim = int(sampling_rate_hz)                       # leave out gait initiation / termination
    if a.shape[0] > 5 * sampling_rate_hz:
        a = a[trim:-trim]
    sos = butter(2, band_hz, btype="bandpass", fs=sampling_rate_hz, output="sos")
    af = sosfiltfilt(sos, a, axis=0) @ R_S_VF
    Q = af[:, [0, 2]] - af[:, [0, 2]].mean(axis=0)
    evals, evecs = np.linalg.eigh(Q.T @ Q)
    p = evecs[:, -1]
    if p[1] < 0:
        p = -p
    z_S = R_S_VF @ np.array([p[0], 0.0, p[1]])
    return frame_from_vertical_and_lateral(R_S_VF[:, 1], z_S)
