"""Alignment with optical capture: angular-rate time sync and constant IMU-to-cluster rotation."""
import numpy as np
import pytest

from stridelab.estimators.calibration import (body_rate_from_quat, constant_offset_rotation, helical_angle_deg,
                                    imu_to_cluster_rotation, sync_by_angular_rate)
from stridelab.validation.simulator.lower_body import random_mounts, walking_trial
from stridelab.estimators.quaternion import quat_from_matrix, quat_mul

FS = 100.0


@pytest.fixture(scope="module")
def walk():
    rng = np.random.default_rng(31)
    return walking_trial(mounts=random_mounts(rng), rng=rng, strides=12, noise=True)


@pytest.mark.parametrize("lag", [0, 7, -23, 41])
def test_sync_recovers_known_lag(walk, lag):
    gyr = walk.gyr["shank_right"]
    ref = body_rate_from_quat(walk.quat_segment["shank_right"], sampling_rate_hz=FS)
    ref_shifted = np.roll(ref, -lag, axis=0)          # imu[k] = ref_shifted[k - lag]
    res = sync_by_angular_rate(gyr, ref_shifted, sampling_rate_hz=FS)
    assert abs(res.lag_samples - lag) < 0.5 and res.peak_corr > 0.9
    assert res.lag_s == pytest.approx(res.lag_samples / FS)


def test_body_rate_of_constant_rotation():
    t = np.arange(200) / FS
    q = np.column_stack([np.cos(0.5 * 2.0 * t), np.zeros(200), np.zeros(200), np.sin(0.5 * 2.0 * t)])
    np.testing.assert_allclose(body_rate_from_quat(q, sampling_rate_hz=FS), np.tile([0, 0, 2.0], (200, 1)), atol=1e-9)


def test_imu_to_cluster_rotation(walk):
    rng = np.random.default_rng(32)
    R_C_S = random_mounts(rng)["foot_left"]            # any rotation
    w_s = walk.gyr["foot_left"]
    w_c = w_s @ R_C_S.T + rng.normal(0, 0.02, w_s.shape)
    assert helical_angle_deg(R_C_S, imu_to_cluster_rotation(w_s, w_c)) < 0.2
    with pytest.raises(ValueError, match="fewer than two axes"):
        imu_to_cluster_rotation(np.outer(np.sin(np.arange(100)), [0, 0, 1.0]),
                                np.outer(np.sin(np.arange(100)), [0, 1.0, 0]))


def test_constant_offset_rotation(walk):
    R = random_mounts(np.random.default_rng(33))["thigh_left"]
    qa = walk.quat_segment["thigh_left"]
    qb = quat_mul(qa, quat_from_matrix(R))
    assert helical_angle_deg(R, constant_offset_rotation(qa, qb)) < 1e-6
