"""Body geometry and gait parameters of a simulated participant (healthy or hemiparetic).

All numbers are per-participant constants derived from the manifest's ``ParticipantSpec``; the
kinematic model (``_kinematics.py``) turns them into trajectories. Angles in radians unless the name
says ``_deg``. "Phase" fractions are of the stride time (right initial contact = 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stridelab.studies.manifest import ParticipantSpec


@dataclass(frozen=True)
class BodyGeometry:
    """Segment lengths and landmark offsets (m). Foot frame origin = ankle joint centre; heel, ball
    (toe-rocker pivot) and toe-tip points lie on the sole at ``-ankle_height_m`` along foot y."""
    thigh_m: float
    shank_m: float
    hip_width_m: float          # distance between the hip joint centres (pelvis origin = their midpoint)
    ankle_height_m: float       # ankle joint centre above the sole
    heel_x_m: float             # heel (heel-rocker pivot) along foot x (negative = posterior)
    ball_x_m: float             # ball of the foot (toe-rocker pivot) along foot x
    toe_tip_x_m: float          # toe tip along foot x
    trunk_m: float              # pelvis origin -> chest segment origin (sternum level) along trunk y
    chest_depth_m: float        # chest segment origin -> sternum surface along trunk x


@dataclass(frozen=True)
class SideGait:
    """Per-side gait parameters."""
    stance_frac: float          # stance duration / stride time
    theta_hs: float             # foot pitch at initial contact (toe up, rad)
    theta_to: float             # foot pitch at toe-off (toe down, negative, rad)
    clearance_m: float          # extra ankle lift in swing (bump amplitude)
    circumduction_m: float      # outward swing bump (hemiparetic)
    footprint_offset_m: float   # shifts this foot's footprints forward (+) / backward (-)
    toe_out: float              # foot heading outward from the walking direction (rad)


@dataclass(frozen=True)
class GaitParams:
    stride_s: float
    speed_m_s: float
    left_ic_phase: float        # left IC follows right IC by this fraction of the stride
    step_width_m: float
    load_frac: float            # heel-rocker (IC -> foot flat) duration / stride
    preswing_frac: float        # toe-rocker (heel off -> toe-off) duration / stride
    right: SideGait
    left: SideGait
    pelvis_vertical_m: float    # amplitude of the pelvis vertical oscillation (twice per stride)
    pelvis_drop_m: float        # mean pelvis lowering while walking
    pelvis_lateral_m: float     # amplitude of the lateral sway (once per stride)
    pelvis_rotation: float      # amplitude of the pelvis axial rotation (rad)
    pelvis_obliquity: float     # amplitude of the pelvis obliquity (rad)
    pelvis_tilt: float          # amplitude of the pelvis tilt oscillation (rad)
    hip_hike: float             # extra obliquity raising the paretic hip during its swing (rad)
    paretic_side: str | None
    trunk_lean: float           # forward trunk lean while walking (rad)

    def side(self, side: str) -> SideGait:
        return self.right if side == "right" else self.left

    def swing_s(self, side: str) -> float:
        return (1.0 - self.side(side).stance_frac) * self.stride_s


def body_geometry(p: ParticipantSpec) -> BodyGeometry:
    h = p.height_m
    foot = 0.152 * h
    return BodyGeometry(thigh_m=p.thigh_m, shank_m=p.shank_m, hip_width_m=0.10 * h,
                        ankle_height_m=0.042 * h, heel_x_m=-0.20 * foot, ball_x_m=0.78 * foot,
                        toe_tip_x_m=0.78 * foot, trunk_m=0.28 * h, chest_depth_m=0.06 * h)


def gait_params(p: ParticipantSpec) -> GaitParams:
    """Healthy: symmetric, stance 61 %, heel strike +20°, toe-off -35°. Hemiparetic (severity s):
    shorter paretic stance and longer non-paretic stance, longer paretic step time, shorter paretic
    step, reduced paretic heel strike / push-off / clearance (hence knee flexion), circumduction and
    hip hiking on the paretic side, wider steps."""
    stride = 120.0 / p.cadence_steps_min
    d = np.deg2rad
    speed_factor = float(np.clip(p.speed_m_s / 1.3, 0.5, 1.1))
    healthy = SideGait(stance_frac=0.61, theta_hs=d(22.0) * speed_factor, theta_to=-d(50.0) * speed_factor,
                       clearance_m=0.02, circumduction_m=0.0, footprint_offset_m=0.0, toe_out=d(6.0))
    if not p.hemiparetic:
        return GaitParams(stride_s=stride, speed_m_s=p.speed_m_s, left_ic_phase=0.5, step_width_m=0.10,
                          load_frac=0.11, preswing_frac=0.20, right=healthy, left=healthy,
                          pelvis_vertical_m=0.02 * speed_factor, pelvis_drop_m=0.02,
                          pelvis_lateral_m=0.022, pelvis_rotation=d(4.0), pelvis_obliquity=d(4.0),
                          pelvis_tilt=d(1.5), hip_hike=0.0, paretic_side=None, trunk_lean=d(4.0))
    s = p.severity
    paretic = SideGait(stance_frac=0.60 - 0.07 * s, theta_hs=d(22.0 - 14.0 * s) * speed_factor,
                       theta_to=-d(50.0 - 25.0 * s) * speed_factor, clearance_m=0.035 - 0.02 * s,
                       circumduction_m=0.07 * s, footprint_offset_m=-0.05 * s, toe_out=d(6.0 + 6.0 * s))
    nonpar = SideGait(stance_frac=0.62 + 0.08 * s, theta_hs=healthy.theta_hs, theta_to=healthy.theta_to,
                      clearance_m=0.02, circumduction_m=0.0, footprint_offset_m=0.0, toe_out=d(6.0))
    left_par = p.paretic_side == "left"
    phase = 0.5 + (0.06 if left_par else -0.06) * s    # paretic step time is the longer one
    return GaitParams(stride_s=stride, speed_m_s=p.speed_m_s, left_ic_phase=phase, step_width_m=0.10 + 0.06 * s,
                      load_frac=0.11, preswing_frac=0.20,
                      right=nonpar if left_par else paretic, left=paretic if left_par else nonpar,
                      pelvis_vertical_m=0.010 * speed_factor, pelvis_drop_m=0.015, pelvis_lateral_m=0.03 + 0.01 * s,
                      pelvis_rotation=d(4.0 + 2.0 * s), pelvis_obliquity=d(3.0), pelvis_tilt=d(1.5),
                      hip_hike=d(4.0 * s), paretic_side=p.paretic_side, trunk_lean=d(6.0 + 4.0 * s))
