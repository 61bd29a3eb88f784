"""The pipeline's default chest-activity classifier: rule timeline refined by a window model fitted on UCI.

``classify_recording`` is what the activity stage and ``stridelab bench activity`` (method ``default``) run:
``stridelab.estimators.activity.classify_day`` (rules) then ``refine_with_window_model`` with the shipped model
``pipeline/models/activity_window_lr.json``. That file is produced by
``stridelab bench activity --fit-model pipeline/models/activity_window_lr.json`` from ``../shared/data/uci_chest``
participants 1-8 (UCI "Activity Recognition from a Single Chest-Mounted Accelerometer", Casale et al.,
CC BY 4.0; the file holds only fitted coefficients, no data). The design (feature set, temporal context, L2
strength C) is chosen by leave-one-participant-out over ``DESIGNS``; the bench reports that choice and its
nested (outer-fold) score (``nested_lopo``).
"""
from __future__ import annotations

import json
from dataclasses import replace
from itertools import product
from pathlib import Path

import numpy as np

from stridelab.estimators.activity import PRESETS, ActivityParams, ActivityResult, classify_day
from stridelab.estimators.activity.window_model import (FEATURE_SETS, MODEL_CLASSES, RATE_HZ, WINDOW_S, WindowModel,
                                              merge_window_posterior, resample_to_model_rate)
from stridelab.estimators.activity.windows import FEATURE_NAMES, add_context, window_features

MODEL_PATH = Path(__file__).resolve().parent / "models" / "activity_window_lr.json"
#: designs the model is chosen among by leave-one-participant-out (feature set, context half widths, C)
DESIGNS = tuple({"feature_set": f, "context": c, "C": C}
                for f, c, C in product(("all", "no_clusters"), ((1,), (6,), (1, 6)), (0.03, 0.3)))
_CACHE: dict = {}


def load_model(path: Path | str = MODEL_PATH) -> WindowModel:
    """The fitted window model; ``ValueError`` naming the file when it is missing or malformed."""
    p = Path(path)
    key = (str(p), p.stat().st_mtime_ns if p.exists() else None)
    if key in _CACHE:
        return _CACHE[key]
    try:
        m = WindowModel.from_dict(json.loads(p.read_text()))
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ValueError(f"{p}: not a window-model file ({e}); refit it with "
                         "'stridelab bench activity --fit-model PATH'") from e
    _CACHE[key] = m
    return m


def classify_recording(acc_m_s2: np.ndarray, *, sampling_rate_hz: float, t0_ns: int = 0, timezone: str = "UTC",
                       params: ActivityParams = PRESETS["default"], window_model: str | None = "default",
                       overwrite_input: bool = False) -> ActivityResult:
    """Rules (``classify_day``) refined, unless ``window_model`` is None, by the window model. The window
    posterior is computed first, so that with ``overwrite_input=True`` the rules may reuse the samples' memory
    (a 24 h day at 100 Hz: 200 MB less at the peak; the caller must not use ``acc_m_s2`` afterwards)."""
    posterior = None
    if window_model is not None:
        from stridelab.estimators.activity.window_model import window_posterior
        model = load_model(MODEL_PATH if window_model == "default" else window_model)
        posterior = window_posterior(acc_m_s2, sampling_rate_hz, model)
    res = classify_day(acc_m_s2, sampling_rate_hz=sampling_rate_hz, t0_ns=t0_ns, timezone=timezone, params=params,
                       overwrite_input=overwrite_input)
    if window_model is None:
        return res
    from stridelab.estimators.activity.window_model import apply_window_posterior
    return apply_window_posterior(res, posterior, params.stairs_lean_deg)


# ---------------------------------------------------------------- fitting and cross-validation (UCI)

def raw_features(acc_m_s2: np.ndarray, fs: float):
    """``window_features`` at ``RATE_HZ`` (all ``FEATURE_NAMES``), computed once per participant."""
    return window_features(resample_to_model_rate(acc_m_s2, fs), RATE_HZ, WINDOW_S)


def design_x(wf, design: dict) -> np.ndarray:
    cols = [FEATURE_NAMES.index(n) for n in FEATURE_SETS[design["feature_set"]]]
    x, _ = add_context(wf.x[:, cols], FEATURE_SETS[design["feature_set"]], tuple(design["context"]))
    return x


def fit_model(xs: list, ys: list, design: dict, provenance: str = "") -> WindowModel:
    """Multinomial L2 logistic regression (scikit-learn, newton-cg), classes weighted to equal total weight, on the
    labelled windows (y ≥ 0) of the given participants, features clipped to their 1st-99th percentiles and
    standardised (``WindowModel``)."""
    from sklearn.linear_model import LogisticRegression
    X = np.vstack([x[y >= 0] for x, y in zip(xs, ys)])
    Y = np.concatenate([y[y >= 0] for y in ys])
    lo, hi = np.percentile(X, 1, axis=0), np.percentile(X, 99, axis=0)
    X = np.clip(X, lo, hi)
    mean, scale = X.mean(axis=0), X.std(axis=0)
    scale[scale < 1e-9] = 1.0
    clf = LogisticRegression(C=design["C"], class_weight="balanced", solver="newton-cg", max_iter=200)
    clf.fit((X - mean) / scale, Y)
    coef = np.zeros((len(MODEL_CLASSES), X.shape[1]))
    icpt = np.full(len(MODEL_CLASSES), -50.0)      # a class absent from training is never predicted
    coef[clf.classes_] = clf.coef_
    icpt[clf.classes_] = clf.intercept_
    return WindowModel(feature_set=design["feature_set"], context=tuple(design["context"]), mean=mean, scale=scale,
                       coef=coef, intercept=icpt, provenance=provenance, lo=lo, hi=hi,
                       C=float(design["C"]))


def save_model(model: WindowModel, path: Path | str) -> None:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(".tmp")
    tmp.write_text(json.dumps(model.to_dict(), indent=1) + "\n")
    tmp.replace(p)


def merged_window_classes(model: WindowModel, x: np.ndarray, wf, rule_second_class: np.ndarray,
                          stairs_lean_deg: float) -> np.ndarray:
    """Per-second classes of the refined timeline from precomputed features (what ``classify_recording`` does)."""
    proba = model.predict_proba(x)
    return merge_window_posterior(rule_second_class, proba, wf.gait, wf.x[:, FEATURE_NAMES.index("lean_walk_deg")],
                                  stairs_lean_deg)


def with_provenance(model: WindowModel, text: str) -> WindowModel:
    return replace(model, provenance=text)
