"""The Mobilise-D cadence detectors Shin-improved and HKLee-improved (``_icd_cwt``), the peak timing of their
contacts and the per-second / per-step cadence, on hand-made signals of known answer."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from stridelab.estimators.trunk_gait import TrunkGaitParams, analyse_trunk_gait
from stridelab.estimators.trunk_gait._icd import detect_initial_contacts
from stridelab.estimators.trunk_gait._icd_cwt import (cwt_chain_signal, detect_initial_contacts_hklee,
                                                      detect_initial_contacts_shin, refine_to_peaks,
                                                      rising_zero_crossings, run_maxima)
from stridelab.estimators.trunk_gait._pipeline import bout_cadence, per_second_cadence
from tests.estimators.trunk_gait._signals import walking_body

FS = 100.0


def test_rising_zero_crossings_are_interpolated_between_samples():
    y = np.array([1.0, -1.0, -3.0, 1.0, 2.0, -2.0, 0.0, 0.5, -1.0, -1.0, 3.0])
    # rising: 2 -> 3 (-3 to 1: 2 + 3/4), 5 -> 6 (-2 to 0: exactly at 6), 9 -> 10 (-1 to 3: 9 + 1/4)
    pos, height = rising_zero_crossings(y)
    np.testing.assert_allclose(pos, [2.75, 6.0, 9.25])
    np.testing.assert_allclose(height, [2.0, 0.5, 3.0])                 # max of the positive lobe each opens
    assert rising_zero_crossings(np.ones(5))[0].size == 0


def test_run_maxima_one_per_positive_run_of_at_least_min_len():
    r = np.array([0.0, 1.0, 3.0, 2.0, 0.0, 5.0, 0.0, 0.0, 1.0, 4.0, 4.5, 0.0])
    assert run_maxima(r, 2).tolist() == [2, 10]              # the single-sample run at 5 is dropped (source)
    assert run_maxima(r, 1).tolist() == [2, 5, 10]
    assert run_maxima(r, 1, 4.0).tolist() == [5, 10]                    # runs whose maximum reaches 4


@pytest.mark.parametrize("f", [1.0, 1.8, 2.2], ids=["slow_60_spm", "108_spm", "132_spm"])
def test_chain_is_zero_phase_so_contacts_fall_at_known_phases_of_a_sinusoid(f):
    # a = sin(2 pi f t): every step of the chain is zero-phase (Savitzky-Golay, forward-backward band-pass,
    # Gaussians) and the two second-derivative wavelets give (2 pi f)^4 > 0, so y = g sin(2 pi f t) with g > 0:
    # Shin's rising zero crossings at t = k / f, HKLee's closing-minus-opening maxima at the peaks t = (k + 1/4) / f
    t = np.arange(0, 30, 1 / FS)
    a = np.sin(2 * np.pi * f * t)
    y = cwt_chain_signal(a, FS)
    mid = (t > 4) & (t < 26)
    assert np.corrcoef(y[mid], a[mid])[0, 1] > 0.999
    shin = detect_initial_contacts_shin(a, FS) / FS
    hk = detect_initial_contacts_hklee(a, FS) / FS
    for det, phase in ((shin, 0.0), (hk, 0.25)):
        d = det[(det > 4.013) & (det < 25.987)]
        want = (np.arange(0, 40 * f) + phase) / f
        want = want[(want > 4.013) & (want < 25.987)]
        assert len(d) == len(want)
        np.testing.assert_allclose(d, want, atol=1.5 / FS)


def test_shin_and_hklee_count_the_small_steps_of_slow_walking_that_the_prominence_threshold_misses():
    # one gait sequence: 10 s of brisk steps, then 10 s of slow shuffling steps with a fifth of the vertical
    # acceleration (slow walking inside a longer sequence, as the Mobilise-D course; HA-001 Test11): the peak
    # detector's threshold (0.7 SD of the whole sequence) drops the small steps, the amplitude-free detectors
    # count one contact per step cycle whatever its amplitude
    t = np.arange(0, 24, 1 / FS)
    ic = np.r_[np.arange(2.0, 12.0, 0.55), np.arange(12.2, 22.0, 0.7)]
    amp = np.where(ic < 12.0, 2.0, 0.4)
    a = sum(k * np.exp(-0.5 * ((t - c) / 0.07) ** 2) for k, c in zip(amp, ic))
    a = a - a.mean()
    slow = ic[ic > 13.0]
    slow = slow[slow < 21.0]
    peak = detect_initial_contacts(a, FS, smooth_s=0.11, min_step_s=0.25, prominence=0.7) / FS
    found = lambda det: int(sum(np.min(np.abs(det - c)) < 0.2 for c in slow))   # noqa: E731
    assert found(peak) < len(slow) // 2
    for det in (detect_initial_contacts_shin(a, FS) / FS, detect_initial_contacts_hklee(a, FS) / FS):
        assert found(det) == len(slow)
        inside = det[(det > 13.0) & (det < 21.0)]
        assert len(inside) == len(slow)                         # one per step, no extra


def test_norm_input_does_not_depend_on_how_the_sensor_is_worn():
    acc, gyr, ic_true, _ = walking_body(30.0, rest_s=2.0, step_s=0.55)
    R = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])         # axes permuted
    a1 = np.linalg.norm(acc, axis=1)
    a2 = np.linalg.norm(acc @ R.T, axis=1)
    np.testing.assert_allclose(detect_initial_contacts_shin(a1, FS), detect_initial_contacts_shin(a2, FS))


def test_refine_moves_each_contact_to_the_nearest_acceleration_peak():
    vs = np.zeros(100)
    vs[[20, 50, 53, 80]] = [1.0, 2.0, 1.5, 1.0]
    # 15 -> 20; 48 -> 50 (50 beats 53); 55 -> 53 is within min_gap 5 of 50: dropped; 95 -> 80 is beyond half 10: 90
    assert refine_to_peaks(np.array([15, 48, 55, 95]), vs, 10, 5).tolist() == [20, 50, 85]


@pytest.mark.parametrize("method", ["shin", "hklee"])
def test_pipeline_with_the_cwt_detectors_finds_every_simulated_step(method):
    step_s = 0.55
    acc, gyr, ic_true, _ = walking_body(40.0, rest_s=3.0, step_s=step_s)
    p = dataclasses.replace(TrunkGaitParams(), ic_method=method, ic_refine_s=0.15, ic_offset_s=0.0,
                            ic_zc_min_depth=0.0)
    det = analyse_trunk_gait(acc, gyr, FS, height_m=1.75, params=p).initial_contacts_s
    hit = np.array([np.min(np.abs(det - x)) for x in ic_true])
    inner = (ic_true > 3.0 + 2 * step_s) & (ic_true < 43.0 - 2 * step_s)
    # timed by the upward-acceleration peak, which is the simulated contact
    assert np.all(hit[inner] < 0.015)
    # as the source (no amplitude gate) the standing still inside the gait sequence (its windows reach into the
    # rest) gives crossings of sensor noise; the gate of 0.3 SD of the filtered signal drops them. (Within 1 s of
    # the walk the zero-phase chain rings before the first and after the last step, a full-height lobe the gate
    # keeps, as _icd_ionescu.)
    standing = lambda x: int(np.sum((x < ic_true[0] - 1.0) | (x > ic_true[-1] + 1.0)))   # noqa: E731
    assert standing(det) >= 1
    gated = analyse_trunk_gait(acc, gyr, FS, height_m=1.75,
                               params=dataclasses.replace(p, ic_zc_min_depth=0.3)).initial_contacts_s
    assert standing(gated) == 0
    hit = np.array([np.min(np.abs(gated - x)) for x in ic_true])
    assert np.all(hit[inner] < 0.015)
    with pytest.raises(ValueError, match="ic_cwt_signal"):
        analyse_trunk_gait(acc, gyr, FS, params=dataclasses.replace(p, ic_cwt_signal="ml"))


def test_per_second_cadence_ignores_a_missed_contact_and_step_mean_is_the_mean_step_rate():
    ic = np.arange(0, 12.01, 0.5)                                        # 120 steps/min
    assert per_second_cadence(ic, max_step_s=1.5) == pytest.approx(120.0)
    missed = np.delete(ic, 9)                                           # one 1.0 s interval
    assert per_second_cadence(missed, max_step_s=1.5) == pytest.approx(120.0)
    # the plain mean of 60 / step time reads the missed contact as one 60 steps/min step
    d = np.diff(missed)
    assert bout_cadence(missed, max_step_s=1.5, method="step_mean") == pytest.approx(np.mean(60 / d))
    assert bout_cadence(missed, max_step_s=1.5, method="step_mean") < 118.0
    # a slower second half: the per-second mean weights the seconds, 0.5 s steps for 6 s then 0.75 s for 6 s
    two = np.r_[np.arange(0, 6.0, 0.5), 6.0 + np.arange(0, 6.01, 0.75)]
    assert per_second_cadence(two, max_step_s=1.5) == pytest.approx((6 * 120 + 6 * 80) / 12, rel=0.03)
    assert np.isnan(per_second_cadence(ic[:4], max_step_s=1.5))


def test_stride_mean_cadence_is_the_mean_of_120_over_stride_time_as_the_indip_reference():
    # strides IC_i -> IC_{i+2}: steps of 0.5 s then 0.6 s alternate, every stride lasts 1.1 s -> 120 / 1.1
    ic = np.cumsum(np.r_[0.0, np.tile([0.5, 0.6], 6)])
    assert bout_cadence(ic, max_step_s=1.5, method="stride_mean") == pytest.approx(120 / 1.1)
    # a stop of 2 s inside the bout: the strides over it (2.5 s, 2.6 s <= 2 x max_step_s) count, as INDIP's
    stop = np.r_[ic, ic[-1] + 2.0, ic[-1] + 2.5]
    st = stop[2:] - stop[:-2]
    assert bout_cadence(stop, max_step_s=1.5, method="stride_mean") == pytest.approx(np.mean(120 / st))
    assert bout_cadence(stop, max_step_s=1.5, method="stride_mean") < 120 / 1.1
    # a stride longer than 2 x max_step_s is a pause, not a stride
    pause = np.r_[ic, ic[-1] + 4.0, ic[-1] + 4.5, ic[-1] + 5.0]
    st = pause[2:] - pause[:-2]
    assert bout_cadence(pause, max_step_s=1.5, method="stride_mean") == pytest.approx(np.mean(120 / st[st <= 3.0]))
    assert np.isnan(bout_cadence(ic[:2], max_step_s=1.5, method="stride_mean"))
