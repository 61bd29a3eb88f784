"""Batch completion of Algorithm-1 events on the swings of the zero-velocity mask (issue 18: paretic feet).

Algorithm 1 (``_events``) needs a push-off that passes the threshold T (TC) and a toes-up heel strike (IC). A paretic
foot may lift almost flat (no push-off), swing with the toes down (drop foot) and land flat or on the forefoot: TCs are
then missed, strict alternation drops the next IC, or the IC is put on the swing's pitch maximum (mid-swing, too
early) or in the following stance (too late). With the stance mask of the batch kinematics every swing is known:

    swing = a moving run [e, f) of the zero-velocity mask between two still runs, n_ref ≤ f − e ≤ 3 s     (W0)
    A swing where Algorithm 1 found a TC and then a heel strike (an IC with s_IC ≥ s_f + M, toes up above the
    stance that follows) is left exactly as Algorithm 1 found it. Otherwise the swing is one step: one TC, one IC.
    (W1) TC = the first pitch minimum after the lift, s_k ≤ s_e − M with s rising for the next two samples (the
         end of the push-off's plantarflexion; Algorithm 1's TC when it is that sample, later minima are the
         swing's: a drop-foot swing can fall again toward a toes-down landing), else argmin s over
         [e, e + ⌈(f − e)/2⌉) (a flat lift); refined to the toe-off by T1 like Algorithm 1's TCs.
    (W4) with the gyroscope norm |ω|: if between the lift e and that TC |ω| falls below f_T1 = 0.2 of its maximum
         since e after the foot has plantarflexed by ≥ M, and s later in the swing falls by ≥ M more, the push-off
         ended there and the further plantarflexion is the swing (drop foot): TC = that sample (refined by T1).
    (W2) IC (when no heel strike follows the TC): the start j of the last monotone run of s before f (the loading
         rotation about the heel or the ball ends at foot flat; its start is the contact) when
         f − j ≤ MAX_LOADING_S; otherwise (flat contact: no loading rotation) Algorithm 1's first IC after the TC,
         or argmax s over (TC + n_ref, f] without one. Other ICs between the TC and the next swing are dropped.
Only for feet that do not heel-strike: ``foot_kinematics`` applies W1–W4 (and K0) when fewer than
HEEL_STRIKER_FRACTION = 0.5 of the foot's swings end in an Algorithm-1 heel strike (a priori: the majority); a
heel-striking foot keeps Algorithm 1 everywhere (its other swings are turns, shuffles, first and last steps).
M = ``IcTcParams.flat_lift_margin`` (0.05 ≈ 3°, R4's margin: a few times the stance pitch noise) and n_ref = the
refractory period: both a priori, none fitted. Strides keep needing one TC then one IC between mid-stances (K2).
f_T1 = ``ROTATION_STOP_FRACTION`` = 0.2, a priori (it was T1's a-priori onset fraction; T1's own fraction is now
chosen on the Voisard subjects, W4's is not). A normal push-off accelerates the rotation up to the toe-off, so |ω|
never nearly stops before its pitch minimum (W4 does not fire on heel-strike steps anyway).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from stridelab.estimators.gait._events import GaitEvents

__all__ = ["complete_swing_events", "swing_runs", "heel_strike_fraction", "MAX_LOADING_S", "HEEL_STRIKER_FRACTION",
           "ROTATION_STOP_FRACTION"]

#: longest loading rotation (contact -> foot flat): loading response ≈ 10-12 % of the gait cycle (Perry & Burnfield
#: 2010) of the slowest strides walked (≈ 2.5 s); a priori
MAX_LOADING_S = 0.3
#: a foot whose swings end in an Algorithm-1 heel strike at least this often keeps Algorithm 1 everywhere (majority)
HEEL_STRIKER_FRACTION = 0.5
#: f_T1 of (W4): |ω| below this share of its maximum since the lift = the push-off's rotation stopped (a priori)
ROTATION_STOP_FRACTION = 0.2


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


def _first_minimum(s: np.ndarray, e: int, f: int, margin: float):
    """(W1) the first sample k in [e, f) with s_k ≤ s_e − margin after which s rises for two samples (the end of
    the push-off's plantarflexion); None if the foot never plantarflexes that much."""
    for k in range(e, f - 2):
        if s[k] <= s[e] - margin and s[k + 1] > s[k] and s[k + 2] > s[k + 1]:
            return k
    return None


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


def heel_strike_fraction(ev: GaitEvents, s: np.ndarray, still: np.ndarray, *, sampling_rate_hz: float,
                         max_swing_s: float = 3.0) -> float:
    """Share of the swings (W0) in which Algorithm 1 found a TC and then a heel strike (s_IC ≥ s_f + M); NaN
    without swings."""
    fs = float(sampling_rate_hz)
    n_ref = max(1, int(round(ev.params.refractory_s * fs)))
    s = np.asarray(s, float)
    sw = [(e, f) for e, f in swing_runs(still, min_samples=n_ref, max_samples=int(max_swing_s * fs)) if f < len(s)]
    if not sw:
        return float("nan")
    hit = 0
    for e, f in sw:
        tcs = ev.tc_idx[(ev.tc_idx >= e - n_ref) & (ev.tc_idx < f)]
        if not len(tcs):
            continue
        ics = ev.ic_idx[(ev.ic_idx > tcs[0]) & (ev.ic_idx < f + n_ref)]
        hit += bool(np.any(s[ics] >= s[f] + ev.params.flat_lift_margin))
    return hit / len(sw)


def complete_swing_events(ev: GaitEvents, s: np.ndarray, still: np.ndarray, *, sampling_rate_hz: float,
                          max_swing_s: float = 3.0, gyr_norm: np.ndarray | None = None,
                          onset_fraction: float = ROTATION_STOP_FRACTION) -> GaitEvents:
    """(W0)–(W4) on the events ``ev`` of pitch signal ``s`` with the stance mask ``still`` (module docstring).
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
        if not finite[e:f].all() or f >= n:
            continue
        in_sw = [t for t in tc if e - n_ref <= t[0] < f]
        first_tc = in_sw[0][0] if in_sw else e
        heel = [t for t in ic if first_tc < t[0] < f + n_ref and s[t[0]] >= s[f] + margin]
        if in_sw and heel:
            continue                                       # Algorithm 1 found this step: a TC, then a heel strike
        for t in in_sw:                                    # one step has one TC (W1)
            tc.remove(t)
        t_tc = _first_minimum(s, e, f, margin)
        if t_tc is None:
            half = e + int(np.ceil((f - e) / 2))
            t_tc = int(e + np.argmin(s[e:half]))
        keep = [t for t in in_sw if t[0] == t_tc]
        in_sw = keep[:1] or [(t_tc, t_tc + 1)]
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
        if heel:                                                       # a heel strike after a W1 / W4 TC
            continue
        cand = [t for t in ic if t_tc < t[0] < nxt]
        alg1 = cand[0] if cand and cand[0][0] < f + n_ref else None
        for c in cand:                                     # one step has one IC: the others go
            ic.remove(c)
        j = _landing(s, lo, f)                                         # (W2)
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
