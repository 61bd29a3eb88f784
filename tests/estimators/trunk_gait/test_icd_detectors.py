"""Initial-contact detectors on hand-made signals of known answer: the jerk-lobe detector after Paraschiv-Ionescu et
al. 2020 (``_icd_ionescu``), the closing-step fill and the turn threshold of the peak detector (``_icd``), closing
steps in the pipeline and the count cadence."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.signal import butter, sosfreqz

from stridelab.estimators.trunk_gait import TrunkGaitParams, analyse_trunk_gait
from stridelab.estimators.trunk_gait._icd import detect_initial_contacts, fill_missed_steps
from stridelab.estimators.trunk_gait._icd_ionescu import (IONESCU_BAND_HZ, IONESCU_SIGMA_S, detect_initial_contacts_ionescu,
                                                ionescu_signal, lobe_minima)
from tests.estimators.trunk_gait._signals import walking_body

FS = 100.0


def test_lobe_minima_one_minimum_per_closed_negative_lobe():
    w = np.array([1.0, -1.0, -3.0, -2.0, 1.0, 2.0, -0.5, 0.5, 1.0, -4.0, -1.0, 2.0, -5.0, -6.0])
    # lobes: [1, 4) min at 2; [6, 7) min at 6; [9, 11) min at 9; [12, end) still open -> not counted
    assert lobe_minima(w, 0.0, 1).tolist() == [2, 6, 9]
    assert lobe_minima(w, 1.0, 1).tolist() == [2, 9]                  # the shallow lobe (-0.5) is dropped
    assert lobe_minima(w, 0.0, 4).tolist() == [2, 9]                  # 6 is within 4 samples of 2: the deeper stays
    assert lobe_minima(-np.ones(10), 0.0, 1).tolist() == []           # starts negative: no opening crossing


def test_ionescu_signal_is_the_smoothed_jerk():
    # Eq. (3): for a sinusoid the smoothed derivative is the derivative times the zero-phase band-pass gain |H|^2
    # and the Gaussian's gain exp(-(2 pi f sigma)^2 / 2): minima where the acceleration falls fastest,
    # t = (k + 1/2) / f
    f = 1.8
    t = np.arange(0, 20, 1 / FS)
    v = np.sin(2 * np.pi * f * t)
    w = ionescu_signal(v, FS)
    _, h = sosfreqz(butter(2, IONESCU_BAND_HZ, "bandpass", fs=FS, output="sos"), worN=[f], fs=FS)
    gain = np.exp(-0.5 * (2 * np.pi * f * IONESCU_SIGMA_S) ** 2) * np.abs(h[0]) ** 2
    mid = slice(int(3 * FS), int(17 * FS))
    expect = 2 * np.pi * f * np.cos(2 * np.pi * f * t) * gain
    assert np.max(np.abs(w[mid] - expect[mid])) < 0.05 * np.max(np.abs(expect))
    ic = detect_initial_contacts_ionescu(v, FS) / FS
    ic = ic[(ic > 2) & (ic < 18)]
    want = (np.arange(0, 40) + 0.5) / f
    want = want[(want > 2) & (want < 18)]
    np.testing.assert_allclose(ic, want, atol=1.5 / FS)


def test_ionescu_keeps_small_closing_and_turning_steps_the_prominence_threshold_misses():
    t = np.arange(0, 12, 1 / FS)
    ic = np.arange(1.0, 10.0, 0.55)
    amp = np.ones(len(ic))
    amp[7] = 0.2                                            # a small turning step
    amp[-1] = 0.15                                          # the closing step
    v = sum(a * np.exp(-0.5 * ((t - c) / 0.06) ** 2) for a, c in zip(amp, ic))
    v = v - v.mean()
    peak = detect_initial_contacts(v, FS, smooth_s=0.05, min_step_s=0.25, prominence=0.7) / FS
    lobes = detect_initial_contacts_ionescu(v, FS, sigma_s=0.06) / FS
    assert not np.any(np.abs(peak - ic[7]) < 0.1) and not np.any(np.abs(peak - ic[-1]) < 0.1)
    # one contact per step, each a constant delay after the pulse (the fastest fall of the acceleration)
    assert len(lobes) == len(ic)
    d = lobes - ic
    assert np.all((d > 0) & (d < 0.15)) and np.ptp(d) < 0.03


def test_ionescu_min_depth_drops_sway_lobes_while_standing():
    rng = np.random.default_rng(3)
    t = np.arange(0, 16, 1 / FS)
    ic = np.arange(5.0, 11.0, 0.55)
    v = sum(np.exp(-0.5 * ((t - c) / 0.06) ** 2) for c in ic) + rng.normal(0, 0.004, len(t))
    v = v - v.mean()
    loose = detect_initial_contacts_ionescu(v, FS, min_depth=0.0) / FS
    strict = detect_initial_contacts_ionescu(v, FS, min_depth=0.2) / FS
    # standing (more than 1 s from the walk: closer, the zero-phase band-pass rings before the first and after the
    # last step, one lobe each, which is the extra contact before a walk's first step)
    still = lambda x: np.sum((x < 4.0) | (x > 11.5))             # noqa: E731
    assert still(loose) > 0 and still(strict) == 0
    steps = strict[(strict > ic[0]) & (strict < ic[-1] + 0.3)]
    assert len(steps) == len(ic)


def test_fill_end_steps_add_the_closing_step_only_after_the_walk():
    kept = np.array([100, 150, 200, 250, 300])               # T = 50
    cand = np.array([52, 349])                               # a weak peak before the walk and the closing step
    prom = np.array([0.3, 0.3])
    assert fill_missed_steps(kept, cand, prom, max_step=150).tolist() == kept.tolist()
    assert fill_missed_steps(kept, cand, prom, max_step=150, end_steps=1).tolist() == [100, 150, 200, 250, 300,
                                                                                       349]
    assert fill_missed_steps(kept, cand, prom, max_step=150, edge_steps=1).tolist() == [52, 100, 150, 200, 250,
                                                                                        300, 349]


@pytest.mark.parametrize("step_s", [0.55, 1.1], ids=["normal", "slow_55_spm"])
def test_pipeline_with_the_ionescu_detector_finds_every_simulated_step(step_s):
    # the upward acceleration is amp cos(2 pi (t - ic) / step_s): it falls fastest a quarter step after each
    # contact, which is where the jerk-lobe minima must be
    acc, gyr, ic_true, _ = walking_body(40.0, rest_s=3.0, step_s=step_s)
    # lobes deeper than 0.2 SD: with 0 the sensor noise while standing still gives lobes too (next test)
    p = dataclasses.replace(TrunkGaitParams(), ic_method="ionescu", ic_zc_min_depth=0.2, ic_offset_s=0.0)
    det = analyse_trunk_gait(acc, gyr, FS, height_m=1.75, params=p).initial_contacts_s
    want = ic_true + step_s / 4
    hit = np.array([np.min(np.abs(det - x)) for x in want])
    inner = (want > 3.0 + 2 * step_s) & (want < 43.0 - 2 * step_s)    # bout edges depend on the bout rules
    assert np.all(hit[inner] < 0.03)
    assert len(det) <= len(ic_true) + 1


def test_unknown_ic_method_is_an_error():
    acc, gyr = walking_body(20.0)[:2]
    with pytest.raises(ValueError, match="ic_method"):
        analyse_trunk_gait(acc, gyr, FS, params=dataclasses.replace(TrunkGaitParams(), ic_method="zijlstra"))


def test_turn_prominence_lowers_the_threshold_inside_turns_only():
    t = np.arange(0, 12, 1 / FS)
    ic = np.arange(1.0, 11.0, 0.55)
    amp = np.ones(len(ic))
    amp[[4, 12]] = 0.1                                       # two weak steps: 4 outside the turn, 12 inside it
    v = sum(a * np.exp(-0.5 * ((t - c) / 0.06) ** 2) for a, c in zip(amp, ic))
    v = v - v.mean()
    turning = (t > ic[11] - 0.2) & (t < ic[13] + 0.2)
    kw = dict(smooth_s=0.05, min_step_s=0.25, prominence=0.7)
    plain = detect_initial_contacts(v, FS, **kw) / FS + t[0]
    turned = detect_initial_contacts(v, FS, **kw, turning=turning, turn_prominence=0.3) / FS
    near = lambda x, c: bool(np.any(np.abs(x - c) < 0.03))    # noqa: E731
    assert not near(plain, ic[4]) and not near(plain, ic[12])
    assert near(turned, ic[12]) and not near(turned, ic[4])
    assert len(turned) == len(plain) + 1


def _walk_with_a_weak_closing_step(step: float = 0.55):
    """A 20 s walk (steps of ``step`` s) after 4 s of rest whose closing step lifts the trunk little."""
    from tests.estimators.trunk_gait._signals import G
    acc, gyr, ic, _ = walking_body(20.0, rest_s=4.0, step_s=step)
    t = np.arange(len(acc)) / FS
    last = t >= ic[-1] - step / 2
    acc[last, 1] = G + 0.12 * (acc[last, 1] - G)
    return acc, gyr, ic


def test_a_filled_closing_step_is_a_contact_but_starts_no_stride():
    acc, gyr, ic = _walk_with_a_weak_closing_step()
    base = dataclasses.replace(TrunkGaitParams(), ic_offset_s=0.0, ic_fill_offset_s=0.0, ic_walk_end_offset_s=0.0,
                               cadence_method="count", ic_fill_prominence=0.0,
                               ic_fill_end_steps=0, stride_rule="run")
    plain = analyse_trunk_gait(acc, gyr, FS, height_m=1.75, params=base)
    filled = analyse_trunk_gait(acc, gyr, FS, height_m=1.75,
                                params=dataclasses.replace(base, ic_fill_prominence=0.02, ic_fill_end_steps=1))
    near = lambda x, c: bool(np.any(np.abs(x - c) < 0.05))    # noqa: E731
    assert not near(plain.initial_contacts_s, ic[-1]) and near(filled.initial_contacts_s, ic[-1])
    assert len(filled.initial_contacts_s) == len(plain.initial_contacts_s) + 1
    # no stride ends at the closing contact; the bout, its strides and its cadence are those without it
    assert filled.strides.end_s.max() == pytest.approx(plain.strides.end_s.max())
    assert len(filled.strides) == len(plain.strides)
    np.testing.assert_allclose(filled.bouts.cadence_spm, plain.bouts.cadence_spm)
    assert filled.bouts.cadence_spm[0] == pytest.approx(60 / 0.55, rel=0.01)              # the walk's step time
    # the consensus stride rule (shipped): the closing contact ends the walk's last stride but starts none
    cons = analyse_trunk_gait(acc, gyr, FS, height_m=1.75,
                              params=dataclasses.replace(base, ic_fill_prominence=0.02, ic_fill_end_steps=1,
                                                         stride_rule="consensus"))
    closing_t = cons.initial_contacts_s[-1]
    assert near(np.array([closing_t]), ic[-1])
    assert np.sum(np.abs(cons.strides.end_s - closing_t) < 1e-9) == 1
    assert not np.any(np.abs(cons.strides.start_s - closing_t) < 1e-9)
    assert len(cons.strides) == len(plain.strides) + 1
    np.testing.assert_allclose(cons.bouts.cadence_spm, plain.bouts.cadence_spm)


def test_bout_cadence_count_is_steps_over_walking_time_and_counts_a_missed_contact():
    from stridelab.estimators.trunk_gait._pipeline import bout_cadence
    ic = np.cumsum(np.r_[0.0, 0.7, 0.5, 0.5, 0.5, 0.5, 0.7])        # slower first and last steps (1.4 T)
    assert bout_cadence(ic, max_step_s=1.5, method="median") == pytest.approx(120.0)
    assert bout_cadence(ic, max_step_s=1.5, method="count") == pytest.approx(60 * 6 / 3.4)
    # an interval of 1.5 T or more is read as a missed contact (two steps), as the fill reads it
    slow = np.cumsum(np.r_[0.0, 0.8, 0.5, 0.5, 0.5, 0.5])
    assert bout_cadence(slow, max_step_s=1.5, method="count") == pytest.approx(60 * 6 / 2.8)
    missed = np.delete(np.arange(0, 5.01, 0.5), 4)                  # one contact missed: a 1.0 s interval
    assert bout_cadence(missed, max_step_s=1.5, method="count") == pytest.approx(120.0)
    paused = np.r_[np.arange(0, 2.01, 0.5), 5.0 + np.arange(0, 2.01, 0.5)]   # a 3 s pause is no step
    assert bout_cadence(paused, max_step_s=1.5, method="count") == pytest.approx(120.0)
    assert np.isnan(bout_cadence(np.array([1.0]), max_step_s=1.5, method="count"))
    with pytest.raises(ValueError, match="cadence_method"):
        bout_cadence(ic, max_step_s=1.5, method="mean")


def test_fill_start_prominence_adds_the_first_step_of_every_walk_when_it_is_prominent_enough():
    # two walks inside one sequence (T = 50 samples) separated by a pause of 4 T; the first step of each is weak
    kept = np.array([100, 150, 200, 250, 500, 550, 600, 650])
    cand = np.array([52, 455, 380])                          # before walk 1, before walk 2, standing sway in the pause
    prom = np.array([0.5, 0.45, 0.2])
    assert fill_missed_steps(kept, cand, prom, max_step=150).tolist() == kept.tolist()       # off: unchanged
    got = fill_missed_steps(kept, cand, prom, max_step=150, start_prominence=0.4).tolist()
    assert got == [52, 100, 150, 200, 250, 455, 500, 550, 600, 650]                          # 380 is 2.4 T early
    assert fill_missed_steps(kept, cand, prom, max_step=150, start_prominence=0.48).tolist() == [52] + kept.tolist()


def test_the_start_fill_finds_a_weak_first_step_the_threshold_misses():
    # a walk whose first step lifts the trunk to a quarter of the others (gait initiation): below the 0.7 SD
    # threshold, above the 0.4 SD of the start fill. (In a short walk of 5 contacts, 4 strides, the miss leaves 3
    # strides and the 4-stride bout rule then drops all its contacts: HA-001 Test11 at 28.6 s and 119.9 s.)
    t = np.arange(3.5, 10.0, 1 / FS)
    ic = 4.0 + 0.6 * np.arange(10)
    amp = np.ones(len(ic))
    amp[0] = 0.25                                           # about 0.55 SD of prominence: between 0.4 and 0.7
    v = sum(a * np.exp(-0.5 * ((t - c) / 0.07) ** 2) for a, c in zip(amp, ic))
    v = v - v.mean()
    kw = dict(smooth_s=0.11, min_step_s=0.25, prominence=0.7, fill_prominence=0.05, fill_end_steps=2)
    plain = detect_initial_contacts(v, FS, **kw) / FS + t[0]
    start = detect_initial_contacts(v, FS, **kw, fill_start_prominence=0.4) / FS + t[0]
    near = lambda x, c: bool(np.any(np.abs(x - c) < 0.03))    # noqa: E731
    assert not near(plain, ic[0]) and near(start, ic[0])
    assert len(start) == len(plain) + 1


def test_parabolic_peaks_find_the_vertex_between_samples():
    from stridelab.estimators.trunk_gait._icd import parabolic_peaks
    x = np.arange(20.0)
    y = -(x - 7.3) ** 2 + 4.0 - 0.1 * (x - 15.0) ** 2 * (x > 11)      # a parabola with its vertex at 7.3
    np.testing.assert_allclose(parabolic_peaks(y, np.array([7])), [7.3])
    # a sampled Gaussian pulse centred 0.4 sample after a sample: within 0.05 sample (a parabola fits its top)
    g = np.exp(-0.5 * ((x - 10.4) / 2.0) ** 2)
    assert abs(parabolic_peaks(g, np.array([10]))[0] - 10.4) < 0.05
    assert parabolic_peaks(g, np.array([0, 19])).tolist() == [0.0, 19.0]     # edge samples stay


def test_subsample_contacts_time_an_off_grid_step_rhythm_better():
    # contacts every 0.553 s (off the 10 ms sample grid): the peak sample errs by up to 5 ms, the vertex by far less
    t = np.arange(0, 12, 1 / FS)
    ic = 1.0 + 0.553 * np.arange(19) + 0.0037
    v = sum(np.exp(-0.5 * ((t - c) / 0.08) ** 2) for c in ic)
    v = v - v.mean()
    from scipy.ndimage import gaussian_filter1d
    from stridelab.estimators.trunk_gait._icd import parabolic_peaks
    idx = detect_initial_contacts(v, FS, smooth_s=0.05, min_step_s=0.25, prominence=0.7)
    sub = parabolic_peaks(gaussian_filter1d(v, 5.0, mode="nearest"), idx) / FS
    assert len(idx) == len(ic)
    e_int = np.abs(idx / FS - ic)
    e_sub = np.abs(sub - ic)
    assert e_int.max() > 0.003 and e_sub.max() < 0.0015


def test_end_rhythm_places_the_first_closing_step_one_median_step_after_the_last_contact():
    kept = np.array([100, 150, 200, 250, 300])               # T = 50
    cand = np.array([330, 390])                              # noise peaks after the walk (the closing step has none)
    prom = np.array([0.3, 0.2])
    # the peak fill takes the most prominent candidate 0.5-1.5 T after the last contact: 330, 20 samples off
    assert fill_missed_steps(kept, cand, prom, max_step=150, end_steps=1).tolist() == [100, 150, 200, 250, 300, 330]
    # by the rhythm: last + T, when the signal is that long
    assert fill_missed_steps(kept, cand, prom, max_step=150, end_steps=1,
                             end_rhythm_before=1000).tolist() == [100, 150, 200, 250, 300, 350]
    # the signal ends before last + T: the peak fill as without the rhythm
    assert fill_missed_steps(kept, cand, prom, max_step=150, end_steps=1,
                             end_rhythm_before=340).tolist() == [100, 150, 200, 250, 300, 330]
    # a second closing step is still looked for among the peaks, 0.5-1.5 T after the first
    assert fill_missed_steps(kept, cand, prom, max_step=150, end_steps=2,
                             end_rhythm_before=1000).tolist() == [100, 150, 200, 250, 300, 350, 390]


def test_a_closing_step_without_a_trunk_rebound_is_found_by_the_rhythm():
    # a walk whose last heel strike gives no upward-acceleration peak at all (the trailing foot joins the other
    # while the trunk decelerates; Voisard: prominence 0-0.04 SD), then standing with a little sway
    rng = np.random.default_rng(5)
    t = np.arange(0, 14, 1 / FS)
    ic = 2.0 + 0.55 * np.arange(16)                          # the last one, at 10.25 s, is the closing step
    v = sum(np.exp(-0.5 * ((t - c) / 0.07) ** 2) for c in ic[:-1]) + rng.normal(0, 0.01, len(t))
    v = v - v.mean()
    kw = dict(smooth_s=0.11, min_step_s=0.25, prominence=0.7, fill_prominence=0.05, fill_end_steps=2)
    peak_fill = detect_initial_contacts(v, FS, **kw) / FS
    rhythm = detect_initial_contacts(v, FS, **kw, fill_end_rhythm=True) / FS
    near = lambda x, c: bool(np.any(np.abs(x - c) < 0.03))    # noqa: E731
    assert not near(peak_fill, ic[-1])
    assert near(rhythm, ic[-1])


def test_walk_ends_add_the_closing_step_before_every_pause_not_only_the_last():
    # two walks inside one sequence (T = 50 samples) separated by a stop of 6 T; neither closing step has a peak
    kept = np.array([100, 150, 200, 250, 300, 600, 650, 700, 750])
    cand = np.array([450])                                  # standing sway in the stop, 3 T after walk 1
    prom = np.array([0.3])
    kw = dict(max_step=150, end_steps=1, end_rhythm_before=1000)
    assert fill_missed_steps(kept, cand, prom, **kw).tolist() == kept.tolist() + [800]        # sequence end only
    got, closing = fill_missed_steps(kept, cand, prom, **kw, walk_ends=True, return_closing=True)
    assert got.tolist() == [100, 150, 200, 250, 300, 350, 600, 650, 700, 750, 800]
    assert got[closing].tolist() == [350, 800]
    # a second closing step is looked for among the peaks, but not closer than 0.5 T to the next walk
    kept2 = np.array([100, 150, 200, 250, 300, 440, 490, 540, 590])      # a stop of 2.8 T
    got2 = fill_missed_steps(kept2, np.array([395, 415]), np.array([0.3, 0.5]), max_step=150, end_steps=2,
                             end_rhythm_before=1000, walk_ends=True).tolist()
    assert got2 == [100, 150, 200, 250, 300, 350, 395, 440, 490, 540, 590, 640]      # 415 is not < 440 - 0.5 T


def test_the_walk_end_fill_finds_the_closing_step_of_a_walk_inside_a_sequence():
    # walk 1 (8 contacts, the last without a trunk rebound), a 2.5 s stop with a little sway, walk 2 (10 contacts)
    rng = np.random.default_rng(7)
    t = np.arange(0, 16, 1 / FS)
    w1 = 1.0 + 0.6 * np.arange(8)
    w2 = w1[-1] + 2.5 + 0.6 * np.arange(10)
    v = sum(np.exp(-0.5 * ((t - c) / 0.07) ** 2) for c in np.r_[w1[:-1], w2]) + rng.normal(0, 0.01, len(t))
    v = v - v.mean()
    kw = dict(smooth_s=0.11, min_step_s=0.25, prominence=0.7, fill_prominence=0.05, fill_end_steps=1,
              fill_end_rhythm=True, return_closing=True)
    near = lambda x, c: bool(np.any(np.abs(x - c) < 0.03))    # noqa: E731
    seq_end, _ = detect_initial_contacts(v, FS, **kw)
    every, closing = detect_initial_contacts(v, FS, **kw, fill_walk_ends=True)
    assert not near(seq_end / FS, w1[-1]) and near(every / FS, w1[-1])
    assert near(every[closing] / FS, w1[-1]) and len(every) == len(seq_end) + 1


def test_fill_labels_how_each_contact_was_found():
    from stridelab.estimators.trunk_gait._icd import IC_KINDS
    # T = 50 samples; a missed step at 350 (gap 300-400, weak peak at 352), a weak first step at 52, the walk's
    # closing step without a peak (by the rhythm at 550 + 50 = 600) and a second closing step at a weak peak (648)
    kept = np.array([100, 150, 200, 250, 300, 400, 450, 500, 550])
    cand = np.array([52, 352, 648])
    prom = np.array([0.5, 0.3, 0.2])
    out, closing, kinds = fill_missed_steps(kept, cand, prom, max_step=150, end_steps=2, end_rhythm_before=1000,
                                            start_prominence=0.4, return_kinds=True)
    assert out.tolist() == [52, 100, 150, 200, 250, 300, 352, 400, 450, 500, 550, 600, 648]
    got = dict(zip(out.tolist(), (IC_KINDS[k] for k in kinds)))
    assert got[52] == "start_fill" and got[352] == "gap_fill"
    assert got[600] == "closing_rhythm" and got[648] == "closing_peak"
    assert all(got[k] == "peak" for k in kept)
    assert out[closing].tolist() == [600, 648]
    # an edge step after the last contact (edge_steps) is labelled as such, the closing step after it by the peak
    out2, _c, kinds2 = fill_missed_steps(kept, np.array([598, 648]), np.array([0.3, 0.2]), max_step=150,
                                         edge_steps=1, end_steps=1, return_kinds=True)
    assert [IC_KINDS[k] for k in kinds2[-2:]] == ["edge_fill", "closing_peak"] and out2[-2:].tolist() == [598, 648]
    # the detector itself returns the same labels
    t = np.arange(0, 10, 1 / FS)
    ic = 1.0 + 0.5 * np.arange(12)
    v = sum(np.exp(-0.5 * ((t - c) / 0.06) ** 2) for c in ic[:-1])            # the last contact has no peak
    v = v - v.mean()
    idx, closing3, kinds3 = detect_initial_contacts(v, FS, smooth_s=0.05, min_step_s=0.25, prominence=0.7,
                                                    fill_prominence=0.05, fill_end_steps=1, fill_end_rhythm=True,
                                                    return_kinds=True)
    assert IC_KINDS[kinds3[-1]] == "closing_rhythm" and closing3[-1] and abs(idx[-1] / FS - ic[-1]) < 0.02
    assert (kinds3[:-1] == 0).all()


def test_kind_offsets_move_the_fill_contacts_and_the_last_peak_before_a_closing_step():
    from stridelab.estimators.trunk_gait._icd import IC_KINDS, kind_offsets_s
    k = np.array([IC_KINDS.index(x) for x in ("start_fill", "peak", "peak", "gap_fill", "peak", "peak",
                                              "closing_rhythm", "peak", "peak", "closing_peak")])
    np.testing.assert_allclose(kind_offsets_s(k), 0.0)
    np.testing.assert_allclose(kind_offsets_s(k, fill_offset_s=-0.05),
                               [-0.05, 0, 0, -0.05, 0, 0, -0.05, 0, 0, -0.05])
    # the walk-end offset: the threshold peak right before each closing step (indices 5 and 8), nothing else
    np.testing.assert_allclose(kind_offsets_s(k, walk_end_offset_s=-0.03),
                               [0, 0, 0, 0, 0, -0.03, 0, 0, -0.03, 0])
    np.testing.assert_allclose(kind_offsets_s(k, fill_offset_s=-0.05, walk_end_offset_s=-0.03),
                               [-0.05, 0, 0, -0.05, 0, -0.03, -0.05, 0, -0.03, -0.05])
    assert kind_offsets_s(np.zeros(0, np.int8), fill_offset_s=-0.05, walk_end_offset_s=-0.03).shape == (0,)


def test_pipeline_kind_offsets_shift_only_the_closing_contact_and_the_one_before_it():
    from stridelab.estimators.trunk_gait._icd import IC_KINDS
    acc, gyr, ic = _walk_with_a_weak_closing_step()
    base = dataclasses.replace(TrunkGaitParams(), ic_offset_s=0.0, ic_fill_prominence=0.02, ic_fill_end_steps=1,
                               ic_fill_end_rhythm=True, ic_fill_offset_s=0.0, ic_walk_end_offset_s=0.0)
    ref = analyse_trunk_gait(acc, gyr, FS, height_m=1.75, params=base)
    kinds = np.array([IC_KINDS[k] for k in ref.ic_kind])
    assert kinds[-1] == "closing_rhythm" and (kinds[:-1] == "peak").all()
    moved = analyse_trunk_gait(acc, gyr, FS, height_m=1.75,
                               params=dataclasses.replace(base, ic_fill_offset_s=-0.05, ic_walk_end_offset_s=-0.02))
    d = moved.initial_contacts_s - ref.initial_contacts_s
    np.testing.assert_allclose(d, np.r_[np.zeros(len(d) - 2), -0.02, -0.05], atol=1e-9)
    # only the reported heel strikes move: strides, bouts, cadence and stride lengths are those without the offsets
    np.testing.assert_allclose(moved.strides.start_s, ref.strides.start_s)
    np.testing.assert_allclose(moved.strides.end_s, ref.strides.end_s)
    np.testing.assert_allclose(moved.strides.length_m, ref.strides.length_m)
    np.testing.assert_allclose(moved.bouts.cadence_spm, ref.bouts.cadence_spm)
    np.testing.assert_allclose(moved.bouts.end_s, ref.bouts.end_s)
