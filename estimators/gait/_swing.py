"""Batch completion of Algorithm-1 events on the swings of the zero-velocity mask (issue 18: paretic feet).

Algorithm 1 (``_events``) needs a push-off that passes the threshold T (TC) and a toes-up heel strike (IC). A paretic
foot may lift almost flat (no push-off), swing with the toes down (drop foot) and land flat or on the forefoot: TCs are
then missed, strict alternation drops the next IC, or the IC is put on the swing's pitch maximum (mid-swing, too
early) or in the following stance (too late). With the stance mask of the batch kinematics every swing is known:

    swing = a moving run [e, f) of the zero-velocity mask between two still runs, n_ref ≤ f − e ≤ 3 s; one swing
    is one step: one TC (the first Algorithm-1 TC; later pitch minima are the swing's, dropped) and one IC
    (below); a swing with two toes-up heel-strike ICs (s ≥ s_f + M) holds two steps (the mask missed a stance)
    and is left as Algorithm 1 found it                                                                  (W0)
    (W1) no TC in [e, f): TC = argmin s over [e, e + ⌈(f − e)/2⌉) (the lift's pitch minimum, refined to the
         toe-off by T1 like Algorithm 1's TCs).
    (W2) the swing's IC: Algorithm 1's last toes-up IC (s_IC ≥ s_f + M, a heel strike) after the TC and before
         f + n_ref; otherwise the start j of the last
         monotone run of s before f (the loading rotation about the heel or the ball ends at foot flat, its start
         is the contact) when f − j ≤ MAX_LOADING_S; otherwise (flat contact: no loading rotation) Algorithm 1's IC,
         or argmax s over (TC + n_ref, f] without one.
    (W3) after a heel-strike peak, if s falls to a minimum s_m ≤ s_IC − M and rises again by ≥ M before
         f + n_ref, the foot landed toes-down at that minimum (the heel drops after it): IC = argmin.
    (W4) with the gyroscope norm |ω|: if between the lift e and the TC (pitch minimum) |ω| falls below f_T1 = 0.2
         of its maximum since e after the foot has plantarflexed by ≥ M, and s later in the swing falls by ≥ M
         more, the push-off ended there and the further plantarflexion is the swing (drop foot): TC = that sample (then refined by T1). A normal push-off
         accelerates the rotation up to the toe-off, so |ω| never nearly stops before the pitch minimum.
M = ``IcTcParams.flat_lift_margin`` (0.05 ≈ 3°, R4's margin: a few times the stance pitch noise) and n_ref = the
refractory period: both a priori, none fitted. Strides keep needing one TC then one IC between mid-stances (K2).
Algorithm 1's events are kept unless W2–W4 say otherwise; f_T1 is T1's onset fraction (``FootParams``).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from estimators.gait._events import GaitEvents

__all__ = ["complete_swing_events", "swing_runs", "MAX_LOADING_S"]

#: longest loading rotation (contact -> foot flat): loading response ≈ 10-12 % of the gait cycle (Perry & Burnfield
#: 2010) of the slowest strides walked (≈ 2.5 s); a priori
MAX_LOADING_S = 0.3


def swing_runs(still: np.ndarray, *, min_samples: int, max_samples: int) -> np.ndarray:
    """(K, 2) [e, f): moving runs of the stance mask bounded by still samples on both sides (W0)."""
    m = np.asarray(still, bool)
    d = np.diff(np.concatenate([[1], m.astype(np.int8), [1]]))
    starts, ends = np.flatnonzero(d == -1), np.flatnonzero(d == 1)
    keep = (starts > 0) & (ends < len(m)) & (ends - starts >= min_samples) & (ends - starts <= max_samples)
    return np.column_stack([starts[keep], ends[keep]]).astype(np.int64).reshape(-1, 2)


def _landing(s: np.ndarray, lo: int, f: int) -> int:
    """(W2) the start of the last monotone run of s before the stance starts at f (the loading rotation: falling
    after a heel strike, rising after a forefoot contact), i.e. the last pitch extremum in [lo, f]; argmax of s
    over [lo, f] when the run reaches back to lo (no extremum: flat contact). Steps smaller than 5 % of the largest
    step in [lo, f] count as no slope (stance noise at the end of the run)."""
    seg = s[lo:f + 1]
    ds = np.diff(seg)
    if len(ds) < 2:
        return int(lo + np.argmax(seg))
    eps = 0.05 * np.max(np.abs(ds))
    i = len(ds) - 1
    while i >= 0 and abs(ds[i]) < eps:
        i -= 1
    if i < 0:
        return int(lo + np.argmax(seg))
    d = np.sign(ds[i])
    end = i + 1
    while i >= 0 and not (np.sign(ds[i]) == -d and abs(ds[i]) >= eps):
        i -= 1
    if i < 0:
        return int(lo + np.argmax(seg))
    part = seg[i + 1:end + 1]
    return int(lo + i + 1 + (np.argmin(part) if d > 0 else np.argmax(part)))


def _rotation_stop(w: np.ndarray, s: np.ndarray, e: int, j: int, f: int, frac: float, margin: float):
    """(W4) first sample in (e, j) where |ω| falls below ``frac`` of its running maximum since the lift e, after the
    foot has plantarflexed by ≥ ``margin`` (s fell by that much) and before the TC j, when s later in the swing
    (before f) falls a further ≥ ``margin`` (a real second plantarflexion, not the end of the push-off's own
    deceleration); None otherwise."""
    peak = 0.0
    for k in range(e, j):
        if not np.isfinite(w[k]):
            return None
        peak = max(peak, w[k])
        if w[k] < frac * peak and s[k] <= s[e] - margin:
            return k if s[k] - np.min(s[k:f]) >= margin else None
    return None


def complete_swing_events(ev: GaitEvents, s: np.ndarray, still: np.ndarray, *, sampling_rate_hz: float,
                          max_swing_s: float = 3.0, gyr_norm: np.ndarray | None = None,
                          onset_fraction: float = 0.2) -> GaitEvents:
    """(W0)–(W3) on the events ``ev`` of pitch signal ``s`` with the stance mask ``still`` (module docstring).
    Added / moved events get a detection index = event + 1 (a pitch extremum, refined by T1 like Algorithm 1's)."""
    fs = float(sampling_rate_hz)
    p = ev.params
    n_ref = max(1, int(round(p.refractory_s * fs)))
    max_load = int(round(MAX_LOADING_S * fs))
    onset = float(onset_fraction)
    margin = p.flat_lift_margin
    s = np.asarray(s, float)
    n = len(s)
    tc = list(zip(ev.tc_idx.tolist(), ev.tc_detect_idx.tolist()))
    ic = list(zip(ev.ic_idx.tolist(), ev.ic_detect_idx.tolist()))
    sw = swing_runs(still, min_samples=n_ref, max_samples=int(max_swing_s * fs))
    finite = np.isfinite(s)
    for k, (e, f) in enumerate(sw):
        nxt = sw[k + 1, 0] if k + 1 < len(sw) else n
        if not finite[e:f].all():
            continue
        in_sw = [t for t in tc if e - n_ref <= t[0] < f]
        if f < n and len([t for t in ic if e < t[0] < f and s[t[0]] >= s[f] + margin]) > 1:
            continue                                       # two heel strikes: more than one step, a missed stance
        for t in in_sw[1:]:                                # one step has one TC: later pitch minima are the swing's
            tc.remove(t)
        in_sw = in_sw[:1]
        if in_sw:
            t_tc = in_sw[0][0]
        else:                                                         # (W1)
            half = e + int(np.ceil((f - e) / 2))
            t_tc = int(e + np.argmin(s[e:half]))
            in_sw = [(t_tc, t_tc + 1)]
            tc.append(in_sw[0])
        if gyr_norm is not None and t_tc > e + 2:                      # (W4) push-off ended before a drop-foot swing
            stop = _rotation_stop(gyr_norm, s, e, t_tc, f, onset, margin)
            if stop is not None:
                tc.remove(in_sw[0])
                t_tc = stop
                tc.append((t_tc, t_tc + 1))
        lo = t_tc + n_ref
        if lo >= f:
            continue
        cand = [t for t in ic if t_tc < t[0] < nxt]
        heel = [t for t in cand if t[0] < f + n_ref and s[t[0]] >= s[min(f, n - 1)] + margin]
        alg1 = heel[-1] if heel else (cand[0] if cand and cand[0][0] < f + n_ref else None)
        for c in cand:                                     # one step has one IC: the others go
            ic.remove(c)
        if alg1 is not None and s[alg1[0]] >= s[f] + margin:         # a toes-up peak above the stance: heel strike
            t_ic = alg1[0]
            hi = min(f + n_ref, n)
            seg = s[t_ic + 1:hi]                                       # (W3) forefoot landing after that peak
            if len(seg) > 1:
                j = int(np.argmin(seg))
                if seg[j] <= s[t_ic] - margin and j + 1 < len(seg) and np.max(seg[j + 1:]) >= seg[j] + margin:
                    t_ic = t_ic + 1 + j
        else:                                                          # (W2)
            j = _landing(s, lo, f)
            if f - j <= max_load:
                t_ic = j
            elif alg1 is not None:
                t_ic = alg1[0]
            else:
                t_ic = int(lo + np.argmax(s[lo:f + 1]))
        ic.append((t_ic, t_ic + 1) if alg1 is None or t_ic != alg1[0] else alg1)
    tc.sort()
    ic.sort()
    a = lambda x, i: np.array([v[i] for v in x], np.int64)       # noqa: E731
    return replace(ev, tc_idx=a(tc, 0), tc_detect_idx=a(tc, 1), ic_idx=a(ic, 0), ic_detect_idx=a(ic, 1))
