"""stridelab.estimators.sync (sensors on one time grid) and the walking-frame helpers of stridelab.estimators.gait.clinical, moved out
of the calibration / gait / clinical stages (issue #45): checked against constructed truths."""
from __future__ import annotations

import numpy as np

from stridelab.estimators.gait.clinical import positions_at, straight_stride_lengths, walking_frame_xy
from stridelab.estimators.sync import clock_fit, common_grid, interp_columns, nearest_sample, nlerp, to_clock_of


def test_common_grid_is_the_stamps_every_sensor_has():
    a, b = np.arange(0, 100, 10, dtype=np.int64), np.arange(0, 100, 20, dtype=np.int64)
    np.testing.assert_array_equal(common_grid({"x": a, "y": b, "z": a[2:]}), b[1:])
    assert common_grid({}).dtype == np.int64 and len(common_grid({})) == 0


def test_a_clock_offset_and_rate_error_are_recovered_and_undone():
    rng = np.random.default_rng(3)
    t_true = np.arange(0, 60_000_000_000, 10_000_000, dtype=np.int64)        # 60 s at 100 Hz, host time
    # sensor A: stamps = host - 2 ms; sensor B: 1.3 s behind and 50 ppm slow; arrivals jitter by ~0.5 ms
    ta = t_true - 2_000_000
    tb = (t_true - 1_300_000_000 - 50e-6 * t_true).astype(np.int64)
    log = t_true + rng.normal(0, 5e5, len(t_true)).astype(np.int64)
    fa, fb = clock_fit(ta, log), clock_fit(tb, log)
    assert abs(fa[1] - 2e6) < 5e4 and abs(fa[2]) < 1e-6
    assert abs(fb[2] - 50e-6 / (1 - 50e-6)) < 1e-6
    # B's stamps in A's clock: the A stamps of the same instants (within the jitter's averaged error)
    assert np.abs(to_clock_of(tb, fb, fa) - ta).max() < 1e5
    np.testing.assert_allclose(to_clock_of(ta, fa, fa), ta, atol=1.0)


def test_interpolation_and_nlerp_keep_the_samples_and_unit_norm():
    t = np.array([0.0, 1.0, 2.0])
    np.testing.assert_allclose(interp_columns(np.array([0.5, 2.0]), t, np.column_stack([t, 2 * t])),
                               [[0.5, 1.0], [2.0, 4.0]])
    ang = np.array([0.0, 0.4, 0.8])
    q = np.column_stack([np.cos(ang / 2), np.zeros(3), np.zeros(3), np.sin(ang / 2)])
    q[1] *= -1                                                   # the same rotation, other sign
    out = nlerp(t, q, np.array([0.0, 0.5, 1.0, 2.0]))
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)
    np.testing.assert_allclose(np.abs(out[[0, 2, 3]]), np.abs(q), atol=1e-12)
    half = 2 * np.arctan2(out[1, 3], out[1, 0])                   # about z: 0.2 rad halfway between 0 and 0.4
    assert abs(abs(half) - 0.2) < 1e-3


def test_nearest_sample_within_half_a_period():
    grid = np.arange(0, 1_000_000_000, 10_000_000, dtype=np.int64)          # 100 Hz
    t = np.array([3_000_000, 16_000_000, 995_000_000, 1_020_000_000], np.int64)
    i, ok = nearest_sample(grid, t)
    np.testing.assert_array_equal(i, [0, 2, 99, 99])
    np.testing.assert_array_equal(ok, [True, True, True, False])


def test_straight_stride_lengths_stop_at_the_first_turn_and_skip_initiation():
    ic = np.array([5, 1, 2, 3, 4], np.int64)                  # unsorted: IC order is 1, 2, 3, 4, 5
    L = np.array([9.0, 1.0, 1.2, 1.3, np.nan])
    turn = np.array([0.0, 0.0, 0.0, 0.0, 90.0])                 # the IC-4 stride turns
    prev = np.array([True, True, True, False, True])           # the IC-3 stride has no previous IC
    np.testing.assert_array_equal(straight_stride_lengths(ic, L, turn, prev, max_turn_deg=20.0), [1.2])
    turn[4] = 0.0
    # no turn: up to the last stride, the IC-4 stride's NaN length left out
    np.testing.assert_array_equal(straight_stride_lengths(ic, L, turn, prev, max_turn_deg=20.0), [1.2, 9.0])
    L[4] = 1.4
    np.testing.assert_array_equal(straight_stride_lengths(ic, L, turn, prev, max_turn_deg=20.0), [1.2, 1.4, 9.0])


def test_walking_frame_turns_the_first_straight_walk_onto_x_from_zero():
    fs, th = 100.0, np.deg2rad(35.0)
    t = np.arange(1000, dtype=np.int64) * 10_000_000
    s = np.clip((np.arange(1000) - 100) / 100.0, 0, None)        # standing 1 s, then 1 m/s along th
    xy = 5.0 + np.column_stack([s * np.cos(th), s * np.sin(th)])
    stance = np.arange(1000) < 100
    start = t[[100, 300, 500, 700]]
    end = t[[300, 500, 700, 900]]
    out, notes = walking_frame_xy(t, xy, stance, start, end, [0.0, 0.0, 0.0, 120.0], max_turn_deg=20.0)
    assert not notes
    np.testing.assert_allclose(out[:701, 0], s[:701], atol=1e-9)      # +x = the walking direction, from 0
    np.testing.assert_allclose(out[:701, 1], 0.0, atol=1e-9)
    assert np.isnan(out[701:]).all()                                  # after the turning stride starts
    np.testing.assert_allclose(positions_at(t, out, [t[300], t[999] + 1]), [[2.0, 0.0], [np.nan, np.nan]],
                               atol=1e-9)
    out, notes = walking_frame_xy(t, xy, np.zeros(1000, bool), start, end, [0.0] * 4, max_turn_deg=20.0)
    assert np.isnan(out).all() and notes == ["trajectory does not start standing: no step lengths for that stretch"]
