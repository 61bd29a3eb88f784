"""Evaluation of gait events and strides against a reference (STYLE P11): library code with explicit tolerances.

Event matching (spec thesis §3.5): one-to-one, greedy in order of |Δ|, same event type, per foot. A detection within
``tolerance_samples`` of a reference event is a true positive; unmatched references are false negatives and
unmatched detections false positives. Error = detected − reference (positive = late).
Sensitivity Se = TP/(TP+FN), precision Pr = TP/(TP+FP) (thesis Eq. 53), as fractions 0…1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EventMatch", "match_events", "StrideMatch", "match_strides"]


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
    cand = [(abs(int(d) - int(r)), i, j) for i, d in enumerate(det) for j, r in enumerate(ref)
            if abs(int(d) - int(r)) <= tolerance_samples]
    cand.sort()
    used_d, used_r, pairs = set(), set(), []
    for _, i, j in cand:
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
