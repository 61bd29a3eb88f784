"""Sensor-to-segment calibration (Nazarahari 2021 ch. 3; spec/thesis_calib_gait_posture.md §2, 7.A).

Quiet standing gives the vertical axis (Eq. 14), ≥ 10 hip flexion/extension repetitions or ≥ 8
straight steps give the medio-lateral axis by PCA of the angular velocity (Eq. 15); the pelvis uses
the spec 7.A7 proposal. Windows are detected automatically or given (study manifest), and every IMU
gets quality indicators and a pass / warn / fail status.

    from stridelab.estimators.calibration import calibrate_session
    cal = calibrate_session(acc, gyr, sampling_rate_hz=100.0)     # dicts placement -> (N, 3)
    q_thigh_af = cal.segment_quat("thigh_left", q_thigh_sensor)

The names below load their submodule on first use (PEP 562): the pipeline's coordinator reads
``CalibrationParams`` for a stage's default parameters without importing the estimators and SciPy's
signal package behind them (0.7-0.9 s, with both workers waiting for the next stage level).
"""
import importlib

_SUBMODULE = {
    **dict.fromkeys(("CalibrationError", "calibrate_imu", "heading_calibration", "pelvis_from_sway",
                     "pelvis_from_thighs", "vertical_calibration"), "_s2s"),
    **dict.fromkeys(("calibrate_session", "missing_calibration", "motion_plausibility"), "_session"),
    **dict.fromkeys(("LEG_PLACEMENTS", "PRESETS", "CalibrationParams", "CalibrationWindows", "ImuCalibration",
                     "SessionCalibration"), "_types"),
    **dict.fromkeys(("count_cycles", "count_repetitions", "detect_calibration_windows", "first_quiet_standing"),
                    "_windows"),
    **dict.fromkeys(("body_rate_from_quat", "constant_offset_rotation", "imu_to_cluster_rotation",
                     "sync_by_angular_rate"), "alignment"),
    "helical_angle_deg": "evaluation",
}

__all__ = list(_SUBMODULE)


def __getattr__(name: str):
    where = _SUBMODULE.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{where}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
