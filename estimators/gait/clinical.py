"""Clinical gait measures of one session from both feet: steps, phases, asymmetry, variability, uncertainty.

What stroke-rehabilitation clinicians read (docs/clinical_measures.md has the definitions with references and
normative bands). Everything is computed from the events and strides of :func:`stridelab.estimators.gait.foot_kinematics`
(times in seconds, positions in metres); no I/O.

Per stride of foot X (previous IC ``a`` → TC_X → IC ``b``; the other foot Y):

    C1  contralateral events: IC_Y = the only IC of Y in (a, b); TC_Y = the only TC of Y in (a, IC_Y).
        Missing or extra contralateral events, or the order a < TC_Y < IC_Y < TC_X < b violated: the step
        measures of that stride are NaN (never guessed), ``reason`` says why.
    C2  step time X = b − IC_Y (the step that ends with X's initial contact; Patterson et al. 2010).
    C3  stance X = TC_X − a;  swing X = b − TC_X;  stride time = b − a.
    C4  single-limb support X = IC_Y − TC_Y (Y swings while X alone carries the body weight).
    C5  double support = (TC_Y − a) + (TC_X − IC_Y) (initial + terminal), and in % of the stride time.
    C6  step length X = (p_X(m_b) − p_Y(m_Y)) · d̂_X: anterior distance between the two feet when both are flat
        after X's contact; p = foot-flat (mid-stance) position of each foot in one common frame, m_b the
        mid-stance that ends X's stride, m_Y the first mid-stance of Y after IC_Y, d̂_X the unit direction of
        X's stride displacement. Needs both feet's trajectories in a common frame (:func:`common_walking_frame`).
        The two feet are integrated separately, so their relative position drifts by the difference of their
        stride-length errors, stride after stride (a 2 % error is ~2 cm a stride, tens of cm over a walk): each
        trajectory is scaled to the mean straight-stride length of both feet (:func:`equal_stride_scale`) and step
        lengths are taken on the first straight stretch of a walk only (up to the first turning stride), where the
        start anchor (feet side by side) holds; after a turn the two frames no longer agree well enough.
    C7  a stride is *used* when its turning angle is at most ``max_turn_deg`` (turns are not steady walking),
        it is not among the first or last ``walk_end_strides`` strides of a walk (gait initiation and
        termination: a walk = strides whose consecutive ICs are less than 3 median stride times apart) and its
        measure is finite. Per side: mean, SD (ddof 1), n, CV = 100 SD / mean.
Session:
    C8  gait speed = Σ stride length / Σ stride time over the used strides of both feet (m/s);
        cadence = 120 / mean stride time of both feet (steps/min).
    C9  paretic ratio = paretic / non-paretic mean; symmetry ratio SR = larger / smaller mean (Patterson et al.
        2010, Gait Posture 31:241-246: "symmetry ratio", 1 = symmetric, always ≥ 1).
    C10 uncertainty from the stride-to-stride variation: SEM of a side mean = SD / √n; of a pooled value the
        SEM of the pooled strides; of a ratio R = A/B by the delta method, SEM_R = R·√((SEM_A/A)² + (SEM_B/B)²);
        minimal detectable change MDC95 = 1.96·√2·SEM (Haley & Fragala-Pinkham 2006, Phys Ther 86:735-743; the
        √2 because a change is the difference of two sessions). Only the within-session variation: day-to-day
        variation adds to it, so this is the precision of one session's value, not an MDC for a change between
        visits. A change between visits is judged against :func:`change_mdc95` (between-session error: repeated
        baseline sessions, else published test-retest values; docs/clinical_measures.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ClinicalParams", "FootEvents", "FootStrides", "StepPhases", "Measure", "ClinicalSummary",
           "step_phases", "clinical_summary", "common_walking_frame", "walking_direction", "equal_stride_scale",
           "mdc95", "change_mdc95", "ChangeMdc", "PublishedMdc", "PUBLISHED_MDC95", "repeated_baseline_sem",
           "SIDE_MEASURES", "SESSION_MEASURES", "positions_at", "walking_frame_xy", "straight_stride_lengths"]

#: per-side measures: name -> unit
SIDE_MEASURES = {"step_length_m": "m", "step_time_s": "s", "swing_time_s": "s", "stance_time_s": "s",
                 "single_support_s": "s", "stride_time_s": "s", "stride_length_m": "m",
                 "double_support_pct": "%"}
#: session measures (both feet): name -> unit
SESSION_MEASURES = {"gait_speed_m_s": "m/s", "cadence_steps_min": "steps/min"}


@dataclass(frozen=True)
class ClinicalParams:
    """max_turn_deg: strides turning more are not used (C7); 20° keeps the straight parts of a lab walkway and
        drops the 180° turn (chosen a priori, not tuned). max_step_time_s: a contralateral mid-stance further
        than this after IC_Y is not that step's (C6). min_strides: fewer used strides on a side flag the
        measure ``few_strides``. walk_end_strides: strides not used at each end of a walk (C7; the first stride
        from standing is a half stride, the last one stops), a priori."""
    max_turn_deg: float = 20.0
    max_step_time_s: float = 2.0
    min_strides: int = 6
    walk_end_strides: int = 1


@dataclass(frozen=True)
class FootEvents:
    """Every event of one foot (s, sorted): ``ic_s``, ``tc_s``; foot-flat samples ``mid_s`` (M,) with their
    positions ``mid_xy`` (M, 2) m in the session's common frame (NaN when unknown)."""
    ic_s: np.ndarray
    tc_s: np.ndarray
    mid_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mid_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass(frozen=True)
class FootStrides:
    """Strides of one foot (S,): ``pre_ic_s`` (NaN if none), ``tc_s``, ``ic_s``, ``stride_length_m``,
    ``turning_deg``; optional foot-flat positions at the stride borders ``start_xy``, ``end_xy`` (S, 2) m in the
    common frame (NaN when unknown)."""
    pre_ic_s: np.ndarray
    tc_s: np.ndarray
    ic_s: np.ndarray
    stride_length_m: np.ndarray
    turning_deg: np.ndarray
    start_xy: np.ndarray | None = None
    end_xy: np.ndarray | None = None


@dataclass(frozen=True)
class StepPhases:
    """Per-stride step and phase measures of one foot (C1-C7), all (S,); s, m, %; NaN where undefined.

    contra_ic_s, contra_tc_s: the contralateral events used.  reason: "ok" | "turn" | "no_previous_ic" |
    "no_contralateral_ic" | "several_contralateral_ic" | "no_contralateral_tc" | "events_out_of_order".
    used: C7 (not a turn and the temporal measures defined)."""
    stride_time_s: np.ndarray
    stance_time_s: np.ndarray
    swing_time_s: np.ndarray
    step_time_s: np.ndarray
    step_length_m: np.ndarray
    single_support_s: np.ndarray
    ds_initial_s: np.ndarray
    ds_terminal_s: np.ndarray
    double_support_pct: np.ndarray
    stride_length_m: np.ndarray
    contra_ic_s: np.ndarray
    contra_tc_s: np.ndarray
    used: np.ndarray
    reason: np.ndarray

    def __len__(self) -> int:
        return int(self.used.shape[0])


@dataclass(frozen=True)
class Measure:
    """One clinical measure of a session (C6-C10). ``value``: the session value (pooled over both feet for a
    per-side measure: mean of the two side means, so a side with more strides does not weigh more).
    Ratios need both sides; ``paretic_ratio`` needs the paretic side. ``flag``: "" | "few_strides" |
    "one_side" | "no_data"."""
    name: str
    unit: str
    value: float
    left: float = float("nan")
    right: float = float("nan")
    sd_left: float = float("nan")
    sd_right: float = float("nan")
    n_left: int = 0
    n_right: int = 0
    cv_left_pct: float = float("nan")
    cv_right_pct: float = float("nan")
    paretic: float = float("nan")
    non_paretic: float = float("nan")
    paretic_ratio: float = float("nan")
    symmetry_ratio: float = float("nan")
    sem: float = float("nan")
    sem_symmetry_ratio: float = float("nan")
    flag: str = ""

    @property
    def mdc95(self) -> float:
        return mdc95(self.sem)

    @property
    def mdc95_symmetry_ratio(self) -> float:
        return mdc95(self.sem_symmetry_ratio)


@dataclass(frozen=True)
class ClinicalSummary:
    """measures: {name: Measure} (``SIDE_MEASURES`` and ``SESSION_MEASURES``); paretic_side "left" | "right" |
    None; notes: human messages (e.g. how many strides lacked a contralateral event)."""
    measures: dict
    paretic_side: str | None
    notes: tuple = ()


def mdc95(sem: float) -> float:
    """Minimal detectable change at 95 % confidence, 1.96·√2·SEM (C10)."""
    return float(1.96 * np.sqrt(2.0) * sem)


def _only(x: np.ndarray, lo: float, hi: float) -> tuple[float, int]:
    """The single value of sorted ``x`` in the open interval (lo, hi) and how many there are."""
    sel = x[(x > lo) & (x < hi)]
    return (float(sel[0]) if len(sel) == 1 else float("nan")), int(len(sel))


def step_phases(own: FootStrides, other: FootEvents, *, params: ClinicalParams = ClinicalParams()) -> StepPhases:
    """Per-stride measures C1-C7 of one foot given every event of the other foot."""
    n = len(own.ic_s)
    f = lambda: np.full(n, np.nan)                                   # noqa: E731
    out = {k: f() for k in ("stride_time_s", "stance_time_s", "swing_time_s", "step_time_s", "step_length_m",
                            "single_support_s", "ds_initial_s", "ds_terminal_s", "double_support_pct",
                            "contra_ic_s", "contra_tc_s")}
    reason = np.full(n, "ok", dtype=object)
    ends = _walk_ends(np.asarray(own.ic_s, float), params.walk_end_strides)
    oic, otc = np.sort(np.asarray(other.ic_s, float)), np.sort(np.asarray(other.tc_s, float))
    mid_s = np.asarray(other.mid_s, float)
    mid_xy = np.asarray(other.mid_xy, float).reshape(-1, 2)
    for k in range(n):
        a, tc, b = float(own.pre_ic_s[k]), float(own.tc_s[k]), float(own.ic_s[k])
        out["swing_time_s"][k] = b - tc
        if not np.isfinite(a):
            reason[k] = "no_previous_ic"
            continue
        out["stride_time_s"][k], out["stance_time_s"][k] = b - a, tc - a
        ic_y, n_ic = _only(oic, a, b)
        if n_ic != 1:
            reason[k] = "no_contralateral_ic" if n_ic == 0 else "several_contralateral_ic"
            continue
        tc_y, n_tc = _only(otc, a, ic_y)
        if n_tc != 1:
            reason[k] = "no_contralateral_tc" if n_tc == 0 else "events_out_of_order"
            continue
        if not (a < tc_y < ic_y < tc < b):
            reason[k] = "events_out_of_order"
            continue
        out["contra_ic_s"][k], out["contra_tc_s"][k] = ic_y, tc_y
        out["step_time_s"][k] = b - ic_y
        out["single_support_s"][k] = ic_y - tc_y
        out["ds_initial_s"][k], out["ds_terminal_s"][k] = tc_y - a, tc - ic_y
        out["double_support_pct"][k] = 100.0 * (tc_y - a + tc - ic_y) / (b - a)
        if own.start_xy is not None and own.end_xy is not None and len(mid_s):
            j = int(np.searchsorted(mid_s, ic_y, side="right"))
            if j < len(mid_s) and mid_s[j] - ic_y <= params.max_step_time_s:
                d = np.asarray(own.end_xy[k], float) - np.asarray(own.start_xy[k], float)
                L = float(np.hypot(*d))
                if np.isfinite(L) and L > 0:
                    out["step_length_m"][k] = float((np.asarray(own.end_xy[k], float) - mid_xy[j]) @ (d / L))
    turn = np.abs(np.asarray(own.turning_deg, float)) > params.max_turn_deg
    reason[turn & (reason == "ok")] = "turn"
    reason[ends & (reason == "ok")] = "walk_end"
    used = (~turn) & (~ends) & np.isfinite(out["stride_time_s"])
    return StepPhases(**out, stride_length_m=np.asarray(own.stride_length_m, float), used=used,
                      reason=reason.astype(str))


def _walk_ends(ic_s: np.ndarray, k: int) -> np.ndarray:
    """(S,) bool: the first and last ``k`` strides of each walk (C7) in a foot's strides sorted by IC."""
    n = len(ic_s)
    out = np.zeros(n, bool)
    if k <= 0 or n == 0:
        return out
    d = np.diff(ic_s)
    med = float(np.median(d)) if len(d) else np.inf
    cut = np.flatnonzero(d > 3.0 * med) + 1
    for a, b in zip(np.r_[0, cut], np.r_[cut, n]):
        out[a:min(b, a + k)] = True
        out[max(a, b - k):b] = True
    return out


def _stats(v: np.ndarray) -> tuple[float, float, int]:
    v = v[np.isfinite(v)]
    if not len(v):
        return float("nan"), float("nan"), 0
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else float("nan"), int(len(v))


def _ratio_sem(a: float, sa: float, b: float, sb: float) -> float:
    r = a / b
    return float(abs(r) * np.sqrt((sa / a) ** 2 + (sb / b) ** 2))


def clinical_summary(left: StepPhases, right: StepPhases, *, paretic_side: str | None = None,
                     params: ClinicalParams = ClinicalParams()) -> ClinicalSummary:
    """Session measures C7-C10 from the per-stride measures of both feet."""
    if paretic_side not in (None, "left", "right"):
        raise ValueError(f"paretic_side must be 'left', 'right' or None, got {paretic_side!r}")
    sides = {"left": left, "right": right}
    measures, notes = {}, []
    for name, unit in SIDE_MEASURES.items():
        st = {}
        for side, ph in sides.items():
            v = getattr(ph, name)[ph.used] if len(ph) else np.zeros(0)
            st[side] = _stats(v)
        (ml, sl, nl), (mr, sr, nr) = st["left"], st["right"]
        sem_l = sl / np.sqrt(nl) if nl > 1 else float("nan")
        sem_r = sr / np.sqrt(nr) if nr > 1 else float("nan")
        both = np.isfinite(ml) and np.isfinite(mr)
        value = 0.5 * (ml + mr) if both else (ml if np.isfinite(ml) else mr)
        sem = 0.5 * np.hypot(sem_l, sem_r) if both else (sem_l if np.isfinite(ml) else sem_r)
        m = dict(name=name, unit=unit, value=float(value), left=ml, right=mr, sd_left=sl, sd_right=sr,
                 n_left=nl, n_right=nr, cv_left_pct=100 * sl / ml if nl > 1 and ml else float("nan"),
                 cv_right_pct=100 * sr / mr if nr > 1 and mr else float("nan"), sem=float(sem))
        if both and min(ml, mr) > 0:
            big, s_big, small, s_small = (ml, sem_l, mr, sem_r) if ml >= mr else (mr, sem_r, ml, sem_l)
            m["symmetry_ratio"] = big / small
            m["sem_symmetry_ratio"] = _ratio_sem(big, s_big, small, s_small)
            if paretic_side is not None:
                p, q = (ml, mr) if paretic_side == "left" else (mr, ml)
                m.update(paretic=p, non_paretic=q, paretic_ratio=p / q)
        m["flag"] = ("no_data" if not (nl or nr) else "one_side" if not both
                     else "few_strides" if min(nl, nr) < params.min_strides else "")
        measures[name] = Measure(**m)
    # C8: session measures over the used strides of both feet
    T = np.concatenate([ph.stride_time_s[ph.used] for ph in sides.values()])
    L = np.concatenate([ph.stride_length_m[ph.used] for ph in sides.values()])
    ok = np.isfinite(T) & np.isfinite(L) & (T > 0)
    n_lr = {s: int(np.sum(ph.used & np.isfinite(ph.stride_time_s) & np.isfinite(ph.stride_length_m)))
            for s, ph in sides.items()}
    flag = ("no_data" if not ok.any() else "one_side" if min(n_lr.values()) == 0
            else "few_strides" if min(n_lr.values()) < params.min_strides else "")
    if ok.sum() > 1:
        speed = float(L[ok].sum() / T[ok].sum())
        v = L[ok] / T[ok]
        sem_speed = float(v.std(ddof=1) / np.sqrt(ok.sum()))
        t_mean, t_sem = float(T[ok].mean()), float(T[ok].std(ddof=1) / np.sqrt(ok.sum()))
        cad, sem_cad = 120.0 / t_mean, 120.0 * t_sem / t_mean ** 2          # delta method
    else:
        speed = sem_speed = cad = sem_cad = float("nan")
    measures["gait_speed_m_s"] = Measure("gait_speed_m_s", "m/s", speed, sem=sem_speed, flag=flag,
                                         n_left=n_lr["left"], n_right=n_lr["right"])
    measures["cadence_steps_min"] = Measure("cadence_steps_min", "steps/min", cad, sem=sem_cad, flag=flag,
                                            n_left=n_lr["left"], n_right=n_lr["right"])
    for side, ph in sides.items():
        bad = {r: int(c) for r, c in zip(*np.unique(ph.reason, return_counts=True))
               if r not in ("ok", "turn", "walk_end")}
        if bad:
            notes.append(f"{side}: " + ", ".join(f"{c} stride(s) {r.replace('_', ' ')}" for r, c in bad.items()))
        nt = int(np.sum(ph.reason == "turn"))
        if nt:
            notes.append(f"{side}: {nt} turning stride(s) not used")
        ne = int(np.sum(ph.reason == "walk_end"))
        if ne:
            notes.append(f"{side}: {ne} stride(s) at the start or end of a walk not used")
    if paretic_side is None:
        notes.append("paretic side unknown (study manifest or session metadata 'paretic_side'): no paretic ratios")
    return ClinicalSummary(measures=measures, paretic_side=paretic_side, notes=tuple(notes))


def common_walking_frame(start_xy: np.ndarray, end_xy: np.ndarray, turning_deg: np.ndarray, *,
                         max_turn_deg: float = 20.0, n_strides: int = 3) -> np.ndarray | None:
    """(2, 2) rotation that turns a foot's own horizontal frame into the walking frame (+x = initial walking
    direction), or None without a straight stride.

    Each foot's trajectory (:func:`stridelab.estimators.trajectory.eskf_trajectory`) has its own yaw and its origin at the
    foot's first stance. Rotating both feet so that the displacement over their first ``n_strides`` straight
    strides points along +x puts them in one frame whose origins are the two feet at the start; with the feet
    side by side in the standing that starts a lab walk (the usual instruction), the anterior offset of the two
    origins is zero and step lengths (C6) follow. The lateral offset (step width) drops out of C6.
    """
    d = walking_direction(start_xy, end_xy, turning_deg, max_turn_deg=max_turn_deg, n_strides=n_strides)
    if d is None:
        return None
    c, si = d
    return np.array([[c, si], [-si, c]])


def walking_direction(start_xy: np.ndarray, end_xy: np.ndarray, turning_deg: np.ndarray, *, at_end: bool = False,
                      max_turn_deg: float = 20.0, n_strides: int = 3) -> np.ndarray | None:
    """(2,) unit horizontal direction of the first (or, ``at_end``, the last) ``n_strides`` straight strides, or
    None (no straight stride, or less than 0.1 m walked)."""
    s, e, t = (np.asarray(x, float) for x in (start_xy, end_xy, turning_deg))
    if at_end:
        s, e, t = s[::-1], e[::-1], t[::-1]
    k = 0
    while k < len(t) and np.abs(t[k]) <= max_turn_deg and k < n_strides:
        k += 1
    if k == 0:
        return None
    d = (e[0] - s[k - 1]) if at_end else (e[k - 1] - s[0])
    if not np.all(np.isfinite(d)) or np.hypot(*d) < 0.1:
        return None
    return d / np.hypot(*d)



def equal_stride_scale(own_lengths_m: np.ndarray, other_lengths_m: np.ndarray) -> float:
    """Factor that gives this foot's trajectory the mean straight-stride length of both feet (C6 drift).

    In straight walking both feet progress equally, so their mean stride lengths are equal for any gait
    (hemiparetic included); a difference is a scale error of one integration, and it makes the relative position
    of the feet drift by that difference every stride. Scaling each trajectory about the common start point to the
    mean of the two feet removes the relative drift (not the common one, which the stride lengths keep)."""
    a, b = np.asarray(own_lengths_m, float), np.asarray(other_lengths_m, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if not len(a) or not len(b) or not a.mean() > 0:
        return float("nan")
    return float(0.5 * (a.mean() + b.mean()) / a.mean())


@dataclass(frozen=True)
class PublishedMdc:
    """A published between-session (test-retest) MDC95 of one measure, by baseline band.

    bands: ((lower, upper, mdc95), ...) over the baseline value [lower, upper); population, source: what it was
    measured on and where (docs/clinical_measures.md "Minimal detectable change")."""
    measure: str
    quantity: str
    unit: str
    bands: tuple
    population: str
    source: str

    def at(self, baseline: float) -> float:
        for lo, hi, v in self.bands:
            if lo <= baseline < hi:
                return float(v)
        return float("nan")


#: published test-retest MDC95 per (measure, quantity). Only values read from the source are listed; a measure
#: without one has no MDC unless the study has repeated baseline sessions (never the within-session SEM).
PUBLISHED_MDC95 = {
    ("gait_speed_m_s", "value"): PublishedMdc(
        "gait_speed_m_s", "value", "m/s", ((0.0, 0.4, 0.10), (0.4, 0.8, 0.15), (0.8, float("inf"), 0.18)),
        "chronic stroke, comfortable gait speed, 2 visits (n = 76), by baseline speed < 0.4 / 0.4-0.8 / > 0.8 m/s",
        "Lewek & Sykes 2019, J Neurol Phys Ther 43:122-127, doi:10.1097/NPT.0000000000000257"),
}


@dataclass(frozen=True)
class ChangeMdc:
    """MDC95 of a change between two sessions and where it comes from: ``source`` = "repeated baselines (n
    participants, k sessions)", the published source, or "" with ``mdc95`` NaN when no between-session error is
    known."""
    mdc95: float
    source: str


def repeated_baseline_sem(values_per_participant) -> tuple[float, int, int]:
    """Between-session SEM from repeated baseline sessions: the pooled within-participant SD,
    √(Σ_i Σ_j (x_ij − x̄_i)² / Σ_i (n_i − 1)) over participants with ≥ 2 finite baseline values (the SEM of
    test-retest reliability, de Vet et al. 2006, J Clin Epidemiol 59:1033-1039). Returns (SEM, participants,
    sessions); SEM NaN with fewer than 2 sessions of one participant."""
    ss, dof, n_p, n_s = 0.0, 0, 0, 0
    for v in values_per_participant:
        x = np.asarray(v, float)
        x = x[np.isfinite(x)]
        if len(x) < 2:
            continue
        ss += float(((x - x.mean()) ** 2).sum())
        dof += len(x) - 1
        n_p += 1
        n_s += len(x)
    return (float(np.sqrt(ss / dof)) if dof else float("nan")), n_p, n_s


def change_mdc95(measure: str, quantity: str = "value", *, baseline: float = float("nan"),
                 repeated_baselines=None) -> ChangeMdc:
    """MDC95 of the change of a measure between two sessions from between-session error: from repeated baseline
    sessions when given (``repeated_baselines``: one array of baseline-session values per participant;
    MDC95 = 1.96·√2·SEM with SEM = :func:`repeated_baseline_sem`), else the published test-retest value for the
    ``baseline`` value (:data:`PUBLISHED_MDC95`), else NaN. Never the within-session stride-to-stride SEM, which
    says nothing about visit-to-visit error (C10 is a within-session precision only)."""
    if repeated_baselines is not None:
        sem, n_p, n_s = repeated_baseline_sem(repeated_baselines)
        if np.isfinite(sem):
            return ChangeMdc(mdc95(sem), f"repeated baselines ({n_p} participants, {n_s} sessions)")
    pub = PUBLISHED_MDC95.get((measure, quantity))
    if pub is not None and np.isfinite(baseline):
        v = pub.at(float(baseline))
        if np.isfinite(v):
            return ChangeMdc(v, pub.source)
    return ChangeMdc(float("nan"), "")


def positions_at(t_ns: np.ndarray, xy: np.ndarray, q_ns) -> np.ndarray:
    """(n, 2) positions ``xy`` (sampled at ``t_ns``) at the stamps ``q_ns``: the sample at or after each stamp
    (events fall on samples, so this is the exact sample; the last sample after the end); NaN without samples."""
    q = np.asarray(q_ns, np.int64)
    if not len(t_ns) or not len(q):
        return np.full((len(q), 2), np.nan)
    i = np.clip(np.searchsorted(t_ns, q), 0, len(t_ns) - 1)
    return xy[i]


def walking_frame_xy(t_ns: np.ndarray, xy: np.ndarray, stance: np.ndarray, start_ns: np.ndarray, end_ns: np.ndarray,
                     turning_deg: np.ndarray, *, max_turn_deg: float, min_stance_s: float = 0.3
                     ) -> tuple[np.ndarray, list[str]]:
    """One foot's trajectory in the walking frame of C6: (N, 2) positions, per contiguous stretch of samples,
    turned by :func:`common_walking_frame` (from the stretch's strides ``start_ns``/``end_ns``/``turning_deg``) and
    starting at 0, up to the stride that first turns more than ``max_turn_deg``; NaN elsewhere and in stretches
    that do not start standing (``stance`` over the first ``min_stance_s``: the side-by-side start anchor) or have
    no straight stride. Returns the positions and a note per stretch left out."""
    from stridelab.estimators.timebase import contiguous_segments
    out = np.full_like(xy, np.nan)
    notes = []
    fs = 1e9 / float(np.median(np.diff(t_ns))) if len(t_ns) > 1 else 100.0
    start_ns, end_ns = np.asarray(start_ns, np.int64), np.asarray(end_ns, np.int64)
    turning_deg = np.asarray(turning_deg, float)
    for a, b in contiguous_segments(t_ns):
        sel = np.flatnonzero((start_ns >= t_ns[a]) & (start_ns <= t_ns[b - 1]))
        sel = sel[np.argsort(start_ns[sel], kind="stable")]
        if not len(sel):
            continue
        if not stance[a:a + max(1, int(min_stance_s * fs))].all():
            notes.append("trajectory does not start standing: no step lengths for that stretch")
            continue
        turn = turning_deg[sel]
        M = common_walking_frame(positions_at(t_ns, xy, start_ns[sel]), positions_at(t_ns, xy, end_ns[sel]), turn,
                                 max_turn_deg=max_turn_deg)
        if M is None:
            notes.append("no straight stride to find the walking direction: no step lengths for that stretch")
            continue
        turns = np.flatnonzero(np.abs(turn) > max_turn_deg)
        stop = b if not len(turns) else int(np.searchsorted(t_ns, start_ns[sel][turns[0]], side="right"))
        out[a:stop] = (xy[a:stop] - xy[a]) @ M.T
    return out, notes


def straight_stride_lengths(ic_s: np.ndarray, stride_length_m: np.ndarray, turning_deg: np.ndarray,
                            has_previous_ic: np.ndarray, *, max_turn_deg: float) -> np.ndarray:
    """Lengths (m) of one foot's steady straight strides, the input of :func:`equal_stride_scale` (C6): in IC
    order, the strides before the first turning one (|turning| > ``max_turn_deg``, where the step lengths stop),
    without the first stride (gait initiation), with a previous IC and a finite length."""
    order = np.argsort(np.asarray(ic_s), kind="stable")
    L, turn = np.asarray(stride_length_m, float)[order], np.asarray(turning_deg, float)[order]
    prev = np.asarray(has_previous_ic, bool)[order]
    turns = np.flatnonzero(np.abs(turn) > max_turn_deg)
    stop = int(turns[0]) if len(turns) else len(L)
    keep = np.zeros(len(L), bool)
    keep[1:stop] = True
    return L[keep & prev & np.isfinite(L)]
