"""Orientation estimators: arrays in, :class:`OrientationResult` out (sensor→ENU, [w x y z]).

``ESTIMATORS`` maps a name to ``f(gyr, acc, mag, *, sampling_rate_hz) -> OrientationResult`` with
default parameters; the pipeline's orientation stage picks one by name (study manifest
``[stages.orientation] estimator = ...``). Accuracy and speed of each: docs/orientation.md,
``stridelab bench orientation``.
"""
from __future__ import annotations

from estimators.orientation._dcf import DCFFilter, DCFOfflineParams, DCFParams, dcf, dcf_offline
from estimators.orientation._fqa import fqa
from estimators.orientation._frames import Q_ENU_NED, enu_to_ned, ned_to_enu
from estimators.orientation._madgwick_mahony import MadgwickParams, MahonyParams, madgwick, mahony
from estimators.orientation._stillness import detect_rest
from estimators.orientation._types import OrientationResult
from estimators.orientation._vqf_adapter import vqf_orientation
from estimators.orientation._yun_cf import YunCFParams, yun_cf


def _vqf_offline(gyr, acc, mag=None, *, sampling_rate_hz):
    return vqf_orientation(gyr, acc, mag, sampling_rate_hz=sampling_rate_hz, offline=True)


#: name -> estimator with default parameters, ``f(gyr, acc, mag, *, sampling_rate_hz)``
ESTIMATORS = {
    "dcf": dcf,
    "dcf_offline": dcf_offline,
    "madgwick": madgwick,
    "mahony": mahony,
    "yun_cf": yun_cf,
    "vqf": vqf_orientation,
    "vqf_offline": _vqf_offline,
}
#: the most accurate online (causal) / batch estimator of this package (docs/orientation.md)
DEFAULT_ONLINE = "dcf"
DEFAULT_OFFLINE = "dcf_offline"

__all__ = ["ESTIMATORS", "DEFAULT_ONLINE", "DEFAULT_OFFLINE", "OrientationResult",
           "DCFParams", "DCFOfflineParams", "DCFFilter", "dcf", "dcf_offline",
           "MadgwickParams", "MahonyParams", "madgwick", "mahony",
           "YunCFParams", "yun_cf", "fqa", "detect_rest", "vqf_orientation",
           "Q_ENU_NED", "ned_to_enu", "enu_to_ned"]
