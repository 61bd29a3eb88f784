"""Joint coordinate system angles (Grood & Suntay 1983; ISB, Wu et al. 2002) for hips, knees, ankles.

Anatomical frames (ISB, both sides): x anterior, y superior, z right. For a joint with proximal
frame P and distal frame D, ``R_rel = R_G_P^T R_G_D`` is decomposed as the Cardan sequence Z–X–Y
``R_rel = R_z(α) R_x(β) R_y(γ)`` (spec §5.3): α about the proximal z (e1, flexion axis), β about the
floating axis e2 = e3 × e1, γ about the distal y (e3, long axis). Clinical signs (docs/joint_angles.md):

| joint  | flexion/extension        | ab/adduction, inversion | internal/external rotation |
|--------|--------------------------|-------------------------|----------------------------|
| hip    | +α (flexion +)           | +β right, −β left (adduction +) | +γ right, −γ left (internal +) |
| knee   | −α (flexion +)           | +β right, −β left (adduction/varus +) | +γ right, −γ left (internal +) |
| ankle  | +α (dorsiflexion +)      | +β right, −β left (inversion +) | +γ right, −γ left (internal/adduction +) |
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from stridelab.estimators.quaternion import quat_conj, quat_mul, quat_normalize

#: joint -> (proximal segment, distal segment)
JOINTS = {"hip": ("pelvis", "thigh"), "knee": ("thigh", "shank"), "ankle": ("shank", "foot")}
#: clinical angle names per joint, in the order (about e1, about e2, about e3)
ANGLE_NAMES = {"hip": ("flexion", "adduction", "internal_rotation"),
               "knee": ("flexion", "adduction", "internal_rotation"),
               "ankle": ("dorsiflexion", "inversion", "internal_rotation")}
#: sign applied to (α, β, γ) per joint for the right side; left side negates β and γ
SIGN_RIGHT = {"hip": (1.0, 1.0, 1.0), "knee": (-1.0, 1.0, 1.0), "ankle": (1.0, 1.0, 1.0)}


def sign_table(joint: str, side: str) -> np.ndarray:
    """(3,) multipliers turning (α, β, γ) of the Z–X–Y decomposition into clinical angles."""
    if joint not in SIGN_RIGHT:
        raise ValueError(f"joint must be one of {sorted(SIGN_RIGHT)}, got {joint!r}")
    if side not in ("left", "right"):
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    s = np.array(SIGN_RIGHT[joint])
    return s if side == "right" else s * np.array([1.0, -1.0, -1.0])


def _relative_matrix(q_prox: np.ndarray, q_dist: np.ndarray) -> np.ndarray:
    """(N, 3, 3) ``R_P_D`` from (N, 4) segment→ENU quaternions (only the needed elements are used)."""
    q = quat_mul(quat_conj(q_prox), q_dist)
    w, x, y, z = np.moveaxis(q, -1, 0)
    n = w * w + x * x + y * y + z * z
    s = 2.0 / np.where(n > 0, n, np.nan)
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 1] = s * (x * y - w * z)
    R[..., 1, 1] = 1 - s * (x * x + z * z)
    R[..., 2, 0] = s * (x * z - w * y)
    R[..., 2, 1] = s * (y * z + w * x)
    R[..., 2, 2] = 1 - s * (x * x + y * y)
    return R


def zxy_angles_deg(R_rel: np.ndarray) -> np.ndarray:
    """(..., 3) Cardan angles (α, β, γ) in degrees of ``R = R_z(α) R_x(β) R_y(γ)``."""
    R = np.asarray(R_rel, float)
    a = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
    b = np.arcsin(np.clip(R[..., 2, 1], -1.0, 1.0))
    c = np.arctan2(-R[..., 2, 0], R[..., 2, 2])
    return np.degrees(np.stack([a, b, c], axis=-1))


def zxy_matrix(alpha_deg, beta_deg, gamma_deg) -> np.ndarray:
    """``R_z(α) R_x(β) R_y(γ)`` (degrees in, (..., 3, 3) out); the inverse of :func:`zxy_angles_deg`."""
    a, b, c = (np.radians(np.asarray(v, float)) for v in (alpha_deg, beta_deg, gamma_deg))
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    R = np.empty(np.broadcast(a, b, c).shape + (3, 3))
    R[..., 0, 0] = ca * cc - sa * sb * sc
    R[..., 0, 1] = -sa * cb
    R[..., 0, 2] = ca * sc + sa * sb * cc
    R[..., 1, 0] = sa * cc + ca * sb * sc
    R[..., 1, 1] = ca * cb
    R[..., 1, 2] = sa * sc - ca * sb * cc
    R[..., 2, 0] = -cb * sc
    R[..., 2, 1] = sb
    R[..., 2, 2] = cb * cc
    return R


def joint_angles_deg(q_prox: np.ndarray, q_dist: np.ndarray, *, joint: str, side: str) -> np.ndarray:
    """(N, 3) clinical angles in degrees [FE, AA, IE] of one joint from anatomical-frame orientations.

    q_prox, q_dist: (N, 4) [w x y z] anatomical frame → ENU of the proximal and distal segments.
    """
    sign = sign_table(joint, side)
    qp = np.asarray(q_prox, float)
    qd = np.asarray(q_dist, float)
    if qp.shape != qd.shape or qp.shape[-1] != 4:
        raise ValueError(f"q_prox and q_dist must both be (N, 4), got {qp.shape} and {qd.shape}")
    return zxy_angles_deg(_relative_matrix(qp, qd)) * sign


def clinical_to_matrix(angles_deg, *, joint: str, side: str) -> np.ndarray:
    """``R_P_D`` of clinical angles [FE, AA, IE] (degrees): the inverse of :func:`joint_angles_deg`."""
    ang = np.asarray(angles_deg, float) * sign_table(joint, side)
    return zxy_matrix(ang[..., 0], ang[..., 1], ang[..., 2])


@dataclass(frozen=True)
class JointAngles:
    """Clinical joint angles of one trial.

    angles_deg: "<joint>_<side>" (``hip_left`` …) -> (N, 3) [FE, AA, IE] in degrees, after the
    offset removal when one was requested (NaN where a segment orientation or calibration is
    missing). offsets_deg: the same keys -> (3,) offsets removed (zeros when none; spec 7.A8
    keeps them so absolute angles can be restored). status: "<joint>_<side>" -> ``pass`` /
    ``warn`` / ``fail`` (the worse calibration of its two segments); notes: -> reasons, e.g.
    ``pelvis calibration: non-thesis``. names: joint -> its three angle names.
    """
    angles_deg: dict
    offsets_deg: dict
    status: dict
    notes: dict = field(default_factory=dict)
    names: dict = field(default_factory=lambda: dict(ANGLE_NAMES))


def remove_standing_offset(angles_deg: np.ndarray, standing: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """``(angles − mean over standing, offset)`` (thesis ch. 8 step 4, Euler subtraction)."""
    a = np.asarray(angles_deg, float)
    s0, s1 = int(standing[0]), int(standing[1])
    if not 0 <= s0 < s1 <= a.shape[0]:
        raise ValueError(f"standing window {standing} outside the trial of {a.shape[0]} samples")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # all-NaN (no calibration): NaN offsets
        off = np.nanmean(a[s0:s1], axis=0)
    return a - off, off


def segment_orientations(quats: dict, calibration) -> dict:
    """placement -> (N, 4) anatomical frame → ENU (``q_sensor ⊗ q_sensor_af``, Eq. 17)."""
    out = {}
    for p, q in quats.items():
        if p in calibration.imus:
            out[p] = quat_normalize(calibration.segment_quat(p, q)) if calibration.imus[p].valid else \
                np.full(np.shape(q), np.nan)
    return out


def compute_joint_angles(quats: dict, calibration, *, standing: tuple[int, int] | None = None) -> JointAngles:
    """Hip, knee and ankle angles of both legs from sensor orientations and a session calibration.

    quats: placement -> (N, 4) sensor → ENU orientation of the trial (one time grid).
    calibration: :class:`stridelab.estimators.calibration.SessionCalibration` (a failed IMU calibration gives
    NaN angles and ``fail``). standing: ``[start, end)`` quiet standing at the start of the trial:
    its mean angle is removed (thesis ch. 8 step 4) and stored in ``offsets_deg``.
    """
    seg_q = segment_orientations(quats, calibration)
    angles, offsets, status, notes = {}, {}, {}, {}
    rank = {"pass": 0, "warn": 1, "fail": 2}
    for joint, (prox, dist) in JOINTS.items():
        for side in ("left", "right"):
            key = f"{joint}_{side}"
            pp = prox if prox == "pelvis" else f"{prox}_{side}"
            dd = f"{dist}_{side}"
            if pp not in seg_q or dd not in seg_q:
                continue
            a = joint_angles_deg(seg_q[pp], seg_q[dd], joint=joint, side=side)
            off = np.zeros(3)
            if standing is not None:
                a, off = remove_standing_offset(a, standing)
            angles[key], offsets[key] = a, off
            cp, cd = calibration.imus[pp], calibration.imus[dd]
            status[key] = max(cp.status, cd.status, key=rank.__getitem__)
            nt = [f"{c.placement}: {r}" for c in (cp, cd) for r in c.reasons]
            if cp.method.startswith("pelvis_"):
                nt.append("pelvis calibration: non-thesis")
            notes[key] = tuple(nt)
    return JointAngles(angles_deg=angles, offsets_deg=offsets, status=status, notes=notes)
