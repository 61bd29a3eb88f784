"""Several sensors of one recording on one time grid: the stamps they share, or (sensors on independent
clocks) a straight-line clock model fitted through the host's arrival times and interpolation onto one sensor's
stamps. Pure NumPy; used by the calibration and joint-angle stages and the live calibration.

Clock model: each sensor's host arrival time ``log`` relates to its own stamp ``t`` by
``log - t = offset + rate (t - t0)`` (constant offset and rate error, least squares over a subsample of at most
~20 000 points; the linear clock model of e.g. Olson, "A passive solution to the sensor synchronization
problem", IROS 2010, without its minimum filter: transport jitter averages out over a trial of seconds to minutes).
Quaternions are interpolated by normalised linear interpolation (nlerp, the first-order approximation of
Shoemake's slerp, SIGGRAPH 1985) after making the sign continuous.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ClockFit", "clock_fit", "common_grid", "interp_columns", "nearest_sample", "nlerp", "to_clock_of"]

#: (t0 ns, offset ns at t0, rate ns/ns) of ``log - t = offset + rate (t - t0)``
ClockFit = tuple[float, float, float]


def common_grid(t_by_placement: dict[str, np.ndarray]) -> np.ndarray:
    """Timestamps (int64 ns) present in every sensor of a recording: one time grid for the estimators."""
    grid = None
    for t in t_by_placement.values():
        grid = t if grid is None else np.intersect1d(grid, t, assume_unique=True)
    return np.asarray(grid if grid is not None else [], np.int64)


def clock_fit(t: np.ndarray, log: np.ndarray) -> ClockFit:
    """(t0, offset at t0, rate) of the straight line ``log - t = offset + rate * (t - t0)``, in ns and ns/ns."""
    k = max(1, len(t) // 20000)
    tt, off = t[::k].astype(np.float64), (log[::k] - t[::k]).astype(np.float64)
    t0 = float(tt[0])
    if len(tt) < 3 or np.ptp(tt) == 0:
        return t0, float(np.median(off)), 0.0
    b, a = np.polyfit(tt - t0, off, 1)
    return t0, float(a), float(b)


def to_clock_of(t: np.ndarray, fit: ClockFit, ref: ClockFit) -> np.ndarray:
    """Stamps ``t`` of a sensor with clock ``fit`` in the clock of the sensor with clock ``ref`` (float64 ns):
    both through the host time, solving ``host = t_r + ra + rb (t_r - r0)`` for ``t_r``."""
    t0, a, b = fit
    r0, ra, rb = ref
    host = t.astype(np.float64) + a + b * (t.astype(np.float64) - t0)
    return (host - ra + rb * r0) / (1.0 + rb)


def interp_columns(t_dst: np.ndarray, t_src: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N, k) columns of ``x`` linearly interpolated from ``t_src`` onto ``t_dst``."""
    return np.column_stack([np.interp(t_dst, t_src, x[:, k]) for k in range(x.shape[1])])


def nlerp(t_src: np.ndarray, q: np.ndarray, t_dst: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions ``q`` (sampled at ``t_src``) at ``t_dst``: sign made continuous, then normalised
    linear interpolation."""
    q = q.copy()
    flip = np.cumsum(np.r_[False, (q[1:] * q[:-1]).sum(axis=1) < 0]) % 2 == 1
    q[flip] *= -1                                   # sign continuity before interpolating
    out = np.column_stack([np.interp(t_dst, t_src, q[:, k]) for k in range(4)])
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def nearest_sample(t_grid: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each stamp ``t`` (int64 ns) the index of the nearest sample of the regular grid ``t_grid`` (N ≥ 2) and
    whether it lies within half a mean grid period of it (readings of a slower sensor onto an IMU's samples)."""
    half = (t_grid[-1] - t_grid[0]) / (len(t_grid) - 1) / 2
    i = np.clip(np.searchsorted(t_grid, t), 1, len(t_grid) - 1)
    i = np.where(np.abs(t_grid[i - 1] - t) <= np.abs(t_grid[i] - t), i - 1, i)
    return i, np.abs(t_grid[i] - t) <= half
