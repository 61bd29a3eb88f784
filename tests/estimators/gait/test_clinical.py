"""Clinical measures (stridelab.estimators.gait.clinical) on hand-made event sequences whose answers are known by
construction: asymmetric step times, missing contralateral events, turns, unknown paretic side, feet in their own
rotated frames."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.gait.clinical import (ClinicalParams, FootEvents, FootStrides, clinical_summary, common_walking_frame,
                                      mdc95, step_phases)


def walk(n=12, step_l=0.70, step_r=0.50, stance_l=0.70, stance_r=0.90, len_l=0.45, len_r=0.55, t0=1.0,
         jitter=None, drop_ic_r=(), turning=None):
    """Events of a walk along +x. Step X ends with X's IC; step time X = IC_X − previous IC of the other foot;
    step length X = x of X's foot flat − x of the other foot's flat. Returns per foot (FootStrides, FootEvents)."""
    ic = {"left": [], "right": []}
    x = {"left": [], "right": []}
    t, pos = t0, 0.0
    ic["left"].append(t)
    x["left"].append(pos)
    for k in range(n):
        sr = step_r + (jitter[k] if jitter is not None else 0.0)
        t, pos = t + sr, pos + len_r
        ic["right"].append(t)
        x["right"].append(pos)
        t, pos = t + step_l, pos + len_l
        ic["left"].append(t)
        x["left"].append(pos)
    stance = {"left": stance_l, "right": stance_r}
    out = {}
    for side in ("left", "right"):
        i = np.array(ic[side])
        tc = i + stance[side]
        keep = np.ones(len(i), bool)
        if side == "right":
            keep[list(drop_ic_r)] = False
        i_k, x_k = i[keep], np.array(x[side])[keep]
        mid = i_k + 0.15
        pre, tcs, ics, L, s_xy, e_xy = [], [], [], [], [], []
        for a in range(len(i_k) - 1):                     # a stride: two consecutive detected ICs, one TC between
            between = tc[(tc > i_k[a]) & (tc < i_k[a + 1])]
            if len(between) != 1:
                continue
            pre.append(i_k[a]), tcs.append(between[0]), ics.append(i_k[a + 1])
            L.append(x_k[a + 1] - x_k[a])
            s_xy.append((x_k[a], 0.0)), e_xy.append((x_k[a + 1], 0.0))
        turn = np.zeros(len(ics)) if turning is None else np.array([turning(side, k) for k in range(len(ics))])
        strides = FootStrides(np.array(pre), np.array(tcs), np.array(ics), np.array(L), turn,
                              np.array(s_xy), np.array(e_xy))
        ev = FootEvents(i_k, tc, mid, np.column_stack([x_k, np.full(len(x_k), 0.1 if side == "left" else -0.1)]))
        out[side] = (strides, ev)
    return out


KEEP_ENDS = ClinicalParams(walk_end_strides=0)      # hand-made walks: every stride counts unless a test says


def phases(w, params=KEEP_ENDS):
    return (step_phases(w["left"][0], w["right"][1], params=params),
            step_phases(w["right"][0], w["left"][1], params=params))


def test_asymmetric_steps_give_the_constructed_values():
    w = walk()
    left, right = phases(w)
    # gait initiation: the first left stride has no right toe-off before the first right contact
    assert left.reason[0] == "no_contralateral_tc" and np.isnan(left.step_time_s[0])
    assert set(left.reason[1:]) == {"ok"} and set(right.reason) == {"ok"}
    left = type(left)(**{k: v[1:] for k, v in vars(left).items()})
    T = 0.70 + 0.50
    np.testing.assert_allclose(left.step_time_s, 0.70)
    np.testing.assert_allclose(right.step_time_s, 0.50)
    np.testing.assert_allclose(left.step_length_m, 0.45)
    np.testing.assert_allclose(right.step_length_m, 0.55)
    np.testing.assert_allclose(left.single_support_s, T - 0.90)        # = swing of the right foot
    np.testing.assert_allclose(right.single_support_s, T - 0.70)
    np.testing.assert_allclose(left.ds_initial_s, 0.90 - 0.70)         # right stance − left step
    np.testing.assert_allclose(left.ds_terminal_s, 0.70 - 0.50)        # left stance − right step
    np.testing.assert_allclose(left.double_support_pct, 100 * 0.40 / T)
    s = clinical_summary(left, right, paretic_side="left", params=KEEP_ENDS)
    m = s.measures
    assert m["step_time_s"].paretic_ratio == pytest.approx(0.70 / 0.50)
    assert m["step_time_s"].symmetry_ratio == pytest.approx(0.70 / 0.50)
    assert m["step_length_m"].paretic_ratio == pytest.approx(0.45 / 0.55)
    assert m["step_length_m"].symmetry_ratio == pytest.approx(0.55 / 0.45)      # larger / smaller, ≥ 1
    assert m["swing_time_s"].symmetry_ratio == pytest.approx((T - 0.70) / (T - 0.90))
    assert m["stance_time_s"].paretic_ratio == pytest.approx(0.70 / 0.90)
    assert m["single_support_s"].paretic_ratio == pytest.approx((T - 0.90) / (T - 0.70))
    assert m["gait_speed_m_s"].value == pytest.approx(1.0 / T)
    assert m["cadence_steps_min"].value == pytest.approx(120 / T)
    assert m["stride_time_s"].cv_left_pct == pytest.approx(0.0, abs=1e-9)
    assert m["step_time_s"].flag == "" and s.paretic_side == "left"


def test_variability_and_mdc_follow_the_constructed_spread():
    rng = np.random.default_rng(3)
    jit = rng.normal(0, 0.03, 30)
    left, right = phases(walk(n=30, jitter=jit))
    m = clinical_summary(left, right).measures["step_time_s"]
    # right step k = 0.5 + jit[k]; every right stride (IC_R k -> k+1) is used: all 29 steps 1..29
    sr = 0.5 + jit[1:30]
    assert m.right == pytest.approx(sr.mean()) and m.sd_right == pytest.approx(sr.std(ddof=1))
    assert m.cv_right_pct == pytest.approx(100 * sr.std(ddof=1) / sr.mean())
    sem_r = sr.std(ddof=1) / np.sqrt(len(sr))
    assert m.left == pytest.approx(0.70) and m.sd_left == pytest.approx(0.0, abs=1e-12)   # left steps constant
    assert m.n_left == 29                        # the first left stride has no right toe-off before it
    sem_l = 0.0
    assert m.sem == pytest.approx(0.5 * np.hypot(sem_l, sem_r))
    assert m.mdc95 == pytest.approx(1.96 * np.sqrt(2) * m.sem)
    r = m.left / m.right
    assert m.sem_symmetry_ratio == pytest.approx(r * np.hypot(sem_l / m.left, sem_r / m.right))
    assert mdc95(0.01) == pytest.approx(0.0277186, rel=1e-5)


def test_missing_contralateral_event_leaves_that_step_undefined():
    w = walk(n=12, drop_ic_r=(5,))
    left, right = phases(w)
    # the left strides around the missing right IC: the one that should contain it has no contralateral IC
    assert list(left.reason).count("no_contralateral_ic") == 1
    k = list(left.reason).index("no_contralateral_ic")
    assert np.isnan(left.step_time_s[k]) and np.isnan(left.single_support_s[k]) and np.isnan(left.step_length_m[k])
    # the right foot lost the stride over the gap (two toe-offs between its ICs: not a stride), the rest is fine
    assert len(right) == 9 and set(right.reason) == {"ok"}
    m = clinical_summary(left, right, paretic_side="left").measures
    assert m["step_time_s"].left == pytest.approx(0.70) and m["step_time_s"].right == pytest.approx(0.50)
    assert m["step_time_s"].n_left == 12 - 2 and m["step_time_s"].n_right == 9
    s = clinical_summary(left, right, paretic_side="left")
    assert any("no contralateral ic" in n for n in s.notes)


def test_turning_strides_are_not_used():
    def turning(side, k):
        return 90.0 if 4 <= k <= 6 else 2.0
    w = walk(n=14, turning=turning)
    # make the turn strides visibly different: their lengths would bias the means if used
    for side in ("left", "right"):
        st = w[side][0]
        st.stride_length_m[4:7] = 0.2
    left, right = phases(w)
    assert list(left.reason).count("turn") == 3 and not left.used[4:7].any()
    s = clinical_summary(left, right, paretic_side="right")
    m = s.measures
    assert m["stride_length_m"].left == pytest.approx(1.0) and m["stride_length_m"].n_left == len(left) - 3
    assert m["gait_speed_m_s"].value == pytest.approx(1.0 / 1.2)
    assert m["step_time_s"].paretic_ratio == pytest.approx(0.50 / 0.70)
    assert any("turning" in n for n in s.notes)


def test_unknown_paretic_side_keeps_the_symmetry_ratio_only():
    left, right = phases(walk())
    m = clinical_summary(left, right, paretic_side=None).measures["swing_time_s"]
    assert np.isnan(m.paretic_ratio) and m.symmetry_ratio > 1.0
    with pytest.raises(ValueError, match="paretic_side"):
        clinical_summary(left, right, paretic_side="paretic")


def test_few_strides_and_one_side_are_flagged():
    w = walk(n=4)
    left, right = phases(w)
    assert clinical_summary(left, right).measures["step_time_s"].flag == "few_strides"
    empty = step_phases(FootStrides(*(np.zeros(0) for _ in range(5))), w["left"][1])
    m = clinical_summary(left, empty).measures["step_time_s"]
    assert m.flag == "one_side" and np.isnan(m.symmetry_ratio) and m.value == pytest.approx(0.70)


def test_common_walking_frame_recovers_step_lengths_from_rotated_feet():
    w = walk(n=10)
    rot = {"left": np.deg2rad(37.0), "right": np.deg2rad(-112.0)}      # each foot's own arbitrary yaw

    def R(a):
        return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    feet = {}
    for side, (st, ev) in w.items():
        o = np.array([0.0, ev.mid_xy[0][1]])       # origin: the foot at the start, feet side by side at x = 0
        rs = lambda p, o=o, a=rot[side]: (np.asarray(p) - o) @ R(a).T     # noqa: E731
        feet[side] = (st, ev, rs(st.start_xy), rs(st.end_xy), rs(ev.mid_xy))
    fixed = {}
    for side, (st, ev, s_xy, e_xy, m_xy) in feet.items():
        M = common_walking_frame(s_xy, e_xy, st.turning_deg)
        assert M is not None
        fixed[side] = (FootStrides(st.pre_ic_s, st.tc_s, st.ic_s, st.stride_length_m, st.turning_deg,
                                   s_xy @ M.T, e_xy @ M.T),
                       FootEvents(ev.ic_s, ev.tc_s, ev.mid_s, m_xy @ M.T))
    left = step_phases(fixed["left"][0], fixed["right"][1])
    right = step_phases(fixed["right"][0], fixed["left"][1])
    np.testing.assert_allclose(left.step_length_m[1:], 0.45)
    np.testing.assert_allclose(right.step_length_m, 0.55)
    assert common_walking_frame(np.zeros((1, 2)), np.zeros((1, 2)), np.zeros(1)) is None


def test_first_and_last_strides_of_a_walk_are_not_used():
    """Gait initiation and termination (C7): with the default one stride at each end of each walk dropped, two
    walks separated by a pause lose two strides each per foot; a short first stride no longer enters the means."""
    w1, w2 = walk(n=8), walk(n=8, t0=30.0)
    both = {}
    for side in ("left", "right"):
        s1, e1 = w1[side]
        s2, e2 = w2[side]
        cat = lambda a, b: np.concatenate([a, b])                      # noqa: E731
        st = FootStrides(cat(s1.pre_ic_s, s2.pre_ic_s), cat(s1.tc_s, s2.tc_s), cat(s1.ic_s, s2.ic_s),
                         cat(s1.stride_length_m, s2.stride_length_m), cat(s1.turning_deg, s2.turning_deg),
                         np.vstack([s1.start_xy, s2.start_xy]), np.vstack([s1.end_xy, s2.end_xy]))
        st.stride_length_m[0] = 0.3                                    # a half stride from standing
        ev = FootEvents(cat(e1.ic_s, e2.ic_s), cat(e1.tc_s, e2.tc_s), cat(e1.mid_s, e2.mid_s),
                        np.vstack([e1.mid_xy, e2.mid_xy]))
        both[side] = (st, ev)
    left, right = phases(both, ClinicalParams())
    assert list(left.reason).count("walk_end") + list(left.reason).count("no_contralateral_tc") == 4
    assert not left.used[0] and not left.used[7] and not left.used[8] and not left.used[-1]
    assert list(right.reason).count("walk_end") == 4 and right.used.sum() == len(right) - 4
    m = clinical_summary(left, right).measures
    assert m["stride_length_m"].left == pytest.approx(1.0)             # the half stride is not in the mean
