"""foot_kinematics on event sequences as recordings give them: starting with any event, ending mid-stride, or
holding terminal contacts without any initial contact (Voisard trial 5-2 once crashed the gait stage with an
IndexError in the toe-off refinement's 'last IC before each TC')."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from stridelab.estimators.gait import FootParams, GaitEvents, IcTcParams, foot_kinematics
from stridelab.estimators.gait._kinematics import _after_last, _refine_tcs
from tests.conftest import shared_data


def test_after_last_handles_empty_and_leading_points():
    pts = np.array([10, 20, 30], np.int64)
    x = np.array([5, 10, 25, 40], np.int64)
    assert _after_last(pts, x, "left").tolist() == [0, 0, 21, 31]       # strictly before: none before 5 or 10
    assert _after_last(pts, x, "right").tolist() == [0, 11, 21, 31]     # at or before
    assert _after_last(np.zeros(0, np.int64), x, "left").tolist() == [0, 0, 0, 0]


def _fake_foot(n=600, fs=100.0):
    """A foot turning about its mediolateral (y) axis: toes-down swings at 1 Hz, still between them."""
    t = np.arange(n) / fs
    gyr = np.zeros((n, 3))
    gyr[:, 1] = 3.0 * np.sin(2 * np.pi * t)
    zupt = (np.arange(n) % 100) < 40
    traj = SimpleNamespace(quat=np.tile([1.0, 0, 0, 0], (n, 1)), zupt=zupt)
    return gyr, traj, np.flatnonzero(zupt)[::40], fs


@pytest.mark.parametrize("ic, tc", [
    ([], [55, 155, 255]),                     # TCs only (the crash: no IC to bound the refinement)
    ([80, 180], [55, 155, 255]),              # starts with a TC (recording starts in stance), ends with one
    ([30, 130, 230], [55, 155]),              # starts with an IC (recording starts in swing)
    ([], []),
])
def test_toe_off_refinement_on_any_event_sequence(ic, tc):
    gyr, traj, mids, fs = _fake_foot()
    ic, tc = np.array(ic, np.int64), np.array(tc, np.int64)
    ev = GaitEvents(ic, tc, ic + 1, tc + 1, IcTcParams())
    out = _refine_tcs(ev, gyr, traj, mids, np.array([1.0, 0, 0]), fs, FootParams())
    assert len(out.tc_idx) == len(tc) and out.ic_idx.tolist() == ic.tolist()
    for k, j in enumerate(tc):                # refined TC stays after the previous IC and the previous still sample
        prev_ic = ic[ic < j]
        prev_still = np.flatnonzero(traj.zupt[: j + 1])
        lo = max(prev_ic[-1] + 1 if len(prev_ic) else 0, prev_still[-1] + 1 if len(prev_still) else 0)
        assert lo <= out.tc_idx[k] <= j


@pytest.mark.realdata
def test_recording_cut_mid_stride_anywhere():
    """The gaitmap walk cut at ten points over one stride at both ends: no crash, and every stride it reports is
    complete (TC then IC between two mid-stances inside the cut)."""
    from stridelab.pipeline.formats.gaitmap import load_gaitmap_example
    ex = load_gaitmap_example(shared_data("gaitmap_example"))
    foot, fs = ex.left, ex.sampling_rate_hz
    first = int(foot.strides[1, 0])
    stride = int(np.median(np.diff(foot.strides[:, 0])))
    for k, cut in enumerate(np.linspace(first, first + stride, 10).astype(int)):
        end = len(foot.acc) - int(0.1 * k * stride) - 1
        fk = foot_kinematics(foot.gyr[cut:end], foot.acc[cut:end], sampling_rate_hz=fs)
        assert fk.status in ("ok", "no_strides", "no_stance")
        st = fk.strides.idx
        assert np.all((st[:, 0] < st[:, 2]) & (st[:, 2] < st[:, 3]) & (st[:, 3] < st[:, 1]))
        assert np.all((st[:, :4] >= 0) & (st[:, :4] < end - cut))


@pytest.mark.parametrize("ic, tc", [
    ([30, 130, 230], []),                     # ICs only (no TC to bound the heel-strike refinement)
    ([80, 180], [55, 155, 255]),              # TC first, TC last
    ([30, 130, 230], [55, 155]),              # IC last, with no TC after it
    ([599], [55]),                            # an IC on the last sample
    ([], []),
])
def test_heel_strike_refinement_on_any_event_sequence(ic, tc):
    from stridelab.estimators.gait._kinematics import _refine_ics
    gyr, traj, mids, fs = _fake_foot()
    ic, tc = np.array(ic, np.int64), np.array(tc, np.int64)
    s = -np.cos(2 * np.pi * np.arange(len(gyr)) / fs)       # any pitch signal: falls after some ICs, not others
    ev = GaitEvents(ic, tc, ic + 1, tc + 1, IcTcParams())
    out = _refine_ics(ev, gyr, traj, mids, np.array([1.0, 0, 0]), s, fs, FootParams())
    assert len(out.ic_idx) == len(ic) and out.tc_idx.tolist() == tc.tolist()
    for k, j in enumerate(ic):                # refined IC stays at/after the pitch maximum, before the next TC / mid
        nxt = [x for x in (*tc[tc > j], *mids[mids > j]) if x > j]
        assert j <= out.ic_idx[k] <= (min(nxt) - 1 if nxt else len(s) - 1)
