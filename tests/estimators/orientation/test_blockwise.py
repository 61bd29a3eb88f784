"""Day-long recordings in blocks: same result as the whole-recording run, no step at the seams."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import binary_dilation, binary_opening

from stridelab.estimators.orientation import dcf, dcf_offline
from stridelab.estimators.orientation._dcf import dilate, keep_long_runs
from stridelab.estimators.orientation.blockwise import blockwise
from stridelab.estimators.orientation.evaluation import orientation_error_deg, orientation_rmse_deg
from stridelab.estimators.quaternion import quat_conj, quat_from_rotvec, quat_mul, quat_rotate
from tests.estimators.orientation.test_dcf import B_ENU, G, _moving


def _moving_with_rests(n, fs, seed):
    """Like ``_moving`` but the sensor rests 5 s of every minute (a day has rests: blocks need them for the
    gyro bias, as the whole recording does)."""
    w, _, _, _ = _moving(n=2, fs=fs, seed=seed)
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    w = np.column_stack([np.sin(2 * np.pi * f * t + p) * a for f, p, a in
                         zip(rng.uniform(0.1, 0.5, 3), rng.uniform(0, 6, 3), (1.0, 0.8, 1.5))])
    w[(t % 60.0) < 5.0] = 0.0
    dq = quat_from_rotvec(w / fs)
    q = np.empty((n, 4))
    q[0] = [1.0, 0.0, 0.0, 0.0]
    for i in range(1, n):
        q[i] = quat_mul(q[i - 1], dq[i])
    return w, quat_rotate(quat_conj(q), np.array([0, 0, G])), quat_rotate(quat_conj(q), B_ENU), q


def test_run_length_mask_ops_equal_scipy_morphology():
    rng = np.random.default_rng(1)
    for _ in range(300):
        n = int(rng.integers(1, 400))
        x = rng.random(n) < rng.random()
        L, m = int(rng.integers(1, 40)), int(rng.integers(1, 30))
        assert np.array_equal(keep_long_runs(x, L), binary_opening(x, structure=np.ones(L, bool)))
        assert np.array_equal(dilate(x, m), binary_dilation(x, structure=np.ones(2 * m + 1, bool)))


@pytest.mark.slow
@pytest.mark.parametrize("estimator", [dcf_offline, dcf])
def test_blockwise_matches_whole_recording(estimator):
    fs = 100.0
    gyr, acc, mag, q = _moving_with_rests(n=80000, fs=fs, seed=3)    # 13 min: blocks of 2 min, margins of 5 × dcf_offline's τ_mag
    rng = np.random.default_rng(0)
    gyr = gyr + rng.normal(0, 0.01, gyr.shape) + np.radians([0.3, -0.2, 0.1])
    acc = acc + rng.normal(0, 0.05, acc.shape)
    whole = estimator(gyr, acc, mag, sampling_rate_hz=fs)
    blk = blockwise(estimator, gyr, acc, mag, sampling_rate_hz=fs, block_s=120.0, margin_s=300.0, fade_s=60.0)
    assert blk.quat.shape == whole.quat.shape and blk.still.shape == (len(gyr),)
    assert np.allclose(np.linalg.norm(blk.quat, axis=1), 1.0)
    # accuracy is that of the whole-recording run, and the two agree sample by sample
    assert orientation_rmse_deg(blk.quat, q).total_rmse_deg < orientation_rmse_deg(whole.quat, q).total_rmse_deg + 0.05
    assert np.percentile(orientation_error_deg(blk.quat, whole.quat)[0], 99) < 1.0
    # no step at the seams: the sample-to-sample change stays at the level of the motion itself
    step = orientation_error_deg(blk.quat[1:], blk.quat[:-1])[0]
    true_step = orientation_error_deg(q[1:], q[:-1])[0]
    assert step.max() < true_step.max() + 0.5


def test_short_recording_is_one_call():
    gyr, acc, mag, _ = _moving(n=3000)
    a = blockwise(dcf_offline, gyr, acc, mag, sampling_rate_hz=100.0, block_s=3600.0)
    b = dcf_offline(gyr, acc, mag, sampling_rate_hz=100.0)
    assert np.array_equal(a.quat, b.quat)
