"""Orientation error against a reference (BROAD protocol; Laidig et al. 2021, spec thesis §8 A9-ii).

The error quaternion is taken in the earth frame, ``e = q_est ⊗ q_ref*`` (both sensor→ENU), and split
into a rotation about ENU z (heading) and the rest (inclination):

* total       = 2·acos|e_w|                 (quaternion angle distance)
* heading     = 2·atan(|e_z| / |e_w|)       (angle of the z-twist of e)
* inclination = 2·acos √(e_w² + e_z²)       (angle of the swing of e, i.e. tilt error)

Errors are RMS over a mask (BROAD: ``movement``) in degrees; samples where either quaternion is NaN
are left out. No alignment or heading offset is removed: a 9D estimate is scored against the ENU
reference as it stands.

Lab sessions (optical segment poses, :func:`segment_alignment`): the reference gives the *segment*
(marker cluster) orientation in the *lab* frame, the IMU estimate the *sensor* orientation in ENU. Two
constant rotations separate them — the sensor's mounting on the segment and the lab frame's heading in
ENU (the lab's z axis is vertical) — and both are estimated from the whole trial before scoring, as in
the BROAD paper's evaluation of sensors with an unknown mounting. Inclination errors are unaffected by the
heading offset; total and heading errors are relative to the trial's mean heading offset.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.quaternion import quat_conj, quat_mul, quat_normalize

__all__ = ["OrientationError", "orientation_error_deg", "orientation_rmse_deg", "pooled_rmse", "segment_alignment",
           "align_reference"]


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


def pooled_rmse(parts: list[OrientationError]) -> OrientationError:
    """The RMS errors of several scored pieces (recordings of one session) taken together: the mean squares
    weighted by the scored sample counts, i.e. the figure :func:`orientation_rmse_deg` gives on the pieces
    concatenated."""
    n = sum(p.n_scored for p in parts)
    if n == 0:
        raise ValueError("no sample to score: every piece is empty")

    def pool(k):
        return float(np.sqrt(sum(p.n_scored * getattr(p, k) ** 2 for p in parts) / n))

    return OrientationError(pool("total_rmse_deg"), pool("heading_rmse_deg"), pool("inclination_rmse_deg"), n)


def _mean_quat(q: np.ndarray) -> np.ndarray:
    """Chordal L2 mean of unit quaternions (eigenvector of Σ q qᵀ with the largest eigenvalue)."""
    q = q[np.all(np.isfinite(q), axis=1)]
    if len(q) == 0:
        raise ValueError("no finite quaternion to average")
    w, v = np.linalg.eigh(q.T @ q)
    m = v[:, -1]
    return m if m[0] >= 0 else -m


def _alternate(q_est: np.ndarray, q_ref: np.ndarray, h: np.ndarray, iterations: int,
               tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray, float]:
    """Alternating chordal-mean least squares from the heading ``h``; returns (h, mount, cost), cost = mean
    chordal residual 1 − ⟨q_est, h ⊗ q_ref ⊗ mount⟩² (0 = exact fit)."""
    mount = None
    for _ in range(iterations):
        mount = _mean_quat(quat_mul(quat_conj(quat_mul(h, q_ref)), q_est))
        g = _mean_quat(quat_mul(q_est, quat_conj(quat_mul(q_ref, mount))))
        new = quat_normalize(np.array([g[0], 0.0, 0.0, g[3]]))            # its twist about the vertical
        done = 1.0 - abs(float(np.dot(new, h))) < tol
        h = new
        if done:
            break
    mount = _mean_quat(quat_mul(quat_conj(quat_mul(h, q_ref)), q_est))
    fit = quat_mul(quat_mul(np.broadcast_to(h, q_ref.shape), q_ref), np.broadcast_to(mount, q_ref.shape))
    ok = np.all(np.isfinite(fit), axis=1) & np.all(np.isfinite(q_est), axis=1)
    cost = float(np.mean(1.0 - np.sum(fit[ok] * q_est[ok], axis=1) ** 2)) if ok.any() else float("inf")
    return h, mount, cost


def segment_alignment(q_est: np.ndarray, q_ref: np.ndarray, *, iterations: int = 200,
                      starts: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """The two constant rotations between an IMU estimate and an optical segment reference.

    q_est (N, 4): sensor→ENU; q_ref (N, 4): segment→lab (both [w x y z], NaN rows ignored). Model
    ``q_est ≈ q_heading ⊗ q_ref ⊗ q_mount`` with ``q_heading`` a rotation about the vertical (lab→ENU) and
    ``q_mount`` the sensor's orientation on the segment (sensor→segment). Alternating chordal-mean least
    squares. The alternation converges slowly when the lab's heading is far from the start (on the gaitmap walk,
    lab x vs the IMU's ENU heading ≈ 150°: 38° total error left after 10 iterations from identity, 3.0° at
    convergence), so it starts from ``starts`` headings evenly spaced over 360°, keeps the one with the lowest
    residual after 5 iterations and iterates it to convergence (at most ``iterations``). Returns
    ``(q_heading, q_mount)``.
    """
    q_est = np.asarray(q_est, float)
    q_ref = np.asarray(q_ref, float)
    if q_est.shape != q_ref.shape or q_est.shape[-1] != 4:
        raise ValueError(f"q_est {q_est.shape} and q_ref {q_ref.shape} must both be (N, 4) [w x y z]")
    best = None
    for k in range(max(1, starts)):
        a = np.pi * k / max(1, starts)                                    # half the heading angle
        h, _, cost = _alternate(q_est, q_ref, np.array([np.cos(a), 0.0, 0.0, np.sin(a)]), 5)
        if best is None or cost < best[1]:
            best = (h, cost)
    h, mount, _ = _alternate(q_est, q_ref, best[0], iterations)
    return h, mount


def align_reference(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """The reference mapped onto the estimate's frames (sensor→ENU), ready for :func:`orientation_rmse_deg`."""
    h, mount = segment_alignment(q_est, q_ref)
    return quat_mul(quat_mul(np.broadcast_to(h, q_ref.shape), q_ref), np.broadcast_to(mount, q_ref.shape))
