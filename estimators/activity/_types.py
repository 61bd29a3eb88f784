"""Parameters, presets and result types of the chest daily-activity family (thesis ch. 7).

Spec: spec/thesis_calib_gait_posture.md §4 and §7.C; seed: Nazarahari 2021 ch. 7
(Nazarahari & Rouhani, Med. Eng. Phys. 57:75-81, 2018, doi:10.1016/j.medengphy.2018.04.008).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

STANDARD_GRAVITY = 9.80665

#: per-second classes, in code order (``ActivityResult.second_class`` holds the index)
CLASSES = ("lying", "sitting", "standing", "level_walking", "stairs_up", "stairs_down", "non_wear")
LYING, SITTING, STANDING, LEVEL, UP, DOWN, NON_WEAR = range(7)
WALKING_CLASSES = ("level_walking", "stairs_up", "stairs_down")

#: postural transitions, in code order (``Transitions.kind``)
TRANSITIONS = ("SiLy", "LySi", "StSi", "SiSt")
SILY, LYSI, STSI, SIST = range(4)


@dataclass(frozen=True)
class ActivityParams:
    """Parameters of the chest-accelerometer activity classifier (units in the names; angles in degrees,
    accelerations in g = 9.80665 m/s² like the thesis maths; the public API takes m/s²).

    ga_mode: gravitational-component filter, ``"lfilter"`` (causal single pass, spec §4.2 default) or
        ``"filtfilt"`` (zero phase). The filter is always the thesis 2nd-order elliptic low-pass, started
        in steady state.
    ga_cutoff_hz: elliptic pass-band edge, Hz (thesis 0.25).
    ga_ripple_db: pass-band ripple, dB (thesis 0.01).
    theta_mode: trunk inclination θ from ``"thesis"`` Eq. 54, arccos(GA_v / g) (assumes ‖GA‖ = 1 g), or
        ``"direction"`` (extension, default) arccos(GA_v / ‖GA‖), the angle of the GA direction alone: identical
        for a calibrated sensor, and immune to a scale error that survives auto-calibration (an uncalibrated
        sensor whose still orientations do not cover the sphere reads e.g. 0.8 g while upright, which Eq. 54
        turns into a 37° lean and every walking bout into a rejected, non-upright one).
    ga_stop_db: stop-band attenuation, dB (thesis 100).
    align: ``"none"`` (thesis: sensor y is vertical, x frontal, z lateral; the mounting tilt stays in θ) or
        ``"upright_reference"`` (rotate each wear period so that the participant's walking posture is +y;
        handles rotated and upside-down sensors; extension).
    autocalibrate: refit per-axis gain and offset from still periods (sphere fit, van Hees 2014) when the
        still orientations cover the sphere well enough; otherwise only a common gain (extension).
    lying_deg: trunk inclination above which the trunk is lying (thesis 70°, Eq. 54).
    lying_hysteresis_deg: a lying crossing needs θ to pass lying_deg ± this, deg (CHOICE, anti-chatter).
    lying_static_g: |GA_f| (thesis) or horizontal |GA| (side_lying) needed in the static check, g (spec 0.8).
    side_lying: also accept side lying (|GA_l|) in the lying static check (extension; thesis: frontal only).
    static_std_g: a second is static if std(‖a‖) < this, g (spec 0.05).
    static_search_s: the lying static period must start within this time of the crossing, s (spec 5).
    sitstand_deg: trunk inclination of a StSi/SiSt candidate excursion, deg (thesis 20).
    max_transition_s: longest θ>sitstand_deg excursion taken as a candidate, s (CHOICE: 8).
    minima_search_s: search for the θ local minima around a candidate, s (spec 5).
    minima_tolerance_deg: the minimum search passes wiggles smaller than this, deg (thesis-literal 0 =
        strictly decreasing, the default; 1° made the synthetic-day agreement worse although it catches
        sit-to-stands whose window starts at a filter-ripple wiggle).
    thigh_length_m: participant thigh length for the ΔY check, m (spec: 0.245 × height if unknown).
    dy_fraction: reject a candidate if |ΔY| < this × thigh length (thesis 0.5; default 0.35 because the
        mean-removed double integral over the θ-minima window recovers only 55-85 % of a synthetic chest drop).
    dy_pad_s: ΔY is also integrated over the θ-minima window widened by this on both sides (still posture
        at both ends, so the mean-removed double integral sees the whole chest motion) and the larger |ΔY| is
        kept, s (extension; thesis 0 = θ-minima window only).
    sitstand_sign: StSi vs SiSt from ``"ci"`` (thesis: sign of the dominant extremum of the cumulative SVM
        integral) or ``"dy"`` (sign of ΔY: the thesis's "alternative method"; default, because the GA-based CI
        had the StSi sign for sit-to-stand too on the synthetic days).
    dy_source: vertical acceleration integrated for ΔY (Eq. 56): ``"ga"`` (thesis Eq. 55 on GA), ``"raw"`` (raw
        acc projected on the GA gravity direction) or ``"norm"`` (default, extension: ‖a‖, the vertical
        acceleration to first order with no orientation estimate, hence no lag of the causal GA filter; the
        projection on the lagging GA direction recovered 55-80 % of a simulated sit-to-stand rise, ‖a‖ 80-100 %).
    sitstand_resolve: posture-sequence check of the sit/stand transitions (extension, timeline "hybrid" only):
        between walking bouts (standing) and lying periods (sitting next to them) StSi and SiSt must alternate;
        a minimum-cost two-state path over all 20° candidate excursions (accepted ones and those the ΔY check
        rejected) flips a transition whose sign contradicts the sequence, adds a rejected candidate where a
        transition is missing (e.g. a SiSt while standing needs a StSi before it) and drops one that fits nowhere;
        posture evidence: ≥ 60 s still with the trunk leaning more than sit_lean_deg from the upright reference
        costs when standing, and such a run's onset / end are virtual candidates (a reclined sit-down keeps θ
        above 20°, so it has no candidate excursion). Thesis preset: off (each transition decided on its own).
    svm_walk_source: ``"ga"`` (thesis Eq. 57 SVM), ``"raw"`` (‖a‖ − 1 g low-passed at step_lowpass_hz) or
        ``"vertical"`` (default, extension: raw acc projected on the GA gravity direction, i.e. the raw form of
        Eq. 55, band-passed step_highpass_hz-step_lowpass_hz; orientation-free and insensitive to the
        calibration offsets left by a ``gain_only`` auto-calibration).
    step_highpass_hz: high-pass edge of the ``"vertical"`` step signal, Hz (cadence range 0.5-2.5 Hz).
    step_lowpass_hz: low-pass of the raw / vertical step signal, Hz (CHOICE).
    step_threshold_g: SVM peak height for a step, g (spec low threshold 0.015 g for GA; with step_relative > 0
        the absolute floor of the adaptive threshold).
    step_relative: adaptive step threshold (extension): a peak must also exceed this fraction of the local
        step amplitude √2 × RMS of the step signal over ±step_rms_window_s / 2 (0 = fixed threshold, thesis).
        Follows the participant's own gait: slow, weak and asymmetric steps of a hemiparetic walker count.
    step_rms_window_s: window of the local RMS of the adaptive threshold, s.
    step_min_interval_s: shortest step interval, s (spec 0.25; default 0.35 = cadence ≤ 2.9 Hz).
    step_max_interval_s: longest step interval inside a bout, s (spec 1.5; default 2.0 = cadence ≥ 0.5 Hz).
    min_bout_steps: fewest successive peaks making a walking bout (thesis 3).
    upright_deg: reject a bout whose mean θ exceeds this, deg (spec 30).
    stairs_var_g2: var(GA_v) above which a bout is non-level, g² (thesis-unspecified; fitted, see docs).
    stairs_up_gf_g: mean GA_f (area / duration) above which a non-level bout is upstairs, g (fitted).
    stairs_mode: ``"thesis"`` (var(GA_v) and GA_f thresholds) or ``"relative"`` (extension: per-second
        cadence and vertical-acceleration ratios to the participant's own level walking).
    stairs_cadence_ratio: relative mode, a second is stairs if its cadence / the participant's median
        walking cadence is below this.
    stairs_lean_deg: relative mode, up if the mean lean of the bout exceeds the walking lean by this, deg.
    timeline: ``"events"`` (spec §4.5: posture changes only at detected transitions) or ``"hybrid"``
        (extension: lying straight from θ, sit/stand also from the static lean relative to the upright
        reference when no transition decides).
    sit_lean_deg: hybrid mode, static lean relative to the upright reference above which a still period
        with no deciding transition is sitting, and the posture evidence of ``sitstand_resolve``, deg.
    nonwear_std_g: a minute is motionless if every axis' std over the minute is below the threshold, g: this
        value when nonwear_noise_factor = 0, else the cap of the adaptive threshold (van Hees 2013: 13 mg).
    nonwear_noise_factor: adaptive non-wear threshold = this × the recording's own noise floor (5th percentile
        of the per-minute smallest-axis std); a worn chest sensor shows breathing on at least one axis, a
        sensor on a table only its noise (extension).
    nonwear_min_s: motionless (all three axes) for at least this long is non-wear, s (CHOICE: 30 min; any
        orientation, no context rule).
    clip_fraction_warn: warn when more than this fraction of samples sits at the range limit.
    """
    ga_mode: str = "lfilter"
    ga_cutoff_hz: float = 0.25
    ga_ripple_db: float = 0.01
    ga_stop_db: float = 100.0
    theta_mode: str = "direction"
    align: str = "upright_reference"
    autocalibrate: bool = True
    lying_deg: float = 70.0
    lying_hysteresis_deg: float = 3.0
    lying_static_g: float = 0.8
    side_lying: bool = True
    static_std_g: float = 0.05
    static_search_s: float = 5.0
    sitstand_deg: float = 20.0
    max_transition_s: float = 8.0
    minima_search_s: float = 5.0
    minima_tolerance_deg: float = 0.0
    thigh_length_m: float = 0.43
    dy_fraction: float = 0.35
    dy_pad_s: float = 1.0
    sitstand_sign: str = "dy"
    sitstand_resolve: bool = True
    dy_source: str = "norm"
    svm_walk_source: str = "vertical"
    step_highpass_hz: float = 0.5
    step_lowpass_hz: float = 3.0
    step_threshold_g: float = 0.03
    step_relative: float = 0.5
    step_rms_window_s: float = 4.0
    step_min_interval_s: float = 0.35
    step_max_interval_s: float = 2.0
    min_bout_steps: int = 3
    upright_deg: float = 30.0
    stairs_var_g2: float = 4e-4
    stairs_up_gf_g: float = 0.12
    stairs_mode: str = "relative"
    stairs_cadence_ratio: float = 0.88
    stairs_lean_deg: float = 4.0
    timeline: str = "hybrid"
    sit_lean_deg: float = 18.0
    nonwear_std_g: float = 0.013
    nonwear_noise_factor: float = 1.4
    nonwear_min_s: float = 1800.0
    clip_fraction_warn: float = 0.001

    def __post_init__(self):
        for name, allowed in (("ga_mode", ("lfilter", "filtfilt")), ("align", ("none", "upright_reference")),
                              ("dy_source", ("ga", "raw", "norm")), ("sitstand_sign", ("ci", "dy")), ("svm_walk_source", ("ga", "raw", "vertical")),
                              ("stairs_mode", ("thesis", "relative")), ("timeline", ("events", "hybrid")),
                              ("theta_mode", ("thesis", "direction"))):
            if getattr(self, name) not in allowed:
                raise ValueError(f"ActivityParams.{name} must be one of {allowed}, got {getattr(self, name)!r}")
        if self.thigh_length_m <= 0 or self.step_min_interval_s <= 0 or self.min_bout_steps < 1:
            raise ValueError("ActivityParams: thigh_length_m, step_min_interval_s > 0 and min_bout_steps >= 1")


#: thesis-literal (sensor axes as mounted, GA everywhere, event-driven timeline, var/area stair rule) and the
#: project default (extensions switched on). Stair thresholds of the thesis preset are thesis-unspecified.
PRESETS = MappingProxyType({
    "thesis": ActivityParams(align="none", autocalibrate=False, side_lying=False, dy_source="ga",
                             svm_walk_source="ga", step_threshold_g=0.015, step_relative=0.0,
                             step_min_interval_s=0.25, step_max_interval_s=1.5, dy_fraction=0.5, dy_pad_s=0.0, sitstand_sign="ci", sitstand_resolve=False, minima_tolerance_deg=0.0, stairs_mode="thesis",
                             timeline="events", theta_mode="thesis"),
    "default": ActivityParams(),
})


@dataclass(frozen=True)
class AccCalibration:
    """Accelerometer auto-calibration: ``calibrated_g = (raw_g - offset_g) * gain``.

    offset_g: (3,) g; gain: (3,) dimensionless; status: ``"sphere_fit"`` (full 6-parameter fit),
    ``"gain_only"`` (still orientations too few for a sphere fit; common gain from the median still
    norm), ``"none"`` (disabled or no still data); n_still: still 10-s windows used; rms_error_g: RMS of
    ‖a‖ − 1 over them after calibration.
    """
    offset_g: np.ndarray
    gain: np.ndarray
    status: str
    n_still: int
    rms_error_g: float


@dataclass(frozen=True)
class Transitions:
    """Detected postural transitions (thesis §7.2.4-7.2.5), sorted by time.

    t_s: (K,) instant, s from the recording start (StSi/SiSt: mid-point of the θ-minima window;
    lying: the 70° crossing). kind: (K,) int8 index into ``TRANSITIONS``. start_s, end_s: (K,) window, s.
    dy_m: (K,) chest height change ΔY, m (Eq. 56; NaN for lying transitions).
    """
    t_s: np.ndarray
    kind: np.ndarray
    start_s: np.ndarray
    end_s: np.ndarray
    dy_m: np.ndarray

    def __len__(self) -> int:
        return int(self.t_s.shape[0])


@dataclass(frozen=True)
class Bouts:
    """Walking bouts (thesis §7.2.6). start_s, end_s: (B,) s from the recording start (first step peak
    − half an interval, last step peak + half an interval); steps: (B,) int; modality: (B,) int8 class
    code (LEVEL, UP, DOWN); cadence_steps_min: (B,); var_gav_g2, mean_gaf_g: (B,) thesis features."""
    start_s: np.ndarray
    end_s: np.ndarray
    steps: np.ndarray
    modality: np.ndarray
    cadence_steps_min: np.ndarray
    var_gav_g2: np.ndarray
    mean_gaf_g: np.ndarray

    def __len__(self) -> int:
        return int(self.start_s.shape[0])


@dataclass(frozen=True)
class ActivityResult:
    """Output of ``classify_day``.

    second_t_ns: (S,) int64 UTC start of each whole second of the recording (t0_ns + k s).
    second_class: (S,) int8 index into ``CLASSES`` — every second has a class.
    step_times_s: (P,) accepted step instants, s from the start; step_modality: (P,) int8 class code.
    bouts, transitions: see ``Bouts`` and ``Transitions``.
    inclination_deg: (S,) per-second mean trunk inclination θ (Eq. 54) in the analysis frame, deg.
    calibration: ``AccCalibration``; upright_ref: (W, 3) unit gravity direction of the upright posture per
    wear period in the (calibrated) sensor frame; clipped_fraction: samples at the range limit.
    warnings: human-readable notes (clipping, no walking, calibration fallback, state inconsistencies).
    sampling_rate_hz, t0_ns, timezone, params: what produced it.
    """
    second_t_ns: np.ndarray
    second_class: np.ndarray
    step_times_s: np.ndarray
    step_modality: np.ndarray
    bouts: Bouts
    transitions: Transitions
    inclination_deg: np.ndarray
    calibration: AccCalibration
    upright_ref: np.ndarray
    clipped_fraction: float
    warnings: tuple
    sampling_rate_hz: float
    t0_ns: int
    timezone: str
    params: ActivityParams = field(repr=False, default=ActivityParams())

    def class_names(self) -> np.ndarray:
        """(S,) class names per second."""
        return np.asarray(CLASSES)[self.second_class]


@dataclass(frozen=True)
class DailySummary:
    """One local calendar day (the participant's timezone; DST days have 23 or 25 h).

    date: ISO local date; day_start_ns, day_end_ns: UTC ns of local midnight and of the next one;
    day_length_s: their difference (82800, 86400 or 90000 s); recorded_s: seconds of this day inside the
    recording; seconds: class name -> seconds; steps: walking class -> steps; transitions: kind -> count;
    n_bouts: walking bouts starting this day; bout_s_median, bout_s_max: walking-bout durations, s (0 if none);
    wear_s: recorded_s − non-wear seconds.
    """
    date: str
    day_start_ns: int
    day_end_ns: int
    day_length_s: int
    recorded_s: int
    wear_s: int
    seconds: dict
    steps: dict
    transitions: dict
    n_bouts: int
    bout_s_median: float
    bout_s_max: float

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}
