"""Sample-grid helpers shared by estimators and stages: contiguous segments between gaps."""
from __future__ import annotations

import numpy as np


def contiguous_segments(t_ns: np.ndarray, *, max_gap_factor: float = 5.0) -> list[tuple[int, int]]:
    """Half-open ``[start, end)`` index ranges between gaps.

    A gap is a step longer than ``max_gap_factor`` times the median sample period. Estimators with
    memory (filters) are run per segment and restart after a gap instead of integrating across it.
    """
    t = np.asarray(t_ns)
    if t.size == 0:
        return []
    if t.size == 1:
        return [(0, 1)]
    d = np.diff(t)
    cut = np.flatnonzero(d > max_gap_factor * np.median(d)) + 1
    edges = np.concatenate([[0], cut, [t.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def sampling_rate_hz(t_ns: np.ndarray) -> float:
    """Nominal rate from the median sample period (robust to jitter and gaps)."""
    d = np.diff(np.asarray(t_ns))
    if d.size == 0:
        raise ValueError("sampling_rate_hz: need at least two samples")
    return 1e9 / float(np.median(d))
