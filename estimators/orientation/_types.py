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
    """
    quat: np.ndarray
    gain: np.ndarray
    still: np.ndarray
    mag_used: bool
    params: object
