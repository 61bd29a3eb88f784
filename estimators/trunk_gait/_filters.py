"""Butterworth designs cached by (order, cut-off, type, rate): a day has hundreds of gait sequences."""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.signal import butter


@lru_cache(maxsize=64)
def _sos(order: int, wn: tuple[float, ...], btype: str, fs_hz: float) -> np.ndarray:
    sos = butter(order, wn if len(wn) > 1 else wn[0], btype, fs=fs_hz, output="sos")
    sos.setflags(write=False)
    return sos


def butter_sos(order: int, wn, btype: str, fs_hz: float) -> np.ndarray:
    """Second-order sections of a Butterworth filter (cut-offs in Hz), designed once per argument set."""
    wn_t = tuple(float(x) for x in np.atleast_1d(wn))
    return _sos(int(order), wn_t, btype, float(fs_hz)).copy()       # scipy's sosfilt wants a writable array
