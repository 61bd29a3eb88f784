"""Per-block checks of ingest, run on the MCAP reader's chunk threads (``iter_blocks(on_block=check_block)``).

One pass of GIL-free numba kernels per block of decoded messages: finite values, unset stamps, order and repeats
inside the block, the subsample for the unit and clock statistics, and the gyroscope-against-gravity sums of the
units check (:func:`stridelab.pipeline.ingest.check.check_units`). :class:`stridelab.pipeline.ingest.series.TopicSeries` then only
compares block edges.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from stridelab.pipeline.formats.mcap_read import Block

SUBSAMPLE = 61              # statistics on every 61st sample (prime: no aliasing with batches or chunks)


@njit(cache=True, nogil=True)
def _stamp_flags(t, log):
    """One pass over a block's stamps: (unset stamps, of them also without log_time, a step back, a
    repeated stamp), with unset (zero) stamps counted as their log_time."""
    n_zero = 0
    n_none = 0
    back = False
    rep = False
    prev = np.int64(0)
    for i in range(t.shape[0]):
        x = t[i]
        if x == 0:
            x = log[i]
            n_zero += 1
            if x == 0:
                n_none += 1
        if i > 0:
            if x < prev:
                back = True
            elif x == prev:
                rep = True
        prev = x
    return n_zero, n_none, back, rep


_EXP = np.uint64(0x7FF0_0000_0000_0000)


@njit(cache=True, nogil=True)
def _max_exponent(bits):
    """Largest exponent field of float64 bit patterns: all ones (``_EXP``) iff some value is NaN or inf
    (an integer max, which vectorises; ``np.isfinite`` with an early exit does not)."""
    m = np.uint64(0)
    for i in range(bits.shape[0]):
        e = bits[i] & _EXP
        if e > m:
            m = e
    return m


def _all_finite(v: np.ndarray) -> bool:
    flat = v.T if v.flags.f_contiguous else v
    if flat.dtype == np.float64 and flat.flags.c_contiguous:
        return bool(_max_exponent(flat.reshape(-1).view(np.uint64)) != _EXP)
    if v.dtype == np.float64 and v.ndim == 2 and v.strides[0] == 8:      # columns contiguous, apart (the reader's
        return all(_max_exponent(v[:, k].view(np.uint64)) != _EXP for k in range(v.shape[1]))   # fast path)
    return bool(np.isfinite(v).all())


G0 = 9.80665
#: windows whose mean specific force is within this of 1 g are quasi-static (gravity dominates the accelerometer)
STILL_TOLERANCE = 1.0      # m/s²
WINDOW_S = 0.1             # window of the rotation check (s); at least 4 samples


@njit(cache=True, nogil=True)
def _rotation_sums(t, v, w):
    """Agreement of the gyroscope with the accelerometer's gravity direction over consecutive quasi-static
    windows of ``w`` samples: the unit specific force ``f`` of a sensor turning at body rate ``omega`` changes as
    ``df/dt = -omega x f`` (gravity is fixed in the world). Per pair of windows, ``c`` = -(integral of omega
    between the window centres) x f (predicted) and ``d`` = the change of f (measured). Returns
    (sum |c|², sum |d|², sum c.d, pairs). With rad/s both agree (|c|/|d| ~ 1); a gyroscope in deg/s predicts
    57.3 times the measured turn, whatever the rate's size (the magnitude check misses a slow turn)."""
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    cnt = 0
    prev_ok = False
    px = 0.0
    py = 0.0
    pz = 0.0
    h = w // 2
    for k in range(t.shape[0] // w):
        a = k * w
        mx = 0.0
        my = 0.0
        mz = 0.0
        for j in range(a, a + w):
            mx += v[j, 3]
            my += v[j, 4]
            mz += v[j, 5]
        mx /= w
        my /= w
        mz /= w
        nrm = np.sqrt(mx * mx + my * my + mz * mz)
        ok = abs(nrm - G0) < STILL_TOLERANCE
        if ok:
            mx /= nrm
            my /= nrm
            mz /= nrm
        if ok and prev_ok:
            gx = 0.0
            gy = 0.0
            gz = 0.0
            good = True
            for j in range(a - w + h, a + h):
                dt = (t[j + 1] - t[j]) * 1e-9
                if dt <= 0.0 or dt > 0.2:
                    good = False
                    break
                gx += v[j, 0] * dt
                gy += v[j, 1] * dt
                gz += v[j, 2] * dt
            if good:
                cx = -(gy * pz - gz * py)
                cy = -(gz * px - gx * pz)
                cz = -(gx * py - gy * px)
                dx = mx - px
                dy = my - py
                dz = mz - pz
                sxx += cx * cx + cy * cy + cz * cz
                syy += dx * dx + dy * dy + dz * dz
                sxy += cx * dx + cy * dy + cz * dz
                cnt += 1
        prev_ok = ok
        px = mx
        py = my
        pz = mz
    return sxx, syy, sxy, cnt


def rotation_window(t: np.ndarray) -> int:
    """Samples per window of :func:`_rotation_sums`: about :data:`WINDOW_S` at the block's rate, at least 4."""
    d = np.diff(t[:64])
    d = d[d > 0]
    if not len(d):
        return 0
    return max(4, int(round(WINDOW_S * 1e9 / float(np.median(d)))))


@dataclass
class BlockChecks:
    """What :func:`check_block` found in one block (``t``: the stamps with unset ones replaced)."""
    t: np.ndarray
    n_zero: int = 0                # unset stamps (replaced by log_time)
    n_none: int = 0                # ... whose log_time is unset too
    back: bool = False             # a stamp below its predecessor inside the block
    rep: bool = False              # a stamp equal to its predecessor inside the block
    n_bad: int = 0                 # samples with NaN/inf values (refused)
    first_bad: int = -1
    n_nan: int = 0                 # reference poses without a position (kept as NaN)
    n_no_quat: int = 0             # ... with a position but no orientation (kept as NaN)
    n_pose: int = 0                # reference poses in the block
    sub: np.ndarray | None = None  # every SUBSAMPLE-th IMU sample (unit checks)
    off: np.ndarray | None = None  # ... and its log_time - stamp (clock checks)
    rot: tuple = (0.0, 0.0, 0.0, 0)  # gyroscope vs gravity direction (:func:`_rotation_sums`; unit check)


def check_block(b: Block) -> Block:
    """Attach :class:`BlockChecks` to ``b`` (GIL-free kernels; safe to call on any thread)."""
    t, log, v = b.t_ns, b.log_ns, b.values
    c = BlockChecks(t)
    if b.kind == "events" or len(t) == 0:
        b.checks = c
        return b
    if b.kind == "range":
        pass        # REP-117: +inf beyond max range, -inf below min, NaN invalid: legitimate readings
    elif b.kind == "reference_pose" and not np.isinf(v).any():
        pos_nan = np.isnan(v[:, :3]).any(axis=1)               # occluded markers: kept as NaN
        c.n_nan = int(pos_nan.sum())
        c.n_no_quat = int((np.isnan(v[:, 3:7]).any(axis=1) & ~pos_nan).sum())
        c.n_pose = len(v)
    elif b.kind == "reference_pose" or not _all_finite(v):
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        c.n_bad, c.first_bad = len(bad), int(bad[0])
    c.n_zero, c.n_none, c.back, c.rep = _stamp_flags(t, log)
    if c.n_zero:
        c.t = t = np.where(t == 0, log, t)
    if b.kind == "imu":                      # every 61st sample feeds the unit and clock statistics
        c.sub = v[::SUBSAMPLE].copy()        # a copy: a view would keep the block alive
        c.off = log[::SUBSAMPLE] - t[::SUBSAMPLE]
        if not c.back:
            w = rotation_window(t)
            if w and len(t) >= 2 * w:
                c.rot = _rotation_sums(t, v, w)
    b.checks = c
    return b
