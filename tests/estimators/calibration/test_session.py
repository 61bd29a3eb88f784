"""Session calibration on the synthetic seven-segment body: windows, accuracy, QC statuses."""
import numpy as np
import pytest

from stridelab.estimators.calibration import (CalibrationParams, CalibrationWindows, calibrate_session,
                                    detect_calibration_windows, helical_angle_deg)
from stridelab.validation.simulator.lower_body import calibration_trial, random_mounts

FS = 100.0


@pytest.fixture(scope="module")
def mounts():
    return random_mounts(np.random.default_rng(11))


@pytest.fixture(scope="module")
def clean(mounts):
    return calibration_trial(mounts=mounts, rng=np.random.default_rng(12), noise=False, standing_offsets=False,
                             crosstalk=0.0)


@pytest.fixture(scope="module")
def noisy(mounts):
    return calibration_trial(mounts=mounts, rng=np.random.default_rng(13))


def _err(cal, mounts):
    return {p: float(helical_angle_deg(mounts[p], c.R_sensor_af)) for p, c in cal.imus.items()}


@pytest.mark.parametrize("method", ["hip_fe", "walking"])
def test_exact_recovery_on_single_axis_movements(clean, mounts, method):
    cal = calibrate_session(clean.acc, clean.gyr, sampling_rate_hz=FS, params=CalibrationParams(method=method),
                            quats=clean.quat_sensor)
    assert cal.status == "pass", cal.as_dict()
    errs = _err(cal, mounts)
    assert max(errs.values()) < 0.1, errs
    assert cal.imus["pelvis"].method == "pelvis_thighs"


@pytest.mark.parametrize("method", ["hip_fe", "walking"])
def test_accuracy_with_noise_and_crosstalk(noisy, mounts, method):
    cal = calibrate_session(noisy.acc, noisy.gyr, sampling_rate_hz=FS, params=CalibrationParams(method=method),
                            quats=noisy.quat_sensor)
    errs = _err(cal, mounts)
    limit = 8.0 if method == "hip_fe" else 15.0          # thesis medians: 6-16° on real data
    assert np.median(list(errs.values())) < limit, errs
    for c in cal.imus.values():
        assert c.status in ("pass", "warn"), c


def test_detected_windows_match_truth(noisy):
    w = detect_calibration_windows(noisy.acc, noisy.gyr, sampling_rate_hz=FS)
    assert w.source == "auto"
    tw = noisy.windows
    assert w.standing[0] <= tw.standing[0] + 50 and w.standing[1] >= tw.standing[1] - 50
    for side in ("left", "right"):
        assert abs(w.hip_fe[side][0] - tw.hip_fe[side][0]) < 100 and abs(w.hip_fe[side][1] - tw.hip_fe[side][1]) < 100
    assert abs(w.walking[0] - tw.walking[0]) < 80 and abs(w.walking[1] - tw.walking[1]) < 80


def test_counts_repetitions_and_steps(noisy):
    cal = calibrate_session(noisy.acc, noisy.gyr, sampling_rate_hz=FS)
    assert all(cal.imus[f"{s}_{side}"].n_cycles == 10 for s in ("thigh", "shank", "foot") for side in ("left", "right"))
    cal = calibrate_session(noisy.acc, noisy.gyr, sampling_rate_hz=FS, params=CalibrationParams(method="walking"))
    assert 8 <= cal.n_steps <= 10


def test_manual_windows_override(noisy, mounts):
    w = CalibrationWindows.from_seconds(sampling_rate_hz=FS, standing=(0.5, 3.5), walking=(47.6, 53.0))
    cal = calibrate_session(noisy.acc, noisy.gyr, sampling_rate_hz=FS, windows=w)
    assert cal.windows.source == "manual" and cal.windows.standing == (50, 350)
    assert all(c.method == "walking" for p, c in cal.imus.items() if p != "pelvis")


def test_mounting_permutation_is_folded_in(clean, mounts):
    P = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], float)          # native -> S, det +1
    acc = {p: a @ P for p, a in clean.acc.items()}                    # native = P^T S
    gyr = {p: g @ P for p, g in clean.gyr.items()}
    cal = calibrate_session(acc, gyr, sampling_rate_hz=FS, mounts={p: P for p in acc})
    for p, c in cal.imus.items():
        if p != "pelvis":
            assert helical_angle_deg(P.T @ mounts[p], c.R_sensor_af) < 0.1


def test_hip_fe_flexion_is_positive_about_z_on_both_legs_ucal6(clean):
    cal = calibrate_session(clean.acc, clean.gyr, sampling_rate_hz=FS, params=CalibrationParams(method="hip_fe"))
    for side in ("left", "right"):
        a, b = clean.windows.hip_fe[side]
        w_af = clean.gyr[f"thigh_{side}"][a:b] @ cal.imus[f"thigh_{side}"].R_sensor_af
        flex = np.diff(clean.angles_deg[f"hip_{side}"][a:b, 0]) * FS
        assert np.corrcoef(w_af[1:, 2], np.radians(flex))[0, 1] > 0.99


# ---- bad input: clear QC statuses -----------------------------------------------------------------

def test_missing_trial():
    cal = calibrate_session(None, None, sampling_rate_hz=FS)
    assert cal.status == "fail" and "missing" in cal.reasons[0]
    assert all(not c.valid and c.status == "fail" for c in cal.imus.values())


def test_too_short_trial(noisy):
    cut = {p: a[:150] for p, a in noisy.acc.items()}
    cal = calibrate_session(cut, {p: g[:150] for p, g in noisy.gyr.items()}, sampling_rate_hz=FS)
    assert cal.status == "fail" and "too short" in cal.reasons[0]


def test_no_standing(noisy):
    a0 = noisy.windows.hip_fe["right"][0] + 100
    cal = calibrate_session({p: a[a0:] for p, a in noisy.acc.items()}, {p: g[a0:] for p, g in noisy.gyr.items()},
                            sampling_rate_hz=FS, params=CalibrationParams(min_standing_s=3.0))
    # the pauses between movements are shorter than 3 s: no usable standing
    assert cal.status == "fail" and "no quiet standing" in cal.reasons[0]


def test_fewer_repetitions_fail(mounts):
    tr = calibration_trial(mounts=mounts, rng=np.random.default_rng(14), fe_reps=6)
    cal = calibrate_session(tr.acc, tr.gyr, sampling_rate_hz=FS, params=CalibrationParams(method="hip_fe"))
    assert cal.status == "fail"
    assert any("6 hip flexion/extension repetitions < 10" in r for r in cal.imus["thigh_left"].reasons)


def test_fewer_steps_fail(mounts):
    tr = calibration_trial(mounts=mounts, rng=np.random.default_rng(15), fe_reps=0, walking_steps=4)
    cal = calibrate_session(tr.acc, tr.gyr, sampling_rate_hz=FS)
    assert cal.status == "fail" and cal.n_steps < 8
    assert any("straight-walking steps < 8" in r for r in cal.imus["shank_right"].reasons)


def test_planarity_below_minimum_fails(noisy):
    cal = calibrate_session(noisy.acc, noisy.gyr, sampling_rate_hz=FS, params=CalibrationParams(min_planarity=0.999))
    assert cal.status == "fail" and any("explained variance" in r for c in cal.imus.values() for r in c.reasons)


def _swap(tr, a, b):
    acc, gyr = dict(tr.acc), dict(tr.gyr)
    acc[a], acc[b], gyr[a], gyr[b] = tr.acc[b], tr.acc[a], tr.gyr[b], tr.gyr[a]
    return acc, gyr


def test_left_right_swapped_is_detected(noisy):
    acc, gyr = _swap(noisy, "shank_left", "shank_right")
    cal = calibrate_session(acc, gyr, sampling_rate_hz=FS)
    assert cal.status == "fail"
    for p in ("shank_left", "shank_right"):
        assert cal.imus[p].status == "fail" and any("placed on the" in r or "swapped" in r for r in cal.imus[p].reasons)
    assert cal.imus["thigh_left"].status != "fail"


def test_left_right_swap_detected_from_walking_only(mounts):
    tr = calibration_trial(mounts=mounts, rng=np.random.default_rng(16), fe_reps=0, walking_steps=10)
    acc, gyr = _swap(tr, "foot_left", "foot_right")
    cal = calibrate_session(acc, gyr, sampling_rate_hz=FS)
    assert {p for p, c in cal.imus.items() if c.status == "fail"} >= {"foot_left", "foot_right"}
    assert any("swapped" in r for r in cal.reasons)


def test_sensor_on_wrong_segment_is_detected(mounts):
    tr = calibration_trial(mounts=mounts, rng=np.random.default_rng(17), fe_reps=0, walking_steps=10)
    acc, gyr = _swap(tr, "thigh_right", "shank_right")
    cal = calibrate_session(acc, gyr, sampling_rate_hz=FS)
    assert cal.imus["thigh_right"].status == "fail"
    assert any("thigh and shank sensors swapped" in r for r in cal.imus["thigh_right"].reasons)
    acc, gyr = _swap(tr, "pelvis", "thigh_left")
    cal = calibrate_session(acc, gyr, sampling_rate_hz=FS)
    assert cal.imus["pelvis"].status == "fail"


def test_pelvis_sway_fallback_without_orientations(mounts):
    tr = calibration_trial(mounts=mounts, rng=np.random.default_rng(18), fe_reps=0, walking_steps=20)
    cal = calibrate_session(tr.acc, tr.gyr, sampling_rate_hz=FS)
    assert cal.imus["pelvis"].method == "pelvis_sway"
    assert helical_angle_deg(mounts["pelvis"], cal.imus["pelvis"].R_sensor_af) < 10


def test_params_validate():
    with pytest.raises(ValueError, match="method"):
        CalibrationParams(method="sitting")
