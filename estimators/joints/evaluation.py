"""Joint-angle accuracy against a reference (thesis Eq. 22, spec 7.A4)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AngleError:
    """Per angle component (K,): offset_deg = mean(ref − est) over standing; rmse_offset_standing_deg =
    RMS of (ref − est − offset_standing) over the trial; sd_error_deg = SD of (ref − est) (trial mean
    removed, Eq. 22 with T − 1); rmse_deg = plain RMS; rom_ref_deg / rom_est_deg = max − min."""
    offset_deg: np.ndarray
    rmse_offset_standing_deg: np.ndarray
    sd_error_deg: np.ndarray
    rmse_deg: np.ndarray
    rom_ref_deg: np.ndarray
    rom_est_deg: np.ndarray


def angle_errors(ref_deg: np.ndarray, est_deg: np.ndarray, *, standing: tuple[int, int] | None = None,
                 mask: np.ndarray | None = None) -> AngleError:
    """Errors of (N, K) estimated angles against (N, K) reference angles (degrees); ``mask`` selects
    the samples scored (e.g. the walking part), ``standing`` the offset window."""
    r = np.asarray(ref_deg, float)
    e = np.asarray(est_deg, float)
    if r.shape != e.shape:
        raise ValueError(f"ref_deg and est_deg must have the same shape, got {r.shape} and {e.shape}")
    if r.ndim == 1:
        r, e = r[:, None], e[:, None]
    err = r - e
    off = np.nanmean(err[standing[0]:standing[1]], axis=0) if standing is not None else np.zeros(r.shape[1])
    m = slice(None) if mask is None else np.asarray(mask, bool)
    em, rm, xm = err[m], r[m], e[m]
    return AngleError(offset_deg=off,
                      rmse_offset_standing_deg=np.sqrt(np.nanmean((em - off) ** 2, axis=0)),
                      sd_error_deg=np.nanstd(em, axis=0, ddof=1),
                      rmse_deg=np.sqrt(np.nanmean(em ** 2, axis=0)),
                      rom_ref_deg=np.nanmax(rm, axis=0) - np.nanmin(rm, axis=0),
                      rom_est_deg=np.nanmax(xm, axis=0) - np.nanmin(xm, axis=0))


def reference_angles_deg(q_prox: np.ndarray, q_dist: np.ndarray, *, joint: str, side: str,
                         standing: tuple[int, int] | None = None) -> np.ndarray:
    """(N, 3) reference joint angles from optical segment orientations (the IMU pipeline's joint coordinate
    system, :func:`stridelab.estimators.joints.joint_angles_deg`), with the same standing-offset removal as the IMU angles
    (thesis ch. 8: the mean over the quiet-standing window ``standing`` [start, stop) subtracted)."""
    from stridelab.estimators.joints._jcs import joint_angles_deg
    ref = joint_angles_deg(q_prox, q_dist, joint=joint, side=side)
    if standing is not None:
        ref = ref - np.nanmean(ref[standing[0]:standing[1]], axis=0)
    return ref


def pooled_rmse_deg(errors: list[np.ndarray]) -> np.ndarray:
    """(K,) RMS of (ref − est) per angle component pooled over trials: ``errors`` is a list of (n_i, K) arrays of
    finite sample errors (every sample weighs the same, as one trial of all samples would)."""
    err = np.concatenate(errors)
    return np.array([np.sqrt(np.mean(err[:, k] ** 2)) for k in range(err.shape[1])])
