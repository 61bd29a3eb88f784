"""SciPy's ``sosfilt`` and ``sosfiltfilt`` along axis 0, bit for bit, without the input copy.

``scipy.signal.sosfilt`` first copies its input into a C-ordered (signals, samples) array that it filters in
place; for a 24 h (N, 3) accelerometer series that transposing copy costs more than the filter (profile of a
24 h ``classify_recording``: 0.40 of the 0.69 s in the six ``sosfilt`` calls). :func:`sosfilt` reads the input
where it lies and writes the output once, into the same memory layout SciPy returns (a transposed C-ordered
(signals, samples) array), so every later reduction over it sums in the same order. The arithmetic is
SciPy's ``_sosfilt`` loop (direct form II transposed per section; SciPy 1.17
``scipy/signal/_sosfilt.pyx``) in the same order without fused multiply-adds (numba's default, like SciPy's
baseline-x86-64 build), so the results are identical, which ``tests/estimators/activity/test_sosfilt.py``
checks on real and random data. :func:`sosfiltfilt` is SciPy's ``sosfiltfilt`` (odd padding, steady-state
start, forward then backward; its padding written out with NumPy, no private SciPy module) with its two
``sosfilt`` calls replaced. The shapes the activity stage filters
(one section or two, one signal or three axes) keep the sections' state in local variables instead of the
state array: the same statements in the same order, without a store and a load in every sample's recurrence
(a 24 h day's gravity filter 0.048 instead of 0.095 s).
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy import signal


@njit(cache=True, nogil=True, inline="always")
def _section(b0, b1, b2, a1, a2, x, z0, z1):
    """One sample through one section, SciPy's three statements in their order: (output, new z0, new z1)."""
    y = b0 * x + z0
    return y, b1 * x - a1 * y + z1, b2 * x - a2 * y


@njit(cache=True, nogil=True)
def _sosfilt_columns(sos, x, zi, out):
    """``out[i, n]`` = section cascade of ``x[n, i]``; ``zi`` (signals, sections, 2) updated in place. The
    signals advance together, sample by sample: their recurrences are independent, so the core overlaps them
    (each one alone is bound by the latency of its multiply-add chain); each signal's operations and their
    order are SciPy's."""
    n_sections = sos.shape[0]
    k = x.shape[1]
    N = x.shape[0]
    if n_sections == 1 and k == 3:
        # the activity stage's gravity filter (one elliptic section, three axes): the same statements with the
        # state in registers. Through the arrays, every sample's recurrence went through a store and a load
        # (~2× the time: 0.095 s for a 24 h day); the operations and their order are unchanged.
        b0, b1, b2, a1, a2 = sos[0, 0], sos[0, 1], sos[0, 2], sos[0, 4], sos[0, 5]
        u0, u1, v0, v1, w0, w1 = zi[0, 0, 0], zi[0, 0, 1], zi[1, 0, 0], zi[1, 0, 1], zi[2, 0, 0], zi[2, 0, 1]
        for n in range(N):
            out[0, n], u0, u1 = _section(b0, b1, b2, a1, a2, x[n, 0], u0, u1)
            out[1, n], v0, v1 = _section(b0, b1, b2, a1, a2, x[n, 1], v0, v1)
            out[2, n], w0, w1 = _section(b0, b1, b2, a1, a2, x[n, 2], w0, w1)
        zi[0, 0, 0], zi[0, 0, 1], zi[1, 0, 0], zi[1, 0, 1], zi[2, 0, 0], zi[2, 0, 1] = u0, u1, v0, v1, w0, w1
        return
    if n_sections == 2 and k in (1, 3):
        # two sections over one signal (the step band-pass) or three axes, interleaved (the window model's band-pass)
        b0, b1, b2, a1, a2 = sos[0, 0], sos[0, 1], sos[0, 2], sos[0, 4], sos[0, 5]
        c0, c1, c2, d1, d2 = sos[1, 0], sos[1, 1], sos[1, 2], sos[1, 4], sos[1, 5]
        u0, u1, v0, v1 = zi[0, 0, 0], zi[0, 0, 1], zi[0, 1, 0], zi[0, 1, 1]
        if k == 1:
            for n in range(N):
                y, u0, u1 = _section(b0, b1, b2, a1, a2, x[n, 0], u0, u1)
                out[0, n], v0, v1 = _section(c0, c1, c2, d1, d2, y, v0, v1)
        else:
            p0, p1, q0, q1 = zi[1, 0, 0], zi[1, 0, 1], zi[1, 1, 0], zi[1, 1, 1]
            r0, r1, s0, s1 = zi[2, 0, 0], zi[2, 0, 1], zi[2, 1, 0], zi[2, 1, 1]
            for n in range(N):
                ya, u0, u1 = _section(b0, b1, b2, a1, a2, x[n, 0], u0, u1)
                yb, p0, p1 = _section(b0, b1, b2, a1, a2, x[n, 1], p0, p1)
                yc, r0, r1 = _section(b0, b1, b2, a1, a2, x[n, 2], r0, r1)
                out[0, n], v0, v1 = _section(c0, c1, c2, d1, d2, ya, v0, v1)
                out[1, n], q0, q1 = _section(c0, c1, c2, d1, d2, yb, q0, q1)
                out[2, n], s0, s1 = _section(c0, c1, c2, d1, d2, yc, s0, s1)
            zi[1, 0, 0], zi[1, 0, 1], zi[1, 1, 0], zi[1, 1, 1] = p0, p1, q0, q1
            zi[2, 0, 0], zi[2, 0, 1], zi[2, 1, 0], zi[2, 1, 1] = r0, r1, s0, s1
        zi[0, 0, 0], zi[0, 0, 1], zi[0, 1, 0], zi[0, 1, 1] = u0, u1, v0, v1
        return
    for n in range(N):
        for i in range(k):
            x_cur = x[n, i]
            for s in range(n_sections):
                x_new = sos[s, 0] * x_cur + zi[i, s, 0]
                zi[i, s, 0] = sos[s, 1] * x_cur - sos[s, 4] * x_new + zi[i, s, 1]
                zi[i, s, 1] = sos[s, 2] * x_cur - sos[s, 5] * x_new
                x_cur = x_new
            out[i, n] = x_cur


def sosfilt(sos: np.ndarray, x: np.ndarray, zi: np.ndarray | None = None, order: str = "scipy"):
    """``scipy.signal.sosfilt(sos, x, axis=0, zi=zi)`` for float64 ``x`` of shape (N,) or (N, k): ``y``, or
    ``(y, zf)`` when ``zi`` is given (``zi`` shaped as SciPy wants it: (sections, 2) or (sections, 2, k)).
    ``order="C"``: ``y`` in C order (the same values; SciPy's layout is the transpose of a C-ordered (k, N), which
    a caller walking the samples row by row would otherwise copy)."""
    sos = np.asarray(sos, dtype=np.float64)
    x = np.asarray(x)
    if x.dtype != np.float64 or x.ndim not in (1, 2) or sos.ndim != 2 or sos.shape[1] != 6:
        return signal.sosfilt(sos, x, axis=0, zi=zi)
    n_sections = sos.shape[0]
    x2 = x[:, None] if x.ndim == 1 else x
    k = x2.shape[1]
    if zi is None:
        z = np.zeros((k, n_sections, 2))
    else:
        zi = np.asarray(zi, dtype=np.float64)
        want = (n_sections, 2) if x.ndim == 1 else (n_sections, 2, k)
        if zi.shape != want:
            raise ValueError(f"zi must be of shape {want}, got {zi.shape}")
        # a copy: the kernel updates the state in place, and the caller's zi must stay as it was (for one signal
        # the moved view is already contiguous, and ascontiguousarray would hand the kernel the caller's array)
        z = np.array(np.moveaxis(zi.reshape(n_sections, 2, -1), (0, 1), (-2, -1)), order="C", copy=True)
    if order == "C" and x.ndim == 2:
        y = np.empty((x2.shape[0], k))
        _sosfilt_columns(sos, x2, z, y.T)         # out[i, n] is y[n, i]
    else:
        out = np.empty((k, x2.shape[0]))
        _sosfilt_columns(sos, x2, z, out)
        y = out[0] if x.ndim == 1 else out.T
    if zi is None:
        return y
    zf = np.moveaxis(z, (-2, -1), (0, 1))
    return y, (zf[:, :, 0] if x.ndim == 1 else zf)


def sosfiltfilt(sos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0)`` (default odd padding) for float64 (N,) or (N, k) ``x``."""
    sos = np.asarray(sos, dtype=np.float64)
    x = np.asarray(x)
    if x.dtype != np.float64 or x.ndim not in (1, 2):
        return signal.sosfiltfilt(sos, x, axis=0)
    n_sections = sos.shape[0]
    ntaps = 2 * n_sections + 1
    ntaps -= min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum())
    edge = 3 * ntaps                             # SciPy's default padlen
    if x.shape[0] <= edge:
        raise ValueError(f"The length of the input vector x must be greater than padlen, which is {edge}.")
    ext = _odd_ext(x, edge)
    zi = signal.sosfilt_zi(sos)
    zi_shape = [1] * x.ndim
    zi_shape[0] = 2
    zi = zi.reshape([n_sections] + zi_shape)
    x_0 = ext[:1]
    y, _ = sosfilt(sos, ext, zi=zi * x_0)
    y_0 = y[-1:]
    y, _ = sosfilt(sos, y[::-1], zi=zi * y_0)
    y = y[::-1]
    return y[edge:-edge]


def _odd_ext(x: np.ndarray, n: int) -> np.ndarray:
    """The odd extension by ``n`` samples at both ends along axis 0, as ``scipy.signal.sosfiltfilt`` pads (SciPy's
    ``odd_ext``, the same operations: ``2 x[0] - x[n:0:-1]`` before, ``2 x[-1] - x[-2:-(n+2):-1]`` after)."""
    return np.concatenate((2 * x[:1] - x[n:0:-1], x, 2 * x[-1:] - x[-2:-(n + 2):-1]), axis=0)

