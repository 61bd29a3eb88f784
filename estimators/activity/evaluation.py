"""Activity accuracy against labelled intervals (STYLE P11): one scorer for the UCI bench and the activity stage.

Classes are scored as four: ``SCORED_CLASSES`` (lying/sitting -> sitting, standing/non-wear -> standing, level
walking -> walking, stairs up/down -> stairs; ``CLASS_MAP`` maps :data:`estimators.activity.CLASSES`). Windows of
``window_s`` (non-overlapping, from the first sample) are scored when they lie wholly inside one reference label
run; the prediction of a window is the majority of its seconds' classes.
"""
from __future__ import annotations

import numpy as np

__all__ = ["SCORED_CLASSES", "CLASS_MAP", "WINDOW_S", "window_confusion", "scores"]

SCORED_CLASSES = ("sitting", "standing", "walking", "stairs")
#: estimators.activity.CLASSES -> SCORED_CLASSES index
CLASS_MAP = np.array([0, 0, 1, 2, 3, 3, 1])
WINDOW_S = 10.0


def window_samples(fs: float, window_s: float = WINDOW_S) -> int:
    """Samples per scoring window of :func:`window_confusion`."""
    return int(round(window_s * fs))


def window_confusion(second_class: np.ndarray, labels: np.ndarray, fs: float, code_to_class: dict,
                     window_s: float = WINDOW_S, first_sample: int = 0) -> np.ndarray:
    """(4, 4) confusion (rows reference, columns predicted) over ``window_s`` windows inside one label.

    second_class: (S,) per-second class index (:data:`estimators.activity.CLASSES`) from sample 0;
    labels: (N,) reference label code per sample; code_to_class: code -> SCORED_CLASSES index (codes not in it
    are not scored). ``labels`` may be a slice of the recording starting at sample ``first_sample`` (a
    multiple of :func:`window_samples`): confusions of consecutive slices add up to that of the whole, so a
    week-long recording is scored a day at a time."""
    n = labels.shape[0]
    w = window_samples(fs, window_s)
    if first_sample % w:
        raise ValueError(f"first_sample {first_sample} is not a multiple of the {w}-sample window")
    sec = (np.arange(first_sample, first_sample + n) / fs).astype(np.int64)
    sec = np.minimum(sec, second_class.shape[0] - 1)
    C = np.zeros((4, 4), dtype=np.int64)
    for i in range(0, n - w + 1, w):
        lab = labels[i:i + w]
        if (lab != lab[0]).any() or int(lab[0]) not in code_to_class:
            continue
        pred = np.bincount(CLASS_MAP[second_class[sec[i:i + w]]], minlength=4).argmax()
        C[code_to_class[int(lab[0])], pred] += 1
    return C


def scores(C: np.ndarray) -> dict:
    """Accuracy and balanced accuracy (mean recall over the reference classes present)."""
    tot = C.sum()
    present = C.sum(axis=1) > 0
    rec = np.diag(C)[present] / C.sum(axis=1)[present]
    return {"accuracy": float(np.trace(C) / tot) if tot else None,
            "balanced_accuracy": float(rec.mean()) if rec.size else None,
            "windows": int(tot), "confusion": C.tolist()}
