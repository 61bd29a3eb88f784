"""Daily activity from one chest accelerometer: postures, postural transitions, walking modality, steps,
non-wear, daily summaries (Nazarahari 2021 ch. 7; spec/thesis_calib_gait_posture.md §4).

Arrays in (acc m/s², ``sampling_rate_hz`` keyword), frozen dataclasses out. See docs/activity.md.
"""
from __future__ import annotations

from stridelab.estimators.activity._daily import daily_summaries, local_midnights_ns
from stridelab.estimators.activity._signals import (autocalibrate, chest_height_change_m, cumulative_svm_sign, ga_dc_gain,
                                          ga_filter_sos, gravitational_component, inclination_deg, svm_g,
                                          vertical_acc_g)
from stridelab.estimators.activity._timeline import classify_day
from stridelab.estimators.activity._types import (CLASSES, PRESETS, TRANSITIONS, WALKING_CLASSES, AccCalibration,
                                        ActivityParams, ActivityResult, Bouts, DailySummary, Transitions)

__all__ = ["classify_day", "daily_summaries", "local_midnights_ns", "ActivityParams", "ActivityResult",
           "AccCalibration", "Bouts", "Transitions", "DailySummary", "PRESETS", "CLASSES", "TRANSITIONS",
           "WALKING_CLASSES", "autocalibrate", "chest_height_change_m", "cumulative_svm_sign", "ga_dc_gain",
           "ga_filter_sos", "gravitational_component", "inclination_deg", "svm_g", "vertical_acc_g"]
