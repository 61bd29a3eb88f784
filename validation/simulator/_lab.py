"""Lab session: a calibration trial and walking trials with 8 IMUs, optical reference and gait events."""
from __future__ import annotations

import datetime as _dt
import zoneinfo
from dataclasses import dataclass, field, replace

import numpy as np

from ._jcs_truth import jcs_angles_deg
from ._records import ImuData, PoseData, RangeData, Recording
from ._rotations import quat_from_matrix
from stridelab.studies.manifest import ParticipantSpec, SensorModelSpec, StudyManifest

from ._gait_patterns import BodyGeometry, GaitParams, body_geometry, gait_params
from ._kinematics import SEGMENTS, SIDES, HipWindow, LowerBodyModel, TrialPlan, WalkPath, rot_z, smoothstep
from .violations import Violations
from ._sensor_model import (FD_STEP_S, MagneticEnvironment, SensorErrors, TrueImu, apply_errors, noisy_pose,
                            random_rotation, rotmat_from_rotvec, true_imu)

LAB_PROTOCOL = "stridelab-lab-gait-v1"
RANGE_DIVIDER = 3            # distance sensors at 100/3 Hz
RANGE_BEAM_FOOT = np.array([0.0, -1.0, 0.0])   # beam direction in the foot frame (down when flat)
#: belt-worn lower-back sensor (L4/L5) on the pelvis segment: a little above and behind the pelvis sensor (m, pelvis
#: frame x anterior, y up, z right); nominal mounting as the Mobilise-D McRoberts sensor: sensor x up, y left,
#: z backward (columns = sensor axes in pelvis coordinates), then the session's misalignment
LOWER_BACK_OFFSET_M = np.array([-0.11, 0.08, 0.0])
LOWER_BACK_MOUNT = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass
class LabTrialTruth:
    """Ground truth of one lab trial (all arrays on the IMU sample grid, N samples).

    - ``t_ns`` (N,) int64 UTC sample times; ``t_s`` (N,) seconds from the trial start.
    - ``segment_pos[seg]`` (N, 3) m ENU origin and ``segment_quat[seg]`` (N, 4) [w x y z] ISB segment
      frame -> ENU, for pelvis, thigh_*, shank_*, foot_*, chest (noise-free; the recording's
      ``reference_poses`` are these plus marker noise).
    - ``mounting_quat[placement]`` (4,) constant segment -> sensor rotation: q_sensor = q_segment ⊗ q_mount
      (before strap wobble); ``sensor_offset_m[placement]`` (3,) sensor position in the segment frame
      (``lower_back``, when the protocol has it: on the pelvis segment).
    - ``sensor_quat[placement]`` (N, 4) true sensor orientation (with wobble) and ``sensor_pos`` (N, 3).
    - ``acc_true`` / ``gyr_true`` / ``mag_true`` [placement] (N, 3): error-free signals in the sensor frame.
    - ``joint_angles_deg[joint]`` (N, 3) for hip_left/right, knee_left/right, ankle_left/right: columns
      (flexion/extension, ab/adduction, internal/external rotation), ISB JCS (Z-X-Y Cardan), signs of
      spec/thesis_calib_gait_posture.md §5.3: hip flexion +, knee flexion +, ankle dorsiflexion +,
      adduction / inversion +, internal rotation +, left side with β and γ negated.
    - ``events[side]`` = {"IC": (k,) s, "TC": (k,) s} from the trial start (true contact instants).
    - ``foot_points[side]`` = {"heel", "ball"}: (N, 3) m sole points (toe-off pivot = "ball").
    - ``windows``: calibration windows (label, t0_s, t1_s, side or None).
    - ``range_geometry[key]`` = (position in foot frame (3,), beam direction in foot frame (3,)).
    """
    t_ns: np.ndarray
    t_s: np.ndarray
    segment_pos: dict
    segment_quat: dict
    mounting_quat: dict
    sensor_offset_m: dict
    sensor_quat: dict
    sensor_pos: dict
    acc_true: dict
    gyr_true: dict
    mag_true: dict
    joint_angles_deg: dict
    events: dict
    foot_points: dict
    windows: list
    range_geometry: dict = field(default_factory=dict)
    geometry: BodyGeometry | None = None
    gait: GaitParams | None = None


def sensor_offsets(geo: BodyGeometry) -> dict[str, np.ndarray]:
    """Sensor positions in the segment frames (m)."""
    out = {"pelvis": np.array([-0.10, 0.04, 0.0]), "chest": np.array([geo.chest_depth_m, 0.0, 0.0]),
           "lower_back": LOWER_BACK_OFFSET_M.copy()}
    for side, sign in (("right", 1.0), ("left", -1.0)):
        out[f"thigh_{side}"] = np.array([0.0, -0.5 * geo.thigh_m, sign * 0.075])
        out[f"shank_{side}"] = np.array([0.035, -0.35 * geo.shank_m, -sign * 0.015])
        out[f"foot_{side}"] = np.array([0.06, -0.005, 0.0])
    return out


def range_geometry(geo: BodyGeometry) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Two downward-looking distance sensors per shoe (Duong & Suh 2015): A at the forefoot, B at the heel,
    3 cm above the sole, on the lateral side."""
    out = {}
    for side, sign in (("right", 1.0), ("left", -1.0)):
        y = -geo.ankle_height_m + 0.03
        out[f"foot_{side}/A"] = (np.array([0.6 * geo.ball_x_m, y, sign * 0.045]), RANGE_BEAM_FOOT)
        out[f"foot_{side}/B"] = (np.array([0.8 * geo.heel_x_m, y, sign * 0.04]), RANGE_BEAM_FOOT)
    return out


def joint_angles_deg(R_prox, R_dist, side: str, joint: str) -> np.ndarray:
    """ISB/Grood & Suntay angles (FE, AA, IE) in degrees with the clinical signs of spec §5.3
    (:func:`stridelab.validation.simulator._jcs_truth.jcs_angles_deg`, the simulator's own JCS)."""
    return jcs_angles_deg(R_prox, R_dist, joint=joint, side=side)


def local_to_utc_ns(day: _dt.date, hhmm: str, tz: str, offset_s: float = 0.0) -> int:
    local = _dt.datetime.combine(day, _dt.time.fromisoformat(hhmm), tzinfo=zoneinfo.ZoneInfo(tz))
    return int(round(local.timestamp() * 1e9)) + int(round(offset_s * 1e9))


# ---- lab body model: upright quiet standing, variable hip flexion/extension ---------------------

@dataclass(frozen=True)
class LabMotion:
    """Per-session motor behaviour of a participant in the lab (drawn once per session).

    - ``standing_knee_deg``: natural knee flexion in quiet standing (thigh and shank each about half
      of it off vertical in the sagittal plane; real quiet standing: 0-3°). The feet stand under the
      hips (stance width = hip width), so the legs are vertical in the frontal plane.
    - ``sway_m`` (AP, ML): amplitude of the postural sway of the pelvis over the standing feet (a sum
      of slow sines, 0.05-0.5 Hz); ``sway_freq_hz`` / ``sway_phase`` (2, 3) per direction.
    - ``hip_amp[side]`` (reps,): flexion/extension amplitude factor of each repetition (×18° hip,
      ×6° knee oscillation), ``hip_plane_deg[side]`` (reps,): each repetition swings about an axis
      turned about the vertical by this angle (flexion mixed with ab/adduction: the leg does not
      swing in the same plane every time), ``hip_ie_deg[side]`` (reps,): internal/external rotation
      amplitude coupled to the swing, ``knee_amp[side]`` (reps,): knee oscillation factor.
    """
    standing_knee_deg: float = 1.0
    sway_m: tuple[float, float] = (0.0, 0.0)
    sway_freq_hz: np.ndarray = field(default_factory=lambda: np.array([[0.1, 0.23, 0.41], [0.13, 0.29, 0.37]]))
    sway_phase: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    hip_amp: dict = field(default_factory=dict)
    hip_plane_deg: dict = field(default_factory=dict)
    hip_ie_deg: dict = field(default_factory=dict)
    knee_amp: dict = field(default_factory=dict)

    #: SD of the per-repetition swing plane (deg), amplitude (fraction), coupled internal/external
    #: rotation (deg); bias of the swing plane common to all repetitions of a leg (deg); practice
    #: effect: the first repetitions of the unfamiliar movement vary more, SD × (1 + PRACTICE·e^(−k/PRACTICE_REPS)).
    #: PRACTICE is 0 (off): no source quantifies it, and the repetitions study must not be shaped by the
    #: simulator — with independent repetitions the error still falls and levels off (bench calibration)
    PLANE_SD_DEG = 3.0
    AMP_SD = 0.15
    IE_SD_DEG = 1.5
    PLANE_BIAS_SD_DEG = 0.5
    PRACTICE = 0.0
    PRACTICE_REPS = 2.5

    @classmethod
    def draw(cls, rng: np.random.Generator, reps: int, sway_scale: float = 1.0) -> "LabMotion":
        """Random behaviour: knee flexion U(0.5, 2)°, sway ≈ 3 mm AP / 2 mm ML (× ``sway_scale``),
        per-repetition swing plane N(bias, 3°), coupled rotation N(0, 1.5°), hip and knee amplitude
        factors N(1, 0.15) clipped to [0.6, 1.4], all SDs larger in the first repetitions (practice)."""
        knee = float(rng.uniform(0.5, 2.0))
        sway = (0.003 * sway_scale, 0.002 * sway_scale)
        freq = rng.uniform(0.05, 0.5, (2, 3))
        phase = rng.uniform(0.0, 2.0 * np.pi, (2, 3))
        amp, plane, ie, kamp = {}, {}, {}, {}
        n = max(int(reps), 1)
        practice = 1.0 + cls.PRACTICE * np.exp(-np.arange(n) / cls.PRACTICE_REPS)
        for side in SIDES:
            amp[side] = np.clip(1.0 + cls.AMP_SD * practice * rng.normal(size=n), 0.6, 1.4)
            plane[side] = rng.normal(0.0, cls.PLANE_BIAS_SD_DEG) + cls.PLANE_SD_DEG * practice * rng.normal(size=n)
            ie[side] = cls.IE_SD_DEG * practice * rng.normal(size=n)
            kamp[side] = np.clip(1.0 + cls.AMP_SD * practice * rng.normal(size=n), 0.6, 1.4)
        return cls(standing_knee_deg=knee, sway_m=sway, sway_freq_hz=freq, sway_phase=phase, hip_amp=amp,
                   hip_plane_deg=plane, hip_ie_deg=ie, knee_amp=kamp)


def _per_rep(values: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Smooth (C2) function of the repetition coordinate ``u`` (rep k spans [k, k+1)) through ``values[k]``
    at the middle of each repetition (quintic smoothstep between neighbouring repetitions)."""
    v = np.asarray(values, float)
    if v.size == 1:
        return np.full_like(u, v[0])
    x = np.clip(u - 0.5, 0.0, v.size - 1.0)
    k = np.minimum(np.floor(x).astype(int), v.size - 2)
    f = smoothstep(x - k)
    return v[k] + (v[k + 1] - v[k]) * f


class LabBodyModel(LowerBodyModel):
    """:class:`LowerBodyModel` with a realistic quiet standing and hip flexion/extension for lab trials.

    * Quiet standing is upright: the pelvis stands high enough that the knee is flexed only by
      ``motion.standing_knee_deg`` (thigh and shank within about 1° of vertical), the feet stand
      under the hip joint centres, and the pelvis sways by a few millimetres over the feet. The
      base model's standing height keeps a reach margin that flexes the knees by about 9° (thigh and
      shank about 5° off vertical), which the thesis calibration (segment y vertical in standing,
      Eq. 14) would see as calibration error. Before the walk starts the knees unlock smoothly.
    * Hip flexion/extension repetitions vary: every repetition has its own amplitude and swings
      about an axis turned about the vertical by a few degrees, with a little coupled internal /
      external rotation, so the principal axis (Eq. 15) from few repetitions is off and converges as
      repetitions are added (thesis ch. 3: about 10 suffice).
    """

    def __init__(self, geom: BodyGeometry, gait: GaitParams, plan: TrialPlan, motion: LabMotion | None = None):
        self.motion = motion or LabMotion()
        super().__init__(geom, gait, plan)
        L1, L2 = geom.thigh_m, geom.shank_m
        k = np.deg2rad(self.motion.standing_knee_deg)
        self.l_stand = float(np.sqrt(L1 ** 2 + L2 ** 2 + 2.0 * L1 * L2 * np.cos(k)))

    # feet under the hips in standing (first and last footprint), step width in between
    def _schedule(self, side: str):
        sch = super()._schedule(side)
        sign = 1.0 if side == "right" else -1.0
        widen = 0.5 * (self.geom.hip_width_m - self.gait.step_width_m)
        toe = self.gait.side(side).toe_out
        idx = [0] if sch.n_steps == 0 else [0, len(sch.fp_pos) - 1]
        fp = sch.fp_pos.copy()
        for i in idx:
            psi = sch.fp_psi[i] + sign * toe                   # walking direction
            right = np.array([np.sin(psi), -np.cos(psi), 0.0])
            fp[i] = fp[i] + sign * widen * right
        sch.fp_pos = fp
        return sch

    def standing_weight(self, t):
        """1 in quiet standing (before the walk and after it), 0 while walking; smooth in between."""
        t = np.asarray(t, dtype=float)
        p = self.plan
        if p.t_walk0 is None:
            return np.ones_like(t)
        w = 1.0 - smoothstep((t - (p.t_walk0 - 0.6)) / 0.55)          # knees unlock just before gait initiation
        ends = [float(s.ff.max()) for s in self.schedules.values() if s.n_steps]
        t_end = max([p.t_walk1] + ends) + 0.3
        return w + smoothstep((t - t_end) / 1.0)

    def pelvis(self, t, ankles):
        pos, R, E, ph = super().pelvis(t, ankles)
        if self._z_spline is None:                          # base model: reach limits while walking
            return pos, R, E, ph
        t = np.asarray(t, dtype=float)
        S = self.standing_weight(t)
        if not np.any(S > 0):
            return pos, R, E, ph
        mo = self.motion
        pos = pos.copy()
        # postural sway: AP along the pelvis x axis, ML along its z axis
        for j, axis in ((0, 0), (1, 2)):
            if mo.sway_m[j] > 0:
                sw = mo.sway_m[j] / np.sqrt(3.0) * np.sum(
                    np.sin(2.0 * np.pi * mo.sway_freq_hz[j][None, :] * t[:, None] + mo.sway_phase[j][None, :]), 1)
                pos[:, :2] += (S * sw)[:, None] * R[:, :2, axis]
        # standing height: hips at l_stand from the ankles (knees almost straight)
        zs = []
        for side, sign in (("right", 1.0), ("left", -1.0)):
            off = R[:, :, 2] * (sign * 0.5 * self.geom.hip_width_m)
            a = ankles[side]
            dxy2 = np.sum((pos[:, :2] + off[:, :2] - a[:, :2]) ** 2, axis=1)
            zs.append(a[:, 2] + np.sqrt(np.maximum(self.l_stand ** 2 - dxy2, 1e-6)) - off[:, 2])
        z_up = np.min(zs, axis=0)
        pos[:, 2] += S * np.maximum(z_up - pos[:, 2], 0.0)
        return pos, R, E, ph

    def _apply_hip_window(self, w: HipWindow, t, out):
        m = (t > w.t0) & (t < w.t1)
        if not np.any(m):
            return
        mo = self.motion
        if w.side not in mo.hip_amp:
            return super()._apply_hip_window(w, t, out)
        tt = t[m]
        ramp = 1.0
        env = smoothstep((tt - w.t0) / ramp) - smoothstep((tt - (w.t1 - ramp)) / ramp)
        # the leg lifts into the mean posture (hip and knee flexed) slowly, over the first repetition
        lift = (w.t1 - w.t0) / max(w.reps, 1)
        env_m = smoothstep((tt - w.t0) / lift) - smoothstep((tt - (w.t1 - lift)) / lift)
        u = w.reps * (tt - w.t0) / (w.t1 - w.t0)             # repetition coordinate
        osc = np.sin(2.0 * np.pi * u)
        amp = _per_rep(mo.hip_amp[w.side], u)
        plane = np.deg2rad(_per_rep(mo.hip_plane_deg[w.side], u))
        ie = np.deg2rad(_per_rep(mo.hip_ie_deg[w.side], u))
        kamp = _per_rep(mo.knee_amp[w.side], u)
        # hip flexion (12° mean + 18° oscillation, per-repetition amplitude) about the thigh's z axis
        # turned about its y axis by the repetition's `plane` angle, plus a coupled rotation about y
        f_hip = np.deg2rad(12.0) * env_m + np.deg2rad(18.0) * amp * env * osc
        rv = np.stack([np.sin(plane) * f_hip, ie * env * osc, np.cos(plane) * f_hip], -1)
        d_knee = np.deg2rad(24.0) * env_m + np.deg2rad(6.0) * kamp * env * osc
        d_ank = -(np.cos(plane) * f_hip - d_knee)              # keeps the foot about level
        self._bend_leg(out, w.side, m, rotmat_from_rotvec(rv), d_knee, d_ank)


# ---- trial plans ---------------------------------------------------------------------------------

def calibration_plan(m: StudyManifest, gait: GaitParams) -> tuple[TrialPlan, list]:
    """Quiet standing, hip flexion/extension right then left, straight steps, standing."""
    lab = m.lab
    f_hip = 0.6
    t = lab.quiet_standing_s
    windows = [("quiet_standing", 0.0, t, None)]
    hips = []
    for side in ("right", "left"):
        dur = lab.hip_repetitions / f_hip + 1.0
        hips.append(HipWindow(side=side, t0=t, t1=t + dur, reps=lab.hip_repetitions))
        windows.append(("hip_flexion_extension", t, t + dur, side))
        t += dur + 1.5
    t_w0 = t
    path = WalkPath(psi0=np.pi / 2)
    # find the walking duration that gives exactly `straight_steps` steps
    best = None
    for k in range(200):
        t_w1 = t_w0 + 2.0 + 0.05 * k
        plan = TrialPlan(duration_s=t_w1 + 3.0, path=path, t_walk0=t_w0, t_walk1=t_w1, hip_windows=tuple(hips))
        mdl = LowerBodyModel(_geo_dummy(), gait, plan)
        n = sum(mdl.schedules[s].n_steps for s in SIDES)
        if n >= lab.straight_steps:
            best = plan
            if n == lab.straight_steps:
                break
    plan = best
    last = max(float(LowerBodyModel(_geo_dummy(), gait, plan).schedules[s].ic.max()) for s in SIDES)
    windows.append(("straight_walking", t_w0, min(plan.duration_s, last + 0.6), None))
    return plan, windows


_GEO_DUMMY = None


def _geo_dummy():
    # the schedule does not depend on the geometry except for the footprints; any geometry works here
    global _GEO_DUMMY
    if _GEO_DUMMY is None:
        _GEO_DUMMY = body_geometry(ParticipantSpec(id="X"))
    return _GEO_DUMMY


def walking_plan(m: StudyManifest, gait: GaitParams, trial: int) -> TrialPlan:
    """Straight walk, a smooth 180° turn (left on odd trials, right on even ones), straight back."""
    dur = m.lab.walking_trial_s
    t_w0, t_w1 = 3.0, dur - 3.0
    dist = gait.speed_m_s * (t_w1 - t_w0 - 1.2)
    turn_len = 4.0
    s_turn = max(0.5, 0.5 * (dist - turn_len))
    sign = 1.0 if trial % 2 == 1 else -1.0
    path = WalkPath(psi0=np.pi / 2, turns=[(s_turn, turn_len, sign * np.pi)], s_max=dist + 10.0)
    return TrialPlan(duration_s=dur, path=path, t_walk0=t_w0, t_walk1=t_w1)


# ---- one trial -------------------------------------------------------------------------------

@dataclass
class SessionDevices:
    """Per-session constants: mounting rotations and device errors (same physical IMUs in all trials)."""
    mounts: dict
    errors: dict
    offsets: dict
    gyr_bias: dict


def draw_devices(rng: np.random.Generator, spec: SensorModelSpec, geo: BodyGeometry, placements) -> SessionDevices:
    lo, hi = spec.mounting_misalignment_deg
    mounts = {p: random_rotation(rng, lo, hi) for p in placements}
    errors = {p: SensorErrors.draw(rng, spec, p) for p in placements}
    return SessionDevices(mounts=mounts, errors=errors, offsets=sensor_offsets(geo),
                          gyr_bias={p: errors[p].gyr_bias.copy() for p in placements})


def simulate_trial(model: LowerBodyModel, *, t0_ns: int, rate_hz: float, devices: SessionDevices,
                   spec: SensorModelSpec, mag_env: MagneticEnvironment | None, rng: np.random.Generator,
                   distance_sensors: bool, optical_reference: bool, windows: list,
                   metadata: dict, name: str, violations: Violations | None = None) -> tuple[Recording, LabTrialTruth]:
    vio = violations or Violations()
    n = int(round(model.plan.duration_s * rate_hz))
    t_s = np.arange(n) / rate_hz
    t_ns = t0_ns + np.round(t_s * 1e9).astype(np.int64)
    h = FD_STEP_S
    t5 = (t_s[None, :] + h * np.arange(-2, 3)[:, None]).ravel()
    poses = model.poses(t5)
    poses5 = {seg: (p.reshape(5, n, 3), R.reshape(5, n, 3, 3)) for seg, (p, R) in poses.items()}
    geo = model.geom
    rec = Recording(metadata=dict(metadata), name=name)
    seg_pos = {s: poses5[s][0][2] for s in SEGMENTS}
    seg_R = {s: poses5[s][1][2] for s in SEGMENTS}
    truth = LabTrialTruth(t_ns=t_ns, t_s=t_s, segment_pos=seg_pos,
                          segment_quat={s: quat_from_matrix(seg_R[s]) for s in SEGMENTS},
                          mounting_quat={p: quat_from_matrix(devices.mounts[p]) for p in devices.mounts},
                          sensor_offset_m=dict(devices.offsets), sensor_quat={}, sensor_pos={}, acc_true={},
                          gyr_true={}, mag_true={}, joint_angles_deg={}, events={}, foot_points={},
                          windows=list(windows), geometry=geo, gait=model.gait)
    wobble_on = spec.wobble_deg_per_g > 0 or spec.wobble_mm_per_g > 0
    extra = tuple(p for p in devices.mounts if p not in SEGMENTS)       # lower_back: on the pelvis segment
    rng_extra = np.random.default_rng(rng.bit_generator.seed_seq.spawn(1)[0]) if extra else None
    for p in SEGMENTS + extra:
        seg = "pelvis" if p == "lower_back" else p
        mount = devices.mounts[p]
        if vio.sta_deg_per_knee_deg and p.startswith(("thigh_", "shank_")):
            # soft-tissue artefact: the sensor turns about the segment long axis with the knee flexion
            side = p.split("_")[1]
            Rt, Rsh = poses5[f"thigh_{side}"][1], poses5[f"shank_{side}"][1]
            flex = np.stack([jcs_angles_deg(Rt[j], Rsh[j], joint="knee", side=side)[:, 0] for j in range(5)])
            ang = np.deg2rad(vio.sta_deg_per_knee_deg * flex)
            mount = rotmat_from_rotvec(ang[..., None] * np.array([0.0, 1.0, 0.0]))[1:4] @ mount
        sig: TrueImu = true_imu(poses5[seg], devices.offsets[p], mount,
                                devices.errors[p] if wobble_on else None, mag_env)
        acc, gyr, mag, end_bias = apply_errors(sig, devices.errors[p], spec, rng if p in SEGMENTS else rng_extra,
                                               rate_hz, devices.gyr_bias[p])
        devices.gyr_bias[p] = end_bias
        if vio.heel_strike_g and p.startswith(("foot_", "shank_")):
            side = p.split("_")[1]
            amp = vio.heel_strike_g * 9.81 * (1.0 if p.startswith("foot_") else 0.5)
            axis = devices.mounts[p].T @ np.array([0.0, 1.0, 0.0])        # segment long axis, sensor frame
            pulse = np.zeros(n)
            for tic in model.schedules[side].ic:
                dt = t_s - tic
                on = (dt >= 0) & (dt < 0.1)
                pulse[on] += np.exp(-dt[on] / 0.015) * np.cos(2 * np.pi * 30.0 * dt[on])
            acc = acc + amp * pulse[:, None] * axis
        if vio.gyro_range_dps is not None:
            lim = np.deg2rad(vio.gyro_range_dps)
            gyr = np.clip(gyr, -lim, lim)
        rec.imu[p] = ImuData(t_ns=t_ns, acc=acc, gyr=gyr, mag=mag)
        truth.sensor_quat[p], truth.sensor_pos[p] = sig.quat, sig.pos
        truth.acc_true[p], truth.gyr_true[p], truth.mag_true[p] = sig.acc, sig.gyr, sig.mag
    for side in SIDES:
        for joint, prox, dist in (("hip", "pelvis", f"thigh_{side}"), ("knee", f"thigh_{side}", f"shank_{side}"),
                                  ("ankle", f"shank_{side}", f"foot_{side}")):
            truth.joint_angles_deg[f"{joint}_{side}"] = joint_angles_deg(seg_R[prox], seg_R[dist], side, joint)
        pts = model.sole_points(side, seg_pos[f"foot_{side}"], seg_R[f"foot_{side}"])
        truth.foot_points[side] = {"heel": pts["heel"], "ball": pts["ball"]}
        sch = model.schedules[side]
        ic = sch.ic[(sch.ic >= 0) & (sch.ic < t_s[-1])]
        tc = sch.tc[(sch.tc >= 0) & (sch.tc < t_s[-1])]
        truth.events[side] = {"IC": ic, "TC": tc}
        for typ, times in (("IC", ic), ("TC", tc)):
            for tt in times:
                rec.events.append({"t_ns": int(t0_ns + round(tt * 1e9)), "type": typ, "side": side,
                                   "placement": f"foot_{side}"})
    for label, a, b, side in windows:
        ev = {"t_ns": int(t0_ns + round(a * 1e9)), "end_ns": int(t0_ns + round(b * 1e9)),
              "type": "calibration_window", "label": label}
        if side is not None:
            ev["side"] = side
        if label == "hip_flexion_extension":
            ev["repetitions"] = int(next(w.reps for w in model.plan.hip_windows if w.side == side))
        if label == "straight_walking":
            ev["steps"] = int(sum(np.sum((model.schedules[s].ic >= a) & (model.schedules[s].ic <= b)) for s in SIDES))
        rec.events.append(ev)
    rec.events.sort(key=lambda e: (e["t_ns"], e["type"]))
    if optical_reference:
        for s in SEGMENTS:
            pos, q = noisy_pose(seg_pos[s], seg_R[s], spec, rng)
            rec.reference_poses[s] = PoseData(t_ns=t_ns, pos=pos, quat=q)
    if distance_sensors:
        idx = np.arange(0, n, RANGE_DIVIDER)
        for key, (r_foot, beam) in range_geometry(geo).items():
            seg = key.split("/")[0]
            R = seg_R[seg][idx]
            pnt = seg_pos[seg][idx] + R @ r_foot
            d = R @ beam
            with np.errstate(divide="ignore", invalid="ignore"):
                rng_m = np.where(d[:, 2] < -0.1, -pnt[:, 2] / d[:, 2], np.inf)
            if spec.range_noise_m > 0:
                rng_m = rng_m + rng.normal(0.0, spec.range_noise_m, rng_m.shape)
            rng_m = np.where((rng_m > 0.2) | ~np.isfinite(rng_m), np.nan, np.maximum(rng_m, 0.0))
            rec.ranges[key] = RangeData(t_ns=t_ns[idx], range_m=rng_m, min_range_m=0.0, max_range_m=0.2)
            truth.range_geometry[key] = (r_foot, beam)
    return rec, truth


def simulate_lab_session(manifest: StudyManifest, participant: ParticipantSpec, index: int, *,
                         seed: int | None = None, sensor_model: SensorModelSpec | None = None,
                         session: int = 1, violations: Violations | None = None):
    """Yield ``(Recording, LabTrialTruth)`` for the calibration trial and each walking trial of one lab
    session of ``participant`` (0-based ``index`` in the study, which fixes the date: first_lab_date +
    index days + (session − 1) · visit_interval_days, trials from lab_start_local on; visit ``session`` of a
    programme simulates :meth:`ParticipantSpec.at_visit`). ``sensor_model`` overrides the manifest's (e.g.
    ``SensorModelSpec.ideal()`` for noise-free signals); ``violations`` puts the session beyond the methods'
    assumptions (:mod:`stridelab.validation.simulator.violations`; None = none)."""
    vio = violations or Violations()
    spec = sensor_model or manifest.sensor_model
    seed = manifest.seed if seed is None else int(seed)
    rate = manifest.sampling_rate_hz
    participant = participant.at_visit(session, manifest.visits)      # a programme: the follow-up values
    geo, gait = body_geometry(participant), gait_params(participant)
    root = np.random.SeedSequence([seed, index, 1, session])
    dev_ss, env_ss, *trial_ss = root.spawn(2 + 1 + manifest.lab.walking_trials)
    devices = draw_devices(np.random.default_rng(dev_ss), spec, geo, SEGMENTS)
    if manifest.lab.lower_back:      # its own stream: the other sensors' draws stay as they were
        lb = draw_devices(np.random.default_rng(np.random.SeedSequence([seed, index, 3, session])), spec, geo,
                          ("lower_back",))
        devices.mounts["lower_back"] = LOWER_BACK_MOUNT @ lb.mounts["lower_back"]
        devices.errors["lower_back"] = lb.errors["lower_back"]
        devices.gyr_bias["lower_back"] = lb.gyr_bias["lower_back"]
    mag_env = MagneticEnvironment(spec, np.random.default_rng(np.random.SeedSequence([seed, 99])))
    # a programme's visits are visit_interval_days apart; with one visit, ``session`` only reseeds (benches)
    later = (session - 1) * manifest.visit_interval_days if manifest.visits > 1 else 0
    day = manifest.first_lab_date + _dt.timedelta(days=index + later)
    t_start = local_to_utc_ns(day, manifest.lab_start_local, manifest.timezone)
    pid = participant.id
    sess = f"{pid}-lab-{session}"
    base = {"study": manifest.name, "participant": pid, "session": sess, "protocol": LAB_PROTOCOL,
            "timezone": manifest.timezone, "condition": participant.condition,
            "height_m": f"{participant.height_m:.3f}", "thigh_length_m": f"{participant.thigh_m:.3f}",
            "shank_length_m": f"{participant.shank_m:.3f}"}
    if participant.hemiparetic:
        base["paretic_side"] = str(participant.paretic_side)
    plan, windows = calibration_plan(manifest, gait)
    # motor behaviour of this session (standing posture, sway, hip FE variability); its own stream so
    # the device and trial streams stay as they were. Postural sway scales with the sensor model's
    # noise (the ideal model keeps quiet standing exactly still, the rest contract of its tests).
    motion = LabMotion.draw(np.random.default_rng(np.random.SeedSequence([seed, index, 2, session])),
                            manifest.lab.hip_repetitions, sway_scale=spec.noise_scale)
    if vio.standing_knee_deg is not None:
        motion = replace(motion, standing_knee_deg=float(vio.standing_knee_deg))
    if vio.hip_axis_tilt_deg:
        motion = replace(motion, hip_plane_deg={s: np.asarray(a) + vio.hip_axis_tilt_deg
                                                for s, a in motion.hip_plane_deg.items()})
    trials = [("calibration", "lab", plan, windows)]   # one lab session; the trial name marks calibration
    for k in range(1, manifest.lab.walking_trials + 1):
        trials.append((f"walk-{k}", "lab", walking_plan(manifest, gait, k), []))
    t_off = 0.0
    for k, ((trial, kind, plan, windows), ss) in enumerate(zip(trials, trial_ss)):
        if k == 1 and vio.strap_slip_deg:              # the straps slipped after the calibration trial
            turn = rotmat_from_rotvec(np.array([0.0, np.deg2rad(vio.strap_slip_deg), 0.0]))
            for p in SEGMENTS:
                if p.startswith(("thigh_", "shank_")):
                    devices.mounts[p] = turn @ devices.mounts[p]
        model = LabBodyModel(geo, gait, plan, motion)
        md = dict(base, kind=kind, trial=trial)
        rec, truth = simulate_trial(model, t0_ns=t_start + int(round(t_off * 1e9)), rate_hz=rate, devices=devices,
                                    spec=spec, mag_env=mag_env, rng=np.random.default_rng(ss),
                                    distance_sensors=manifest.lab.distance_sensors,
                                    optical_reference=manifest.lab.optical_reference, windows=windows,
                                    metadata=md, name=f"{pid}_lab{session}_{trial}", violations=vio)
        t_off += plan.duration_s + 60.0
        yield rec, truth
