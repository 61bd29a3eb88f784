"""Real-world gait from one trunk sensor (lower back L4/L5 or chest): gait sequences, initial contacts and their
side, cadence, stride length, walking speed, turns, walking bouts by the Mobilise-D consensus rules, and daily
outcomes. Arrays in (acc m/s², gyr rad/s, ``fs_hz``), frozen dataclasses out. Methods and references:
docs/trunk_gait.md; scorer: ``stridelab.estimators.trunk_gait.evaluation``.
"""
from __future__ import annotations

from stridelab.estimators.trunk_gait._daily import daily_outcomes
from stridelab.estimators.trunk_gait._pipeline import analyse_trunk_gait, detect_trunk_frame
from stridelab.estimators.trunk_gait._types import (DEFAULT_HEIGHT_M, DURATION_CLASSES_S, LEG_LENGTH_PER_HEIGHT, PLACEMENTS,
                                          Bouts, DailyOutcomes, Strides, TrunkFrame, TrunkGaitParams,
                                          TrunkGaitResult, Turns)

__all__ = ["analyse_trunk_gait", "detect_trunk_frame", "daily_outcomes", "TrunkGaitParams", "TrunkGaitResult",
           "TrunkFrame", "Bouts", "Strides", "Turns", "DailyOutcomes", "DEFAULT_HEIGHT_M", "LEG_LENGTH_PER_HEIGHT",
           "DURATION_CLASSES_S", "PLACEMENTS"]
