"""IC/TC detector (thesis ch. 6): streaming = batch, synthetic gait, alternation, rest, matching."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from stridelab.estimators.gait import GaitEventDetector, IcTcParams, detect_ic_tc, pitch_signal
from stridelab.estimators.gait.evaluation import match_events, match_strides
from stridelab.estimators.quaternion import quat_from_axis_angle, quat_mul

FS = 100.0


def synthetic_s(stride_s=1.1, n=30, stance=0.6, noise=0.0, seed=0):
    """Spec §9.4 template: +0.25 at IC, ≈0 foot flat, −0.6 at TC, −0.1 mid-swing; 3 s standing first."""
    rng = np.random.default_rng(seed)
    ns = int(round(stride_s * FS))
    kn = np.array([0, 0.15 * stance, 0.7 * stance, stance, stance + (1 - stance) / 2, 1.0])
    val = np.array([0.25, 0.0, 0.0, -0.6, -0.1, 0.25])
    cs = CubicSpline(kn, val, bc_type="periodic")
    one = cs(np.arange(ns) / ns)
    pre = np.zeros(300)
    # start with a ramp from standing into the first push-off (so the first event is TC)
    s = np.concatenate([pre, one[int(0.7 * stance * ns):], np.tile(one, n)])
    ic = [len(pre) + (ns - int(0.7 * stance * ns)) + k * ns for k in range(n + 1)]
    ic = [i for i in ic if i - 5 < len(s) - 2]
    ic_true = np.array([i - 5 + int(np.argmax(s[i - 5:min(i + 6, len(s) - 1)])) for i in ic])
    return s + noise * rng.standard_normal(len(s)), ic_true


def test_streaming_equals_batch_and_causal():
    s, _ = synthetic_s(noise=0.002)
    ev = detect_ic_tc(s, sampling_rate_hz=FS)
    det = GaitEventDetector(sampling_rate_hz=FS)
    ic, tc = [], []
    for x in s:
        r = det.push(x)
        if r:
            (ic if r[0] == "IC" else tc).append(r[1])
    assert np.array_equal(ic, ev.ic_detect_idx) and np.array_equal(tc, ev.tc_detect_idx)
    assert np.array_equal(ev.ic_idx, ev.ic_detect_idx - 1)
    # causality (U-EV-4): events on a truncated record are the prefix of the full record
    k = len(s) // 2
    ev2 = detect_ic_tc(s[:k], sampling_rate_hz=FS)
    assert np.array_equal(ev2.ic_detect_idx, ev.ic_detect_idx[ev.ic_detect_idx < k])


def test_synthetic_gait_exact_and_alternating():
    s, ic_true = synthetic_s()
    ev = detect_ic_tc(s, sampling_rate_hz=FS)
    m = match_events(ev.ic_idx, ic_true, tolerance_samples=50)
    assert m.sensitivity == 1.0 and m.precision == 1.0
    assert np.all(m.error_samples == 0)
    allev = sorted([(i, "I") for i in ev.ic_idx] + [(i, "T") for i in ev.tc_idx])
    kinds = "".join(k for _, k in allev)
    assert kinds.startswith("T") and "TT" not in kinds and "II" not in kinds


def test_noisy_strides_timing():
    s, ic_true = synthetic_s(stride_s=0.9, noise=0.002, seed=3)
    ev = detect_ic_tc(s, sampling_rate_hz=FS)
    m = match_events(ev.ic_idx, ic_true, tolerance_samples=50)
    assert m.sensitivity == 1.0 and m.precision == 1.0
    assert np.abs(m.error_samples).max() <= 2


def test_no_events_at_rest():
    rng = np.random.default_rng(0)
    s = 0.01 * rng.standard_normal(6000) + 0.05 * np.sin(np.arange(6000) / 2000)
    ev = detect_ic_tc(s, sampling_rate_hz=FS)
    assert len(ev.ic_idx) == 0 and len(ev.tc_idx) == 0


def test_pitch_signal_mapping_and_yaw_invariance():
    pitch = np.radians(11.54)   # toes down: rotation about +y (x toward −z)
    q = quat_from_axis_angle(np.array([0, 1.0, 0]), np.array([pitch]))
    assert pitch_signal(q, np.array([1.0, 0, 0]))[0] == pytest.approx(-0.2, abs=1e-3)
    qy = quat_mul(quat_from_axis_angle(np.array([0, 0, 1.0]), np.array([1.234])), q)
    assert pitch_signal(qy, np.array([1.0, 0, 0]))[0] == pytest.approx(pitch_signal(q, np.array([1.0, 0, 0]))[0])


def test_match_events_fixtures():
    m = match_events([100, 103, 300], [101, 249], tolerance_samples=50)
    assert m.tp == 1 and list(m.fp) == [103, 300] and list(m.fn) == [249]
    m = match_events([100], [151], tolerance_samples=50)
    assert m.tp == 0 and len(m.fp) == 1 and len(m.fn) == 1
    with pytest.raises(ValueError):
        match_events([1], [1], tolerance_samples=-1)
    sm = match_strides([[0, 100], [100, 200]], [[2, 98], [300, 400]], tolerance_samples=5)
    assert list(sm.det_rows) == [0] and list(sm.unmatched_ref) == [1]


def test_rate_scaling_params():
    p = IcTcParams()
    s, ic_true = synthetic_s()
    s200 = np.interp(np.arange(2 * len(s)) / 200.0, np.arange(len(s)) / FS, s)
    ev = detect_ic_tc(s200, sampling_rate_hz=200.0, params=p)
    m = match_events(ev.ic_idx / 2.0, ic_true, tolerance_samples=50)
    assert m.sensitivity == 1.0 and np.abs(m.error_samples).max() <= 1


def _flat_lift_walk(noise=0.002, seed=1):
    """Two normal strides, then a flat-footed lift (turning step: the foot leaves a 0.6 s still stance without
    pitching toes-down) landing with a heel strike, then normal strides again. Returns s, stance mask, lift
    sample, heel-strike peak sample."""
    s, _ = synthetic_s(n=2, noise=0.0)
    stance = np.zeros(len(s), bool)
    # still foot-flat after the last IC of the template: the template is ≈ 0 there
    end_flat = len(s)
    flat = np.zeros(60)                                   # 0.6 s standing still
    lift = np.zeros(35)                                   # flat lift: s stays at 0 ± tiny wobble
    t = np.arange(40) / 40.0
    strike = 0.35 * np.sin(np.pi * t)                     # toes up to +0.35 (heel strike) and back
    tail, _ = synthetic_s(n=2, noise=0.0)
    tail = tail[300:]                                     # no second standing period
    s2 = np.concatenate([s, flat, lift, strike, np.zeros(30), tail])
    stance2 = np.concatenate([stance, np.ones(60, bool), np.zeros(35 + 40, bool), np.ones(30, bool),
                              np.zeros(len(tail), bool)])
    stance2[:300] = True                                  # initial standing
    rng = np.random.default_rng(seed)
    s2 = s2 + noise * rng.standard_normal(len(s2))
    lift_k = end_flat + 60
    peak = lift_k + 35 + int(np.argmax(strike))
    return s2, stance2, lift_k, peak


def test_flat_lift_rule_finds_the_heel_strike_after_a_flat_lift():
    s, stance, lift_k, peak = _flat_lift_walk()
    plain = detect_ic_tc(s, sampling_rate_hz=FS)
    ev = detect_ic_tc(s, sampling_rate_hz=FS, stance=stance)
    # thesis Algorithm 1 alone: no TC in the flat lift, so strict alternation blocks that heel strike
    assert not np.any(np.abs(plain.ic_idx - peak) <= 3)
    # (R4): TC at the lift (first moving sample), IC at the heel-strike maximum
    assert np.any(ev.tc_idx == lift_k)
    assert np.any(np.abs(ev.ic_idx - peak) <= 3)
    allev = sorted([(i, "I") for i in ev.ic_idx] + [(i, "T") for i in ev.tc_idx])
    kinds = "".join(k for _, k in allev)
    assert kinds.startswith("T") and "TT" not in kinds and "II" not in kinds
    # streaming with the stance flag gives the same events (the flat-lift TC reported late, at the IC)
    det = GaitEventDetector(sampling_rate_hz=FS)
    ic, tc = [], []
    for x, st in zip(s, stance):
        r = det.push(x, bool(st))
        for e in ([] if r is None else (r if isinstance(r, list) else [r])):
            (ic if e[0] == "IC" else tc).append(e[2])
    assert np.array_equal(ic, ev.ic_idx) and np.array_equal(tc, ev.tc_idx)


def test_stance_mask_changes_nothing_in_normal_gait():
    """(R4) must never fire in ordinary strides (stance = foot-flat part of the template)."""
    for stride_s in (0.8, 1.1, 1.6):
        s, _ = synthetic_s(stride_s=stride_s, noise=0.002, seed=3)
        stance = np.abs(s) < 0.02
        a = detect_ic_tc(s, sampling_rate_hz=FS)
        b = detect_ic_tc(s, sampling_rate_hz=FS, stance=stance)
        assert np.array_equal(a.ic_idx, b.ic_idx) and np.array_equal(a.tc_idx, b.tc_idx)


def _push_off_gyr(n, tc, dec_len, fs, axis):
    """Sagittal rate about ``axis``: plantarflexion rate ramps up to 8 rad/s, then (toe-off at ``tc``) falls
    linearly to 0 over ``dec_len`` samples (pitch minimum at tc + dec_len) and goes on to −3 rad/s."""
    w = np.zeros(n)
    w[tc - 40:tc + 1] = np.linspace(2.0, 8.0, 41)
    w[tc:tc + dec_len + 1] = np.linspace(8.0, 0.0, dec_len + 1)
    w[tc + dec_len:] = np.linspace(0.0, -3.0, n - tc - dec_len)
    return np.outer(w, axis)


def test_refine_toe_off_finds_the_onset_of_the_plantarflexion_deceleration():
    from stridelab.estimators.gait import refine_toe_off
    fs = 200.0
    axis = np.array([0.3, 0.9, 0.1])
    axis /= np.linalg.norm(axis)
    for dec_len in (4, 6, 10):
        gyr = _push_off_gyr(400, 200, dec_len, fs, axis)
        pmin = 200 + dec_len                                   # Algorithm 1's TC: pitch minimum (rate zero)
        out = refine_toe_off(gyr, np.array([pmin]), axis, sampling_rate_hz=fs)
        assert abs(int(out[0]) - 200) <= 1, (dec_len, out)
        # the other sign of the axis (toes-up rotation) finds no deceleration: TC unchanged
        assert refine_toe_off(gyr, np.array([pmin]), -axis, sampling_rate_hz=fs)[0] != 200
        # a lower bound (previous IC / last still sample) is respected
        assert refine_toe_off(gyr, np.array([pmin]), axis, sampling_rate_hz=fs,
                              lower_bound=np.array([pmin - 2]))[0] >= pmin - 2
    # no deceleration at all (constant rate): nothing to refine
    g = np.outer(np.full(300, 5.0), axis)
    assert refine_toe_off(g, np.array([150]), axis, sampling_rate_hz=fs)[0] == 150


def test_foot_kinematics_toe_off_refinement_is_optional_and_only_moves_tcs_earlier():
    from dataclasses import replace

    from stridelab.estimators.gait import FootParams, foot_kinematics
    from stridelab.validation.simulator.foot_walk_yun import simulate_yun_walk
    sim = simulate_yun_walk(12, noise_scale=1.0, seed=3, sampling_rate_hz=100)
    plain = foot_kinematics(sim.gyr, sim.acc, sampling_rate_hz=100, params=replace(FootParams(), toe_off_refine=False))
    ref = foot_kinematics(sim.gyr, sim.acc, sampling_rate_hz=100)
    assert plain.events.tc_pitch_min_idx is None
    assert np.array_equal(ref.events.tc_pitch_min_idx, plain.events.tc_idx)
    assert np.array_equal(ref.events.ic_idx, plain.events.ic_idx)
    d = ref.events.tc_idx - plain.events.tc_idx
    assert np.all(d <= 0) and np.all(d >= -15)
    # never before the previous IC
    for tc in ref.events.tc_idx:
        prev = ref.events.ic_idx[ref.events.ic_idx < tc]
        nxt_plain = plain.events.ic_idx[plain.events.ic_idx < tc]
        assert len(prev) == len(nxt_plain)
