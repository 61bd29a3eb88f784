"""JCS joint angles: sign table on constructed poses (spec U-PIPE-1), offsets, cycles, end to end."""
import numpy as np
import pytest

from stridelab.estimators.calibration import CalibrationParams, calibrate_session, missing_calibration
from stridelab.validation.simulator.lower_body import R_G_AF0, calibration_trial, random_mounts, walking_trial
from stridelab.estimators.joints import (angle_errors, clinical_to_matrix, compute_joint_angles, joint_angles_deg,
                               normalise_cycles, remove_standing_offset, session_gait_curves, zxy_angles_deg,
                               zxy_matrix)
from stridelab.estimators.quaternion import quat_from_matrix

FS = 100.0


def _rot(axis, deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]), "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def _angles(R_prox, R_dist, joint, side):
    q = lambda R: quat_from_matrix(R)[None]
    return joint_angles_deg(q(R_prox), q(R_dist), joint=joint, side=side)[0]


@pytest.mark.parametrize("side", ["left", "right"])
def test_sign_table_upipe1(side):
    I = np.eye(3)
    sgn = 1 if side == "right" else -1
    np.testing.assert_allclose(_angles(I, _rot("z", 20), "hip", side), [20, 0, 0], atol=1e-9)
    np.testing.assert_allclose(_angles(I, _rot("z", 20), "knee", side), [-20, 0, 0], atol=1e-9)
    np.testing.assert_allclose(_angles(I, _rot("z", 20), "ankle", side), [20, 0, 0], atol=1e-9)
    for joint in ("hip", "knee", "ankle"):
        np.testing.assert_allclose(_angles(I, _rot("x", 10), joint, side), [0, 10 * sgn, 0], atol=1e-9)
        np.testing.assert_allclose(_angles(I, _rot("y", 15), joint, side), [0, 0, 15 * sgn], atol=1e-9)


def test_roundtrip_matrix_angles():
    rng = np.random.default_rng(0)
    ang = rng.uniform([-90, -60, -90], [90, 60, 90], (500, 3))
    R = zxy_matrix(ang[:, 0], ang[:, 1], ang[:, 2])
    np.testing.assert_allclose(zxy_angles_deg(R), ang, atol=1e-9)
    for joint in ("hip", "knee", "ankle"):
        for side in ("left", "right"):
            Rc = clinical_to_matrix(ang, joint=joint, side=side)
            q = quat_from_matrix(Rc)
            out = joint_angles_deg(np.tile([1.0, 0, 0, 0], (500, 1)), q, joint=joint, side=side)
            np.testing.assert_allclose(out, ang, atol=1e-9)


# ---- physical meaning of the signs on a constructed standing body (ENU, facing east) -----------

def _pose(side, joint, R_rel):
    """Proximal segment upright facing east; distal segment rotated by R_rel (in the proximal frame)."""
    Rp = R_G_AF0
    return _angles(Rp, Rp @ R_rel, joint, side), Rp @ R_rel


@pytest.mark.parametrize("side", ["left", "right"])
def test_physical_signs(side):
    # facing east the body's right is south (ENU −y): medial is north for the right leg, south for the left
    medial = np.array([0, 1.0, 0]) if side == "right" else np.array([0, -1.0, 0])
    east, up = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    # knee flexion: the shank's distal end moves posterior → K_FE > 0
    for deg in np.linspace(-60, 60, 13):
        if deg == 0:
            continue
        R_rel = _rot("z", deg)
        ang, Rd = _pose(side, "knee", R_rel)
        distal = Rd @ [0, -1.0, 0]
        assert np.sign(ang[0]) == np.sign(-(distal @ east)), (deg, ang)
        ang, Rd = _pose(side, "hip", R_rel)                      # hip flexion: knee moves anterior
        assert np.sign(ang[0]) == np.sign((Rd @ [0, -1.0, 0]) @ east)
        ang, Rd = _pose(side, "ankle", R_rel)                    # dorsiflexion: toes up
        assert np.sign(ang[0]) == np.sign((Rd @ [1.0, 0, 0]) @ up)
    for deg in (-15, 15):
        # adduction: the distal end of the thigh moves medially
        ang, Rd = _pose(side, "hip", _rot("x", deg))
        assert np.sign(ang[1]) == np.sign((Rd @ [0, -1.0, 0]) @ medial)
        # inversion: the sole (foot −y) faces medially
        ang, Rd = _pose(side, "ankle", _rot("x", deg))
        assert np.sign(ang[1]) == np.sign((Rd @ [0, -1.0, 0]) @ medial)
        # internal rotation: the anterior axis turns medially
        for joint in ("hip", "knee", "ankle"):
            ang, Rd = _pose(side, joint, _rot("y", deg))
            assert np.sign(ang[2]) == np.sign((Rd @ [1.0, 0, 0]) @ medial)


def test_offset_removal_upipe2():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(1000, 3)) + [5, -3, 10]
    b, off = remove_standing_offset(a, (0, 300))
    np.testing.assert_allclose(b[:300].mean(axis=0), 0, atol=1e-9)
    np.testing.assert_allclose(off, a[:300].mean(axis=0))
    with pytest.raises(ValueError, match="standing window"):
        remove_standing_offset(a, (900, 1200))


def test_cycle_normalisation():
    t = np.arange(1000)
    sig = np.column_stack([np.sin(2 * np.pi * t / 100), np.cos(2 * np.pi * t / 100)])
    cc = normalise_cycles(sig, np.arange(50, 1000, 100))
    assert cc.cycles.shape == (9, 101, 2) and cc.mean.shape == (101, 2)
    np.testing.assert_allclose(cc.mean[:, 0], np.sin(2 * np.pi * (0.5 + np.linspace(0, 1, 101))), atol=1e-3)
    np.testing.assert_allclose(cc.sd, 0, atol=1e-9)
    np.testing.assert_allclose(cc.rom_mean, [2, 2], atol=1e-3)
    empty = normalise_cycles(sig, [10])
    assert empty.n_cycles == 0 and empty.mean.shape == (101, 2) and np.all(np.isnan(empty.mean))


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(21)
    mounts = random_mounts(rng)
    cal_tr = calibration_trial(mounts=mounts, rng=rng, noise=False, standing_offsets=False, crosstalk=0.0)
    walk = walking_trial(mounts=mounts, rng=rng, strides=15)
    return mounts, cal_tr, walk


def test_end_to_end_truth_orientations_upipe3(scene):
    mounts, cal_tr, walk = scene
    cal = calibrate_session(cal_tr.acc, cal_tr.gyr, sampling_rate_hz=FS, params=CalibrationParams(method="walking"),
                            quats=cal_tr.quat_sensor)
    ja = compute_joint_angles(walk.quat_sensor, cal, standing=walk.standing)
    assert set(ja.angles_deg) == {f"{j}_{s}" for j in ("hip", "knee", "ankle") for s in ("left", "right")}
    for key, est in ja.angles_deg.items():
        ref, _ = remove_standing_offset(walk.angles_deg[key], walk.standing)
        err = angle_errors(ref, est)
        assert np.all(err.rmse_deg < 1.0), (key, err.rmse_deg)
        assert ja.status[key] in ("pass", "warn")
    assert "pelvis calibration: non-thesis" in ja.notes["hip_left"]
    curves = session_gait_curves(ja, walk.ic, sampling_rate_hz=FS)
    k = curves["knee_right"]
    assert k.n_cycles >= 12 and 50 < k.rom_mean[0] < 70


def test_failed_calibration_marks_angles(scene):
    mounts, cal_tr, walk = scene
    ja = compute_joint_angles(walk.quat_sensor, missing_calibration())
    assert all(s == "fail" for s in ja.status.values())
    assert all(np.all(np.isnan(a)) for a in ja.angles_deg.values())
