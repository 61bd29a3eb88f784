"""Issue 43, third round: heading observability in stance (ZARU option) and the non-gait trial whose 3-D error was
1.8 m (PyShoe 2018-02-09-11-19-39). Thresholds are a-priori bounds, not figures read off this code's output."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from stridelab.estimators.quaternion import quat_to_matrix
from stridelab.estimators.trajectory import EskfParams, eskf_trajectory
from tests.conftest import shared_data

FS = 200.0


def _yaw_deg(q) -> float:
    R = quat_to_matrix(q)
    return float(np.degrees(np.arctan2(R[1, 0], R[0, 0])))


def test_zaru_makes_a_yaw_gyro_bias_observable():
    """(E5d, option ``zaru``) A still sensor whose gyro reads a constant bias, 0.01 rad/s about the vertical: the
    ZUPT only sees tilt, so without a zero angular-rate update the yaw drifts by the integrated bias (30 s x
    0.01 rad/s = 17 deg, with 9 states and with 15 states alike); with ZARU the bias is estimated in stance and the
    yaw stays within 3 deg (bound: a tenth of the unobserved drift, a priori)."""
    n = int(30 * FS)
    rng = np.random.default_rng(0)
    bias = np.array([0.002, -0.003, 0.01])
    gyr = bias + rng.normal(0, 0.005, (n, 3))
    acc = np.array([0.0, 0.0, 9.81]) + rng.normal(0, 0.02, (n, 3))
    yaw = {}
    for name, p in {"9": EskfParams(), "15": EskfParams(estimate_biases=True),
                    "zaru": EskfParams(estimate_biases=True, zaru=True)}.items():
        r = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, params=p)
        yaw[name] = abs(_yaw_deg(r.quat[-1]) - _yaw_deg(r.quat[0]))
        if name == "zaru":
            assert abs(r.bias[-1, 5] - bias[2]) < 0.002, r.bias[-1, 3:]
    assert yaw["9"] > 10 and yaw["15"] > 10, yaw            # the failure: yaw unobservable by the ZUPT
    assert yaw["zaru"] < 3, yaw


def test_zaru_needs_the_bias_states():
    with pytest.raises(ValueError, match="estimate_biases"):
        eskf_trajectory(np.zeros((400, 3)), np.tile([0.0, 0.0, 9.81], (400, 1)), sampling_rate_hz=FS,
                        params=EskfParams(zaru=True))


# ---------------------------------------------------------------- the non-gait trial 2018-02-09-11-19-39

def _lift_excerpt():
    """10-17 s of PyShoe 2018-02-09-11-19-39: the sensor rests, is lifted 0.7 m (fast, 1 rad/s) and lowered
    slowly back to its rest height, rests again (Vicon)."""
    from stridelab.pipeline.formats.pyshoe import load_pyshoe_trial
    f = shared_data("pyshoe_vicon") / "2018-02-09-11-19-39.mat"
    if not f.exists():
        pytest.skip(f"{f} not found")
    tr = load_pyshoe_trial(f)
    s = slice(int(10 * FS), int(17 * FS))
    return tr.gyr[s], tr.acc[s], tr.position[s], tr.oracle_zv["shoe"][s]


def _final_height_error(r, ref) -> float:
    return float((r.pos[-1, 2] - r.pos[r.start_idx, 2]) - (ref[-1, 2] - ref[0, 2]))


@pytest.mark.realdata
def test_non_gait_height_error_comes_from_stance_labels_during_the_slow_lowering():
    """Diagnosis of the 1.8 m 3-D error: the filter itself follows the lift (with PyShoe's per-trial optimised
    SHOE labels the sensor comes back within 0.1 m of its rest height), while the shipped detector marks stance
    in the last, slow part of the lowering (Vicon speed > 0.1 m/s, |ω| 0.1-0.3 rad/s below θ_lo = 0.3 rad/s,
    |f| within 1 m/s² of g): a constant slow velocity is indistinguishable from rest for an IMU, the ZUPT zeroes
    the descent there and the height stays up (+0.36 m after one lift; 16 lifts in the trial)."""
    gyr, acc, ref, oracle = _lift_excerpt()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ro = eskf_trajectory(gyr, acc, sampling_rate_hz=FS, zupt=oracle)
        r = eskf_trajectory(gyr, acc, sampling_rate_hz=FS)
    assert abs(_final_height_error(ro, ref)) < 0.1
    speed = np.linalg.norm(np.gradient(ref, axis=0), axis=1) * FS
    lowering = (np.gradient(ref[:, 2]) * FS < -0.05) & (speed > 0.1)
    assert (r.zupt & lowering).sum() > 0.05 * FS            # ≥ 50 ms of stance while the sensor moves down
    assert not (oracle & lowering).any()


@pytest.mark.realdata
@pytest.mark.xfail(strict=True, reason="open (issue 43): the shipped detector takes the slow end of a lowering "
                                       "for stance; no detector change examined held on the other trials "
                                       "(docs/trajectory.md, third round)")
def test_non_gait_lift_returns_to_its_rest_height():
    """Target for the failure mode above: after one lift the sensor is back within 0.1 m of its rest height."""
    gyr, acc, ref, _ = _lift_excerpt()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = eskf_trajectory(gyr, acc, sampling_rate_hz=FS)
    assert abs(_final_height_error(r, ref)) < 0.1


# ---------------------------------------------------------------- gyro bias from genuine rests (option "rest")

def test_rest_gyro_bias_reads_the_bias_only_where_the_sensor_is_still():
    """(E1d) 3 s still (bias + noise), 5 s of gait-like rotation, 3 s still: the estimate is the bias within
    its noise (σ / √N); a slow steady roll of 0.1 rad/s (a settling foot, above the 0.05 rad/s rest bound) is not
    taken; a recording without any 2 s rest gives no estimate (zeros), rather than one from a rolling stance."""
    from stridelab.estimators.trajectory import rest_gyro_bias
    rng = np.random.default_rng(1)
    bias = np.array([0.004, -0.002, 0.003])
    still = lambda s: bias + rng.normal(0, 0.008, (int(s * FS), 3))                     # noqa: E731
    t = np.arange(int(5 * FS)) / FS
    gait = np.column_stack([0.5 * np.sin(2 * np.pi * t), 6.0 * np.sin(2 * np.pi * t), 0.3 * np.cos(np.pi * t)])
    roll = np.tile([0.1, 0.0, 0.0], (int(3 * FS), 1)) + bias
    gyr = np.concatenate([still(3), gait, roll, still(3)])
    est = rest_gyro_bias(gyr, sampling_rate_hz=FS)
    assert np.all(np.abs(est - bias) < 5 * 0.008 / np.sqrt(6 * FS)), est
    assert np.all(rest_gyro_bias(np.concatenate([gait, roll]), sampling_rate_hz=FS) == 0)
    r = eskf_trajectory(gyr, np.tile([0.0, 0.0, 9.81], (len(gyr), 1)), sampling_rate_hz=FS,
                        params=EskfParams(gyro_bias="rest"))
    np.testing.assert_allclose(r.bias[r.start_idx, 3:], est)
