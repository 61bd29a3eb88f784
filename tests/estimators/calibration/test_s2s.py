"""Sensor-to-segment calibration: spec §8.1 invariants (U-CAL-1..6) on synthetic IMUs."""
import numpy as np
import pytest

from stridelab.estimators.calibration import (CalibrationError, calibrate_imu, heading_calibration, helical_angle_deg,
                                    vertical_calibration)
from stridelab.validation.simulator.lower_body import random_mounts

G = 9.81


def _mount(rng, max_psi=60, max_tilt=30):
    psi = np.radians(rng.uniform(-max_psi, max_psi))
    tilt = np.radians(rng.uniform(0, max_tilt))
    ax = rng.normal(size=2)
    ax = np.array([ax[0], 0, ax[1]]) / np.hypot(*ax)
    K = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
    Rt = np.eye(3) + np.sin(tilt) * K + (1 - np.cos(tilt)) * K @ K
    c, s = np.cos(psi), np.sin(psi)
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return (Ry @ Rt).T                                   # R_S_AF


def _movement(rng, n=1000, xtalk=0.1, corr=0.0, fs=100.0):
    t = np.arange(n) / fs
    wz = 3.0 * np.sin(2 * np.pi * 1.0 * t)
    wx = xtalk * 3.0 * np.sin(2 * np.pi * 1.7 * t + 0.3) + corr * wz
    wy = xtalk * 3.0 * np.sin(2 * np.pi * 2.3 * t + 1.1)
    return np.column_stack([wx, wy, wz])                 # AF frame


def test_vertical_invariant_ucal1():
    rng = np.random.default_rng(0)
    for _ in range(200):
        R_S_AF = _mount(rng, 180, 60)
        if np.degrees(np.arccos(abs((R_S_AF @ [0, 1, 0])[0]))) < 21:
            continue
        a = np.tile(R_S_AF @ [0, G, 0], (50, 1))
        R_S_VF = vertical_calibration(a)
        v = R_S_VF.T @ a.mean(axis=0)
        assert abs(v[0]) < 1e-9 * G and abs(v[2]) < 1e-9 * G and v[1] == pytest.approx(G)


def test_exact_recovery_noise_free_ucal2():
    rng = np.random.default_rng(1)
    for _ in range(100):
        R = _mount(rng)
        a = np.tile(R @ [0, G, 0], (100, 1))
        w = _movement(rng) @ R.T
        R_est, _, planarity, gamma = calibrate_imu(a, w)
        assert helical_angle_deg(R, R_est) < 0.01
        assert planarity > 0.9 and abs(gamma) <= 90


def test_recovery_with_noise_and_correlated_crosstalk_ucal2():
    rng = np.random.default_rng(2)
    errs = []
    for _ in range(200):
        R = _mount(rng)
        a = R @ [0, G, 0] + rng.normal(0, 0.05, (300, 3))
        w = (_movement(rng, corr=0.03) + rng.normal(0, 0.05, (1000, 3))) @ R.T
        errs.append(float(helical_angle_deg(R, calibrate_imu(a, w)[0])))
    assert np.median(errs) < 2.0 and max(errs) < 2.5


def test_pca_sign_and_order_invariance_ucal3():
    rng = np.random.default_rng(3)
    R = _mount(rng)
    a = np.tile(R @ [0, G, 0], (100, 1))
    w = _movement(rng) @ R.T
    R1 = calibrate_imu(a, w)[0]
    R2 = calibrate_imu(a, -w)[0]                       # flips the eigenvector sign
    R3 = calibrate_imu(a, w[::-1])[0]                   # order of samples
    np.testing.assert_allclose(R1, R2, atol=1e-12)
    np.testing.assert_allclose(R1, R3, atol=1e-12)


def test_decorrelation_ucal4():
    rng = np.random.default_rng(4)
    R = _mount(rng)
    a = np.tile(R @ [0, G, 0], (100, 1))
    w = (_movement(rng, corr=0.2) + rng.normal(0, 0.1, (1000, 3))) @ R.T
    R_est, _, planarity, _ = calibrate_imu(a, w)
    w_af = w @ R_est
    c = np.corrcoef(w_af[:, 0], w_af[:, 2])[0, 1]
    assert abs(c) < 1e-6
    v = w_af - w_af.mean(axis=0)
    assert np.var(v[:, 2]) / (np.var(v[:, 0]) + np.var(v[:, 2])) == pytest.approx(planarity, abs=1e-9)


def test_degenerate_mount_is_rejected_ucal5():
    a = np.tile([G * np.cos(np.radians(10)), G * np.sin(np.radians(10)), 0.0], (100, 1))  # x 10° from up
    with pytest.raises(CalibrationError, match="mounting permutation"):
        vertical_calibration(a)
    with pytest.raises(CalibrationError):
        vertical_calibration(np.empty((0, 3)))
    with pytest.raises(CalibrationError, match="no rotation"):
        heading_calibration(np.zeros((100, 3)), np.eye(3))
    with pytest.raises(ValueError, match="main_axis"):
        heading_calibration(np.ones((100, 3)) * np.arange(100)[:, None], np.eye(3), main_axis="y")


def test_abduction_variant_puts_principal_axis_on_x():
    rng = np.random.default_rng(5)
    R = _mount(rng)
    a = np.tile(R @ [0, G, 0], (100, 1))
    w_af = _movement(rng)[:, [2, 1, 0]]                 # main rotation about AF x
    R_VF_AF, _, _ = heading_calibration(w_af @ R.T, vertical_calibration(a), main_axis="x")
    assert helical_angle_deg(R, vertical_calibration(a) @ R_VF_AF) < 0.01


def test_random_mounts_keep_x_anterior():
    rng = np.random.default_rng(6)
    for R in random_mounts(rng).values():
        assert R[0, 0] > np.cos(np.radians(50))          # sensor x within 50° of AF x
