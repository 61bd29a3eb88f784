"""Gyroscope saturation: find clipped peaks and rebuild them from their shoulders (issue 15, point 3).

A MEMS gyroscope clips each axis at its range (the PyShoe MicroStrain near ±9.5 rad/s; the reading then sits at a
soft plateau of ±2 % because of on-board compensation). Clipping removes rotation, so the strapdown attitude and
then the position drift by the missing angle. The range is not known for an unknown sensor, so it is found from the
recording itself:

    L_j = max_k |ω_j,k| ;  candidate samples  C_j = {k : |ω_j,k| ≥ (1 − δ) L_j}                             (S1)
    axis j is clipped iff L_j ≥ ω_min and C_j forms ≥ n_min runs of ≥ 2 consecutive samples                 (S2)
      (a range limit is hit stride after stride and flattens the top; a natural maximum is a single sharp peak)
    each run [a, b) is rebuilt by the least-squares parabola through the h samples before a and after b−1
    (same sign, below the plateau), keeping the larger magnitude, capped at 2 L_j                           (S3)
    repaired samples get the extra gyro noise |ω_rebuilt − ω_measured| (σ_g,k += that, E4b in ``_eskf``)     (S4)

δ = 0.03, ω_min = 4 rad/s, n_min = 3, h = 3 are a priori (δ covers the ±2 % soft plateau; 4 rad/s is above
walking peaks of the foot's sagittal rate on most sensors' ranges being ≥ 5 rad/s).
"""
from __future__ import annotations

import numpy as np

__all__ = ["repair_gyro_saturation"]

DELTA = 0.03
OMEGA_MIN = 4.0
N_MIN_RUNS = 3
SHOULDER = 3


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def repair_gyro_saturation(gyr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(S1)–(S4): ``(gyr_repaired (N, 3), extra_noise (N,) rad/s, clipped_axes (3,) bool)``; a copy, input unchanged."""
    g = np.array(gyr, dtype=float, copy=True)
    n = g.shape[0]
    extra = np.zeros(n)
    clipped = np.zeros(3, bool)
    for j in range(3):
        a = np.abs(g[:, j])
        fin = np.isfinite(a)
        if not fin.any():
            continue
        L = float(a[fin].max())
        if L < OMEGA_MIN:
            continue
        runs = [(s, e) for s, e in _runs(fin & (a >= (1 - DELTA) * L)) if e - s >= 2]
        if len(runs) < N_MIN_RUNS:
            continue
        clipped[j] = True
        for s, e in runs:
            sign = np.sign(np.nanmean(g[s:e, j]))
            lo = np.arange(max(0, s - SHOULDER), s)
            hi = np.arange(e, min(n, e + SHOULDER))
            idx = np.concatenate([lo, hi])
            idx = idx[np.isfinite(g[idx, j]) & (np.sign(g[idx, j]) == sign)]
            if len(lo) < 2 or len(hi) < 1 or len(idx) < 3:
                continue
            c = np.polyfit(idx - s, g[idx, j], 2)
            fit = np.polyval(c, np.arange(s, e) - s)
            new = sign * np.minimum(np.maximum(np.abs(fit), a[s:e]), 2 * L)
            extra[s:e] += np.abs(new - g[s:e, j])
            g[s:e, j] = new
    return g, extra, clipped
