"""The compiled per-frame joint angles equal the NumPy path (segment_orientations + joint_angles_deg)."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.joints import JOINTS, calibrated_joint_angles_deg, joint_angles_deg
from stridelab.estimators.quaternion import quat_mul, quat_normalize


def _rand_quat(rng, n):
    return quat_normalize(rng.normal(size=(n, 4)))


@pytest.mark.parametrize("joint", sorted(JOINTS))
@pytest.mark.parametrize("side", ["left", "right"])
def test_kernel_equals_numpy_path(joint, side):
    rng = np.random.default_rng(7)
    qp, qd = _rand_quat(rng, 500), _rand_quat(rng, 500)
    rp, rd = _rand_quat(rng, 1)[0], _rand_quat(rng, 1)[0]
    ref = joint_angles_deg(quat_normalize(quat_mul(qp, rp)), quat_normalize(quat_mul(qd, rd)), joint=joint, side=side)
    got = calibrated_joint_angles_deg(qp, qd, rp, rd, joint=joint, side=side)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
    # one row at a time gives the same rows
    one = np.vstack([calibrated_joint_angles_deg(qp[i:i + 1], qd[i:i + 1], rp, rd, joint=joint, side=side)
                     for i in range(0, 500, 50)])
    np.testing.assert_array_equal(one, got[::50])


def test_a_lost_sample_gives_nan_angles_not_a_clipped_value():
    rng = np.random.default_rng(1)
    qp, qd = _rand_quat(rng, 3), _rand_quat(rng, 3)
    qd[1] = np.nan
    out = calibrated_joint_angles_deg(qp, qd, np.array([1.0, 0, 0, 0]), np.array([1.0, 0, 0, 0]), joint="knee",
                                      side="left")
    assert np.isnan(out[1]).all() and np.isfinite(out[[0, 2]]).all()


def test_shapes_are_checked():
    with pytest.raises(ValueError, match="must both be"):
        calibrated_joint_angles_deg(np.zeros((2, 4)), np.zeros((3, 4)), np.ones(4), np.ones(4), joint="hip",
                                    side="left")
