"""Orientation estimators: arrays in, :class:`OrientationResult` out (sensor→ENU, [w x y z]).

``ESTIMATORS`` maps a name to ``f(gyr, acc, mag, *, sampling_rate_hz) -> OrientationResult`` with
default parameters; the pipeline's orientation stage picks one by name (study manifest
``[stages.orientation] estimator = ...``).
"""
from __future__ import annotations

from estimators.orientation._fqa import fqa
from estimators.orientation._frames import Q_ENU_NED, enu_to_ned, ned_to_enu
from estimators.orientation._stillness import detect_rest
from estimators.orientation._types import OrientationResult
from estimators.orientation._vqf_adapter import vqf_orientation
from estimators.orientation._yun_cf import YunCFParams, yun_cf

ESTIMATORS = {
    "yun_cf": lambda gyr, acc, mag=None, *, sampling_rate_hz: yun_cf(gyr, acc, mag, sampling_rate_hz=sampling_rate_hz),
    "vqf": lambda gyr, acc, mag=None, *, sampling_rate_hz: vqf_orientation(gyr, acc, mag,
                                                                            sampling_rate_hz=sampling_rate_hz),
    "vqf_offline": lambda gyr, acc, mag=None, *, sampling_rate_hz: vqf_orientation(
        gyr, acc, mag, sampling_rate_hz=sampling_rate_hz, offline=True),
}
#: the most accurate online / batch estimator of this package (see docs and `stridelab bench orientation`)
DEFAULT_ONLINE = "yun_cf"
DEFAULT_OFFLINE = "yun_cf"

__all__ = ["ESTIMATORS", "DEFAULT_ONLINE", "DEFAULT_OFFLINE", "OrientationResult", "YunCFParams", "yun_cf", "fqa",
           "vqf_orientation", "detect_rest", "Q_ENU_NED", "ned_to_enu", "enu_to_ned"]
