"""Full-state LKF / robust EKF (spec/thesis_orientation.md §5, §8 A1/A2/A18, acceptance 9.1 T2-T3, T6, 9.2 T9)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from stridelab.estimators.orientation import (FullStateLKFFilter, FullStateLKFParams, RobustEKFFilter, RobustEKFParams,
                                    full_state_lkf, full_state_lkf_literal, robust_ekf)
from stridelab.estimators.orientation._fullstate_kernel import (NX, STATE_LEN, ekf_series, f_taylor, h_jac_q, h_model,
                                                      process_jac, _level)
from stridelab.estimators.orientation.evaluation import orientation_rmse_deg
from stridelab.estimators.quaternion import quat_conj, quat_from_axis_angle, quat_from_rotvec, quat_mul, quat_rotate

G = 9.81
B_ENU = np.array([0.0, 20.0, -40.0])


def simulate(n=12000, fs=100.0, bias_deg_s=0.5, seed=0, noise=True):
    """Smooth multi-axis rotation (ω up to ≈ 2 rad/s), gravity + small external acceleration, exact
    strap-down truth, constant gyro bias, white noise (gyro 0.01 rad/s, acc 0.01 g, mag 0.01 of the field)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    w = np.zeros((n, 3))
    for k in range(3):
        for f, a in zip(rng.uniform(0.05, 0.6, 3), rng.uniform(0.2, 0.8, 3)):
            w[:, k] += a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    w[: int(2 * fs)] = 0.0                                         # 2 s still at the start
    q = np.empty((n, 4))
    q[0] = quat_from_axis_angle([1.0, 0.5, 0.0], 0.4)
    for i in range(1, n):
        q[i] = quat_mul(q[i - 1], quat_from_rotvec(w[i] / fs))
    a_ext = 0.3 * np.column_stack([np.sin(2 * np.pi * 1.1 * t), np.cos(2 * np.pi * 0.7 * t), 0 * t])
    a_ext[: int(2 * fs)] = 0.0
    acc = quat_rotate(quat_conj(q), np.array([0, 0, G]) + a_ext)
    mag = quat_rotate(quat_conj(q), B_ENU)
    bias = np.radians(bias_deg_s) * np.ones(3)
    gyr = w + bias
    if noise:
        gyr = gyr + 0.01 * rng.standard_normal((n, 3))
        acc = acc + 0.01 * G * rng.standard_normal((n, 3))
        mag = mag + 0.01 * np.linalg.norm(B_ENU) * rng.standard_normal((n, 3))
    return gyr, acc, mag, q, bias


# ------------------------------------------------------------------ T2 Jacobians

def _fd(fun, x, eps=1e-6):
    return np.array([(fun(x + e) - fun(x - e)) / (2 * eps) for e in np.eye(len(x)) * eps]).T


@pytest.mark.parametrize("seed", range(5))
def test_measurement_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=NX)
    x[:4] /= np.linalg.norm(x[:4])
    m = np.array([0.0, 0.45, -0.89])

    def h(v):
        out = np.empty(6)
        h_model(v, m, out)
        return out

    J = np.zeros((6, NX))
    Hq = np.empty((6, 4))
    h_jac_q(x, m, Hq)
    J[:, :4] = Hq
    J[0:3, 4:7] = np.eye(3)
    J[3:6, 10:13] = np.eye(3)
    np.testing.assert_allclose(J, _fd(h, x), atol=1e-6)
    # h is R(q)ᵀ applied to the references (spec §1.2)
    x0 = np.r_[x[:4], np.zeros(9)]
    np.testing.assert_allclose(h(x0)[:3], quat_rotate(quat_conj(x[:4]), [0, 0, 1.0]), atol=1e-12)
    np.testing.assert_allclose(h(x0)[3:], quat_rotate(quat_conj(x[:4]), m), atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_process_jacobian_and_fbk_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=NX)
    x[:4] /= np.linalg.norm(x[:4])
    y = rng.normal(size=3) * 3.0
    dt, ca, cd = 0.01, 0.9, 0.95

    def f(v):
        out = np.empty(NX)
        f_taylor(v, y, dt, ca, cd, out)
        return out

    A = np.empty((NX, NX))
    process_jac(x, y, dt, ca, cd, False, A)                # Taylor form, Th. Eq 39-40
    np.testing.assert_allclose(A, _fd(f, x), atol=1e-6)
    # the exact-exponential q block used by the filter is within O(T³) of it
    Ae = np.empty((NX, NX))
    process_jac(x, y, dt, ca, cd, True, Ae)
    assert np.abs(Ae[:4, :4] - A[:4, :4]).max() < 1e-5


def test_switching_level_is_strict_less_than_and_nested():
    thr = np.array([0.1, 0.3])
    assert [_level(v, thr) for v in (0.0, 0.0999, 0.1, 0.2999, 0.3, 5.0)] == [0, 0, 1, 1, 2, 2]
    assert _level(1.0, np.zeros(0)) == 0


# ------------------------------------------------------------------ T3 robust EKF reduces to the EKF

def test_robust_ekf_with_huge_gamma_equals_plain_ekf():
    gyr, acc, mag, _, _ = simulate(n=10000, seed=1)
    base = RobustEKFParams()
    plain = robust_ekf(gyr, acc, mag, sampling_rate_hz=100.0, params=dataclasses.replace(base, gamma=math.inf))
    big = robust_ekf(gyr, acc, mag, sampling_rate_hz=100.0, params=dataclasses.replace(base, gamma=1e8))
    assert big.n_robust_fallback == 0
    np.testing.assert_allclose(big.quat, plain.quat, rtol=0, atol=1e-9)
    np.testing.assert_allclose(big.gyr_bias, plain.gyr_bias, rtol=0, atol=1e-9)
    np.testing.assert_allclose(big.ext_acc, plain.ext_acc, rtol=0, atol=1e-9)


def test_robust_update_inflates_covariance_and_keeps_it_symmetric_psd():
    gyr, acc, mag, _, _ = simulate(n=3000, seed=2)
    f = RobustEKFFilter(RobustEKFParams(gamma=math.inf), sampling_rate_hz=100.0)
    f.update_batch(gyr[:2000], acc[:2000] , mag[:2000])
    s0 = f.state[:STATE_LEN]
    g_ref, m_norm, mref = f.state[STATE_LEN + 1], f.state[STATE_LEN + 2], f.state[STATE_LEN + 3:STATE_LEN + 6]
    lv = np.array([1.0])
    th = np.zeros(0)
    out = []
    for gi2 in (0.0, 1.0 / 30.0 ** 2):                       # one step, same P⁻: EKF vs robust
        s = s0.copy()
        ekf_series(gyr[2000:2001], acc[2000:2001] / g_ref, mag[2000:2001] / m_norm, True, 0.01,
                   np.array([0.8, 0.99, 1e-3, 1e-8, 1e-5, gi2]), lv * 0.005, th, lv * 0.05, th, lv * 0.3, th, mref, s,
                   np.empty((1, 4)), np.empty((1, 9)), np.empty((1, 3), dtype=np.int8))
        out.append(s[NX:NX + NX * NX].reshape(NX, NX))
    p_ekf, p_rob = out
    assert np.linalg.eigvalsh(p_rob - p_ekf).min() > -1e-15
    assert np.trace(p_rob - p_ekf) > 0
    # over a whole run P stays symmetric and positive (semi-)definite (A18)
    r = RobustEKFFilter(RobustEKFParams(gamma=30.0), sampling_rate_hz=100.0)
    r.update_batch(gyr, acc, mag)
    P = r.state[NX:NX + NX * NX].reshape(NX, NX)
    np.testing.assert_allclose(P, P.T, atol=0)
    assert np.linalg.eigvalsh(P).min() > -1e-12


# ------------------------------------------------------------------ T9 bias convergence (A1)

def test_gyro_bias_converges_for_robust_ekf_and_corrected_lkf_not_for_literal_lkf():
    gyr, acc, mag, q, bias = simulate(n=12000, seed=0)                 # 120 s, 0.5°/s on every axis
    ekf = robust_ekf(gyr, acc, mag, sampling_rate_hz=100.0, params=RobustEKFParams(static_bias=False))
    err = np.degrees(np.abs(ekf.gyr_bias[-1000:] - bias)).max()
    assert err < 0.1, f"robust EKF bias error {err:.3f}°/s"
    lkf = full_state_lkf(gyr, acc, mag, sampling_rate_hz=100.0, params=FullStateLKFParams(static_bias=False))
    err_l = np.degrees(np.abs(lkf.gyr_bias[-1000:] - bias)).max()
    assert err_l < 0.2, f"corrected LKF bias error {err_l:.3f}°/s"
    lit = full_state_lkf_literal(gyr, acc, mag, sampling_rate_hz=100.0,
                                 params=FullStateLKFParams(literal=True, static_bias=False))
    assert np.abs(lit.gyr_bias).max() == 0.0                            # b_G never moves (spec A1)


def test_full_state_filters_track_noisy_motion_9d_and_6d():
    gyr, acc, mag, q, _ = simulate(n=6000, seed=3)
    for fn in (robust_ekf, full_state_lkf):
        for m in (mag, None):
            res = fn(gyr, acc, m, sampling_rate_hz=100.0)
            e = orientation_rmse_deg(res.quat, q)
            if m is None:
                assert e.inclination_rmse_deg < 2.0, (fn.__name__, e)
            else:
                assert e.total_rmse_deg < 3.0, (fn.__name__, e)


# ------------------------------------------------------------------ P4 chunked == whole, state round trip

@pytest.mark.parametrize("cls,params", [(RobustEKFFilter, RobustEKFParams()),
                                        (FullStateLKFFilter, FullStateLKFParams()),
                                        (FullStateLKFFilter, FullStateLKFParams(literal=True))])
def test_chunked_equals_whole_and_state_roundtrip(cls, params):
    gyr, acc, mag, _, _ = simulate(n=1500, seed=4)
    whole = cls(params, sampling_rate_hz=100.0).update_batch(gyr, acc, mag)
    f = cls(params, sampling_rate_hz=100.0)
    a = f.update_batch(gyr[:700], acc[:700], mag[:700])
    g = cls(params, sampling_rate_hz=100.0)
    g.state = f.state
    b = g.update_batch(gyr[700:], acc[700:], mag[700:])
    np.testing.assert_allclose(np.vstack([a.quat, b.quat]), whole.quat, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.vstack([a.gyr_bias, b.gyr_bias]), whole.gyr_bias, rtol=0, atol=1e-12)


def test_nan_samples_do_not_cascade():
    gyr, acc, mag, q, _ = simulate(n=3000, seed=5)
    gyr[1000:1010] = np.nan
    acc[1500:1600] = np.nan
    mag[2000:2300] = np.nan
    for fn in (robust_ekf, full_state_lkf):
        res = fn(gyr, acc, mag, sampling_rate_hz=100.0)
        assert np.all(np.isfinite(res.quat))
        assert orientation_rmse_deg(res.quat[2500:], q[2500:]).total_rmse_deg < 3.0


@pytest.mark.parametrize("cls", [RobustEKFParams, FullStateLKFParams])
def test_params_documented_hashable_json(cls):
    import json
    p = cls()
    assert all(f.name in (cls.__doc__ + (RobustEKFParams.__doc__ or "")) for f in dataclasses.fields(p))
    d = json.loads(json.dumps(dataclasses.asdict(p)))
    assert cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}) == p
    hash(p)


def test_bad_switching_levels_raise():
    with pytest.raises(ValueError, match="sigma_acc_g"):
        RobustEKFFilter(RobustEKFParams(sigma_acc_g=(0.1, 0.2), s_acc_g=()), sampling_rate_hz=100.0)
    with pytest.raises(ValueError, match="gamma"):
        RobustEKFFilter(RobustEKFParams(gamma=0.0), sampling_rate_hz=100.0)
