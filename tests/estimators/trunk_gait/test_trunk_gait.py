"""Trunk gait: hand-made signals of known answer (frame, contacts, sides, bouts, daily outcomes, scorer)."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from stridelab.estimators.trunk_gait import (DURATION_CLASSES_S, TrunkGaitParams, analyse_trunk_gait, daily_outcomes,
                                   detect_trunk_frame)
from stridelab.estimators.trunk_gait._icd import assign_sides, regular_runs
from stridelab.estimators.trunk_gait._wba import assemble_bouts
from stridelab.estimators.trunk_gait.evaluation import ic_metrics, match_bouts, match_initial_contacts
from tests.estimators.trunk_gait._signals import rot, walking_body

FS = 100.0


def _to_sensor(acc_b, gyr_b, R_sensor_to_body):
    """Body-frame signals seen by a sensor with v_body = R v_sensor."""
    return acc_b @ R_sensor_to_body, gyr_b @ R_sensor_to_body


@pytest.mark.parametrize("R_true", [np.eye(3), rot("z", 35.0) @ rot("y", 90.0), rot("x", 180.0),
                                    rot("z", 180.0) @ rot("x", 20.0)],
                         ids=["aligned", "tilted_turned", "upside_down", "backwards_tilted"])
def test_frame_detected_for_any_mounting(R_true):
    acc_b, gyr_b, _, _ = walking_body(30.0, rest_s=2.0)
    acc, gyr = _to_sensor(acc_b, gyr_b, R_true)
    f = detect_trunk_frame(acc, gyr, FS)
    assert f.walking_found
    np.testing.assert_allclose(f.R, R_true, atol=0.08)
    assert np.linalg.det(f.R) == pytest.approx(1.0, abs=1e-9)
    upside = any("upside down" in w for w in f.warnings)
    assert upside == (R_true[1] @ np.eye(3)[int(np.argmax(np.abs(R_true[1])))] < 0)


def test_frame_flags_a_sensor_that_is_not_on_the_trunk():
    rng = np.random.default_rng(1)
    t = np.arange(int(60 * FS)) / FS
    ang = 1.2 * np.sin(2 * np.pi * 0.9 * t)                      # a swinging limb: gravity direction sweeps ±70°
    acc = 9.81 * np.column_stack([np.sin(ang), np.cos(ang), 0 * t]) + rng.normal(0, 0.3, (len(t), 3))
    f = detect_trunk_frame(acc, np.zeros_like(acc), FS)
    assert any("vertical axis not found" in w for w in f.warnings)


def test_units_checked():
    acc_b, gyr_b, _, _ = walking_body(10.0)
    with pytest.raises(ValueError, match="looks like g"):
        analyse_trunk_gait(acc_b / 9.81, gyr_b, FS)
    with pytest.raises(ValueError, match="deg/s"):
        analyse_trunk_gait(acc_b, np.full_like(gyr_b, 100.0), FS)
    with pytest.raises(ValueError, match="placement"):
        analyse_trunk_gait(acc_b, gyr_b, FS, placement="foot_left")


def test_contacts_sides_and_cadence_on_rotated_synthetic_walk():
    acc_b, gyr_b, ic, left = walking_body(40.0, rest_s=5.0, step_s=0.6)
    acc, gyr = _to_sensor(acc_b, gyr_b, rot("z", 180.0) @ rot("x", 25.0))
    # the simulated walk stops after a full step, without the closing step of a real walk, which the shipped
    # fill places one step after the last contact (ic_fill_end_rhythm; test_icd_detectors): off here
    p = TrunkGaitParams(ic_offset_s=0.0, ic_fill_end_rhythm=False, ic_fill_offset_s=0.0, ic_walk_end_offset_s=0.0)
    res = analyse_trunk_gait(acc, gyr, FS, params=p)
    m = match_initial_contacts(res.initial_contacts_s, ic, tolerance_s=0.05)
    met = ic_metrics(m)
    assert met["sensitivity"] > 0.9 and met["precision"] > 0.99
    assert met["timing_mae_s"] < 0.02
    side_ok = (res.ic_side[m.det_idx] == np.where(left[m.ref_idx], "left", "right")).mean()
    assert side_ok == 1.0
    assert len(res.bouts) == 1
    assert res.bouts.cadence_spm[0] == pytest.approx(100.0, rel=0.01)
    assert res.height_source.startswith("default") and "default_height" in res.bouts.flags[0]


def test_no_walking_gives_an_empty_typed_result():
    rng = np.random.default_rng(2)
    acc = np.tile([0.0, 9.81, 0.0], (6000, 1)) + rng.normal(0, 0.02, (6000, 3))
    res = analyse_trunk_gait(acc, np.zeros_like(acc), FS, height_m=1.8)
    assert len(res.bouts) == 0 and res.initial_contacts_s.shape == (0,) and len(res.turns) == 0
    assert any("no walking" in w for w in res.warnings)
    assert res.height_source == "given"


def test_side_assignment_corrects_isolated_wrong_votes():
    ic = np.arange(10) * 50 + 20                                   # samples
    yaw = np.zeros(600)
    truth_left = np.arange(10) % 2 == 1                            # starts with right
    for k, i in enumerate(ic):                                     # yaw before contact: > 0 right, < 0 left
        yaw[i - 20:i] = -0.5 if truth_left[k] else 0.5
    left = assign_sides(yaw, FS, ic, np.zeros(10, np.int64), lag_s=-0.1, lowpass_hz=20.0)
    np.testing.assert_array_equal(left, truth_left)
    yaw[ic[4] - 20:ic[4]] *= -1                                    # one wrong vote
    left = assign_sides(yaw, FS, ic, np.zeros(10, np.int64), lag_s=-0.1, lowpass_hz=20.0)
    np.testing.assert_array_equal(left, truth_left)
    # two runs (a pause) are labelled independently
    runs = regular_runs(np.r_[np.arange(5) * 0.5, 10 + np.arange(5) * 0.5], max_step_s=1.5)
    np.testing.assert_array_equal(runs, [0] * 5 + [1] * 5)


def test_bout_assembly_merge_and_break_rules():
    # strides every 0.5 s (overlapping pairs of 1.0 s), a 2.5 s pause (merged), a 4 s pause (new bout),
    # then a lone pair of strides (kept only when min_strides <= 2) and an invalid stride in the middle
    s1 = np.arange(0, 5, 0.5)
    s2 = s1[-1] + 1.0 + 2.5 + np.arange(0, 3, 0.5)                 # break 2.5 s after the last stride ended
    s3 = s2[-1] + 1.0 + 4.0 + np.arange(0, 3, 0.5)                 # break 4.0 s
    s4 = s3[-1] + 1.0 + 10.0 + np.array([0.0, 0.5])
    start = np.r_[s1, s2, s3, s4]
    end = start + 1.0
    valid = np.ones(len(start), bool)
    b = assemble_bouts(start, end, valid, max_break_s=3.0, min_strides=4)
    assert set(b[: len(s1) + len(s2)]) == {0}
    assert set(b[len(s1) + len(s2): len(s1) + len(s2) + len(s3)]) == {1}
    assert set(b[-2:]) == {-1}
    b2 = assemble_bouts(start, end, valid, max_break_s=3.0, min_strides=2)
    assert set(b2[-2:]) == {2}
    # an invalid stride is dropped but does not split the bout (its neighbours overlap it)
    valid[3] = False
    b3 = assemble_bouts(start, end, valid, max_break_s=3.0, min_strides=4)
    assert b3[3] == -1 and set(b3[:3]) == {0} and set(b3[4: len(s1)]) == {0}
    # a break exactly at the limit still merges; just above it splits
    st = np.array([0.0, 0.5, 1.0, 1.5, 5.5, 6.0, 6.5, 7.0])
    assert len(set(assemble_bouts(st, st + 1.0, np.ones(8, bool), max_break_s=3.0, min_strides=4))) == 1
    st[4:] += 0.01
    assert len(set(assemble_bouts(st, st + 1.0, np.ones(8, bool), max_break_s=3.0, min_strides=4))) == 2


def test_daily_outcomes_classes_medians_and_centiles():
    dur = np.array([5.0, 10.0, 12.0, 29.9, 30.0, 59.0, 60.0, 119.0, 120.0, 400.0])
    speed = np.arange(10) * 0.1 + 0.3                               # 0.3 ... 1.2
    cad = 80.0 + np.arange(10)
    sl = np.linspace(0.6, 1.5, 10)
    out = daily_outcomes(np.cumsum(dur) * 2, dur, cad, sl, speed,
                         stride_speed_m_s=np.r_[np.full(50, 5.0), np.arange(100) / 100.0],
                         stride_bout=np.r_[np.zeros(50, int), np.full(100, 9)])
    assert out.walking_time_s == pytest.approx(dur.sum())
    assert out.n_bouts == 10
    # 10.0 is not > 10 s (excluded from outcomes) but falls in [10, 30)
    assert out.n_bouts_by_class == (3, 2, 2, 2)
    assert out.n_bouts_over_10s == 8
    long = dur > 10
    assert out.speed_median_m_s == pytest.approx(np.median(speed[long]))
    assert out.speed_median_m_s == pytest.approx(0.85)             # bouts 2..9: 0.5 ... 1.2
    assert out.speed_p95_m_s == pytest.approx(0.5 + 0.95 * 0.7)    # linear interpolation over 8 values
    assert out.cadence_median_spm == pytest.approx(85.5)
    assert out.stride_length_median_m == pytest.approx(np.median(sl[long]))
    # strides of the 5 s bout (speed 5.0) are excluded from SV95C; the rest are 0.00 ... 0.99
    assert out.stride_velocity_p95_m_s == pytest.approx(0.9405)
    assert sum(out.n_bouts_by_class) == int(np.sum(dur >= DURATION_CLASSES_S[0][0]))
    empty = daily_outcomes([], [], [], [], [])
    assert empty.n_bouts == 0 and np.isnan(empty.speed_median_m_s) and empty.walking_time_s == 0.0
    with pytest.raises(ValueError, match="same length"):
        daily_outcomes([0.0], [12.0, 13.0], [1.0], [1.0], [1.0])


def test_ic_matching_one_to_one_within_tolerance():
    ref = np.array([1.0, 2.0, 3.0, 4.0])
    det = np.array([1.05, 1.10, 2.30, 3.0, 3.02, 4.2])
    m = match_initial_contacts(det, ref, tolerance_s=0.25)
    pairs = sorted(zip(m.det_idx.tolist(), m.ref_idx.tolist()))
    assert pairs == [(0, 0), (3, 2), (5, 3)]                         # 2.30 is 0.30 away; 1.10/3.02 lose
    met = ic_metrics(m)
    assert met["sensitivity"] == pytest.approx(3 / 4) and met["precision"] == pytest.approx(3 / 6)
    assert met["timing_mae_s"] == pytest.approx((0.05 + 0.0 + 0.2) / 3)
    with pytest.raises(ValueError):
        match_initial_contacts(det, ref, tolerance_s=-1)



def test_ic_matching_inside_windows_leaves_out_detections_elsewhere():
    ref = np.array([1.0, 2.0, 3.0])
    det = np.array([0.5, 1.02, 2.05, 3.1, 3.6, 7.0])
    # scored inside [1, 3] ± 0.25: 0.5 and 3.6 and 7.0 lie outside; 3.1 inside (tolerance); no extra contacts
    m = match_initial_contacts(det, ref, tolerance_s=0.25, windows_s=[[1.0, 3.0]])
    assert sorted(zip(m.det_idx.tolist(), m.ref_idx.tolist())) == [(1, 0), (2, 1), (3, 2)]   # full-input indices
    assert m.fp_idx.tolist() == [] and m.fn_idx.tolist() == []
    assert m.error_s == pytest.approx([0.02, 0.05, 0.1])
    # two windows: 7.0 falls in the second and has no reference -> extra; everywhere (None): 0.5, 3.6, 7.0 extra
    m2 = match_initial_contacts(det, ref, tolerance_s=0.25, windows_s=[[1.0, 3.0], [6.9, 7.5]])
    assert m2.fp_idx.tolist() == [5]
    assert match_initial_contacts(det, ref, tolerance_s=0.25).fp_idx.tolist() == [0, 4, 5]

def test_bout_matching_by_overlap():
    m = match_bouts([0.0, 10.0, 30.0], [8.0, 20.0, 31.0], [1.0, 12.0, 50.0], [9.0, 19.0, 60.0], min_iou=0.5)
    assert m.det_idx.tolist() == [0, 1] and m.ref_idx.tolist() == [0, 1]
    assert m.fp_idx.tolist() == [2] and m.fn_idx.tolist() == [2]
    assert m.iou[0] == pytest.approx(7 / 9)


def test_params_documented_and_json_round_trip():
    p = TrunkGaitParams()
    doc = TrunkGaitParams.__doc__
    assert all(f.name in doc for f in dataclasses.fields(p))
    assert TrunkGaitParams(**json.loads(json.dumps(dataclasses.asdict(p)))) == p
    assert hash(p) == hash(TrunkGaitParams())


def test_turns_found_with_angle_and_direction():
    from stridelab.estimators.trunk_gait._turns import detect_turns
    t = np.arange(int(20 * FS)) / FS
    yaw = np.zeros_like(t)
    m1 = (t >= 5) & (t < 7)                                        # 90 deg to the left in 2 s (half-sine rate)
    yaw[m1] = np.deg2rad(90.0) * np.pi / 4 * np.sin(np.pi * (t[m1] - 5) / 2)
    m2 = (t >= 12) & (t < 13)                                      # 180 deg to the right in 1 s
    yaw[m2] = -np.deg2rad(180.0) * np.pi / 2 * np.sin(np.pi * (t[m2] - 12) / 1)
    m3 = (t >= 16) & (t < 16.5)                                    # 20 deg: too small to be a turn
    yaw[m3] = np.deg2rad(20.0) * np.pi / 1 * np.sin(np.pi * (t[m3] - 16) / 0.5)
    p = TrunkGaitParams()
    tr = detect_turns(yaw, FS, t0_s=100.0, lowpass_hz=p.turn_lowpass_hz, min_peak_deg_s=p.turn_min_peak_deg_s,
                      edge_deg_s=p.turn_edge_deg_s, min_angle_deg=p.turn_min_angle_deg, min_s=p.turn_min_s,
                      max_s=p.turn_max_s)
    assert len(tr) == 2
    np.testing.assert_allclose(tr.angle_deg, [90.0, -180.0], rtol=0.1)
    assert 104.5 < tr.start_s[0] < 105.5 and 106.5 < tr.end_s[0] < 107.5


def test_chest_placement_and_given_height_are_reported():
    acc_b, gyr_b, _, _ = walking_body(30.0, rest_s=3.0)
    res = analyse_trunk_gait(acc_b, gyr_b, FS, placement="chest", height_m=1.60, leg_length_m=0.80)
    assert res.placement == "chest" and res.height_source == "given" and res.leg_length_source == "given"
    assert len(res.bouts) == 1
    assert "chest_stride_length_model" in res.bouts.flags[0] and "default_height" not in res.bouts.flags[0]
    # stride length scales with the pendulum length (Zijlstra & Hof Eq. 1): a longer leg, longer strides
    res2 = analyse_trunk_gait(acc_b, gyr_b, FS, placement="chest", height_m=1.60, leg_length_m=1.0)
    assert res2.bouts.stride_length_m[0] > res.bouts.stride_length_m[0]


def test_slow_small_steps_are_still_walking():
    # about 0.3 m/s: 1.1 s per step (55 steps/min), upward acceleration only ±0.6 m/s²
    acc_b, gyr_b, ic, left = walking_body(60.0, rest_s=5.0, step_s=1.1, amp=0.6, seed=3)
    p = TrunkGaitParams(ic_offset_s=0.0, ic_fill_offset_s=0.0, ic_walk_end_offset_s=0.0)
    res = analyse_trunk_gait(acc_b, gyr_b, FS, height_m=1.65, params=p)
    m = match_initial_contacts(res.initial_contacts_s, ic, tolerance_s=0.1)
    met = ic_metrics(m)
    assert met["sensitivity"] > 0.9 and met["precision"] > 0.95, met
    assert len(res.bouts) == 1 and res.bouts.cadence_spm[0] == pytest.approx(60 / 1.1, rel=0.02)
    assert (res.ic_side[m.det_idx] == np.where(left[m.ref_idx], "left", "right")).mean() == 1.0


def test_hampel_replaces_an_isolated_step_but_keeps_a_change_of_pace_and_runs_apart():
    from stridelab.estimators.trunk_gait._spatial import hampel
    x = np.array([0.60, 0.62, 0.61, 1.30, 0.60, 0.62, 0.61])   # one step measured twice as long
    y = hampel(x, 1, 3.0)
    assert y[3] == pytest.approx(0.61) and np.array_equal(np.delete(y, 3), np.delete(x, 3))
    # a lasting change of pace (slow -> fast) is not an outlier
    pace = np.r_[np.full(5, 0.5), np.full(5, 0.7)]
    assert np.array_equal(hampel(pace, 2, 3.0), pace)
    # windows do not cross runs: the first step of a new run is judged only among its own run
    runs = np.r_[np.zeros(4, int), np.ones(4, int)]
    z = np.r_[np.full(4, 0.5), 0.9, 0.9, 0.9, 0.9]
    assert np.array_equal(hampel(z, 1, 3.0, runs), z)
    # NaN stays NaN and does not spread
    w = np.array([0.6, np.nan, 0.6, 0.61, 0.6])
    out = hampel(w, 1, 3.0)
    assert np.isnan(out[1]) and np.allclose(out[[0, 2, 3, 4]], w[[0, 2, 3, 4]])


def test_bout_average_must_be_mean_or_median():
    acc, gyr = walking_body(20.0)[:2]
    with pytest.raises(ValueError, match="bout_average"):
        analyse_trunk_gait(acc, gyr, 100.0, params=dataclasses.replace(TrunkGaitParams(), bout_average="mode"))


def test_fill_missed_steps_adds_the_rhythm_s_missing_contact_and_edge_steps_only_when_asked():
    from stridelab.estimators.trunk_gait._icd import fill_missed_steps
    kept = np.array([100, 150, 200, 300, 350, 400])          # T = 50 samples; the contact near 250 was missed
    cand = np.array([120, 248, 262, 58, 445, 520])            # 248 (prominent) and 262 in the gap; 58 / 445 at edges
    prom = np.array([0.9, 0.5, 0.3, 0.4, 0.4, 0.9])
    out = fill_missed_steps(kept, cand, prom, max_step=150)
    assert out.tolist() == [100, 150, 200, 248, 300, 350, 400]   # 120 is inside a regular step: not added
    out1 = fill_missed_steps(kept, cand, prom, max_step=150, edge_steps=1)
    assert out1.tolist() == [58, 100, 150, 200, 248, 300, 350, 400, 445]   # 520 is 1.5 T beyond 445: not with 1 step
    # a pause (gap > 2.5 T) is not filled
    assert fill_missed_steps(np.array([0, 50, 100, 300, 350]), np.array([200]), np.array([1.0]),
                             max_step=150).tolist() == [0, 50, 100, 300, 350]


def test_fill_finds_a_weak_step_inside_a_synthetic_walk():
    from stridelab.estimators.trunk_gait._icd import detect_initial_contacts
    fs = 100.0
    t = np.arange(0, 12, 1 / fs)
    ic = np.arange(0.5, 11.6, 0.55)
    amp = np.ones(len(ic))
    amp[10] = 0.15                                           # one weak step (a turn) among strong ones
    v = sum(a * np.exp(-0.5 * ((t - c) / 0.05) ** 2) for a, c in zip(amp, ic))
    v = v - v.mean()
    kw = dict(smooth_s=0.03, min_step_s=0.25, prominence=0.7)
    plain = detect_initial_contacts(v, fs, **kw) / fs
    filled = detect_initial_contacts(v, fs, **kw, fill_prominence=0.1) / fs
    assert not np.any(np.abs(plain - ic[10]) < 0.05)
    assert np.any(np.abs(filled - ic[10]) < 0.05) and len(filled) == len(plain) + 1


def test_consensus_strides_span_a_stop_as_kluge_and_mobgap_do():
    from stridelab.estimators.trunk_gait._wba import strides_from_contacts
    from stridelab.estimators.trunk_gait._icd import regular_runs
    ic = np.r_[0.6 * np.arange(5), 2.4 + 1.9, 2.4 + 1.9 + 2.0]      # 5 steps, a 1.9 s stop, a contact, a 2 s stop
    runs = regular_runs(ic, max_step_s=1.5)
    step = np.ones(len(ic) - 1)
    first, st, en, _ = strides_from_contacts(ic, runs, step)                       # rule "run": inside runs only
    assert first.tolist() == [0, 1, 2]
    first, st, en, ln = strides_from_contacts(ic, runs, step, rule="consensus", max_stride_s=3.0)
    assert first.tolist() == [0, 1, 2, 3]                  # 1.8 → 4.3 (2.5 s) is a stride; 2.4 → 6.3 (3.9 s) is not
    np.testing.assert_allclose(en - st, [1.2, 1.2, 1.2, 2.5])
    np.testing.assert_allclose(ln, 2.0)
    closing = np.zeros(len(ic), bool)
    closing[5] = True                                      # a closing step added by the fill starts no stride
    assert strides_from_contacts(ic, runs, step, rule="consensus", max_stride_s=4.0,
                                 no_start=closing)[0].tolist() == [0, 1, 2, 3, 4]
    with pytest.raises(ValueError, match="stride_rule"):
        strides_from_contacts(ic, runs, step, rule="foot")


def test_a_short_walk_with_a_stop_is_a_bout_under_the_consensus_stride_rule():
    # hand-made walk of known answer: 5 steps of 0.6 s, a 1.6 s stop, one last contact (6 contacts, 4 strides, as
    # the INDIP reference bout of HA-001 Test11 at 28.6 s); the run rule splits off the last contact and leaves 3
    # strides, below the 4-stride bout rule, the consensus rule keeps the whole walk
    rng = np.random.default_rng(3)
    t = np.arange(0, 16, 1 / FS)
    ic = np.r_[4.0 + 0.6 * np.arange(5), 4.0 + 0.6 * 4 + 1.6]
    up = sum(2.0 * np.exp(-0.5 * ((t - c) / 0.08) ** 2) for c in ic)
    up -= np.convolve(up, np.ones(200) / 200, "same")
    yaw = np.zeros_like(t)
    for k, c in enumerate(ic):
        m = (t >= c - 0.3) & (t < c + 0.3)
        yaw[m] = -0.4 * (1.0 if k % 2 == 0 else -1.0) * np.cos(np.pi * (t[m] - c) / 0.6)
    acc = np.column_stack([-0.05 * np.gradient(up, 1 / FS), up + 9.80665, 0 * t]) + rng.normal(0, 0.03, (len(t), 3))
    gyr = np.column_stack([0 * t, yaw, 0 * t]) + rng.normal(0, 0.003, (len(t), 3))
    base = TrunkGaitParams(ic_offset_s=0.0, ic_fill_end_rhythm=False, ic_fill_end_steps=0, stride_rule="run",
                           ic_fill_offset_s=0.0, ic_walk_end_offset_s=0.0)
    run = analyse_trunk_gait(acc, gyr, FS, height_m=1.75, params=base)
    cons = analyse_trunk_gait(acc, gyr, FS, height_m=1.75, params=dataclasses.replace(base, stride_rule="consensus"))
    assert len(run.bouts) == 0 and len(run.initial_contacts_s) == 0
    assert len(cons.bouts) == 1 and cons.bouts.n_strides.tolist() == [4] and cons.bouts.n_steps.tolist() == [5]
    m = match_initial_contacts(cons.initial_contacts_s, ic, tolerance_s=0.05)
    assert ic_metrics(m)["sensitivity"] == 1.0 and ic_metrics(m)["precision"] == 1.0
    assert cons.bouts.start_s[0] == pytest.approx(ic[0], abs=0.02) and cons.bouts.end_s[0] == pytest.approx(ic[-1],
                                                                                                           abs=0.02)
    # the stride over the stop counts for the bout rules but not for its stride length and speed
    assert cons.strides.steady.tolist() == [True, True, True, False]
    assert cons.bouts.stride_length_m[0] == pytest.approx(np.median(cons.strides.length_m[:3]))
    # speed = stride length x the bout's steps over its walking time (cadence "count"), whatever cadence it reports
    count = analyse_trunk_gait(acc, gyr, FS, height_m=1.75,
                               params=dataclasses.replace(base, stride_rule="consensus", cadence_method="count"))
    assert cons.bouts.walking_speed_m_s[0] == pytest.approx(count.bouts.walking_speed_m_s[0])
    assert count.bouts.walking_speed_m_s[0] == pytest.approx(
        cons.bouts.stride_length_m[0] * count.bouts.cadence_spm[0] / 120)


def test_bout_spatial_leaves_out_strides_over_a_stop_unless_none_is_left():
    from stridelab.estimators.trunk_gait._pipeline import bout_spatial
    length = np.array([1.2, 1.2, 1.2, 3.0, 0.9, 0.9])
    dur = np.array([1.0, 1.0, 1.0, 2.6, 1.0, 2.7])
    bout = np.array([0, 0, 0, 0, 1, 1])
    steady = np.array([True, True, True, False, False, False])
    sl, sp = bout_spatial(length, dur, bout, np.array([120.0, 100.0]), average="mean", strides="all",
                          speed_method="cadence", steady=steady)
    np.testing.assert_allclose(sl, [1.2, 0.9])                  # bout 1 has no steady stride: all of its strides
    np.testing.assert_allclose(sp, [1.2, 0.9 * 100 / 120])
    sl_all, _ = bout_spatial(length, dur, bout, np.array([120.0, 100.0]), average="mean", strides="all",
                             speed_method="cadence")
    assert sl_all[0] == pytest.approx((3 * 1.2 + 3.0) / 4)


def test_hampel_row_median_equals_numpy_nanmedian():
    # the Hampel filter's median by one sort (NaNs last) must equal np.nanmedian row by row, odd and even counts
    from stridelab.estimators.trunk_gait._spatial import _row_nanmedian
    rng = np.random.default_rng(3)
    w = rng.normal(size=(400, 5))
    w[rng.random(w.shape) < 0.35] = np.nan
    w = w[np.isfinite(w).any(axis=1)]
    np.testing.assert_array_equal(_row_nanmedian(w), np.nanmedian(w, axis=1))
    assert _row_nanmedian(np.array([[3.0, np.nan, 1.0, 10.0]]))[0] == 3.0
    assert _row_nanmedian(np.array([[4.0, 1.0, np.nan, np.nan]]))[0] == 2.5
