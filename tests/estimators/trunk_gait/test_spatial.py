"""Known answers for the inverted-pendulum stride length (stridelab.estimators.trunk_gait._spatial, Zijlstra & Hof 2003 Eq. 1).

A hand-made vertical trunk trajectory whose excursion per step is known (h1 for 15 steps, then h2) is turned into an
upward acceleration (second derivative, plus sensor noise); double integration, per-step excursion and Eq. 1 must
return 2 sqrt(2 l h - h²) for each step. A foot-stride reference helper of the trunk-gait bench is checked on
hand-made strides."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.trunk_gait._spatial import step_lengths, vertical_position

FS = 100.0
L = 0.9          # pendulum length, m
STEP_S = 0.55


def _trajectory(h: np.ndarray, *, drift_acc_m_s2: float = 0.0, seed: int = 0):
    """(upward acc (N,), contact samples (K+1,)) of steps with vertical excursions ``h`` (m): the trunk is lowest at
    each contact and rises by h[k] at mid-step (a smooth raised cosine); 2 s of standing before and after.
    ``drift_acc_m_s2``: a constant accelerometer bias (integrates to a parabola the filters must remove)."""
    t_ic = 2.0 + STEP_S * np.arange(len(h) + 1)
    n = int((t_ic[-1] + 2.0) * FS)
    t = np.arange(n) / FS
    z = np.zeros(n)
    for k in range(len(h)):
        m = (t >= t_ic[k]) & (t < t_ic[k + 1])
        z[m] = h[k] * (1 - np.cos(2 * np.pi * (t[m] - t_ic[k]) / STEP_S)) / 2
    acc = np.gradient(np.gradient(z, 1 / FS), 1 / FS)
    acc = acc + drift_acc_m_s2 + np.random.default_rng(seed).normal(0, 0.05, n)
    return acc, np.round(t_ic * FS).astype(np.int64)


def _expected(h):
    return 2 * np.sqrt(2 * L * h - h * h)          # Zijlstra & Hof 2003 Eq. 1 with K = 1


@pytest.mark.parametrize("drift", [0.0, 0.02])
def test_pendulum_step_length_known_answer(drift):
    h = np.r_[np.full(15, 0.05), np.full(15, 0.025)]       # 0.58 m then 0.42 m steps
    acc, ic = _trajectory(h, drift_acc_m_s2=drift)
    sl = step_lengths(vertical_position(acc, FS, 0.1), ic, L, 1.0)
    assert sl.shape == (30,)
    ratio = sl / _expected(h)
    # every step within 5 %; away from the change of pace and the ends (filter transients) within 2.5 %
    assert np.all(np.abs(ratio - 1) < 0.05), ratio
    inner = np.r_[2:13, 17:26]
    assert np.all(np.abs(ratio[inner] - 1) < 0.025), ratio[inner]
    # the change of pace is seen step by step (no smoothing across it)
    assert sl[:14].mean() > 1.3 * sl[16:].mean()


def test_correction_factor_and_pendulum_length_scale_as_eq1():
    h = np.full(20, 0.04)
    acc, ic = _trajectory(h)
    pos = vertical_position(acc, FS, 0.1)
    base = step_lengths(pos, ic, L, 1.0)
    np.testing.assert_allclose(step_lengths(pos, ic, L, 1.2), 1.2 * base)
    # a longer pendulum gives longer steps, as 2 sqrt(2 l h - h^2)
    longer = step_lengths(pos, ic, 1.2 * L, 1.0)
    hh = (base / 2) ** 2                           # back out 2 l h - h^2 per step, then h
    h_est = L - np.sqrt(L * L - hh)
    np.testing.assert_allclose(longer, 2 * np.sqrt(2 * 1.2 * L * h_est - h_est ** 2), rtol=1e-9)


def test_standing_gives_no_length_and_short_input_is_safe():
    acc = np.random.default_rng(1).normal(0, 0.02, 1000)
    ic = np.arange(200, 800, 55)
    sl = step_lengths(vertical_position(acc, FS, 0.1), ic, L, 1.0)
    assert np.all(sl < 0.1)                        # noise only: a few cm at most
    assert len(step_lengths(np.zeros(10), np.array([3]), L, 1.0)) == 0
    assert np.all(vertical_position(np.ones(8), FS, 0.1) == 0)


def test_foot_stride_reference_counts_contact_to_contact_strides_inside_the_trial():
    from stridelab.validation.bench.trunk_gait import foot_stride_reference
    fs = 100.0
    # left foot: strides [100 -> 220] 1.2 m, [220 -> 340] 1.4 m, [-1 -> 100] first step out of standing (no stride),
    # [340 -> 460] ends after the trial (s1 = 400); right foot: [160 -> 280] 1.0 m, [50 -> 160] starts before s0
    left = (np.array([-1, 100, 220, 340]), np.array([100, 220, 340, 460]), np.array([0.6, 1.2, 1.4, 1.3]))
    right = (np.array([50, 160]), np.array([160, 280]), np.array([1.1, 1.0]))
    sl, speed, n = foot_stride_reference([left, right], 80, 400, fs)
    assert n == 3
    assert sl == pytest.approx((1.2 + 1.4 + 1.0) / 3)
    assert speed == pytest.approx((1.2 / 1.2 + 1.4 / 1.2 + 1.0 / 1.2) / 3)
    sl0, sp0, n0 = foot_stride_reference([right], 300, 400, fs)
    assert n0 == 0 and np.isnan(sl0) and np.isnan(sp0)


def test_step_heading_change_cancels_pelvic_sway_and_finds_a_turn():
    from stridelab.estimators.trunk_gait._spatial import step_heading_change, turn_shortened
    n_steps = 20
    ic = (2.0 + STEP_S * np.arange(n_steps + 1)) * FS
    ic = np.round(ic).astype(np.int64)
    t = np.arange(int(ic[-1] + 2 * FS)) / FS
    # pelvic yaw sway: ±5° at the stride frequency (one period per two steps), no net heading change
    sway_rate = np.deg2rad(5.0) * (2 * np.pi / (2 * STEP_S)) * np.cos(2 * np.pi * t / (2 * STEP_S))
    d = step_heading_change(sway_rate, FS, ic)
    assert d.shape == (n_steps,)
    assert np.max(np.abs(d)) < np.deg2rad(1.0)
    # plus a 180° turn over steps 8-11 (45° per step at a constant rate)
    turn_rate = np.zeros_like(t)
    turn_rate[ic[8]:ic[12]] = np.pi / (ic[12] - ic[8]) * FS
    d = step_heading_change(sway_rate + turn_rate, FS, ic)
    np.testing.assert_allclose(d[9:11], np.pi / 4, atol=np.deg2rad(2.0))
    assert np.all(np.abs(d[:6]) < np.deg2rad(1.0)) and np.all(np.abs(d[14:]) < np.deg2rad(1.0))
    # turning steps shortened as step / (1 + c |Δψ|); straight steps untouched; c = 0 is off
    steps = np.full(n_steps, 0.6)
    short = turn_shortened(steps, d, 0.2)
    np.testing.assert_allclose(short[9:11], 0.6 / (1 + 0.2 * np.pi / 4), rtol=0.01)
    np.testing.assert_allclose(short[:6], 0.6, rtol=0.002)
    np.testing.assert_array_equal(turn_shortened(steps, d, 0.0), steps)
    assert len(step_heading_change(sway_rate, FS, ic[:1])) == 0


def _pendulum_walk(speed_m_s: float, step_s: float, leg_m: float, n_steps: int, seed: int = 0):
    """(upward acc (N,), contact samples (K+1,)) of an inverted pendulum walking at a constant forward speed: in
    each step the trunk is at sqrt(l² - x²) above the stance foot, x the forward distance from it (-s/2 .. s/2,
    s = speed x step time), the stance foot changes at each contact (the trunk is lowest there); 2 s of standing
    before and after, sensor noise. The physics, not Eq. 1 itself: the excursion of each step is l - sqrt(l² - s²/4)."""
    fs = FS
    t_ic = 2.0 + step_s * np.arange(n_steps + 1)
    n = int((t_ic[-1] + 2.0) * fs)
    t = np.arange(n) / fs
    z = np.full(n, np.sqrt(leg_m ** 2 - (speed_m_s * step_s / 2) ** 2))
    w = (t >= t_ic[0]) & (t < t_ic[-1])
    x = speed_m_s * (((t[w] - t_ic[0]) % step_s) - step_s / 2)
    z[w] = np.sqrt(leg_m ** 2 - x ** 2)
    acc = np.gradient(np.gradient(z, 1 / fs), 1 / fs) + np.random.default_rng(seed).normal(0, 0.02, n)
    return acc, np.round(t_ic * fs).astype(np.int64)


@pytest.mark.parametrize("speed, step_s", [(0.3, 1.1), (0.6, 0.75), (1.3, 0.53)], ids=["0.3_m_s", "0.6_m_s", "1.3_m_s"])
def test_pendulum_physics_step_length_from_slow_to_fast_walking(speed, step_s):
    # slow pathological walking (0.3 m/s, 55 steps/min: a 0.33 m step rises the trunk by only 16 mm) to fast
    leg = 0.85
    acc, ic = _pendulum_walk(speed, step_s, leg, 20)
    sl = step_lengths(vertical_position(acc, FS, 0.1), ic, leg, 1.0)
    inner = sl[2:-2]                               # away from the filter transients at the ends
    np.testing.assert_allclose(inner, speed * step_s, rtol=0.05)


def test_bout_spatial_averages_the_strides_as_the_references_define_them():
    from stridelab.estimators.trunk_gait._pipeline import bout_spatial
    # bout 0: four strides of 1.0 s, 1.2 m and one hesitating 2.0 s stride of 0.4 m (a real, slow stride: INDIP
    # and the foot-INS reference average every stride of the bout); bout 1: 0.8 m strides of 1.0 s
    length = np.array([1.2, 1.2, 0.4, 1.2, 1.2, 0.8, 0.8, 0.8])
    dur = np.array([1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    bout = np.array([0, 0, 0, 0, 0, 1, 1, 1])
    cad = np.array([100.0, 120.0])
    kw = dict(speed_method="stride")
    sl, sp = bout_spatial(length, dur, bout, cad, average="mean", strides="regular", **kw)
    assert sl[0] == pytest.approx(1.2) and sp[0] == pytest.approx(1.2)        # the 2 s stride (> 1.5 x 1 s) left out
    sl, sp = bout_spatial(length, dur, bout, cad, average="mean", strides="all", **kw)
    assert sl[0] == pytest.approx((4 * 1.2 + 0.4) / 5) and sp[0] == pytest.approx((4 * 1.2 + 0.2) / 5)
    sl, sp = bout_spatial(length, dur, bout, cad, average="median", strides="all", **kw)
    assert sl[0] == pytest.approx(1.2) and sp[0] == pytest.approx(1.2)
    # time average: strides weighted by duration; speed = distance / time
    sl, sp = bout_spatial(length, dur, bout, cad, average="time", strides="all", **kw)
    assert sl[0] == pytest.approx((4 * 1.2 + 0.4 * 2) / 6) and sp[0] == pytest.approx(5.2 / 6)
    # speed from cadence: bout stride length x steps/min / 120
    sl, sp = bout_spatial(length, dur, bout, cad, average="mean", strides="all", speed_method="cadence")
    assert sp[0] == pytest.approx(sl[0] * 100 / 120) and sp[1] == pytest.approx(0.8 * 120 / 120)
    assert np.allclose(sl[1], 0.8)
    for bad in (dict(average="mode"), dict(strides="some"), dict(speed_method="gps")):
        args = dict(average="mean", strides="all", speed_method="stride") | bad
        with pytest.raises(ValueError, match=next(iter(bad)).replace("average", "bout_average")
                           .replace("strides", "bout_strides")):
            bout_spatial(length, dur, bout, cad, **args)


def test_step_tilt_and_the_lean_gate_leave_out_a_sit_to_walk_stride():
    from stridelab.estimators.trunk_gait._pipeline import bout_spatial
    from stridelab.estimators.trunk_gait._spatial import step_tilt_deg
    # gravity seen by a trunk leaning 20° forward for the first two steps (still rising from a chair), upright after
    g = 9.80665
    ic = np.arange(0, 700, 100)
    lean = np.where(np.arange(700) < 200, np.deg2rad(20.0), 0.0)
    acc = np.column_stack([g * np.sin(lean), g * np.cos(lean), np.zeros(700)])
    acc[:, 1] += 1.5 * np.sin(2 * np.pi * np.arange(700) / 100)      # step oscillation averages out per step
    tilt = step_tilt_deg(acc, ic)
    np.testing.assert_allclose(tilt, [20, 20, 0, 0, 0, 0], atol=0.5)
    # the strides that lean are left out of the bout value when the gate is on, kept when off
    length = np.array([1.9, 1.4, 1.0, 1.0, 1.02])
    stride_tilt = np.array([20.0, 10.0, 0.0, 0.0, 0.0])
    dur = np.ones(5)
    kw = dict(average="mean", strides="all", speed_method="stride", tilt_deg=stride_tilt)
    assert bout_spatial(length, dur, np.zeros(5, int), np.array([110.0]), max_tilt_deg=0.0, **kw)[0][0] == \
        pytest.approx(length.mean())
    assert bout_spatial(length, dur, np.zeros(5, int), np.array([110.0]), max_tilt_deg=15.0, **kw)[0][0] == \
        pytest.approx(length[1:].mean())
    # a bout whose every stride leans keeps them all (no empty bout)
    assert np.isfinite(bout_spatial(length[:1], dur[:1], np.zeros(1, int), np.array([110.0]), max_tilt_deg=15.0,
                                    **(kw | dict(tilt_deg=stride_tilt[:1])))[0][0])
