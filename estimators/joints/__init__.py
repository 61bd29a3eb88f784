"""Clinical joint angles: anatomical frames, JCS (Grood & Suntay / ISB) angles with a left/right sign
table (docs/joint_angles.md), quiet-standing offset removal and gait-cycle normalised curves.

    from stridelab.estimators.joints import compute_joint_angles, session_gait_curves
    ja = compute_joint_angles(quats, session_calibration, standing=(0, 300))
    curves = session_gait_curves(ja, {"left": ic_left, "right": ic_right}, sampling_rate_hz=100.0)
"""
from stridelab.estimators.joints._cycles import N_POINTS, CycleCurves, normalise_cycles, pool_cycles, session_gait_curves
from stridelab.estimators.joints._jcs import (ANGLE_NAMES, JOINTS, SIGN_RIGHT, JointAngles, clinical_to_matrix,
                                    compute_joint_angles, joint_angles_deg, remove_standing_offset,
                                    segment_orientations, sign_table, zxy_angles_deg, zxy_matrix)
from stridelab.estimators.joints._online import calibrated_joint_angles_deg
from stridelab.estimators.joints.evaluation import AngleError, angle_errors

__all__ = ["ANGLE_NAMES", "JOINTS", "SIGN_RIGHT", "JointAngles", "clinical_to_matrix", "compute_joint_angles",
           "joint_angles_deg", "remove_standing_offset", "segment_orientations", "sign_table", "zxy_angles_deg",
           "zxy_matrix", "N_POINTS", "CycleCurves", "normalise_cycles", "pool_cycles", "session_gait_curves", "AngleError",
           "angle_errors", "calibrated_joint_angles_deg"]
