"""estimators/activity/_resample.py returns exactly what scipy.signal.resample_poly(x, up, down, axis=0) returns
(values bit for bit, shape and memory layout), for the window model's 100 -> 26 Hz and 52 -> 26 Hz, other
ratios, lengths around the filter's and the block of four outputs' edges, and a real chest recording."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from stridelab.estimators.activity._resample import resample_poly_axis0
from tests.conftest import shared_data

RATIOS = [(13, 50), (1, 2), (2, 1), (3, 7), (26, 100)]


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.shape == b.shape and a.strides == b.strides and a.dtype == b.dtype
    assert a.tobytes() == b.tobytes()                 # bit for bit (NaN payloads and the sign of zero included)


@pytest.mark.parametrize("up,down", RATIOS)
def test_identical_to_scipy_on_random_data(up, down):
    rng = np.random.default_rng(up * 100 + down)
    for n in (1, 2, 7, 76, 77, 78, 500, 1000, 1001, 1003, 4097):
        for scale in (1e-3, 1.0, 9.81e3):
            x = rng.normal(0.0, scale, (n, 3)) + scale
            _same(signal.resample_poly(x, up, down, axis=0), resample_poly_axis0(x, up, down))
        x = rng.normal(0.0, 1.0, (n, 2))              # not three columns: the one-output-at-a-time loop only
        _same(signal.resample_poly(x, up, down, axis=0), resample_poly_axis0(x, up, down))


def test_zeros_and_signed_zeros_as_scipy():
    x = np.zeros((300, 3))
    x[::7, 1] = -0.0
    _same(signal.resample_poly(x, 13, 50, axis=0), resample_poly_axis0(x, 13, 50))


@pytest.mark.realdata
def test_identical_to_scipy_on_a_real_chest_recording():
    from stridelab.pipeline.formats.uci_chest import load_uci_participant
    p = load_uci_participant(shared_data("uci_chest") / "1.csv")
    x = p.acc[:300_000] / 9.80665
    for up, down in ((1, 2), (13, 50)):
        _same(signal.resample_poly(x, up, down, axis=0), resample_poly_axis0(x, up, down))
