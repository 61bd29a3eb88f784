"""``analyse_trunk_gait`` and ``detect_trunk_frame``: the trunk-gait pipeline on arrays.

Order (Micó-Amigo et al. 2023, "Assessing real-world gait with digital technology? Validation, insights and
recommendations from the Mobilise-D consortium", J NeuroEng Rehabil 20:78, doi:10.1186/s12984-023-01198-5, Fig. 7):
gait sequences -> body frame -> per sequence initial contacts, side, step lengths, turns -> strides -> walking
bouts (Kluge et al. 2021) -> per-bout cadence, stride length, walking speed.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from stridelab.estimators.trunk_gait._frame import check_units, frame_from_axes, frame_from_sequences
from stridelab.estimators.trunk_gait._gsd import detect_gait_sequences
from stridelab.estimators.trunk_gait._icd import (assign_sides, detect_initial_contacts, kind_offsets_s,
                                                  parabolic_peaks, regular_runs)
from stridelab.estimators.trunk_gait._icd_cwt import (detect_initial_contacts_hklee, detect_initial_contacts_shin,
                                                     refine_to_peaks)
from stridelab.estimators.trunk_gait._icd_ionescu import detect_initial_contacts_ionescu
from stridelab.estimators.trunk_gait._spatial import (hampel, step_heading_change, step_lengths, step_tilt_deg,
                                                      turn_shortened, vertical_position)
from stridelab.estimators.trunk_gait._turns import EMPTY_TURNS, detect_turns
from stridelab.estimators.trunk_gait._types import (DEFAULT_HEIGHT_M, LEG_LENGTH_PER_HEIGHT, PLACEMENTS, Bouts, Strides,
                                          TrunkFrame, TrunkGaitParams, TrunkGaitResult, Turns)
from stridelab.estimators.trunk_gait._wba import assemble_bouts, strides_from_contacts

LOW_FRAME_CONFIDENCE = 0.2


def _sequences(acc: np.ndarray, fs_hz: float, p: TrunkGaitParams) -> np.ndarray:
    return detect_gait_sequences(acc, fs_hz, window_s=p.gsd_window_s, hop_s=p.gsd_hop_s,
                                 min_std_m_s2=p.gsd_min_std_m_s2, min_autocorr=p.gsd_min_autocorr,
                                 merge_gap_s=p.gsd_merge_gap_s, slow_min_std_m_s2=p.gsd_slow_min_std_m_s2,
                                 slow_min_autocorr=p.gsd_slow_min_autocorr)


def bout_cadence(ic_s: np.ndarray, *, max_step_s: float, method: str) -> float:
    """Steps per minute of one bout from its sorted initial contacts (NaN with fewer than two).

    "median": 60 / the median step time (robust to a missed or an extra contact). "count": steps per time,
    60 Σ n_i / Σ d_i over the step intervals d_i ≤ ``max_step_s`` (longer ones are pauses), where an interval
    counts n_i = max(1, round(d_i / T)) steps with T the median step time, so a missed contact (d ≈ 2 T)
    counts as the two steps it spans: the bout's step count over its walking time, the definition of the
    reference cadence of Mobilise-D (steps per minute of the walking bout, Micó-Amigo et al. 2023) and of the
    Voisard reference (60 (n - 1) / span), which differs from the median where step times vary (turns, the
    slower first and last steps). "step_mean": the mean over the steps of the instantaneous cadence 60 / d_i
    (d_i ≤ ``max_step_s``), the per-step average, which the Mobilise-D INDIP reference cadence of a walking bout
    approaches (within 1-2 steps/min of the mean of 60 / step time of its own contacts on HA-001, gaps included;
    its exact definition is "stride_mean"). "per_second": ``per_second_cadence``, mobgap's robust per-second cadence averaged over
    the bout. "stride_mean": the mean over the bout's strides IC_i -> IC_{i+2} (at most 2 ``max_step_s``, a stride
    across a short stop included, Kluge et al. 2021) of the stride cadence 120 / stride time (two steps per
    stride): the definition of the Mobilise-D INDIP reference cadence of a walking bout (Micó-Amigo et al. 2023:
    bout values are the means of their stride values; its per-bout Cadence of HA-001 equals the mean of 120 /
    stride time of its own contacts to 0.1 steps/min in 7 of 8 bouts, the eighth holds a duplicated contact,
    2026-12-08), and mobgap's per-bout value is likewise a mean over strides (``_aggregate_per_wb``)."""
    if method == "per_second":
        return per_second_cadence(ic_s, max_step_s=max_step_s)
    if method == "stride_mean":
        ic = np.sort(np.asarray(ic_s, float))
        st = ic[2:] - ic[:-2] if len(ic) >= 3 else np.empty(0)
        st = st[(st > 0) & (st <= 2.0 * max_step_s)]
        return float(np.mean(120.0 / st)) if len(st) else float("nan")
    d = np.diff(ic_s)
    d = d[d <= max_step_s]
    if len(d) == 0:
        return float("nan")
    T = float(np.median(d))
    if method == "median":
        return 60.0 / T
    if method == "step_mean":
        return float(np.mean(60.0 / d[d > 0]))
    if method != "count":
        raise ValueError(f"cadence_method must be one of {CADENCE_METHODS}, got {method!r}")
    n = np.maximum(1.0, np.rint(d / T))
    return 60.0 * float(n.sum()) / float(d.sum())


def bout_spatial(length_m: np.ndarray, duration_s: np.ndarray, bout: np.ndarray, cadence_spm: np.ndarray, *,
                 average: str, strides: str, speed_method: str, tilt_deg: np.ndarray | None = None,
                 max_tilt_deg: float = 0.0, steady: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(stride length m, walking speed m/s) per bout from its strides: (S,) ``length_m``, ``duration_s``, ``bout``
    (index 0..B-1) and the bouts' (B,) ``cadence_spm``.

    ``strides``: "regular" = only strides lasting ≤ 1.5 x the bout's median stride duration (a longer one may span
    a missed contact, three steps measured as two), "all" = every stride of the bout (the reference definitions:
    INDIP's bout stride length and walking speed are the means over all its strides, Voisard's foot-INS reference
    likewise). ``average``: "mean" | "median" over those strides, or "time" = their mean weighted by stride
    duration (the bout's time average of the stride values; mobgap interpolates the stride values onto one value per
    second and averages those over the bout, Micó-Amigo et al. 2023, which weighs strides by duration as well).
    ``speed_method``: "stride" = the same average of
    the stride speeds (length / duration); "cadence" = bout stride length x cadence / 120 (steps/min -> strides/s;
    mobgap's walking speed, Micó-Amigo et al. 2023 / Kirk et al. 2024: speed = cadence x stride length / 2 per
    second), which does not divide a noisy length by a noisy duration stride by stride. ``max_tilt_deg`` > 0: strides
    whose trunk leans more than that from the walking posture (``tilt_deg`` (S,), ``_spatial.step_tilt_deg``) are
    left out, unless that would leave the bout without a stride (0 = off). ``steady`` (S,) bool: strides over a stop
    (False; kept by ``stride_rule`` "consensus" for the bout rules) are left out likewise: the inverted-pendulum
    step length is not defined across a stop (None = all strides)."""
    if average not in ("mean", "median", "time"):
        raise ValueError(f"bout_average must be 'mean', 'median' or 'time', got {average!r}")
    if strides not in ("regular", "all"):
        raise ValueError(f"bout_strides must be 'regular' or 'all', got {strides!r}")
    if speed_method not in ("stride", "cadence"):
        raise ValueError(f"speed_method must be 'stride' or 'cadence', got {speed_method!r}")
    n_b = len(cadence_spm)
    length_m = np.asarray(length_m, float)
    duration_s = np.asarray(duration_s, float)
    sl = np.full(n_b, np.nan)
    sp = np.full(n_b, np.nan)
    for b in range(n_b):
        m = bout == b
        if not m.any():
            continue
        if strides == "regular":
            m = m & (duration_s <= 1.5 * np.median(duration_s[m]))
        if steady is not None and (m & steady).any():
            m = m & steady
        if max_tilt_deg > 0 and tilt_deg is not None and (m & (tilt_deg <= max_tilt_deg)).any():
            m = m & (tilt_deg <= max_tilt_deg)
        x, d = length_m[m], duration_s[m]
        if average == "median":
            sl[b], sp[b] = np.median(x), np.median(x / d)
        elif average == "mean":
            sl[b], sp[b] = np.mean(x), np.mean(x / d)
        else:
            sl[b], sp[b] = np.sum(x * d) / np.sum(d), np.sum(x) / np.sum(d)
        if speed_method == "cadence":
            sp[b] = sl[b] * cadence_spm[b] / 120.0
    return sl, sp


IC_METHODS = ("peak", "ionescu", "shin", "hklee")


def _refine(pos: np.ndarray, v: np.ndarray, fs_hz: float, p: TrunkGaitParams) -> np.ndarray:
    """``pos`` (float or int sample positions) moved to the highest sample of the smoothed upward acceleration
    within ± ``p.ic_refine_s`` (``refine_to_peaks``); unchanged when that is 0."""
    if p.ic_refine_s <= 0 or len(pos) == 0:
        return pos
    vs = gaussian_filter1d(v, p.ic_smooth_s * fs_hz, mode="nearest")
    return refine_to_peaks(np.rint(pos).astype(np.int64), vs, max(1, int(round(p.ic_refine_s * fs_hz))),
                           max(1, int(round(p.ic_min_step_s * fs_hz))))


def per_second_cadence(ic_s: np.ndarray, *, max_step_s: float, half_width: int = 2, n_sigma: float = 3.0,
                       max_gap_s: int = 3) -> float:
    """Mean over the bout's seconds of 60 / (robust step time of that second), steps/min (NaN with fewer than
    ``2 half_width + 2`` contacts).

    After the Mobilise-D cadence (Micó-Amigo et al. 2023, Additional file 1, CADB/CADC; mobgap 1.2.0
    ``CadFromIc``, our re-implementation): step times d_i = t_{i+1} - t_i (the last repeated for the last contact)
    are cleaned by a Hampel filter (``half_width`` steps, ``n_sigma`` MADs: a missed or an extra contact gives one
    step time twice or half the others), averaged per one-second bin of the bout (the bin of the contact that
    starts the step), cleaned again by the same Hampel filter over the seconds, bins without a contact are
    interpolated linearly when the gap is at most ``max_gap_s`` s; the bout's cadence is the mean of 60 / step
    time over its seconds (time-weighted, as the per-second values are mapped to the bout in mobgap). Deviation:
    step times above ``max_step_s`` (pauses) are left out before the filter."""
    from stridelab.estimators.trunk_gait._spatial import hampel
    ic = np.sort(np.asarray(ic_s, float))
    if len(ic) < 2 * half_width + 2:
        return float("nan")
    d = np.diff(ic)
    d = np.r_[d, d[-1]]
    ok = d <= max_step_s
    if ok.sum() < 2 * half_width + 1:
        return float("nan")
    t, d = ic[ok], hampel(d[ok], half_width, n_sigma)
    sec = np.floor(t - ic[0]).astype(np.int64)
    n_sec = int(np.floor(ic[-1] - ic[0])) + 1
    cnt = np.bincount(sec, minlength=n_sec)
    per = np.full(n_sec, np.nan)
    has = cnt > 0
    per[has] = np.bincount(sec, weights=d, minlength=n_sec)[has] / cnt[has]
    per = hampel(per, half_width, n_sigma)
    fin = np.isfinite(per)
    if not fin.any():
        return float("nan")
    idx = np.arange(n_sec)
    fill = np.interp(idx, idx[fin], per[fin])
    # a gap longer than max_gap_s stays empty (mobgap: not interpolated)
    gap_id = np.cumsum(fin)
    gap_len = np.bincount(gap_id[~fin], minlength=int(gap_id.max()) + 1)
    use = fin | ((~fin) & (gap_len[gap_id] <= max_gap_s))
    return float(np.mean(60.0 / fill[use]))


CADENCE_METHODS = ("median", "count", "step_mean", "per_second", "stride_mean")


def _contacts(v: np.ndarray, fs_hz: float, p: TrunkGaitParams, turning: np.ndarray | None = None,
              acc_seq: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(sample positions, closing (K,) bool: closing steps added by the fill, kinds (K,) int8: how each was found,
    ``_icd.IC_KINDS``; see ``_icd.detect_initial_contacts``).
    Positions are float for "shin" (sub-sample zero crossings), else integer sample indices. ``acc_seq`` (N, 3):
    the sequence's acceleration, for the norm input of "shin" / "hklee"."""
    if p.ic_method == "ionescu":
        idx = detect_initial_contacts_ionescu(v, fs_hz, sigma_s=p.ic_zc_sigma_s, min_depth=p.ic_zc_min_depth,
                                              min_step_s=p.ic_min_step_s)
        idx = _refine(idx, v, fs_hz, p)
        return idx, np.zeros(len(idx), bool), np.zeros(len(idx), np.int8)
    if p.ic_method in ("shin", "hklee"):
        if p.ic_cwt_signal == "norm" and acc_seq is not None:
            x = np.sqrt(np.einsum("ij,ij->i", acc_seq, acc_seq))
        elif p.ic_cwt_signal in ("norm", "vertical"):
            x = v
        else:
            raise ValueError(f"ic_cwt_signal must be 'norm' or 'vertical', got {p.ic_cwt_signal!r}")
        det = detect_initial_contacts_shin if p.ic_method == "shin" else detect_initial_contacts_hklee
        idx = _refine(det(x, fs_hz, min_step_s=p.ic_min_step_s, min_height=p.ic_zc_min_depth), v, fs_hz, p)
        return idx, np.zeros(len(idx), bool), np.zeros(len(idx), np.int8)
    if p.ic_method != "peak":
        raise ValueError(f"ic_method must be one of {IC_METHODS}, got {p.ic_method!r}")
    idx, closing, kinds = detect_initial_contacts(v, fs_hz, smooth_s=p.ic_smooth_s, min_step_s=p.ic_min_step_s,
                                           prominence=p.ic_prominence, local_window_s=p.ic_local_window_s,
                                           fill_prominence=p.ic_fill_prominence,
                                           fill_edge_steps=p.ic_fill_edge_steps, fill_end_steps=p.ic_fill_end_steps,
                                           fill_start_prominence=p.ic_fill_start_prominence,
                                           fill_end_rhythm=p.ic_fill_end_rhythm, fill_walk_ends=p.ic_fill_walk_ends,
                                           max_step_s=p.stride_max_s / 2.0, turning=turning,
                                           turn_prominence=p.ic_turn_prominence, return_kinds=True)
    if p.ic_subsample and len(idx):
        idx = parabolic_peaks(gaussian_filter1d(v, p.ic_smooth_s * fs_hz, mode="nearest"), idx)
    return idx, closing, kinds


def detect_trunk_frame(acc: np.ndarray, gyr: np.ndarray | None, fs_hz: float, *,
                       params: TrunkGaitParams = TrunkGaitParams()) -> TrunkFrame:
    """Sensor-to-body frame of a trunk sensor from its data (see ``stridelab.estimators.trunk_gait._frame``).

    acc (N, 3) m/s², gyr (N, 3) rad/s or None (not needed for the frame), fs_hz > 0. The body frame is ISB:
    x anterior, y up, z right; ``frame.R @ v_sensor`` gives body coordinates. Walking is found first (gait-sequence
    detection) and only walking samples are used; without walking the vertical comes from all samples and the
    anterior axis is undetermined (a warning says so).
    """
    acc = np.ascontiguousarray(acc, dtype=np.float64)
    check_units(acc, None if gyr is None else np.asarray(gyr, float), fs_hz)
    return frame_from_sequences(acc, fs_hz, _sequences(acc, fs_hz, params))


def _body_height(height_m, leg_length_m) -> tuple[float, float, str, str]:
    if height_m is None or not np.isfinite(height_m):
        h, hsrc = DEFAULT_HEIGHT_M, f"default ({DEFAULT_HEIGHT_M:.2f} m, documented)"
    else:
        if not 0.5 < float(height_m) < 2.6:
            raise ValueError(f"height_m is {height_m}: expected the body height in metres (0.5-2.6)")
        h, hsrc = float(height_m), "given"
    if leg_length_m is None or not np.isfinite(leg_length_m):
        return h, LEG_LENGTH_PER_HEIGHT * h, hsrc, f"from height ({LEG_LENGTH_PER_HEIGHT} H)"
    if not 0.3 < float(leg_length_m) < 1.5:
        raise ValueError(f"leg_length_m is {leg_length_m}: expected the leg length in metres (0.3-1.5)")
    return h, float(leg_length_m), hsrc, "given"


def analyse_trunk_gait(acc_m_s2: np.ndarray, gyr_rad_s: np.ndarray, fs_hz: float, *, placement: str = "lower_back",
                       height_m: float | None = None, leg_length_m: float | None = None,
                       params: TrunkGaitParams = TrunkGaitParams()) -> TrunkGaitResult:
    """Walking bouts, initial contacts with side, cadence, stride length, walking speed and turns from one trunk
    sensor (lower back at L4/L5 or chest).

    acc_m_s2, gyr_rad_s: (N, 3) in any sensor orientation (the frame is detected, ``detect_trunk_frame``);
    fs_hz: sampling rate. height_m / leg_length_m: body height and leg length (pendulum length of the stride-length
    model); when unknown the documented defaults are used and every bout is flagged ``default_height``.
    Times in the result are seconds from the first sample. No walking -> empty, typed result and a warning.
    """
    if placement not in PLACEMENTS:
        raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
    acc = np.ascontiguousarray(acc_m_s2, dtype=np.float64)
    gyr = np.ascontiguousarray(gyr_rad_s, dtype=np.float64)
    check_units(acc, gyr, fs_hz)
    p = params
    height, leg, hsrc, lsrc = _body_height(height_m, leg_length_m)
    seqs = _sequences(acc, fs_hz, p)
    frame = frame_from_sequences(acc, fs_hz, seqs) if len(acc) else None
    warnings = list(frame.warnings) if frame is not None else ["no samples"]
    ic_all, left_all, run_all, step_all, closing_all, tilt_all, kind_all = [], [], [], [], [], [], []
    ic_rep_all = []
    turns: list[Turns] = []
    run_offset = 0
    offset_n = p.ic_offset_s
    for s, e in seqs:
        a = acc[s:e]
        up = a.mean(axis=0)
        R = frame_from_axes(up, frame.R[0])          # local vertical, global heading of the anterior axis
        ab = a @ R.T
        gb = gyr[s:e] @ R.T
        v = ab[:, 1] - ab[:, 1].mean()
        tt = detect_turns(gb[:, 1], fs_hz, t0_s=s / fs_hz, lowpass_hz=p.turn_lowpass_hz,
                          min_peak_deg_s=p.turn_min_peak_deg_s, edge_deg_s=p.turn_edge_deg_s,
                          min_angle_deg=p.turn_min_angle_deg, min_s=p.turn_min_s, max_s=p.turn_max_s)
        turning = None
        if p.ic_turn_prominence != 1.0 and len(tt):
            turning = np.zeros(e - s, bool)
            for a0, a1 in zip(tt.start_s, tt.end_s):
                turning[max(0, int(round(a0 * fs_hz)) - s):max(0, int(round(a1 * fs_hz)) - s)] = True
        ic_pos, closing, kinds = _contacts(v, fs_hz, p, turning, a)
        t = (s + ic_pos) / fs_hz + offset_n
        # the per-kind offsets time the reported heel strikes only; strides, bouts and cadence keep the contact
        # times of the one constant offset (the walk-end and fill contacts are not re-spaced)
        ic_rep_all.append(t + kind_offsets_s(kinds, fill_offset_s=p.ic_fill_offset_s,
                                             walk_end_offset_s=p.ic_walk_end_offset_s))
        peaks = np.clip(np.rint(ic_pos).astype(np.int64), 0, max(e - s - 1, 0))
        runs = regular_runs(t, max_step_s=p.stride_max_s / 2.0) + run_offset
        # a closing step gets a run of its own: no stride starts or ends there (the reference walking bouts of
        # Mobilise-D end with the last complete stride), it still is a contact of the bout it closes
        if closing.any():
            runs[closing] = runs.max() + 1 + np.arange(int(closing.sum()))
        run_offset = int(runs.max()) + 1 if len(runs) else run_offset
        left = assign_sides(gb[:, 1], fs_hz, peaks, runs, lag_s=p.side_lag_s, lowpass_hz=p.side_lowpass_hz)
        pos = vertical_position(v, fs_hz, p.sl_highpass_hz)
        sl = step_lengths(pos, peaks, leg, p.sl_correction)
        if p.sl_turn_per_rad > 0 and len(sl):
            sl = turn_shortened(sl, step_heading_change(gb[:, 1], fs_hz, peaks), p.sl_turn_per_rad)
        if p.sl_hampel_half_width > 0 and len(sl):
            # a step is only compared with steps of the same run; a step across a pause (two runs) stands alone
            same = runs[1:] == runs[:-1]
            sl = hampel(sl, p.sl_hampel_half_width, 3.0, np.where(same, runs[1:], -1 - np.arange(len(sl))))
        ic_all.append(t)
        closing_all.append(closing)
        kind_all.append(kinds)
        left_all.append(left)
        run_all.append(runs)
        step_all.append(np.r_[sl, np.nan] if len(peaks) else np.empty(0))   # step i -> i+1; last has none
        tilt_all.append(np.r_[step_tilt_deg(ab, peaks), np.nan] if len(peaks) else np.empty(0))
        turns.append(tt)
    cat = lambda xs, dt: np.concatenate(xs) if xs else np.empty(0, dt)  # noqa: E731
    ic = cat(ic_all, float)
    ic_rep = cat(ic_rep_all, float)
    left = cat(left_all, bool)
    runs = cat(run_all, np.int64)
    closing = cat(closing_all, bool)
    kind = cat(kind_all, np.int8)
    step_len = cat(step_all, float)
    turn = Turns(*(cat([getattr(tt, f) for tt in turns], float)
                   for f in ("start_s", "end_s", "angle_deg", "peak_rate_deg_s"))) if turns else EMPTY_TURNS

    kw = dict(rule=p.stride_rule, max_stride_s=p.stride_max_s, no_start=closing)
    first, st, en, length = strides_from_contacts(ic, runs, step_len, **kw)
    steady = runs[first] == runs[first + 2] if len(first) else np.zeros(0, bool)
    stride_tilt = strides_from_contacts(ic, runs, cat(tilt_all, float), **kw)[3] / 2.0     # mean of its two steps
    dur = en - st
    valid = (dur >= p.stride_min_s) & (dur <= p.stride_max_s) & (np.nan_to_num(length) >= p.stride_min_length_m)
    bout_of = assemble_bouts(st, en, valid, max_break_s=p.wb_max_break_s, min_strides=p.wb_min_strides)
    in_b = bout_of >= 0
    n_b = int(bout_of.max()) + 1 if in_b.any() else 0
    strides = Strides(start_s=st[in_b], end_s=en[in_b], side=np.where(left[first[in_b]], "left", "right"),
                      length_m=length[in_b], speed_m_s=length[in_b] / dur[in_b], bout=bout_of[in_b],
                      tilt_deg=stride_tilt[in_b], steady=steady[in_b])
    b_start = np.array([strides.start_s[strides.bout == b].min() for b in range(n_b)])
    b_end = np.array([strides.end_s[strides.bout == b].max() for b in range(n_b)])
    ic_bout = np.full(len(ic), -1, np.int64)
    for b in range(n_b):
        ic_bout[(ic >= b_start[b] - 1e-9) & (ic <= b_end[b] + 1e-9)] = b
    for k in np.flatnonzero(closing):        # a closing step belongs to the bout of the contact before it
        if k > 0 and ic_bout[k] < 0 and ic_bout[k - 1] >= 0 and ic[k] - ic[k - 1] <= p.stride_max_s / 2.0:
            ic_bout[k] = ic_bout[k - 1]
    n_ic = np.bincount(ic_bout[ic_bout >= 0], minlength=n_b)
    n_steps = np.maximum(n_ic - 1, 0)
    cadence = np.array([bout_cadence(ic[(ic_bout == b) & ~closing], max_step_s=p.stride_max_s / 2.0,
                                     method=p.cadence_method) for b in range(n_b)])
    n_str = np.bincount(strides.bout, minlength=n_b)
    # the speed's cadence: steps over walking time ("count"), distance over time whatever cadence is reported
    cad_count = cadence if p.cadence_method == "count" else np.array(
        [bout_cadence(ic[(ic_bout == b) & ~closing], max_step_s=p.stride_max_s / 2.0, method="count")
         for b in range(n_b)])
    sl_b, sp_b = bout_spatial(strides.length_m, dur[in_b], strides.bout, cad_count, average=p.bout_average,
                              strides=p.bout_strides, speed_method=p.speed_method, tilt_deg=strides.tilt_deg,
                              max_tilt_deg=p.sl_max_tilt_deg, steady=strides.steady)
    n_turns = np.array([int(np.sum((turn.start_s < b_end[b]) & (turn.end_s > b_start[b]))) for b in range(n_b)],
                       np.int64)
    flags = []
    common = []
    if hsrc != "given" and lsrc != "given":
        common.append("default_height")
    if frame is not None and frame.confidence < LOW_FRAME_CONFIDENCE:
        common.append("low_frame_confidence")
    if placement == "chest":
        common.append("chest_stride_length_model")
    for _ in range(n_b):
        flags.append(tuple(common))
    if n_b == 0:
        warnings.append("no walking bout found")
    bouts = Bouts(start_s=b_start, end_s=b_end, n_steps=n_steps.astype(np.int64), n_strides=n_str.astype(np.int64),
                  cadence_spm=cadence, stride_length_m=sl_b, walking_speed_m_s=sp_b, n_turns=n_turns,
                  flags=tuple(flags))
    keep_ic = ic_bout >= 0
    empty_frame = TrunkFrame(R=np.eye(3), confidence=0.0, vertical_axis=1, vertical_sign=1, anterior_axis=0,
                             anterior_sign=1, walking_found=False, warnings=("no samples",))
    return TrunkGaitResult(bouts=bouts, strides=strides, turns=turn, initial_contacts_s=ic_rep[keep_ic],
                           ic_side=np.where(left[keep_ic], "left", "right"),
                           gait_sequences_s=seqs.astype(float) / fs_hz, frame=frame or empty_frame,
                           height_m=height, leg_length_m=leg, height_source=hsrc, leg_length_source=lsrc,
                           placement=placement, params=p, warnings=tuple(warnings), ic_closing=closing[keep_ic],
                           ic_kind=kind[keep_ic])
