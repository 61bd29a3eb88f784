"""Foot-IMU simulator of hemiparetic gait after stroke (issue 18): both feet, three severities, own ground truth.

Independent of the estimator layer by design (DESIGN.md, issue 16): it imports nothing from there, builds its own
rotations (scipy), its own contact instants and footprints, and none of its thresholds or shapes is a detector's.

Model (per foot, sagittal rockers plus swing in 3-D; ENU, z up; foot frame x to the toes, y left, z up):

* A foot's cycle: **loading** from initial contact IC (the first ground contact, what a force plate's 20 N
  threshold sees) to foot flat FF, **flat** (pose fixed up to a ≤ 0.3° sway), **push-off** from heel-off HO to
  terminal contact TC (rotation about the fixed ball of the foot), **swing** TC → next IC.
* Loading pivots about the point that touches first: the heel when the foot lands toes-up (heel strike,
  pitch θ_ic > 0), the ball when it lands toes-down (forefoot contact, θ_ic < 0); a flat-foot contact is the
  limit θ_ic ≈ 0. The contact point lands with a velocity v_land and is stopped within ``IMPACT_S`` (a C2
  deceleration pulse, the impact); pitch goes θ_ic → 0 (quintic, rate ω_ic at IC).
* Push-off: pitch 0 → θ_to (< 0) about the ball, plantarflexion rate ω_to at TC; a paretic foot with little
  push-off lifts almost flat (θ_to −3…−8°).
* Swing: the toe-off plantarflexion rate stops within 30–50 ms (pitch minimum just after TC) while the swinging
  shank turns the foot toes-up (pitch acceleration 5–12 rad/s² at TC, choice), then a quintic to
  θ_ic with a local peak (rate ω_ic, curvature) over the last ``PEAK_S`` before IC, lowered by a mid-swing bump
  to θ_mid (drop foot: the foot stays plantarflexed, θ_mid < 0); the heel point by a quintic Hermite matching
  position, velocity and acceleration of the rockers at both ends (plus a forward acceleration step of 2–4 m/s² at
  TC: the swinging leg pulls the foot away, it does not hover after the lift), plus a clearance bump (hip hiking) and an outward circumduction bump,
  inversion (roll) and external rotation (yaw) bumps. Every join is C2 except that acceleration step at TC, and
  the impact pulse is smooth but short.
* Both feet follow one cycle template: NP IC (t = 0) → double support d1 → P TC → paretic swing → P IC → d2 →
  NP TC → non-paretic swing → NP IC; stride time T, swing times and the double-support split drawn per stride
  (stride-to-stride CV). Gait starts from 3 s quiet standing with the paretic foot (a shorter first step) and ends
  with a closing step of the trailing foot beside the other (3 s standing). Straight walking (no turns).
* Sensor: on the dorsum, 0.06 m above the sole and 0.11 m in front of the heel, with a random mounting rotation
  (5–20°); white noise, constant bias, 1 % scale errors (``SensorSpec``); internal 1 kHz, sampled at ``rate_hz``.

Severity presets (``SEVERITIES``), from published stroke gait data (values we chose inside the published ranges are
marked "choice"; none is from a detector):

* speed 0.2–0.8 m/s overall (Olney & Richards 1996, Gait Posture 4:136–148: hemiparetic free speeds
  ~0.2–0.8 m/s, low cadence, long double support, paretic stance shortened and swing prolonged); mild 0.65–0.8,
  moderate 0.4–0.6, severe 0.2–0.35 m/s.
* swing-time ratio paretic/non-paretic: mild 1.05–1.2, moderate 1.2–1.5, severe 1.5–2.0; step-length ratio
  (paretic/non-paretic, the paretic step usually the longer) mild 1.0–1.1, moderate 1.05–1.25, severe 1.1–1.4
  (Patterson et al. 2008, Arch Phys Med Rehabil 89:304–310: normative temporal symmetry 0.9–1.1, "mild" and
  "severe" asymmetry groups of community ambulators, swing ratios up to ≈ 2; spatial asymmetry rarer and
  smaller than temporal).
* cadence: mild 85–100, moderate 70–85, severe 50–65 steps/min (Olney & Richards 1996: cadence falls with speed).
* paretic initial contact: mild heel strike with a reduced angle (θ_ic +4…+12°), moderate flat-foot (−3…+3°),
  severe forefoot (−12…−4°) with drop foot in swing (the swing pitch capped at θ_mid −8…−3°, moderate −3…+3°), circumduction 4–10 cm, inversion 5–15°
  (Olney & Richards 1996; Perry & Burnfield 2010, Gait Analysis 2nd ed., ch. on hemiplegia: flat-foot or forefoot
  contact, reduced push-off, drop foot, circumduction / hip hiking) — amplitudes: choice.
* non-paretic foot: heel strike θ_ic +8…+20° and push-off θ_to −25…−45° scaled down at low speed (choice, healthy
  foot-pitch ranges of Perry & Burnfield), the short non-paretic swing.
* severe = cane users: step-to gait (the non-paretic foot lands about beside the paretic one; step-length ratio
  up to 1.4), longer double support, stride CV 6 % (choice).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["SEVERITIES", "SeverityPreset", "SensorSpec", "SimFoot", "SimTrial", "simulate_hemiparetic_trial",
           "hemiparetic_subjects"]

G = 9.81
PEAK_S = 0.12             # the pitch rate and curvature of the contact act over this time before IC, choice
IMPACT_S = 0.025           # contact point stopped within 25 ms (impact pulse), choice
INTERNAL_HZ = 1000.0
L_BALL = 0.18              # heel -> ball of the foot along the sole (m), adult foot (choice)
L_TOE = 0.25               # heel -> toe tip
SENSOR_IN_FOOT = np.array([0.11, 0.0, 0.06])   # dorsum of the midfoot, in the foot frame (origin = heel on the sole)


@dataclass(frozen=True)
class SeverityPreset:
    """Ranges (lo, hi) drawn uniformly per subject; see the module docstring for their sources."""
    speed_m_s: tuple
    cadence_steps_min: tuple
    swing_ratio: tuple          # paretic / non-paretic swing time
    step_ratio: tuple           # paretic / non-paretic step length
    np_swing_frac: tuple        # non-paretic swing time / stride time
    par_theta_ic_deg: tuple
    par_theta_to_deg: tuple
    par_theta_mid_deg: tuple    # paretic mid-swing pitch ceiling (drop foot < 0; inf = no drop foot)
    circumduction_m: tuple
    inversion_deg: tuple
    stride_cv: float
    par_load_s: tuple           # paretic IC -> foot flat
    par_preswing_s: tuple       # paretic heel-off -> TC


SEVERITIES = {
    "mild": SeverityPreset(speed_m_s=(0.65, 0.8), cadence_steps_min=(85, 100), swing_ratio=(1.05, 1.2),
                           step_ratio=(1.0, 1.1), np_swing_frac=(0.33, 0.37), par_theta_ic_deg=(4, 12),
                           par_theta_to_deg=(-32, -20), par_theta_mid_deg=(np.inf, np.inf), circumduction_m=(0.0, 0.03),
                           inversion_deg=(0, 5), stride_cv=0.03, par_load_s=(0.08, 0.12), par_preswing_s=(0.2, 0.3)),
    "moderate": SeverityPreset(speed_m_s=(0.4, 0.6), cadence_steps_min=(70, 85), swing_ratio=(1.2, 1.5),
                               step_ratio=(1.05, 1.25), np_swing_frac=(0.28, 0.33), par_theta_ic_deg=(-3, 3),
                               par_theta_to_deg=(-20, -10), par_theta_mid_deg=(-3, 3), circumduction_m=(0.03, 0.07),
                               inversion_deg=(3, 10), stride_cv=0.045, par_load_s=(0.06, 0.12),
                               par_preswing_s=(0.15, 0.25)),
    "severe": SeverityPreset(speed_m_s=(0.2, 0.35), cadence_steps_min=(50, 65), swing_ratio=(1.5, 2.0),
                             step_ratio=(1.1, 1.4), np_swing_frac=(0.22, 0.28), par_theta_ic_deg=(-12, -4),
                             par_theta_to_deg=(-8, -3), par_theta_mid_deg=(-8, -3), circumduction_m=(0.04, 0.10),
                             inversion_deg=(5, 15), stride_cv=0.06, par_load_s=(0.1, 0.2),
                             par_preswing_s=(0.08, 0.15)),
}


@dataclass(frozen=True)
class SensorSpec:
    """IMU error model (per axis): white noise σ, constant bias σ, scale-factor σ; mounting rotation angle range."""
    acc_noise: float = 0.03
    gyr_noise: float = 0.01
    acc_bias: float = 0.05
    gyr_bias: float = np.deg2rad(0.3)
    scale: float = 0.01
    mounting_deg: tuple = (5.0, 20.0)


@dataclass(frozen=True)
class SimFoot:
    """One foot: gyr (N, 3) rad/s, acc (N, 3) m/s² (sensor frame); truth ``ic_s``, ``tc_s`` (K,) contact instants
    (s from the trial start), ``footprints`` (K+1, 3) sensor position during each flat stance (stride k goes from
    footprint k to k+1, its TC is ``tc_s[k]`` and its IC ``ic_s[k]``); ``contact`` per IC: "heel" | "flat" | "forefoot"."""
    side: str
    paretic: bool
    gyr: np.ndarray
    acc: np.ndarray
    ic_s: np.ndarray
    tc_s: np.ndarray
    footprints: np.ndarray
    contact: tuple
    sensor_pos: np.ndarray


@dataclass(frozen=True)
class SimTrial:
    severity: str
    subject: int
    rate_hz: float
    paretic_side: str
    feet: dict
    params: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------------------------ helpers
def _q5(u, y0, d0, a0, y1, d1, a1, T):
    """Quintic Hermite on u ∈ [0, 1] over duration T (values, first and second time derivatives at both ends);
    y* may be arrays (..., k) broadcast against u (N, 1)."""
    u = np.clip(u, 0.0, 1.0)
    d0, d1, a0, a1 = d0 * T, d1 * T, a0 * T * T, a1 * T * T
    h0 = 1 - 10 * u ** 3 + 15 * u ** 4 - 6 * u ** 5
    h1 = u - 6 * u ** 3 + 8 * u ** 4 - 3 * u ** 5
    h2 = 0.5 * u ** 2 - 1.5 * u ** 3 + 1.5 * u ** 4 - 0.5 * u ** 5
    h3 = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5
    h4 = -4 * u ** 3 + 7 * u ** 4 - 3 * u ** 5
    h5 = 0.5 * u ** 3 - u ** 4 + 0.5 * u ** 5
    return h0 * y0 + h1 * d0 + h2 * a0 + h3 * y1 + h4 * d1 + h5 * a1


def _bump(u):
    u = np.clip(u, 0.0, 1.0)
    return 256.0 * (u * (1 - u)) ** 4


def _smooth(u):
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10 - 15 * u + 6 * u * u)


def _smooth_int(u):
    """∫₀ᵘ (1 − smoothstep) (the impact's displacement shape; value 0.5 at u = 1)."""
    c = np.clip(u, 0.0, 1.0)
    return c - c ** 4 * (2.5 - 3 * c + c * c)


def _rot(psi, theta, phi=0.0):
    """(N, 3, 3) foot -> world: yaw ψ about z, then roll φ about the foot x, then pitch θ (toes up > 0)."""
    psi, theta, phi = np.broadcast_arrays(np.atleast_1d(np.asarray(psi, float)), np.atleast_1d(np.asarray(theta, float)),
                                          np.atleast_1d(np.asarray(phi, float)))
    return Rotation.from_euler("ZXY", np.stack([psi, phi, -theta], -1).reshape(-1, 3)).as_matrix()


# ------------------------------------------------------------------------------------------------ one foot
@dataclass
class _Step:
    """Swing k of a foot: footprint k -> k+1."""
    ho: float
    tc: float
    ic: float
    a_swing: float              # pitch acceleration (toes up) the swinging shank gives the foot at TC (rad/s²)
    a_lift: float               # forward acceleration the swinging leg gives the foot at TC (m/s²)
    ff: float
    theta_to: float
    omega_to: float
    theta_ic: float
    omega_ic: float
    stop_s: float               # the toe-off plantarflexion rate stops within this time after TC
    acc_ic: float               # pitch curvature at IC (rad/s²): < 0 heel strike (a pitch peak), > 0 forefoot
    theta_mid: float
    v_land: np.ndarray          # (3,) world
    clearance: float
    circ: float
    roll: float
    yaw: float


class _Foot:
    def __init__(self, side, heel_fp: np.ndarray, psi: float, steps: list[_Step]):
        self.side, self.fp, self.psi, self.steps = side, heel_fp, psi, steps
        self.sgn = 1.0 if side == "left" else -1.0          # outward = +y_left for the left foot
        self.R0 = _rot(np.array([psi]), np.array([0.0]))[0]

    def _pivot_local(self, theta_ic):
        return np.array([0.0, 0, 0]) if theta_ic >= 0 else np.array([L_BALL, 0, 0])

    def _pushoff(self, k, t):
        """Heel position and (ψ, θ) of push-off k at times t (extends past TC with the TC rate)."""
        s = self.steps[k]
        T = s.tc - s.ho
        u = (t - s.ho) / T
        th = np.where(u <= 1.0, _q5(u, 0.0, 0.0, 0.0, s.theta_to, s.omega_to, 0.0, T),
                      s.theta_to + s.omega_to * (t - s.tc))
        R = _rot(np.full_like(t, self.psi), th)
        ball = self.fp[k] + _rot(np.array([self.psi]), np.array([0.0]))[0] @ np.array([L_BALL, 0, 0])
        return ball[None] - R @ np.array([L_BALL, 0, 0]), th

    def _loading(self, k, t):
        """Loading after swing k (footprint k+1), extended before IC with the landing velocity and rate."""
        s = self.steps[k]
        T = s.ff - s.ic
        u = (t - s.ic) / T
        th = np.where(u >= 0.0, _q5(u, s.theta_ic, s.omega_ic, s.acc_ic, 0.0, 0.0, 0.0, T),
                      s.theta_ic + s.omega_ic * (t - s.ic) + 0.5 * s.acc_ic * (t - s.ic) ** 2)
        pl = self._pivot_local(s.theta_ic)
        R0 = _rot(np.array([self.psi]), np.array([0.0]))[0]
        p_fp = self.fp[k + 1] + R0 @ pl
        ui = (t - s.ic) / IMPACT_S
        disp = np.where(ui >= 0.0, _smooth_int(ui), ui)          # linear (landing velocity) before IC
        P = p_fp[None] - s.v_land[None] * IMPACT_S * (0.5 - disp[:, None])
        R = _rot(np.full_like(t, self.psi), th)
        return P - R @ pl, th

    def _state(self, fn, k, t0):
        h = 1e-4
        tt = np.array([t0 - h, t0, t0 + h])
        p, th = fn(k, tt)
        return (p[1], (p[2] - p[0]) / (2 * h), (p[2] - 2 * p[1] + p[0]) / h ** 2,
                th[1], (th[2] - th[0]) / (2 * h))

    def pose(self, t):
        """Heel position (N, 3) and rotation (N, 3, 3) foot -> world."""
        n = len(t)
        pos = np.repeat(self.fp[:1], n, 0).astype(float)
        psi = np.full(n, self.psi)
        th = np.zeros(n)
        phi = np.zeros(n)
        for k, s in enumerate(self.steps):
            m = (t >= s.ff) & ((t < self.steps[k + 1].ho) if k + 1 < len(self.steps) else True)
            pos[m] = self.fp[k + 1]
            m = (t >= s.ho) & (t < s.tc)
            pos[m], th[m] = self._pushoff(k, t[m])
            m = (t >= s.ic) & (t < s.ff)
            pos[m], th[m] = self._loading(k, t[m])
            m = (t >= s.tc) & (t < s.ic)
            if np.any(m):
                T = s.ic - s.tc
                u = (t[m] - s.tc) / T
                p0, v0, a0, _, _ = self._state(self._pushoff, k, s.tc)
                a0 = a0 + s.a_lift * (self.R0 @ np.array([1.0, 0.0, 0.2]))     # the leg pulls the foot into swing
                p1, v1, a1, _, _ = self._state(self._loading, k, s.ic)
                # the toe-off plantarflexion rate is stopped within ``stop_s`` (pitch minimum just after TC)
                stop = s.omega_to * s.stop_s * _smooth_int((t[m] - s.tc) / s.stop_s)
                end = s.theta_ic - 0.5 * s.omega_to * s.stop_s
                # the contact's pitch rate and curvature only act over the last PEAK_S before IC (a local peak)
                w = min(PEAK_S, 0.4 * T)
                peak = _q5((t[m] - (s.ic - w)) / w, 0.0, 0.0, 0.0, 0.0, s.omega_ic, s.acc_ic, w)
                # the swinging shank turns the foot toes-up from the lift on (pitch acceleration a_swing at TC)
                th_base = stop + peak + _q5(u, s.theta_to, 0.0, s.a_swing, end, 0.0, 0.0, T)
                th_mid0 = 0.5 * s.omega_to * s.stop_s + _q5(np.array([0.5]), s.theta_to, 0.0, s.a_swing, end, 0.0,
                                                            0.0, T)[0]
                th[m] = th_base + min(0.0, s.theta_mid - th_mid0) * _bump(u)    # drop foot lowers the swing pitch
                pp = _q5(u[:, None], p0, v0, a0, p1, v1, a1, T)
                R0 = _rot(np.array([self.psi]), np.array([0.0]))[0]
                out = R0 @ np.array([0.0, self.sgn, 0.0])
                phi[m] = -self.sgn * s.roll * _bump(u)           # inversion: sole turned inward
                psi[m] = self.psi + self.sgn * s.yaw * _bump(u)
                R = _rot(psi[m], th[m], phi[m])
                # heel and ball (the toes bend) must clear the floor in mid-swing: raise the clearance bump if needed
                low = np.min(np.stack([(pp + R @ np.array([x, y, 0.0]))[:, 2] for x in (0.0, L_BALL)
                                       for y in (-0.04, 0.04)]), 0)
                b = _bump(u)
                inner = b > 0.3
                need = np.max((0.01 - low[inner]) / b[inner]) if np.any(inner) else 0.0
                lift = max(s.clearance, need)
                pos[m] = pp + b[:, None] * (np.array([0, 0, lift]) + out * s.circ)
        return pos, _rot(psi, th, phi)


# ------------------------------------------------------------------------------------------------ schedule
def _draw_subject(severity: str, rng) -> dict:
    p = SEVERITIES[severity]
    U = lambda r: float(rng.uniform(*r)) if np.isfinite(r[0]) else float(r[0])       # noqa: E731
    v = U(p.speed_m_s)
    cad = U(p.cadence_steps_min)
    T = 120.0 / cad
    L = v * T
    sr = U(p.step_ratio)
    Lp, Lnp = L * sr / (1 + sr), L / (1 + sr)
    sw_np = U(p.np_swing_frac) * T
    sw_p = min(U(p.swing_ratio) * sw_np, 0.6 * T)
    spd = float(np.clip(v / 1.2, 0.2, 1.0))        # healthy pitch amplitudes shrink at low speed (choice)
    return {"severity": severity, "speed_m_s": v, "cadence": cad, "stride_s": T, "stride_m": L, "step_p": Lp,
            "step_np": Lnp, "swing_p": sw_p, "swing_np": sw_np, "ds_split": U((0.4, 0.6)),
            "par_theta_ic": np.deg2rad(U(p.par_theta_ic_deg)), "par_theta_to": np.deg2rad(U(p.par_theta_to_deg)),
            "par_theta_mid": np.deg2rad(U(p.par_theta_mid_deg)), "circ": U(p.circumduction_m),
            "inv": np.deg2rad(U(p.inversion_deg)), "cv": p.stride_cv, "par_load": U(p.par_load_s),
            "par_pre": U(p.par_preswing_s),
            "np_theta_ic": np.deg2rad(U((8, 20)) * (0.5 + 0.5 * spd)),
            "np_theta_to": -np.deg2rad(U((25, 45)) * (0.5 + 0.5 * spd)),
            "np_load": U((0.07, 0.11)), "np_pre": U((0.2, 0.35)) * (0.7 + 0.3 / max(spd, 0.3)) * 0.6,
            "width": U((0.12, 0.2)) if severity != "mild" else U((0.09, 0.14)),
            "paretic_side": "left" if rng.random() < 0.5 else "right", "psi": U((-np.pi, np.pi))}


def _contact_kind(theta_ic: float) -> str:
    d = np.rad2deg(theta_ic)
    return "heel" if d > 3.0 else ("forefoot" if d < -3.0 else "flat")


def simulate_hemiparetic_trial(severity: str, subject: int, *, strides: int = 14, rate_hz: float = 100.0,
                               seed: int = 0, sensor: SensorSpec = SensorSpec()) -> SimTrial:
    """One straight walking trial of simulated subject ``subject`` of ``severity`` (module docstring):
    3 s standing, ``strides`` gait cycles started with the paretic foot, a closing step, 3 s standing."""
    if severity not in SEVERITIES:
        raise ValueError(f"severity must be one of {sorted(SEVERITIES)}, got {severity!r}")
    srng = np.random.default_rng(np.random.SeedSequence([seed, 18, list(SEVERITIES).index(severity), subject]))
    sp = _draw_subject(severity, srng)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 18, list(SEVERITIES).index(severity), subject, 1]))
    par, nps = sp["paretic_side"], {"left": "right", "right": "left"}[sp["paretic_side"]]
    T0 = 3.0
    # cycle template per stride j: NP IC at c_j; P TC = c_j + d1; P IC = P TC + sw_p; NP TC = P IC + d2;
    # NP IC = NP TC + sw_np = c_{j+1}
    cyc, t = [], T0 - 0.0
    c = T0 - 0.25 * sp["stride_s"]                     # a virtual NP IC before the first paretic lift
    for j in range(strides + 1):
        f = float(np.clip(rng.normal(1.0, sp["cv"]), 0.8, 1.2))
        Tj = sp["stride_s"] * f
        swp = sp["swing_p"] * float(np.clip(rng.normal(1.0, sp["cv"]), 0.8, 1.2))
        swn = sp["swing_np"] * float(np.clip(rng.normal(1.0, sp["cv"]), 0.8, 1.2))
        ds = max(Tj - swp - swn, 0.12)
        d1 = ds * float(np.clip(sp["ds_split"] + rng.normal(0, 0.05), 0.25, 0.75))
        ptc = max(c + d1, T0)
        pic = ptc + swp
        ntc = pic + (ds - d1)
        nic = ntc + swn
        cyc.append((ptc, pic, ntc, nic))
        c = nic
    del t
    # footprints along x (walking frame), heel points; paretic leads
    x_p, x_n = [0.0], [0.0]
    ev = {par: [], nps: []}
    for j, (ptc, pic, ntc, nic) in enumerate(cyc):
        fl = float(np.clip(rng.normal(1.0, sp["cv"]), 0.8, 1.2))
        if j < strides:
            x_p.append(x_n[-1] + sp["step_p"] * (0.6 if j == 0 else fl))
            ev[par].append((ptc, pic))
            x_n.append(x_p[-1] + sp["step_np"] * fl)
            ev[nps].append((ntc, nic))
        else:                                          # closing step: NP foot beside the paretic one
            x_n.append(x_p[-1])
            ev[nps].append((ntc, nic))
    t_end = cyc[-1][3] + 3.0
    psi = sp["psi"]
    Rw = np.array([[np.cos(psi), -np.sin(psi), 0], [np.sin(psi), np.cos(psi), 0], [0, 0, 1]])
    feet = {}
    n_int = int(np.ceil(t_end * INTERNAL_HZ))
    t_int = np.arange(n_int) / INTERNAL_HZ
    for side in (par, nps):
        is_p = side == par
        xs = x_p if is_p else x_n
        lat = (0.5 if side == "left" else -0.5) * sp["width"]
        fp = np.array([Rw @ np.array([x, lat, 0.0]) for x in xs])
        steps = []
        for k, (tc, ic) in enumerate(ev[side]):
            J = lambda a, r=0.1: a * float(np.clip(rng.normal(1.0, r), 0.6, 1.4))   # noqa: E731
            if is_p:
                th_ic, th_to, th_mid = J(sp["par_theta_ic"], 0.15), J(sp["par_theta_to"]), J(sp["par_theta_mid"], 0.15)
                load, pre = J(sp["par_load"]), J(sp["par_pre"])
                circ, roll = J(sp["circ"], 0.15), J(sp["inv"], 0.15)
            else:
                th_ic, th_to, th_mid = J(sp["np_theta_ic"]), J(sp["np_theta_to"]), None
                load, pre, circ, roll = J(sp["np_load"]), J(sp["np_pre"]), 0.0, 0.0
            if k == 0 or k == len(ev[side]) - 1:                  # first and closing steps: smaller rockers
                th_to *= 0.6
                th_ic *= 0.6
            swing = ic - tc
            pre = min(pre, 0.45 * (tc - (steps[-1].ff if steps else tc - 1.0)))
            if th_mid is None:                                    # healthy: pitch rises through the swing
                th_mid = np.inf
            omega_to = 1.4 * th_to / pre                           # plantarflexion rate still high at TC
            kind = _contact_kind(th_ic)
            # heel strike: a pitch maximum from 30 ms before to 10 ms after IC (the range of the pitch peak vs the
            # reference contact on the two real walks, Voisard −26 ms, gaitmap +6 ms); curvature: choice
            acc_ic = -np.sign(th_ic if th_ic != 0 else 1.0) * rng.uniform(2.0, 5.0) * max(abs(th_ic), 0.03) / load ** 2
            # toes-down / flat contact: the shank still rotates forward (knee extension in terminal swing), turning the
            # foot toes-up at 0.2–0.8 rad/s as it lands (choice); the heel then drops about the ball
            omega_ic = acc_ic * rng.uniform(-0.01, 0.03) if th_ic > 0 else rng.uniform(0.2, 0.8)
            fwd = Rw @ np.array([1.0, 0, 0])
            vz = rng.uniform(0.1, 0.3)          # the contact point lands at (0.1–0.3)·(0.4 + v) m/s (choice)
            v_land = fwd * rng.uniform(0.0, 0.15) * (0.3 + sp["speed_m_s"]) - np.array([0, 0, vz]) * (
                0.4 + sp["speed_m_s"])
            steps.append(_Step(ho=tc - pre, tc=tc, ic=ic, ff=ic + load, theta_to=th_to, omega_to=omega_to,
                               theta_ic=th_ic, omega_ic=omega_ic, acc_ic=acc_ic,
                               stop_s=rng.uniform(0.03, 0.05), theta_mid=th_mid, v_land=v_land,
                               clearance=(0.02 + 0.02 * rng.random()), a_lift=rng.uniform(2.0, 4.0),
                               a_swing=rng.uniform(5.0, 12.0), circ=circ if is_p else 0.0,
                               roll=roll if is_p else 0.0, yaw=np.deg2rad(4.0) * (sp["circ"] > 0.03) * is_p))
            del swing
        foot = _Foot(side, fp, psi, steps)
        heel, Rf = foot.pose(t_int)
        feet[side] = _sensor(foot, heel, Rf, t_int, rate_hz, steps, fp, is_p, rng, sensor)
    return SimTrial(severity=severity, subject=subject, rate_hz=rate_hz, paretic_side=par, feet=feet,
                    params={k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in sp.items()})


def _sensor(foot, heel, Rf, t_int, rate_hz, steps, fp, is_p, rng, spec: SensorSpec) -> SimFoot:
    ang = np.deg2rad(rng.uniform(*spec.mounting_deg))
    ax = rng.normal(size=3)
    ax /= np.linalg.norm(ax)
    Rm = Rotation.from_rotvec(ang * ax).as_matrix()           # sensor -> foot
    p = heel + Rf @ SENSOR_IN_FOOT
    Rs = Rf @ Rm                                                # sensor -> world
    dt = 1.0 / INTERNAL_HZ
    a_w = np.gradient(np.gradient(p, dt, axis=0), dt, axis=0)
    rs = Rotation.from_matrix(Rs)
    rel = (rs[:-1].inv() * rs[1:]).as_rotvec() / dt            # body rate at the midpoints
    w = np.vstack([rel[:1], 0.5 * (rel[1:] + rel[:-1]), rel[-1:]])
    f_b = np.einsum("nji,nj->ni", Rs, a_w + np.array([0, 0, G]))
    step = int(round(INTERNAL_HZ / rate_hz))
    if abs(INTERNAL_HZ / rate_hz - step) > 1e-9:
        raise ValueError(f"rate_hz must divide {INTERNAL_HZ:.0f} Hz, got {rate_hz}")
    idx = np.arange(0, len(t_int), step)
    out = {}
    for name, x, sd, bias in (("acc", f_b[idx], spec.acc_noise, spec.acc_bias),
                              ("gyr", w[idx], spec.gyr_noise, spec.gyr_bias)):
        S = np.eye(3) + np.diag(rng.normal(0, spec.scale, 3))
        out[name] = x @ S.T + rng.normal(0, bias, 3) + rng.normal(0, sd, x.shape)
    ps = p[idx]
    fps = np.array([f + Rotation.from_euler("z", foot.psi).as_matrix() @ SENSOR_IN_FOOT for f in fp])
    # the sensor's flat-stance position is exactly fps (pitch 0) up to the mounting, which does not move it
    return SimFoot(side=foot.side, paretic=is_p, gyr=out["gyr"], acc=out["acc"],
                   ic_s=np.array([s.ic for s in steps]), tc_s=np.array([s.tc for s in steps]), footprints=fps,
                   contact=tuple(_contact_kind(s.theta_ic) for s in steps), sensor_pos=ps)


def hemiparetic_subjects(split: str) -> list[tuple[str, int]]:
    """(severity, subject) pairs, 4 per severity: ``"bench"`` subjects 0–3 (reported, looked at while changing the
    detector), ``"dev"`` subjects 100–103 (held out at first, then used to diagnose failures: no longer held out),
    ``"heldout"`` subjects 200–203 (scored only for the final report, never used to change anything)."""
    base = {"bench": 0, "dev": 100, "heldout": 200}[split]
    return [(sev, base + i) for sev in SEVERITIES for i in range(4)]
