"""Numba kernels: one pass over the samples for calibration, per-second statistics and rotation."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def second_sums(acc, fs, n_sec):
    """Per-second sum and sum of squares of each axis (n_sec, 3) and per-axis min/max plus how many samples
    sit at them (saturation check)."""
    s = np.zeros((n_sec, 3))
    s2 = np.zeros((n_sec, 3))
    cnt = np.zeros(n_sec)
    mn = np.full(3, np.inf)
    mx = np.full(3, -np.inf)
    inv = 1.0 / fs
    for i in range(acc.shape[0]):
        k = int(i * inv)
        cnt[k] += 1.0
        for j in range(3):
            v = acc[i, j]
            s[k, j] += v
            s2[k, j] += v * v
            if v < mn[j]:
                mn[j] = v
            if v > mx[j]:
                mx[j] = v
    n_at = 0
    for i in range(acc.shape[0]):
        for j in range(3):
            v = acc[i, j]
            if v == mn[j] or v == mx[j]:
                n_at += 1
                break
    return s, s2, cnt, mn, mx, n_at


@njit(cache=True)
def calibrate_norm(acc, out, scale, offset, gain, fs, n_sec):
    """acc_g = (acc · scale − offset) · gain into ``out`` (N, 3), which may be ``acc`` itself (each element is read
    before it is written); ‖acc_g‖ − 1 per sample; per-second mean/std of ‖acc_g‖."""
    n = acc.shape[0]
    mag = np.empty(n)
    s = np.zeros(n_sec)
    s2 = np.zeros(n_sec)
    c = np.zeros(n_sec)
    inv = 1.0 / fs
    for i in range(n):
        q = 0.0
        for j in range(3):
            v = (acc[i, j] * scale - offset[j]) * gain[j]
            out[i, j] = v
            q += v * v
        m = np.sqrt(q)
        mag[i] = m - 1.0
        k = int(i * inv)
        s[k] += m
        s2[k] += m * m
        c[k] += 1.0
    mean = s / np.maximum(c, 1.0)
    std = np.sqrt(np.maximum(s2 / np.maximum(c, 1.0) - mean * mean, 0.0))
    return mag, mean, std


@njit(cache=True)
def rotate_inplace(x, R, i0, i1):
    """x[i0:i1] = x[i0:i1] @ R.T in place."""
    for i in range(i0, i1):
        a, b, c = x[i, 0], x[i, 1], x[i, 2]
        x[i, 0] = R[0, 0] * a + R[0, 1] * b + R[0, 2] * c
        x[i, 1] = R[1, 0] * a + R[1, 1] * b + R[1, 2] * c
        x[i, 2] = R[2, 0] * a + R[2, 1] * b + R[2, 2] * c


@njit(cache=True)
def second_mean3(x, fs, n_sec):
    """Per-second mean of (N, 3)."""
    s = np.zeros((n_sec, 3))
    c = np.zeros(n_sec)
    inv = 1.0 / fs
    for i in range(x.shape[0]):
        k = int(i * inv)
        c[k] += 1.0
        for j in range(3):
            s[k, j] += x[i, j]
    for k in range(n_sec):
        if c[k] > 0:
            for j in range(3):
                s[k, j] /= c[k]
    return s


@njit(cache=True)
def theta_deg(gv, dc):
    """Eq. 54 per sample: degrees(arccos(clip(GA_v / dc, −1, 1)))."""
    out = np.empty(gv.shape[0])
    r = 180.0 / np.pi
    for i in range(gv.shape[0]):
        v = gv[i] / dc
        if v > 1.0:
            v = 1.0
        elif v < -1.0:
            v = -1.0
        out[i] = np.arccos(v) * r
    return out


@njit(cache=True)
def theta_direction_deg(ga):
    """θ as the angle (deg) between each GA sample (N, 3) and the sensor y axis: arccos(GA_y / ‖GA‖)
    (``ActivityParams.theta_mode="direction"``); 0 where ‖GA‖ = 0."""
    c = np.empty(ga.shape[0])
    for i in range(ga.shape[0]):
        nrm = np.sqrt(ga[i, 0] * ga[i, 0] + ga[i, 1] * ga[i, 1] + ga[i, 2] * ga[i, 2])
        c[i] = ga[i, 1] / nrm if nrm > 0.0 else 1.0
    return theta_deg(c, 1.0)


@njit(cache=True)
def second_mean1(x, fs, n_sec):
    s = np.zeros(n_sec)
    c = np.zeros(n_sec)
    inv = 1.0 / fs
    for i in range(x.shape[0]):
        k = int(i * inv)
        c[k] += 1.0
        s[k] += x[i]
    return s / np.maximum(c, 1.0)


@njit(cache=True)
def vertical_projection(acc, ga):
    """a_v = acc · GA / ‖GA‖ − 1 per sample (raw form of Eq. 55, in g)."""
    n = acc.shape[0]
    out = np.empty(n)
    for i in range(n):
        q = ga[i, 0] * ga[i, 0] + ga[i, 1] * ga[i, 1] + ga[i, 2] * ga[i, 2]
        if q > 1e-12:
            out[i] = (acc[i, 0] * ga[i, 0] + acc[i, 1] * ga[i, 1] + acc[i, 2] * ga[i, 2]) / np.sqrt(q) - 1.0
        else:
            out[i] = 0.0
    return out


@njit(cache=True)
def acf_at_lag(v, lag, eps):
    """Per row of ``v`` (W, n): Σ (v_i − v̄)(v_{i+k} − v̄) / max(Σ (v_i − v̄)², eps) at the row's lag k (0 unless
    0 < k < n). ``stridelab.estimators.activity.windows`` step and stride regularity."""
    w, n = v.shape
    out = np.zeros(w)
    for r in range(w):
        k = lag[r]
        if k <= 0 or k >= n:
            continue
        m = 0.0
        for i in range(n):
            m += v[r, i]
        m /= n
        den = 0.0
        for i in range(n):
            d = v[r, i] - m
            den += d * d
        num = 0.0
        for i in range(n - k):
            num += (v[r, i] - m) * (v[r, i + k] - m)
        out[r] = num / max(den, eps)
    return out


@njit(cache=True)
def step_threshold_kernel(svm, w, floor_g, scale):
    """``max(floor_g, scale · √max(uniform_filter1d(svm², w, mode="nearest"), 0))`` per sample, in one pass and with
    SciPy's operations: ``ndimage.uniform_filter1d``'s running sum of the squares (kept undivided, ``sum +=
    entering − leaving``, each output that sum / w; edges repeat the first and last sample), then NumPy's
    ``maximum`` (``a if a >= b else b``) and ``sqrt``. Equal bit for bit to the NumPy/SciPy expression (tested)."""
    n = svm.shape[0]
    out = np.empty(n)
    if n == 0:
        return out
    s1 = w // 2
    s2 = w - s1 - 1
    tmp = 0.0
    for k in range(w):
        j = min(max(k - s1, 0), n - 1)
        tmp += svm[j] * svm[j]
    for i in range(n):
        if i > 0:
            a = svm[min(i + s2, n - 1)]
            b = svm[max(i - 1 - s1, 0)]
            tmp += a * a - b * b
        v = tmp / w
        v = v if v >= 0.0 else 0.0
        y = scale * np.sqrt(v)
        out[i] = floor_g if floor_g >= y else y
    return out


@njit(cache=True)
def prominent_peaks(x, peaks, pmin):
    """Which ``peaks`` have a topographic prominence of at least ``pmin`` (``scipy.signal.peak_prominences`` with
    no window, then ``pmin <= prominence``, as ``find_peaks(prominence=pmin)`` selects). Each side's search for the
    lowest point stops as soon as it is low enough, instead of running to the next higher sample (for the
    day's highest peaks, the whole day): the same answer, since the prominence only grows along the search."""
    keep = np.zeros(peaks.shape[0], dtype=np.bool_)
    n = x.shape[0]
    for r in range(peaks.shape[0]):
        pk = peaks[r]
        v = x[pk]
        ok = False
        m = v
        i = pk
        while i >= 0 and x[i] <= v:
            if x[i] < m:
                m = x[i]
                if pmin <= v - m:
                    ok = True
                    break
            i -= 1
        if not ok and not (pmin <= v - m):
            continue
        ok = False
        m = v
        i = pk
        while i < n and x[i] <= v:
            if x[i] < m:
                m = x[i]
                if pmin <= v - m:
                    ok = True
                    break
            i += 1
        keep[r] = ok or (pmin <= v - m)
    return keep
