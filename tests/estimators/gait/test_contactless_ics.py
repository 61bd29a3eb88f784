"""Issue 43, gait events in turns: a pitch maximum at which nothing touches the ground is no initial contact (R7,
``FootParams.min_impact_m_s2``). On Voisard et al. 42 of the 53 false ICs of the former defaults lay in the U-turns;
14 of them were pitch maxima of a foot pivoting, rocking or turning on the spot with |f| within 1 m/s² of the
sensor's g_s from 0.05 s before to 0.15 s after (no mass is stopped), while every detected IC that matched an
annotated heel strike showed at least 1.37 m/s² there."""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from stridelab.estimators.gait import FootParams, GaitEvents, IcTcParams, foot_kinematics, refine_events
from stridelab.estimators.gait._kinematics import drop_contactless_ics
from tests.conftest import shared_data

FS = 100.0
G_S = 10.2          # the sensor's own reading at rest (Voisard's left-foot MTw reads 10.0-10.45 m/s²)


def _events(tc, ic):
    tc, ic = np.asarray(tc, np.int64), np.asarray(ic, np.int64)
    return GaitEvents(ic_idx=ic, tc_idx=tc, ic_detect_idx=ic + 1, tc_detect_idx=tc + 1, params=IcTcParams(),
                      ic_pitch_max_idx=ic - 3)


def _acc(n=600, seed=1):
    """Specific force of a foot on the sensor's vertical axis: g_s plus 0.05 m/s² noise, and a heel-strike
    transient (a 30 ms half-sine of 25 m/s²) at sample 130 and a slow, flat landing (3 m/s² over 60 ms) at 430."""
    rng = np.random.default_rng(seed)
    acc = np.zeros((n, 3))
    acc[:, 2] = G_S + 0.05 * rng.standard_normal(n)
    acc[128:131, 2] += 25.0 * np.sin(np.linspace(0, np.pi, 5))[1:4]
    acc[427:433, 2] += 3.0 * np.sin(np.linspace(0, np.pi, 8))[1:7]
    return acc


def test_an_ic_without_an_impact_is_dropped_and_real_landings_are_kept():
    """ICs at 130 (heel strike), 280 (a pitch maximum while |f| = g_s: a pivot on the spot) and 430 (slow flat
    landing). The old code (R7 off) keeps all three; with A_min = 1 m/s² the one at 280 goes, the TCs all stay
    (the foot did leave the ground before each), and the pitch-maximum record follows the kept ICs."""
    ev = _events([80, 230, 380], [130, 280, 430])
    acc = _acc()
    out = drop_contactless_ics(ev, acc, gravity_m_s2=G_S, sampling_rate_hz=FS, min_impact_m_s2=1.0)
    assert out.ic_idx.tolist() == [130, 430] and out.ic_detect_idx.tolist() == [131, 431]
    assert out.ic_pitch_max_idx.tolist() == [127, 427]
    assert out.tc_idx.tolist() == [80, 230, 380]
    # the window: an impact 0.05 s before the IC still counts (H1 may sit a few samples after the first touch),
    # one 0.2 s after it does not (that is the next event's business)
    early = drop_contactless_ics(_events([], [134, 250]), acc, gravity_m_s2=G_S, sampling_rate_hz=FS,
                                 min_impact_m_s2=1.0)
    assert early.ic_idx.tolist() == [134]
    # a bound above the slow landing's 3 m/s² drops it as well: the threshold is what separates the two
    high = drop_contactless_ics(ev, acc, gravity_m_s2=G_S, sampling_rate_hz=FS, min_impact_m_s2=4.0)
    assert high.ic_idx.tolist() == [130]
    # the reading at rest is the sensor's own: judged against 9.81 the whole quiet signal deviates by 0.4 m/s²
    # and a bound of 0.3 would keep the pivot
    assert drop_contactless_ics(ev, acc, gravity_m_s2=9.81, sampling_rate_hz=FS,
                                min_impact_m_s2=0.3).ic_idx.tolist() == [130, 280, 430]


def test_refine_events_refuses_r7_without_the_accelerometer():
    base = FootParams(toe_off_refine=False, heel_strike_fraction=None, min_step_m=None, min_impact_m_s2=None)
    rng = np.random.default_rng(0)
    n = 3000
    gyr = 0.01 * rng.standard_normal((n, 3))
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + 0.01 * rng.standard_normal((n, 3))
    fk = foot_kinematics(gyr, acc, sampling_rate_hz=FS, params=base)
    if fk.status == "no_stance":                                   # nothing to refine: R7 never runs
        pytest.skip("the still signal gave no stance")
    fk = dataclasses.replace(fk, events=dataclasses.replace(_events([100], [200]), ic_pitch_max_idx=None))
    with pytest.raises(ValueError, match="min_impact_m_s2.*acc"):
        refine_events(fk, gyr, dataclasses.replace(base, min_impact_m_s2=1.0))


@pytest.mark.realdata
def test_voisard_u_turn_pivot_is_not_an_initial_contact():
    """Voisard 7-1, right foot, U-turn [1617, 1758]: the reference has the right foot's U-turn step (toe-off 1620,
    heel strike 1660) and the next one only after it (1808 → 1853). The foot then pivots on the spot: without R7
    the detector reports an IC near 1746 (|f| within ±0.5 m/s² of g_s around it) that matches nothing; with the
    shipped defaults it is gone and every annotated IC of the trial is still found within ±0.1 s."""
    from stridelab.estimators.gait.evaluation import event_accuracy
    from stridelab.pipeline.formats.xsens_mt import load_voisard_dir
    src = shared_data("voisard_gait")
    tr = [t for t in load_voisard_dir(src, skipped=[]) if t.name == "7-1"][0]
    a, rec = tr.annotation, tr.right
    fs = rec.sampling_rate_hz
    span = [(a.trial_boundaries[0] / fs, a.trial_boundaries[1] / fs)]
    res = {}
    for name, p in (("off", dataclasses.replace(FootParams(), min_impact_m_s2=None)), ("shipped", FootParams())):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fk = foot_kinematics(rec.gyr, rec.acc, sampling_rate_hz=fs, params=p)
        res[name] = (fk.events.ic_idx, event_accuracy([fk.events.ic_idx / fs], [a.right_events[:, 1] / fs],
                                                      tolerance_s=0.1, spans_s=span))
    ic_off, acc_off = res["off"]
    ic_new, acc_new = res["shipped"]
    pivot = ic_off[(ic_off > 1700) & (ic_off < 1790)]
    assert len(pivot) == 1 and acc_off.fp >= 1                                 # the failure (R7 off)
    assert not np.any((ic_new > 1700) & (ic_new < 1790)), ic_new
    assert acc_new.fp == acc_off.fp - 1 and acc_new.tp == acc_off.tp and acc_new.fn == acc_off.fn
