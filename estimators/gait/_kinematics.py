"""Foot kinematics of one foot (trajectory, events, strides) and the session parameters of both feet.

Per foot (``foot_kinematics``): ESKF + ZUPT + RTS trajectory (stridelab.estimators.trajectory) → stance runs and their
mid-stance samples (minimum |ω| in each run, gaitmap's ``min_vel``) → the foot's anterior axis in sensor
coordinates, found from the walk itself (mounting-agnostic, §K1) → pitch signal s = −sin(pitch) (thesis Eq. 52)
→ IC/TC by Algorithm 1 (with the flat-lift rule R4 on the zero-velocity samples) → events completed on the swings
of the zero-velocity mask (W0–W3, ``_swing``: flat lift, drop foot, flat/forefoot contact) → lifts that put the foot
down where it was dropped (R6, ``drop_in_place_steps``; ``FootParams.min_step_m``) → TCs refined from the pitch
minimum to the toe-off (T1, ``refine_toe_off``; batch only, ``FootParams.toe_off_refine``) → heel-strike ICs moved
from the pitch maximum into the loading rotation (H1, ``refine_heel_strike``; ``FootParams.heel_strike_fraction``)
→ ICs without a ground contact in the specific force dropped (R7, ``drop_contactless_ics``;
``FootParams.min_impact_m_s2``) → strides.

    K1  u_S = normalise( Σ_i R(q_{m_i})ᵀ d̂_i ),  d_i = horizontal displacement between consecutive mid-stances
        (only strides with |d_i| ≥ 0.2 m); fallback: sensor x when the walk has no such stride.
    K2  a stride = two consecutive mid-stances m_i < m_{i+1} with exactly one TC then one IC between them
        (gaitmap's min_vel stride); any other pattern is not a stride (no invented strides). K2b: a stride whose
        stride time IC − previous IC exceeds ``max_stride_time_s`` is discarded (spec §3.8); without a previous IC
        (out of quiet standing) the time from the end of its first stance run to m_{i+1} is used (the mid-stance
        of a long standing period is anywhere in it).
    K3  stride length = |p_xy(m_{i+1}) − p_xy(m_i)|; stride time = IC − previous IC (NaN without one);
        swing = IC − TC; stance = TC − previous IC; gait speed = length / stride time;
        clearance = max p_z over [TC, IC] − p_z(m_i) (height of the sensor point above its stance level);
        turning angle = change of the heading of R u_S between the two mid-stances (deg, + = to the left, ENU).
    K4  the foot trajectory itself (``foot_trajectory``: what the gait stage stores and scores) is the ESKF on the
        trajectory's own stance detector (``FootParams.trajectory_zupt``, default ``TRAJECTORY_ZUPT``), not on the
        events' mask (K0, ``GAIT_ZUPT``): each detector is the one its own cross-validation chose.
Session (``gait_session``):
    S1  cadence = 120 / mean stride time (steps/min, both feet);  S2  double support % = share of each stride
        (previous IC → IC) during which both feet are in stance (stance = IC → next TC of that foot);
    S3  symmetry index SI = 200 |L − R| / (L + R) % of the per-foot means (Robinson et al. 1987).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from dataclasses import replace

from stridelab.estimators.gait._events import (GaitEvents, IcTcParams, detect_ic_tc, pitch_signal, refine_heel_strike,
                                     refine_toe_off)
from stridelab.estimators.gait._swing import HEEL_STRIKER_FRACTION, complete_swing_events, heel_strike_fraction
from stridelab.estimators.trajectory import (TRAJECTORY_ZUPT, EskfParams, TrajectoryResult, ZuptParams,
                                            eskf_trajectory)

__all__ = ["FootParams", "StrideTable", "FootKinematics", "foot_kinematics", "foot_trajectory", "refine_events",
           "SessionGait",
           "gait_session", "gait_session_pooled", "foot_params_from_dict", "STRIDE_COLUMNS", "mid_stances"]

STRIDE_COLUMNS = ("start", "end", "tc", "ic", "pre_ic")
PARAM_COLUMNS = ("stride_length_m", "stride_time_s", "stance_time_s", "swing_time_s", "stance_pct", "swing_pct",
                 "gait_speed_m_s", "clearance_m", "turning_angle_deg")


#: the gait events' stance detector (``FootParams.trajectory.zupt``), pinned here so that a stance-detector value
#: chosen for the foot trajectory alone (``TRAJECTORY_ZUPT``) does not move the events (validation/provenance.toml)
GAIT_ZUPT = ZuptParams(min_stance_s=0.05)


@dataclass(frozen=True)
class FootParams:
    """Everything that configures ``foot_kinematics``.

    trajectory: ESKF/ZUPT/RTS parameters; their ``zupt`` is the stance detector of the events *and* of the
        trajectory the events and strides are measured on (``FootKinematics.trajectory``, one mask for both, K0).
        Default: the trajectory's shipped ``EskfParams`` with ``GAIT_ZUPT`` (the ``ZuptParams`` class defaults) as
        the stance detector, not the trajectory's own ``TRAJECTORY_ZUPT``: the trajectory's leave-one-trial-out on
        PyShoe chose a longer minimum stance (issue 43, fourth round) that the gait events' cross-validation
        (Voisard, gaitmap walk) did not.
    trajectory_zupt: the stance detector of the foot trajectory itself (``foot_trajectory``, K4: what the gait stage
        stores and scores): ``trajectory`` with this ``zupt``. Default ``TRAJECTORY_ZUPT``, so the stored trajectory
        is what ``stridelab bench trajectory`` scores as shipped (``EskfParams()``); None = the events' trajectory
        (``FootKinematics.trajectory``, the behaviour before).
    events: Algorithm 1 parameters; threshold T = −0.1 (≈ 5.7° toes down)
        instead of the thesis' −0.2, chosen by leave-one-group-out over the Voisard subjects and the gaitmap walk
        (``stridelab bench gait --voisard``, docs/gait.md); the streaming ``GaitEventDetector`` keeps −0.2.
    min_stride_length_m: strides shorter than this are not used to find the anterior axis (K1).
    max_stride_time_s: strides longer than this are dropped (spec §3.8: 3 s).
    toe_off_refine: move each Algorithm-1 TC (pitch minimum, thesis) back to the toe-off (T1 in ``_events``:
        onset of the plantarflexion deceleration); False = the thesis' plain TC. Flat-lift TCs (R4) are kept.
    toe_off_onset_fraction: f of (T1): 0.6 of the peak deceleration, chosen by leave-one-subject-out over the
        Voisard subjects and the gaitmap walk (the a-priori 0.2 put the toe-off 8 ms early on Voisard, 6 ms on the
        gaitmap walk; ``stridelab bench gait --voisard``, validation/provenance.toml).
    toe_off_window_s: W of (T1), 0.15 s (Algorithm 1's look-back window), a priori.
    swing_events: complete the events on the swings of the zero-velocity mask (W0–W3 in ``_swing``: flat lift,
        drop foot, flat-foot and forefoot contact); False = Algorithm 1 (+ R4) only.
    heel_strike_fraction: f of (H1) in ``_events.refine_heel_strike``: a heel-strike IC (a pitch maximum followed
        by a fall of the pitch) moves to the first sample where the toes-down rotation rate reaches f of its peak
        within ``heel_strike_window_s`` (the reference's heel strike, docs/gait.md "Which instant is initial
        contact"); None = the pitch maximum (the thesis' IC). Chosen by leave-one-subject-out over the Voisard
        subjects and the gaitmap walk (``stridelab bench gait --voisard``; validation/provenance.toml).
    heel_strike_window_s: W of (H1), 0.15 s as T1 (a priori).
    weak_push_off_steps: (R5) on heel-striking feet, a step whose push-off never passes T (the first step out of
        standing) is found after the fact: ``_weak_push_off_steps``. False = Algorithm 1 (+ R4) only.
    min_step_m: (R6, issue 43) a lift that puts the foot down where it was is no step: a TC → IC pair is dropped
        when the foot's horizontal displacement from the last stance sample at or before the TC to the first
        stance sample at or after the IC is below ``min_step_m`` (heel raise, weight shift or toe tap in place
        before the first step; on Voisard they moved the foot 4–13 mm, the shortest annotated step 5.5 cm).
        None = off. Chosen by leave-one-subject-out over the Voisard subjects and the gaitmap walk
        (``stridelab bench gait --voisard``; validation/provenance.toml).
    min_impact_m_s2: (R7, issue 43) an IC at which |f| stays within ``min_impact_m_s2`` of the sensor's own g from
        0.05 s before to 0.15 s after is no ground contact and is dropped (``drop_contactless_ics``: pivots, rocks
        and turns on the spot in U-turns that Algorithm 1 took for heel strikes). 1.0 m/s², chosen by
        leave-one-subject-out over the Voisard subjects and the gaitmap walk among the values that keep every
        matched IC of the training groups (validation/provenance.toml); None = off.
    """
    trajectory: EskfParams = EskfParams(zupt=GAIT_ZUPT)
    trajectory_zupt: ZuptParams | None = TRAJECTORY_ZUPT
    events: IcTcParams = IcTcParams(threshold=-0.1)
    min_stride_length_m: float = 0.2
    max_stride_time_s: float = 3.0
    toe_off_refine: bool = True
    toe_off_onset_fraction: float = 0.7
    toe_off_window_s: float = 0.15
    swing_events: bool = True
    heel_strike_fraction: float | None = 0.4
    heel_strike_window_s: float = 0.15
    weak_push_off_steps: bool = True
    min_step_m: float | None = 0.02
    min_impact_m_s2: float | None = 1.0


@dataclass(frozen=True)
class StrideTable:
    """Strides of one foot (K2, K3).

    idx: (S, 5) int64 sample indices, columns ``STRIDE_COLUMNS`` (start/end = mid-stances; pre_ic = −1 if none).
    values: (S, 9) float, columns ``PARAM_COLUMNS`` (SI units; NaN where undefined).
    """
    idx: np.ndarray
    values: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """One parameter column by name (``PARAM_COLUMNS``) or index column (``STRIDE_COLUMNS``)."""
        if name in PARAM_COLUMNS:
            return self.values[:, PARAM_COLUMNS.index(name)]
        return self.idx[:, STRIDE_COLUMNS.index(name)]

    def __len__(self) -> int:
        return int(self.idx.shape[0])


@dataclass(frozen=True)
class FootKinematics:
    """Result of ``foot_kinematics`` for one foot.

    trajectory: the ESKF result (pos, vel, quat, zupt).  pitch: (N,) s = −sin(pitch), NaN before the filter starts.
    anterior_axis: (3,) u_S in sensor coordinates.  mid_stance: (M,) int64 mid-stance samples.
    events: IC/TC.  strides: StrideTable.  status: "ok" | "no_stance" | "no_strides".  notes: human messages.
    """
    trajectory: TrajectoryResult
    pitch: np.ndarray
    anterior_axis: np.ndarray
    mid_stance: np.ndarray
    events: GaitEvents
    strides: StrideTable
    sampling_rate_hz: float
    status: str
    notes: tuple = field(default=())


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _mids(runs, w: np.ndarray) -> list[int]:
    """The sample of least angular rate ``w`` in each stance run (gaitmap's ``min_vel`` mid-stance)."""
    return [a + int(np.argmin(w[a:b])) for a, b in runs]


def mid_stances(stance: np.ndarray, gyr: np.ndarray) -> np.ndarray:
    """Mid-stance samples of a stance mask: in each run of ``stance`` the sample of least |ω| (``gyr`` (N, 3)
    rad/s; gaitmap's ``min_vel``), the points strides are cut at (:func:`foot_kinematics`)."""
    return np.array(_mids(_runs(np.asarray(stance, bool)), np.linalg.norm(np.asarray(gyr, float), axis=1)),
                    dtype=np.int64)


def _rot_T(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    from stridelab.estimators.quaternion import quat_to_matrix
    return quat_to_matrix(q).T @ v


def _empty_strides() -> StrideTable:
    return StrideTable(np.zeros((0, 5), np.int64), np.zeros((0, len(PARAM_COLUMNS))))


def _after_last(points: np.ndarray, x: np.ndarray, side: str) -> np.ndarray:
    """(len(x),) int64: 1 + the last of the sorted ``points`` before each ``x`` (at or before with side="right"),
    0 where there is none (also when ``points`` is empty)."""
    points = np.asarray(points, np.int64)
    k = np.searchsorted(points, x, side=side) - 1
    out = np.zeros(len(x), np.int64)
    has = k >= 0
    out[has] = points[k[has]] + 1
    return out


def _refine_tcs(ev: GaitEvents, gyr, traj: TrajectoryResult, mids, u, fs: float, params: FootParams) -> GaitEvents:
    """(T1) on the Algorithm-1 TCs (pitch minima: detection = extremum + 1); flat-lift TCs (R4) stay. The
    mediolateral axis m_S = up_S × u_S, up_S = mean sensor-frame vertical over the mid-stances."""
    ups = np.array([_rot_T(traj.quat[m], np.array([0.0, 0.0, 1.0])) for m in mids])
    up = ups.mean(axis=0)
    up /= np.linalg.norm(up)
    ml = np.cross(up, u)
    if not np.linalg.norm(ml) > 0.1:
        return ev
    alg1 = ev.tc_detect_idx == ev.tc_idx + 1
    still = np.flatnonzero(traj.zupt)
    # TC' stays after the last IC before the TC and after the last still sample at or before it; a sequence may
    # start with a TC (a recording starting mid-stance or mid-swing) or hold no IC at all: no bound then
    lo = np.maximum(_after_last(ev.ic_idx, ev.tc_idx, "left"), _after_last(still, ev.tc_idx, "right"))
    ref = refine_toe_off(gyr, ev.tc_idx, ml, sampling_rate_hz=fs, onset_fraction=params.toe_off_onset_fraction,
                         window_s=params.toe_off_window_s, lower_bound=lo)
    tc = np.where(alg1, ref, ev.tc_idx)
    return replace(ev, tc_idx=tc, tc_pitch_min_idx=ev.tc_idx.copy())


def _weak_push_off_steps(ev: GaitEvents, s: np.ndarray, fs: float, params: FootParams) -> GaitEvents:
    """(R5) batch, heel-striking feet: between an IC a and the next TC (or the end), a pitch maximum j (a local
    maximum after a + n_ref) that rises more than |T| above s_a, with a pitch minimum m in (a, j) at least |T| below
    s_j, is a step whose push-off was too weak for (R2) (s_m > T: the first step out of standing, after a weight
    shift that Algorithm 1 took for a step); strict alternation then blocked its heel strike. TC at m and IC at j
    are added (detections m + 1, j + 1, so T1 and H1 refine them). In ordinary walking s only falls from a heel
    strike to the stance level before the next push-off, so the rule cannot fire there. The rise |T| (≈ 6°) is the
    size of the threshold itself, a priori; applied once per interval."""
    p = ev.params
    n_ref = max(1, int(round(p.refractory_s * fs)))
    rise = abs(p.threshold)
    n = len(s)
    add_tc, add_ic = [], []
    for a in ev.ic_idx:
        later = ev.tc_idx[ev.tc_idx > a]
        b = int(later[0]) if len(later) else n - 1
        lo = int(a) + n_ref
        if b - lo < 3 or not np.isfinite(s[a]):
            continue
        seg = s[lo:b]
        if not np.all(np.isfinite(seg)):
            continue
        j = lo + int(np.argmax(seg))
        if not (lo < j < b - 1 and s[j] >= s[j - 1] and s[j] >= s[j + 1] and s[j] > p.threshold):
            continue
        if not s[j] > s[a] + rise:
            continue
        m = int(a) + 1 + int(np.argmin(s[a + 1:j]))
        if not s[m] < s[j] - rise:
            continue
        add_tc.append(m)
        add_ic.append(j)
    if not add_ic:
        return ev
    tc = np.concatenate([ev.tc_idx, add_tc]).astype(np.int64)
    tcd = np.concatenate([ev.tc_detect_idx, np.asarray(add_tc) + 1]).astype(np.int64)
    ic = np.concatenate([ev.ic_idx, add_ic]).astype(np.int64)
    icd = np.concatenate([ev.ic_detect_idx, np.asarray(add_ic) + 1]).astype(np.int64)
    ot, oi = np.argsort(tc, kind="stable"), np.argsort(ic, kind="stable")
    return replace(ev, tc_idx=tc[ot], tc_detect_idx=tcd[ot], ic_idx=ic[oi], ic_detect_idx=icd[oi])


def _refine_ics(ev: GaitEvents, gyr, traj: TrajectoryResult, mids, u, s, fs: float, params: FootParams) -> GaitEvents:
    """(H1) on the heel-strike ICs: pitch extrema (detection = extremum + 1) with the pitch falling after them; the
    refined IC stays before the next TC and the next mid-stance."""
    ups = np.array([_rot_T(traj.quat[m], np.array([0.0, 0.0, 1.0])) for m in mids])
    up = ups.mean(axis=0)
    up /= np.linalg.norm(up)
    ml = np.cross(up, u)
    ic = ev.ic_idx
    if not np.linalg.norm(ml) > 0.1 or not len(ic):
        return ev
    n = len(s)
    nxt = ic + 1
    falls = (ev.ic_detect_idx == nxt) & (nxt < n)
    falls[falls] = s[nxt[falls]] <= s[ic[falls]]
    hi = np.full(len(ic), n - 1, np.int64)
    for points in (ev.tc_idx, mids):
        k = np.searchsorted(np.asarray(points, np.int64), ic, side="right")
        has = k < len(points)
        hi[has] = np.minimum(hi[has], np.asarray(points, np.int64)[k[has]] - 1)
    ref = refine_heel_strike(gyr, ic, ml, sampling_rate_hz=fs, onset_fraction=params.heel_strike_fraction,
                             window_s=params.heel_strike_window_s, upper_bound=hi)
    return replace(ev, ic_idx=np.where(falls, ref, ic), ic_pitch_max_idx=ic.copy())


def drop_in_place_steps(ev: GaitEvents, pos: np.ndarray, stance: np.ndarray, min_step_m: float) -> GaitEvents:
    """(R6) ``ev`` without the TC → IC pairs whose step moves the foot less than ``min_step_m`` horizontally.

    The pair of an IC is the last TC before it with no IC in between; the step's displacement is
    |p_xy(first stance sample ≥ IC) − p_xy(last stance sample ≤ TC)| (``pos`` (N, 3) m, ``stance`` (N,) bool, the
    trajectory's zero-velocity samples). An IC without such a TC, or without a stance sample on either side, or
    with non-finite positions there, stays."""
    ic, tc = np.asarray(ev.ic_idx, np.int64), np.asarray(ev.tc_idx, np.int64)
    if not len(ic) or not len(tc):
        return ev
    still = np.flatnonzero(stance)
    if not len(still):
        return ev
    drop_ic, drop_tc = np.zeros(len(ic), bool), np.zeros(len(tc), bool)
    for i, x in enumerate(ic):
        j = int(np.searchsorted(tc, x, side="left")) - 1          # last TC before the IC
        if j < 0 or (i > 0 and ic[i - 1] > tc[j]):
            continue
        a = int(np.searchsorted(still, tc[j], side="right")) - 1
        b = int(np.searchsorted(still, x, side="left"))
        if a < 0 or b >= len(still):
            continue
        d = pos[still[b], :2] - pos[still[a], :2]
        if np.all(np.isfinite(d)) and float(np.hypot(d[0], d[1])) < min_step_m:
            drop_ic[i] = drop_tc[j] = True
    if not drop_ic.any():
        return ev
    kt, ki = ~drop_tc, ~drop_ic
    return replace(ev, ic_idx=ic[ki], ic_detect_idx=np.asarray(ev.ic_detect_idx)[ki], tc_idx=tc[kt],
                   tc_detect_idx=np.asarray(ev.tc_detect_idx)[kt])


#: (R7) the window around an IC in which a ground contact must show in the specific force: 0.05 s before (the
#: H1-refined IC may sit a few samples after the first touch) to 0.15 s after (loading response ≈ 0–10 % of a
#: ≥ 1.2 s stride, Perry & Burnfield), a priori
CONTACT_WINDOW_S = (0.05, 0.15)


def drop_contactless_ics(ev: GaitEvents, acc: np.ndarray, *, gravity_m_s2: float,
                         sampling_rate_hz: float, min_impact_m_s2: float,
                         window_s: tuple[float, float] = CONTACT_WINDOW_S) -> GaitEvents:
    """(R7) ``ev`` without the ICs at which nothing touches the ground.

        D(IC) = max over k in [IC − w₁, IC + w₂] of | |f_k| − g_s |        (f = specific force, g_s = the sensor's
                                                                          own reading at rest, ``gravity_m_s2``)
        IC dropped when D(IC) < A_min (``min_impact_m_s2``)

    Physics: a foot that lands is decelerated by the ground within a few tens of ms (heel-strike transient;
    walking heel strikes give 15–60 m/s² on Voisard et al.'s foot IMUs, and even 0.1 m/s stopped within 0.1 s
    gives 1 m/s²), so |f| departs from g. A pitch maximum that Algorithm 1 (or H1) takes for a heel strike while
    the foot rocks or pivots on the spot, or turns in the air without coming down (the U-turns of Voisard et al.:
    lifts, pivots, shuffles), has |f| within a few tenths of g: no mass was stopped, so there was no contact.
    A_min is bounded below by the stance noise of | |f| − g_s | (≈ 0.1 m/s²) and above by the softest real
    landing (on Voisard the lowest D of a matched heel strike is 1.37 m/s², docs/gait.md "U-turns").
    Only ICs are dropped: the TC before a dropped IC stays (the foot did leave the ground; its landing was missed
    or mistimed), and so does the TC after it (on Voisard such a false IC is mostly a pitch maximum while the foot
    pivots on the ground after an unseen landing, and the next TC is its real take-off; dropping it too lost two
    real toe-offs for one false one). Non-finite windows keep the IC."""
    ic = np.asarray(ev.ic_idx, np.int64)
    if not len(ic):
        return ev
    fs = float(sampling_rate_hz)
    dev = np.abs(np.linalg.norm(np.asarray(acc, float), axis=1) - float(gravity_m_s2))
    n = len(dev)
    w1, w2 = int(round(window_s[0] * fs)), int(round(window_s[1] * fs))
    drop_ic = np.zeros(len(ic), bool)
    for i, x in enumerate(ic):
        seg = dev[max(int(x) - w1, 0):min(int(x) + w2 + 1, n)]
        if len(seg) and np.all(np.isfinite(seg)) and float(seg.max()) < min_impact_m_s2:
            drop_ic[i] = True
    if not drop_ic.any():
        return ev
    ki = ~drop_ic
    return replace(ev, ic_idx=ic[ki], ic_detect_idx=np.asarray(ev.ic_detect_idx)[ki],
                   ic_pitch_max_idx=None if ev.ic_pitch_max_idx is None else np.asarray(ev.ic_pitch_max_idx)[ki])


def _refine(ev: GaitEvents, gyr, traj: TrajectoryResult, mids, u, s, fs: float, params: FootParams,
            acc=None) -> GaitEvents:
    """The batch refinements of the events: R6 (in-place lifts dropped), T1 (toe-off), H1 (heel strike) then R7
    (contactless ICs dropped), as ``params`` asks."""
    if params.min_step_m is not None and params.min_step_m > 0:
        ev = drop_in_place_steps(ev, traj.pos, traj.zupt, params.min_step_m)
    if params.toe_off_refine and len(ev.tc_idx):
        ev = _refine_tcs(ev, gyr, traj, mids, u, fs, params)
    if params.heel_strike_fraction is not None and len(ev.ic_idx):
        ev = _refine_ics(ev, gyr, traj, mids, u, s, fs, params)
    if params.min_impact_m_s2 is not None and params.min_impact_m_s2 > 0 and len(ev.ic_idx):
        if acc is None:
            raise ValueError("FootParams.min_impact_m_s2 (R7) needs the accelerometer: pass acc=")
        ev = drop_contactless_ics(ev, acc, gravity_m_s2=traj.sensor_gravity_m_s2, sampling_rate_hz=fs,
                                  min_impact_m_s2=params.min_impact_m_s2)
    return ev


def refine_events(fk: "FootKinematics", gyr: np.ndarray, params: FootParams, *,
                  acc: np.ndarray | None = None) -> GaitEvents:
    """The events ``foot_kinematics(gyr, acc, …, params=params)`` returns, from a result ``fk`` computed with the
    same parameters but the refinements off (``toe_off_refine=False, heel_strike_fraction=None, min_step_m=None,
    min_impact_m_s2=None``): R6, T1, H1 and R7 are the last steps and touch nothing else, so a bench can score
    several settings from one ESKF run. ``acc`` is needed when ``params.min_impact_m_s2`` is set (R7)."""
    if fk.events.tc_pitch_min_idx is not None or fk.events.ic_pitch_max_idx is not None:
        raise ValueError("refine_events needs a FootKinematics computed with both refinements off")
    if fk.status == "no_stance":
        return fk.events
    return _refine(fk.events, gyr, fk.trajectory, fk.mid_stance, fk.anterior_axis, fk.pitch, fk.sampling_rate_hz,
                   params, acc)


def _anterior_axis(traj: TrajectoryResult, runs, w, fs: float, params: FootParams):
    """K1 over the mid-stances of ``runs``; (u_S, found) with u_S = sensor x when no stride is long enough."""
    mids = _mids(runs, w)
    us = []
    for a, b in zip(mids[:-1], mids[1:]):
        d = traj.pos[b] - traj.pos[a]
        d[2] = 0.0
        L = np.linalg.norm(d)
        if np.isfinite(L) and L >= params.min_stride_length_m and (b - a) <= params.max_stride_time_s * fs:
            us.append(_rot_T(traj.quat[a], d / L))
    if not us:
        return np.array([1.0, 0.0, 0.0]), False
    u = np.sum(us, axis=0)
    return u / np.linalg.norm(u), True


def foot_kinematics(gyr: np.ndarray, acc: np.ndarray, *, sampling_rate_hz: float,
                    params: FootParams = FootParams()) -> FootKinematics:
    """All kinematics of one foot IMU (module docstring K1–K3). gyr rad/s, acc m/s², any mounting."""
    fs = float(sampling_rate_hz)
    notes: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        traj = eskf_trajectory(gyr, acc, sampling_rate_hz=fs, params=params.trajectory)
    n = traj.pos.shape[0]
    empty_ev = GaitEvents(*(np.zeros(0, np.int64) for _ in range(4)), params=params.events)
    if traj.status != "ok":
        notes.append("no stance (zero-velocity) period detected: sensor not on a foot, shuffling or running?")
        return FootKinematics(traj, np.full(n, np.nan), np.array([1.0, 0, 0]), np.zeros(0, np.int64), empty_ev,
                              _empty_strides(), fs, "no_stance", tuple(notes))
    w = np.linalg.norm(np.asarray(gyr, float), axis=1)
    stance = traj.zupt
    u, ok = _anterior_axis(traj, _runs(stance), w, fs, params)
    s0 = pitch_signal(traj.quat, u)
    ev0 = detect_ic_tc(s0, sampling_rate_hz=fs, params=params.events, stance=traj.zupt)
    swing_rules = params.swing_events and not (heel_strike_fraction(
        ev0, s0, traj.zupt, sampling_rate_hz=fs, max_swing_s=params.max_stride_time_s) >= HEEL_STRIKER_FRACTION)
    if swing_rules:
        # K0: a still run shorter than n_ref with the toes down (its pitch more than M below the level of the runs
        # >= n_ref) is no stance: a slow swing can pause in the air (after the lift, before a toes-down landing).
        # Stances, mid-stances, the anterior axis and the trajectory (ESKF rerun with that mask) then come from the
        # other runs.
        n_ref = max(1, int(round(params.events.refractory_s * fs)))
        runs = _runs(stance)
        long_runs = [(a, b) for a, b in runs if b - a >= n_ref]
        if long_runs:
            level = float(np.nanmedian(np.concatenate([s0[a:b] for a, b in long_runs])))
            stance = np.zeros(n, bool)
            for a, b in runs:
                if b - a >= n_ref or float(np.nanmedian(s0[a:b])) >= level - params.events.flat_lift_margin:
                    stance[a:b] = True
            if not np.array_equal(stance, traj.zupt):          # no zero-velocity update in those pauses either
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    traj = eskf_trajectory(gyr, acc, sampling_rate_hz=fs, params=params.trajectory, zupt=stance)
                u, ok = _anterior_axis(traj, _runs(stance), w, fs, params)
    if not ok:
        notes.append("no stride long enough to find the foot's anterior axis; assumed sensor x points to the toes")
    mids = np.array(_mids(_runs(stance), w), dtype=np.int64)
    s = pitch_signal(traj.quat, u) if swing_rules else s0
    ev = detect_ic_tc(s, sampling_rate_hz=fs, params=params.events, stance=traj.zupt) if swing_rules else ev0
    if swing_rules:
        ev = complete_swing_events(ev, s, stance, sampling_rate_hz=fs, max_swing_s=params.max_stride_time_s,
                                   gyr_norm=w)
    elif params.weak_push_off_steps:
        ev = _weak_push_off_steps(ev, s, fs, params)
    ev = _refine(ev, gyr, traj, mids, u, s, fs, params, acc)
    # K2, K3
    idx_rows, val_rows = [], []
    heading = None
    run_end = dict(zip(mids.tolist(), (b for _a, b in _runs(stance))))       # mid-stance -> end of its stance
    for a, b in zip(mids[:-1], mids[1:]):
        tcs = ev.tc_idx[(ev.tc_idx > a) & (ev.tc_idx < b)]
        ics = ev.ic_idx[(ev.ic_idx > a) & (ev.ic_idx < b)]
        if len(tcs) != 1 or len(ics) != 1 or not tcs[0] < ics[0]:
            continue
        tc, ic = int(tcs[0]), int(ics[0])
        prev = ev.ic_idx[ev.ic_idx <= a]
        pre_ic = int(prev[-1]) if len(prev) and (ic - prev[-1]) <= params.max_stride_time_s * fs else -1
        # K2b (spec §3.8): discard strides longer than max_stride_time_s, stride time = IC − previous IC; a stride
        # without a previous IC in time (the first step out of quiet standing) is timed from leaving its stance
        if pre_ic < 0 and (b - run_end.get(int(a), a)) > params.max_stride_time_s * fs:
            continue
        d = traj.pos[b] - traj.pos[a]
        length = float(np.hypot(d[0], d[1]))
        stride_t = (ic - pre_ic) / fs if pre_ic >= 0 else np.nan
        stance_t = (tc - pre_ic) / fs if pre_ic >= 0 else np.nan
        swing_t = (ic - tc) / fs
        clearance = float(np.nanmax(traj.pos[tc:ic + 1, 2]) - traj.pos[a, 2])
        from stridelab.estimators.quaternion import quat_rotate
        ha, hb = quat_rotate(traj.quat[a], u), quat_rotate(traj.quat[b], u)
        turn = np.degrees(np.angle(np.exp(1j * (np.arctan2(hb[1], hb[0]) - np.arctan2(ha[1], ha[0])))))
        idx_rows.append((a, b, tc, ic, pre_ic))
        val_rows.append((length, stride_t, stance_t, swing_t, 100 * stance_t / stride_t, 100 * swing_t / stride_t,
                         length / stride_t, clearance, turn))
    strides = StrideTable(np.array(idx_rows, np.int64).reshape(-1, 5),
                          np.array(val_rows, float).reshape(-1, len(PARAM_COLUMNS))) if idx_rows else _empty_strides()
    status = "ok" if len(strides) else "no_strides"
    if not len(strides):
        notes.append(f"{len(mids)} stance period(s) but no complete stride (stance, TC, IC, stance)")
    return FootKinematics(traj, s, u, mids, ev, strides, fs, status, tuple(notes))


def foot_trajectory(gyr: np.ndarray, acc: np.ndarray, fk: FootKinematics, *, sampling_rate_hz: float,
                    params: FootParams = FootParams()) -> TrajectoryResult:
    """(K4) The foot trajectory on its own stance detector: ``eskf_trajectory`` with ``params.trajectory`` and
    ``zupt = params.trajectory_zupt`` (no K0: the events' rule for slow-swing pauses is theirs), i.e. with the
    defaults exactly ``eskf_trajectory(gyr, acc, params=EskfParams())``, what ``stridelab bench trajectory``
    scores. ``fk`` is ``foot_kinematics`` of the same arrays with the same ``params``: its trajectory is returned
    as it is when ``trajectory_zupt`` is None, and reused (no second filter run) when the two detectors give the
    same stance mask (``eskf_trajectory(reuse=…)``). The events and strides stay on ``fk.trajectory``."""
    if params.trajectory_zupt is None:
        return fk.trajectory
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return eskf_trajectory(gyr, acc, sampling_rate_hz=sampling_rate_hz,
                               params=replace(params.trajectory, zupt=params.trajectory_zupt), reuse=fk.trajectory)


@dataclass(frozen=True)
class SessionGait:
    """Session parameters from both feet (S1–S3); NaN where a foot has no strides.

    cadence_steps_min, gait_speed_m_s, stride_length_m, stride_time_s: session means (both feet).
    double_support_pct: mean over strides of both feet (S2).
    per_foot: {"left"|"right": {param: mean, "double_support_pct", "cadence_steps_min"}};
    symmetry_index_pct: {param: SI} (S3).  n_strides: {"left": int, "right": int}.
    pooled: {param: mean over the strides of both feet} for every ``PARAM_COLUMNS`` entry.
    """
    cadence_steps_min: float
    gait_speed_m_s: float
    stride_length_m: float
    stride_time_s: float
    double_support_pct: float
    per_foot: dict
    symmetry_index_pct: dict
    n_strides: dict
    pooled: dict = field(default_factory=dict)


def _stance_mask(fk: FootKinematics, n: int) -> np.ndarray:
    m = np.zeros(n, bool)
    for ic in fk.events.ic_idx:
        nxt = fk.events.tc_idx[fk.events.tc_idx > ic]
        if len(nxt) and nxt[0] - ic < 3 * fk.sampling_rate_hz:
            m[ic:nxt[0] + 1] = True
    return m


def gait_session(left: FootKinematics, right: FootKinematics) -> SessionGait:
    """Session parameters of a recording with both feet on the same sample grid (S1–S3)."""
    if left.sampling_rate_hz != right.sampling_rate_hz:
        raise ValueError("left and right feet must share one sample grid (resample first)")
    return gait_session_pooled([(left, right)])


def gait_session_pooled(trials) -> SessionGait:
    """Session parameters (S1–S3) pooled over several trials (walking trials of one lab session, or the
    contiguous segments of one recording).

    ``trials``: sequence of ``(left, right)`` pairs of :class:`FootKinematics`; either may be ``None`` (foot
    missing). Per-foot means pool the strides of every trial; double support (S2) is only computed for pairs
    with both feet (same sample grid). Equals :func:`gait_session` for a single pair.
    """
    feet = {"left": [], "right": []}
    ds = {"left": [], "right": []}
    for left, right in trials:
        if left is not None and right is not None:
            if left.sampling_rate_hz != right.sampling_rate_hz:
                raise ValueError("left and right feet of a trial must share one sample grid (resample first)")
            n = max(len(left.pitch), len(right.pitch))
            both = _stance_mask(left, n) & _stance_mask(right, n)
            for side, fk in (("left", left), ("right", right)):
                for pre, ic in zip(fk.strides.column("pre_ic"), fk.strides.column("ic")):
                    if pre >= 0:
                        ds[side].append(100.0 * both[pre:ic].mean())
        for side, fk in (("left", left), ("right", right)):
            if fk is not None and len(fk.strides):
                feet[side].append(fk.strides)

    def values(tables, c):
        v = np.concatenate([t.column(c) for t in tables]) if tables else np.zeros(0)
        return v[np.isfinite(v)]

    per_foot = {}
    for side in ("left", "right"):
        per_foot[side] = {}
        for c in PARAM_COLUMNS:
            v = values(feet[side], c)
            per_foot[side][c] = float(v.mean()) if len(v) else float("nan")
        per_foot[side]["double_support_pct"] = float(np.mean(ds[side])) if ds[side] else float("nan")
        t = per_foot[side]["stride_time_s"]
        per_foot[side]["cadence_steps_min"] = 120.0 / t if np.isfinite(t) and t > 0 else float("nan")
    allst = feet["left"] + feet["right"]

    def pooled(c):
        v = values(allst, c)
        return float(v.mean()) if len(v) else float("nan")
    stride_t = pooled("stride_time_s")
    si = {}
    for c in ("stride_length_m", "stride_time_s", "stance_pct", "swing_time_s", "clearance_m"):
        a, b = per_foot["left"][c], per_foot["right"][c]
        si[c] = float(200.0 * abs(a - b) / (a + b)) if np.isfinite(a) and np.isfinite(b) and (a + b) else float("nan")
    ds_all = ds["left"] + ds["right"]
    return SessionGait(cadence_steps_min=120.0 / stride_t if np.isfinite(stride_t) else float("nan"),
                       gait_speed_m_s=pooled("gait_speed_m_s"), stride_length_m=pooled("stride_length_m"),
                       stride_time_s=stride_t,
                       double_support_pct=float(np.mean(ds_all)) if ds_all else float("nan"),
                       per_foot=per_foot, symmetry_index_pct=si,
                       n_strides={s: int(sum(len(t) for t in feet[s])) for s in ("left", "right")},
                       pooled={c: pooled(c) for c in PARAM_COLUMNS})


def foot_params_from_dict(d: dict) -> FootParams:
    """:class:`FootParams` from its ``dataclasses.asdict`` form (nested dicts; e.g. a stage's JSON params).
    Unknown keys raise ``TypeError`` (a misspelt manifest key must not be silently ignored)."""
    d = dict(d)
    traj = dict(d.pop("trajectory", {}))
    defaults = FootParams()                                # missing keys keep the gait defaults (GAIT_ZUPT, T = -0.1)
    zupt = replace(defaults.trajectory.zupt, **traj.pop("zupt", {}))
    if d.get("trajectory_zupt") is not None:              # missing keys keep TRAJECTORY_ZUPT; None stays None
        d["trajectory_zupt"] = replace(TRAJECTORY_ZUPT, **d["trajectory_zupt"])
    return FootParams(trajectory=replace(defaults.trajectory, **traj, zupt=zupt),
                      events=replace(defaults.events, **d.pop("events", {})), **d)
