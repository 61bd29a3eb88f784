"""``stridelab bench trajectory --loop`` scores the foot trajectory the gait stage stores (issue 43).

The shipped row must be ``estimators.gait.foot_trajectory`` (the ESKF on the trajectory's own stance detector,
``FootParams.trajectory_zupt``) at the mid-stances of that trajectory's own stance runs; before, it took the gait
events' trajectory (``FootKinematics.trajectory``, ``GAIT_ZUPT``) and their mid-stances. A synthetic loop walk
(Yun et al. simulator, 12 strides turning 30° each) whose feet pivot in the middle of every foot-flat, so that
the foot-flat splits into two short still pieces and the two detectors disagree, written as an x-io CSV.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

FS = 100.0


def _pivot_walk():
    from stridelab.validation.simulator.foot_walk_yun import simulate_yun_walk
    w = simulate_yun_walk(12, sampling_rate_hz=FS, heading_rate_deg_per_stride=30.0, seed=0)
    gyr = w.gyr.copy()
    d = np.diff(np.concatenate([[0], w.stance.astype(np.int8), [0]]))
    runs = list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))
    for a, b in runs[1:-1]:
        c = (a + b) // 2
        gyr[c - 12:c + 12, 2] += 1.0            # 0.24 s pivot about the vertical in the middle of the foot-flat
    return gyr, w.acc


def _write_csv(path, gyr, acc):
    from stridelab.pipeline.formats.loop_csv import COLUMNS, G0
    t = np.arange(len(gyr)) / FS
    data = np.column_stack([t, np.degrees(gyr), acc / G0])
    np.savetxt(path, data, delimiter=",", header=",".join(COLUMNS), comments="", fmt="%.9g")


@pytest.fixture(scope="module")
def loop_csv(tmp_path_factory):
    gyr, acc = _pivot_walk()
    p = tmp_path_factory.mktemp("loop") / "pivot_loop.csv"
    _write_csv(p, gyr, acc)
    return p


def _trajectory_zupt_differs():
    from stridelab.estimators.gait import FootParams
    from stridelab.estimators.trajectory import TRAJECTORY_ZUPT
    return dataclasses.replace(FootParams(), trajectory_zupt=dataclasses.replace(TRAJECTORY_ZUPT, cycle_window=False))


def test_loop_row_scores_the_stored_trajectory_at_its_own_mid_stances(loop_csv):
    from stridelab.estimators.gait import foot_kinematics, foot_trajectory, mid_stances
    from stridelab.estimators.trajectory.evaluation import final_position_error
    from stridelab.pipeline.formats.loop_csv import load_loop_csv
    from stridelab.validation.bench.trajectory import _loop_row
    rec = load_loop_csv(loop_csv)
    fp = _trajectory_zupt_differs()
    row, losses = _loop_row(loop_csv, rec, [], foot_params=fp)
    fk = foot_kinematics(rec.gyr, rec.acc, sampling_rate_hz=rec.sampling_rate_hz, params=fp)
    stored = foot_trajectory(rec.gyr, rec.acc, fk, sampling_rate_hz=rec.sampling_rate_hz, params=fp)
    assert not np.array_equal(stored.zupt, fk.trajectory.zupt)          # the case where the two differ
    mids = mid_stances(stored.zupt, rec.gyr)
    exy, e3 = final_position_error(stored.pos[mids])
    assert row["final_position_error_xy_m"] == exy and row["final_position_error_3d_m"] == e3
    assert row["n_stances"] == len(mids)
    old_xy, _ = final_position_error(fk.trajectory.pos[fk.mid_stance])  # what the bench scored before
    assert old_xy != exy
    assert losses.shape == (0, 2)


def test_loop_benchmark_shipped_row_is_the_default_grid_point(loop_csv, tmp_path, monkeypatch):
    """With the shipped defaults, the stored trajectory is ``eskf_trajectory(EskfParams())``: the shipped block and
    the grid point of the shipped EskfParams give the same closure errors (one two-point grid, two walks)."""
    import stridelab.validation.bench.trajectory as bt
    from stridelab.estimators.trajectory import EskfParams
    from stridelab.pipeline.formats.loop_csv import load_loop_csv
    default = next(g for g in bt.PYSHOE_GRID if bt.grid_params(*g) == EskfParams())
    other = next(g for g in bt.PYSHOE_GRID if bt.grid_params(*g) != EskfParams())
    monkeypatch.setattr(bt, "PYSHOE_GRID", (other, default))
    second = tmp_path / "second.csv"
    second.write_bytes(loop_csv.read_bytes())
    out = bt.loop_benchmark([loop_csv, second], show_progress=False)
    assert out["unreadable"] == []
    ship = out["shipped_defaults"]
    assert ship["final_position_error_xy_m"][0] is not None
    _, losses = bt._loop_row(loop_csv, load_loop_csv(loop_csv), [bt.grid_params(*other), bt.grid_params(*default)])
    assert losses[1, 0] == ship["final_position_error_xy_m"][0]
    assert losses[1, 1] == ship["final_position_error_3d_m"][0]
