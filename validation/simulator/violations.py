"""Scenarios that break the methods' assumptions on purpose (issue 16 point 7), for ``stridelab bench violations``.

Each field moves the simulated lab session one step beyond what a method assumes; the default (all off) is the
ordinary simulated session. What each one breaks:

* ``standing_knee_deg``: quiet standing with the knees flexed by this much (thigh and shank each about half of it
  off vertical). The thesis calibration takes the segment long axis as vertical in quiet standing (Eq. 14).
* ``hip_axis_tilt_deg``: every hip flexion/extension repetition swings about an axis turned about the vertical by
  this much (flexion mixed with ab/adduction). Calibration takes the principal axis of the swing as the
  medio-lateral axis (Eq. 15).
* ``sta_deg_per_knee_deg``: soft-tissue artefact: thigh and shank sensors rotate about the segment long axis by this
  many degrees per degree of knee flexion (skin and muscle move the strap; thigh artefacts reach several degrees of
  axial rotation at large knee flexion, Leardini et al. 2005, Gait Posture 21:212). All methods take the sensor as
  rigidly fixed to the bone.
* ``strap_slip_deg``: after the calibration trial every thigh and shank strap has turned by this much about the
  segment long axis (slipped between trials). Joint angles apply the calibration of the calibration trial.
* ``heel_strike_g``: an impact transient at every initial contact on the foot sensors (shank: half of it),
  peak in g along the segment long axis, 30 Hz damped with τ = 15 ms. Stance detection and the ZUPT take
  the foot as quiet in early stance.
* ``gyro_range_dps``: gyroscope full scale (readings clipped at ± this): swing of the foot exceeds ±250 dps, the
  integration assumes the gyroscope measures the whole rotation.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Violations:
    standing_knee_deg: float | None = None
    hip_axis_tilt_deg: float = 0.0
    sta_deg_per_knee_deg: float = 0.0
    strap_slip_deg: float = 0.0
    heel_strike_g: float = 0.0
    gyro_range_dps: float | None = None

    @property
    def any(self) -> bool:
        return self != Violations()


#: the scenarios of the bench: name -> (Violations, what it breaks)
SCENARIOS: dict[str, tuple[Violations, str]] = {
    "baseline": (Violations(), "ordinary simulated session"),
    "non_upright_standing": (Violations(standing_knee_deg=15.0), "quiet standing with 15° knee flexion"),
    "tilted_hip_axis": (Violations(hip_axis_tilt_deg=15.0), "hip FE about an axis turned 15° about the vertical"),
    "soft_tissue_artefact": (Violations(sta_deg_per_knee_deg=0.1),
                             "thigh/shank sensors rotate 0.1°/° of knee flexion about the long axis"),
    "strap_slip": (Violations(strap_slip_deg=10.0), "thigh/shank straps turned 10° after the calibration trial"),
    "heel_strike_impacts": (Violations(heel_strike_g=6.0), "6 g (foot) / 3 g (shank) impact transient at each IC"),
    "gyro_saturation": (Violations(gyro_range_dps=250.0), "gyroscope full scale ±250 dps"),
}
