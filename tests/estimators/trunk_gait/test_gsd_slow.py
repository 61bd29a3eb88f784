"""Gait-sequence detection for slow and aided walking (issue 42, point 3), and what it must not take for walking.

The walks come from the tests' own mechanical model (``_signals.pendulum_walk``: an inverted pendulum over each
stance foot joined by a double support, nothing of the estimator's code or thresholds): at 0.3 m/s with a third of
each step in double support the SD of the acceleration norm is about 0.14 m/s², below the strong rule's 0.25 m/s²,
so only the periodicity-led slow rule can find it. Standing sway, a seated tremor-like oscillation and repeated
sit-to-stand are the non-walking side."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from stridelab.estimators.trunk_gait import TrunkGaitParams, analyse_trunk_gait
from stridelab.estimators.trunk_gait._gsd import _decimate_norm, detect_gait_sequences
from stridelab.estimators.trunk_gait.evaluation import ic_metrics, match_initial_contacts
from tests.estimators.trunk_gait._signals import G, pendulum_walk, rot, sit_to_stand, standing_sway

FS = 100.0
SHIPPED = TrunkGaitParams()


def _gsd(acc, p: TrunkGaitParams = SHIPPED, fs: float = FS) -> np.ndarray:
    """Gait sequences (s) with every GSD constant of ``p``."""
    return detect_gait_sequences(acc, fs, window_s=p.gsd_window_s, hop_s=p.gsd_hop_s,
                                 min_std_m_s2=p.gsd_min_std_m_s2, min_autocorr=p.gsd_min_autocorr,
                                 merge_gap_s=p.gsd_merge_gap_s, slow_min_std_m_s2=p.gsd_slow_min_std_m_s2,
                                 slow_min_autocorr=p.gsd_slow_min_autocorr) / fs


def _covered(seqs_s: np.ndarray, a: float, b: float) -> float:
    """Fraction of [a, b] inside the gait sequences."""
    return sum(max(0.0, min(e, b) - max(s, a)) for s, e in seqs_s) / (b - a)


def _trunk_events(ic: np.ndarray, double_support: float = 0.35) -> np.ndarray:
    """The model's trunk event of each step: the middle of the double support that follows the initial contact,
    where its upward acceleration (constant over the double support) is centred; the contact detector finds that
    peak, which real trunks show shortly after the heel strike."""
    d = np.diff(ic)
    return ic + double_support * np.r_[d, d[-1]] / 2


def _norm_sd(acc, a: float, b: float) -> float:
    x, fd = _decimate_norm(acc, FS)
    return float(x[int(a * fd):int(b * fd)].std())


SLOW = {"0.3_m_s": dict(speed_m_s=0.3, step_s=1.1),
        "0.3_m_s_hemiparetic": dict(speed_m_s=0.3, step_s=1.1, step_cv=0.08, asymmetry=0.25),
        "0.3_m_s_walking_aid": dict(speed_m_s=0.3, step_s=1.1, step_cv=0.08, asymmetry=0.25, vertical_scale=0.6)}


@pytest.mark.parametrize("kw", list(SLOW.values()), ids=list(SLOW))
def test_slow_walk_is_found_with_the_shipped_defaults_where_the_strong_rule_alone_misses_it(kw):
    acc_b, gyr_b, ic, (a, b) = pendulum_walk(**kw, seed=4)
    R = rot("z", 20.0) @ rot("x", 170.0)                 # any mounting: the rules see the norm only
    acc, gyr = acc_b @ R, gyr_b @ R
    # the walk is weaker than the strong rule's amplitude threshold (that is why the old detector missed it)
    assert _norm_sd(acc, a + 2, b - 2) < SHIPPED.gsd_min_std_m_s2
    old = dataclasses.replace(SHIPPED, gsd_slow_min_std_m_s2=float("inf"))
    assert _covered(_gsd(acc, old), a, b) == 0.0
    assert _covered(_gsd(acc), a, b) >= 0.95
    # end to end with the shipped defaults: one bout over the walk, its steps and cadence
    res = analyse_trunk_gait(acc, gyr, FS, height_m=1.62)
    assert len(res.bouts) == 1
    # (the first step out of standing lifts the trunk least: with a walking aid the contact detector may drop it)
    assert res.bouts.start_s[0] - a < 3 * kw["step_s"] and b - res.bouts.end_s[0] < 3 * kw["step_s"]
    m = ic_metrics(match_initial_contacts(res.initial_contacts_s - SHIPPED.ic_offset_s, _trunk_events(ic)))
    assert m["sensitivity"] >= 0.9 and m["precision"] >= 0.95, m
    cad = 60.0 * (len(ic) - 1) / (ic[-1] - ic[0])
    assert res.bouts.cadence_spm[0] == pytest.approx(cad, rel=0.03)


def test_the_slow_rule_constants_reach_the_pipeline():
    acc, gyr, _ic, _ = pendulum_walk(0.3, 1.1, seed=4)
    off = dataclasses.replace(SHIPPED, gsd_slow_min_std_m_s2=float("inf"))
    assert len(analyse_trunk_gait(acc, gyr, FS, params=off).gait_sequences_s) == 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_standing_sway_is_not_walking(seed):
    acc, gyr = standing_sway(120.0, seed=seed)
    assert len(_gsd(acc)) == 0
    res = analyse_trunk_gait(acc, gyr, FS)
    assert len(res.bouts) == 0 and len(res.initial_contacts_s) == 0


def test_noise_and_a_tremor_inside_the_step_lags_are_not_walking():
    rng = np.random.default_rng(7)
    n = int(120 * FS)
    t = np.arange(n) / FS
    # a noisy sensor at rest (three times the model's sensor noise)
    acc = np.tile([0.0, G, 0.0], (n, 1)) + rng.normal(0, 0.06, (n, 3))
    assert len(_gsd(acc)) == 0
    # a weak 4.5 Hz rest tremor (Parkinson's 4-6 Hz): strongly periodic, its lag 0.22 s is almost a step lag,
    # but it lies above the gait band of the slow rule and below the strong rule's amplitude
    acc2 = acc.copy()
    acc2[:, 1] += 0.2 * np.sin(2 * np.pi * 4.5 * t)
    assert _norm_sd(acc2, 0, 120) < SHIPPED.gsd_min_std_m_s2
    assert len(_gsd(acc2)) == 0


def test_sit_to_stand_is_not_a_walking_bout_and_the_walk_after_it_is():
    sts, sts_g = sit_to_stand(5, period_s=3.0)
    sway, sway_g = standing_sway(10.0, seed=3)
    walk, walk_g, ic, (a, b) = pendulum_walk(0.3, 1.1, n_steps=30, rest_s=2.0, seed=5)
    acc = np.vstack([sts, sway, walk])
    gyr = np.vstack([sts_g, sway_g, walk_g])
    off = (len(sts) + len(sway)) / FS
    res = analyse_trunk_gait(acc, gyr, FS, height_m=1.62)
    assert len(res.bouts) == 1
    assert res.bouts.start_s[0] >= off + a - 0.5
    assert np.all(res.initial_contacts_s >= off)
    m = ic_metrics(match_initial_contacts(res.initial_contacts_s - SHIPPED.ic_offset_s, _trunk_events(ic) + off))
    assert m["sensitivity"] >= 0.9 and m["precision"] >= 0.95, m
    # sit-to-stand alone: no contact, no bout
    res = analyse_trunk_gait(sts, sts_g, FS, height_m=1.62)
    assert len(res.bouts) == 0 and len(res.initial_contacts_s) == 0


def test_faster_walks_are_found_by_the_strong_rule_as_before():
    for speed, step in ((0.6, 0.75), (1.2, 0.55)):
        acc, _gyr, _ic, (a, b) = pendulum_walk(speed, step, seed=1)
        old = dataclasses.replace(SHIPPED, gsd_slow_min_std_m_s2=float("inf"))
        assert _covered(_gsd(acc, old), a, b) >= 0.95
        np.testing.assert_array_equal(_gsd(acc, old), _gsd(acc))
