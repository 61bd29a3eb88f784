"""Calibration on the platform simulator's lab calibration trial (quiet standing, 10 hip FE repetitions
per leg, 8 straight steps): realistic standing, every step counted, QC statuses for healthy and
hemiparetic participants and for bad input (swapped sensors, too few repetitions), error vs repetitions."""
from dataclasses import replace

import numpy as np
import pytest

from stridelab.estimators.calibration import (CalibrationParams, CalibrationWindows, calibrate_session, count_cycles,
                                    helical_angle_deg)
from stridelab.estimators.quaternion import quat_to_matrix

pytestmark = pytest.mark.slow

FS = 100.0
LEGS = ("thigh_left", "thigh_right", "shank_left", "shank_right")


def _manifest(**lab):
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    m = load_manifest(DEFAULT_MANIFEST)
    return replace(m, lab=replace(m.lab, walking_trials=0, distance_sensors=False, optical_reference=False, **lab))


def _calibration_trial(m, index):
    from stridelab.validation.simulator import simulate_lab_session, study_participants
    person = study_participants(m, index + 1)[index]
    rec, truth = next(simulate_lab_session(m, person, index))
    acc = {p: d.acc for p, d in rec.imu.items()}
    gyr = {p: d.gyr for p, d in rec.imu.items()}
    r_true = {p: quat_to_matrix(np.asarray(q, float)).T for p, q in truth.mounting_quat.items()}
    return person, acc, gyr, truth, r_true


@pytest.fixture(scope="module")
def trials():
    """P001 (healthy) and P003 (hemiparetic, paretic left) with the default (noisy) sensor model."""
    m = _manifest()
    return {i: _calibration_trial(m, i) for i in (0, 2)}


def _window(truth, label):
    return [(a, b, s) for lab, a, b, s in truth.windows if lab == label]


def test_simulated_quiet_standing_sways(trials):
    """The simulated quiet standing is never perfectly still (postural sway). How upright it is, is the
    simulator's own draw, not pinned to the calibration's assumption (issue 16: the test that bounded the segment
    tilt by 1.6° is gone; bench violations scores calibration on standing with knee flexion)."""
    for person, acc, gyr, truth, _ in trials.values():
        (a, b, _), = _window(truth, "quiet_standing")
        sl = slice(int(a * FS) + 10, int(b * FS) - 10)
        for p in LEGS:
            w = np.linalg.norm(truth.gyr_true[p][sl], axis=1)
            assert 1e-4 < w.max() < 0.05, (person.id, p, w.max())                # postural sway, still quiet


def test_all_eight_steps_counted_and_qc_passes(trials):
    for person, acc, gyr, truth, _ in trials.values():
        cal = calibrate_session(acc, gyr, sampling_rate_hz=FS, params=CalibrationParams(method="walking"),
                                quats=truth.sensor_quat)
        (a, b, _), = _window(truth, "straight_walking")
        true_steps = sum(int(np.sum((truth.events[s]["IC"] >= a) & (truth.events[s]["IC"] <= b))) for s in truth.events)
        assert true_steps == 8
        assert cal.n_steps == true_steps, (person.id, cal.n_steps)
        bad = {p: c.reasons for p, c in cal.imus.items() if c.status == "fail"}
        assert not bad, (person.id, bad)                     # no "swapped" flag on the paretic leg either
        assert not cal.reasons, cal.reasons


def test_hip_fe_calibration_accuracy_and_repetitions(trials):
    for person, acc, gyr, truth, r_true in trials.values():
        cal = calibrate_session(acc, gyr, sampling_rate_hz=FS, quats=truth.sensor_quat)
        assert all(cal.imus[p].method == "hip_fe" and cal.imus[p].status != "fail" for p in LEGS), cal.as_dict()
        assert all(cal.imus[p].n_cycles == 10 for p in LEGS)
        err = [float(helical_angle_deg(r_true[p], cal.imus[p].R_sensor_af)) for p in LEGS]
        assert np.median(err) < 3.5, (person.id, err)


def _errors_with_k_reps(acc, gyr, truth, r_true, k, reps=10):
    (a, b, _), = _window(truth, "quiet_standing")
    fe = {s: (int(a0 * FS), int((a0 + k * (b0 - a0) / reps) * FS)) for a0, b0, s in _window(truth, "hip_flexion_extension")}
    w = CalibrationWindows(standing=(int(a * FS), int(b * FS)), hip_fe=fe, source="manual")
    cal = calibrate_session(acc, gyr, sampling_rate_hz=FS, windows=w, placements=LEGS,
                            params=CalibrationParams(method="hip_fe", min_fe_repetitions=1))
    return [float(helical_angle_deg(r_true[p], cal.imus[p].R_sensor_af)) for p in LEGS]


def test_error_falls_with_the_number_of_repetitions(trials):
    """Thesis ch. 3: few hip FE repetitions give a larger error than ten (the simulated repetitions
    differ independently in amplitude and swing plane, so the error of the mean axis falls with k)."""
    few, ten = [], []
    for person, acc, gyr, truth, r_true in trials.values():
        few += _errors_with_k_reps(acc, gyr, truth, r_true, 1) + _errors_with_k_reps(acc, gyr, truth, r_true, 2)
        ten += _errors_with_k_reps(acc, gyr, truth, r_true, 10)
    assert np.mean(few) > 1.3 * np.mean(ten), (np.mean(few), np.mean(ten))
    assert np.mean(ten) < 2.0


def _swap(d, a, b):
    d = dict(d)
    d[a], d[b] = d[b], d[a]
    return d


def test_bad_input_on_the_simulator_gives_clear_qc(trials):
    person, acc, gyr, truth, _ = trials[0]
    # left/right thighs swapped: each moves during the other leg's hip FE
    cal = calibrate_session(_swap(acc, "thigh_left", "thigh_right"), _swap(gyr, "thigh_left", "thigh_right"),
                            sampling_rate_hz=FS)
    for p in ("thigh_left", "thigh_right"):
        assert cal.imus[p].status == "fail" and any("placed on the" in r or "swapped" in r for r in cal.imus[p].reasons)
    # thigh and shank sensors exchanged on one leg, walking calibration
    cal = calibrate_session(_swap(acc, "thigh_right", "shank_right"), _swap(gyr, "thigh_right", "shank_right"),
                            sampling_rate_hz=FS, params=CalibrationParams(method="walking"))
    assert cal.imus["thigh_right"].status == "fail"
    assert any("thigh and shank sensors swapped" in r for r in cal.imus["thigh_right"].reasons)
    # trial cut before the straight walking and without its standing: no standing, clear status
    a0 = int(_window(truth, "hip_flexion_extension")[0][0] * FS) + 50
    cal = calibrate_session({p: v[a0:] for p, v in acc.items()}, {p: v[a0:] for p, v in gyr.items()},
                            sampling_rate_hz=FS, params=CalibrationParams(min_standing_s=2.0))
    assert cal.status == "fail" and "no quiet standing" in cal.reasons[0]


def test_fewer_repetitions_than_needed_on_the_simulator():
    person, acc, gyr, truth, _ = _calibration_trial(_manifest(hip_repetitions=6), 0)
    cal = calibrate_session(acc, gyr, sampling_rate_hz=FS, params=CalibrationParams(method="hip_fe"))
    assert cal.status == "fail"
    for p in LEGS:
        assert any("6 hip flexion/extension repetitions < 10" in r for r in cal.imus[p].reasons), cal.imus[p]


def test_count_cycles_keeps_the_closing_step_and_drops_stance_bumps():
    t = np.arange(0, 6.0, 1 / FS)
    w = np.zeros_like(t)

    def bump(t0, h, width=0.12):
        return h * np.exp(-0.5 * ((t - t0) / width) ** 2)

    swings = [0.5, 1.6, 2.7, 3.8]
    for i, t0 in enumerate(swings):
        w += bump(t0, 6.0 if i < 3 else 0.8)                     # the last swing: a short closing step
        w += bump(t0 + 0.55, 1.3, 0.15) if i < 3 else 0.0      # stance bump half a stride later
    g = np.column_stack([np.zeros_like(w), np.zeros_like(w), w])
    assert count_cycles(g, np.array([0.0, 0.0, 1.0]), sampling_rate_hz=FS) == len(swings)
