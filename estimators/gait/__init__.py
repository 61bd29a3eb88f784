"""Foot gait analysis: stance/swing, initial/terminal contacts, strides, per-session parameters.

Arrays in (gyr rad/s, acc m/s² specific force, ``sampling_rate_hz`` keyword), frozen dataclasses out, events
and strides as sample indices. See docs/gait.md for conventions and measured accuracy.
"""
from __future__ import annotations

from stridelab.estimators.gait._events import (GaitEventDetector, GaitEvents, IcTcParams, detect_ic_tc, pitch_signal,
                                     refine_heel_strike, refine_toe_off)
from stridelab.estimators.gait._kinematics import (PARAM_COLUMNS, STRIDE_COLUMNS, FootKinematics, FootParams, SessionGait,
                                         StrideTable, foot_kinematics, foot_params_from_dict, foot_trajectory,
                                         gait_session,
                                         gait_session_pooled, mid_stances, refine_events)

__all__ = ["GaitEventDetector", "GaitEvents", "IcTcParams", "detect_ic_tc", "pitch_signal", "refine_toe_off",
           "refine_heel_strike",
           "FootKinematics",
           "FootParams", "SessionGait", "StrideTable", "foot_kinematics", "foot_trajectory", "gait_session",
           "gait_session_pooled",
           "foot_params_from_dict", "refine_events", "PARAM_COLUMNS",
           "STRIDE_COLUMNS", "mid_stances"]
