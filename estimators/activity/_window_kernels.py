"""Numba kernels of the window features (``windows.window_features``): NumPy's reductions, bit for bit, in one pass.

``window_features`` reduces a day of windows with NumPy expressions that each walk the whole (W, w, 3) block and
allocate one or two temporaries of its size (a 24 h day at the model's 26 Hz: 54 MB each): the window means and
standard deviations of the auto-calibration, the calibrated copy, the window means, the RMS of the dynamic, the
vertical and the horizontal acceleration and of the jerk of the acceleration norm, the band powers of the two
periodograms. Together they were ~0.4 of the ~0.8-1.0 s of a day's window features. These kernels compute the same numbers window by window, in the order
NumPy adds them, so the features are unchanged to the last bit (``tests/estimators/activity/test_window_kernels.py``
compares them with the NumPy expressions on real and random data):

- a reduction over the window's samples of a (W, w, 3) C-ordered block (``blk.mean(axis=1)``) adds sample after
  sample (NumPy's outer loop runs over the samples, its inner loop over the three axes);
- a reduction over a contiguous axis (``x.mean(axis=1)`` of (W, w)) is NumPy's pairwise summation
  (:func:`pairwise_sum`: blocks of at most 128 values summed with eight accumulators, longer runs split in two
  at a multiple of 8) started from 0;
- the sum over the three axes is ``(0 + x₀) + x₁ + x₂``; a mean divides the sum by the count, a standard deviation
  is NumPy's two-pass one (``sqrt(Σ (x − mean)² / n)``);
- a band power of a periodogram, ``P[:, sel].sum(axis=1)``, adds bin after bin (the boolean selection is laid out
  column-major); :func:`spectrum_bands` computes the bands and the peak bin from the spectra without the PSD array.

No fused multiply-adds (numba's default), as in NumPy.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _block_sum(a, lo, n):
    # a run of at most 128 values: eight accumulators (fewer than 8 values: one), the rest added in order
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    m = n - n % 8
    while i < m:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


def pairwise_scratch():
    """Work arrays of :func:`pairwise_sum` (an explicit stack: numba's cache cannot hold a recursive function)."""
    return np.empty((64, 3), np.int64), np.empty(64)


@njit(cache=True)
def pairwise_sum(a, lo, n, stack, vals):
    """NumPy's pairwise summation of ``a[lo:lo + n]`` (``DOUBLE_pairwise_sum``, numpy/_core/src/umath/
    loops_utils.h.src: runs of at most 128 values summed by :func:`_block_sum`, longer runs split at
    ``n // 2`` rounded down to a multiple of 8 and the halves' sums added), i.e. ``np.add.reduce`` over a
    contiguous run without the initial 0. The recursion is walked with the explicit stack ``stack`` (rows
    lo, n, state) and ``vals`` from :func:`pairwise_scratch` (64 levels: any n)."""
    if n <= 128:
        return _block_sum(a, lo, n)
    sp, vp = 0, 0
    stack[0, 0], stack[0, 1], stack[0, 2] = lo, n, 0
    while sp >= 0:
        lo_, n_, state = stack[sp, 0], stack[sp, 1], stack[sp, 2]
        if n_ <= 128:
            vals[vp] = _block_sum(a, lo_, n_)
            vp += 1
            sp -= 1
            continue
        n2 = n_ // 2
        n2 -= n2 % 8
        if state == 0:                      # the left half first
            stack[sp, 2] = 1
            sp += 1
            stack[sp, 0], stack[sp, 1], stack[sp, 2] = lo_, n2, 0
        elif state == 1:                    # then the right half
            stack[sp, 2] = 2
            sp += 1
            stack[sp, 0], stack[sp, 1], stack[sp, 2] = lo_ + n2, n_ - n2, 0
        else:                               # both done: left + right
            vals[vp - 2] = vals[vp - 2] + vals[vp - 1]
            vp -= 1
            sp -= 1
    return vals[0]


#: NumPy's reductions run through its iterator's buffer: a contiguous run longer than this is summed in pieces of
#: this many values, each pairwise, added one after the other (``np.getbufsize()``'s default)
NUMPY_BUFSIZE = 8192


@njit(cache=True)
def contiguous_mean(a, lo, n, stack, vals):
    """``a[lo:lo + n].mean()`` as NumPy computes it (with its default buffer size)."""
    s = 0.0
    for b in range(lo, lo + n, NUMPY_BUFSIZE):
        s += pairwise_sum(a, b, min(NUMPY_BUFSIZE, lo + n - b), stack, vals)
    return s / n


@njit(cache=True, nogil=True)
def scaled_window_mean_std(acc, divisor, w):
    """``a = acc / divisor`` (N, 3) and, over the W = N // w whole windows of ``a``, ``blk.mean(axis=1)`` and
    ``blk.std(axis=1)`` (W, 3) with ``blk = a[:W w].reshape(W, w, 3)``."""
    n = acc.shape[0]
    a = np.empty((n, 3))
    for i in range(n):
        for k in range(3):
            a[i, k] = acc[i, k] / divisor
    mean = window_mean(a, w)
    std = np.empty_like(mean)
    for j in range(mean.shape[0]):
        b = j * w
        for k in range(3):
            q = 0.0
            for i in range(b, b + w):
                d = a[i, k] - mean[j, k]
                q += d * d
            std[j, k] = np.sqrt(q / w)
    return a, mean, std


@njit(cache=True, nogil=True)
def affine_window_mean(a, offset, gain, w):
    """``c = (a − offset) · gain`` (N, 3) and its window means ``c[:W w].reshape(W, w, 3).mean(axis=1)``."""
    n = a.shape[0]
    c = np.empty((n, 3))
    for i in range(n):
        for k in range(3):
            c[i, k] = (a[i, k] - offset[k]) * gain[k]
    return c, window_mean(c, w)


@njit(cache=True, nogil=True)
def window_mean(a, w):
    """``a[:W w].reshape(W, w, 3).mean(axis=1)`` (W, 3) of a C-ordered (N, 3) array."""
    nw = a.shape[0] // w
    mean = np.empty((nw, 3))
    for j in range(nw):
        b = j * w
        for k in range(3):
            s = 0.0
            for i in range(b, b + w):
                s += a[i, k]
            mean[j, k] = s / w
    return mean


@njit(cache=True, nogil=True)
def window_mean_squares(a, d, vert, u, w, fs):
    """Per window j (W = N // w), with ``A``/``D`` the (W, w, 3) windows of ``a``/``d`` and ``vert`` (W, w):

    - ``dyn``: ``(D ** 2).sum(axis=2).mean(axis=1)`` (mean square of the dynamic acceleration);
    - ``horiz``: ``((D − vert[:, :, None] · u[:, None, :]) ** 2).sum(axis=2).mean(axis=1)``;
    - ``vert``: ``(vert ** 2).mean(axis=1)``;
    - ``jerk``: ``((np.diff(np.linalg.norm(A, axis=2), axis=1) · fs) ** 2).mean(axis=1)``.
    """
    nw = a.shape[0] // w
    dyn = np.empty(nw)
    hor = np.empty(nw)
    ver = np.empty(nw)
    jerk = np.empty(nw)
    r1 = np.empty(w)
    r2 = np.empty(w)
    r3 = np.empty(w)
    nrm = np.empty(w)
    stack = np.empty((64, 3), np.int64)
    vals = np.empty(64)
    for j in range(nw):
        b = j * w
        u0, u1, u2 = u[j, 0], u[j, 1], u[j, 2]
        for i in range(w):
            d0, d1, d2 = d[b + i, 0], d[b + i, 1], d[b + i, 2]
            r1[i] = ((0.0 + d0 * d0) + d1 * d1) + d2 * d2
            v = vert[j, i]
            h0 = d0 - v * u0
            h1 = d1 - v * u1
            h2 = d2 - v * u2
            r2[i] = ((0.0 + h0 * h0) + h1 * h1) + h2 * h2
            r3[i] = v * v
            a0, a1, a2 = a[b + i, 0], a[b + i, 1], a[b + i, 2]
            nrm[i] = np.sqrt(((0.0 + a0 * a0) + a1 * a1) + a2 * a2)
        dyn[j] = contiguous_mean(r1, 0, w, stack, vals)
        hor[j] = contiguous_mean(r2, 0, w, stack, vals)
        ver[j] = contiguous_mean(r3, 0, w, stack, vals)
        for i in range(w - 1):
            x = (nrm[i + 1] - nrm[i]) * fs
            r1[i] = x * x
        jerk[j] = contiguous_mean(r1, 0, w - 1, stack, vals)
    return dyn, hor, ver, jerk


@njit(cache=True, nogil=True)
def spectrum_bands(X, scale, one_sided_end, starts, stops, peak_lo, peak_hi):
    """Band powers and the peak bin of the one-sided periodograms whose spectra are the rows of ``X`` (W, bins),
    as ``windows.window_features`` computed them from ``P = X.real ** 2 + X.imag ** 2``, ``P *= scale``,
    ``P[:, 1:one_sided_end] *= 2``: ``bands[:, b] = P[:, starts[b]:stops[b]].sum(axis=1)`` and
    ``peak = np.argmax(P[:, peak_lo:peak_hi], axis=1)`` (the first of equal maxima), without the (W, bins) P."""
    nw, nb = X.shape
    bands = np.empty((nw, starts.shape[0]))
    peak = np.empty(nw, np.int64)
    p = np.empty(nb)
    for j in range(nw):
        for i in range(nb):
            re = X[j, i].real
            im = X[j, i].imag
            v = (re * re + im * im) * scale
            if 1 <= i < one_sided_end:
                v = v * 2.0
            p[i] = v
        for b in range(starts.shape[0]):
            # P[:, sel] (a boolean column selection) is laid out column-major, so NumPy's sum over its rows adds
            # bin after bin: sequential, not pairwise
            acc = 0.0
            for i in range(starts[b], stops[b]):
                acc += p[i]
            bands[j, b] = acc
        best = peak_lo
        for i in range(peak_lo + 1, peak_hi):
            if p[i] > p[best]:
                best = i
        peak[j] = best - peak_lo
    return bands, peak
