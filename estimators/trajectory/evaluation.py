"""Trajectory accuracy against a reference (STYLE P11).

- ``rms_error_per_axis``: per-axis RMS position error as in Duong & Suh Table 2 (no alignment).
- ``armse_2d_aligned``: PyShoe's 2-D alignment (Wagstaff et al. 2017 / PyShoe ``align_plots``) with the
  Euclidean error (issue 15):
      both trajectories minus their first sample;  k* = first sample where |p̂_xy(k) − p̂_xy(0)| ≥ 0.8 m (else 300)
      ψ = atan2 of the reference xy at k* − atan2 of the estimate xy at k*;  p̂_xy ← R_z(ψ) p̂_xy            (M1)
      ARMSE = mean_k |p̂_xy(k) − p_xy(k)|   over all samples                                                (M2)
- ``armse_3d_aligned`` (issue 43): the same alignment (M1, a rotation about z; both start at their first sample)
  with the 3-D Euclidean error mean_k |p̂(k) − p(k)| (M3): adds the height drift the 2-D figure hides.
- ``armse_pyshoe`` (issue 43): PyShoe's published ARMSE exactly as its evaluation code computes it
  (Wagstaff et al.; PyShoe ``ins_tools/util.py``: ``align_plots`` then ``compute_error``):
      both minus their first sample;  d_i = |p̂_xy(i+1) − p̂_xy(0)| ;  i* = first i with d_i ≥ 0.8 m (else 300)
      ψ = signed angle from p̂_xy(i*) to p_xy(i*) (arccos of the normalised dot product, sign of the cross
      product);  p̂_xy ← R_z(ψ) p̂_xy  (z untouched)                                                          (M5)
      ARMSE_D = mean_k sqrt( (1/D) Σ_{j<D} (p̂_j(k) − p_j(k))² ),  D = 2 or 3                                  (M6)
  (M6) is the per-sample RMS over the *axes*, i.e. the Euclidean error divided by √D: PyShoe's published
  figures (and the ``best_error`` stored in its Vicon files) are on this scale, (M2)/(M3) are √2 / √3 larger.
  (M5) aligns on the sample *before* the one (M1) uses (PyShoe indexes the cumulative sum of the differences).
  PyShoe rounds to 1 mm; this does not.
- ``final_position_error``: closure error of a walk that ends where it started, |p(last) − p(first)| of the
  mid-stance positions, horizontal and 3-D (M4).
"""
from __future__ import annotations

import numpy as np

__all__ = ["rms_error_per_axis", "armse_2d_aligned", "armse_3d_aligned", "armse_pyshoe", "final_position_error", "ALIGN_DISTANCE_M", "ALIGN_FALLBACK_SAMPLE"]

ALIGN_DISTANCE_M = 0.8
ALIGN_FALLBACK_SAMPLE = 300


def rms_error_per_axis(estimate: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(3,) m: E_RMS per axis = sqrt(mean_k (p̂_k − p_k)²) over samples where both are finite (spec B8; no alignment:
    the caller puts both in one frame). NaN for an axis without any finite pair."""
    e = np.asarray(estimate, float) - np.asarray(reference, float)
    out = np.full(e.shape[1], np.nan)
    for j in range(e.shape[1]):
        c = e[:, j][np.isfinite(e[:, j])]
        if len(c):
            out[j] = float(np.sqrt(np.mean(c ** 2)))
    return out


def _hold_leading_rows(p: np.ndarray) -> bool:
    """The estimate rule of every ARMSE here, in place on ``p`` (N, D): leading non-finite rows (a filter that starts at
    the first stance) take the first finite row (the foot has not moved before it); any other non-finite row is a
    ValueError. False when no row is finite (the caller returns NaN)."""
    ok = np.all(np.isfinite(p), axis=1)
    if not ok.any():
        return False
    k0 = int(np.argmax(ok))
    p[:k0] = p[k0]
    if not np.all(np.isfinite(p)):
        raise ValueError("estimate has non-finite rows after its first finite one")
    return True


def armse_2d_aligned(estimate: np.ndarray, reference: np.ndarray, *, align_distance_m: float = ALIGN_DISTANCE_M,
                     fallback_sample: int = ALIGN_FALLBACK_SAMPLE) -> tuple[float, np.ndarray]:
    """(M1)–(M2): 2-D Euclidean ARMSE (m) and the aligned estimate (N, 2).

    ``estimate``/``reference``: (N, ≥2) positions on the same samples, z up. Leading non-finite estimate rows (a
    filter that starts at the first stance) take the first finite row (the foot has not moved before it); any other
    non-finite row is an error. Rows where the reference is not finite are left out of the mean (M2).
    """
    p = np.asarray(estimate, float)[:, :2].copy()
    r = np.asarray(reference, float)[:, :2]
    if p.shape != r.shape or len(p) < 2:
        raise ValueError(f"estimate and reference need the same (N >= 2, 2+) shape; got {p.shape} and {r.shape}")
    if not _hold_leading_rows(p):
        return float("nan"), p
    rv = np.all(np.isfinite(r), axis=1)
    r0 = r[int(np.argmax(rv))]
    p = p - p[0]
    rr = r - r0
    d = np.hypot(p[:, 0], p[:, 1])
    far = np.flatnonzero(d >= align_distance_m)
    k = int(far[0]) if len(far) else min(fallback_sample, len(p) - 1)
    if np.all(np.isfinite(rr[k])) and d[k] > 0 and np.hypot(*rr[k]) > 0:
        psi = np.arctan2(rr[k, 1], rr[k, 0]) - np.arctan2(p[k, 1], p[k, 0])
        c, s = np.cos(psi), np.sin(psi)
        p = p @ np.array([[c, s], [-s, c]])
    e = np.hypot(*(p[rv] - rr[rv]).T)
    return float(e.mean()) if len(e) else float("nan"), p


def armse_3d_aligned(estimate: np.ndarray, reference: np.ndarray, *, align_distance_m: float = ALIGN_DISTANCE_M,
                     fallback_sample: int = ALIGN_FALLBACK_SAMPLE) -> float:
    """(M1), (M3): 3-D Euclidean ARMSE (m) after the 2-D alignment of :func:`armse_2d_aligned` (same heading
    rotation; heights minus their first finite value). Same input rules."""
    p3 = np.asarray(estimate, float)[:, :3].copy()
    r3 = np.asarray(reference, float)[:, :3]
    _, pxy = armse_2d_aligned(p3, r3, align_distance_m=align_distance_m, fallback_sample=fallback_sample)
    ok = np.all(np.isfinite(p3), axis=1)
    if not ok.any():
        return float("nan")
    k0 = int(np.argmax(ok))
    z = p3[:, 2].copy()
    z[:k0] = z[k0]
    rv = np.all(np.isfinite(r3), axis=1)
    rr = r3 - r3[int(np.argmax(rv))]
    e = np.sqrt(np.sum((np.column_stack([pxy, z - z[0]])[rv] - rr[rv]) ** 2, axis=1))
    return float(e.mean()) if len(e) else float("nan")


def armse_pyshoe(estimate: np.ndarray, reference: np.ndarray, *, dims: int = 2,
                 align_distance_m: float = ALIGN_DISTANCE_M, fallback_sample: int = ALIGN_FALLBACK_SAMPLE) -> float:
    """(M5)–(M6): PyShoe's ARMSE (m) over ``dims`` = 2 (x, y) or 3 axes. Same input rules as
    :func:`armse_2d_aligned` (leading non-finite estimate rows take the first finite row; reference rows that are
    not finite are left out of the mean)."""
    if dims not in (2, 3):
        raise ValueError(f"dims must be 2 or 3, got {dims}")
    p = np.asarray(estimate, float)[:, :3].copy()
    r = np.asarray(reference, float)[:, :3]
    if p.shape != r.shape or len(p) < 2:
        raise ValueError(f"estimate and reference need the same (N >= 2, 3) shape; got {p.shape} and {r.shape}")
    if not _hold_leading_rows(p):
        return float("nan")
    rv = np.all(np.isfinite(r), axis=1)
    p = p - p[0]
    rr = r - r[int(np.argmax(rv))]
    d = np.hypot(p[1:, 0], p[1:, 1])                     # d_i = distance of sample i + 1 (M5)
    far = np.flatnonzero(d >= align_distance_m)
    i = int(far[0]) if len(far) else min(fallback_sample, len(p) - 1)
    v1, v2 = p[i, :2], rr[i, :2]
    n1, n2 = np.hypot(*v1), np.hypot(*v2) if np.all(np.isfinite(v2)) else 0.0
    if n1 > 0 and n2 > 0:
        cross = v1[0] * v2[1] - v1[1] * v2[0]
        psi = np.sign(cross) * np.arccos(min(1.0, float(np.dot(v1, v2) / (n1 * n2))))
        c, s = np.cos(psi), np.sin(psi)
        p[:, :2] = p[:, :2] @ np.array([[c, s], [-s, c]])
    e = p[rv, :dims] - rr[rv, :dims]
    return float(np.mean(np.sqrt(np.mean(e ** 2, axis=1)))) if len(e) else float("nan")


def final_position_error(pos_at_mid_stances: np.ndarray) -> tuple[float, float]:
    """(M4) ``(horizontal, 3-D)`` m: |p(last) − p(first)| of the (K, 3) mid-stance positions (K ≥ 2)."""
    p = np.asarray(pos_at_mid_stances, float)
    if p.ndim != 2 or p.shape[0] < 2 or p.shape[1] < 3:
        raise ValueError(f"need (K >= 2, 3) mid-stance positions, got {p.shape}")
    e = p[-1, :3] - p[0, :3]
    return float(np.hypot(e[0], e[1])), float(np.linalg.norm(e))
