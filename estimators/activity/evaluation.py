"""Activity accuracy against labelled intervals (STYLE P11): one scorer for the UCI bench and the activity stage.

Classes are scored as four: ``SCORED_CLASSES`` (lying/sitting -> sitting, standing/non-wear -> standing, level
walking -> walking, stairs up/down -> stairs; ``CLASS_MAP`` maps :data:`stridelab.estimators.activity.CLASSES`). Windows of
``window_s`` (non-overlapping, from the first sample) are scored when they lie wholly inside one reference label
run; the prediction of a window is the majority of its seconds' classes.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["SCORED_CLASSES", "CLASS_MAP", "WINDOW_S", "window_confusion", "scores"]

SCORED_CLASSES = ("sitting", "standing", "walking", "stairs")
#: stridelab.estimators.activity.CLASSES -> SCORED_CLASSES index
CLASS_MAP = np.array([0, 0, 1, 2, 3, 3, 1])
WINDOW_S = 10.0


def window_samples(fs: float, window_s: float = WINDOW_S) -> int:
    """Samples per scoring window of :func:`window_confusion`."""
    return int(round(window_s * fs))


def window_confusion(second_class: np.ndarray, labels: np.ndarray, fs: float, code_to_class: dict,
                     window_s: float = WINDOW_S, first_sample: int = 0) -> np.ndarray:
    """(4, 4) confusion (rows reference, columns predicted) over ``window_s`` windows inside one label.

    second_class: (S,) per-second class index (:data:`stridelab.estimators.activity.CLASSES`) from sample 0;
    labels: (N,) reference label code per sample; code_to_class: code -> SCORED_CLASSES index (codes not in it
    are not scored). ``labels`` may be a slice of the recording starting at sample ``first_sample`` (a
    multiple of :func:`window_samples`): confusions of consecutive slices add up to that of the whole, so a
    week-long recording is scored a day at a time."""
    n = labels.shape[0]
    w = window_samples(fs, window_s)
    if first_sample % w:
        raise ValueError(f"first_sample {first_sample} is not a multiple of the {w}-sample window")
    C = np.zeros((4, 4), dtype=np.int64)
    n_w = n // w                                      # whole windows; a partial last one is not scored
    if n_w == 0 or second_class.shape[0] == 0:
        return C
    codes, inv = np.unique(labels[:n_w * w:w], return_inverse=True)           # each window's first label
    ref = np.array([code_to_class.get(int(c), -1) for c in codes], dtype=np.int64)[inv.ravel()]
    _confusion(np.ascontiguousarray(second_class, dtype=np.int64), np.ascontiguousarray(labels), ref, w, float(fs),
               int(first_sample), C)
    return C


@njit(cache=True)
def _confusion(second_class, labels, ref, w, fs, first_sample, C):
    """Add each window's (reference, majority prediction) to ``C``: windows whose labels are all equal and
    whose class ``ref`` is scored; a sample's second is ⌊(first_sample + i) / fs⌋ (capped at the last second),
    a tie in the vote goes to the first class."""
    last = second_class.shape[0] - 1
    votes = np.zeros(4, dtype=np.int64)
    for k in range(ref.shape[0]):
        if ref[k] < 0:
            continue
        a = k * w
        same = True
        for i in range(a + 1, a + w):
            if labels[i] != labels[a]:
                same = False
                break
        if not same:
            continue
        votes[:] = 0
        for i in range(a, a + w):
            sec = min(int((first_sample + i) / fs), last)
            votes[CLASS_MAP[second_class[sec]]] += 1
        pred = 0
        for c in range(1, 4):
            if votes[c] > votes[pred]:
                pred = c
        C[ref[k], pred] += 1


def scores(C: np.ndarray) -> dict:
    """Accuracy and balanced accuracy (mean recall over the reference classes present)."""
    tot = C.sum()
    present = C.sum(axis=1) > 0
    rec = np.diag(C)[present] / C.sum(axis=1)[present]
    return {"accuracy": float(np.trace(C) / tot) if tot else None,
            "balanced_accuracy": float(rec.mean()) if rec.size else None,
            "windows": int(tot), "confusion": C.tolist()}
