"""Evaluation of gait events and strides against a reference (STYLE P11): library code with explicit tolerances.

Event matching (spec thesis §3.5): one-to-one, greedy in order of |Δ|, same event type, per foot. A detection within
``tolerance_samples`` of a reference event is a true positive; unmatched references are false negatives and
unmatched detections false positives. Error = detected − reference (positive = late).
Sensitivity Se = TP/(TP+FN), precision Pr = TP/(TP+FP) (thesis Eq. 53), as fractions 0…1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EventMatch", "match_events", "StrideMatch", "match_strides", "EventAccuracy", "event_accuracy",
           "EVENT_TOLERANCE_S", "STRIDE_TOLERANCE_S", "reference_stride_lengths", "stride_length_reference",
           "paired_errors"]

#: default event matching tolerance (±0.5 s, as the gaitmap bench; thesis §3.5 matches within a stride)
EVENT_TOLERANCE_S = 0.5


@dataclass(frozen=True)
class EventMatch:
    """Matched pairs ``pairs`` (K, 2) [detected_idx, reference_idx] (sample indices), ``error_samples`` (K,)
    detected − reference; ``fp`` detections and ``fn`` references left unmatched; Se/Pr as fractions."""
    pairs: np.ndarray
    error_samples: np.ndarray
    fp: np.ndarray
    fn: np.ndarray

    @property
    def tp(self) -> int:
        return int(len(self.pairs))

    @property
    def sensitivity(self) -> float:
        d = self.tp + len(self.fn)
        return self.tp / d if d else float("nan")

    @property
    def precision(self) -> float:
        d = self.tp + len(self.fp)
        return self.tp / d if d else float("nan")


def match_events(detected: np.ndarray, reference: np.ndarray, *, tolerance_samples: int) -> EventMatch:
    """One-to-one nearest matching; ``|detected − reference| <= tolerance_samples`` is a true positive."""
    if tolerance_samples < 0:
        raise ValueError(f"tolerance_samples must be >= 0, got {tolerance_samples}")
    det = np.asarray(detected, dtype=np.int64).ravel()
    ref = np.asarray(reference, dtype=np.int64).ravel()
    diff = np.abs(det[:, None] - ref[None, :])
    ii, jj = np.nonzero(diff <= tolerance_samples)
    order = np.lexsort((jj, ii, diff[ii, jj]))             # nearest first, ties by detection then reference
    used_d, used_r, pairs = set(), set(), []
    for i, j in zip(ii[order].tolist(), jj[order].tolist()):
        if i in used_d or j in used_r:
            continue
        used_d.add(i)
        used_r.add(j)
        pairs.append((det[i], ref[j]))
    pairs_a = np.array(sorted(pairs, key=lambda p: p[1]), dtype=np.int64).reshape(-1, 2)
    return EventMatch(pairs=pairs_a, error_samples=pairs_a[:, 0] - pairs_a[:, 1],
                      fp=np.array([d for i, d in enumerate(det) if i not in used_d], dtype=np.int64),
                      fn=np.array([r for j, r in enumerate(ref) if j not in used_r], dtype=np.int64))


@dataclass(frozen=True)
class StrideMatch:
    """Strides matched by their borders: ``det_rows``/``ref_rows`` (K,) row indices; ``unmatched_ref`` rows."""
    det_rows: np.ndarray
    ref_rows: np.ndarray
    unmatched_ref: np.ndarray

    def errors(self, detected_values: np.ndarray, reference_values: np.ndarray) -> np.ndarray:
        """detected − reference of a per-stride quantity for the matched strides."""
        return np.asarray(detected_values)[self.det_rows] - np.asarray(reference_values)[self.ref_rows]


def match_strides(det_start_end: np.ndarray, ref_start_end: np.ndarray, *, tolerance_samples: int) -> StrideMatch:
    """A detected stride matches a reference stride when both its start and its end lie within
    ``tolerance_samples`` of the reference's (each reference used once, nearest first)."""
    if tolerance_samples < 0:
        raise ValueError(f"tolerance_samples must be >= 0, got {tolerance_samples}")
    d = np.asarray(det_start_end, dtype=np.int64).reshape(-1, 2)
    r = np.asarray(ref_start_end, dtype=np.int64).reshape(-1, 2)
    cand = []
    for i in range(len(d)):
        for j in range(len(r)):
            e = np.abs(d[i] - r[j])
            if e.max() <= tolerance_samples:
                cand.append((int(e.sum()), i, j))
    cand.sort()
    ud, ur, di, rj = set(), set(), [], []
    for _, i, j in cand:
        if i in ud or j in ur:
            continue
        ud.add(i)
        ur.add(j)
        di.append(i)
        rj.append(j)
    order = np.argsort(rj)
    return StrideMatch(np.array(di, np.int64)[order], np.array(rj, np.int64)[order],
                       np.array([j for j in range(len(r)) if j not in ur], np.int64))


@dataclass(frozen=True)
class EventAccuracy:
    """Event detection accuracy pooled over trials: Se/Pr as fractions (NaN when undefined), timing error
    detected − reference in ms (positive = late; NaN without matches), counts, and the matched pairs
    ``pairs_s`` (K, 2) [detected, reference] in the seconds the caller used."""
    sensitivity: float
    precision: float
    timing_mae_ms: float
    timing_mean_ms: float
    tp: int
    fp: int
    fn: int
    pairs_s: np.ndarray
    unscored: int = 0


def event_accuracy(detected_s, reference_s, *, tolerance_s: float = EVENT_TOLERANCE_S,
                   spans_s=None, unscored_spans_s=None) -> EventAccuracy:
    """Match detected to reference events per trial (:func:`match_events` on a 1 µs grid) and pool the counts.

    ``detected_s`` / ``reference_s``: sequences (one entry per trial) of 1-D arrays of event times in seconds
    (any common origin per trial). ``spans_s``: optional (start, end) per trial, the part the reference annotates
    (e.g. Voisard's ``TrialBoundaries``); None = [first − tol, last + tol] of the trial's reference events.
    Only reference events inside the span count; detections within ``tolerance_s`` of the span may match them,
    and unmatched detections outside the span are not counted (the reference says nothing there). A trial
    without reference events contributes nothing. ``unscored_spans_s``: optional, per trial, a list of open
    intervals (a, b) where the reference is known to leave events out (e.g. an unlabelled foot placement); an
    unmatched detection strictly inside one is counted in ``unscored``, not as a false positive.
    """
    if tolerance_s < 0:
        raise ValueError(f"tolerance_s must be >= 0, got {tolerance_s}")
    if len(detected_s) != len(reference_s) or (spans_s is not None and len(spans_s) != len(reference_s)):
        raise ValueError("detected_s, reference_s (and spans_s) need one entry per trial")
    if unscored_spans_s is not None and len(unscored_spans_s) != len(reference_s):
        raise ValueError("unscored_spans_s needs one entry per trial")
    tp = fp = fn = unscored = 0
    pairs = []
    us = 1e6
    for i, (det, ref) in enumerate(zip(detected_s, reference_s)):
        det = np.asarray(det, float).ravel()
        ref = np.asarray(ref, float).ravel()
        if spans_s is not None:
            lo, hi = float(spans_s[i][0]), float(spans_s[i][1])
            ref = ref[(ref >= lo) & (ref <= hi)]
        if not len(ref):
            continue
        if spans_s is None:
            lo, hi = ref.min() - tolerance_s, ref.max() + tolerance_s
        det = det[(det >= lo - tolerance_s) & (det <= hi + tolerance_s)]
        m = match_events(np.rint(det * us).astype(np.int64), np.rint(ref * us).astype(np.int64),
                         tolerance_samples=int(round(tolerance_s * us)))
        fp_s = m.fp / us
        fp_s = fp_s[(fp_s >= lo) & (fp_s <= hi)]
        if unscored_spans_s is not None and len(fp_s):
            inside = np.zeros(len(fp_s), bool)
            for a, b in unscored_spans_s[i]:
                inside |= (fp_s > a) & (fp_s < b)
            unscored += int(inside.sum())
            fp_s = fp_s[~inside]
        tp, fp, fn = tp + m.tp, fp + len(fp_s), fn + len(m.fn)
        pairs.append(m.pairs / us)
    p = np.vstack(pairs) if pairs else np.zeros((0, 2))
    err_ms = (p[:, 0] - p[:, 1]) * 1000.0
    nan = float("nan")
    return EventAccuracy(sensitivity=tp / (tp + fn) if tp + fn else nan, precision=tp / (tp + fp) if tp + fp else nan,
                         timing_mae_ms=float(np.abs(err_ms).mean()) if len(err_ms) else nan,
                         timing_mean_ms=float(err_ms.mean()) if len(err_ms) else nan, tp=tp, fp=fp, fn=fn, pairs_s=p,
                         unscored=unscored)


def reference_stride_lengths(ref_t_s: np.ndarray, ref_pos: np.ndarray, start_s: np.ndarray,
                             end_s: np.ndarray) -> np.ndarray:
    """(S,) m: horizontal displacement of a reference point (optical marker or segment origin; ``ref_pos`` (M, 3),
    ``ref_t_s`` (M,) increasing) between stride borders ``start_s`` / ``end_s`` (mid-stances: the foot is flat
    and still, so any foot point moves by the same amount up to foot yaw × lever arm). Linear interpolation;
    NaN where a border is outside the reference or the reference is missing (occluded marker)."""
    t = np.asarray(ref_t_s, float)
    p = np.asarray(ref_pos, float)
    out = np.full(len(start_s), np.nan)
    if len(t) < 2:
        return out

    def at(x):
        xy = np.column_stack([np.interp(x, t, p[:, k], left=np.nan, right=np.nan) for k in range(2)])
        return xy
    a, b = at(np.asarray(start_s, float)), at(np.asarray(end_s, float))
    return np.hypot(b[:, 0] - a[:, 0], b[:, 1] - a[:, 1])


#: stride matching tolerance on both borders (±0.3 s, as the gaitmap bench)
STRIDE_TOLERANCE_S = 0.3


def stride_length_reference(det_start_end_s: np.ndarray, ref_t_s: np.ndarray, ref_pos: np.ndarray,
                            ref_start_end_s: np.ndarray | None = None, *,
                            tolerance_s: float = STRIDE_TOLERANCE_S) -> np.ndarray:
    """(S,) m: the reference length of each detected stride (``det_start_end_s`` (S, 2) borders in s), NaN where
    there is none; the one definition the gait stage and ``stridelab bench gait`` share.

    With annotated reference strides (``ref_start_end_s`` (R, 2), e.g. gaitmap's mocap strides): a detected stride
    matched to one (:func:`match_strides`, both borders within ``tolerance_s``, on a 1 µs grid) gets the reference
    point's displacement between the *reference* borders; unmatched strides get NaN (the reference does not label
    them). Without (``None``: C3D markers, PyShoe's Vicon): the displacement between the detected borders (both
    mid-stances, where the foot stands still). :func:`reference_stride_lengths` measures both.
    """
    det = np.asarray(det_start_end_s, float).reshape(-1, 2)
    if ref_start_end_s is None:
        return reference_stride_lengths(ref_t_s, ref_pos, det[:, 0], det[:, 1])
    ref = np.asarray(ref_start_end_s, float).reshape(-1, 2)
    us = 1e6
    m = match_strides(np.rint(det * us).astype(np.int64), np.rint(ref * us).astype(np.int64),
                      tolerance_samples=int(round(tolerance_s * us)))
    out = np.full(len(det), np.nan)
    out[m.det_rows] = reference_stride_lengths(ref_t_s, ref_pos, ref[m.ref_rows, 0], ref[m.ref_rows, 1])
    return out


def paired_errors(estimate: np.ndarray, reference: np.ndarray) -> dict:
    """Summary of estimate − reference over pairs where both are finite: ``mae``, ``mean``, ``rmse``, ``n``
    (NaN statistics when n = 0)."""
    e = np.asarray(estimate, float) - np.asarray(reference, float)
    e = e[np.isfinite(e)]
    nan = float("nan")
    return {"mae": float(np.abs(e).mean()) if len(e) else nan, "mean": float(e.mean()) if len(e) else nan,
            "rmse": float(np.sqrt(np.mean(e ** 2))) if len(e) else nan, "n": int(len(e))}
