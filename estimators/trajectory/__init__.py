"""Foot trajectories: ESKF + ZUPT + RTS (default for batch use) and the Duong & Suh distance-sensor filters.

Arrays in (gyr rad/s, acc m/s² specific force, sample rate keyword), frozen dataclasses out; world frame z up.
"""
from __future__ import annotations

from stridelab.estimators.trajectory._api import (TRAJECTORY_ZUPT, EskfParams, TrajectoryResult, ZuptParams, check_foot_imu, detect_zupt,
                                        eskf_trajectory, gait_cycle_period, rest_gyro_bias, sensor_gravity,
                                        stance_gyro_bias)
from stridelab.estimators.trajectory._duong_suh import (EQ24_GEOMETRY, TABLE1_GEOMETRY, DuongSuhParams, DuongSuhResult,
                                              UNKNOWN_GEOMETRY_CALIB_VAR, RangeGeometry,
                                              duong_suh_params_from_dict, duong_suh_trajectory,
                                              geometry_from_stance)

__all__ = ["EskfParams", "TRAJECTORY_ZUPT", "TrajectoryResult", "ZuptParams", "check_foot_imu", "detect_zupt", "sensor_gravity",
           "eskf_trajectory", "gait_cycle_period", "stance_gyro_bias", "rest_gyro_bias",
           "DuongSuhParams", "DuongSuhResult", "RangeGeometry", "duong_suh_trajectory", "TABLE1_GEOMETRY",
           "EQ24_GEOMETRY", "geometry_from_stance", "duong_suh_params_from_dict",
           "UNKNOWN_GEOMETRY_CALIB_VAR"]
