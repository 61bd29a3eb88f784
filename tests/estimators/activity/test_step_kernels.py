"""The step detector's kernels (estimators/activity/_kernels.py) give exactly what the NumPy/SciPy expressions they
replace give: the adaptive threshold bit for bit, and the same peaks as ``find_peaks(..., prominence=...)``."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.ndimage import uniform_filter1d

from stridelab.estimators.activity import PRESETS
from stridelab.estimators.activity import _detect as D
from stridelab.estimators.activity._kernels import prominent_peaks, step_threshold_kernel
from tests.conftest import shared_data

FS = 100.0
P = PRESETS["default"]


def _reference_threshold(x: np.ndarray, w: int, floor: float, rel: float) -> np.ndarray:
    rms = np.sqrt(np.maximum(uniform_filter1d(x * x, w, mode="nearest"), 0.0))
    return np.maximum(floor, rel * np.sqrt(2.0) * rms)


def _reference_steps(x: np.ndarray) -> np.ndarray:
    w = max(3, int(round(P.step_rms_window_s * FS)))
    h = _reference_threshold(x, w, P.step_threshold_g, P.step_relative)
    pk, _ = signal.find_peaks(x, height=h, distance=max(1, int(P.step_min_interval_s * FS)),
                              prominence=0.5 * P.step_threshold_g)
    return pk


def _gait_like(n: int, rng, rounding: bool) -> np.ndarray:
    t = np.arange(n) / FS
    walking = np.sin(2 * np.pi * t / rng.uniform(20, 300)) > 0
    x = 0.3 * np.sin(2 * np.pi * 1.8 * t) * walking + rng.normal(0, rng.choice([0.005, 0.05]), n)
    x = signal.sosfilt(signal.butter(2, [0.5, 3.0], "bandpass", fs=FS, output="sos"), x)
    return np.round(x, 3) if rounding else x                 # rounding: plateaus and ties


@pytest.mark.parametrize("w", [1, 2, 3, 250, 251, 5000])
def test_threshold_is_the_scipy_expression_bit_for_bit(w):
    rng = np.random.default_rng(w)
    for n in (1, 2, 3, 10, 4999, 20_000):
        x = rng.normal(0, 0.2, n)
        got = step_threshold_kernel(x, w, 0.04, 0.6 * np.sqrt(2.0))
        assert got.tobytes() == _reference_threshold(x, w, 0.04, 0.6).tobytes()


def test_prominence_selection_is_scipys():
    rng = np.random.default_rng(7)
    for _ in range(40):
        x = np.round(rng.normal(0, 1, int(rng.integers(3, 3000))).cumsum(), int(rng.integers(0, 3)))
        pk, _ = signal.find_peaks(x)
        prom = signal.peak_prominences(x, pk)[0] if pk.size else np.zeros(0)
        for pmin in (0.0, 0.5, 1.0, 3.0, float(np.median(prom)) if prom.size else 1.0):
            assert np.array_equal(prominent_peaks(x, pk.astype(np.int64), pmin), pmin <= prom)


def test_detected_steps_are_find_peaks_with_prominence():
    rng = np.random.default_rng(3)
    for k in range(12):
        x = _gait_like(int(rng.integers(100, 200_000)), rng, rounding=k % 3 == 0)
        assert np.array_equal(D.detect_steps(x, FS, P), _reference_steps(x))


@pytest.mark.realdata
def test_detected_steps_on_a_real_chest_recording():
    from stridelab.estimators.activity import gravitational_component
    from stridelab.pipeline.formats.uci_chest import load_uci_participant
    rec = load_uci_participant(shared_data("uci_chest") / "1.csv")
    fs = rec.sampling_rate_hz
    acc_g = rec.acc[:150_000] / 9.80665
    ga = np.ascontiguousarray(gravitational_component(acc_g, fs))
    x = D.step_signal(acc_g, ga, fs, P)
    w = max(3, int(round(P.step_rms_window_s * fs)))
    h = _reference_threshold(x, w, P.step_threshold_g, P.step_relative)
    ref, _ = signal.find_peaks(x, height=h, distance=max(1, int(P.step_min_interval_s * fs)),
                               prominence=0.5 * P.step_threshold_g)
    assert ref.size > 100 and np.array_equal(D.detect_steps(x, fs, P), ref)
