"""Trajectory accuracy against a reference (STYLE P11): per-axis RMS position error as in Duong & Suh Table 2."""
from __future__ import annotations

import numpy as np

__all__ = ["rms_error_per_axis"]


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
