"""Sensor-to-segment calibration (Nazarahari 2021 ch. 3; spec/thesis_calib_gait_posture.md §2, 7.A).

Quiet standing gives the vertical axis (Eq. 14), ≥ 10 hip flexion/extension repetitions or ≥ 8
straight steps give the medio-lateral axis by PCA of the angular velocity (Eq. 15); the pelvis uses
the spec 7.A7 proposal. Windows are detected automatically or given (study manifest), and every IMU
gets quality indicators and a pass / warn / fail status.

    from estimators.calibration import calibrate_session
    cal = calibrate_session(acc, gyr, sampling_rate_hz=100.0)     # dicts placement -> (N, 3)
    q_thigh_af = cal.segment_quat("thigh_left", q_thigh_sensor)
"""
from estimators.calibration._s2s import (CalibrationError, calibrate_imu, heading_calibration, pelvis_from_sway,
                                         pelvis_from_thighs, vertical_calibration)
from estimators.calibration._session import calibrate_session, missing_calibration, motion_plausibility
from estimators.calibration._types import (LEG_PLACEMENTS, PRESETS, CalibrationParams, CalibrationWindows,
                                           ImuCalibration, SessionCalibration)
from estimators.calibration._windows import (count_cycles, count_repetitions, detect_calibration_windows,
                                             first_quiet_standing)
from estimators.calibration.alignment import (body_rate_from_quat, constant_offset_rotation,
                                              imu_to_cluster_rotation, sync_by_angular_rate)
from estimators.calibration.evaluation import helical_angle_deg

__all__ = ["CalibrationError", "calibrate_imu", "heading_calibration", "pelvis_from_sway", "pelvis_from_thighs",
           "vertical_calibration", "calibrate_session", "missing_calibration", "motion_plausibility",
           "LEG_PLACEMENTS", "PRESETS", "CalibrationParams", "CalibrationWindows", "ImuCalibration",
           "SessionCalibration", "count_cycles", "count_repetitions", "detect_calibration_windows", "first_quiet_standing", "body_rate_from_quat",
           "constant_offset_rotation", "imu_to_cluster_rotation", "sync_by_angular_rate", "helical_angle_deg"]
