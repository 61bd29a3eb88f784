"""Yun CF online class (STYLE P4): fused kernel = detect_rest + original kernel; chunked = whole."""
from __future__ import annotations

import numpy as np

from stridelab.estimators.orientation import YunCFParams, detect_rest
from stridelab.estimators.orientation._frames import ned_to_enu
from stridelab.estimators.orientation._yun_cf import YunCFFilter, _yun_series, initial_attitude_ned, yun_cf
from tests.estimators.orientation.test_fullstate import simulate


def _reference(gyr, acc, mag, p, fs):
    still = detect_rest(gyr, acc, sampling_rate_hz=fs, gyr_threshold_rad_s=p.rest_gyr_rad_s,
                        acc_tolerance_m_s2=p.rest_acc_m_s2, min_duration_s=p.rest_min_s)
    n = len(gyr)
    q0 = initial_attitude_ned(acc, mag, max(1, int(p.init_s * fs)), 1.0, 0.0)
    q, g = np.empty((n, 4)), np.empty(n)
    _yun_series(gyr, acc, mag if mag is not None else np.full((n, 3), np.nan), mag is not None, still, 1.0 / fs,
                p.k_stance_per_s, p.k_swing_per_s, 1.0, 0.0, q0, q, g)
    return ned_to_enu(q), still


def test_fused_kernel_equals_rest_detector_plus_filter():
    gyr, acc, mag, _, _ = simulate(n=3000, seed=11)
    gyr[::7] *= 0.05                                    # some samples satisfy the rest condition
    p = YunCFParams(rest_gyr_rad_s=0.8, rest_acc_m_s2=1.0)
    for m in (mag, None):
        q_ref, still_ref = _reference(gyr, acc, m, p, 100.0)
        res = yun_cf(gyr, acc, m, sampling_rate_hz=100.0, params=p)
        np.testing.assert_array_equal(res.still, still_ref)
        np.testing.assert_allclose(res.quat, q_ref, rtol=0, atol=1e-14)


def test_chunked_equals_whole_and_state_roundtrip():
    gyr, acc, mag, _, _ = simulate(n=1500, seed=12)
    p = YunCFParams(rest_gyr_rad_s=0.8, rest_acc_m_s2=1.0)
    whole = yun_cf(gyr, acc, mag, sampling_rate_hz=100.0, params=p)
    f = YunCFFilter(p, sampling_rate_hz=100.0)
    a = f.update_batch(gyr[:700], acc[:700], mag[:700])
    g = YunCFFilter(p, sampling_rate_hz=100.0)
    g.state = f.state
    b = g.update_batch(gyr[700:], acc[700:], mag[700:])
    np.testing.assert_allclose(np.vstack([a.quat, b.quat]), whole.quat, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.r_[a.still, b.still], whole.still)
