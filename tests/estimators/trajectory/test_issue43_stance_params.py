"""Issue 43, fourth round: the foot trajectory has its own stance-detector parameters (``TRAJECTORY_ZUPT``, the
default of ``EskfParams.zupt``), the gait events keep theirs (``GAIT_ZUPT`` in ``FootParams.trajectory``).

A value that the trajectory's cross-validation chooses for its detector (PyShoe) must not move the gait events,
whose detector is chosen by another cross-validation (Voisard, the gaitmap walk), and the other way round. The
trajectory the gait stage stores is ``foot_trajectory`` (K4): the trajectory on its own detector, reusing the
events' filter run when both detectors give the same mask.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from stridelab.estimators.gait import FootParams, foot_kinematics, foot_trajectory
from stridelab.estimators.gait._kinematics import GAIT_ZUPT, foot_params_from_dict
from stridelab.estimators.trajectory import TRAJECTORY_ZUPT, EskfParams, detect_zupt, eskf_trajectory

FS = 200.0


def _short_stance_steps(n_cycles: int = 12, stance_s: float = 0.125, swing_s: float = 0.6, seed: int = 0):
    """Running-like foot signal: still runs of ``stance_s`` between swings of 8 rad/s
    about the sensor y axis (the foot pitches) with a 25 m/s² swing acceleration; a 1 s rest at each end."""
    rng = np.random.default_rng(seed)
    ns, nw, nr = int(round(stance_s * FS)), int(round(swing_s * FS)), int(FS)
    w_parts, a_parts = [np.zeros(nr)], [np.zeros(nr)]
    for _ in range(n_cycles):
        w_parts += [np.zeros(ns), 8.0 * np.sin(np.pi * np.arange(nw) / nw)]
        a_parts += [np.zeros(ns), 25.0 * np.sin(2 * np.pi * np.arange(nw) / nw)]
    w_parts.append(np.zeros(ns + nr))
    a_parts.append(np.zeros(ns + nr))
    w, a = np.concatenate(w_parts), np.concatenate(a_parts)
    gyr = np.column_stack([np.zeros_like(w), w, np.zeros_like(w)]) + 0.01 * rng.standard_normal((len(w), 3))
    acc = np.column_stack([a, np.zeros_like(a), 9.81 + 0.3 * a]) + 0.05 * rng.standard_normal((len(w), 3))
    return gyr, acc


def test_trajectory_and_gait_each_own_their_stance_detector():
    assert EskfParams().zupt == TRAJECTORY_ZUPT
    assert FootParams().trajectory.zupt == GAIT_ZUPT
    # everything but the stance detector stays one set of trajectory parameters
    assert dataclasses.replace(FootParams().trajectory, zupt=TRAJECTORY_ZUPT) == EskfParams()
    # a stage's JSON params without the detector keep the gait's, not the trajectory's
    assert foot_params_from_dict({}).trajectory == FootParams().trajectory
    assert foot_params_from_dict({}) == FootParams()                  # the events too (T = -0.1, not the class's -0.2)
    assert foot_params_from_dict({"events": {"refractory_s": 0.2}}).events.threshold == FootParams().events.threshold
    assert foot_params_from_dict(dataclasses.asdict(FootParams())) == FootParams()
    fp = foot_params_from_dict({"trajectory": {"acc_noise_rel": 0.3}})
    assert fp.trajectory.zupt == GAIT_ZUPT and fp.trajectory.acc_noise_rel == 0.3
    # the stored foot trajectory (K4) is the trajectory's own: FootParams' trajectory with its detector is EskfParams()
    assert dataclasses.replace(FootParams().trajectory, zupt=FootParams().trajectory_zupt) == EskfParams()
    assert foot_params_from_dict({"trajectory_zupt": None}).trajectory_zupt is None
    fp = foot_params_from_dict({"trajectory_zupt": {"window_s": 0.03}})
    assert fp.trajectory_zupt == dataclasses.replace(TRAJECTORY_ZUPT, window_s=0.03)


def test_short_stances_are_detected_by_the_parameters_of_each_user():
    """On still runs whose detected core (the 0.05 s window maximum of Z1 erodes 0.125 s to 0.09–0.11 s) lies
    between two minimum durations, a trajectory detector of 0.1 s (what the trajectory's own cross-validation chose;
    not shipped, docs/trajectory.md) differs from the gait's 0.05 s, and each caller gets the one it is given: the
    longer one drops them down to the cycle's quietest window (Z5), the gait's keeps them whole."""
    gyr, acc = _short_stance_steps()
    longer = dataclasses.replace(TRAJECTORY_ZUPT, min_stance_s=0.1)
    z_long = detect_zupt(gyr, acc, sampling_rate_hz=FS, params=longer, gravity=9.81)
    z_gait = detect_zupt(gyr, acc, sampling_rate_hz=FS, params=GAIT_ZUPT, gravity=9.81)
    assert not np.array_equal(z_long, z_gait)
    assert np.array_equal(eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=EskfParams(zupt=longer)).zupt, z_long)
    assert np.array_equal(eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=FootParams().trajectory).zupt,
                          z_gait)
    # shipped: the trajectory on its own detects stance with TRAJECTORY_ZUPT, as the stored (gait stage) one does
    z_traj = detect_zupt(gyr, acc, sampling_rate_hz=FS, params=TRAJECTORY_ZUPT, gravity=9.81)
    assert np.array_equal(eskf_trajectory(gyr, acc, sampling_rate_hz=FS).zupt, z_traj)
    fk = foot_kinematics(gyr, acc, sampling_rate_hz=FS)
    assert np.array_equal(foot_trajectory(gyr, acc, fk, sampling_rate_hz=FS).zupt, z_traj)


def _arrays(r):
    return (r.pos, r.vel, r.quat, r.bias, r.zupt)


def test_the_stored_trajectory_is_the_trajectorys_own_and_the_events_do_not_move():
    """K4 on short stances that the two detectors see differently: ``foot_trajectory`` is ``eskf_trajectory`` with
    the trajectory's detector (what the trajectory bench scores), the events and strides are those of the events'
    detector alone (``trajectory_zupt=None``), and None gives the events' trajectory back."""
    gyr, acc = _short_stance_steps()
    longer = dataclasses.replace(TRAJECTORY_ZUPT, min_stance_s=0.1)
    fp = dataclasses.replace(FootParams(), trajectory_zupt=longer)
    fk = foot_kinematics(gyr, acc, sampling_rate_hz=FS, params=fp)
    own = foot_trajectory(gyr, acc, fk, sampling_rate_hz=FS, params=fp)
    bench = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=dataclasses.replace(fp.trajectory, zupt=longer))
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(_arrays(own), _arrays(bench)))
    assert not np.array_equal(own.zupt, fk.trajectory.zupt)
    before = foot_kinematics(gyr, acc, sampling_rate_hz=FS, params=dataclasses.replace(fp, trajectory_zupt=None))
    for f in ("ic_idx", "tc_idx"):
        assert np.array_equal(getattr(fk.events, f), getattr(before.events, f))
    assert np.array_equal(fk.strides.values, before.strides.values, equal_nan=True)
    assert foot_trajectory(gyr, acc, before, sampling_rate_hz=FS,
                           params=dataclasses.replace(fp, trajectory_zupt=None)) is before.trajectory


def test_a_filter_run_is_reused_only_for_the_same_mask_and_filter():
    """``eskf_trajectory(reuse=r)`` returns r's arrays (no second run) when the mask and every filter parameter but
    the minimum stance agree, and they equal a fresh run; a different mask or filter parameter runs the filter."""
    gyr, acc = _short_stance_steps()
    p = FootParams().trajectory
    r = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=p)
    z = r.zupt
    same_mask = dataclasses.replace(p, zupt=dataclasses.replace(p.zupt, min_stance_s=0.04))
    assert np.array_equal(detect_zupt(gyr, acc, sampling_rate_hz=FS, params=same_mask.zupt, gravity=9.81), z)
    again = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=same_mask, reuse=r)
    assert again.pos is r.pos and again.params == same_mask
    fresh = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=same_mask)
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(_arrays(again), _arrays(fresh)))
    other_filter = dataclasses.replace(p, acc_noise_rel=0.3)
    o = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=other_filter, reuse=r)
    assert o.pos is not r.pos and not np.array_equal(o.pos, r.pos, equal_nan=True)
    other_mask = dataclasses.replace(p, zupt=dataclasses.replace(p.zupt, min_stance_s=0.1))
    m = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=other_mask, reuse=r)
    assert not np.array_equal(m.zupt, z) and m.pos is not r.pos
