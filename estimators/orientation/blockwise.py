"""Long recordings in overlapping blocks: bounded memory and time for day-long orientation.

A batch estimator over a 24 h, 100 Hz recording (8.6 M samples) allocates several full-length temporaries
per step (dcf_offline: about 4 GB and much of its time in page faults). No estimator of this package has
memory longer than minutes (dcf_offline's slowest zero-phase filter has τ = 60 s, the causal filters
converge within seconds), so a block that carries ``margin_s`` of context on each side is, inside the
block, as accurate as the whole-recording run (the two differ by less than either's error: a block's
strap-down frame starts elsewhere, and a block needs a rest period within reach for its gyro bias, as the
whole recording does; tests/estimators/orientation/test_blockwise.py); consecutive blocks are
cross-faded (normalised weighted quaternion average) over ``fade_s`` around each seam so the series has
no step. Peak memory is then that of one block plus the input and output arrays.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from stridelab.estimators.orientation._dcf import _blend
from stridelab.estimators.orientation._types import OrientationResult


def blockwise(estimate: Callable[..., OrientationResult], gyr: np.ndarray, acc: np.ndarray,
              mag: np.ndarray | None, *, sampling_rate_hz: float, block_s: float = 3600.0,
              margin_s: float = 300.0, fade_s: float = 60.0) -> OrientationResult:
    """Run ``estimate(gyr, acc, mag, sampling_rate_hz=...)`` over blocks of ``block_s`` seconds.

    Each block is estimated with ``margin_s`` of extra samples on both sides (clipped at the recording's
    ends); the output keeps the block's own samples, cross-faded linearly with the previous block over
    ``fade_s`` centred on the seam (``fade_s`` ≤ ``margin_s``). A recording no longer than
    ``block_s + 2·margin_s`` is estimated in one call, so short recordings are unaffected. ``params`` of
    the result are those of the first block; ``gain`` and ``still`` are taken from the block that owns
    each sample.
    """
    fs = float(sampling_rate_hz)
    n = len(gyr)
    blk, mar = int(round(block_s * fs)), int(round(margin_s * fs))
    half = min(int(round(0.5 * fade_s * fs)), mar)
    if blk <= 0 or n <= blk + 2 * mar:
        return estimate(gyr, acc, mag, sampling_rate_hz=fs)
    quat = np.empty((n, 4))
    gain = np.empty(n)
    still = np.empty(n, dtype=bool)
    first = None
    for a in range(0, n, blk):
        b = min(n, a + blk)
        if n - b < blk // 4:          # a short remainder joins this block instead of forming its own
            b = n
        lo, hi = max(0, a - mar), min(n, b + mar)
        r = estimate(gyr[lo:hi], acc[lo:hi], None if mag is None else mag[lo:hi], sampling_rate_hz=fs)
        first = first or r
        # own samples [a, b) plus the fade-in tail of the next seam [b, b + half)
        s0, s1 = a, min(n, b + half)
        seg = r.quat[s0 - lo:s1 - lo]
        if a > 0 and half > 0:         # fade from the previous block over [a - half, a + half)
            f0, f1 = a - half, min(n, a + half)
            w = (np.arange(f0, f1) - f0 + 0.5) / (f1 - f0)
            quat[f0:f1] = _blend(r.quat[f0 - lo:f1 - lo], quat[f0:f1], w)     # weight w on the new block
            quat[f1:s1] = seg[f1 - s0:]
        else:
            quat[s0:s1] = seg
        gain[a:b] = r.gain[a - lo:b - lo]
        still[a:b] = r.still[a - lo:b - lo]
        if b == n:
            break
    return OrientationResult(quat=quat, gain=gain, still=still, mag_used=first.mag_used, params=first.params)
