"""Initial contact at the heel strike (H1, ``refine_heel_strike``) instead of the pitch maximum (issue 43: IC timing
bias −27 ms on the Voisard feet). Hand-made signals of known answer; on a real Voisard trial the shipped defaults
against the target (≤ 20 ms MAE at ±0.1 s, the issue's), where the pitch-maximum IC of the old code misses it."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.gait import FootParams, foot_kinematics, refine_heel_strike
from tests.conftest import shared_data


def test_refinement_finds_the_rise_of_the_loading_rotation():
    fs = 100.0
    n = 200
    gyr = np.zeros((n, 3))
    # pitch maximum at 50 (ω_ml = 0), toes-down rate rising linearly to 4 rad/s at 60, back to 0 at 75 (foot flat)
    gyr[50:61, 1] = np.linspace(0.0, 4.0, 11)
    gyr[60:76, 1] = np.linspace(4.0, 0.0, 16)
    gyr[30:50, 1] = -1.0                                      # dorsiflexing before the pitch maximum
    ml = np.array([0.0, 1.0, 0.0])
    out = refine_heel_strike(gyr, np.array([50]), ml, sampling_rate_hz=fs, onset_fraction=0.5)
    assert out.tolist() == [55]                               # 2 rad/s = half the peak, 5 samples after j
    assert refine_heel_strike(gyr, np.array([50]), ml, sampling_rate_hz=fs, onset_fraction=0.1).tolist() == [51]
    # the search stops at the bound (peak 0.8 rad/s at 52, half of it at 51); a landing with no toes-down rotation
    # (flat / forefoot) keeps the pitch maximum
    assert refine_heel_strike(gyr, np.array([50]), ml, sampling_rate_hz=fs, upper_bound=np.array([52])).tolist() \
        == [51]
    assert refine_heel_strike(-gyr, np.array([50]), ml, sampling_rate_hz=fs).tolist() == [50]
    # the same at 200 Hz: the window is in seconds
    g2 = np.repeat(gyr, 2, axis=0)
    assert refine_heel_strike(g2, np.array([100]), ml, sampling_rate_hz=2 * fs).tolist() == [110]


@pytest.mark.realdata
def test_voisard_trial_ic_bias_of_the_pitch_maximum_is_removed():
    """Trial 4-2 (both feet, ±0.1 s inside TrialBoundaries): with H1 off (the IC at the pitch maximum, the old code)
    the ICs are early by more than 20 ms on average (the definition gap of issue 43); the shipped defaults cut the
    bias by more than half and lower the MAE. In-sample for H1's fraction (chosen by leave-one-subject-out over these
    subjects); the figures against the target are the bench's."""
    from stridelab.estimators.gait.evaluation import event_accuracy
    from stridelab.pipeline.formats.xsens_mt import load_voisard_trial
    tr = load_voisard_trial(shared_data("voisard_gait"), "4-2")
    a = tr.annotation
    fs = tr.left.sampling_rate_hz
    span = (a.trial_boundaries[0] / fs, a.trial_boundaries[1] / fs)

    def mae(params):
        dets, refs = [], []
        for rec, ev in ((tr.left, a.left_events), (tr.right, a.right_events)):
            fk = foot_kinematics(rec.gyr, rec.acc, sampling_rate_hz=fs, params=params)
            dets.append(fk.events.ic_idx / fs)
            refs.append(ev[:, 1] / fs)
        acc = event_accuracy(dets, refs, tolerance_s=0.1, spans_s=[span, span])
        return acc.timing_mae_ms, acc.timing_mean_ms
    new, old = mae(FootParams()), mae(FootParams(heel_strike_fraction=None))
    assert old[1] < -20.0 and abs(new[1]) < 0.5 * abs(old[1])     # the old ICs are early: the definition gap
    assert new[0] < old[0]


@pytest.mark.realdata
@pytest.mark.parametrize("toe_off, heel, min_step, min_impact", [(0.6, 0.4, None, None), (0.2, None, None, None),
                                                                 (None, 0.75, None, None), (0.7, 0.4, 0.02, None),
                                                                 (0.7, 0.4, 0.5, None), (0.7, 0.4, 0.02, 1.0),
                                                                 (None, None, None, 30.0)])
def test_refine_events_equals_foot_kinematics(toe_off, heel, min_step, min_impact):
    """The bench scores its grid with ``refine_events`` on one unrefined run: it must give exactly the events
    ``foot_kinematics`` gives with the same parameters (gaitmap walk, left foot)."""
    from stridelab.estimators.gait import refine_events
    from stridelab.pipeline.formats.gaitmap import load_gaitmap_example
    ex = load_gaitmap_example(shared_data("gaitmap_example"))
    f, fs = ex.left, ex.sampling_rate_hz
    params = FootParams(toe_off_refine=toe_off is not None, toe_off_onset_fraction=toe_off or 0.2,
                        heel_strike_fraction=heel, min_step_m=min_step, min_impact_m_s2=min_impact)
    base = foot_kinematics(f.gyr, f.acc, sampling_rate_hz=fs,
                           params=FootParams(toe_off_refine=False, heel_strike_fraction=None, min_step_m=None,
                                             min_impact_m_s2=None))
    direct = foot_kinematics(f.gyr, f.acc, sampling_rate_hz=fs, params=params).events
    ev = refine_events(base, f.gyr, params, acc=f.acc)
    np.testing.assert_array_equal(ev.ic_idx, direct.ic_idx)
    np.testing.assert_array_equal(ev.tc_idx, direct.tc_idx)
    assert len(ev.ic_idx) > 20             # (min_step 0.5 m makes R6 fire here: one short turning step of 33 goes;
    #                                        min_impact 30 m/s² makes R7 drop the softer landings)
    if min_impact is not None and min_impact > 10:
        assert len(ev.ic_idx) < len(base.events.ic_idx)
    if heel is not None:                      # H1 moved ICs later, never earlier
        assert np.all(ev.ic_idx >= ev.ic_pitch_max_idx) and np.any(ev.ic_idx > ev.ic_pitch_max_idx)


def _pitch(points, n=400):
    """Piecewise-linear pitch signal s through (sample, value) points."""
    x, y = zip(*points)
    return np.interp(np.arange(n), x, y)


def test_weak_push_off_step_is_added_and_ordinary_strides_are_not_touched():
    """(R5) Voisard 1-1 right foot in miniature: a weight shift Algorithm 1 took for a step (TC 40, IC 80 at
    s = 0.05), then the first real step whose push-off only reaches s = −0.03 (> T = −0.1, so no TC, and strict
    alternation blocks its heel strike at s = 0.3), then stance and an ordinary push-off (TC 300)."""
    from stridelab.estimators.gait import GaitEvents, IcTcParams
    from stridelab.estimators.gait._kinematics import _weak_push_off_steps
    fs = 100.0
    s = _pitch([(0, 0), (40, -0.15), (80, 0.05), (120, -0.03), (160, 0.3), (200, 0.0), (260, 0.0), (300, -0.4),
                (340, 0.3), (399, 0.0)])
    ev = GaitEvents(np.array([80, 340]), np.array([40, 300]), np.array([81, 341]), np.array([41, 301]), IcTcParams())
    out = _weak_push_off_steps(ev, s, fs, FootParams())
    assert out.tc_idx.tolist() == [40, 120, 300] and out.ic_idx.tolist() == [80, 160, 340]
    assert out.tc_detect_idx.tolist() == [41, 121, 301] and out.ic_detect_idx.tolist() == [81, 161, 341]
    # an ordinary stride: heel strike, stance, push-off: nothing added
    s2 = _pitch([(0, 0), (40, -0.4), (80, 0.3), (120, 0.0), (200, 0.0), (240, -0.4), (280, 0.3), (399, 0.0)])
    ev2 = GaitEvents(np.array([80, 280]), np.array([40, 240]), np.array([81, 281]), np.array([41, 241]),
                     IcTcParams())
    out2 = _weak_push_off_steps(ev2, s2, fs, FootParams())
    assert out2.ic_idx.tolist() == [80, 280] and out2.tc_idx.tolist() == [40, 240]
