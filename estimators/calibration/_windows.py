"""Automatic segmentation of a calibration trial (spec §2.2 "Segmentation" [CHOICE], §5.2 S2).

Quiet standing = the longest run where every IMU is still (smoothed gyro norm < 0.1 rad/s and
| |a| − g | < 0.3 m/s²). Movement is labelled per sample from 1-s smoothed gyro norms of the
thigh, shank and foot of each side: one leg moving while the other stands still = hip
flexion/extension of that leg; both legs moving = walking. Runs shorter than 1 s are absorbed by
their neighbours. Repetitions / swings are positive peaks of the angular velocity projected on
the main rotation axis.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import find_peaks

from stridelab.estimators.calibration._types import LEG_SEGMENTS, SIDES, CalibrationParams, CalibrationWindows


def smoothed_norm(x: np.ndarray, n: int) -> np.ndarray:
    """Moving average (``n`` samples, centred) of the row norms of ``x``; NaN rows count as 0."""
    v = np.linalg.norm(np.nan_to_num(np.asarray(x, float)), axis=1)
    return uniform_filter1d(v, size=max(int(n), 1), mode="nearest")


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open ``[start, end)`` runs of True in a boolean array."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(d[::2], d[1::2])]


def standing_mask(acc: Mapping[str, np.ndarray], gyr: Mapping[str, np.ndarray], *, sampling_rate_hz: float,
                  params: CalibrationParams = CalibrationParams()) -> np.ndarray:
    """(N,) True where every IMU is quiet (spec §2.2 thresholds, 0.25-s smoothing): smoothed |ω| below
    ``stand_gyr_rad_s`` and |a| within ``stand_acc_m_s2`` of the IMU's own median |a| while its gyro is
    quiet (g as that accelerometer reads it, within 3 × ``stand_acc_m_s2`` of ``gravity_m_s2``)."""
    n_s = int(round(0.25 * sampling_rate_hz))
    mask = None
    for p in gyr:
        g = smoothed_norm(gyr[p], n_s) < params.stand_gyr_rad_s
        a_n = uniform_filter1d(np.linalg.norm(np.nan_to_num(acc[p]), axis=1), n_s, mode="nearest")
        # |a| at rest as this accelerometer reads it (scale-factor / bias errors of a few 0.1 m/s² must
        # not hide quiet standing; the QC flags |a| far from g separately)
        g_ref = float(np.median(a_n[g])) if np.any(g) else params.gravity_m_s2
        if abs(g_ref - params.gravity_m_s2) > 3 * params.stand_acc_m_s2:
            g_ref = params.gravity_m_s2
        a = np.abs(a_n - g_ref) < params.stand_acc_m_s2
        m = g & a
        mask = m if mask is None else mask & m
    return mask


def _label_runs(labels: np.ndarray, min_len: int) -> list[tuple[int, int, int]]:
    """Runs ``(start, end, label)`` after absorbing runs shorter than ``min_len`` into the longer neighbour."""
    edges = np.flatnonzero(np.diff(labels)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [labels.size]])
    rr = [[int(a), int(b), int(labels[a])] for a, b in zip(starts, ends)]
    changed = True
    while changed and len(rr) > 1:
        changed = False
        lens = [b - a for a, b, _ in rr]
        i = int(np.argmin(lens))
        if lens[i] < min_len:
            left = rr[i - 1] if i > 0 else None
            right = rr[i + 1] if i + 1 < len(rr) else None
            tgt = left if (right is None or (left is not None and left[1] - left[0] >= right[1] - right[0])) else right
            tgt[0], tgt[1] = min(tgt[0], rr[i][0]), max(tgt[1], rr[i][1])
            del rr[i]
            # merge equal neighbours
            merged = [rr[0]]
            for r in rr[1:]:
                if r[2] == merged[-1][2]:
                    merged[-1][1] = r[1]
                else:
                    merged.append(r)
            rr = merged
            changed = True
    return [(a, b, c) for a, b, c in rr]


#: per-sample activity labels
REST, FE_LEFT, FE_RIGHT, WALK = 0, 1, 2, 3


def _hysteresis(x: np.ndarray, high: float, low_fraction: float = 0.5) -> np.ndarray:
    """``x > high``, with the gaps between such runs filled where ``x`` stays above ``low_fraction·high``
    (a few small hip FE repetitions do not split the movement into pieces; the edges do not move)."""
    hi = x > high
    out = hi.copy()
    for a, b in runs(x > low_fraction * high):
        idx = np.flatnonzero(hi[a:b])
        if idx.size:
            out[a + idx[0]:a + idx[-1] + 1] = True
    return out


def activity_labels(gyr: Mapping[str, np.ndarray], *, sampling_rate_hz: float,
                    params: CalibrationParams = CalibrationParams()) -> np.ndarray:
    """(N,) int8 labels REST / FE_LEFT / FE_RIGHT / WALK from the leg IMUs (majority of a side's sensors;
    a sensor is active from where its 1-s smoothed gyro norm exceeds ``active_gyr_rad_s`` while it
    stays above half of that)."""
    n1 = int(round(1.0 * sampling_rate_hz))
    n = len(next(iter(gyr.values())))
    active = {}
    for side in SIDES:
        votes = [_hysteresis(smoothed_norm(gyr[f"{seg}_{side}"], n1), params.active_gyr_rad_s)
                 for seg in LEG_SEGMENTS if f"{seg}_{side}" in gyr]
        if votes:
            active[side] = np.sum(votes, axis=0) * 2 > len(votes)   # strict majority
        else:
            active[side] = np.zeros(n, bool)
    lab = np.full(n, REST, np.int8)
    lab[active["left"] & ~active["right"]] = FE_LEFT
    lab[active["right"] & ~active["left"]] = FE_RIGHT
    lab[active["left"] & active["right"]] = WALK
    return lab


def detect_calibration_windows(acc: Mapping[str, np.ndarray], gyr: Mapping[str, np.ndarray], *,
                               sampling_rate_hz: float, params: CalibrationParams = CalibrationParams()
                               ) -> CalibrationWindows:
    """Quiet standing, hip FE per leg and straight walking in a calibration trial (``source="auto"``).

    acc, gyr: placement -> (N, 3) arrays on one time grid (m/s², rad/s). A window is ``None`` (or
    absent from ``hip_fe``) when not found; standing shorter than ``min_standing_s`` is not reported.
    """
    if sampling_rate_hz <= 0:
        raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
    if not gyr:
        return CalibrationWindows()
    stand = standing_mask(acc, gyr, sampling_rate_hz=sampling_rate_hz, params=params)
    st = [r for r in runs(stand) if r[1] - r[0] >= params.min_standing_s * sampling_rate_hz]
    standing = max(st, key=lambda r: r[1] - r[0]) if st else None
    legs = {p: g for p, g in gyr.items() if p.split("_")[0] in LEG_SEGMENTS}
    fe, walking = {}, None
    if legs:
        lab = activity_labels(legs, sampling_rate_hz=sampling_rate_hz, params=params)
        rr = _label_runs(lab, int(round(1.0 * sampling_rate_hz)))
        best = {}
        for a, b, c in rr:
            if c != REST and (c not in best or b - a > best[c][1] - best[c][0]):
                best[c] = (a, b)
        if FE_LEFT in best:
            fe["left"] = best[FE_LEFT]
        if FE_RIGHT in best:
            fe["right"] = best[FE_RIGHT]
        walking = best.get(WALK)
    return CalibrationWindows(standing=standing, hip_fe=fe, walking=walking, source="auto")


def first_quiet_standing(acc: Mapping[str, np.ndarray], gyr: Mapping[str, np.ndarray], *, sampling_rate_hz: float,
                         params: CalibrationParams = CalibrationParams()) -> tuple[int, int] | None:
    """The first ``[start, end)`` run where every IMU is quiet for ≥ ``min_standing_s`` (e.g. the
    standing at the start of a walking trial, for the quiet-standing offset removal of thesis ch. 8),
    or ``None``. Same thresholds as :func:`standing_mask`."""
    if sampling_rate_hz <= 0:
        raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
    if not gyr:
        return None
    stand = standing_mask(acc, gyr, sampling_rate_hz=sampling_rate_hz, params=params)
    st = [r for r in runs(stand) if r[1] - r[0] >= params.min_standing_s * sampling_rate_hz]
    return st[0] if st else None


def count_cycles(gyr_move: np.ndarray, axis_S: np.ndarray, *, sampling_rate_hz: float,
                 prominence_rad_s: float = 0.5, min_peak_fraction: float = 0.1,
                 min_period_fraction: float = 0.6) -> int:
    """Positive peaks of the angular velocity on ``axis_S`` (hip flexion, or a leg swing in walking).

    A peak needs prominence ≥ ``prominence_rad_s`` and height ≥ ``min_peak_fraction`` of the largest
    peak. Peaks closer than ``min_period_fraction`` of the movement period (median interval of the
    peaks at least half as high as the largest; 0.3 s when fewer than two) keep only the higher one:
    one peak per repetition or swing. This counts the slow swings of gait initiation and of the short
    closing step (a fraction of a full swing's rate) and rejects the smaller stance-phase bumps half a
    stride away from a swing.
    """
    w = np.nan_to_num(np.asarray(gyr_move, float)) @ np.asarray(axis_S, float)
    w = np.concatenate([[0.0], w, [0.0]])          # a peak cut by the window edge still counts
    if w.size < 5 or not np.any(w > 0):
        return 0
    d0 = max(1, int(0.3 * sampling_rate_hz))
    pk, _ = find_peaks(w, prominence=prominence_rad_s, distance=d0)
    if not pk.size:
        return 0
    big = pk[w[pk] >= 0.5 * w[pk].max()]
    if big.size >= 2:
        period = float(np.median(np.diff(big)))
        pk, _ = find_peaks(w, prominence=prominence_rad_s, distance=max(d0, int(min_period_fraction * period)))
    pk = pk[w[pk] >= min_peak_fraction * w[pk].max()]
    return int(pk.size)


def count_repetitions(gyr_move: np.ndarray, axis_S: np.ndarray, *, sampling_rate_hz: float,
                      min_amplitude_rad: float = 0.1, min_fraction: float = 0.2) -> int:
    """Hip flexion/extension repetitions: maxima of the flexion angle (angular velocity on ``axis_S``
    integrated, linear trend removed: a constant gyro bias does not count) with a prominence of at
    least ``min_amplitude_rad`` and ``min_fraction`` of the largest one.

    One maximum per flexion/extension cycle: lifting the leg into the mean posture before the first
    repetition and lowering it after the last are part of those repetitions, not extra ones (peaks
    of the angular velocity would count them). Give a window that includes some rest before and after
    the movement: a maximum at the window edge is not counted.
    """
    from scipy.signal import detrend
    w = np.nan_to_num(np.asarray(gyr_move, float)) @ np.asarray(axis_S, float)
    if w.size < 5:
        return 0
    ang = detrend(np.cumsum(w) / sampling_rate_hz)
    pk, pr = find_peaks(ang, prominence=min_amplitude_rad, distance=max(1, int(0.3 * sampling_rate_hz)))
    if not pk.size:
        return 0
    return int(np.sum(pr["prominences"] >= min_fraction * pr["prominences"].max()))
