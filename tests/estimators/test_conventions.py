"""Quaternion convention of DESIGN.md: Hamilton, [w x y z], q rotates sensor -> ENU."""
import numpy as np

from stridelab.estimators.quaternion import (quat_conj, quat_exp_step_1, quat_from_axis_angle, quat_from_matrix,
                                   quat_from_rotvec, quat_mul, quat_rotate, quat_to_matrix, quat_to_rotvec)


def test_hamilton_product_ij_is_k():
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_allclose(quat_mul(i, j), k)
    np.testing.assert_allclose(quat_mul(j, i), -k)


def test_rotation_about_z_moves_sensor_x_to_earth_y():
    q = quat_from_axis_angle([0, 0, 1], np.pi / 2)
    np.testing.assert_allclose(quat_rotate(q, [1.0, 0, 0]), [0, 1, 0], atol=1e-12)
    # same as the sandwich product q ⊗ v ⊗ q*
    v = np.array([0.0, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(quat_mul(quat_mul(q, v), quat_conj(q))[1:], [0, 1, 0], atol=1e-12)


def test_matrix_roundtrip_and_rotvec_roundtrip():
    rng = np.random.default_rng(1)
    rv = rng.normal(size=(200, 3))
    rv *= (np.pi * 0.99 / np.maximum(np.linalg.norm(rv, axis=1), np.pi))[:, None]
    q = quat_from_rotvec(rv)
    np.testing.assert_allclose(quat_from_matrix(quat_to_matrix(q)), q * np.sign(q[:, :1]), atol=1e-12)
    np.testing.assert_allclose(quat_to_rotvec(q), rv, atol=1e-10)


def test_body_rate_integration_uses_right_multiplication():
    # q_dot = 1/2 q ⊗ [0, ω_body]: 1 rad/s about body z for 1 s after a 90° pitch turns about the earth axis
    q = quat_from_axis_angle([0, 1, 0], np.pi / 2)   # sensor z now points along earth +x... (R e_z = +x)
    for _ in range(1000):
        q = quat_exp_step_1(q, 0.0, 0.0, 1.0, 1e-3)
    expected = quat_mul(quat_from_axis_angle([0, 1, 0], np.pi / 2), quat_from_axis_angle([0, 0, 1], 1.0))
    np.testing.assert_allclose(q, expected, atol=1e-12)
    np.testing.assert_allclose(quat_rotate(q, [0, 0, 1.0]), [1, 0, 0], atol=1e-12)


def test_numba_matrix_kernel_equals_quat_to_matrix():
    from stridelab.estimators.quaternion import quat_from_axis_angle, quat_to_matrix, quat_to_matrix_1
    q = quat_from_axis_angle([0.3, -1.0, 0.5], 1.2)
    R = np.empty((3, 3))
    quat_to_matrix_1(q, R)
    np.testing.assert_allclose(R, quat_to_matrix(q), atol=1e-15)
