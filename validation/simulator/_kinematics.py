"""Physically consistent multi-segment lower-body kinematics for lab trials.

Construction (all functions of continuous time, C2 almost everywhere, evaluated vectorised):

1. **Feet** follow a footstep schedule. Stance = heel rocker (rotation about the fixed heel point,
   IC -> foot flat), foot flat (pose exactly constant: zero velocity and angular velocity), toe
   rocker (rotation about the fixed ball of the foot, heel-off -> toe-off). Swing = quintic Hermite
   interpolation of ankle position, heading and pitch matching position, velocity and acceleration of
   the rockers at toe-off and initial contact, plus a clearance bump and (paretic) a circumduction bump.
2. **Pelvis** moves along a walking path (straight lines and smooth turns) with a smooth speed
   envelope, vertical / lateral oscillation and rotations; its height is a smooth minimum of the
   nominal height and the highest height both legs can reach (so the legs never over-stretch).
3. **Legs** by analytic two-link inverse kinematics between hip and ankle joint centres (thigh and
   shank lengths constant), knee in the plane of the leg and the foot's forward direction.
4. **Hip flexion/extension windows** (calibration trial) override one leg by forward kinematics
   from the standing posture with smooth envelopes.

Frames: ENU world, ISB segment frames (x anterior, y superior, z right) given as rotation matrices
segment -> world (columns = segment axes in world coordinates). Segment origins: pelvis = midpoint
of the hip joint centres, thigh = hip joint centre, shank = knee joint centre, foot = ankle joint
centre, chest = trunk point at sternum level.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ._gait_patterns import BodyGeometry, GaitParams

SEGMENTS = ("pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left", "foot_right",
            "chest")
SIDES = ("left", "right")


# ---- small helpers ----------------------------------------------------------------------------

def smoothstep(u):
    """Quintic 0 -> 1 on [0, 1] with zero 1st and 2nd derivatives at both ends (clipped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


def _smoothstep_integral(u):
    u = np.clip(u, 0.0, 1.0)
    return u ** 4 * (2.5 + u * (-3.0 + u))


def bump(u):
    """C2 bump 64 u³(1-u)³ on [0, 1] (peak 1 at 0.5), zero outside."""
    u = np.asarray(u, dtype=float)
    inside = (u > 0.0) & (u < 1.0)
    uc = np.where(inside, u, 0.0)
    return np.where(inside, 64.0 * uc ** 3 * (1.0 - uc) ** 3, 0.0)


def smoothstep7(u):
    """Septic 0 -> 1 on [0, 1] with zero 1st..3rd derivatives at both ends (clipped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u ** 4 * (35.0 + u * (-84.0 + u * (70.0 - 20.0 * u)))


def _smoothstep7_integral(u):
    """∫₀ᵘ smoothstep7 (u may exceed 1: linear continuation; 0 for u < 0)."""
    u = np.asarray(u, dtype=float)
    c = np.clip(u, 0.0, 1.0)
    return c ** 5 * (7.0 + c * (-14.0 + c * (10.0 - 2.5 * c))) + np.maximum(u - 1.0, 0.0)


def _septic_basis():
    """Coefficients (8, 8) of the septic Hermite basis on [0, 1]: value, 1st..3rd derivative at 0, then at 1."""
    from math import factorial
    M = np.zeros((8, 8))
    for d in range(4):
        for p in range(d, 8):
            M[d, p] = factorial(p) if p == d else 0.0
            M[4 + d, p] = factorial(p) / factorial(p - d)
    return np.linalg.inv(M)          # column i: polynomial coefficients of basis function i


_H7 = _septic_basis()


def hermite7(u, ends):
    """Septic Hermite on u in [0, 1] (clipped): ``ends`` = value and 1st..3rd derivatives at 0, then at 1, in u
    units (scalars or arrays broadcasting with u)."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    out = np.zeros_like(u)
    for i, e in enumerate(ends):
        if np.any(np.asarray(e) != 0.0):
            out = out + np.asarray(e, dtype=float) * np.polynomial.polynomial.polyval(u, _H7[:, i])
    return out


HS_CURV = 4.0            # heel rocker: pitch curvature at IC (units theta_hs / t_load^2): the pitch peak at IC


def _heel_rocker_profile(u):
    """0 -> 1 over the heel rocker: zero rate and curvature HS_CURV at IC, C3 into foot flat."""
    return hermite7(u, (0.0, 0.0, HS_CURV, 0.0, 1.0, 0.0, 0.0, 0.0))


def _ramp5(u):
    """∫₀ᵘ smoothstep (linear continuation u - 1/2 beyond 1, 0 below 0)."""
    u = np.asarray(u, dtype=float)
    return _smoothstep_integral(u) + np.maximum(u - 1.0, 0.0)


def bump4(u):
    """C3 bump 256 u⁴(1-u)⁴ on [0, 1] (peak 1 at 0.5), zero outside."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    return 256.0 * (u * (1.0 - u)) ** 4


# foot pitch and swing shape near the contacts (see LowerBodyModel._swing and docs/gait.md)
TOE_RISE = 0.6           # toe rocker: the plantarflexion rate rises over this fraction of the pre-swing, then holds
TOE_OFF_STOP_S = 0.045   # toe-off -> end of the push-off plantarflexion (quintic stop; pitch minimum ~35 ms after TO)
SWING_PULSE_START = 0.0  # the swing dorsiflexion pulse starts this fraction of TOE_OFF_STOP_S after toe-off
SWING_RAMP1 = 0.15       # swing progression ramps down over this fraction of the swing before IC
HEEL_APPROACH = 0.5      # heel speed before that final ramp (fraction of the walking speed)
SWING_RISE = 0.45        # pre-IC dorsiflexion (to theta_hs) over this fraction of the swing (at most RISE_MAX
RISE_MAX = 1.7           # heel-rocker times: its curvature at IC must match the heel rocker's, monotone septic)
SWING_OVERLAP = 0.7      # the swing's main dorsiflexion (to level) ends this fraction of the pre-IC rise before IC
BLEND = (0.3, 0.8)       # ball track -> heel track blend (swing fraction)


def heading_frame(psi):
    """(N, 3, 3): x = horizontal heading (cos ψ, sin ψ, 0), y = up, z = x × y (right)."""
    psi = np.asarray(psi, dtype=float)
    c, s = np.cos(psi), np.sin(psi)
    z0 = np.zeros_like(psi)
    one = np.ones_like(psi)
    return np.stack([np.stack([c, z0, s], -1), np.stack([s, z0, -c], -1), np.stack([z0, one, z0], -1)], -2)


def rot_x(a):
    a = np.asarray(a, dtype=float)
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_y(a):
    a = np.asarray(a, dtype=float)
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def rot_z(a):
    a = np.asarray(a, dtype=float)
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# ---- walking path --------------------------------------------------------------------------------

class WalkPath:
    """Planar path parameterised by arc length ``s``: heading ψ(s) = ψ0 + Σ Δψ·smoothstep((s-s_i)/L_i)
    (smooth turns), position by integrating the heading (cubic spline on a 5 mm grid)."""

    def __init__(self, origin_xy=(0.0, 0.0), psi0: float = np.pi / 2, turns=(), s_max: float = 200.0):
        self.psi0 = float(psi0)
        self.turns = tuple((float(a), float(b), float(c)) for a, b, c in turns)  # (s_start, length, dpsi)
        s = np.arange(-1.0, s_max + 1.0, 0.005)
        psi = self.heading(s)
        dx, dy = np.cos(psi), np.sin(psi)
        x = np.concatenate([[0.0], np.cumsum(0.5 * (dx[1:] + dx[:-1]) * np.diff(s))])
        y = np.concatenate([[0.0], np.cumsum(0.5 * (dy[1:] + dy[:-1]) * np.diff(s))])
        i0 = np.searchsorted(s, 0.0)
        x += origin_xy[0] - np.interp(0.0, s, x)
        y += origin_xy[1] - np.interp(0.0, s, y)
        del i0
        self._x = CubicSpline(s, x)
        self._y = CubicSpline(s, y)

    def heading(self, s):
        s = np.asarray(s, dtype=float)
        psi = np.full_like(s, self.psi0)
        for s0, length, dpsi in self.turns:
            psi = psi + dpsi * smoothstep((s - s0) / length)
        return psi

    def xy(self, s):
        s = np.asarray(s, dtype=float)
        return np.stack([self._x(s), self._y(s)], -1)


# ---- trial plan and footstep schedule -----------------------------------------------------------

@dataclass(frozen=True)
class HipWindow:
    """Hip flexion/extension repetitions of one leg: ``side``, ``t0``..``t1`` (s), ``reps`` cycles."""
    side: str
    t0: float
    t1: float
    reps: int


@dataclass
class TrialPlan:
    """What happens in one trial: standing, optional hip windows, one walk (``t_walk0``..``t_walk1``
    = pelvis speed envelope) along ``path``."""
    duration_s: float
    path: WalkPath
    t_walk0: float | None = None
    t_walk1: float | None = None
    ramp_s: float = 1.2
    hip_windows: tuple[HipWindow, ...] = ()


@dataclass
class FootSchedule:
    """Footsteps of one foot. Footprint k: flat-foot ankle position ``fp_pos[k]`` (3,) and heading
    ``fp_psi[k]``; step k moves footprint k -> k+1 with heel-off ``ho[k]``, toe-off ``tc[k]``,
    initial contact ``ic[k]``, foot flat ``ff[k]``; pitches ``theta_to[k]``, ``theta_hs[k]``."""
    side: str
    fp_pos: np.ndarray
    fp_psi: np.ndarray
    ho: np.ndarray
    tc: np.ndarray
    ic: np.ndarray
    ff: np.ndarray
    theta_to: np.ndarray
    theta_hs: np.ndarray
    clearance: np.ndarray
    circumduction: np.ndarray

    @property
    def n_steps(self) -> int:
        return len(self.ic)


class LowerBodyModel:
    """Segment poses of one participant in one trial as functions of time (see module docstring)."""

    def __init__(self, geom: BodyGeometry, gait: GaitParams, plan: TrialPlan):
        self.geom, self.gait, self.plan = geom, gait, plan
        self.l_max = 0.9995 * (geom.thigh_m + geom.shank_m)
        self.softmin_m = 0.006
        T = gait.stride_s
        if plan.t_walk0 is not None:
            self._ic_r0 = plan.t_walk0 + gait.swing_s("right") + 0.15
        else:
            self._ic_r0 = 0.0
        self.schedules = {side: self._schedule(side) for side in SIDES}
        self._T = T
        # pelvis height: the nominal height, lowered where a leg could not reach (smooth lower envelope:
        # min-filter then Gaussian with half-width >= 3 sigma keeps it below every limit; 2 mm margin)
        self._z_spline = None
        dt, sig = 0.005, 0.05
        tg = np.arange(-0.5, plan.duration_s + 0.5, dt)
        ank = {side: self.foot(side, tg)[0] for side in SIDES}
        zt = self.pelvis(tg, ank)[0][:, 2]
        from scipy.ndimage import gaussian_filter1d, minimum_filter1d
        half = int(np.ceil(3.0 * sig / dt))
        zt = gaussian_filter1d(minimum_filter1d(zt, 2 * half + 1, mode="nearest"), sig / dt, truncate=3.0,
                               mode="nearest") - 0.002
        self._z_spline = CubicSpline(tg, zt)

    # -- pelvis progression
    def walk_envelope(self, t):
        p = self.plan
        t = np.asarray(t, dtype=float)
        if p.t_walk0 is None:
            return np.zeros_like(t)
        return smoothstep((t - p.t_walk0) / p.ramp_s) - smoothstep((t - (p.t_walk1 - p.ramp_s)) / p.ramp_s)

    def pelvis_arc(self, t):
        p = self.plan
        t = np.asarray(t, dtype=float)
        if p.t_walk0 is None:
            return np.zeros_like(t)
        r = p.ramp_s
        up = r * _smoothstep_integral((t - p.t_walk0) / r)
        plateau = np.clip(t, p.t_walk0 + r, p.t_walk1 - r) - (p.t_walk0 + r)
        u = np.clip((t - (p.t_walk1 - r)) / r, 0.0, 1.0)
        down = r * (u - _smoothstep_integral(u))
        return self.gait.speed_m_s * (up + plateau + down)

    def _footprint(self, side: str, s: float, psi_path: float | None = None):
        g = self.gait
        sg = g.side(side)
        sign = 1.0 if side == "right" else -1.0
        xy = self.plan.path.xy(np.array([s]))[0]
        psi = float(self.plan.path.heading(np.array([s]))[0])
        n = np.array([-np.sin(psi), np.cos(psi)])      # left normal
        pos = np.array([*(xy - sign * 0.5 * g.step_width_m * n), self.geom.ankle_height_m])
        return pos, psi - sign * sg.toe_out

    def _schedule(self, side: str) -> FootSchedule:
        g, p, T = self.gait, self.plan, self.gait.stride_s
        sg = g.side(side)
        fp0, psi0 = self._footprint(side, 0.0)
        fps, psis = [fp0], [psi0]
        ho, tc, ic, ff, th_to, th_hs, clr, circ = ([] for _ in range(8))
        if p.t_walk0 is not None:
            first = self._ic_r0 + (g.left_ic_phase * T if side == "left" else 0.0)
            t_load, t_pre = g.load_frac * T, g.preswing_frac * T
            swing = g.swing_s(side)
            mid = 0.25 * T                          # pelvis passes over the ankle at 25 % of the stride
            s_prev = 0.0
            stride_len = g.speed_m_s * T
            k = 0
            while True:
                t_ic = first + k * T
                if t_ic + mid > p.duration_s - 1.0:
                    break
                s_new = float(self.pelvis_arc(np.array([t_ic + mid]))[0]) + sg.footprint_offset_m
                if s_new - s_prev < 0.06:
                    break
                scale = float(np.clip((s_new - s_prev) / stride_len, 0.25, 1.0))
                pos, psi = self._footprint(side, s_new)
                pos[:2] += 0.0
                fps.append(pos)
                psis.append(psi)
                tc.append(t_ic - swing)
                ho.append(t_ic - swing - t_pre)
                ic.append(t_ic)
                ff.append(t_ic + t_load)
                th_to.append(sg.theta_to * scale)
                th_hs.append(sg.theta_hs * scale)
                clr.append(sg.clearance_m * scale)
                circ.append(sg.circumduction_m * scale)
                s_prev = s_new
                k += 1
        # make headings continuous (unwrap) so swings interpolate the short way
        psis = np.unwrap(np.asarray(psis, dtype=float))
        return FootSchedule(side=side, fp_pos=np.asarray(fps, dtype=float), fp_psi=psis,
                            ho=np.asarray(ho, float), tc=np.asarray(tc, float), ic=np.asarray(ic, float),
                            ff=np.asarray(ff, float), theta_to=np.asarray(th_to, float),
                            theta_hs=np.asarray(th_hs, float), clearance=np.asarray(clr, float),
                            circumduction=np.asarray(circ, float))

    # -- feet
    def _about(self, pivot, psi, pivot_x, theta):
        """Ankle position of a foot with heading ``psi`` and pitch ``theta`` whose sole point ``pivot_x``
        (foot x) is at ``pivot`` (N, 3)."""
        geo = self.geom
        cx, cy = -pivot_x, geo.ankle_height_m           # ankle relative to the pivot, foot frame
        c, s = np.cos(theta), np.sin(theta)
        rx, ry = cx * c - cy * s, cx * s + cy * c        # rotated (heading-frame x, world up)
        h = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], -1)
        return pivot + h * rx[..., None] + np.array([0.0, 0.0, 1.0]) * ry[..., None]

    def _sole_point(self, fp_pos, fp_psi, x):
        """World position of sole point ``x`` (foot x) of a flat footprint (ankle at ``fp_pos``)."""
        h = np.stack([np.cos(fp_psi), np.sin(fp_psi), np.zeros_like(fp_psi)], -1)
        return fp_pos + h * x + np.array([0.0, 0.0, -self.geom.ankle_height_m])

    def _toe_rate_peak(self, theta_to):
        """Plantarflexion rate at toe-off (rad/s): the toe-rocker rate rises (quintic) over the first
        ``TOE_RISE`` of the pre-swing and stays at its peak until toe-off."""
        return theta_to / (self.gait.preswing_frac * self.gait.stride_s * (1.0 - 0.5 * TOE_RISE))

    def _toe_rocker_pitch(self, theta_to, u):
        """Pitch over the toe rocker (u = 0 heel-off .. 1 toe-off)."""
        v = np.clip(u, 0.0, 1.0) / TOE_RISE
        area = np.where(v < 1.0, TOE_RISE * _smoothstep_integral(v), TOE_RISE * (0.5 + (v - 1.0)))
        return theta_to * area / (1.0 - 0.5 * TOE_RISE)

    def _swing_pitch(self, theta_to, theta_hs, dt, dur):
        """Swing pitch at ``dt`` s after toe-off (sum of three C3 pieces): the toe-off plantarflexion rate stops
        within ``TOE_OFF_STOP_S`` (quintic in the rate, its onset at toe-off), a septic dorsiflexion brings the
        foot level, and an overlapping septic rise (a stretched mirror image of the heel rocker) raises it to
        ``theta_hs`` at IC: zero rate and the heel rocker's curvature at IC (a pitch peak at the heel strike)."""
        w0 = self._toe_rate_peak(theta_to)
        stop = np.minimum(TOE_OFF_STOP_S, 0.3 * dur)
        v = np.clip(dt / stop, 0.0, 1.0)
        fall = np.where(dt < stop, v - _smoothstep_integral(v), 0.5)
        th_stop = theta_to + 0.5 * w0 * stop
        t_load = self.gait.load_frac * self.gait.stride_s
        d2 = SWING_PULSE_START * stop
        t_rise = np.minimum(SWING_RISE * dur, RISE_MAX * t_load)
        end = np.maximum(dur - SWING_OVERLAP * t_rise, d2 + 2.0 * stop)
        level = smoothstep7((dt - d2) / (end - d2))
        curv = HS_CURV * (t_rise / t_load) ** 2          # same pitch curvature at IC as the heel rocker's
        rise = 1.0 - hermite7((dur - dt) / t_rise, (0.0, 0.0, curv, 0.0, 1.0, 0.0, 0.0, 0.0))
        return theta_to + w0 * stop * fall - th_stop * level + theta_hs * rise

    def foot(self, side: str, t):
        """Ankle position (N, 3), heading ψ (N,), pitch θ (N,) of one foot."""
        sch = self.schedules[side]
        geo, g = self.geom, self.gait
        T = g.stride_s
        t_load, t_pre = g.load_frac * T, g.preswing_frac * T
        t = np.asarray(t, dtype=float)
        n = t.shape[0]
        pos = np.empty((n, 3))
        psi = np.empty(n)
        theta = np.zeros(n)
        K = sch.n_steps
        if K == 0:
            pos[:] = sch.fp_pos[0]
            psi[:] = sch.fp_psi[0]
            return pos, psi, theta
        b = np.stack([sch.ho, sch.tc, sch.ic, sch.ff], 1).ravel()
        j = np.searchsorted(b, t, side="right")
        # flat phases: j == 0 (footprint 0) or (j-1) % 4 == 3 (footprint k+1)
        k = np.maximum(j - 1, 0) // 4
        r = np.where(j == 0, -1, (j - 1) % 4)
        flat = (r == -1) | (r == 3)
        fp_idx = np.where(r == -1, 0, k + 1)
        pos[flat] = sch.fp_pos[fp_idx[flat]]
        psi[flat] = sch.fp_psi[fp_idx[flat]]
        # toe rocker (footprint k): rotation about the fixed ball of the foot
        m = r == 0
        if np.any(m):
            kk = k[m]
            th = self._toe_rocker_pitch(sch.theta_to[kk], (t[m] - sch.ho[kk]) / t_pre)
            ball = self._sole_point(sch.fp_pos[kk], sch.fp_psi[kk], geo.ball_x_m)
            pos[m], psi[m], theta[m] = self._about(ball, sch.fp_psi[kk], geo.ball_x_m, th), sch.fp_psi[kk], th
        # heel rocker (footprint k+1): rotation about the fixed heel, pitch peak (zero rate) at IC
        m = r == 2
        if np.any(m):
            kk = k[m]
            th = sch.theta_hs[kk] * (1.0 - _heel_rocker_profile((t[m] - sch.ic[kk]) / t_load))
            heel = self._sole_point(sch.fp_pos[kk + 1], sch.fp_psi[kk + 1], geo.heel_x_m)
            pos[m], psi[m], theta[m] = self._about(heel, sch.fp_psi[kk + 1], geo.heel_x_m, th), sch.fp_psi[kk + 1], th
        # swing k: footprint k -> k+1
        m = r == 1
        if np.any(m):
            pos[m], psi[m], theta[m] = self._swing(side, sch, k[m], t[m])
        return pos, psi, theta

    def _swing(self, side, sch, kk, tt):
        """Swing of steps ``kk`` at times ``tt``: two contact tracks, blended in mid-swing.

        Ball track: the ball of the foot leaves its toe-off position along a path whose derivatives (up to
        the 4th) vanish at toe-off, the ankle follows from the pitch (rotation about the moving ball);
        heel track: likewise the heel arrives at its IC position. The ankle is the ball-track ankle early in
        swing, the heel-track ankle late in swing, a septic blend in between. So the foot motion near both
        contacts is the rocker's own (C3 joins, no contact point below the floor) whatever the pitch does.
        """
        geo, g = self.geom, self.gait
        ah = geo.ankle_height_m
        L = geo.ball_x_m - geo.heel_x_m
        dur = sch.ic[kk] - sch.tc[kk]
        dt = tt - sch.tc[kk]
        tau = dt / dur
        th_to, th_hs = sch.theta_to[kk], sch.theta_hs[kk]
        th = self._swing_pitch(th_to, th_hs, dt, dur)
        ps0, ps1 = sch.fp_psi[kk], sch.fp_psi[kk + 1]
        ps = ps0 + (ps1 - ps0) * smoothstep7(tau)
        ez = np.array([0.0, 0.0, 1.0])
        h0 = np.stack([np.cos(ps0), np.sin(ps0), np.zeros_like(ps0)], -1)
        h1 = np.stack([np.cos(ps1), np.sin(ps1), np.zeros_like(ps1)], -1)
        ball0 = self._sole_point(sch.fp_pos[kk], ps0, geo.ball_x_m)
        heel1 = self._sole_point(sch.fp_pos[kk + 1], ps1, geo.heel_x_m)
        ball_ic = heel1 + h1 * (L * np.cos(th_hs))[:, None] + ez * (L * np.sin(th_hs))[:, None]
        heel_to = ball0 - h0 * (L * np.cos(th_to))[:, None] - ez * (L * np.sin(th_to))[:, None]
        d_b, d_h = ball_ic - ball0, heel1 - heel_to
        d_b[:, 2] = 0.0           # the ball track stays low (toe clearance from ``lift``); the heel track takes over
        # ankle velocity at toe-off (rotation about the ball at the toe-off plantarflexion rate)
        w0 = self._toe_rate_peak(th_to)
        cx, cy = -geo.ball_x_m, ah
        rx, ry = cx * np.cos(th_to) - cy * np.sin(th_to), cx * np.sin(th_to) + cy * np.cos(th_to)
        v_to = h0 * (-ry * w0)[:, None] + ez * (rx * w0)[:, None]
        v_ic = h1 * (HEEL_APPROACH * g.speed_m_s)
        # progression variable: its rate ramps up over the toe-off pitch stop (the ball takes over the ankle's
        # velocity as the foot stops rotating about it) and down over SWING_RAMP1 before IC (zero derivatives
        # up to the 3rd at both contacts); quintic Hermite paths in it, same end velocities for both tracks
        stop = np.minimum(TOE_OFF_STOP_S, 0.3 * dur)
        d0, d1 = stop / dur, SWING_RAMP1
        x = d0 * _ramp5(tau / d0) - d1 * _smoothstep7_integral((tau - (1.0 - d1)) / d1)
        X = 1.0 - 0.5 * (d0 + d1)
        xs = (x / X)[:, None]
        x3 = xs ** 3
        h01 = x3 * (10.0 + xs * (-15.0 + 6.0 * xs))             # quintic Hermite basis (zero end curvature)
        h10 = xs + x3 * (-6.0 + xs * (8.0 - 3.0 * xs))
        h11 = x3 * (-4.0 + xs * (7.0 - 3.0 * xs))
        m0 = v_to * (X * dur)[:, None]
        m1 = v_ic * (X * dur)[:, None]
        lift = sch.clearance[kk] * bump4(tau)
        sign = 1.0 if side == "right" else -1.0
        pm = 0.5 * (ps0 + ps1)
        outward = np.stack([np.sin(pm), -np.cos(pm), np.zeros_like(pm)], -1) * sign
        extra = ez * lift[:, None] + outward * (sch.circumduction[kk] * bump4(tau))[:, None]
        pb = ball0 + d_b * h01 + m0 * h10 + m1 * h11 + extra
        ph = heel1 - d_h * (1.0 - h01) + m0 * h10 + m1 * h11 + extra
        a_b = self._about(pb, ps, geo.ball_x_m, th)
        a_h = self._about(ph, ps, geo.heel_x_m, th)
        w = smoothstep7((tau - BLEND[0]) / (BLEND[1] - BLEND[0]))[:, None]
        return a_b + w * (a_h - a_b), ps, th

    @staticmethod
    def foot_rotation(psi, theta):
        return heading_frame(psi) @ rot_z(theta)

    # -- pelvis
    def _swing_bumps(self, side, t):
        sch = self.schedules[side]
        out = np.zeros_like(t)
        for a, b in zip(sch.tc, sch.ic):
            out += bump((t - a) / (b - a))
        return out

    def pelvis(self, t, ankles):
        """Pelvis origin (N, 3) and rotation (N, 3, 3); ``ankles`` = {side: ankle positions}."""
        g, geo, plan = self.gait, self.geom, self.plan
        t = np.asarray(t, dtype=float)
        E = self.walk_envelope(t)
        s = self.pelvis_arc(t)
        psi_path = plan.path.heading(s)
        xy = plan.path.xy(s)
        ph = 2.0 * np.pi * (t - self._ic_r0) / g.stride_s
        lat = -g.pelvis_lateral_m * E * np.cos(ph - 0.6 * np.pi)
        n = np.stack([-np.sin(psi_path), np.cos(psi_path)], -1)
        xy = xy + n * lat[:, None]
        yaw = psi_path + g.pelvis_rotation * E * np.cos(ph)
        obl = -g.pelvis_obliquity * E * np.cos(ph - 0.3 * np.pi)
        if g.paretic_side is not None and g.hip_hike > 0:
            obl = obl + (1.0 if g.paretic_side == "left" else -1.0) * g.hip_hike * self._swing_bumps(g.paretic_side, t)
        tilt = g.pelvis_tilt * E * np.cos(2.0 * ph)
        R = heading_frame(yaw) @ rot_z(tilt) @ rot_x(obl)
        z_stand = geo.ankle_height_m + self.l_max
        z_nom = z_stand - E * (g.pelvis_drop_m - g.pelvis_vertical_m * np.cos(2.0 * (ph - 0.6 * np.pi)))
        zs = [z_nom]
        for side, sign in (("right", 1.0), ("left", -1.0)):
            off = R[:, :, 2] * (sign * 0.5 * geo.hip_width_m)
            hip_xy = xy + off[:, :2]
            a = ankles[side]
            dxy2 = np.sum((hip_xy - a[:, :2]) ** 2, axis=1)
            zs.append(a[:, 2] + np.sqrt(np.maximum(self.l_max ** 2 - dxy2, 1e-6)) - off[:, 2])
        if self._z_spline is None:
            z = np.stack(zs, 0).min(0)
        else:
            z = self._z_spline(t)
        pos = np.concatenate([xy, z[:, None]], 1)
        return pos, R, E, ph

    # -- whole body
    def poses(self, t) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """{segment: (origin position (N, 3) m ENU, rotation segment->ENU (N, 3, 3))}."""
        t = np.asarray(t, dtype=float)
        geo, g = self.geom, self.gait
        feet = {side: self.foot(side, t) for side in SIDES}
        ankles = {side: feet[side][0] for side in SIDES}
        p_pel, R_pel, E, ph = self.pelvis(t, ankles)
        out = {"pelvis": (p_pel, R_pel)}
        for side, sign in (("right", 1.0), ("left", -1.0)):
            A, psi_f, th_f = feet[side]
            R_f = self.foot_rotation(psi_f, th_f)
            H = p_pel + R_pel[:, :, 2] * (sign * 0.5 * geo.hip_width_m)
            d = A - H
            dist = np.linalg.norm(d, axis=1)
            u = d / dist[:, None]
            # the knee flexes in the plane of the walking direction: the foot's toe-out is tibial torsion
            # (a constant ankle rotation), not a rotation of the thigh/shank flexion axes
            f = self.foot_rotation(psi_f + sign * g.side(side).toe_out, th_f)[:, :, 0]
            nvec = _unit(f - np.sum(f * u, 1)[:, None] * u)
            L1, L2 = geo.thigh_m, geo.shank_m
            a = (L1 ** 2 - L2 ** 2 + dist ** 2) / (2.0 * dist)
            bb = np.sqrt(np.maximum(L1 ** 2 - a ** 2, 0.0))
            K = H + u * a[:, None] + nvec * bb[:, None]
            out[f"thigh_{side}"] = (H, _frame_from_y_and_forward((H - K) / L1, nvec))
            out[f"shank_{side}"] = (K, _frame_from_y_and_forward((K - A) / L2, nvec))
            out[f"foot_{side}"] = (A, R_f)
        for w in self.plan.hip_windows:
            self._apply_hip_window(w, t, out)
        # trunk: counter-rotates the pelvis, leans forward while walking
        yaw_rel = -0.5 * g.pelvis_rotation * E * np.cos(ph)
        R_tr = R_pel @ rot_y(yaw_rel) @ rot_z(-g.trunk_lean * E) @ rot_x(0.5 * g.pelvis_obliquity * E * np.cos(ph - 0.3 * np.pi))
        out["chest"] = (p_pel + R_tr[:, :, 1] * geo.trunk_m, R_tr)
        return out

    def _apply_hip_window(self, w: HipWindow, t, out):
        m = (t > w.t0) & (t < w.t1)
        if not np.any(m):
            return
        tt = t[m]
        ramp = 1.0
        env = smoothstep((tt - w.t0) / ramp) - smoothstep((tt - (w.t1 - ramp)) / ramp)
        osc = np.sin(2.0 * np.pi * w.reps * (tt - w.t0) / (w.t1 - w.t0))
        d_hip = np.deg2rad(12.0) * env + np.deg2rad(18.0) * env * osc
        d_knee = np.deg2rad(24.0) * env + np.deg2rad(6.0) * env * osc
        d_ank = -(d_hip - d_knee)                       # keeps the foot level
        self._bend_leg(out, w.side, m, rot_z(d_hip), d_knee, d_ank)

    def _bend_leg(self, out: dict, side: str, m, R_hip, d_knee, d_ank) -> None:
        """Rotate one leg's thigh by ``R_hip`` (thigh frame) about the hip, then add ``d_knee`` knee flexion
        and ``d_ank`` ankle rotation (rad, about the segments' z axes) to the walking pose, on samples ``m``;
        the chain (knee, ankle positions) follows."""
        geo = self.geom
        th_key, sh_key, ft_key = f"thigh_{side}", f"shank_{side}", f"foot_{side}"
        H, R_th = out[th_key][0][m], out[th_key][1][m]
        R_sh, R_ft = out[sh_key][1][m], out[ft_key][1][m]
        rel_knee = np.swapaxes(R_th, 1, 2) @ R_sh
        rel_ank = np.swapaxes(R_sh, 1, 2) @ R_ft
        R_th2 = R_th @ R_hip
        R_sh2 = R_th2 @ rel_knee @ rot_z(-d_knee)
        R_ft2 = R_sh2 @ rel_ank @ rot_z(d_ank)
        K2 = H - R_th2[:, :, 1] * geo.thigh_m
        A2 = K2 - R_sh2[:, :, 1] * geo.shank_m
        for key, val in ((th_key, (H, R_th2)), (sh_key, (K2, R_sh2)), (ft_key, (A2, R_ft2))):
            p_all, R_all = out[key]
            p_all = p_all.copy()
            R_all = R_all.copy()
            p_all[m], R_all[m] = val
            out[key] = (p_all, R_all)

    def sole_points(self, side: str, pos, R):
        """World heel, ball and toe-tip points of a foot pose."""
        geo = self.geom
        pts = {}
        for name, x in (("heel", geo.heel_x_m), ("ball", geo.ball_x_m), ("toe", geo.toe_tip_x_m)):
            pts[name] = pos + R @ np.array([x, -geo.ankle_height_m, 0.0])
        return pts


def _frame_from_y_and_forward(y, fwd):
    y = _unit(y)
    x = _unit(fwd - np.sum(fwd * y, 1)[:, None] * y)
    z = np.cross(x, y)
    return np.stack([x, y, z], -1)
