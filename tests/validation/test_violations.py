"""The assumption violations of the simulator do what they say (issue 16 point 7), and the bench scores them."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stridelab.validation.simulator import SCENARIOS, Violations, simulate_lab_session, study_participants
from stridelab.validation.simulator._rotations import quat_to_matrix


def _session(v):
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    m = load_manifest(DEFAULT_MANIFEST)
    m = replace(m, lab=replace(m.lab, walking_trials=1, distance_sensors=False, optical_reference=False))
    return list(simulate_lab_session(m, study_participants(m, 1)[0], 0, violations=v))


@pytest.fixture(scope="module")
def base():
    return _session(None)


@pytest.mark.slow
def test_gyro_saturation_and_strap_slip(base):
    sat = _session(SCENARIOS["gyro_saturation"][0])
    lim = np.deg2rad(250.0)
    assert np.abs(base[1][0].imu["foot_right"].gyr).max() > lim          # the foot swing exceeds the range
    assert np.abs(sat[1][0].imu["foot_right"].gyr).max() <= lim + 1e-12
    slip = _session(Violations(strap_slip_deg=10.0))
    for p in ("thigh_left", "shank_right"):
        q_cal, q_walk = slip[0][1].mounting_quat[p], slip[1][1].mounting_quat[p]
        R = quat_to_matrix(q_cal).T @ quat_to_matrix(q_walk)
        assert np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))) == pytest.approx(10.0, abs=1e-6)
        np.testing.assert_allclose(base[0][1].mounting_quat[p], q_cal)      # the calibration trial is unchanged
    np.testing.assert_allclose(slip[1][1].mounting_quat["foot_left"], base[1][1].mounting_quat["foot_left"])


@pytest.mark.slow
def test_non_upright_standing_tilts_the_legs_and_costs_calibration_accuracy(base):
    from stridelab.validation.bench.violations import lab_scenario
    knee = _session(SCENARIOS["non_upright_standing"][0])
    tilt = {}
    for name, s in (("base", base), ("knee", knee)):
        (_, a, b, _), = [w for w in s[0][1].windows if w[0] == "quiet_standing"]
        R = quat_to_matrix(s[0][1].segment_quat["shank_right"][int(a * 100) + 10:int(b * 100) - 10])
        tilt[name] = np.degrees(np.arccos(np.clip(R[:, 2, 1], -1, 1))).mean()
    assert tilt["knee"] > tilt["base"] + 3.0, tilt
    e0 = lab_scenario(Violations(), 1)["calibration_error_deg_median"]
    e1 = lab_scenario(SCENARIOS["non_upright_standing"][0], 1)["calibration_error_deg_median"]
    assert e1 > e0 + 1.0, (e0, e1)
