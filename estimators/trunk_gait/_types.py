"""Parameters and result types of the trunk-gait family (see docs/trunk_gait.md).

Body frame of this family (ISB, as DESIGN.md): x anterior, y superior (up, along gravity reversed), z right.
``TrunkFrame.R`` maps sensor-frame vectors into it: ``v_body = R @ v_sensor`` (rows = body axes in sensor
coordinates). The frame is gravity-aligned (tilt-corrected, Moe-Nilssen 1998) and heading-free: y is the mean
specific-force direction while walking, x its horizontal direction of forward acceleration.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DEFAULT_HEIGHT_M = 1.70
"""Body height used when none is given (flagged ``default_height``): the mean of adult European men and women
(about 1.78 / 1.65 m, NCD-RisC 2016, doi:10.7554/eLife.13410), rounded."""

LEG_LENGTH_PER_HEIGHT = 0.53
"""Leg length (greater trochanter to floor) per body height, Winter 2009 (Biomechanics and Motor Control of Human
Movement, 4th ed., Fig. 4.1: 0.530 H); used when only the height is known."""

PLACEMENTS = ("lower_back", "chest")


@dataclass(frozen=True)
class TrunkGaitParams:
    """Parameters of ``analyse_trunk_gait`` (units in the names; rate-independent).

    Gait-sequence detection (windowed step periodicity, after Iluz et al. 2014 / Moe-Nilssen & Helbostad 2004):
      gsd_window_s: window length, s (3 s as Iluz 2014).
      gsd_hop_s: hop between windows, s.
      gsd_min_std_m_s2: minimum standard deviation of the acceleration norm in a walking window, m/s².
      gsd_min_autocorr: minimum normalised autocorrelation at the step lag (0.25-1.6 s) in a walking window.
      gsd_merge_gap_s: walking windows closer than this are merged into one gait sequence, s.
      gsd_slow_min_std_m_s2: slow-walking rule (periodicity-led, ``_gsd``): minimum SD of the acceleration norm
        band-passed to 0.5-3 Hz in a walking window, m/s² (inf = off).
      gsd_slow_min_autocorr: slow-walking rule: minimum normalised autocorrelation of that band-passed norm at the
        step lag.
    Initial contacts (``ic_method``: "peak" = peak of the smoothed upward acceleration, McCamley et al. 2012 /
    Zijlstra & Hof 2003, ``_icd``; "ionescu" = minima of the wavelet-smoothed vertical jerk between its zero
    crossings, Paraschiv-Ionescu et al. 2020, ``_icd_ionescu``):
      ic_method: "peak" | "ionescu" | "shin" | "hklee".
      ic_zc_sigma_s: Gaussian σ of the jerk ("ionescu"; 0.159 s = the source's gaus2 scale 9 at 40 Hz), s.
      ic_zc_min_depth: minimum lobe depth in SDs of the smoothed jerk over the sequence ("ionescu"; 0 = source).
    "shin" = negative-to-positive zero crossings and "hklee" = closing-minus-opening maxima of the doubly
    wavelet-filtered acceleration (Shin & Park 2011 / Lee et al. 2010 as improved by Paraschiv-Ionescu et al. 2020,
    the Mobilise-D cadence detectors; ``_icd_cwt``):
      ic_cwt_signal: their input, "norm" (acceleration norm, as the source) or "vertical" (upward acceleration).
      (``ic_zc_min_depth`` is their amplitude gate: minimum lobe / closing-minus-opening height in SDs of the
      filtered signal over the sequence; 0 = the source.)
      (``ic_min_step_s`` also thins their contacts: of two closer than that the first stays.)
    For "peak":
      ic_smooth_s: standard deviation of the Gaussian smoothing of the vertical acceleration, s.
      ic_min_step_s: minimum time between two initial contacts, s.
      ic_prominence: minimum peak prominence as a fraction of the smoothed signal's standard deviation within
        the gait sequence.
      ic_local_window_s: window of that standard deviation, s (0 = the whole sequence).
      ic_fill_prominence: weaker peaks (prominence ≥ this fraction of the sequence's SD) are added where the step
        rhythm of the kept contacts expects a missed one (0 = off; ``_icd.fill_missed_steps``).
      ic_fill_edge_steps: how many such steps may be added before the first and after the last kept contact.
      ic_fill_end_steps: how many more may be added after the last kept contact only (the closing step).
      ic_fill_start_prominence: with the fill on, before the first contact of every walk (the first kept one and
        the first after a pause) the most prominent peak 0.5-1.5 steps earlier is added when its prominence reaches
        this many SDs (0 = off; the first step out of standing lifts the trunk less).
      ic_fill_end_rhythm: with the closing-step fill on (``ic_fill_end_steps`` > 0), the first closing step is
        placed one median step after the last contact instead of at a weak peak (the closing heel strike gives the
        trunk no rebound; ``_icd.fill_missed_steps``).
      ic_fill_walk_ends: with the closing-step fill on, closing steps are looked for after the last contact of every
        walk (before every pause > 2.5 steps inside a gait sequence), not only after the sequence's last contact
        (``_icd.fill_missed_steps``).
      ic_turn_prominence: factor on the prominence threshold for peaks inside a detected turn (1 = off).
      ic_subsample: each peak at the vertex of the parabola through its three samples (``_icd.parabolic_peaks``)
        instead of at the peak sample.
      ic_offset_s: added to every detected contact time (trunk event vs heel strike; both methods), s.
      ic_fill_offset_s: added on top of ``ic_offset_s`` to the contacts the fill added (closing steps, gaps; not the
        threshold peaks), s (0 = off; ``_icd.kind_offsets_s``).
      ic_walk_end_offset_s: added on top of ``ic_offset_s`` to the last threshold peak before a closing step, s
        (0 = off; ``_icd.kind_offsets_s``). Both time the reported initial contacts only: strides, bouts and
        cadence use the contact times with ``ic_offset_s`` alone.
      ic_refine_s: for "ionescu" / "shin" / "hklee": each contact is moved to the highest sample of the upward
        acceleration smoothed with σ ``ic_smooth_s`` within ± this (the amplitude-free detector counts the steps,
        the acceleration peak of "peak" times them; 0 = off), s.
      cadence_method: per-bout cadence, "median" (60 / median step time), "count" (steps over walking time,
        a missed contact counted by the rhythm), "step_mean" (mean of 60 / step time), "per_second"
        (mobgap's robust per-second cadence, Hampel-cleaned step times) or "stride_mean" (mean over the bout's
        strides of 120 / stride time, the Mobilise-D INDIP reference definition); ``_pipeline.bout_cadence``.
    Side (McCamley et al. 2012: sign of the yaw rate):
      side_lag_s: the yaw rate is read this long after each initial contact (negative = before), s.
      side_lowpass_hz: low-pass cut-off of the yaw rate, Hz.
    Stride length (Zijlstra & Hof 2003 inverted pendulum):
      sl_correction: multiplicative correction factor K of the pendulum step length (with l = leg length; chosen
        by cross-validation on foot-INS and INDIP references, validation/provenance.toml; Zijlstra & Hof 2003 give
        1.25).
      sl_highpass_hz: high-pass cut-off before and after the double integration, Hz.
      sl_hampel_half_width: half width (steps) of the Hampel filter on the step lengths within a run of regular
        steps (0 = off; Soltani et al. 2021 use 2 steps, 3 MAD).
      sl_turn_per_rad: turning steps are shortened to step / (1 + sl_turn_per_rad · |heading change of the step,
        rad|) (0 = off; ``_spatial.turn_shortened``).
      bout_average: "mean", "median" or "time" (mean weighted by stride duration, as mobgap's per-second values) of
        the bout's strides (``bout_strides``) for its stride length and walking speed.
      bout_strides: "regular" (strides lasting ≤ 1.5 x the bout's median stride duration) or "all" strides of the
        bout (``_pipeline.bout_spatial``).
      sl_max_tilt_deg: strides whose trunk leans more than this from the gait sequence's walking posture (mean
        up) are left out of the bout's stride length and speed (not pendular: rising from a chair, stooping;
        ``_spatial.step_tilt_deg``), deg (0 = off).
      speed_method: bout walking speed as the average of the stride speeds ("stride") or as bout stride length x
        cadence / 120 ("cadence", mobgap's definition; the cadence there is the bout's steps over its walking time,
        ``cadence_method`` "count", whatever cadence the bout reports: distance over time).
    Walking-bout assembly (Kluge et al. 2021 consensus):
      wb_min_strides: minimum number of strides of a walking bout (4, as mobgap's reading of Kluge 2021).
      wb_max_break_s: longest break between strides inside one walking bout, s.
      stride_rule: "run" (a stride IC_i -> IC_{i+2} only within a run of steps each ≤ stride_max_s / 2) or
        "consensus" (every IC_i -> IC_{i+2} of at most stride_max_s, as Kluge et al. 2021 / mobgap; no stride starts
        at a closing step; ``_wba.strides_from_contacts``).
      stride_min_s, stride_max_s: plausible stride duration, s.
      stride_min_length_m: strides shorter than this are not counted as walking, m.
    Turns (El-Gohary et al. 2014):
      turn_lowpass_hz: low-pass cut-off of the yaw rate, Hz.
      turn_min_peak_deg_s: minimum peak yaw rate of a turn, deg/s.
      turn_edge_deg_s: the turn starts and ends where the yaw rate falls below this, deg/s.
      turn_min_angle_deg: minimum turn angle, deg.
      turn_min_s, turn_max_s: plausible turn duration, s.
    """
    gsd_window_s: float = 3.0
    gsd_hop_s: float = 0.5
    gsd_min_std_m_s2: float = 0.25
    gsd_min_autocorr: float = 0.3
    gsd_merge_gap_s: float = 1.0
    gsd_slow_min_std_m_s2: float = 0.08
    gsd_slow_min_autocorr: float = 0.8
    ic_method: str = "peak"
    ic_zc_sigma_s: float = 0.159
    ic_zc_min_depth: float = 0.0
    ic_cwt_signal: str = "norm"
    ic_refine_s: float = 0.0
    ic_subsample: bool = False
    ic_smooth_s: float = 0.14
    ic_min_step_s: float = 0.25
    ic_prominence: float = 0.7
    ic_local_window_s: float = 0.0
    ic_fill_prominence: float = 0.1
    ic_fill_edge_steps: int = 0
    ic_fill_end_steps: int = 1
    ic_fill_start_prominence: float = 0.0
    ic_fill_end_rhythm: bool = True
    ic_fill_walk_ends: bool = True
    ic_turn_prominence: float = 1.0
    ic_offset_s: float = -0.07
    ic_fill_offset_s: float = -0.07
    ic_walk_end_offset_s: float = -0.04
    cadence_method: str = "stride_mean"
    side_lag_s: float = -0.1
    side_lowpass_hz: float = 2.0
    sl_correction: float = 1.27
    sl_highpass_hz: float = 0.1
    sl_hampel_half_width: int = 1
    sl_turn_per_rad: float = 0.3
    bout_average: str = "median"
    bout_strides: str = "all"
    speed_method: str = "cadence"
    sl_max_tilt_deg: float = 0.0
    wb_min_strides: int = 4
    stride_rule: str = "consensus"
    wb_max_break_s: float = 3.0
    stride_min_s: float = 0.2
    stride_max_s: float = 3.0
    stride_min_length_m: float = 0.15
    turn_lowpass_hz: float = 1.5
    turn_min_peak_deg_s: float = 15.0
    turn_edge_deg_s: float = 5.0
    turn_min_angle_deg: float = 45.0
    turn_min_s: float = 0.5
    turn_max_s: float = 10.0


@dataclass(frozen=True)
class TrunkFrame:
    """Sensor-to-body rotation found from the data.

    R: (3, 3) rows = body x (anterior), y (up), z (right) in sensor coordinates; ``v_body = R @ v_sensor``.
    confidence: 0..1, the smaller of the vertical confidence (mean resultant length of the acceleration direction)
      and the anterior confidence (|correlation| of the forward axis with the vertical jerk while walking).
    vertical_axis / vertical_sign: the sensor axis closest to up and whether it points up (+1) or down (-1).
    anterior_axis / anterior_sign: the same for anterior.
    walking_found: whether walking was found to fix the anterior axis (else x is an arbitrary horizontal axis).
    warnings: tuple of human-readable warnings (e.g. "sensor looks upside down").
    """
    R: np.ndarray
    confidence: float
    vertical_axis: int
    vertical_sign: int
    anterior_axis: int
    anterior_sign: int
    walking_found: bool
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class Bouts:
    """Walking bouts, one entry per bout (arrays of equal length B).

    start_s, end_s: first and last initial contact of the bout's strides, s from the first sample (closing steps
      added by the fill, ``ic_fill_end_steps``, may follow ``end_s``: contacts of the bout, but no stride).
    n_steps, n_strides: counts (steps = initial contacts - 1; strides = complete same-side IC pairs).
    cadence_spm: steps per minute (``TrunkGaitParams.cadence_method``); stride_length_m: the bout's stride length,
    m; walking_speed_m_s: its walking speed, m/s (``TrunkGaitParams.bout_average`` / ``bout_strides`` /
    ``speed_method``).
    n_turns: turns (≥ turn_min_angle_deg) overlapping the bout.
    flags: per bout a tuple of quality flags ("default_height", "low_frame_confidence", ...).
    """
    start_s: np.ndarray
    end_s: np.ndarray
    n_steps: np.ndarray
    n_strides: np.ndarray
    cadence_spm: np.ndarray
    stride_length_m: np.ndarray
    walking_speed_m_s: np.ndarray
    n_turns: np.ndarray
    flags: tuple[tuple[str, ...], ...] = ()

    def __len__(self) -> int:
        return int(len(self.start_s))

    @property
    def duration_s(self) -> np.ndarray:
        return self.end_s - self.start_s

    def records(self) -> list[dict]:
        """One dict per bout (plain Python types), for tables."""
        return [{"start_s": float(self.start_s[i]), "end_s": float(self.end_s[i]),
                 "duration_s": float(self.end_s[i] - self.start_s[i]), "n_steps": int(self.n_steps[i]),
                 "n_strides": int(self.n_strides[i]), "cadence_spm": float(self.cadence_spm[i]),
                 "stride_length_m": float(self.stride_length_m[i]),
                 "walking_speed_m_s": float(self.walking_speed_m_s[i]), "n_turns": int(self.n_turns[i]),
                 "flags": tuple(self.flags[i]) if self.flags else ()} for i in range(len(self))]


@dataclass(frozen=True)
class Strides:
    """Strides kept in walking bouts (arrays of length S): start_s, end_s (same-side initial contacts), side
    ("left"/"right" per stride), length_m, speed_m_s, bout (index into ``Bouts``), tilt_deg (the trunk's mean lean
    from the walking posture over the stride, ``_spatial.step_tilt_deg``), steady (its three contacts in one run of
    regular steps: False for a stride over a stop, which ``stride_rule`` "consensus" keeps for the bout rules but
    the bout's stride length and speed leave out; None = all steady)."""
    start_s: np.ndarray
    end_s: np.ndarray
    side: np.ndarray
    length_m: np.ndarray
    speed_m_s: np.ndarray
    bout: np.ndarray
    tilt_deg: np.ndarray
    steady: np.ndarray | None = None

    def __len__(self) -> int:
        return int(len(self.start_s))


@dataclass(frozen=True)
class Turns:
    """Turns (arrays of length T): start_s, end_s, angle_deg (signed, + = to the left, counter-clockwise seen from
    above), peak_rate_deg_s."""
    start_s: np.ndarray
    end_s: np.ndarray
    angle_deg: np.ndarray
    peak_rate_deg_s: np.ndarray

    def __len__(self) -> int:
        return int(len(self.start_s))


@dataclass(frozen=True)
class TrunkGaitResult:
    """Everything ``analyse_trunk_gait`` found.

    bouts: ``Bouts``; strides: ``Strides``; turns: ``Turns``.
    initial_contacts_s: (K,) every initial contact of a walking bout (inside it, or a closing step right after
      it), s from the first sample, sorted.
    ic_side: (K,) "left" / "right".
    gait_sequences_s: (G, 2) [start, end) of the detected gait sequences, s.
    frame: the ``TrunkFrame`` used. height_m, leg_length_m: what the spatial model used.
    height_source: "given" | "default (1.70 m, documented)"; leg_length_source likewise ("given" |
    "from height (0.53 H)").
    placement, params, warnings (tuple of str).
    ic_closing: (K,) bool, the contacts that are closing steps added by the fill (left out of the cadence).
    ic_kind: (K,) int8, how each contact was found: an index into ``_icd.IC_KINDS`` ("peak", "gap_fill",
      "edge_fill", "start_fill", "closing_rhythm", "closing_peak"; the other detectors: all "peak").
    """
    bouts: Bouts
    strides: Strides
    turns: Turns
    initial_contacts_s: np.ndarray
    ic_side: np.ndarray
    gait_sequences_s: np.ndarray
    frame: TrunkFrame
    height_m: float
    leg_length_m: float
    height_source: str
    leg_length_source: str
    placement: str
    params: TrunkGaitParams = field(default_factory=TrunkGaitParams)
    warnings: tuple[str, ...] = ()
    ic_closing: np.ndarray | None = None
    ic_kind: np.ndarray | None = None


DURATION_CLASSES_S = ((10.0, 30.0), (30.0, 60.0), (60.0, 120.0), (120.0, float("inf")))


@dataclass(frozen=True)
class DailyOutcomes:
    """Mobilise-D-style digital mobility outcomes of one day (Polhemus et al. 2021; Kirk et al. 2024).

    walking_time_s: total duration of all walking bouts. n_bouts: all bouts. n_bouts_by_class: counts for
    10-30 s, 30-60 s, 60-120 s, > 120 s (``DURATION_CLASSES_S``, [lo, hi)). n_bouts_over_10s.
    speed_median_m_s, speed_p95_m_s, stride_length_median_m, stride_length_p95_m, cadence_median_spm,
    cadence_p95_spm: median and 95th centile over bouts longer than 10 s (NaN when there is none).
    stride_velocity_p95_m_s: 95th centile of stride speeds (of strides in bouts > 10 s when the bout of each stride
    is given), NaN when none.
    """
    walking_time_s: float
    n_bouts: int
    n_bouts_by_class: tuple[int, int, int, int]
    n_bouts_over_10s: int
    speed_median_m_s: float
    speed_p95_m_s: float
    stride_length_median_m: float
    stride_length_p95_m: float
    cadence_median_spm: float
    cadence_p95_spm: float
    stride_velocity_p95_m_s: float
