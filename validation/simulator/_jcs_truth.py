"""True joint angles of the simulated body: the joint coordinate system (JCS) of Grood & Suntay (1983,
J Biomech Eng 105:136) as recommended by the ISB for hip, knee and ankle (Wu et al. 2002, J Biomech 35:543),
written for the simulator from those definitions (no estimator code).

Segment frames are ISB anatomical frames (x anterior, y superior along the long axis, z to the right), given as
rotation matrices whose columns are the segment axes in the earth frame. For a joint with proximal frame P and
distal frame D:

* e1 = Z_P, the proximal medio-lateral axis (flexion/extension axis);
* e3 = Y_D, the distal long axis (internal/external rotation axis);
* e2 = e3 × e1 / |e3 × e1|, the floating axis (ab/adduction axis).

Angles (Grood & Suntay 1983, their eqs. for α, β, γ):

* α, flexion: the rotation about e1 that takes X_P to e2;
* β, adduction: π/2 − ∠(e1, e3), i.e. asin(e1 · e3);
* γ, internal rotation: the rotation about e3 that takes e2 to X_D.

Clinical signs (spec/thesis_calib_gait_posture.md §5.3): hip flexion +, knee flexion + (the knee's α is negated:
the shank rotates the other way about Z than the thigh does at the hip), ankle dorsiflexion +, adduction /
inversion + and internal rotation + on the right; on the left side β and γ are negated.

The inverse (angles → the distal frame in the proximal one) uses that the JCS is the intrinsic Z-X'-Y'' Cardan
sequence (Grood & Suntay 1983): SciPy's ``Rotation.from_euler("ZXY", ...)``.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def _signs(joint: str, side: str) -> np.ndarray:
    if joint not in ("hip", "knee", "ankle") or side not in ("left", "right"):
        raise ValueError(f"unknown joint/side {joint!r}/{side!r}")
    s = np.ones(3)
    if joint == "knee":
        s[0] = -1.0
    if side == "left":
        s[1:] = -1.0
    return s


def _rotation_about(u: np.ndarray, v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Signed angle (rad) of the rotation about ``axis`` taking ``u`` to ``v`` (all (N, 3), u and v ⊥ axis)."""
    return np.arctan2(np.einsum("ni,ni->n", np.cross(u, v), axis), np.einsum("ni,ni->n", u, v))


def jcs_angles_deg(R_prox: np.ndarray, R_dist: np.ndarray, *, joint: str, side: str) -> np.ndarray:
    """(N, 3) clinical angles [flexion, adduction, internal rotation] in degrees from (N, 3, 3) segment frames."""
    Rp, Rd = np.asarray(R_prox, float).reshape(-1, 3, 3), np.asarray(R_dist, float).reshape(-1, 3, 3)
    Xp, Zp = Rp[:, :, 0], Rp[:, :, 2]
    Xd, Yd = Rd[:, :, 0], Rd[:, :, 1]
    e1, e3 = Zp, Yd
    e2 = np.cross(e3, e1)
    e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
    alpha = _rotation_about(Xp, e2, e1)
    beta = np.arcsin(np.clip(np.einsum("ni,ni->n", e1, e3), -1.0, 1.0))
    gamma = _rotation_about(e2, Xd, e3)
    return np.degrees(np.stack([alpha, beta, gamma], 1)) * _signs(joint, side)


def jcs_relative_matrix(angles_deg, *, joint: str, side: str) -> np.ndarray:
    """(..., 3, 3) distal frame in the proximal frame for clinical angles (..., 3) in degrees (inverse of
    :func:`jcs_angles_deg`)."""
    a = np.asarray(angles_deg, float) * _signs(joint, side)
    shape = a.shape[:-1]
    return Rotation.from_euler("ZXY", a.reshape(-1, 3), degrees=True).as_matrix().reshape(shape + (3, 3))


def cardan_zxy(alpha_deg, beta_deg, gamma_deg) -> np.ndarray:
    """R_z(α) R_x(β) R_y(γ) (degrees, broadcast) — the pelvis attitude of the calibration fixtures."""
    a, b, c = np.broadcast_arrays(*(np.asarray(v, float) for v in (alpha_deg, beta_deg, gamma_deg)))
    ang = np.stack([a, b, c], -1)
    return Rotation.from_euler("ZXY", ang.reshape(-1, 3), degrees=True).as_matrix().reshape(a.shape + (3, 3))
