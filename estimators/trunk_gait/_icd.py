"""Initial contacts and their side from the trunk, within one gait sequence (body-frame signals).

Initial contacts: McCamley et al. 2012, "An enhanced estimate of initial contact and final contact instants of time
using lower trunk inertial sensor data", Gait Posture 36:316, doi:10.1016/j.gaitpost.2012.02.019: the vertical
acceleration is integrated and differentiated with a Gaussian continuous wavelet; initial contacts are the
extrema of that signal. Integrating and then differentiating with a first-derivative-of-Gaussian wavelet equals
Gaussian smoothing of the vertical acceleration, which is what we do (σ = ``ic_smooth_s``). Deviation: our vertical
axis points up (McCamley's acceleration is taken positive downwards), so the initial contact is a *maximum* of
the upward acceleration (the double-support rebound of the centre of mass, Zijlstra & Hof 2003); a constant offset
``ic_offset_s`` maps that peak to the heel strike (chosen by cross-validation, validation/provenance.toml).
Peaks are kept at least ``ic_min_step_s`` apart and with a prominence of at least ``ic_prominence`` standard
deviations of the smoothed signal in the sequence (robust to the small accelerations of slow walking at 0.3 m/s,
where an absolute threshold would fail).

Side: McCamley et al. 2012 assign the side from the sign of the angular velocity about the vertical axis around
each initial contact. The pelvis rotates its swing side forward before heel strike, so the yaw rate (about *up*,
right-hand rule: counter-clockwise seen from above, low-passed at ``side_lowpass_hz``) read ``side_lag_s`` from the
contact (negative = before) is positive before a *right* initial contact. Single votes agree with the references
in about 80 % of contacts on the Voisard L5 trials and on the Mobilise-D lab trials alike (the roll rate, which
we tried first, agreed in 91 % on Voisard but in 10 % on Mobilise-D: not a placement-independent cue). Because
steps alternate, each run of regularly spaced contacts gets the alternating labelling that agrees with most votes
(Ullrich et al. 2022, Sensors 22:6463, doi:10.3390/s22176463, use the same alternation after their classifier),
which corrects isolated wrong votes.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d
from scipy.signal import find_peaks

from stridelab.estimators.trunk_gait._filters import butter_filtfilt

# how each contact was found (``detect_initial_contacts(..., return_kinds=True)``): a peak that passed the prominence
# threshold, a weaker peak filling a gap of about two steps, one before the first / after the last contact
# (``edge_steps``), the first step of a walk (``start_prominence``), a closing step placed by the rhythm
# (``end_rhythm_before``), a closing step at a weak peak
IC_KINDS = ("peak", "gap_fill", "edge_fill", "start_fill", "closing_rhythm", "closing_peak")


def detect_initial_contacts(v_up: np.ndarray, fs_hz: float, *, smooth_s: float, min_step_s: float,
                            prominence: float, local_window_s: float = 0.0, fill_prominence: float = 0.0,
                            fill_edge_steps: int = 0, fill_end_steps: int = 0, fill_start_prominence: float = 0.0,
                            fill_end_rhythm: bool = False, fill_walk_ends: bool = False,
                            max_step_s: float = 1.5, turning: np.ndarray | None = None,
                            turn_prominence: float = 1.0, return_closing: bool = False,
                            return_kinds: bool = False):
    """Sample indices of initial-contact peaks of the upward acceleration ``v_up`` (N,) m/s² (gravity removed).

    The prominence threshold is ``prominence`` × the standard deviation of the smoothed signal over the sequence,
    or, with ``local_window_s`` > 0, over a centred window of that length (slow turning steps keep their peaks
    between faster straight steps). With ``fill_prominence`` > 0 the steps the threshold missed are looked for
    where the rhythm says a step must be (``fill_missed_steps``). ``turning`` (N,) bool marks samples inside a
    turn, where the threshold is multiplied by ``turn_prominence`` (turning steps are shorter and lift the trunk
    less; on the Voisard U-turns about 40 % of the missed contacts). With ``return_closing`` the result is
    (indices, closing) where ``closing`` (K,) bool marks the contacts added after the last contact that passed
    the threshold (the closing steps of a walk: contacts, but no stride of steady walking starts or ends there);
    with ``fill_walk_ends`` also the closing steps added before every pause inside the sequence. With
    ``return_kinds`` the result is (indices, closing, kinds) with ``kinds`` (K,) int8 indices into ``IC_KINDS``."""
    empty = np.empty(0, np.int64)

    def result(idx, closing, kinds):
        if return_kinds:
            return idx, closing, kinds
        return (idx, closing) if return_closing else idx
    if len(v_up) < 3:
        return result(empty, np.zeros(0, bool), np.zeros(0, np.int8))
    vs = gaussian_filter1d(v_up, smooth_s * fs_hz, mode="nearest")
    sd = float(vs.std())
    if sd <= 0:
        return result(empty, np.zeros(0, bool), np.zeros(0, np.int8))
    peaks, props = find_peaks(vs, distance=max(1, int(round(min_step_s * fs_hz))), prominence=0.0)
    if local_window_s > 0:
        w = max(3, int(round(local_window_s * fs_hz)))
        m1 = uniform_filter1d(vs, w, mode="nearest")
        m2 = uniform_filter1d(vs * vs, w, mode="nearest")
        ref = np.sqrt(np.maximum(m2 - m1 * m1, 0.0))[peaks]
    else:
        ref = sd
    thr = prominence * ref
    if turning is not None and turn_prominence != 1.0:
        thr = np.where(turning[peaks], turn_prominence * thr, thr)
    strong = props["prominences"] >= thr
    if fill_prominence <= 0 or strong.sum() < 3:
        out = peaks[strong].astype(np.int64)
        closing = np.zeros(len(out), bool)
        kinds = np.zeros(len(out), np.int8)
    else:
        weak = props["prominences"] >= fill_prominence * sd
        out, closing, kinds = fill_missed_steps(
            peaks[strong], peaks[weak & ~strong], props["prominences"][weak & ~strong],
            max_step=max(1, int(round(max_step_s * fs_hz))), edge_steps=fill_edge_steps, end_steps=fill_end_steps,
            start_prominence=fill_start_prominence * sd if fill_start_prominence > 0 else None,
            end_rhythm_before=len(v_up) if fill_end_rhythm and fill_end_steps > 0 else 0, walk_ends=fill_walk_ends,
            return_kinds=True)
    return result(out, closing, kinds)


def parabolic_peaks(vs: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Sub-sample positions of the maxima of ``vs`` at integer indices ``idx``: the vertex of the parabola through
    the three samples around each, i + (y[i-1] - y[i+1]) / (2 (y[i-1] - 2 y[i] + y[i+1])), clipped to ± 0.5 sample;
    edge samples stay. Without it every contact time is a multiple of the sample period, as the references' are,
    so the timing errors and the loss of the offset choice move in steps of one sample (10 ms at 100 Hz)."""
    idx = np.asarray(idx, np.int64)
    out = idx.astype(float)
    ok = (idx > 0) & (idx < len(vs) - 1)
    i = idx[ok]
    y0, y1, y2 = vs[i - 1], vs[i], vs[i + 1]
    den = y0 - 2.0 * y1 + y2
    safe = np.where(den < 0, den, -1.0)
    d = np.where(den < 0, 0.5 * (y0 - y2) / safe, 0.0)
    out[ok] = i + np.clip(d, -0.5, 0.5)
    return out


def fill_missed_steps(kept: np.ndarray, cand: np.ndarray, cand_prom: np.ndarray, *, max_step: int,
                      edge_steps: int = 0, end_steps: int = 0, start_prominence: float | None = None,
                      end_rhythm_before: int = 0, walk_ends: bool = False, return_closing: bool = False,
                      return_kinds: bool = False):
    """Add weaker peaks where the step rhythm expects a contact the prominence threshold missed.

    The closing step of a walk, the first step and the steps of a turn give smaller vertical accelerations than
    straight steady steps (Zijlstra & Hof 2003: the trunk rebound scales with step length), so a single threshold
    misses them; steps nevertheless keep their rhythm (stride-to-stride time variability of a few per cent in
    healthy and impaired gait, Hausdorff 2005, J NeuroEng Rehabil 2:19, doi:10.1186/1743-0003-2-19). With T the
    median step (in samples) of the kept contacts (steps ≤ ``max_step``): a gap of 1.5 T-2.5 T between two kept
    contacts gets the most prominent candidate between 0.5 T after the first and 0.5 T before the second; before
    the first / after the last kept contact the most prominent candidate 0.5 T-1.5 T away is added, up to
    ``edge_steps`` times (a walk starts and ends with smaller steps), and after the last up to ``end_steps`` more
    times: the closing step, which brings the trailing foot beside the other, lifts the centre of mass least and
    is the contact a threshold misses most (on the Voisard trials the last heel strike was the single most missed
    contact, 46 of 104 trials, while the first steps were found). ``cand`` are peak indices with their
    prominences.

    ``walk_ends``: the closing steps (``end_steps``, with ``end_rhythm_before`` the first by the rhythm) are looked
    for after the last contact of every walk, i.e. also before every pause (a step > 2.5 T) inside the sequence, as
    the first step of every walk is with ``start_prominence`` (a sequence can hold several short walks: the
    Mobilise-D course, HA-001 Test11, has walks of 6-8 contacts separated by 2-3 s stops inside one gait sequence,
    whose closing steps the sequence-end fill never reached; on the Voisard trials the slow steps before the U-turn
    are such ends too); each is added before the next walk's first contact minus 0.5 T.
    ``return_closing``: (indices, closing (K,) bool = added by the closing-step fill); ``return_kinds``: (indices,
    closing, kinds (K,) int8 = index into ``IC_KINDS``)."""
    kept = np.sort(kept)
    d = np.diff(kept)
    d = d[d <= max_step]
    if len(d) < 2 or (len(cand) == 0 and not end_rhythm_before):
        if return_kinds:
            return kept, np.zeros(len(kept), bool), np.zeros(len(kept), np.int8)
        return (kept, np.zeros(len(kept), bool)) if return_closing else kept
    T = float(np.median(d))
    kind_of: dict[int, int] = {int(k): 0 for k in kept}

    def best(lo: float, hi: float) -> int | None:
        m = (cand > lo) & (cand < hi)
        return int(cand[m][np.argmax(cand_prom[m])]) if m.any() else None
    out = list(kept)
    if start_prominence is not None:
        # the first step of every walk (the first kept contact and the first after a pause > 2.5 T): gait
        # initiation lifts the trunk less than steady steps (the first step of a short slow walk of the Mobilise-D
        # course, HA-001 Test11, reaches 0.6-0.75 SD against the 0.7 SD threshold), so a candidate 0.5 T-1.5 T
        # before it with at least ``start_prominence`` (absolute, same unit as ``cand_prom``) is added
        starts = [kept[0]] + [b for a, b in zip(kept[:-1], kept[1:]) if b - a > 2.5 * T]
        for k in starts:
            m = (cand > k - 1.5 * T) & (cand < k - 0.5 * T) & (cand_prom >= start_prominence)
            if m.any():
                out.append(int(cand[m][np.argmax(cand_prom[m])]))
                kind_of.setdefault(out[-1], 3)
    for a, b in zip(kept[:-1], kept[1:]):
        if 1.5 * T <= b - a <= 2.5 * T:
            c = best(a + 0.5 * T, b - 0.5 * T)
            if c is not None:
                out.append(c)
                kind_of.setdefault(c, 1)
    first = kept[0]
    for _ in range(edge_steps):
        if (c := best(first - 1.5 * T, first - 0.5 * T)) is None:
            break
        out.append(c)
        kind_of.setdefault(c, 2)
        first = c
    # walk ends: the last kept contact (bounded by the signal) and, with walk_ends, every contact before a pause
    # (bounded by the next walk's first contact - 0.5 T)
    ends = [(kept[-1], end_rhythm_before if end_rhythm_before else np.inf)]
    if walk_ends:
        ends = [(a, b - 0.5 * T) for a, b in zip(kept[:-1], kept[1:]) if b - a > 2.5 * T] + ends
    closing = []
    for last, bound in ends:
        for k in range(edge_steps + end_steps):
            if k == edge_steps and end_rhythm_before and last + T < min(bound, end_rhythm_before):
                # the first closing step by the rhythm alone: its heel strike gives the trunk no rebound
                # (prominence 0-0.04 SD on the Voisard trials, where the last heel strike was the most missed
                # contact, 23 of 52 with the peak fill: the most prominent peak there is noise), so it is placed one
                # median step after the last contact when the signal goes on that long (``end_rhythm_before`` =
                # its length in samples; 0 = off)
                c = int(round(last + T))
                kind_of.setdefault(c, 4)
            elif (c := best(last + 0.5 * T, min(last + 1.5 * T, bound))) is None:
                break
            else:
                kind_of.setdefault(c, 2 if k < edge_steps else 5)
            out.append(c)
            closing.append(c)
            last = c
    out = np.array(sorted(out), np.int64)
    if walk_ends and len(out) > 1:
        # a closing step and the next walk's first step (start fill) can land on one peak in a short pause
        out = out[np.r_[True, np.diff(out) >= 0.5 * T]]
    closing_mask = np.isin(out, np.array(closing, np.int64))
    if return_kinds:
        return out, closing_mask, np.array([kind_of[int(k)] for k in out], np.int8)
    if not return_closing:
        return out
    return out, closing_mask


def kind_offsets_s(kinds: np.ndarray, *, fill_offset_s: float = 0.0, walk_end_offset_s: float = 0.0) -> np.ndarray:
    """Extra time (K,) s added to each contact of one sequence by how it was found (``kinds``, indices into
    ``IC_KINDS``, sorted by time), on top of the constant ``ic_offset_s`` that maps the trunk peak of a steady
    step to its heel strike.

    ``fill_offset_s``: every contact added by the fill (not a threshold peak). The closing step is placed one
    median step after the last contact and a gap is filled at its weak peak, but the closing step of a walk is
    quicker than a steady one (on the Voisard trials the closing heel strike came 0.95 median steps after the
    last one, median; Hausdorff 2005 for the rhythm of steady steps) and the weak peak of a missed step lags its
    heel strike like the rebound of a decelerating step (2026-12-08 diagnosis: closing steps by the rhythm +69 ms
    mean error, gap fills +57 ms, steady peaks -4 ms, shipped defaults). ``walk_end_offset_s``: the last
    threshold peak before a closing step (the step that stops the walk): the trunk decelerates, the double
    support lengthens and its rebound peak comes later after the heel strike (+40 ms mean error on the Voisard
    trials). Both 0 = off; chosen by the bench's leave-one-group-out."""
    kinds = np.asarray(kinds)
    out = np.zeros(len(kinds))
    if fill_offset_s:
        out[kinds != 0] += fill_offset_s
    if walk_end_offset_s and len(kinds) > 1:
        closing = np.isin(kinds, (IC_KINDS.index("closing_rhythm"), IC_KINDS.index("closing_peak")))
        before = np.flatnonzero(closing[1:] & (kinds[:-1] == 0))
        out[before] += walk_end_offset_s
    return out


def regular_runs(ic_s: np.ndarray, *, max_step_s: float) -> np.ndarray:
    """Run id per contact: a new run starts where the step time exceeds ``max_step_s`` (a missed step or a pause),
    so alternation of sides is only assumed inside a run."""
    if len(ic_s) == 0:
        return np.empty(0, np.int64)
    return np.r_[0, np.cumsum(np.diff(ic_s) > max_step_s)].astype(np.int64)


def assign_sides(yaw_rate: np.ndarray, fs_hz: float, ic_idx: np.ndarray, runs: np.ndarray, *, lag_s: float,
                 lowpass_hz: float) -> np.ndarray:
    """Boolean (K,) True = left for initial contacts ``ic_idx`` (sample indices into ``yaw_rate``, rad/s about up)."""
    k = len(ic_idx)
    if k == 0:
        return np.zeros(0, bool)
    if len(yaw_rate) > 12:
        r = butter_filtfilt(2, min(lowpass_hz, 0.45 * fs_hz), "lowpass", fs_hz, yaw_rate,
                            padlen=min(len(yaw_rate) - 1, 3 * 6))
    else:
        r = yaw_rate
    at = np.clip(ic_idx + int(round(lag_s * fs_hz)), 0, len(r) - 1)
    vote = -np.sign(r[at])                                    # +1 = left: negative yaw rate before a left contact
    left = np.empty(k, bool)
    for run in np.unique(runs):
        m = np.flatnonzero(runs == run)
        alt = np.where(np.arange(len(m)) % 2 == 0, 1.0, -1.0)
        phase = 1.0 if float(vote[m] @ alt) >= 0 else -1.0
        left[m] = alt * phase > 0
    return left
