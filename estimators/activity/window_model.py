"""Learned window classifier that refines the rule-based timeline (project default; not in the thesis).

The rule method (``classify_day``, thesis ch. 7 + extensions) decides sitting vs standing from postural
transitions and a lean rule, and stairs from cadence and lean. On the UCI chest set (participants 1-8,
leave-one-participant-out) these rules score 0.58 balanced accuracy, mostly because sitting at a desk with an
upright trunk and stand-ups without a clean transition stay "standing". This module adds a multinomial
logistic regression on per-window features (``stridelab.estimators.activity.windows``) and merges its 4-class window
posterior (sitting, standing, walking, stairs) into the per-second timeline with physical gates:

- lying and non-wear seconds stay as the rules decide (the model has never seen them: UCI has no lying);
- a second the rules call sitting stays sitting (rule sitting comes from a detected stand-to-sit or a strong
  lean; on UCI 1-8 it is right in 96 % of its windows, and it is what separates upright sitting from standing
  on the simulated days, where UCI's desk-work "sitting" posture does not occur);
- walking / stairs only where the chest moves: the rules' walking seconds, or every second of a gait-like
  window when the rules found no bout in it. A still window can only be sitting or standing. (UCI labels
  stairs over still stretches next to walking, and a model trained on the labels alone learns that; the gate
  keeps it from calling still standing next to a short walk "stairs".)

Features are computed after resampling to ``RATE_HZ`` (UCI 52 Hz and the pipeline's 100 Hz read the same
bands) and after the auto-calibration that ``window_features`` does (everything in g, orientation-free:
angles to the participant's own walking posture, band RMS of the vertical dynamic acc, cadence, regularity).

Pure functions: the fitted model is passed in as a ``WindowModel`` (coefficients); loading the artefact and
fitting live in ``pipeline`` (``stridelab.pipeline.activity_model``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction

import numpy as np

from stridelab.estimators.activity._resample import resample_poly_axis0
from stridelab.estimators.activity._types import DOWN, LEVEL, LYING, NON_WEAR, SITTING, STANDING, UP, ActivityResult
from stridelab.estimators.activity.windows import FEATURE_NAMES, add_context, window_features

__all__ = ["RATE_HZ", "WINDOW_S", "MODEL_CLASSES", "WindowModel", "model_features", "resample_to_model_rate",
           "merge_window_posterior", "refine_with_window_model", "FEATURE_SETS"]

#: rate the features are computed at (both UCI 52 Hz and 100 Hz recordings are resampled to it)
RATE_HZ = 26.0
WINDOW_S = 10.0
MODEL_CLASSES = ("sitting", "standing", "walking", "stairs")
#: feature subsets a design may use (``all`` = ``FEATURE_NAMES``; ``no_clusters`` drops the still-posture cluster
#: and standing-reference features, which a 24 h day with lying periods turns into a lying-vs-upright split)
FEATURE_SETS = {
    "all": FEATURE_NAMES,
    "no_clusters": tuple(n for n in FEATURE_NAMES if n not in (
        "lean_stand_deg", "lean_upright_deg", "lean_other_deg", "posture_margin_deg", "cluster_sep_deg")),
}


@dataclass(frozen=True)
class WindowModel:
    """A fitted multinomial logistic regression on standardised window features.

    feature_set: key of ``FEATURE_SETS``; context: half widths for ``add_context`` (windows);
    mean, scale: (F,) standardisation of the context-extended features; coef: (4, F); intercept: (4,);
    classes: ``MODEL_CLASSES``; provenance: free text (data, command, folds); trained_on: participant ids
    of the training data (a benchmark scores these by cross-validation, never with this model); lo, hi: (F,)
    1st / 99th percentiles of the training features: inputs are clipped to them, so a recording unlike the
    training data (e.g. a perfectly regular synthetic gait) cannot push the linear model far outside what it
    was fitted on; C: the L2 strength it was fitted with (inverse regularisation, scikit-learn convention)."""
    feature_set: str
    context: tuple
    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    classes: tuple = MODEL_CLASSES
    provenance: str = ""
    trained_on: tuple = ()
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    C: float | None = None

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """(W, 4) softmax posterior for context-extended features ``x`` (W, F)."""
        x = np.asarray(x, np.float64)
        if self.lo is not None:
            x = np.clip(x, self.lo, self.hi)
        z = (x - self.mean) / self.scale @ self.coef.T + self.intercept
        z -= z.max(axis=1, keepdims=True)
        e = np.exp(z)
        return e / e.sum(axis=1, keepdims=True)

    def to_dict(self) -> dict:
        return {"feature_set": self.feature_set, "context": list(self.context), "mean": self.mean.tolist(),
                "scale": self.scale.tolist(), "coef": self.coef.tolist(), "intercept": self.intercept.tolist(),
                "classes": list(self.classes), "provenance": self.provenance,
                "trained_on": list(self.trained_on),
                "lo": None if self.lo is None else self.lo.tolist(), "hi": None if self.hi is None else self.hi.tolist(), "C": self.C}

    @classmethod
    def from_dict(cls, d: dict) -> "WindowModel":
        m = cls(feature_set=str(d["feature_set"]), context=tuple(int(h) for h in d["context"]),
                mean=np.asarray(d["mean"], float), scale=np.asarray(d["scale"], float),
                coef=np.asarray(d["coef"], float), intercept=np.asarray(d["intercept"], float),
                classes=tuple(d.get("classes", MODEL_CLASSES)), provenance=str(d.get("provenance", "")),
                trained_on=tuple(str(q) for q in d.get("trained_on", ())),
                lo=None if d.get("lo") is None else np.asarray(d["lo"], float),
                hi=None if d.get("hi") is None else np.asarray(d["hi"], float),
                C=None if d.get("C") is None else float(d["C"]))
        n = len(FEATURE_SETS[m.feature_set]) * (1 + len(m.context))
        if m.coef.shape != (len(MODEL_CLASSES), n) or m.mean.shape != (n,) or m.scale.shape != (n,):
            raise ValueError(f"window model: coefficient shapes {m.coef.shape} do not match feature set "
                             f"'{m.feature_set}' with context {m.context} ({n} features)")
        return m


def resample_to_model_rate(acc: np.ndarray, fs: float) -> np.ndarray:
    """Polyphase resampling (anti-aliased, ``scipy.signal.resample_poly``; its numba twin ``resample_poly_axis0``,
    bit for bit) of (N, 3) from ``fs`` to ``RATE_HZ``."""
    r = Fraction(RATE_HZ / float(fs)).limit_denominator(1000)
    if r == 1:
        return np.asarray(acc, np.float64)
    return resample_poly_axis0(np.asarray(acc, np.float64), r.numerator, r.denominator)


def model_features(acc_m_s2: np.ndarray, fs: float, feature_set: str, context: tuple):
    """(context-extended features (W, F'), ``WindowFeatures``) of 10-s windows of the recording resampled to
    ``RATE_HZ``. Window i covers seconds [10 i, 10 i + 10) of the recording."""
    wf = window_features(resample_to_model_rate(acc_m_s2, fs), RATE_HZ, WINDOW_S)
    cols = [FEATURE_NAMES.index(n) for n in FEATURE_SETS[feature_set]]
    x, _ = add_context(wf.x[:, cols], FEATURE_SETS[feature_set], tuple(context))
    return x, wf


def merge_window_posterior(second_class: np.ndarray, proba: np.ndarray, gait_like: np.ndarray,
                           lean_walk_deg: np.ndarray, stairs_lean_deg: float = 4.0) -> np.ndarray:
    """Per-second classes (``CLASSES`` codes) from the rule timeline and the model's window posterior
    (W, 4; window i = seconds [10 i, 10 i + 10)); gates as in the module docstring. Seconds after the last
    whole window keep the rule class. ``lean_walk_deg`` (W,) decides stairs up (lean above the walking posture
    by more than ``stairs_lean_deg``) vs down where the rules did not find the stairs themselves."""
    sec = np.asarray(second_class).astype(np.int8).copy()
    w = int(WINDOW_S)
    n_win = min(proba.shape[0], sec.size // w)
    if n_win <= 0:
        return sec
    rule = sec[: n_win * w].reshape(n_win, w)          # (window, second); the same gates for every window at once
    p = np.asarray(proba)[:n_win]
    free = (rule != LYING) & (rule != NON_WEAR)
    stairs = (rule == UP) | (rule == DOWN)
    walk_s = free & ((rule == LEVEL) | stairs)
    gait = np.asarray(gait_like[:n_win], bool)
    dyn = np.where(walk_s.any(axis=1)[:, None], walk_s, free & gait[:, None])
    k = np.argmax(p, axis=1)                            # the model sees a posture even where the chest moves
    dyn_cls = np.array([SITTING, STANDING, LEVEL, UP], np.int8)[k]     # stairs: up or down by the lean
    dyn_cls[(k == 3) & ~(np.asarray(lean_walk_deg[:n_win]) > stairs_lean_deg)] = DOWN
    posture = np.where(p[:, 0] > p[:, 1], SITTING, STANDING).astype(np.int8)
    keep_stairs = ((dyn_cls == UP) | (dyn_cls == DOWN))[:, None] & stairs   # the rules found the stairs: keep
    moving = np.where(keep_stairs, rule, dyn_cls[:, None])                 # their direction
    still = np.where(rule == SITTING, rule, posture[:, None])
    sec[: n_win * w] = np.where(free, np.where(dyn, moving, still), rule).ravel()
    return sec


def refine_with_window_model(res: ActivityResult, acc_m_s2: np.ndarray, sampling_rate_hz: float,
                             model: WindowModel, stairs_lean_deg: float = 4.0) -> ActivityResult:
    """``res`` (from ``classify_day`` on the same recording) with ``second_class`` refined by ``model``
    (``merge_window_posterior``); bouts, transitions and steps stay the rules'. A recording shorter than
    one window is returned unchanged."""
    return apply_window_posterior(res, window_posterior(acc_m_s2, sampling_rate_hz, model), stairs_lean_deg)


def window_posterior(acc_m_s2: np.ndarray, sampling_rate_hz: float, model: WindowModel):
    """(posterior (W, 4), gait-like (W,), walking lean (W,)) of the 10-s windows of a recording, or None when it is
    shorter than one window; what ``merge_window_posterior`` needs, computed before the rules may reuse the
    samples' memory (``classify_day(..., overwrite_input=True)``)."""
    acc = np.asarray(acc_m_s2, np.float64)
    if acc.shape[0] < WINDOW_S * sampling_rate_hz:
        return None
    x, wf = model_features(acc, sampling_rate_hz, model.feature_set, model.context)
    return model.predict_proba(x), wf.gait, wf.x[:, FEATURE_NAMES.index("lean_walk_deg")]


def apply_window_posterior(res: ActivityResult, posterior, stairs_lean_deg: float = 4.0) -> ActivityResult:
    """``res`` with ``second_class`` refined by a ``window_posterior`` of the same recording (unchanged if None)."""
    if posterior is None or res.second_class.size < WINDOW_S:
        return res
    proba, gait, lean = posterior
    return replace(res, second_class=merge_window_posterior(res.second_class, proba, gait, lean, stairs_lean_deg))
