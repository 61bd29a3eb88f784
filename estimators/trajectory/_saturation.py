"""Gyroscope saturation: find clipped peaks and rebuild them from their shoulders (issue 15 point 3, issue 43).

A MEMS gyroscope clips each axis at its range (the PyShoe MicroStrain near ±9.1–9.7 rad/s, a different level per
axis; the reading then sits on a plateau that wanders by a few 0.01 rad/s because of on-board compensation).
Clipping removes rotation, so the strapdown attitude and then the position drift by the missing angle. The range is
not known for an unknown sensor, so it is found from the recording itself. A natural peak is *curved*: its top
three samples differ by A·(2πT/P)²/2 (amplitude A, swing-peak period P ≈ 0.2–0.3 s, T the sample interval: about
0.05–0.1 rad/s for a 9 rad/s peak at 200 Hz); a clipped one is *flat* to within the sensor noise. Only flat
samples near the top count (issue 43: the former rule "≥ 3 runs within 3 % of the maximum" also fired on the
repeated, curved swing peaks of walking trials and then "repaired" peaks that were never clipped):

    L_j = max_k |ω_j,k| ;  near full scale  C_j = {k : |ω_j,k| ≥ (1 − δ) L_j}                                (S1)
    a run of C_j is a plateau iff it holds ``PLATEAU_LEN`` consecutive samples whose spread (max − min of |ω|)
    is ≤ ε L_j ; axis j is clipped iff L_j ≥ ω_min and it has ≥ n_min plateaus                              (S2)
      (a range limit is hit stride after stride and flattens the top; a natural maximum is curved)
    each plateau run [a, b) is rebuilt by the least-squares parabola through the h samples before a and after
    b−1 (same sign, below the plateau), keeping the larger magnitude, capped at 2 L_j                        (S3)
    repaired samples get the extra gyro noise |ω_rebuilt − ω_measured| (σ_g,k += that, E4b in ``_eskf``)     (S4)

δ = 0.03, ω_min = 4 rad/s, h = 3 (a priori, unchanged from issue 15: δ covers the plateau's wander below the
axis maximum, 4 rad/s is above walking peaks of most foot rates); ε = 0.003 (0.3 % ≈ 0.03 rad/s at 9 rad/s:
about three times the gyro noise, and below the curvature of a swing peak sampled at 200 Hz), ``PLATEAU_LEN`` = 3
samples (a top of three equal samples; two can be equal by chance) and n_min = 2 (one plateau can be a chance
flat top; a range limit recurs) — a priori, not fitted. Effect on the PyShoe trials: docs/gait.md.
"""
from __future__ import annotations

import numpy as np

__all__ = ["repair_gyro_saturation", "plateau_runs"]

DELTA = 0.03
OMEGA_MIN = 4.0
N_MIN_RUNS = 2
SHOULDER = 3
FLAT_EPS = 0.003
PLATEAU_LEN = 3


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def plateau_runs(a: np.ndarray, L: float) -> list[tuple[int, int]]:
    """(S1)–(S2): runs [a, b) of ``|ω| ≥ (1 − δ) L`` that contain ``PLATEAU_LEN`` samples within ε L of each other.
    ``a`` is |ω| of one axis (non-finite samples never belong to a run)."""
    fin = np.isfinite(a)
    out = []
    for s, e in _runs(fin & (a >= (1 - DELTA) * L)):
        if e - s < PLATEAU_LEN:
            continue
        seg = a[s:e]
        w = np.lib.stride_tricks.sliding_window_view(seg, PLATEAU_LEN)
        if np.any(w.max(axis=1) - w.min(axis=1) <= FLAT_EPS * L):
            out.append((int(s), int(e)))
    return out


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
        runs = plateau_runs(a, L)
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
