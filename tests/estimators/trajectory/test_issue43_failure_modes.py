"""Issue 43: one test per diagnosed failure mode of the foot trajectory, each on a hand-made signal or a short real
excerpt where the pre-issue-43 code fails (checked once against a copy of that code; see the commit message).
Thresholds are the issue's targets or a-priori bounds, not figures read off this code's output."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.trajectory import EskfParams, ZuptParams, detect_zupt, eskf_trajectory
from stridelab.estimators.trajectory._saturation import repair_gyro_saturation
from tests.conftest import shared_data

FS = 200.0


def _runs(mask):
    d = np.diff(np.concatenate([[0], np.asarray(mask, np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


# ---------------------------------------------------------------- stance detector: the quietest window per cycle

def _running_like(n_cycles=12, period_s=0.7, quiet=(0.05, 0.6), seed=0):
    """Gyro/acc of a running-like foot: per cycle a short stance whose rate alternates between ``quiet`` values
    (one stance nearly still, the next rolling at 0.6 rad/s), then a 10 rad/s swing; |f| = g in stance."""
    rng = np.random.default_rng(seed)
    n_c = int(round(period_s * FS))
    n_st = int(round(0.12 * FS))
    gyr, acc, stance = [], [], []
    lead = int(FS)                                                         # 1 s quiet start
    gyr.append(np.tile([0.0, 0.01, 0.0], (lead, 1)))
    acc.append(np.tile([0.0, 0.0, 9.81], (lead, 1)))
    stance.append(np.ones(lead, bool))
    for c in range(n_cycles):
        q = quiet[c % 2]
        g = np.zeros((n_c, 3))
        g[:n_st, 1] = q
        t = np.arange(n_c - n_st) / (n_c - n_st)
        g[n_st:, 1] = 10.0 * np.sin(2 * np.pi * t)
        g[n_st:, 0] = 2.0 * np.sin(np.pi * t)
        a = np.tile([0.0, 0.0, 9.81], (n_c, 1))
        a[n_st:, 0] += 30.0 * np.sin(2 * np.pi * t)
        a[n_st:, 2] += 20.0 * np.sin(np.pi * t)
        gyr.append(g + rng.normal(0, 0.005, g.shape))
        acc.append(a + rng.normal(0, 0.02, a.shape))
        st = np.zeros(n_c, bool)
        st[:n_st] = True
        stance.append(st)
    return np.concatenate(gyr), np.concatenate(acc), np.concatenate(stance)


def test_every_gait_cycle_gets_its_quietest_window_as_stance():
    """Pre-issue-43: the threshold followed the quietest stance within ±1 s (3 × 0.05 → θ_lo = 0.3 rad/s), so
    every rolling stance (0.6 rad/s) was missed. Now each cycle's quietest window is stance (bound θ_hi = 3)."""
    gyr, acc, truth = _running_like()
    z = detect_zupt(gyr, acc, sampling_rate_hz=FS)
    stances = [(a, b) for a, b in _runs(truth)][1:]                        # the 12 cycle stances
    missed = [(a, b) for a, b in stances if not z[a:b].any()]
    assert not missed, f"{len(missed)} of {len(stances)} stances without a zero-velocity sample"
    swing = ~truth
    assert z[swing].mean() < 0.02                                          # the swing stays swing


def test_quietest_window_has_a_physical_bound():
    """A cycle whose quietest moment is above θ_hi (here 4 rad/s: no foot stands still like that) gets no stance."""
    gyr, acc, truth = _running_like(quiet=(4.0, 4.0))
    z = detect_zupt(gyr, acc, sampling_rate_hz=FS)
    assert not z[int(FS):].any()


@pytest.mark.realdata
@pytest.mark.slow
def test_running_trials_miss_few_still_phases():
    """PyShoe running trials 2017-11-27-11-1*: every still phase of the oracle labels (PyShoe's zv_shoe_opt,
    thresholds optimised per trial against Vicon; runs ≥ 3 samples) should hold at least one detected
    stance sample. Pre-issue-43: 34 of 115 missed on these files. Bound: at most one in ten (a priori)."""
    from stridelab.pipeline.formats.pyshoe import load_pyshoe_trial
    d = shared_data("pyshoe_vicon")
    files = sorted(d.glob("2017-11-27-11-1*.mat"))
    if not files:
        pytest.skip("PyShoe running trials 2017-11-27-11-1* not found")
    miss = tot = 0
    for f in files:
        tr = load_pyshoe_trial(f)
        z = detect_zupt(tr.gyr, tr.acc, sampling_rate_hz=tr.sampling_rate_hz)
        for a, b in _runs(tr.oracle_zv["shoe"]):
            if b - a >= 3:
                tot += 1
                miss += not z[a:b].any()
    assert tot > 50
    assert miss <= 0.1 * tot, f"{miss} of {tot} oracle still phases missed"


# ---------------------------------------------------------------- noise model: running

@pytest.mark.realdata
@pytest.mark.slow
def test_running_trajectory_meets_the_issue_target():
    """The shipped defaults on the PyShoe running trials 2017-11-27-11-1* (fast running, clipped gyro, 60–100 m/s²
    impacts): mean 2-D ARMSE ≤ 0.20 m (issue 43's running target). Pre-issue-43 defaults (c_a = 0.3 on every
    sample, c_g = 0.01, ±1 s detector): 0.22 m. In-sample for the defaults (chosen on these trials, among others)."""
    from stridelab.estimators.trajectory.evaluation import armse_2d_aligned
    from stridelab.pipeline.formats.pyshoe import load_pyshoe_trial
    d = shared_data("pyshoe_vicon")
    files = sorted(d.glob("2017-11-27-11-1*.mat"))
    if not files:
        pytest.skip("PyShoe running trials 2017-11-27-11-1* not found")
    e = []
    for f in files:
        tr = load_pyshoe_trial(f)
        r = eskf_trajectory(tr.gyr, tr.acc, sampling_rate_hz=tr.sampling_rate_hz)
        e.append(armse_2d_aligned(r.pos, tr.position)[0])
    assert np.mean(e) <= 0.20, e


def test_phase_noise_model_keeps_the_impact_term_out_of_stance():
    """(E4d, the option ``noise_model="phase"``; the default stays "global", chosen by leave-one-trial-out) An impact
    next to a stance must not make the stance's own accelerometer noise large: with the pre-issue-43 model σ_a at
    the stance samples beside a 60 m/s² impact was ≈ 0.5 + 0.3·50 m/s²; a ZUPT then cannot hold the velocity.
    Checked through the filter: the smoothed speed at those stance samples."""
    gyr, acc, truth = _running_like(quiet=(0.05, 0.05))
    for a, _ in _runs(truth)[1:]:
        acc[a - 3:a + 3, 2] += 60.0                                        # heel-strike transient at the border
    r = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, zupt=truth, params=EskfParams(noise_model="phase"))
    st = truth.copy()
    st[:int(FS)] = False
    speed = np.linalg.norm(r.vel[st], axis=1)
    assert np.percentile(speed, 95) < 0.05, np.percentile(speed, 95)


# ---------------------------------------------------------------- saturation: only plateaus near full scale

def _peaks(tops, flat=False, n_per=60):
    """One gyro axis: a series of swing peaks with the given tops; ``flat`` clips them at min(tops)."""
    t = np.linspace(-1, 1, n_per)
    x = np.concatenate([top * (1 - t ** 2) ** 2 for top in tops])
    if flat:
        x = np.minimum(x, min(tops) + 1e-3 * np.sin(np.arange(len(x))))
    g = np.zeros((len(x), 3))
    g[:, 1] = x
    return g


def test_curved_peaks_near_the_maximum_are_not_clipping():
    """Walking-like curved peaks of 8.8–9.0 rad/s (all within 3 % of the maximum, each ≥ 2 samples there): the
    pre-issue-43 rule called the axis clipped and 'rebuilt' peaks that were whole. Now only flat tops count."""
    g = _peaks([9.0, 8.9, 8.95, 8.8, 8.98, 8.85])
    rep, extra, clipped = repair_gyro_saturation(g)
    assert not clipped.any()
    np.testing.assert_array_equal(rep, g)
    assert not extra.any()


def test_flat_plateaus_near_full_scale_are_clipping():
    g = _peaks([12.0, 11.0, 13.0, 12.5], flat=True)                       # clipped at 11 rad/s
    rep, extra, clipped = repair_gyro_saturation(g)
    assert clipped[1] and not clipped[0] and not clipped[2]
    assert np.abs(rep[:, 1]).max() > 11.5                                  # peaks rebuilt above the plateau


# ---------------------------------------------------------------- gyro bias: not from a 1 s stance

def test_gyro_bias_is_not_taken_from_one_stance():
    """True bias 0.005 rad/s on z; the first stance (1 s) holds a settling rotation of 0.05 rad/s. The mean of
    that stance (the pre-issue-43 ``initial_gyro_bias``) is off by 10×; the all-stance median is within 2 mrad/s."""
    from stridelab.estimators.trajectory import stance_gyro_bias
    rng = np.random.default_rng(1)
    b = np.array([0.0, 0.0, 0.005])
    gyr, acc, truth = _running_like(n_cycles=40, quiet=(0.0, 0.0))
    gyr = gyr + b
    gyr[:int(FS), 2] += 0.05 * np.hanning(int(FS)) * 2                      # settling rotation in the first stance
    gyr += rng.normal(0, 0.003, gyr.shape)
    first = _runs(truth)[0]
    old_style = gyr[first[0]:first[1]].mean(axis=0)                         # what the removed option computed
    assert abs(old_style[2] - b[2]) > 0.02
    new = stance_gyro_bias(gyr, truth, sampling_rate_hz=FS)
    assert np.all(np.abs(new - b) < 0.002), new


def test_gyro_bias_needs_enough_stance():
    from stridelab.estimators.trajectory import stance_gyro_bias
    gyr, acc, truth = _running_like(n_cycles=2)
    truth[int(FS):] = False                                                # one 1 s stance only
    np.testing.assert_array_equal(stance_gyro_bias(gyr + 0.01, truth, sampling_rate_hz=FS), np.zeros(3))


# ---------------------------------------------------------------- height drift, 3-D errors, flat-floor option

def test_flat_floor_stance_height_update_removes_height_drift():
    """A level walk with an accelerometer z bias of 0.2 m/s²: without the option the stance height drifts
    (the ZUPT alone does not see it); with ``stance_height_var`` (E5c, off by default) every stance is at the
    first one's height within 5 mm. Horizontal accuracy is unchanged (within 2 cm)."""
    from stridelab.validation.simulator.foot_walk_yun import simulate_yun_walk
    sim = simulate_yun_walk(20, sampling_rate_hz=200, noise_scale=1.0, seed=3, stride_m=1.2, height_m=0.12)
    acc = sim.acc + np.array([0.0, 0.0, 0.2])
    z = np.asarray(sim.stance, bool)
    off = eskf_trajectory(sim.gyr, acc, sampling_rate_hz=200, zupt=z)
    on = eskf_trajectory(sim.gyr, acc, sampling_rate_hz=200, zupt=z, params=EskfParams(stance_height_var=1e-4))
    k0 = off.start_idx
    h_off = off.pos[z, 2] - off.pos[k0, 2]
    h_on = on.pos[z, 2] - on.pos[k0, 2]
    assert np.abs(h_off).max() > 0.02
    assert np.abs(h_on).max() < 0.005
    fin = off.pos[z][:, :2] - on.pos[z][:, :2]
    assert np.abs(fin).max() < 0.02


def test_armse_3d_sees_the_height_error_2d_hides():
    from stridelab.estimators.trajectory.evaluation import armse_2d_aligned, armse_3d_aligned, final_position_error
    t = np.linspace(0, 10, 1001)
    ref = np.column_stack([t, np.zeros_like(t), np.zeros_like(t)])
    est = ref.copy()
    est[:, 2] = 0.01 * t                                                   # 10 mm per metre of height drift
    assert armse_2d_aligned(est, ref)[0] == pytest.approx(0.0, abs=1e-9)
    assert armse_3d_aligned(est, ref) == pytest.approx(0.05, rel=1e-3)     # mean of 0.01 t over 0–10 s
    xy, e3 = final_position_error(np.array([[0, 0, 0], [3.0, 4.0, 12.0]]))
    assert (xy, e3) == (5.0, 13.0)


def test_gait_cycle_period_finds_the_stride_and_not_noise():
    from stridelab.estimators.trajectory import gait_cycle_period
    gyr, _, _ = _running_like(n_cycles=20, period_s=0.7)
    per = gait_cycle_period(gyr, sampling_rate_hz=FS)
    assert np.nanmedian(per[int(2 * FS):]) == pytest.approx(0.7, abs=0.02)
    noise = np.random.default_rng(0).normal(0, 1.0, (int(20 * FS), 3))
    assert np.isnan(gait_cycle_period(noise, sampling_rate_hz=FS)).all()
    assert np.isnan(gait_cycle_period(np.zeros((50, 3)), sampling_rate_hz=FS)).all()


# ---------------------------------------------------------------- attitude timing: the midpoint rule (E1c)

def _smooth_strides(fs, n=20, stride_m=1.2, stance_s=0.6, swing_s=0.5, pitch_rad=0.6, lift_m=0.1):
    """A foot whose rate and acceleration are continuous and sampled at the instants t_k (as a real IMU samples):
    per stride a still stance, then a swing u ∈ [0, 1) with pitch θ = A sin³(2πu) about the sensor y axis, forward
    x = L (u − sin(2πu)/2π) and height z = h/2 (1 − cos 2πu). Returns gyr, specific force (sensor frame), the
    walked distance."""
    T = 1.0 / fs
    t = np.arange(int((2.0 + n * (stance_s + swing_s)) * fs)) * T - 1.0
    k = np.floor(t / (stance_s + swing_s))
    u = (t - k * (stance_s + swing_s) - stance_s) / swing_s
    sw = (t >= 0) & (k < n) & (u >= 0)
    s2, c2 = np.sin(2 * np.pi * u), np.cos(2 * np.pi * u)
    th = np.where(sw, pitch_rad * s2 ** 3, 0.0)
    thd = np.where(sw, pitch_rad * 3 * s2 ** 2 * c2 * 2 * np.pi / swing_s, 0.0)
    ax = np.where(sw, stride_m * 2 * np.pi * s2 / swing_s ** 2, 0.0)
    az = np.where(sw, 0.5 * lift_m * (2 * np.pi) ** 2 * c2 / swing_s ** 2, 0.0)
    c, s = np.cos(th), np.sin(th)
    fz = az + 9.81
    acc = np.column_stack([c * ax - s * fz, np.zeros_like(t), s * ax + c * fz])       # R_y(θ)ᵀ (a + g e_z)
    gyr = np.column_stack([np.zeros_like(t), thd, np.zeros_like(t)])
    return gyr, acc, n * stride_m


@pytest.mark.parametrize("fs", [100.0, 200.0])
def test_midpoint_attitude_removes_the_per_stride_height_drift(fs):
    """Issue 43: height drifted 10–15 mm per stride on PyShoe walks. With forward-Euler attitude (E1 with ω_k) the
    attitude is half a sample behind the accelerometer sample it rotates: on a noise-free, exactly sampled swing
    the foot climbs several mm per stride (about 9 mm at 100 Hz). The midpoint rule (E1c) must keep it below 5 mm per
    stride (a third of the issue's lower figure, a priori) at 100 and 200 Hz, and the walked distance within 1 %."""
    import dataclasses
    import warnings
    gyr, acc, dist = _smooth_strides(fs)
    n = 20
    out = {}
    for rule in ("euler", "midpoint"):
        p = dataclasses.replace(EskfParams(), attitude_rule=rule, gyro_delay_s=0.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = eskf_trajectory(gyr, acc, sampling_rate_hz=fs, params=p)
        k = np.flatnonzero(r.zupt)
        e = r.pos[k[-1]] - r.pos[k[0]]
        out[rule] = (abs(e[2]) / n, np.hypot(e[0], e[1]))
    if fs == 100.0:
        assert out["euler"][0] > 0.005, out                   # the failure the rule fixes (not a fit of this code)
    assert out["midpoint"][0] < 0.005, out
    assert abs(out["midpoint"][1] / dist - 1) < 0.01, out


def test_gyro_delay_shifts_the_attitude_rate_by_the_stated_time():
    """(E1c) ``gyro_delay_s`` = d pairs accelerometer sample k with the gyro at t_k + d: a rate ramp ω = c·t comes out
    as c·(t_k + T/2 + d) with the midpoint rule and c·t_k with Euler and no delay (interpolation, held at the end)."""
    import dataclasses

    from stridelab.estimators.trajectory._api import _attitude_gyro
    fs = 100.0
    t = np.arange(50) / fs
    gyr = np.column_stack([0.3 * t, np.zeros(50), np.zeros(50)])
    mid = _attitude_gyro(gyr, dataclasses.replace(EskfParams(), gyro_delay_s=0.002), fs)
    np.testing.assert_allclose(mid[:-1, 0], 0.3 * (t[:-1] + 0.005 + 0.002), atol=1e-12)
    eul = _attitude_gyro(gyr, dataclasses.replace(EskfParams(), attitude_rule="euler", gyro_delay_s=0.0), fs)
    np.testing.assert_array_equal(eul, gyr)
    with pytest.raises(ValueError, match="attitude_rule"):
        _attitude_gyro(gyr, dataclasses.replace(EskfParams(), attitude_rule="rk4"), fs)
