"""estimators/activity/_sosfilt.py returns exactly what scipy.signal.sosfilt / sosfiltfilt return (values, shape
and memory layout, so later reductions sum in the same order), for the filters and array layouts the activity
stage passes, on random data and on a real chest recording."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from estimators.activity import _sosfilt as fast
from tests.conftest import shared_data

FS = 100.0
FILTERS = {
    "ga_ellip": signal.ellip(2, 0.01, 100.0, 0.25, fs=FS, output="sos"),
    "band": signal.butter(2, [0.3, 20.0], "bandpass", fs=FS, output="sos"),
    "low": signal.butter(2, 1.0, "lowpass", fs=FS, output="sos"),
    "high8": signal.butter(8, 5.0, "highpass", fs=FS, output="sos"),
}


def _layouts(x: np.ndarray):
    yield "C", np.ascontiguousarray(x)
    yield "F", np.asfortranarray(x)
    yield "reversed", np.ascontiguousarray(x)[::-1]
    yield "every other row", np.ascontiguousarray(x)[::2]


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.shape == b.shape and a.strides == b.strides and a.dtype == b.dtype
    np.testing.assert_array_equal(a, b, strict=True)
    assert a.tobytes() == b.tobytes()                 # bit for bit (assert_array_equal treats 0.0 == -0.0)


def _check(x: np.ndarray) -> None:
    for name, sos in FILTERS.items():
        for layout, v in _layouts(x):
            _same(signal.sosfiltfilt(sos, v, axis=0), fast.sosfiltfilt(sos, v))
            zi0 = signal.sosfilt_zi(sos)
            zi = zi0 * v[0] if v.ndim == 1 else zi0[:, :, None] * v[0][None, None, :]
            ya, za = signal.sosfilt(sos, v, axis=0, zi=zi)
            yb, zb = fast.sosfilt(sos, v, zi=zi)
            _same(ya, yb)
            np.testing.assert_array_equal(za, zb, strict=True)
            yc, zc = fast.sosfilt(sos, v, zi=zi, order="C")     # C-ordered output: the same values
            if v.ndim == 2:
                assert yc.flags.c_contiguous
            _same(np.ascontiguousarray(ya), yc)
            np.testing.assert_array_equal(za, zc, strict=True)
            _same(signal.sosfilt(sos, v, axis=0), fast.sosfilt(sos, v))


@pytest.mark.parametrize("shape", [(5000, 3), (5000,), (400, 2)])
def test_identical_to_scipy_on_random_data(shape):
    x = np.random.default_rng(len(shape)).normal(0.0, 1.0, shape) + 1.0
    _check(x)


@pytest.mark.realdata
def test_identical_to_scipy_on_a_real_chest_recording():
    from pipeline.formats.uci_chest import load_uci_participant
    p = load_uci_participant(shared_data("uci_chest") / "1.csv")
    _check(p.acc[:200_000] / 9.80665)
    _check(np.linalg.norm(p.acc[:200_000], axis=1))


def test_wrong_zi_shape_and_too_short_input_are_refused_as_scipy_does():
    short = np.ones((20, 3))
    with pytest.raises(ValueError, match="padlen"):
        signal.sosfiltfilt(FILTERS["high8"], short, axis=0)
    with pytest.raises(ValueError, match="padlen"):
        fast.sosfiltfilt(FILTERS["high8"], short)
    x = np.ones((100, 3))
    with pytest.raises(ValueError):
        signal.sosfilt(FILTERS["low"], x, axis=0, zi=np.zeros((1, 2)))
    with pytest.raises(ValueError):
        fast.sosfilt(FILTERS["low"], x, zi=np.zeros((1, 2)))
