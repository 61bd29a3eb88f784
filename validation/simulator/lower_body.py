"""Known-answer kinematic fixtures for calibration and joint-angle tests (spec §9.4 recipes).

A seven-segment lower body (pelvis, thighs, shanks, feet; ISB frames, ENU earth, walking toward
east) is driven by known clinical joint angles through the simulator's own JCS (``_jcs_truth``);
IMUs sit on the segments with known mounting rotations ``R_sensor_af``; angular velocity is the body
rate of the sensor orientation and specific force the rotated second derivative of the sensor
position plus gravity. Used by the unit tests and as a fallback scene of ``stridelab bench
calibration``; the platform study simulator (``stridelab.validation.simulator``) is the primary benchmark scene.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._jcs_truth import cardan_zxy, jcs_relative_matrix
from ._rotations import body_rate_from_quat, quat_from_matrix

PLACEMENTS7 = ("pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left", "foot_right")
G = 9.81
#: anatomical frame in neutral standing facing east: x_AF = east, y_AF = up, z_AF = south (right)
R_G_AF0 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass
class SyntheticTrial:
    """acc / gyr: placement -> (N, 3) in the sensor frame; quat_sensor / quat_segment: (N, 4) truth
    sensor→ENU and anatomical→ENU; angles_deg: "<joint>_<side>" -> (N, 3) true clinical angles;
    R_sensor_af: true mounting; windows: true calibration windows (:class:`TrueWindows`, sample indices);
    ic: side -> IC sample indices;
    standing: ``[start, end)`` of the initial quiet standing."""
    sampling_rate_hz: float
    acc: dict
    gyr: dict
    quat_sensor: dict
    quat_segment: dict
    angles_deg: dict
    R_sensor_af: dict
    windows: "TrueWindows"
    ic: dict = field(default_factory=dict)
    standing: tuple[int, int] = (0, 0)


@dataclass(frozen=True)
class TrueWindows:
    """Half-open ``[start, end)`` sample windows of what the fixture did: quiet ``standing``, ``hip_fe`` side ->
    window of that leg's hip flexion/extension, ``walking`` (None = not in the trial). The calibration's own
    window type is built from these by the caller (``CalibrationWindows(**trial.windows.as_kwargs())``)."""
    standing: tuple[int, int] | None = None
    hip_fe: dict = field(default_factory=dict)
    walking: tuple[int, int] | None = None

    def as_kwargs(self) -> dict:
        return {"standing": self.standing, "hip_fe": dict(self.hip_fe), "walking": self.walking, "source": "manual"}


def _rot_axis(axis, ang):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(ang) * K + (1 - np.cos(ang)) * K @ K


def random_mounts(rng: np.random.Generator, *, max_heading_deg: float = 45.0, max_tilt_deg: float = 20.0,
                  placements=PLACEMENTS7) -> dict:
    """placement -> true ``R_sensor_af``: heading |ψ| ≤ max about AF y, then a tilt ≤ max about a
    random horizontal axis (sensor x stays roughly anterior, as after a correct P_mount)."""
    out = {}
    for p in placements:
        psi = np.radians(rng.uniform(-max_heading_deg, max_heading_deg))
        tilt = np.radians(rng.uniform(0, max_tilt_deg))
        ax = rng.normal(size=2)
        R_AF_S = _rot_axis([0, 1, 0], psi) @ _rot_axis([ax[0], 0, ax[1]], tilt)
        out[p] = R_AF_S.T
    return out


def _gauss_c(phi, mu, sd):
    d = (phi - mu + 0.5) % 1.0 - 0.5
    return np.exp(-0.5 * (d / sd) ** 2)


def gait_templates(phi: np.ndarray, crosstalk: float = 1.0) -> dict:
    """Clinical angles (deg) per joint for gait-cycle phase ``phi`` (0 = this side's IC).

    Sagittal curves after the usual clinical shapes (hip: maximum extension near toe-off at ~59 %,
    fast flexion in swing, maximum flexion at ~90 %); frontal and transverse components of a few
    degrees scaled by ``crosstalk`` (0 = purely sagittal gait)."""
    tp = 2 * np.pi * phi
    x = 2 * np.pi * (phi - 0.75)
    th = x + 0.8 * np.sin(x) - 1.589                     # phase warp: swing faster than stance
    c = crosstalk
    hip = np.stack([9 + 19 * np.cos(th), c * 4 * np.sin(tp), c * 4 * np.sin(tp + 1.0)], -1)
    knee = np.stack([3 + 12 * _gauss_c(phi, 0.15, 0.06) + 55 * _gauss_c(phi, 0.72, 0.1),
                     c * 3 * np.sin(tp + 0.5), c * 6 * np.sin(tp - 0.3)], -1)
    ankle = np.stack([-6 * _gauss_c(phi, 0.06, 0.03) + 10 * _gauss_c(phi, 0.45, 0.1) - 22 * _gauss_c(phi, 0.63, 0.05),
                      c * 5 * np.sin(tp + 0.2), c * 3 * np.sin(tp - 0.5)], -1)
    return {"hip": hip, "knee": knee, "ankle": ankle}


def _smoothstep(x):
    x = np.clip(x, 0, 1)
    return x * x * (3 - 2 * x)


class _Program:
    """Piecewise motion program: joint angles, pelvis angles and pelvis position over time."""

    def __init__(self, fs, crosstalk=1.0):
        self.fs = fs
        self.xt = crosstalk
        self.knee_ratio = 0.0
        self.ang = {f"{j}_{s}": [] for j in ("hip", "knee", "ankle") for s in ("left", "right")}
        self.pel = []
        self.vel = []
        self.n = 0
        self.phase_r = []

    def _push(self, ang, pel, vel, phase_r):
        for k in self.ang:
            self.ang[k].append(ang[k])
        self.pel.append(pel)
        self.vel.append(vel)
        self.phase_r.append(phase_r)
        self.n += len(vel)

    def stand(self, dur_s, rng, sway_deg=0.05):
        m = int(round(dur_s * self.fs))
        t = np.arange(m) / self.fs
        ang = {k: np.tile(self.neutral[k], (m, 1)) + sway_deg * np.sin(2 * np.pi * 0.3 * t + rng.uniform(0, 6))[:, None]
               for k in self.ang}
        self._push(ang, np.zeros((m, 3)), np.zeros(m), np.full(m, np.nan))
        return self.n - m, self.n

    def hip_fe(self, side, reps, rng, period_s=2.0, amp_deg=55.0):
        m = int(round(reps * period_s * self.fs))
        t = np.arange(m) / self.fs
        u = 0.5 * (1 - np.cos(2 * np.pi * t / period_s))          # 0 → 1 → 0 per repetition
        flex = amp_deg * u
        ang = {k: np.tile(self.neutral[k], (m, 1)) for k in self.ang}
        h = ang[f"hip_{side}"].copy()
        h[:, 0] += flex
        h[:, 1] += self.xt * 1.5 * np.sin(4 * np.pi * t / period_s)          # small cross-talk
        # each repetition's plane deviates a little (random abduction coupling, SD 0.06 rad/rad ≈ 3.4°)
        coupling = rng.normal(0.0, 0.06, reps)[np.minimum((t // period_s).astype(int), reps - 1)]
        h[:, 1] += self.xt * coupling * flex
        h[:, 2] += self.xt * 2.0 * u
        ang[f"hip_{side}"] = h
        kn = ang[f"knee_{side}"].copy()
        kn[:, 0] += self.knee_ratio * flex                      # 0: knee kept extended (rigid leg)
        ang[f"knee_{side}"] = kn
        an = ang[f"ankle_{side}"].copy()
        an[:, 0] += -8 * u * (self.knee_ratio > 0)
        ang[f"ankle_{side}"] = an
        pel = self.xt * np.stack([-4 * u, 0 * u, 0 * u], -1)
        self._push(ang, pel, np.zeros(m), np.full(m, np.nan))
        return self.n - m, self.n

    def walk(self, strides, rng, stride_s=1.1, speed=1.2, ramp_strides=0.5):
        dur = (strides + 2 * ramp_strides) * stride_s
        m = int(round(dur * self.fs))
        t = np.arange(m) / self.fs
        env = _smoothstep(t / (ramp_strides * stride_s)) * _smoothstep((dur - t) / (ramp_strides * stride_s))
        phi_r = (t / stride_s - ramp_strides) % 1.0
        tr, tl = gait_templates(phi_r, self.xt), gait_templates((phi_r - 0.5) % 1.0, self.xt)
        ang = {}
        for j in ("hip", "knee", "ankle"):
            for s, tpl in (("right", tr), ("left", tl)):
                k = f"{j}_{s}"
                ang[k] = self.neutral[k] + env[:, None] * tpl[j]
        tp = 2 * np.pi * phi_r
        pel = env[:, None] * self.xt * np.stack([2 * np.sin(2 * tp), 4 * np.sin(tp), 5 * np.sin(tp)], -1)
        phase = np.where(env > 0.5, t / stride_s - ramp_strides, np.nan)
        self._push(ang, pel, speed * env, phase)
        return self.n - m, self.n


def _simulate(prog: _Program, mounts: dict, rng, noise: bool, placements=PLACEMENTS7):
    fs = prog.fs
    ang = {k: np.concatenate(v) for k, v in prog.ang.items()}
    pel = np.concatenate(prog.pel)
    vel = np.concatenate(prog.vel)
    N = vel.size
    x = np.cumsum(vel) / fs
    R_pel = R_G_AF0 @ cardan_zxy(pel[:, 0], pel[:, 1], pel[:, 2])
    ph = 2 * np.pi * np.nan_to_num(np.concatenate(prog.phase_r))
    walking = vel / max(vel.max(), 1e-9)
    # centre of mass: vertical bounce at the step frequency, medio-lateral sway toward the stance leg
    # (right stance in the first half of the right cycle: toward ENU -y) at the stride frequency
    pos_pel = np.stack([x, -0.02 * np.sin(ph) * walking, 0.95 + 0.01 * np.cos(2 * ph) * walking], -1)
    R = {"pelvis": R_pel}
    pos = {}
    for side, zs in (("left", -1.0), ("right", 1.0)):
        hipc = pos_pel + np.einsum("nij,j->ni", R_pel, [0.0, -0.05, 0.09 * zs])
        Rt = R_pel @ jcs_relative_matrix(ang[f"hip_{side}"], joint="hip", side=side)
        Rs = Rt @ jcs_relative_matrix(ang[f"knee_{side}"], joint="knee", side=side)
        Rf = Rs @ jcs_relative_matrix(ang[f"ankle_{side}"], joint="ankle", side=side)
        knee = hipc + Rt @ np.array([0.0, -0.42, 0.0])
        ankle = knee + Rs @ np.array([0.0, -0.42, 0.0])
        R[f"thigh_{side}"], R[f"shank_{side}"], R[f"foot_{side}"] = Rt, Rs, Rf
        pos[f"thigh_{side}"] = hipc + Rt @ np.array([0.0, -0.2, 0.07 * zs])
        pos[f"shank_{side}"] = knee + Rs @ np.array([0.04, -0.15, 0.0])
        pos[f"foot_{side}"] = ankle + Rf @ np.array([0.08, -0.04, 0.0])
    pos["pelvis"] = pos_pel + np.einsum("nij,j->ni", R_pel, [-0.1, 0.0, 0.0])
    acc, gyr, qs, qa = {}, {}, {}, {}
    for p in placements:
        R_G_S = R[p] @ mounts[p].T
        q_s = quat_from_matrix(R_G_S)
        a_G = np.gradient(np.gradient(pos[p], axis=0), axis=0) * fs * fs + np.array([0.0, 0.0, G])
        a = np.einsum("nji,nj->ni", R_G_S, a_G)
        w = body_rate_from_quat(q_s, fs)
        if noise:
            a = a + rng.normal(0, 0.05, a.shape)
            w = w + rng.normal(0, 0.02, w.shape)
        acc[p], gyr[p], qs[p], qa[p] = a, w, q_s, quat_from_matrix(R[p])
    return acc, gyr, qs, qa, ang


def _ic_from_phase(phase: np.ndarray) -> dict:
    ok = np.isfinite(phase)
    out = {}
    for side, off in (("right", 0.0), ("left", 0.5)):
        c = np.floor(np.where(ok, phase - off, np.nan))
        idx = np.flatnonzero(ok[1:] & ok[:-1] & (np.diff(c) > 0)) + 1
        out[side] = idx
    return out


def _neutral(rng, offsets):
    """Neutral standing joint angles: SD ``offsets`` degrees (True = 2°, False/0 = upright)."""
    sd = 2.0 if offsets is True else float(offsets or 0.0)
    if sd == 0:
        return {f"{j}_{s}": np.zeros(3) for j in ("hip", "knee", "ankle") for s in ("left", "right")}
    return {f"{j}_{s}": rng.normal(0, sd, 3) for j in ("hip", "knee", "ankle") for s in ("left", "right")}


def calibration_trial(*, mounts: dict, rng: np.random.Generator, sampling_rate_hz: float = 100.0,
                      standing_s: float = 4.0, fe_reps: int = 10, fe_sides=("right", "left"),
                      walking_steps: int = 8, noise: bool = True, standing_offsets: bool | float = True,
                      crosstalk: float = 1.0) -> SyntheticTrial:
    """Quiet standing, hip FE repetitions of each leg in ``fe_sides``, then straight walking.

    noise: white noise on acc (0.05 m/s²) and gyr (0.02 rad/s); standing_offsets: random neutral
    joint angles (SD 2°) so segments are not exactly upright in standing; crosstalk: scale of the
    non-sagittal motion (0 = pure single-axis movements)."""
    prog = _Program(sampling_rate_hz, crosstalk)
    prog.neutral = _neutral(rng, standing_offsets)
    st = prog.stand(standing_s, rng)
    fe = {}
    for side in fe_sides:
        prog.stand(1.0, rng)
        if fe_reps > 0:
            fe[side] = prog.hip_fe(side, fe_reps, rng)
    prog.stand(1.5, rng)
    wk = prog.walk(walking_steps / 2.0, rng) if walking_steps > 0 else None
    prog.stand(1.5, rng)
    acc, gyr, qs, qa, ang = _simulate(prog, mounts, rng, noise)
    return SyntheticTrial(sampling_rate_hz, acc, gyr, qs, qa, ang, dict(mounts),
                          TrueWindows(standing=st, hip_fe=fe, walking=wk),
                          _ic_from_phase(np.concatenate(prog.phase_r)), st)


def walking_trial(*, mounts: dict, rng: np.random.Generator, sampling_rate_hz: float = 100.0,
                  standing_s: float = 3.0, strides: int = 20, noise: bool = False,
                  standing_offsets: bool = True, neutral: dict | None = None,
                  crosstalk: float = 1.0) -> SyntheticTrial:
    """Quiet standing then straight walking for ``strides`` strides, then standing."""
    prog = _Program(sampling_rate_hz, crosstalk)
    prog.neutral = neutral if neutral is not None else _neutral(rng, standing_offsets)
    st = prog.stand(standing_s, rng)
    wk = prog.walk(strides, rng)
    prog.stand(1.0, rng)
    acc, gyr, qs, qa, ang = _simulate(prog, mounts, rng, noise)
    return SyntheticTrial(sampling_rate_hz, acc, gyr, qs, qa, ang, dict(mounts),
                          TrueWindows(standing=st, walking=wk),
                          _ic_from_phase(np.concatenate(prog.phase_r)), st)
