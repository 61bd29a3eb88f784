"""Foot trajectories: ESKF + ZUPT + RTS (default for batch use) and the Duong & Suh distance-sensor filters.

Arrays in (gyr rad/s, acc m/s² specific force, sample rate keyword), frozen dataclasses out; world frame z up.
"""
from __future__ import annotations

from estimators.trajectory._api import (EskfParams, TrajectoryResult, ZuptParams, check_foot_imu, detect_zupt,
                                        eskf_trajectory)

__all__ = ["EskfParams", "TrajectoryResult", "ZuptParams", "check_foot_imu", "detect_zupt", "eskf_trajectory"]
