"""Result type shared by the orientation estimators."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OrientationResult:
    """Output of an orientation estimator, one row per input sample.

    quat: (N, 4) [w x y z], rotates sensor-frame vectors into ENU (DESIGN.md conventions).
    gain: (N,) float, the correction gain in force at each sample (1/s; 0 = pure gyro integration).
    still: (N,) bool, samples the estimator treated as stance/rest.
    mag_used: whether a magnetometer informed the heading (False: 6D, heading from the gyro only).
    params: the parameters that produced it (hashed into the stage stamp).
    mag_sensor: (N, 3) the magnetometer after the estimator's own corrections (the dcf's hard-iron offset removed),
        sensor frame, µT; None where the estimator makes none.
    """
    quat: np.ndarray
    gain: np.ndarray
    still: np.ndarray
    mag_used: bool
    params: object
    mag_sensor: np.ndarray | None = None


class OnlineFilter:
    """Base of the online orientation filters. ``state`` is a plain float64 array of ``STATE_SIZE`` values
    (layout per filter) you can copy and restore; ``update_batch`` on consecutive chunks gives the result of
    one call on the whole recording (tested per filter)."""
    STATE_SIZE = 0

    def __init__(self, params, *, sampling_rate_hz: float):
        if not sampling_rate_hz or sampling_rate_hz <= 0:
            raise ValueError(f"sampling_rate_hz must be > 0, got {sampling_rate_hz}")
        self.params = params
        self.sampling_rate_hz = float(sampling_rate_hz)
        self._state = np.zeros(self.STATE_SIZE)

    @property
    def state(self) -> np.ndarray:
        return self._state.copy()

    @state.setter
    def state(self, value) -> None:
        value = np.array(value, dtype=np.float64)
        if value.shape != (self.STATE_SIZE,):
            raise ValueError(f"state must be a ({self.STATE_SIZE},) array, got {value.shape}")
        self._state = value

    @staticmethod
    def _chunk(gyr, acc, mag):
        """(gyr, acc, mag or None) of one chunk as contiguous (N, 3) float64; ValueError on unequal shapes."""
        gyr = np.ascontiguousarray(gyr, dtype=np.float64).reshape(-1, 3)
        acc = np.ascontiguousarray(acc, dtype=np.float64).reshape(-1, 3)
        if acc.shape != gyr.shape:
            raise ValueError(f"gyr {gyr.shape} and acc {acc.shape} must both be (N, 3)")
        if mag is not None:
            mag = np.ascontiguousarray(mag, dtype=np.float64).reshape(-1, 3)
            if mag.shape != gyr.shape:
                raise ValueError(f"mag {mag.shape} must be (N, 3) like gyr")
        return gyr, acc, mag
