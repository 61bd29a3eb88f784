"""Scoring IMU orientation against optical segment poses: mounting and lab heading are recovered."""
from __future__ import annotations

import numpy as np
import pytest

from estimators.orientation.evaluation import align_reference, orientation_rmse_deg, segment_alignment
from estimators.quaternion import quat_from_axis_angle, quat_from_rotvec, quat_mul
from tests.estimators.orientation.test_dcf import _moving


def _angle_deg(a, b):
    return np.degrees(2 * np.arccos(min(1.0, abs(float(np.dot(a, b))))))


def test_mounting_and_heading_recovered_and_error_scored():
    rng = np.random.default_rng(4)
    _, _, _, q_seg = _moving(n=3000, seed=2)                                 # segment -> lab
    mount = quat_from_axis_angle([0.3, -1.0, 0.4], np.radians(35.0))        # sensor -> segment
    heading = quat_from_axis_angle([0, 0, 1], np.radians(-70.0))             # lab -> ENU
    noise = quat_from_rotvec(rng.normal(0, np.radians(1.0), (3000, 3)))     # 1° per axis estimation error
    q_est = quat_mul(quat_mul(quat_mul(heading, q_seg), mount), noise)
    h, m = segment_alignment(q_est, q_seg)
    assert _angle_deg(h, heading) < 0.2 and _angle_deg(m, mount) < 0.2
    err = orientation_rmse_deg(q_est, align_reference(q_est, q_seg))
    assert err.total_rmse_deg == pytest.approx(np.sqrt(3) * 1.0, rel=0.1)    # the injected error, not more
    assert abs(h[1]) < 1e-12 and abs(h[2]) < 1e-12                          # heading is a rotation about z only


def test_tilted_lab_is_not_absorbed_into_the_heading():
    """A tilt between the frames cannot be explained by a heading rotation: it stays in the error."""
    _, _, _, q_seg = _moving(n=2000, seed=5)
    tilt = quat_from_axis_angle([1, 0, 0], np.radians(5.0))
    q_est = quat_mul(tilt, q_seg)
    err = orientation_rmse_deg(q_est, align_reference(q_est, q_seg))
    assert err.inclination_rmse_deg > 2.0


@pytest.mark.parametrize("heading_deg", [150.0, -165.0, 95.0])
def test_a_lab_heading_far_from_the_imus_is_found(heading_deg):
    """The alternating fit converges slowly from a far start (the gaitmap walk: ≈150°, 38° error left after 10
    iterations from identity); the multi-start finds it."""
    rng = np.random.default_rng(7)
    _, _, _, q_seg = _moving(n=3000, seed=3)
    mount = quat_from_axis_angle([1.0, 0.2, -0.3], np.radians(100.0))
    heading = quat_from_axis_angle([0, 0, 1], np.radians(heading_deg))
    noise = quat_from_rotvec(rng.normal(0, np.radians(1.0), (3000, 3)))
    q_est = quat_mul(quat_mul(quat_mul(heading, q_seg), mount), noise)
    h, m = segment_alignment(q_est, q_seg)
    assert _angle_deg(h, heading) < 0.3 and _angle_deg(m, mount) < 0.3
    assert orientation_rmse_deg(q_est, align_reference(q_est, q_seg)).total_rmse_deg < 2.0
