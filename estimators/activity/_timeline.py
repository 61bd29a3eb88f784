"""``classify_day``: chest accelerometer (m/s²) -> per-second classes, transitions, walking bouts, steps.

Thesis ch. 7 (spec/thesis_calib_gait_posture.md §4) plus what free-living data needs (auto-calibration,
per-participant upright reference, non-wear); the timeline state machine is spec §4.5.
"""
from __future__ import annotations

import numpy as np

from estimators.activity import _kernels as K
from estimators.activity._detect import (classify_bouts, detect_steps, detect_transitions, group_bouts,
                                         lying_state, step_signal)
from estimators.activity._signals import (autocalibrate, calibration_from_windows, ga_dc_gain, gravitational_component,
                                          nonwear_seconds, rotation_to_y, runs)
from estimators.activity._types import (LYING, LYSI, NON_WEAR, SILY, SIST, SITTING, STANDING, STANDARD_GRAVITY,
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
                             "pipeline.formats.uci_chest)")
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
                 params: ActivityParams = ActivityParams(), gyr_rad_s: np.ndarray | None = None) -> ActivityResult:
    """Daily postures, transitions, walking modalities and steps from one chest accelerometer.

    Nazarahari 2021 ch. 7 (Nazarahari & Rouhani 2018, doi:10.1016/j.medengphy.2018.04.008);
    spec/thesis_calib_gait_posture.md §4, §7.C. ``acc_m_s2`` (N, 3) specific force in the sensor frame
    (thesis mounting: x anterior, y up, z right; any mounting with ``align="upright_reference"``);
    ``t0_ns`` UTC time of sample 0; ``timezone`` IANA name (kept for ``daily_summaries``). ``gyr_rad_s`` is
    accepted and ignored (the method is accelerometer-only, like the thesis).

    Steps: (1) units check, clipping check; (2) auto-calibration from still periods; (3) GA = elliptic
    low-pass, steady-state start (§4.2); (4) step peaks on the orientation-free SVM, bouts of ≥ 3 peaks;
    (5) per wear period the upright reference = median GA direction while walking, and a rotation of it
    onto +y; non-wear = ≥ 30 min with every axis motionless; (6) θ (Eq. 54), lying, SiLy/LySi, StSi/SiSt with
    ΔY (Eq. 55-56) and the cumulative SVM sign (Eq. 57); (7) upright check and modality of the bouts;
    (8) the timeline state machine (§4.5) gives every second a class.

    Deviations (project default, see ``PRESETS["thesis"]`` for the literal method and docs/activity.md):
    frame alignment to the walking posture (thesis: none, the mounting tilt stays in θ); ΔY from raw acc
    projected on the GA direction (thesis: GA, Eq. 55), also over a quiet-padded window; steps on the
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
    acc_g, mag, _, norm_std = K.calibrate_norm(acc, 1.0 / STANDARD_GRAVITY, cal.offset_g, cal.gain, fs, n_sec)
    sec_static = norm_std < p.static_std_g
    gk = cal.gain[None, :] / STANDARD_GRAVITY
    cand, _ = nonwear_seconds(s1 * gk, s2 * gk ** 2, cnt, std_g=p.nonwear_std_g, noise_factor=p.nonwear_noise_factor,
                              min_s=p.nonwear_min_s)
    segs = [(int(a), int(b)) for a, b in zip(*runs(~cand))] or [(0, n_sec)]
    ga = gravitational_component(acc_g, fs, mode=p.ga_mode, cutoff_hz=p.ga_cutoff_hz, ripple_db=p.ga_ripple_db,
                                 stop_db=p.ga_stop_db)
    svm_steps = step_signal(acc_g, ga, fs, p, mag=mag)   # ‖·‖-based: independent of the sensor orientation
    peaks = detect_steps(svm_steps, fs, p)
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
    theta = K.theta_deg(np.ascontiguousarray(ga[:, 1]), dc)
    lying = lying_state(theta, p)
    tr = detect_transitions(theta, ga, acc_g, sec_static, sec_ga, fs, p, lying)
    groups = [g for g in groups if cand[int(g[0] / fs):int(g[-1] / fs) + 1].mean() < 0.5]
    bouts, steps, smod = classify_bouts(groups, theta, ga, fs, p)
    if len(bouts) == 0:
        warn.append("no walking bout in this recording: step counts are 0")
    theta_sec = K.second_mean1(theta, fs, n_sec)
    lying_sec = K.second_mean1(lying.astype(np.float64), fs, n_sec) > 0.5
    nonwear = cand
    tr = _drop(tr, nonwear)
    cls = _timeline(n_sec, tr, bouts, nonwear, lying_sec, theta_sec, p, warn)
    return ActivityResult(second_t_ns=np.int64(t0_ns) + np.arange(n_sec, dtype=np.int64) * 1_000_000_000,
                          second_class=cls, step_times_s=steps / fs, step_modality=smod, bouts=bouts,
                          transitions=tr, inclination_deg=theta_sec, calibration=cal,
                          upright_ref=np.asarray(refs), clipped_fraction=clipped, warnings=tuple(warn),
                          sampling_rate_hz=fs, t0_ns=int(t0_ns), timezone=timezone, params=p)


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
    from estimators.activity._types import Bouts
    z = np.zeros(0)
    return ActivityResult(second_t_ns=np.zeros(0, np.int64), second_class=np.zeros(0, np.int8),
                          step_times_s=z, step_modality=np.zeros(0, np.int8),
                          bouts=Bouts(z, z, np.zeros(0, np.int64), np.zeros(0, np.int8), z, z, z),
                          transitions=Transitions(z, np.zeros(0, np.int8), z, z, z), inclination_deg=z,
                          calibration=cal, upright_ref=np.zeros((0, 3)), clipped_fraction=0.0,
                          warnings=tuple(warn + ["empty recording"]), sampling_rate_hz=fs, t0_ns=int(t0_ns),
                          timezone=timezone, params=p)
