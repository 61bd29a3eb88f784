"""``classify_day``: chest accelerometer (m/s²) -> per-second classes, transitions, walking bouts, steps.

Thesis ch. 7 (spec/thesis_calib_gait_posture.md §4) plus what free-living data needs (auto-calibration,
per-participant upright reference, non-wear); the timeline state machine is spec §4.5.
"""
from __future__ import annotations

import numpy as np

from stridelab.estimators.activity import _kernels as K
from stridelab.estimators.activity._detect import (classify_bouts, detect_steps, detect_transitions, group_bouts,
                                         lying_state, step_signal)
from stridelab.estimators.activity._signals import (autocalibrate, calibration_from_windows, ga_dc_gain, gravitational_component,
                                          nonwear_seconds, rotation_to_y, runs)
from stridelab.estimators.activity._types import (LYING, LYSI, NON_WEAR, SILY, SIST, SITTING, STANDING, STANDARD_GRAVITY,
                                        STSI, ActivityParams, ActivityResult, Transitions)

_EVENT_STATE = {SILY: LYING, LYSI: SITTING, STSI: SITTING, SIST: STANDING}
_BACKFILL = {SILY: SITTING, LYSI: LYING, STSI: STANDING, SIST: SITTING}


def _check_input(acc: np.ndarray, fs: float) -> np.ndarray:
    a = np.asarray(acc, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"acc_m_s2 must have shape (N, 3), got {a.shape}")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"sampling_rate_hz must be > 0, got {fs}")
    if fs < 10:
        raise ValueError(f"sampling_rate_hz={fs} is too low for step detection (need >= 10 Hz)")
    if not np.isfinite(a).all():
        raise ValueError("acc_m_s2 contains NaN or inf; interpolate or drop those samples first")
    if a.shape[0] >= int(fs):
        g = float(np.median(np.linalg.norm(a[:: max(1, a.shape[0] // 20000)], axis=1)))
        if 0.5 < g < 2.0:
            raise ValueError(f"acc median norm is {g:.2f}: looks like g, expected m/s² (multiply by 9.80665)")
        if g > 50.0:
            raise ValueError(f"acc median norm is {g:.1f}: not m/s² (raw ADC counts? convert, e.g. "
                             "stridelab.pipeline.formats.uci_chest)")
    return a


def _upright_refs(segments, sec_ga_unit, bout_sec, fallback_ref):
    """Per wear segment: median GA direction over walking seconds (upright posture reference)."""
    refs = []
    for a, b in segments:
        m = bout_sec[a:b]
        if m.sum() >= 20:
            u = np.median(sec_ga_unit[a:b][m], axis=0)
            refs.append(u / np.linalg.norm(u))
        else:
            refs.append(None)
    good = [r for r in refs if r is not None]
    glob = None
    if good:
        g = np.median(np.asarray(good), axis=0)
        glob = g / np.linalg.norm(g)
    out = []
    for r in refs:
        out.append(r if r is not None else (glob if glob is not None else fallback_ref))
    return out, glob is not None


def _fallback_ref(sec_ga_unit: np.ndarray) -> np.ndarray:
    """No walking anywhere: the median direction of the seconds within 60° of sensor +y (mounted upright),
    else of −y (upside down), else +y."""
    for sgn in (1.0, -1.0):
        m = sgn * sec_ga_unit[:, 1] > 0.5
        if m.sum() >= 10:
            u = np.median(sec_ga_unit[m], axis=0)
            return u / np.linalg.norm(u)
    return np.array([0.0, 1.0, 0.0])


def classify_day(acc_m_s2: np.ndarray, *, sampling_rate_hz: float, t0_ns: int = 0, timezone: str = "UTC",
                 params: ActivityParams = ActivityParams(), gyr_rad_s: np.ndarray | None = None,
                 overwrite_input: bool = False) -> ActivityResult:
    """Daily postures, transitions, walking modalities and steps from one chest accelerometer.

    Nazarahari 2021 ch. 7 (Nazarahari & Rouhani 2018, doi:10.1016/j.medengphy.2018.04.008);
    spec/thesis_calib_gait_posture.md §4, §7.C. ``acc_m_s2`` (N, 3) specific force in the sensor frame
    (thesis mounting: x anterior, y up, z right; any mounting with ``align="upright_reference"``);
    ``t0_ns`` UTC time of sample 0; ``timezone`` IANA name (kept for ``daily_summaries``). ``gyr_rad_s`` is
    accepted and ignored (the method is accelerometer-only, like the thesis). ``overwrite_input=True`` lets the
    calibrated signal (in g) take the place of ``acc_m_s2`` when that is a C-contiguous float64 array: a day at
    100 Hz then needs 200 MB less (the caller must not use the array afterwards).

    Steps: (1) units check, clipping check; (2) auto-calibration from still periods; (3) GA = elliptic
    low-pass, steady-state start (§4.2); (4) step peaks on the orientation-free SVM, bouts of ≥ 3 peaks;
    (5) per wear period the upright reference = median GA direction while walking, and a rotation of it
    onto +y; non-wear = ≥ 30 min with every axis motionless; (6) θ (Eq. 54), lying, SiLy/LySi, StSi/SiSt with
    ΔY (Eq. 55-56) and the cumulative SVM sign (Eq. 57); (7) upright check and modality of the bouts;
    (8) the timeline state machine (§4.5) gives every second a class.

    Deviations (project default, see ``PRESETS["thesis"]`` for the literal method and docs/activity.md):
    frame alignment to the walking posture (thesis: none, the mounting tilt stays in θ); ΔY (Eq. 56) from ‖a‖,
    lag-free (thesis: a_vg from GA, Eq. 55), also over a quiet-padded window; a posture-sequence check of the
    sit/stand transitions (``resolve_sitstand``: StSi and SiSt alternate between walking and lying anchors); steps on the
    0.5-3 Hz band-passed vertical raw acc with an adaptive threshold (thesis: GA SVM, Eq. 57, fixed threshold);
    stairs by cadence and lean relative to the participant's own walking (thesis: var(GA_v) and GA_f area
    with unspecified thresholds); side lying accepted; hybrid timeline (lying from θ, static lean when no
    transition decides sit vs stand).
    """
    p = params
    fs = float(sampling_rate_hz)
    acc = _check_input(acc_m_s2, fs)
    warn: list[str] = []
    n = acc.shape[0]
    if n == 0:
        return _empty_result(autocalibrate(np.zeros((0, 3)), fs, enabled=False), fs, t0_ns, timezone, p, warn)
    n_sec = int((n - 1) / fs) + 1
    s1, s2, cnt, mn, mx, n_at = K.second_sums(acc, fs, n_sec)
    clipped = float(n_at) / n if n_at > 3 else 0.0
    if clipped > p.clip_fraction_warn:
        warn.append(f"{100 * clipped:.2f} % of samples at the accelerometer range limit (clipped); step and "
                    "transition peaks there are underestimated")
    # auto-calibration from 10-s windows of the per-second sums (in g)
    w = 10
    nw = n_sec // w
    if p.autocalibrate and nw > 0:
        cw = cnt[: nw * w].reshape(nw, w).sum(axis=1)[:, None]
        m_w = s1[: nw * w].reshape(nw, w, 3).sum(axis=1) / cw / STANDARD_GRAVITY
        q_w = s2[: nw * w].reshape(nw, w, 3).sum(axis=1) / cw / STANDARD_GRAVITY ** 2
        cal = calibration_from_windows(m_w, np.sqrt(np.maximum(q_w - m_w ** 2, 0.0)))
    else:
        cal = calibration_from_windows(np.zeros((0, 3)), np.zeros((0, 3)), enabled=False)
    if p.autocalibrate and cal.status != "sphere_fit":
        warn.append(f"auto-calibration: {cal.status} (still orientations do not cover the sphere)")
    counts = np.maximum(cnt, 1.0)
    in_place = overwrite_input and acc is acc_m_s2 and acc.flags.c_contiguous and acc.flags.writeable
    acc_g = acc if in_place else np.empty((n, 3))
    mag, _, norm_std = K.calibrate_norm(acc, acc_g, 1.0 / STANDARD_GRAVITY, cal.offset_g, cal.gain, fs, n_sec)
    del acc
    sec_static = norm_std < p.static_std_g
    gk = cal.gain[None, :] / STANDARD_GRAVITY
    cand, _ = nonwear_seconds(s1 * gk, s2 * gk ** 2, cnt, std_g=p.nonwear_std_g, noise_factor=p.nonwear_noise_factor,
                              min_s=p.nonwear_min_s)
    segs = [(int(a), int(b)) for a, b in zip(*runs(~cand))] or [(0, n_sec)]
    # C order (scipy's filter along axis 0 returns it column-major): the kernels below walk it row by row; the
    # causal filter writes it so, a zero-phase one is copied once (a day at 100 Hz: 207 MB)
    ga = np.ascontiguousarray(gravitational_component(acc_g, fs, mode=p.ga_mode, cutoff_hz=p.ga_cutoff_hz,
                                                      ripple_db=p.ga_ripple_db, stop_db=p.ga_stop_db, order="C"))
    svm_steps = step_signal(acc_g, ga, fs, p, mag=mag)   # ‖·‖-based: independent of the sensor orientation
    del mag                                              # (sample-length arrays are dropped as soon as done:
    peaks = detect_steps(svm_steps, fs, p)               # a day at 100 Hz is 69 MB per channel)
    del svm_steps
    groups = group_bouts(peaks, fs, p)
    sec_ga = K.second_mean3(ga, fs, n_sec)
    sec_ga_unit = sec_ga / np.maximum(np.linalg.norm(sec_ga, axis=1, keepdims=True), 1e-9)
    bout_sec = np.zeros(n_sec, dtype=bool)
    for g in groups:
        bout_sec[int(g[0] / fs):int(g[-1] / fs) + 1] = True
    # ---- wear periods, upright reference, non-wear -------------------------------------------------
    if p.align == "none":
        refs = [np.array([0.0, 1.0, 0.0])]
    else:
        refs, walked = _upright_refs(segs, sec_ga_unit, bout_sec, _fallback_ref(sec_ga_unit))
        if not walked:
            warn.append("no walking found: upright reference from the most upright still posture")
    bounds = [int(np.ceil(a * fs)) for a, _ in segs[1:]]
    edges = [0] + bounds + [n]
    if p.align != "none":
        for (i0, i1), r in zip(zip(edges[:-1], edges[1:]), refs):
            R = rotation_to_y(r)
            K.rotate_inplace(acc_g, R, i0, i1)
            K.rotate_inplace(ga, R, i0, i1)
        sec_ga = K.second_mean3(ga, fs, n_sec)
    # ---- postures and transitions --------------------------------------------------------------------
    dc = ga_dc_gain(fs, p.ga_cutoff_hz, p.ga_ripple_db, p.ga_stop_db)
    theta = (K.theta_direction_deg(np.ascontiguousarray(ga)) if p.theta_mode == "direction"
             else K.theta_deg(np.ascontiguousarray(ga[:, 1]), dc))
    lying = lying_state(theta, p)
    tr, cand_tr, cand_ok = detect_transitions(theta, ga, acc_g, sec_static, sec_ga, fs, p, lying,
                                              return_candidates=True)
    groups = [g for g in groups if cand[int(g[0] / fs):int(g[-1] / fs) + 1].mean() < 0.5]
    bouts, steps, smod = classify_bouts(groups, theta, ga, fs, p)
    if len(bouts) == 0:
        warn.append("no walking bout in this recording: step counts are 0")
    theta_sec = K.second_mean1(theta, fs, n_sec)
    lying_sec = K.second_mean1(lying.astype(np.float64), fs, n_sec) > 0.5
    nonwear = cand
    tr = _drop(tr, nonwear)
    if p.sitstand_resolve and p.timeline == "hybrid":
        tr, n_rev = resolve_sitstand(tr, cand_tr, cand_ok, bouts, lying_sec, nonwear,
                                     p.dy_fraction * p.thigh_length_m, theta_sec, p.sit_lean_deg)
        if n_rev:
            warn.append(f"{n_rev} sit/stand transitions revised by the posture-sequence check "
                        "(sign flipped, rejected candidate added, or dropped)")
    cls = _timeline(n_sec, tr, bouts, nonwear, lying_sec, theta_sec, p, warn)
    return ActivityResult(second_t_ns=np.int64(t0_ns) + np.arange(n_sec, dtype=np.int64) * 1_000_000_000,
                          second_class=cls, step_times_s=steps / fs, step_modality=smod, bouts=bouts,
                          transitions=tr, inclination_deg=theta_sec, calibration=cal,
                          upright_ref=np.asarray(refs), clipped_fraction=clipped, warnings=tuple(warn),
                          sampling_rate_hz=fs, t0_ns=int(t0_ns), timezone=timezone, params=p)


#: costs of the posture-sequence check (``resolve_sitstand``), in units of "one implausible decision"
_C_FLIP = 1.0        # accepted transition applied with the opposite sign
_C_DROP = 1.5        # accepted transition (ΔY ≥ threshold) ignored
_C_ADD = 0.65        # rejected candidate (20° excursion, ΔY below the check) applied; − 0.15 × its ΔY in the
_C_ADD_SLOPE = 0.15  # applied direction / the ΔY threshold (clipped to ±1): 0.5 (sit-like) ... 0.8 (opposite)
_C_IMPLICIT = 1.2    # posture change with no candidate at all, right before a walking bout / lying period
_C_LEAN = 2.0        # standing through ≥ _LEAN_MIN_S still seconds that mostly lean > sit_lean_deg (sitting evidence)
_LEAN_MIN_S = 60


def resolve_sitstand(tr: Transitions, cand: Transitions, ok: np.ndarray, bouts, lying_sec: np.ndarray,
                     nonwear: np.ndarray, dy_threshold_m: float, theta_sec: np.ndarray | None = None,
                     sit_lean_deg: float | None = None) -> tuple[Transitions, int]:
    """Posture-sequence check of the sit/stand transitions (extension; the thesis classifies each transition
    on its own, spec §4.3, and §4.5 applies contradicting events anyway).

    Sitting and standing alternate: a StSi starts from standing, a SiSt from sitting; a walking bout is
    standing at both ends; the trunk sits next to a lying period (SiLy from sitting, LySi to sitting). Per wear
    period, a two-state (standing / sitting) minimum-cost path over the time-ordered sit/stand candidates
    (every 20° excursion with a θ-minima window, spec §4.3 steps 1 and 3, whether its ΔY passed the
    thigh-length check or not) and these anchors decides which candidates are posture changes; the kind follows
    from the state (standing -> StSi). Costs: ``_C_FLIP`` to apply an accepted transition with the other sign,
    ``_C_DROP`` to ignore it, ``_C_ADD`` − ``_C_ADD_SLOPE`` × (ΔY in the applied direction / ``dy_threshold_m``,
    clipped to ±1) to apply a rejected candidate (so the most sit-like of several excursions, e.g. the real
    stand-to-sit rather than a bow before it, is chosen), ``_C_IMPLICIT`` for a change with no candidate right
    before an anchor; ties go to the earlier candidate. Posture evidence (with ``theta_sec``, the per-second
    inclination relative to the upright walking reference, and ``sit_lean_deg``): standing through a gap of
    ≥ ``_LEAN_MIN_S`` s between items whose seconds mostly lean more than ``sit_lean_deg`` costs ``_C_LEAN``
    (a reclined or slumped trunk is sitting, in the thesis' own framing sitting and standing differ in the
    trunk inclination), so a period such evidence marks as sitting takes a rejected candidate or an implicit
    change rather than staying standing. Each such leaning run (≥ ``_LEAN_MIN_S`` s, outside lying and walking)
    also adds two virtual candidates, its onset (StSi) and its end (SiSt), applied at cost ``_C_ADD`` (dy_m NaN
    in the output), because a reclined sit-down keeps θ above 20° for longer than a candidate excursion. A missed stand-to-sit (the ΔY check failed) before a detected sit-to-stand is thereby recovered
    from the rejected excursion, and one wrong sign no longer flips the following correct transition.

    ``tr``: detected transitions (lying ones kept as they are); ``cand``/``ok``: every sit/stand candidate and
    whether it was accepted. Returns (revised transitions, number of candidates whose outcome changed)."""
    n_sec = nonwear.shape[0]
    keep_lying = np.isin(tr.kind, (SILY, LYSI))
    out = {f: [getattr(tr, f)[keep_lying]] for f in ("t_s", "kind", "start_s", "end_s", "dy_m")}
    walk = np.zeros(n_sec + 1, dtype=bool)
    for a, b in zip(bouts.start_s, bouts.end_s):
        walk[int(max(a, 0)):int(np.ceil(b))] = True
    csec = np.minimum(cand.t_s.astype(np.int64), n_sec - 1)
    use = ~nonwear[csec] & ~walk[csec]
    # anchors: (time, kind 1, required state); candidates: (time, kind 0, index). 0 = standing, 1 = sitting
    items = [(float(cand.t_s[i]), 0, int(i)) for i in np.flatnonzero(use)]
    items += [(float(a), 1, 0) for a in bouts.start_s] + [(float(b), 1, 0) for b in bouts.end_s]
    for a, b in zip(*runs(lying_sec)):
        items += [(float(a) - 0.5, 1, 1), (float(b) + 0.5, 1, 1)]
    items.sort(key=lambda x: (x[0], x[1]))
    lean = None
    n_c = len(cand)
    v_t, v_k = [], []                                           # virtual candidates: lean onsets / offsets
    if theta_sec is not None and sit_lean_deg is not None:
        lean = (np.asarray(theta_sec, dtype=np.float64) > sit_lean_deg) & ~lying_sec & ~walk[:n_sec]
        lean_cs = np.concatenate([[0], np.cumsum(lean)])
        for a, b in zip(*runs(lean)):
            if b - a >= _LEAN_MIN_S and not nonwear[a:b].any():
                v_t += [float(a), float(b)]; v_k += [STSI, SIST]
                items += [(float(a), 0, n_c + len(v_t) - 2), (float(b), 0, n_c + len(v_t) - 1)]
        items.sort(key=lambda x: (x[0], x[1]))
    if v_t:
        z = np.full(len(v_t), np.nan)
        cand = Transitions(t_s=np.concatenate([cand.t_s, v_t]), kind=np.concatenate([cand.kind, v_k]).astype(np.int8),
                           start_s=np.concatenate([cand.start_s, v_t]), end_s=np.concatenate([cand.end_s, v_t]),
                           dy_m=np.concatenate([cand.dy_m, z]))
        ok = np.concatenate([ok, np.zeros(len(v_t), dtype=bool)])
        use = np.concatenate([use, np.ones(len(v_t), dtype=bool)])
    if len(cand) == 0:
        return tr, 0
    times = np.asarray([x[0] for x in items], dtype=np.float64)

    def gap_cost(t0, t1):
        """Cost of standing through (t0, t1): _C_LEAN if it is ≥ _LEAN_MIN_S long and most of its seconds
        lean more than sit_lean_deg from the upright (walking) reference (posture evidence of sitting)."""
        if lean is None:
            return 0.0
        i0, i1 = int(np.ceil(max(t0, 0.0))), int(min(t1, n_sec))
        if i1 - i0 < _LEAN_MIN_S:
            return 0.0
        return _C_LEAN if (lean_cs[i1] - lean_cs[i0]) > 0.5 * (i1 - i0) else 0.0

    revised = 0
    applied = np.zeros(len(cand), dtype=bool)
    kind_out = cand.kind.copy()
    for wa, wb in zip(*runs(~nonwear)):                         # one wear period at a time
        lo, hi = np.searchsorted(times, [wa - 1.0, wb], side="left")
        seg = items[lo:hi]
        if not any(typ == 0 for _, typ, _ in seg):
            continue
        cost = np.zeros(2)                                      # free start (back-filled like spec §4.5)
        back = []                                               # per item: (prev state of state 0, of state 1)
        rank = 0
        t_prev = float(wa)
        for t, typ, v in seg:
            cost = cost + np.array([gap_cost(t_prev, t), 0.0])  # evidence over the gap before this item
            t_prev = max(t_prev, t)
            if typ == 1:                                        # anchor: state must be v
                new = np.full(2, np.inf)
                new[v] = min(cost[v], cost[1 - v] + _C_IMPLICIT)
                back.append((0 if new[0] == cost[0] else 1, 1 if new[1] == cost[1] else 0))
                cost = new
                continue
            rank += 1
            k = int(cand.kind[v])
            eps = 1e-3 * rank
            new, bp = np.empty(2), [0, 0]
            for s1 in (0, 1):
                opts = []
                for s0 in (0, 1):
                    if s0 == s1:
                        c = _C_DROP if ok[v] else 0.0
                    else:
                        natural = (k == STSI) == (s0 == 0)
                        if ok[v]:
                            c = 0.0 if natural else _C_FLIP
                        elif v >= n_c:                          # lean onset / offset (no ΔY)
                            c = (_C_ADD if natural else _C_DROP) + eps
                        else:
                            r = float(np.clip((-1.0 if s0 == 0 else 1.0) * cand.dy_m[v] / dy_threshold_m, -1, 1))
                            c = _C_ADD - _C_ADD_SLOPE * r + eps
                    opts.append(cost[s0] + c)
                bp[s1] = int(np.argmin(opts))
                new[s1] = opts[bp[s1]]
            back.append(tuple(bp))
            cost = new
        cost = cost + np.array([gap_cost(t_prev, float(wb)), 0.0])
        s = int(np.argmin(cost))
        for (t, typ, v), bp in zip(reversed(seg), reversed(back)):
            s0 = bp[s]
            if typ == 0 and s0 != s:
                applied[v] = True
                kind_out[v] = STSI if s0 == 0 else SIST
            s = s0
    for v in range(len(cand)):
        if applied[v] != bool(ok[v] and use[v]) or (applied[v] and kind_out[v] != cand.kind[v]):
            revised += 1
    sel = applied
    out["t_s"].append(cand.t_s[sel]); out["kind"].append(kind_out[sel].astype(np.int8))
    out["start_s"].append(cand.start_s[sel]); out["end_s"].append(cand.end_s[sel]); out["dy_m"].append(cand.dy_m[sel])
    cat = {f: np.concatenate(v) for f, v in out.items()}
    order = np.argsort(cat["t_s"], kind="stable")
    return Transitions(**{f: v[order] for f, v in cat.items()}), revised


def _drop(tr: Transitions, mask: np.ndarray) -> Transitions:
    """Transitions whose instant falls in a masked second removed."""
    if len(tr) == 0:
        return tr
    keep = ~mask[np.minimum(tr.t_s.astype(np.int64), mask.shape[0] - 1)]
    return Transitions(*(getattr(tr, f)[keep] for f in ("t_s", "kind", "start_s", "end_s", "dy_m")))


def _timeline(n_sec, tr: Transitions, bouts, nonwear, lying_sec, theta_sec, p: ActivityParams, warn) -> np.ndarray:
    """Spec §4.5 state machine, one wear period at a time: posture changes at transitions, walking bouts
    start and end in STANDING, initial state LYING if θ > 70° else back-filled from the first event.
    ``timeline="hybrid"`` adds: LYING wherever θ says so (its end implies LySi), and a still period that no
    transition decides gets SITTING if its lean relative to the upright reference exceeds sit_lean_deg."""
    change_s, change_v, kinds = [], [], []
    for t, k in zip(tr.t_s, tr.kind):
        change_s.append(int(np.floor(t))); change_v.append(_EVENT_STATE[int(k)]); kinds.append(int(k))
    for a, b in zip(bouts.start_s, bouts.end_s):
        change_s.append(int(np.floor(a))); change_v.append(STANDING); kinds.append(-1)
        change_s.append(int(np.ceil(b))); change_v.append(STANDING); kinds.append(-1)
    hybrid = p.timeline == "hybrid"
    if hybrid:
        for a, b in zip(*runs(lying_sec)):
            change_s.append(int(a)); change_v.append(LYING); kinds.append(SILY)
            change_s.append(int(b)); change_v.append(SITTING); kinds.append(LYSI)
    order = np.argsort(np.asarray(change_s, dtype=np.int64), kind="stable")
    cs = np.asarray(change_s, dtype=np.int64)[order]
    cv = np.asarray(change_v, dtype=np.int8)[order]
    ck = np.asarray(kinds, dtype=np.int64)[order]
    out = np.full(n_sec, STANDING, dtype=np.int8)
    n_incons = 0
    for a, b in zip(*runs(~nonwear)):
        sel = (cs >= a) & (cs < b)
        s_, v_, k_ = cs[sel], cv[sel], ck[sel]
        first = int(s_[0]) if s_.size else b
        if theta_sec[a] > p.lying_deg:
            init = LYING
        elif hybrid and (s_.size == 0 or k_[0] not in (STSI, SIST) or first - a > 3600):
            pre = theta_sec[a:max(first, a + 1)]
            init = SITTING if np.median(pre) > p.sit_lean_deg else STANDING
        elif s_.size:
            init = _BACKFILL.get(int(k_[0]), STANDING)
        else:
            init = STANDING
        idx = np.searchsorted(s_, np.arange(a, b), side="right") - 1
        seg = np.where(idx >= 0, v_[np.maximum(idx, 0)] if v_.size else init, init).astype(np.int8)
        out[a:b] = seg
        prev = init
        for v, k in zip(v_, k_):
            if k in (SILY, STSI) and prev not in ((SITTING,) if k == SILY else (STANDING,)):
                n_incons += 1
            if k in (LYSI,) and prev != LYING or k == SIST and prev != SITTING:
                n_incons += 1
            prev = v
    for a, b, m in zip(bouts.start_s, bouts.end_s, bouts.modality):
        lo, hi = int(np.ceil(a - 0.5)), int(np.ceil(b - 0.5))      # seconds whose centre lies in the bout
        out[lo:max(hi, lo + 1)] = m
    out[nonwear] = NON_WEAR
    if n_incons and not hybrid:
        warn.append(f"{n_incons} transitions contradict the current state (applied anyway, spec §4.5)")
    return out


def _empty_result(cal, fs, t0_ns, timezone, p, warn):
    from stridelab.estimators.activity._types import Bouts
    z = np.zeros(0)
    return ActivityResult(second_t_ns=np.zeros(0, np.int64), second_class=np.zeros(0, np.int8),
                          step_times_s=z, step_modality=np.zeros(0, np.int8),
                          bouts=Bouts(z, z, np.zeros(0, np.int64), np.zeros(0, np.int8), z, z, z),
                          transitions=Transitions(z, np.zeros(0, np.int8), z, z, z), inclination_deg=z,
                          calibration=cal, upright_ref=np.zeros((0, 3)), clipped_fraction=0.0,
                          warnings=tuple(warn + ["empty recording"]), sampling_rate_hz=fs, t0_ns=int(t0_ns),
                          timezone=timezone, params=p)
