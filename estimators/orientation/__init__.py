"""Orientation estimators: arrays in, :class:`OrientationResult` out (sensor→ENU, [w x y z]).

``ESTIMATORS`` maps a name to ``f(gyr, acc, mag, *, sampling_rate_hz) -> OrientationResult`` with
default parameters; the pipeline's orientation stage picks one by name (study manifest
``[stages.orientation] estimator = ...``). Accuracy and speed of each: docs/orientation.md,
``stridelab bench orientation``.
"""
from __future__ import annotations

from stridelab.estimators.orientation._dcf import (DCFFilter, DCFOfflineParams, DCFParams, dcf, dcf_offline,
                                        dcf_offline_from_online)
from stridelab.estimators.orientation._fqa import fqa
from stridelab.estimators.orientation._frames import Q_ENU_NED, enu_to_ned, ned_to_enu
from stridelab.estimators.orientation._fullstate import (FullStateLKFFilter, FullStateLKFParams, FullStateResult,
                                               RobustEKFFilter, RobustEKFParams, full_state_lkf,
                                               full_state_lkf_literal, robust_ekf)
from stridelab.estimators.orientation._madgwick_mahony import (MADGWICK_BROAD_VST2, MAHONY_BROAD_VST2, MadgwickFilter,
                                                     MadgwickParams, MahonyFilter, MahonyParams, madgwick,
                                                     madgwick_tuned, mahony, mahony_tuned)
from stridelab.estimators.orientation._stillness import detect_rest
from stridelab.estimators.orientation._types import OrientationResult
from stridelab.estimators.orientation._vqf_adapter import vqf_orientation
from stridelab.estimators.orientation._yun_cf import YunCFFilter, YunCFParams, yun_cf


def _vqf_offline(gyr, acc, mag=None, *, sampling_rate_hz):
    return vqf_orientation(gyr, acc, mag, sampling_rate_hz=sampling_rate_hz, offline=True)


#: name -> estimator with default parameters, ``f(gyr, acc, mag, *, sampling_rate_hz)``
ESTIMATORS = {
    "dcf": dcf,
    "dcf_offline": dcf_offline,
    "madgwick": madgwick,
    "mahony": mahony,
    "madgwick_tuned": madgwick_tuned,
    "mahony_tuned": mahony_tuned,
    "yun_cf": yun_cf,
    "robust_ekf": robust_ekf,
    "full_state_lkf": full_state_lkf,
    "vqf": vqf_orientation,
    "vqf_offline": _vqf_offline,
}
#: estimators kept for replication only, not for use: the thesis' LKF exactly as printed (spec §8 A1/A2:
#: its gyro bias never updates and its measurement lags one sample, so it fails the convention tests of the
#: family suite); ``stridelab bench orientation`` scores them beside ``ESTIMATORS``
REPLICATION = {"full_state_lkf_literal": full_state_lkf_literal}
#: the most accurate online (causal) / batch estimator of this package (docs/orientation.md)
DEFAULT_ONLINE = "dcf"
DEFAULT_OFFLINE = "dcf_offline"

__all__ = ["ESTIMATORS", "REPLICATION", "DEFAULT_ONLINE", "DEFAULT_OFFLINE", "OrientationResult",
           "DCFParams", "DCFOfflineParams", "DCFFilter", "dcf", "dcf_offline", "dcf_offline_from_online",
           "MadgwickParams", "MahonyParams", "MadgwickFilter", "MahonyFilter", "madgwick", "mahony",
           "madgwick_tuned", "mahony_tuned", "MADGWICK_BROAD_VST2", "MAHONY_BROAD_VST2",
           "RobustEKFParams", "RobustEKFFilter", "robust_ekf", "FullStateLKFParams", "FullStateLKFFilter",
           "FullStateResult", "full_state_lkf", "full_state_lkf_literal",
           "YunCFParams", "YunCFFilter", "yun_cf", "fqa", "detect_rest", "vqf_orientation",
           "Q_ENU_NED", "ned_to_enu", "enu_to_ned"]
