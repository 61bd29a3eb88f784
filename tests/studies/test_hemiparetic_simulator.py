"""Hemiparetic foot-IMU simulator (validation/simulator/hemiparetic_gait.py, issue 18): independent of the
estimators, its own truth consistent with its signals, severities within their published ranges."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from stridelab.validation.simulator import hemiparetic_gait as H

SRC = Path(H.__file__)


def test_imports_nothing_from_estimators():
    tree = ast.parse(SRC.read_text())
    mods = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    mods += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert not [m for m in mods if m.split(".")[:2] in (["stridelab", "estimators"], ["stridelab", "pipeline"],
                                                       ["stridelab", "warehouse"])], mods


def test_deterministic_and_seeded():
    a = H.simulate_hemiparetic_trial("moderate", 3, strides=4)
    b = H.simulate_hemiparetic_trial("moderate", 3, strides=4)
    c = H.simulate_hemiparetic_trial("moderate", 4, strides=4)
    for side in a.feet:
        assert np.array_equal(a.feet[side].gyr, b.feet[side].gyr)
    assert a.params != c.params


@pytest.mark.parametrize("severity", list(H.SEVERITIES))
def test_truth_matches_signals_and_presets(severity):
    ideal = H.SensorSpec(acc_noise=0.0, gyr_noise=0.0, acc_bias=0.0, gyr_bias=0.0, scale=0.0)
    tr = H.simulate_hemiparetic_trial(severity, 1, strides=6, sensor=ideal)
    p, pre = tr.params, H.SEVERITIES[severity]
    assert pre.speed_m_s[0] <= p["speed_m_s"] <= pre.speed_m_s[1]
    assert pre.cadence_steps_min[0] <= p["cadence"] <= pre.cadence_steps_min[1]
    fs = tr.rate_hz
    for f in tr.feet.values():
        # quiet standing: specific force = g up, no rotation; the sensor sits on its first footprint
        still = slice(int(0.5 * fs), int(2.5 * fs))
        assert np.allclose(np.linalg.norm(f.acc[still], axis=1), H.G, atol=1e-6)
        assert np.abs(f.gyr[still]).max() < 1e-6
        assert np.allclose(f.sensor_pos[still], f.footprints[0], atol=1e-9)
        # every contact is in order TC < IC < next TC, and the sensor is back on footprint k+1 between strides
        assert np.all(f.tc_s < f.ic_s) and np.all(f.ic_s[:-1] < f.tc_s[1:])
        for k in range(len(f.ic_s) - 1):
            mid = int(round(0.5 * (f.ic_s[k] + f.tc_s[k + 1]) * fs))
            assert np.linalg.norm(f.sensor_pos[mid] - f.footprints[k + 1]) < 0.01
        # the trial ends standing on the last footprint
        assert np.linalg.norm(f.sensor_pos[-1] - f.footprints[-1]) < 1e-6
    par = tr.feet[tr.paretic_side]
    oth = [f for f in tr.feet.values() if not f.paretic][0]
    ratio = np.median(par.ic_s - par.tc_s) / np.median(oth.ic_s - oth.tc_s)
    assert pre.swing_ratio[0] * 0.85 <= ratio <= pre.swing_ratio[1] * 1.15
    expected = {"mild": "heel", "moderate": "flat", "severe": "forefoot"}[severity]
    assert par.contact[1:-1].count(expected) >= len(par.contact) - 3
    assert all(c == "heel" for c in oth.contact[1:-1])


def test_accelerometer_is_the_second_derivative_of_the_sensor_path():
    """Ideal sensor: the norm of the measured specific force equals |p̈ + g e_z| of the true sensor path
    (rotation-invariant, so the test needs no orientation)."""
    ideal = H.SensorSpec(acc_noise=0.0, gyr_noise=0.0, acc_bias=0.0, gyr_bias=0.0, scale=0.0)
    tr = H.simulate_hemiparetic_trial("severe", 2, strides=4, sensor=ideal)
    f = tr.feet[tr.paretic_side]
    dt = 1.0 / tr.rate_hz
    a = np.gradient(np.gradient(f.sensor_pos, dt, axis=0), dt, axis=0)
    ref = np.linalg.norm(a + np.array([0, 0, H.G]), axis=1)
    got = np.linalg.norm(f.acc, axis=1)
    inner = slice(5, -5)
    # 100 Hz finite differences of a path sampled from a 1 kHz model: agreement within 1 m/s² (impacts are 25 ms)
    assert np.median(np.abs(got[inner] - ref[inner])) < 0.05
    assert np.percentile(np.abs(got[inner] - ref[inner]), 99) < 1.0
