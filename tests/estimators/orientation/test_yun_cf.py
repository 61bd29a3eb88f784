"""FQA and the Yun complementary filter against spec/foot_papers.md A12 and the STYLE.md P8 suite."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.orientation import ESTIMATORS, YunCFParams, enu_to_ned, fqa, yun_cf
from stridelab.estimators.quaternion import (quat_conj, quat_from_axis_angle, quat_mul, quat_rotate, quat_to_matrix)

G = 9.81
B_ENU = 48.0 * np.array([0.0, np.cos(np.radians(63.0)), -np.sin(np.radians(63.0))])   # north = +y, dip down


def small_angle(q_est, q_true):
    """Angle (rad) of q_true* ⊗ q_est, computed from the vector part (A12 T-Y-FQA)."""
    e = quat_mul(quat_conj(q_true), q_est)
    return 2 * np.arcsin(np.clip(np.linalg.norm(e[..., 1:], axis=-1), 0, 1))


def test_fqa_recovers_random_static_orientations_noise_free():
    """T-Y-FQA: random (ψ, θ, φ) with |θ| < 80°; error < 1e-6 rad."""
    rng = np.random.default_rng(0)
    n = 500
    psi, theta, phi = rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.39, 1.39, n), rng.uniform(-np.pi, np.pi, n)
    q = quat_mul(quat_mul(quat_from_axis_angle(np.tile([0, 0, 1.0], (n, 1)), psi),
                          quat_from_axis_angle(np.tile([0, 1.0, 0], (n, 1)), theta)),
                 quat_from_axis_angle(np.tile([1.0, 0, 0], (n, 1)), phi))      # sensor -> ENU
    acc = quat_rotate(quat_conj(q), np.array([0, 0, G]))
    mag = quat_rotate(quat_conj(q), B_ENU)
    est = fqa(acc, mag)
    assert small_angle(est, q).max() < 1e-6


def test_ned_enu_boundary_is_one_fixed_rotation():
    q = quat_from_axis_angle([0.3, -0.2, 0.9], 0.7)
    R_ned = quat_to_matrix(enu_to_ned(q))
    R_enu = quat_to_matrix(q)
    v = np.array([0.2, -1.0, 0.5])
    e, n = R_enu @ v, R_ned @ v
    np.testing.assert_allclose([e[0], e[1], e[2]], [n[1], n[0], -n[2]], atol=1e-12)


ALL = sorted(ESTIMATORS)


@pytest.mark.parametrize("name", ALL)
def test_tilted_rest_maps_gravity_up(name):
    acc = np.tile([G, 0.0, 0.0], (300, 1))                       # sensor x axis points up
    res = ESTIMATORS[name](np.zeros((300, 3)), acc, None, sampling_rate_hz=100.0)
    np.testing.assert_allclose(quat_rotate(res.quat[-1], acc[-1]), [0, 0, G], atol=0.05)
    np.testing.assert_allclose(np.linalg.norm(res.quat, axis=1), 1.0, atol=1e-9)
    assert res.quat.shape == (300, 4)


@pytest.mark.parametrize("name", ALL)
def test_turn_about_sensor_z_moves_sensor_x_towards_enu_y(name):
    n = 400
    gyr = np.zeros((n, 3))
    gyr[100:200, 2] = np.pi / 2                                 # 90° in 1 s about sensor z (= up)
    acc = np.tile([0.0, 0.0, G], (n, 1))
    res = ESTIMATORS[name](gyr, acc, None, sampling_rate_hz=100.0)
    x0 = quat_rotate(res.quat[50], [1.0, 0, 0])
    x1 = quat_rotate(res.quat[-1], [1.0, 0, 0])
    # a +90° turn about up rotates the sensor x axis counter-clockwise in the horizontal plane
    ang = np.degrees(np.arctan2(x1[1], x1[0]) - np.arctan2(x0[1], x0[0]))
    assert (ang + 180) % 360 - 180 == pytest.approx(90.0, abs=1.0)


@pytest.mark.parametrize("name", ALL)
def test_nine_d_heading_points_sensor_to_magnetic_north(name):
    n = 600
    q = quat_from_axis_angle([0, 0, 1.0], np.radians(30))          # sensor x 30° left of east
    acc = np.tile(quat_rotate(quat_conj(q), [0, 0, G]), (n, 1))
    mag = np.tile(quat_rotate(quat_conj(q), B_ENU), (n, 1))
    res = ESTIMATORS[name](np.zeros((n, 3)), acc, mag, sampling_rate_hz=100.0)
    assert np.degrees(small_angle(res.quat[-1], q)) < 1.0


def test_pendulum_roll_yaw_error_follows_gyro_bias_over_gain():
    """T-Y-PEND (A7.1/A12.10): 3° pendulum, period 2 s, k = 1, gyro bias 0.1°/s on all axes."""
    fs, L, T = 100.0, 9.81 / np.pi**2, 60.0
    t = np.arange(int(T * fs)) / fs
    c, w0, amp = 0.05, np.pi, np.radians(3.0)
    th = amp * np.exp(-c * t) * np.cos(w0 * t)
    thd = np.gradient(th, 1 / fs)
    thdd = np.gradient(thd, 1 / fs)
    beta = np.radians(60.36)
    # NED body frame of eq. (11)-(13): x tangential, y pivot axis, z along the rod (down at θ = 0)
    a_ned = np.column_stack([L * thdd + G * np.sin(th), 0 * t, -L * thd**2 - G * np.cos(th)])
    m_ned = np.column_stack([np.cos(beta + th), 0 * t, np.sin(beta + th)])
    gyr = np.column_stack([0 * t, thd, 0 * t]) + np.radians(0.1)
    # eq. (11) is already the specific force the accelerometer measures
    res = yun_cf(gyr, a_ned, m_ned, sampling_rate_hz=fs,
                 params=YunCFParams(k_stance_per_s=1.0, rest_gyr_rad_s=1e9, rest_acc_m_s2=1e9))
    q_true_ned = np.column_stack([np.cos(th / 2), 0 * t, np.sin(th / 2), 0 * t])
    q_est_ned = enu_to_ned(res.quat)
    err = quat_mul(quat_conj(q_true_ned), q_est_ned)
    half = len(t) // 2
    roll = np.degrees(2 * np.abs(err[half:, 1])).mean()
    yaw = np.degrees(2 * np.abs(err[half:, 3])).mean()
    pitch = np.degrees(2 * np.abs(err[half:, 2])).max()
    assert roll == pytest.approx(0.1, abs=0.03) and yaw == pytest.approx(0.1, abs=0.03)
    assert pitch < 1.0


def test_bad_input_is_refused_with_a_reason():
    with pytest.raises(ValueError, match="shorter than one second"):
        yun_cf(np.zeros((50, 3)), np.tile([0, 0, G], (50, 1)), sampling_rate_hz=100.0)
    with pytest.raises(ValueError, match="looks like g"):
        yun_cf(np.zeros((200, 3)), np.tile([0, 0, 1.0], (200, 1)), sampling_rate_hz=100.0)
    with pytest.raises(ValueError, match="deg/s"):
        yun_cf(np.full((200, 3), 90.0), np.tile([0, 0, G], (200, 1)), sampling_rate_hz=100.0)


def test_nan_samples_do_not_cascade():
    n = 500
    gyr = np.zeros((n, 3))
    acc = np.tile([0.0, 0.0, G], (n, 1))
    gyr[100:110] = np.nan
    acc[200:220] = np.nan
    res = yun_cf(gyr, acc, None, sampling_rate_hz=100.0)
    assert np.isfinite(res.quat).all()
