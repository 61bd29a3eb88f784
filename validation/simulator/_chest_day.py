"""Free-living day: one chest IMU (acc + gyr, no magnetometer) following a scripted day with labels.

The day is a list of bouts (lying with posture changes, sitting, standing, level walking, stairs up and
down, postural transitions, non-wear). Each bout is a closed-form function of time for the trunk
angles (forward lean λ, lateral bend β, axial roll ρ, heading ψ) and the chest point position; bouts
join continuously with zero velocity at the joins. Trunk frame (spec §0.2 chest): x anterior, y up,
z right; R_trunk = H(ψ) · Rz(-λ) · Rx(β) · Ry(ρ) (λ = -90° is supine, ρ = ±90° side lying).
Sensor frame = trunk frame · mounting rotation (redrawn when the sensor is put back on after a
non-wear period). Static bouts are filled in bulk with breathing (the sternum tilts ≈ 1° at 12-20
breaths/min; a worn sensor is never as still as one on a table); hemiparetic walking has a severity-scaled
step asymmetry (longer, weaker paretic step). Dynamic bouts are differentiated numerically
(central differences, h = 0.25 ms). Vectorised per bout: a 24 h day at 100 Hz takes a few seconds.

Labels: ``lying, sitting, standing, level_walking, stairs_up, stairs_down, transition`` plus
``non_wear`` (sensor taken off and lying on a table); walking labels carry ``steps``.
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field

import numpy as np

from ._records import ImuData, Recording
from stridelab.studies.manifest import ParticipantSpec, SensorModelSpec, StudyManifest

from ._kinematics import bump, heading_frame, rot_x, rot_y, rot_z, smoothstep
from ._lab import LOWER_BACK_MOUNT, local_to_utc_ns
from ._sensor_model import FD_STEP_S, G, SensorErrors, TrueImu, apply_errors, random_rotation, vee_rate

FREE_LIVING_PROTOCOL = "stridelab-free-living-chest-v1"
D = np.deg2rad


@dataclass
class Posture:
    lean: float      # rad, forward +
    bend: float      # rad
    roll: float      # rad, about the trunk long axis
    psi: float       # heading, rad
    z: float         # chest height, absolute (m): the floor of the current storey + the posture's height


@dataclass
class Bout:
    label: str
    t0: float                     # s from local midnight of the recording's first day
    t1: float
    kind: str                     # static | transition | walk | nonwear
    start: Posture
    end: Posture
    params: dict = field(default_factory=dict)
    steps: int = 0


#: Published ranges the day is drawn from (issue 16: not from the activity rules' thresholds, which sit at
#: stairs cadence / level cadence < 0.88 and a chest drop > 0.35 thigh lengths).
#: - Segment heights as fractions of stature H (Winter, Biomechanics and Motor Control of Human Movement, 4th ed.
#:   2009, Fig. 4.1, after Drillis & Contini 1966): greater trochanter (hip) 0.530 H, knee 0.285 H.
#: - Sitting: the seat is at about knee height (popliteal height ≈ knee height) scaled by U(0.85, 1.15) per sit
#:   (chairs are not fitted to the person: low sofa … high stool); the hip sits half a thigh depth, 0.08 m, above
#:   the seat. Chest drop stand -> sit = hip drop (upright trunk) = 0.530 H − seat − 0.08 m
#:   (H = 1.75 m: 0.27-0.42 m = 0.63-0.98 thigh lengths).
#: - Stair descent: gait cycle 0.97 ± 0.18 s (mean ± SD of 101 unimpaired adults aged 18-35 descending an
#:   unconstrained 13-step staircase outside the laboratory, wearable sensors; abstract at
#:   https://www.safetylit.org/citations/index.php?fuseaction=citations.viewdetails&citationIds%5B%5D=citjournalarticle_703263_26),
#:   i.e. about 124 steps/min, faster than most level walking.
#: - Stair ascent: gait cycle N(1.15, 0.15) s is an ASSUMPTION (no cited figure at hand; slower than the descent);
#:   replace it when a source is cited.
#: Hemiparetic participants take stairs 1.4× slower (assumption, as their level walking in ``speed``).
HIP_HEIGHT_FRAC, KNEE_HEIGHT_FRAC, SEATED_HIP_ABOVE_SEAT_M = 0.530, 0.285, 0.08
SEAT_SCALE_RANGE = (0.85, 1.15)
STAIRS_CYCLE_S = {"stairs_down": (0.97, 0.18), "stairs_up": (1.15, 0.15)}
STAIRS_CYCLE_CLIP_S = (0.65, 1.8)


class _Script:
    """Builds the day's bouts sequentially, tracking the posture."""

    def __init__(self, rng: np.random.Generator, p: ParticipantSpec):
        self.rng, self.p = rng, p
        s = p.height_m / 1.75
        self.z_stand, self.z_lie = 1.30 * s, 0.62
        self.floor = 0.0     # height of the storey the person is on (stairs move it); postures are relative to it
        self.t = 0.0
        self.bouts: list[Bout] = []
        self.pos = Posture(lean=D(-90.0), bend=0.0, roll=0.0, psi=0.3, z=self.z_lie)
        self.slow = p.hemiparetic
        self.step_hz = p.cadence_steps_min / 60.0

    def _z_sit(self) -> float:
        """Chest height when seated on a seat drawn for this sit (module constants: published anthropometry)."""
        h = self.p.height_m
        seat = KNEE_HEIGHT_FRAC * h * self.rng.uniform(*SEAT_SCALE_RANGE)
        return self.z_stand - (HIP_HEIGHT_FRAC * h - seat - SEATED_HIP_ABOVE_SEAT_M)

    def _add(self, label, dur, kind, end: Posture, **params):
        b = Bout(label, self.t, self.t + dur, kind, self.pos, end, params)
        self.bouts.append(b)
        self.t += dur
        self.pos = end
        return b

    def static(self, label, dur):
        self._add(label, dur, "static", self.pos)

    def lying_roll(self, roll):
        e = Posture(D(-90.0), 0.0, roll, self.pos.psi, self.floor + self.z_lie)
        self._add("lying", 4.0, "transition", e, bump_lean=0.0, shift=0.0)

    def lie_to_sit(self):
        e = Posture(D(8.0), 0.0, 0.0, self.pos.psi + D(90.0), self.floor + self._z_sit())
        self._add("transition", self.rng.uniform(3.0, 4.5), "transition", e, bump_lean=0.0, shift=0.25)

    def sit_to_lie(self):
        e = Posture(D(-90.0), 0.0, 0.0, self.pos.psi - D(90.0), self.floor + self.z_lie)
        self._add("transition", self.rng.uniform(3.0, 4.5), "transition", e, bump_lean=0.0, shift=-0.25)

    def sit_to_stand(self):
        dur = self.rng.uniform(2.0, 3.0) * (1.5 if self.slow else 1.0)
        e = Posture(D(5.0), 0.0, 0.0, self.pos.psi, self.floor + self.z_stand)
        self._add("transition", dur, "transition", e, bump_lean=D(32.0), shift=0.2)

    def stand_to_sit(self):
        dur = self.rng.uniform(2.0, 3.0) * (1.5 if self.slow else 1.0)
        e = Posture(D(self.rng.uniform(-5.0, 15.0)), 0.0, 0.0, self.pos.psi, self.floor + self._z_sit())
        self._add("transition", dur, "transition", e, bump_lean=D(30.0), shift=-0.2)

    def walk(self, label, dur, turns=0):
        if label == "level_walking":
            f = self.step_hz * self.rng.uniform(0.93, 1.05)
        else:                                   # stairs: published cycle times, not a ratio to level cadence
            mu, sd = STAIRS_CYCLE_S[label]
            cycle = float(np.clip(self.rng.normal(mu, sd), *STAIRS_CYCLE_CLIP_S)) * (1.4 if self.slow else 1.0)
            f = 2.0 / cycle
        rise = {"level_walking": 0.0, "stairs_up": 0.17, "stairs_down": -0.17}[label]
        n_turn = turns
        turn_t = np.sort(self.rng.uniform(2.0, max(2.5, dur - 3.0), n_turn)) if n_turn else np.zeros(0)
        turn_a = self.rng.choice([-1.0, 1.0], n_turn) * self.rng.uniform(D(60), D(180), n_turn)
        ramp = 1.0
        steps = int(round(f * (dur - ramp)))
        dz = rise * f * (dur - ramp)
        e = Posture(D(5.0), 0.0, 0.0, self.pos.psi + float(turn_a.sum()), self.pos.z + dz)
        self.floor += dz
        speed = (0.65 if self.slow else 1.0) * self.p.speed_m_s * (1.0 if rise == 0 else 0.45)
        sev = float(self.p.severity) if self.slow else 0.0
        b = self._add(label, dur, "walk", e, f=f, rise=rise, turn_t=turn_t, turn_a=turn_a, ramp=ramp, speed=speed,
                      lean=D({"level_walking": 4.0, "stairs_up": 12.0, "stairs_down": 1.0}[label]),
                      amp=0.5 if self.slow else 1.0, asym=0.35 * sev, phase_mod=0.35 * sev)
        b.steps = steps

    def nonwear(self, dur):
        self._add("non_wear", dur, "nonwear", self.pos)

    def stand_walk_stand(self, walk_s, label="level_walking", turns=1):
        self.walk(label, walk_s, turns)


def build_day_script(rng: np.random.Generator, p: ParticipantSpec, total_s: float) -> list[Bout]:
    """A day from local midnight: night sleep, morning routine, daytime blocks, bedtime, sleep."""
    s = _Script(rng, p)
    slow = p.hemiparetic
    wake = rng.uniform(6.3, 7.2) * 3600
    bed = rng.uniform(22.3, 23.2) * 3600
    # night
    rolls = [0.0, D(90.0), D(-90.0)]
    while s.t < wake - 600:
        s.static("lying", min(rng.uniform(30, 110) * 60, max(60.0, wake - s.t - 300)))
        s.lying_roll(rolls[rng.integers(3)] if rng.random() < 0.8 else 0.0)
    s.static("lying", max(10.0, wake - s.t))
    # morning routine
    s.lie_to_sit(); s.static("sitting", rng.uniform(40, 150)); s.sit_to_stand()
    s.static("standing", rng.uniform(5, 20)); s.walk("level_walking", rng.uniform(12, 30), 1)
    s.static("standing", rng.uniform(60, 200))
    s.nonwear(rng.uniform(35, 60) * 60)                      # shower / charging
    s.static("standing", rng.uniform(20, 90)); s.walk("level_walking", rng.uniform(8, 15), 1)
    s.walk("stairs_down", rng.uniform(8, 12)); s.walk("level_walking", rng.uniform(8, 20), 1)
    s.static("standing", rng.uniform(30, 120)); s.stand_to_sit(); s.static("sitting", rng.uniform(15, 30) * 60)
    s.sit_to_stand()
    # daytime blocks
    while s.t < bed - 1800:
        r = rng.random()
        if r < (0.45 if slow else 0.35):
            s.static("standing", rng.uniform(5, 30)); s.stand_to_sit()
            s.static("sitting", rng.uniform(10, 70 if slow else 50) * 60); s.sit_to_stand()
            s.static("standing", rng.uniform(3, 20))
        elif r < 0.65:
            for _ in range(int(rng.integers(1, 4))):
                s.walk("level_walking", rng.uniform(15, 120 if slow else 400), int(rng.integers(0, 4)))
                s.static("standing", rng.uniform(10, 180))
        elif r < 0.8:
            s.walk("level_walking", rng.uniform(8, 25), 1)
            up = rng.random() < 0.5
            s.walk("stairs_up" if up else "stairs_down", rng.uniform(6, 14) * (1.4 if slow else 1.0))
            s.walk("level_walking", rng.uniform(5, 20), 1)
            s.static("standing", rng.uniform(10, 90))
            s.walk("level_walking", rng.uniform(5, 20), 1)
            s.walk("stairs_down" if up else "stairs_up", rng.uniform(6, 14) * (1.4 if slow else 1.0))
            s.walk("level_walking", rng.uniform(5, 15), 1)
            s.static("standing", rng.uniform(5, 30))
        else:
            for _ in range(int(rng.integers(2, 6))):
                s.static("standing", rng.uniform(30, 300))
                s.walk("level_walking", rng.uniform(5, 25), int(rng.integers(0, 2)))
    # bedtime
    s.walk("level_walking", rng.uniform(10, 25), 1); s.static("standing", rng.uniform(30, 120))
    s.stand_to_sit(); s.static("sitting", rng.uniform(60, 240)); s.sit_to_lie()
    while s.t < total_s + 3600:
        s.static("lying", rng.uniform(30, 110) * 60)
        s.lying_roll(rolls[rng.integers(3)])
    return s.bouts


def _angles_pos(b: Bout, tau: np.ndarray):
    """Trunk angles (N,) and chest position (N, 3) of bout ``b`` at local times ``tau`` (s)."""
    a, e = b.start, b.end
    n = tau.shape[0]
    dur = b.t1 - b.t0
    if b.kind in ("static", "nonwear"):
        one = np.ones(n)
        return a.lean * one, a.bend * one, a.roll * one, a.psi * one, np.tile([0.0, 0.0, a.z], (n, 1))
    u = tau / dur
    if b.kind == "transition":
        s = smoothstep(u)
        lean = a.lean + (e.lean - a.lean) * s + b.params["bump_lean"] * bump(u)
        roll = a.roll + (e.roll - a.roll) * s
        psi = a.psi + (e.psi - a.psi) * s
        # sit-to-stand: rise in the second part; stand-to-sit: descend in the first part
        if e.z > a.z:
            sz = smoothstep((u - 0.3) / 0.7)
        else:
            sz = smoothstep(u / 0.75)
        z = a.z + (e.z - a.z) * sz
        fwd = b.params["shift"] * s
        h = np.stack([np.cos(psi), np.sin(psi)], -1)
        pos = np.column_stack([h * fwd[:, None], z])
        return lean, np.zeros(n), roll, psi, pos
    # walking / stairs
    P = b.params
    ramp = P["ramp"]
    env = smoothstep(tau / ramp) - smoothstep((tau - (dur - ramp)) / ramp)
    # progression: integral of the envelope (speed v·env), analytic for the smoothstep ramps
    f = P["f"]
    psi = a.psi + np.zeros(n)
    for tt, aa in zip(P["turn_t"], P["turn_a"]):
        psi = psi + aa * smoothstep((tau - tt) / 1.8)
    ph = 2.0 * np.pi * f * tau
    # hemiparetic asymmetry (severity-scaled): the paretic step takes longer (phase modulated at the stride
    # frequency, the stride period is unchanged, so is the step count) and has a smaller vertical excursion
    beta = P.get("phase_mod", 0.0)
    phs = ph + beta * (np.cos(0.5 * ph) - 1.0)
    step_amp = 1.0 + P.get("asym", 0.0) * np.cos(0.5 * ph)
    amp = P["amp"] * env
    lean = a.lean + (P["lean"] - a.lean) * smoothstep(tau / ramp) + (e.lean - P["lean"]) * smoothstep((tau - (dur - ramp)) / ramp)
    lean = lean + amp * D(1.5 if P["rise"] == 0 else 5.0) * np.sin(phs + 0.4)
    bend = amp * D(2.0) * np.sin(0.5 * ph)
    roll = amp * D(3.0) * np.sin(0.5 * ph + 0.3)
    # vertical: oscillation at the step frequency; stairs add the pulsed rise (monotone)
    vert = amp * step_amp * 0.025 * np.cos(phs) * (0.6 if P["rise"] != 0 else 1.0)
    phi_steps = f * (tau - _ramp_lag(tau, ramp, dur))
    rise = P["rise"] * (phi_steps - np.sin(2.0 * np.pi * phi_steps) / (2.0 * np.pi)) if P["rise"] != 0 else 0.0
    lat = amp * 0.02 * np.sin(0.5 * ph)
    ap = amp * step_amp * 0.012 * np.sin(phs + 1.2)
    hx, hy = np.cos(psi), np.sin(psi)
    pos = np.column_stack([(ap) * hx - lat * hy, (ap) * hy + lat * hx, a.z + vert + rise])
    return lean, bend, roll, psi, pos


def _ramp_lag(tau, ramp, dur):
    """tau - ∫ env: the delay accumulated by the start ramp (and the stop ramp)."""
    from ._kinematics import _smoothstep_integral
    up = ramp * _smoothstep_integral(tau / ramp)
    u = np.clip((tau - (dur - ramp)) / ramp, 0.0, 1.0)
    integ = up + np.clip(tau, ramp, dur - ramp) - ramp + ramp * (u - _smoothstep_integral(u))
    return tau - integ


def _progress_acc(b: Bout, tau: np.ndarray, h: float) -> np.ndarray:
    """Horizontal acceleration of the forward progression: v̇ h(ψ) + v ψ̇ h⊥(ψ)."""
    P = b.params
    dur, ramp = b.t1 - b.t0, P["ramp"]

    def v(tt):
        return P["speed"] * (smoothstep(tt / ramp) - smoothstep((tt - (dur - ramp)) / ramp))

    def psi(tt):
        out = b.start.psi + np.zeros_like(tt)
        for t0, aa in zip(P["turn_t"], P["turn_a"]):
            out = out + aa * smoothstep((tt - t0) / 1.8)
        return out
    vd = (v(tau + h) - v(tau - h)) / (2 * h)
    pd = (psi(tau + h) - psi(tau - h)) / (2 * h)
    v0, p0 = v(tau), psi(tau)
    hx, hy = np.cos(p0), np.sin(p0)
    return np.column_stack([vd * hx - v0 * pd * hy, vd * hy + v0 * pd * hx, np.zeros_like(tau)])


#: lower-back sensor point (L4/L5, on the back) from the chest point, in the trunk frame (x anterior, y up, z right):
#: the trunk treated as rigid from sternum to sacrum, 0.45 m below and 0.22 m behind the chest sensor (about the
#: sternum-to-L5 distance and trunk depth of an adult; Winter 2009 segment proportions, rounded)
LOWER_BACK_FROM_CHEST_M = np.array([-0.22, -0.45, 0.0])


def _trunk_R(lean, bend, roll, psi):
    return heading_frame(psi) @ rot_z(-lean) @ rot_x(bend) @ rot_y(roll)


@dataclass
class ChestDayTruth:
    """Truth of a free-living day: ``bouts`` (label, t0_ns, t1_ns, steps) as scripted (before merging),
    ``mounts`` list of (t_from_ns, (3, 3) trunk -> sensor rotation), ``acc_true``/``gyr_true`` only when
    ``keep_true`` was requested."""
    bouts: list
    mounts: list
    acc_true: np.ndarray | None = None
    gyr_true: np.ndarray | None = None


def simulate_chest_day(manifest: StudyManifest, participant: ParticipantSpec, index: int, *,
                       seed: int | None = None, sensor_model: SensorModelSpec | None = None,
                       session: int = 1, keep_true: bool = False) -> tuple[Recording, ChestDayTruth]:
    """One free-living chest recording of ``manifest.free_living.hours`` starting at
    ``free_living.start_local`` on the day after the participant's lab session ``session``."""
    spec = sensor_model or manifest.sensor_model
    seed = manifest.seed if seed is None else int(seed)
    rate = manifest.sampling_rate_hz
    participant = participant.at_visit(session, manifest.visits)      # after visit ``session`` of a programme
    ss = np.random.SeedSequence([seed, index, 2, session])
    s_script, s_dev, s_noise, s_mount, s_breath = ss.spawn(5)      # the first four as before
    rng_script = np.random.default_rng(s_script)
    hh, mm = (int(x) for x in manifest.free_living.start_local.split(":"))
    start_s = hh * 3600 + mm * 60
    total = manifest.free_living.hours * 3600.0
    bouts = build_day_script(rng_script, participant, start_s + total)
    n = int(round(total * rate))
    t_rel = np.arange(n) / rate                                   # s from the recording start
    acc = np.empty((n, 3))
    gyr = np.empty((n, 3))
    rng_mount = np.random.default_rng(s_mount)
    rng_breath = np.random.default_rng(s_breath)
    lo, hi = spec.mounting_misalignment_deg
    mount = random_rotation(rng_mount, 0.3 * lo, 0.5 * hi)
    # after visit ``session`` of a programme; with one visit, ``session`` only reseeds (benches: several days)
    later = (session - 1) * manifest.visit_interval_days if manifest.visits > 1 else 0
    day = manifest.first_lab_date + _dt.timedelta(days=index + 1 + later)
    t0_ns = local_to_utc_ns(day, "00:00", manifest.timezone, offset_s=start_s)
    mounts = [(t0_ns, mount)]
    # a belt-worn lower-back sensor on the same rigid trunk (its own random streams: the chest's stay as they were)
    lb_on = manifest.free_living.lower_back
    if lb_on:
        s_lb_mount, s_lb_breath, s_lb_dev, s_lb_noise = np.random.SeedSequence([seed, index, 4, session]).spawn(4)
        mount_lb = LOWER_BACK_MOUNT @ random_rotation(np.random.default_rng(s_lb_mount), lo, hi)
        rng_lb_breath = np.random.default_rng(s_lb_breath)
        acc_lb, gyr_lb = np.empty((n, 3)), np.empty((n, 3))
    h = FD_STEP_S
    gz = np.array([0.0, 0.0, G])
    labels = []
    for b in bouts:
        if b.t1 <= start_s or b.t0 >= start_s + total:
            if b.kind == "nonwear" and b.t1 <= start_s:
                mount = random_rotation(rng_mount, 0.3 * lo, 0.5 * hi)
                mounts[0] = (t0_ns, mount)
            continue
        i0 = int(np.ceil((b.t0 - start_s) * rate - 1e-9))
        i1 = min(n, int(np.ceil((b.t1 - start_s) * rate - 1e-9)))
        i0 = max(i0, 0)
        labels.append((b.label, max(b.t0, start_s), min(b.t1, start_s + total), b.steps))
        if i1 <= i0:
            continue
        tau = start_s + t_rel[i0:i1] - b.t0
        if b.kind == "static":
            R_t = _trunk_R(*(np.array([x]) for x in (b.start.lean, b.start.bend, b.start.roll, b.start.psi)))[0]
            acc[i0:i1], gyr[i0:i1] = _breathing(R_t, mount, tau, rng_breath)
            if lb_on:
                acc_lb[i0:i1], gyr_lb[i0:i1] = _breathing(R_t, mount_lb, tau, rng_lb_breath)
            continue
        if b.kind == "nonwear":
            new_mount = random_rotation(rng_mount, 0.3 * lo, 0.5 * hi)
            R_a = _trunk_R(*(np.array([x]) for x in (b.start.lean, b.start.bend, b.start.roll, b.start.psi)))[0]
            R_on0, R_on1 = R_a @ mount, R_a @ new_mount
            table = heading_frame(np.array([b.start.psi + 1.0]))[0] @ rot_x(np.array([D(90.0)]))[0]
            _fill_nonwear(acc, gyr, i0, i1, tau, b.t1 - b.t0, R_on0, table, R_on1, h)
            if lb_on:       # the belt comes off too and goes back on as it was
                _fill_nonwear(acc_lb, gyr_lb, i0, i1, tau, b.t1 - b.t0, R_a @ mount_lb, table, R_a @ mount_lb, h)
            mount = new_mount
            mounts.append((t0_ns + int(round((b.t1 - start_s) * 1e9)), mount))
            continue
        for c0 in range(0, i1 - i0, 200_000):
            tt = tau[c0:c0 + 200_000]
            Rs, ps, Rl, pl = [], [], [], []
            for dt in (-h, 0.0, h):
                lean, bend, roll, psi, pos = _angles_pos(b, tt + dt)
                Rt = _trunk_R(lean, bend, roll, psi)
                Rs.append(Rt @ mount)
                ps.append(pos)
                if lb_on:
                    Rl.append(Rt @ mount_lb)
                    pl.append(pos + Rt @ LOWER_BACK_FROM_CHEST_M)
            prog = _progress_acc(b, tt, h) if b.kind == "walk" else 0.0
            a_w = (ps[2] - 2 * ps[1] + ps[0]) / h ** 2 + prog + gz
            sl = slice(i0 + c0, i0 + c0 + tt.shape[0])
            acc[sl] = np.einsum("nki,nk->ni", Rs[1], a_w)
            gyr[sl] = vee_rate(Rs[0], Rs[1], Rs[2], h)
            if lb_on:
                a_l = (pl[2] - 2 * pl[1] + pl[0]) / h ** 2 + prog + gz
                acc_lb[sl] = np.einsum("nki,nk->ni", Rl[1], a_l)
                gyr_lb[sl] = vee_rate(Rl[0], Rl[1], Rl[2], h)
    truth = ChestDayTruth(bouts=[(l, t0_ns + int(round((a - start_s) * 1e9)), t0_ns + int(round((b_ - start_s) * 1e9)), st)
                                 for l, a, b_, st in labels], mounts=mounts)
    if keep_true:
        truth.acc_true, truth.gyr_true = acc.copy(), gyr.copy()
    err = SensorErrors.draw(np.random.default_rng(s_dev), spec, "chest")
    sig = TrueImu(acc=acc, gyr=gyr, mag=None, pos=np.empty((0, 3)), quat=np.empty((0, 4)))
    acc_m, gyr_m, _, _ = apply_errors(sig, err, spec, np.random.default_rng(s_noise), rate)
    del acc, gyr, sig
    t_ns = t0_ns + np.round(t_rel * 1e9).astype(np.int64)
    events = []
    for l, a, b_, st in _merge_labels(truth.bouts):
        ev = {"t_ns": a, "end_ns": b_, "type": "activity", "label": l}
        if l in ("level_walking", "stairs_up", "stairs_down"):
            ev["steps"] = int(st)
        events.append(ev)
    pid = participant.id
    md = {"study": manifest.name, "participant": pid, "session": f"{pid}-free-living-{session}",
          "kind": "free_living", "protocol": FREE_LIVING_PROTOCOL, "trial": f"day-{session}",
          "timezone": manifest.timezone, "condition": participant.condition,
          "height_m": f"{participant.height_m:.3f}", "thigh_length_m": f"{participant.thigh_m:.3f}"}
    if participant.hemiparetic:
        md["paretic_side"] = str(participant.paretic_side)
    rec = Recording(metadata=md, imu={"chest": ImuData(t_ns=t_ns, acc=acc_m, gyr=gyr_m, mag=None)},
                    events=events, name=f"{pid}_free{session}_day-{session}")
    if lb_on:
        err_lb = SensorErrors.draw(np.random.default_rng(s_lb_dev), spec, "lower_back")
        sig = TrueImu(acc=acc_lb, gyr=gyr_lb, mag=None, pos=np.empty((0, 3)), quat=np.empty((0, 4)))
        a_m, g_m, _, _ = apply_errors(sig, err_lb, spec, np.random.default_rng(s_lb_noise), rate)
        rec.imu["lower_back"] = ImuData(t_ns=t_ns, acc=a_m, gyr=g_m, mag=None)
    return rec, truth


#: breathing tilts the sternum about an axis that is mostly the trunk's lateral (z) axis, with smaller
#: components about the long (y) and frontal (x) axes, so it shows in every posture including side lying
BREATH_AXIS = np.array([0.5, 0.6, 1.0]) / np.linalg.norm([0.5, 0.6, 1.0])


def _breathing(R_trunk, mount, tau, rng):
    """Specific force and rate of a worn sensor during a still posture: the sternum tilts with breathing
    (tidal tilt 0.8-1.5° peak, 12-20 breaths/min, drawn per bout; a still body is never as still as a
    sensor on a table). Exact rotation R_trunk · Rot(BREATH_AXIS, α(t)) · mount; translation (≈ 1 mg) ignored."""
    amp = D(rng.uniform(0.8, 1.5))
    f = rng.uniform(0.2, 0.33)
    ph0 = rng.uniform(0.0, 2.0 * np.pi)
    w = 2.0 * np.pi * f
    alpha = amp * np.sin(w * tau + ph0)
    alpha_d = amp * w * np.cos(w * tau + ph0)
    g_t = R_trunk.T @ np.array([0.0, 0.0, G])          # gravity in the trunk frame (constant in the bout)
    k = BREATH_AXIS
    c, s_ = np.cos(alpha)[:, None], np.sin(alpha)[:, None]
    # Rot(k, α)^T g_t (Rodrigues with −α)
    g_rot = g_t[None, :] * c - s_ * np.cross(k, g_t)[None, :] + (1.0 - c) * float(k @ g_t) * k[None, :]
    acc = g_rot @ mount                                 # mount^T · v for each row
    gyr = alpha_d[:, None] * (mount.T @ k)[None, :]
    return acc, gyr


def _merge_labels(bouts):
    out = []
    for l, a, b, st in bouts:
        if out and out[-1][0] == l and out[-1][2] == a and l not in ("transition",):
            out[-1] = (l, out[-1][1], b, out[-1][3] + st)
        else:
            out.append((l, a, b, st))
    return out


def _fill_nonwear(acc, gyr, i0, i1, tau, dur, R_on0, R_table, R_on1, h):
    """Sensor taken off (4 s), lying still on a table, put back on (4 s) with a new mounting."""
    from ._rotations import quat_conj, quat_from_matrix, quat_from_rotvec, quat_mul, quat_to_matrix, quat_to_rotvec
    q0, qt, q1 = quat_from_matrix(R_on0), quat_from_matrix(R_table), quat_from_matrix(R_on1)
    d_off = quat_to_rotvec(quat_mul(quat_conj(q0), qt))
    d_on = quat_to_rotvec(quat_mul(quat_conj(qt), q1))
    gz = np.array([0.0, 0.0, G])

    def pose(tt):
        s1 = smoothstep(tt / 4.0)
        s2 = smoothstep((tt - (dur - 4.0)) / 4.0)
        q = quat_mul(quat_mul(q0, quat_from_rotvec(s1[:, None] * d_off)), quat_from_rotvec(s2[:, None] * d_on))
        z = -0.5 * s1 + 0.5 * s2
        return quat_to_matrix(q), z
    moving = (tau < 4.0) | (tau > dur - 4.0)
    idx = np.flatnonzero(moving)
    still = np.flatnonzero(~moving)
    acc[i0 + still] = R_table.T @ gz
    gyr[i0 + still] = 0.0
    if idx.size:
        tt = tau[idx]
        (Rm, zm), (R0, z0), (Rp, zp) = pose(tt - h), pose(tt), pose(tt + h)
        a_w = np.zeros((tt.size, 3))
        a_w[:, 2] = (zp - 2 * z0 + zm) / h ** 2 + G
        acc[i0 + idx] = np.einsum("nki,nk->ni", R0, a_w)
        gyr[i0 + idx] = vee_rate(Rm, R0, Rp, h)
