"""butter_filtfilt is scipy.signal.sosfiltfilt with the design's initial state cached: equal to the bit."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from stridelab.estimators.trunk_gait._filters import butter_filtfilt


@pytest.mark.parametrize("design", [(4, 3.0, "lowpass", 100.0), (2, (0.5, 3.0), "bandpass", 25.0),
                                    (4, 0.1, "highpass", 100.0)])
@pytest.mark.parametrize("shape,axis", [((500,), -1), ((500, 3), 0), ((3, 500), -1)])
@pytest.mark.parametrize("padlen", [None, 18, 0, 300])
def test_butter_filtfilt_equals_sosfiltfilt(design, shape, axis, padlen):
    order, wn, btype, fs = design
    x = np.random.default_rng(1).normal(size=shape)
    expected = sosfiltfilt(butter(order, wn, btype, fs=fs, output="sos"), x, axis=axis, padlen=padlen)
    for _ in range(2):                                          # the second call uses the cached design
        assert np.array_equal(butter_filtfilt(order, wn, btype, fs, x, axis=axis, padlen=padlen), expected)


def test_butter_filtfilt_refuses_a_signal_not_longer_than_the_padding_as_scipy_does():
    with pytest.raises(ValueError, match="greater than padlen"):
        butter_filtfilt(2, 3.0, "lowpass", 100.0, np.zeros(10), padlen=10)
