"""The simulator computes its ground truth with code of its own (issue 16 point 1); here the two independent
implementations are checked against each other, which is a real test of both (they share no code)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from stridelab.estimators import recording as est_rec
from stridelab.estimators.joints import clinical_to_matrix, joint_angles_deg
from stridelab.estimators.quaternion import quat_from_matrix, quat_from_rotvec, quat_mul, quat_to_matrix, quat_to_rotvec
from stridelab.validation.simulator import _jcs_truth as jcs
from stridelab.validation.simulator import _records as sim_rec
from stridelab.validation.simulator import _rotations as rot


@pytest.mark.parametrize("name", ["ImuData", "PoseData", "RangeData", "Recording"])
def test_simulator_records_have_the_recording_layout(name):
    a = [(f.name, f.default) for f in dataclasses.fields(getattr(sim_rec, name))]
    b = [(f.name, f.default) for f in dataclasses.fields(getattr(est_rec, name))]
    assert a == b


def _random_rotations(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_rotation_helpers_agree_with_the_estimators_quaternions():
    rng = np.random.default_rng(3)
    q = _random_rotations(rng, 200)
    R = quat_to_matrix(q)
    np.testing.assert_allclose(rot.quat_to_matrix(q), R, atol=1e-12)
    np.testing.assert_allclose(rot.quat_from_matrix(R), quat_from_matrix(R), atol=1e-9)
    p = _random_rotations(rng, 200)
    np.testing.assert_allclose(rot.quat_mul(q, p), quat_mul(q, p), atol=1e-12)
    rv = rng.normal(size=(200, 3))
    a, b = rot.quat_from_rotvec(rv), quat_from_rotvec(rv)
    np.testing.assert_allclose(a * np.sign(a[:, :1]), b * np.sign(b[:, :1]), atol=1e-12)
    np.testing.assert_allclose(rot.quat_to_rotvec(q), quat_to_rotvec(q), atol=1e-9)


@pytest.mark.parametrize("joint", ["hip", "knee", "ankle"])
@pytest.mark.parametrize("side", ["left", "right"])
def test_simulator_jcs_agrees_with_the_estimator_jcs(joint, side):
    """Two implementations of Grood & Suntay: the simulator's from the JCS axes (floating axis, dot products), the
    estimator's from the Cardan matrix elements; they must give the same clinical angles."""
    rng = np.random.default_rng(7)
    n = 300
    ang = np.column_stack([rng.uniform(-60, 80, n), rng.uniform(-25, 25, n), rng.uniform(-30, 30, n)])
    Rp = quat_to_matrix(_random_rotations(rng, n))
    Rd = Rp @ jcs.jcs_relative_matrix(ang, joint=joint, side=side)
    np.testing.assert_allclose(jcs.jcs_angles_deg(Rp, Rd, joint=joint, side=side), ang, atol=1e-9)
    np.testing.assert_allclose(jcs.jcs_relative_matrix(ang, joint=joint, side=side),
                               clinical_to_matrix(ang, joint=joint, side=side), atol=1e-12)
    est = joint_angles_deg(quat_from_matrix(Rp), quat_from_matrix(Rd), joint=joint, side=side)
    np.testing.assert_allclose(est, ang, atol=1e-7)


def test_body_rate_of_a_constant_rotation():
    fs, w = 100.0, np.array([0.3, -1.2, 2.0])
    t = np.arange(200) / fs
    q = rot.quat_mul(rot.quat_from_rotvec([0.2, 0.1, -0.4]), rot.quat_from_rotvec(t[:, None] * w))
    np.testing.assert_allclose(rot.body_rate_from_quat(q, fs), np.tile(w, (200, 1)), atol=1e-9)
