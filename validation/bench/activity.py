"""``stridelab bench activity``: chest-accelerometer activity classes on the UCI chest set, and the speed of a
24 h, 100 Hz day.

UCI "Activity Recognition from a Single Chest-Mounted Accelerometer" (uncalibrated 12-bit counts, 52 Hz,
unknown sensor orientation; reader ``stridelab.pipeline.formats.uci_chest``). Each participant file is classified as one
continuous recording by ``stridelab.estimators.activity.classify_day``; the per-second classes are mapped to four classes
(lying/sitting -> sitting, standing/non-wear -> standing, level walking -> walking, stairs up/down -> stairs)
and scored on non-overlapping 10-s windows lying wholly inside one reference label (majority of the window's
seconds). Reference: label 1 sitting, 3 and 7 standing, 4 and 6 walking, 5 stairs; 2 and 0 excluded.

Methods: ``thesis`` (``PRESETS["thesis"]``) and ``rules`` (``PRESETS["default"]``, rules only): nothing learned
from UCI labels. ``default``: what the pipeline's activity stage runs (``stridelab.pipeline.activity_model.classify_recording``:
the rules refined by the shipped window model fitted on UCI participants 1-8). Participants in the model's
``trained_on`` are scored by nested leave-one-participant-out (``nested_lopo``: outer fold = the participant, the
design chosen among ``stridelab.pipeline.activity_model.DESIGNS`` by an inner LOPO over the other training participants);
any other participant file by the shipped model. ``rf_tuned``: a random forest alone on the same features with
the same budget (12 designs, ``RF_DESIGNS``) and the same nested protocol. ``learned_loso``: the fixed forest of
issue #6 (``LEARNED``, features ``stridelab.estimators.activity.windows`` at 52 Hz, ±1-window context),
leave-one-subject-out. ``development`` groups the participants used for any tuning (``DEVELOPMENT`` = 1-8),
``held_out`` every other file. ``--fit-model PATH`` refits the default's model on the given participants
(design by flat LOPO) and writes it.

Label consistency (key ``label_consistency``, ``label_consistency``): windows whose UCI label the chest signal
contradicts (labelled walking/stairs but still for most seconds, labelled sitting/standing but walking
throughout) and the balanced accuracy this leaves at most to any classifier that answers what the chest did.
Speed: ``classify_recording`` (key ``seconds_24h_100hz``; rules only: ``seconds_24h_100hz_rules_only``) +
``daily_summaries`` on a synthetic 24 h, 100 Hz chest day (8.64 M samples), after a warm-up call (numba JIT).

Simulated free-living days (``--simulated N``, key ``simulated``): the demo study's first N participants, one
24 h day each from ``stridelab.validation.simulator.simulate_chest_day`` (its reference labels and scripted step counts),
classified with the pipeline's default (``classify_recording``) and the participant's thigh length. ``agreement`` = per-second agreement
over the seconds whose reference is a class (``transition`` seconds are not scored; a labelled interval covers
its whole seconds, same definition as docs/activity.md); ``steps_error_pct`` = 100 (detected − scripted) /
scripted; ``seconds`` = classify_recording + daily_summaries on that day.
"""
from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np

from stridelab.pipeline.console import UserError, emit_json, err_console, progress

PROJECT_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_UCI = PROJECT_ROOT.parent / "shared" / "data" / "uci_chest"
from stridelab.estimators.activity.evaluation import CLASS_MAP, SCORED_CLASSES as BENCH_CLASSES, WINDOW_S, scores  # noqa: E402,F401
from stridelab.estimators.activity.evaluation import window_confusion as _window_confusion  # noqa: E402
from stridelab.pipeline.formats.uci_chest import LABEL_TO_CLASS  # noqa: E402
#: participants used for any tuning: 1-4 were inspected while the rules were developed, 5-8 in a later session,
#: and 1-8 train (and choose the design of) the default's window model; any other participant file is held out
DEVELOPMENT = ("1", "2", "3", "4", "5", "6", "7", "8")


def window_confusion(second_class: np.ndarray, labels: np.ndarray, fs: float, window_s: float = WINDOW_S) -> np.ndarray:
    """The one activity scorer (:func:`stridelab.estimators.activity.evaluation.window_confusion`) with the UCI label codes."""
    return _window_confusion(second_class, labels, fs, LABEL_TO_CLASS, window_s)


#: fixed hyper-parameters of the learned LOSO method (not tuned on the held-out participants)
LEARNED = {"model": "RandomForestClassifier", "n_estimators": 300, "min_samples_leaf": 2, "max_features": "sqrt",
           "class_weight": "balanced", "random_state": 0, "context_half_widths": [1], "window_s": WINDOW_S}


def window_labels(labels: np.ndarray, window_samples: int, n_windows: int) -> np.ndarray:
    """(W,) bench class index per window (``window_confusion``'s windows), −1 when the window is not wholly
    inside one scored label."""
    lab = np.asarray(labels)[: n_windows * window_samples].reshape(n_windows, window_samples)
    pure = (lab == lab[:, :1]).all(axis=1)
    return np.array([LABEL_TO_CLASS.get(int(v), -1) if ok else -1 for v, ok in zip(lab[:, 0], pure)], dtype=np.int64)


def _new_forest():
    from sklearn.ensemble import RandomForestClassifier
    return RandomForestClassifier(n_estimators=LEARNED["n_estimators"], min_samples_leaf=LEARNED["min_samples_leaf"],
                                  max_features=LEARNED["max_features"], class_weight=LEARNED["class_weight"],
                                  random_state=LEARNED["random_state"], n_jobs=1)


def participant_features(parts) -> dict:
    """``window_features`` of every participant (``WINDOW_S`` windows), by participant id; computed once and
    shared by ``learned_loso`` and ``label_consistency``."""
    from stridelab.estimators.activity.windows import window_features
    return {u.participant: window_features(u.acc, u.sampling_rate_hz, WINDOW_S) for u in parts}


def learned_loso(parts, progress_cb=None, features: dict | None = None) -> dict:
    """Leave-one-subject-out scores of the learned window classifier (see module docstring) over ``parts``
    (``UciParticipant`` list, ≥ 2). Same keys as the other methods plus ``protocol`` and, per participant,
    the unlabelled normalisation it used (gait-like windows, still-posture cluster separation)."""
    from stridelab.estimators.activity.windows import add_context
    if len(parts) < 2:
        raise ValueError("learned_loso needs at least two participants (train on the others)")
    features = features or participant_features(parts)
    feats = {}
    for u in parts:
        wf = features[u.participant]
        x, _ = add_context(wf.x, wf.names, tuple(LEARNED["context_half_widths"]))
        y = window_labels(u.labels, wf.window_samples, x.shape[0])
        feats[u.participant] = (x, y, wf)
    per, groups = {}, {k: np.zeros((4, 4), np.int64) for k in ("all", "development", "held_out")}
    for u in parts:
        if progress_cb:
            progress_cb(f"learned_loso: participant {u.participant}")
        x, y, wf = feats[u.participant]
        others = [q for q in feats if q != u.participant]
        Xtr = np.vstack([feats[q][0][feats[q][1] >= 0] for q in others])
        ytr = np.concatenate([feats[q][1][feats[q][1] >= 0] for q in others])
        clf = _new_forest().fit(Xtr, ytr)
        pred = clf.predict(x)
        sc = y >= 0
        C = np.zeros((4, 4), np.int64)
        np.add.at(C, (y[sc], pred[sc]), 1)
        names = wf.names
        per[u.participant] = {**scores(C), "calibration": wf.calibration, "trained_on": others,
                              "gait_like_windows": int(wf.gait.sum()),
                              "cluster_sep_deg": float(wf.x[0, names.index("cluster_sep_deg")])}
        groups["all"] += C
        groups["development" if u.participant in DEVELOPMENT else "held_out"] += C
        if progress_cb:
            progress_cb(None)
    return {**scores(groups["all"]), "development": scores(groups["development"]),
            "held_out": scores(groups["held_out"]), "per_participant": per,
            "protocol": ("leave-one-subject-out: each participant scored by a model trained only on the others; "
                         "per-participant normalisation from its own unlabelled signal; fixed hyper-parameters"),
            "hyper_parameters": dict(LEARNED)}


#: designs of the tuned random-forest baseline: same feature sets and contexts as ``DESIGNS`` of the default's
#: window model, ``min_samples_leaf`` in place of C (same number of designs, same nested protocol)
RF_DESIGNS = tuple({"feature_set": f, "context": c, "min_samples_leaf": leaf}
                   for f in ("all", "no_clusters") for c in ((1,), (6,), (1, 6)) for leaf in (2, 8))


def nested_lopo(ids: list, designs: tuple, predict, progress_cb=None) -> dict:
    """Leave-one-participant-out with the design chosen inside each outer fold by an inner
    leave-one-participant-out over the remaining participants.

    ``predict(train_ids, test_ids, design) -> {test_id: (4, 4) confusion}``. Every model is fitted on all
    participants but one (outer) or two (inner: trained without the outer and the inner test participant; the
    same fit serves both orders of a pair). Returns the outer-fold confusion per participant (``outer``), the
    design each outer fold chose (``chosen``), the flat LOPO score of every design (``designs``; choosing by it
    is what picks the final model, so its maximum is optimistic and is not a headline) and the design index
    the flat LOPO prefers (``final``)."""
    ids = list(ids)
    pair = {}
    outer = {}
    for k, d in enumerate(designs):
        if progress_cb:
            progress_cb(f"nested LOPO design {k + 1}/{len(designs)}")
        for i, a in enumerate(ids):
            outer[(a, k)] = predict([q for q in ids if q != a], [a], d)[a]
            for b in ids[i + 1:]:
                r = predict([q for q in ids if q not in (a, b)], [a, b], d)
                pair[(a, b, k)], pair[(b, a, k)] = r[b], r[a]     # (outer, inner): inner's confusion
    chosen, res = {}, {}
    for o in ids:
        inner = [_ba(sum(pair[(o, i, k)] for i in ids if i != o)) for k in range(len(designs))]
        chosen[o] = int(np.argmax(inner))
        res[o] = outer[(o, chosen[o])]
    flat = [_ba(sum(outer[(o, k)] for o in ids)) for k in range(len(designs))]
    return {"outer": res, "chosen": chosen, "designs": [{**designs[k], "lopo_balanced_accuracy": flat[k]}
                                                         for k in range(len(designs))],
            "final": int(np.argmax(flat))}


def _ba(C) -> float:
    C = np.asarray(C)
    present = C.sum(axis=1) > 0
    return float((np.diag(C)[present] / C.sum(axis=1)[present]).mean()) if present.any() else 0.0


def _design_json(d: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}


class UciWindows:
    """Per-participant data the window methods share, computed once: 26-Hz window features, window labels,
    the rules' per-second classes (``rules``) and the design matrices per design."""

    def __init__(self, parts, rule_seconds: dict):
        from stridelab.pipeline.activity_model import raw_features
        self.parts = {u.participant: u for u in parts}
        self.wf = {q: raw_features(u.acc, u.sampling_rate_hz) for q, u in self.parts.items()}
        self.y = {}
        for q, u in self.parts.items():
            n = min(self.wf[q].x.shape[0], u.labels.size // int(round(WINDOW_S * u.sampling_rate_hz)))
            self.y[q] = window_labels(u.labels, int(round(WINDOW_S * u.sampling_rate_hz)), n)
        self.rule = rule_seconds
        self._x = {}
        self._nested = {}

    def nested(self, name: str, ids: list, designs: tuple, predict, progress_cb=None) -> dict:
        """``nested_lopo`` once per (method, participants)."""
        key = (name, tuple(ids))
        if key not in self._nested:
            self._nested[key] = nested_lopo(ids, designs, predict, progress_cb)
        return self._nested[key]

    def x(self, q: str, d: dict) -> np.ndarray:
        from stridelab.pipeline.activity_model import design_x
        key = (q, d["feature_set"], tuple(d["context"]))
        if key not in self._x:
            self._x[key] = design_x(self.wf[q], d)
        return self._x[key]

    def train(self, ids, d):
        return [self.x(q, d)[: self.y[q].size] for q in ids], [self.y[q] for q in ids]

    def default_confusion(self, model, q: str, stairs_lean_deg: float) -> np.ndarray:
        from stridelab.pipeline.activity_model import merged_window_classes
        u = self.parts[q]
        sec = merged_window_classes(model, self.x(q, {"feature_set": model.feature_set, "context": model.context}),
                                    self.wf[q], self.rule[q], stairs_lean_deg)
        return window_confusion(sec, u.labels, u.sampling_rate_hz)

    def predict_default(self, stairs_lean_deg: float):
        from stridelab.pipeline.activity_model import fit_model

        def predict(train, tests, d):
            m = fit_model(*self.train(train, d), {**d, "C": d["C"]})
            return {q: self.default_confusion(m, q, stairs_lean_deg) for q in tests}
        return predict

    def predict_rf(self):
        def predict(train, tests, d):
            from sklearn.ensemble import RandomForestClassifier
            xs, ys = self.train(train, d)
            X = np.vstack([x[y >= 0] for x, y in zip(xs, ys)])
            Y = np.concatenate([y[y >= 0] for y in ys])
            clf = RandomForestClassifier(n_estimators=RF_TREES, min_samples_leaf=d["min_samples_leaf"],
                                         max_features="sqrt", class_weight="balanced", random_state=0,
                                         n_jobs=2).fit(X, Y)
            out = {}
            for q in tests:
                y = self.y[q]
                pred = clf.predict(self.x(q, d)[: y.size])
                C = np.zeros((4, 4), np.int64)
                np.add.at(C, (y[y >= 0], pred[y >= 0]), 1)
                out[q] = C
            return out
        return predict


#: trees of the tuned random-forest baseline (fixed; fewer than ``LEARNED``'s 300 because it is fitted 36 × 12 times)
RF_TREES = 50


def _grouped(per_conf: dict, development: tuple, extra: dict | None = None) -> dict:
    """Method entry from per-participant confusions: overall, development (tuning) and held-out groups."""
    per, groups = {}, {k: np.zeros((4, 4), np.int64) for k in ("all", "development", "held_out")}
    for q, C in per_conf.items():
        per[q] = {**scores(C), **((extra or {}).get(q, {}))}
        groups["all"] += C
        groups["development" if q in development else "held_out"] += C
    out = {**scores(groups["all"])}
    for g in ("development", "held_out"):
        if groups[g].sum():
            out[g] = scores(groups[g])
    out["per_participant"] = per
    return out


def tuned_window_methods(data: "UciWindows", stairs_lean_deg: float, *, rf: bool = True,
                         progress_cb=None) -> dict:
    """``default`` (rules + shipped window model) and ``rf_tuned`` (random forest, same designs budget and
    protocol). Participants the shipped model was trained on are scored by nested LOPO among them (outer
    folds); any other participant by the shipped model (``default``) or by a forest fitted on all training
    participants with the design the flat LOPO picked (``rf_tuned``)."""
    from stridelab.pipeline.activity_model import DESIGNS, MODEL_PATH, load_model
    model = load_model()
    train_ids = [q for q in data.parts if q in model.trained_on]
    new_ids = [q for q in data.parts if q not in model.trained_on]
    out = {}
    specs = [("default", DESIGNS, data.predict_default(stairs_lean_deg))]
    if rf and train_ids:             # the forest is fitted on the training participants only
        specs.append(("rf_tuned", RF_DESIGNS, data.predict_rf()))
    for name, designs, predict in specs:
        conf, extra, nested = {}, {}, None
        if len(train_ids) >= 3:
            nested = data.nested(name, train_ids, designs, predict, progress_cb)
            for q in train_ids:
                conf[q] = nested["outer"][q]
                extra[q] = {"scored_by": "nested LOPO outer fold", "design": _design_json(designs[nested["chosen"][q]])}
        for q in new_ids:
            if name == "default":
                conf[q] = data.default_confusion(model, q, stairs_lean_deg)
                extra[q] = {"scored_by": f"shipped model {MODEL_PATH.name} (trained on {', '.join(model.trained_on)})"}
            elif len(train_ids) >= 1:
                d = designs[nested["final"]] if nested else designs[0]
                conf[q] = predict(train_ids, [q], d)[q]
                extra[q] = {"scored_by": "forest fitted on the training participants", "design": _design_json(d)}
        entry = _grouped(conf, tuple(train_ids), extra)
        entry["protocol"] = (f"participants {', '.join(train_ids) or '-'}: nested leave-one-participant-out (outer "
                             f"folds; design chosen by an inner LOPO among the other {max(len(train_ids) - 1, 0)}); "
                             "others: the model fitted on all of them")
        if nested:
            entry["designs"] = [_design_json(d) for d in nested["designs"]]
            entry["final_design"] = _design_json(designs[nested["final"]])
        if name == "default":
            entry["shipped_model"] = {"path": str(MODEL_PATH.relative_to(PROJECT_ROOT)), "trained_on": list(model.trained_on),
                                      "feature_set": model.feature_set, "context": list(model.context),
                                      "provenance": model.provenance}
        out[name] = entry
    return out


def fit_shipped_model(data: "UciWindows", stairs_lean_deg: float, path: Path, progress_cb=None) -> dict:
    """Choose the design by flat LOPO over ``parts`` (``nested_lopo``'s ``final``), fit it on all of them and
    write the model file. Returns the choice and the nested score (what the design choice is worth on a
    participant not used for it)."""
    from stridelab.pipeline.activity_model import DESIGNS, fit_model, save_model
    ids = list(data.parts)
    nested = data.nested("default", ids, DESIGNS, data.predict_default(stairs_lean_deg), progress_cb)
    d = DESIGNS[nested["final"]]
    nested_ba = _ba(sum(nested["outer"].values()))
    prov = (f"UCI chest participants {', '.join(ids)} (CC BY 4.0), 10-s windows at 26 Hz; design chosen by "
            f"leave-one-participant-out over {len(DESIGNS)} designs (LOPO balanced accuracy "
            f"{nested['designs'][nested['final']]['lopo_balanced_accuracy']:.3f}; nested outer-fold {nested_ba:.3f}); "
            "command: stridelab bench activity --fit-model PATH")
    m = fit_model(*data.train(ids, d), d, provenance=prov)
    from dataclasses import replace
    m = replace(m, trained_on=tuple(ids))
    save_model(m, path)
    return {"path": str(path), "design": _design_json(d), "nested_balanced_accuracy": nested_ba,
            "designs": nested["designs"], "provenance": prov}


#: a priori rule for windows whose UCI label the chest signal contradicts (``label_consistency``); 0.2 is the most
#: lenient of the levels looked at (0.2 / 0.3 / 0.4 × gait intensity), i.e. the one giving the highest ceiling
CONSISTENCY = {"moving_rel_gait": 0.2, "moving_min_fraction": 0.5}


def label_consistency(parts, features: dict | None = None) -> dict:
    """Windows whose UCI label the chest signal contradicts, and the balanced accuracy this leaves at most.

    A scored window (``window_labels``) is *contradicted* when
    - it is labelled walking or stairs but the participant moves at walking-like intensity in fewer than half of
      its seconds (``moving_fraction`` with ``CONSISTENCY``: a 1-s chunk moves when its 0.3-20 Hz RMS reaches
      0.2 × the participant's median over its own gait-like windows), i.e. the chest is still for most of it;
    - it is labelled sitting or standing but is gait-like (``gait_windows``: regular stepping at 1.4-2.4 steps/s,
      ≥ 40 % of the vertical power in that band, ≥ 50 mg), i.e. the participant walks through it.
    A classifier that answers what the chest did in the window is wrong on every contradicted window, so the
    mean over classes of the consistent fraction (``ceiling_balanced_accuracy``) bounds its balanced accuracy
    from above, even if it is perfect on every other window (including stairs vs level walking). Labels are read
    only to count; nothing here is fitted."""
    from stridelab.estimators.activity.windows import moving_fraction
    features = features or participant_features(parts)
    per, tot, bad = {}, np.zeros(4, np.int64), np.zeros(4, np.int64)
    for u in parts:
        wf = features[u.participant]
        y = window_labels(u.labels, wf.window_samples, wf.x.shape[0])
        log_dyn = wf.x[:, wf.names.index("log_dyn")]
        level = 10 ** (np.median(log_dyn[wf.gait]) if wf.gait.sum() >= 3 else np.percentile(log_dyn, 90))
        mf = moving_fraction(u.acc, u.sampling_rate_hz, WINDOW_S, level, CONSISTENCY["moving_rel_gait"])
        mf = mf[: y.size]
        contra = np.where(y >= 2, mf < CONSISTENCY["moving_min_fraction"], wf.gait[: y.size])
        n = np.array([(y == c).sum() for c in range(4)])
        b = np.array([(contra & (y == c)).sum() for c in range(4)])
        per[u.participant] = {"windows": n.tolist(), "contradicted": b.tolist()}
        tot += n
        bad += b
    out = {"rule": dict(CONSISTENCY), "classes": list(BENCH_CLASSES), **_ceiling(tot, bad)}
    for group, keep in (("development", lambda q: q in DEVELOPMENT), ("held_out", lambda q: q not in DEVELOPMENT)):
        sel = [v for q, v in per.items() if keep(q)]
        if sel:
            out[group] = _ceiling(np.sum([v["windows"] for v in sel], axis=0), np.sum([v["contradicted"] for v in sel], axis=0))
    out["per_participant"] = per
    return out


def _ceiling(tot, bad) -> dict:
    tot, bad = np.asarray(tot), np.asarray(bad)
    present = tot > 0
    frac = 1.0 - bad[present] / tot[present]
    cons = np.full(tot.shape, np.nan)
    cons[present] = frac
    return {"windows": tot.tolist(), "contradicted": bad.tolist(),
            "consistent_fraction": [None if np.isnan(v) else float(v) for v in cons],
            "ceiling_balanced_accuracy": float(frac.mean()) if frac.size else None}


def synthetic_day(hours: float = 24.0, fs: float = 100.0, seed: int = 0) -> np.ndarray:
    """A synthetic chest day (m/s², sensor y up): blocks of lying, sitting, standing and 2 Hz walking."""
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * fs)
    acc = np.empty((n, 3))
    i = 0
    g = 9.80665
    while i < n:
        kind = rng.integers(4)
        m = min(n - i, int(rng.uniform(60, 1800) * fs))
        t = np.arange(m) / fs
        if kind == 0:
            acc[i:i + m] = [g, 0.0, 0.0]
        elif kind == 1:
            acc[i:i + m] = [-g * np.sin(0.15), g * np.cos(0.15), 0.0]
        elif kind == 2:
            acc[i:i + m] = [-g * np.sin(0.05), g * np.cos(0.05), 0.0]
        else:
            acc[i:i + m, 0] = -g * np.sin(0.07) + 2.0 * np.sin(2 * np.pi * 1.9 * t)
            acc[i:i + m, 1] = g * np.cos(0.07) + 3.0 * np.sin(2 * np.pi * 1.9 * t + 0.5)
            acc[i:i + m, 2] = 1.0 * np.sin(np.pi * 1.9 * t)
        i += m
    acc += rng.normal(0.0, 0.03, acc.shape)
    return acc


def speed_24h(fs: float = 100.0, window_model: str | None = "default") -> float:
    """Seconds for the pipeline's classifier (``classify_recording``; ``window_model=None``: rules only) +
    daily_summaries on a synthetic 24 h day at ``fs`` (after a warm-up call: numba JIT, model file)."""
    from stridelab.estimators.activity import daily_summaries
    from stridelab.pipeline.activity_model import classify_recording
    acc = synthetic_day(24.0, fs)
    classify_recording(acc[: int(600 * fs)], sampling_rate_hz=fs, t0_ns=0, timezone="Europe/Zurich",
                       window_model=window_model)
    t0 = time.perf_counter()
    r = classify_recording(acc, sampling_rate_hz=fs, t0_ns=1_700_000_000_000_000_000, timezone="Europe/Zurich",
                           window_model=window_model)
    daily_summaries(r)
    return time.perf_counter() - t0


def reference_seconds(events, t0_ns: int, n_sec: int) -> tuple[np.ndarray, int]:
    """Per-second reference class index (−1 = not scored, e.g. transitions) and the scripted step total from a
    simulated recording's activity events (whole seconds inside each labelled interval)."""
    from stridelab.estimators.activity import CLASSES
    ref = np.full(n_sec, -1, dtype=np.int64)
    steps = 0
    for e in events:
        if e.get("label") in CLASSES:
            a = int(np.ceil((e["t_ns"] - t0_ns) / 1e9))
            b = int((e["end_ns"] - t0_ns) // 1_000_000_000)
            ref[max(a, 0):max(min(b, n_sec), 0)] = CLASSES.index(e["label"])
        steps += int(e.get("steps", 0))
    return ref, steps


def simulated_days(n: int, *, preset: str = "default", window_model: str | None = "default", progress_cb=None) -> dict:
    """Per-second agreement and step error of the pipeline's classifier (``preset`` rules + ``window_model``;
    None = rules only) on N simulated 24 h days of the demo study."""
    import dataclasses

    from stridelab.estimators.activity import CLASSES, PRESETS, daily_summaries
    from stridelab.pipeline.activity_model import classify_recording
    from stridelab.studies.manifest import load_manifest
    from stridelab.validation.simulator import simulate_chest_day, study_participants
    m = load_manifest(None)
    m = dataclasses.replace(m, visits=1, free_living=dataclasses.replace(m.free_living, hours=24.0, start_local="00:00"))
    per = {}
    for i, part in enumerate(study_participants(m, n)):
        if progress_cb:
            progress_cb(f"simulated day {part.id}")
        rec, _ = simulate_chest_day(m, part, i)
        imu = rec.imu["chest"]
        t0 = int(imu.t_ns[0])
        params = dataclasses.replace(PRESETS[preset], thigh_length_m=float(rec.metadata["thigh_length_m"]))
        tic = time.perf_counter()
        r = classify_recording(imu.acc, sampling_rate_hz=m.sampling_rate_hz, t0_ns=t0, timezone=m.timezone,
                               params=params, window_model=window_model)
        daily_summaries(r)
        el = time.perf_counter() - tic
        ref, steps_ref = reference_seconds(rec.events, t0, r.second_class.size)
        sc = ref >= 0
        C = np.zeros((len(CLASSES), len(CLASSES)), dtype=np.int64)
        np.add.at(C, (ref[sc], r.second_class[sc].astype(np.int64)), 1)
        per[part.id] = {"agreement": float((r.second_class[sc] == ref[sc]).mean()) if sc.any() else None,
                        "steps": int(r.step_times_s.size), "steps_reference": int(steps_ref),
                        "steps_error_pct": (100.0 * (r.step_times_s.size - steps_ref) / steps_ref) if steps_ref else None,
                        "seconds": el, "hemiparetic": bool(getattr(part, "hemiparetic", False)),
                        "scored_s": int(sc.sum()), "confusion": C.tolist()}
        if progress_cb:
            progress_cb(None)
    ag = [v["agreement"] for v in per.values() if v["agreement"] is not None]
    return {"preset": preset, "window_model": window_model, "hours": 24.0, "classes": list(CLASSES), "per_participant": per,
            "min_agreement": min(ag) if ag else None,
            "max_abs_steps_error_pct": max((abs(v["steps_error_pct"]) for v in per.values()
                                            if v["steps_error_pct"] is not None), default=None),
            "goal": {"agreement": 0.95, "abs_steps_error_pct": 3.0}}


def run_benchmark(directory: Path | None, *, show_progress: bool = True, speed: bool = True,
                  simulated: int = 0, tuned_rf: bool = True, fit_model_path: Path | None = None) -> dict:
    """Run the benchmark; returns the JSON-able result (see module docstring). ``directory`` None skips UCI.
    ``fit_model_path``: refit the default's window model on every participant in ``directory`` and write it
    there (``fit_model`` key) before scoring."""
    from stridelab.estimators.activity import PRESETS, classify_day
    from stridelab.pipeline.formats.uci_chest import load_uci_participant
    parts, skipped = [], []
    if directory is not None:
        # file by file, as load_uci_chest orders them: a file that cannot be read is listed and the bench goes on
        files = sorted(Path(directory).glob("*.csv"),
                       key=lambda f: (0, int(f.stem)) if f.stem.isdigit() else (1, f.stem))
        if not files:
            raise UserError(f"no UCI chest CSV files (*.csv) in {directory}")
        for f in files:
            try:
                parts.append(load_uci_participant(f))
            except ValueError as e:
                skipped.append({"file": str(f), "reason": str(e).splitlines()[0] if str(e) else "unreadable"})
        if not parts:
            raise UserError(f"{directory}: no UCI chest file could be read: "
                            + "; ".join(f"{x['file']}: {x['reason']}" for x in skipped))
    methods, out_extra = {}, {}
    stairs_lean = PRESETS["default"].stairs_lean_deg
    with progress(show_progress) as p:
        task = p.add_task("activity", total=None)

        def cb(desc):
            if desc:
                p.update(task, description=desc)
        rule_seconds = {}
        for name, preset in (("thesis", "thesis"), ("rules", "default")) if parts else ():
            params = PRESETS[preset]
            conf, extra = {}, {}
            for u in parts:
                cb(f"{name}: participant {u.participant}")
                r = classify_day(u.acc, sampling_rate_hz=u.sampling_rate_hz, params=params)
                if name == "rules":
                    rule_seconds[u.participant] = r.second_class
                conf[u.participant] = window_confusion(r.second_class, u.labels, u.sampling_rate_hz)
                extra[u.participant] = {"calibration": r.calibration.status, "bouts": len(r.bouts),
                                        "transitions": len(r.transitions)}
            methods[name] = {**_grouped(conf, DEVELOPMENT, extra),
                             "protocol": "rules only; nothing fitted to UCI labels"}
        data = UciWindows(parts, rule_seconds) if parts else None
        if fit_model_path is not None and len(parts) >= 3:
            out_extra["fit_model"] = fit_shipped_model(data, stairs_lean, fit_model_path, cb)
        if data is not None:
            methods.update(tuned_window_methods(data, stairs_lean, rf=tuned_rf, progress_cb=cb))
        features = participant_features(parts) if parts else {}
        if len(parts) >= 2:
            methods["learned_loso"] = learned_loso(parts, progress_cb=cb, features=features)
        if parts:
            cb("label consistency")
            consistency = label_consistency(parts, features)
        scored = {k: v["balanced_accuracy"] for k, v in methods.items() if v.get("balanced_accuracy") is not None}
        out = {"dataset": str(directory) if directory is not None else None, "classes": list(BENCH_CLASSES),
               "window_s": WINDOW_S,
               "protocol": ("thesis / rules: nothing learned from UCI labels. default (rules + window model, the "
                            "pipeline's activity stage) and rf_tuned: participants the shipped model was trained on "
                            "are scored by nested leave-one-participant-out (see each method's 'protocol'), others "
                            "by the fitted model. learned_loso: fixed forest, leave-one-subject-out"),
               "development_participants": list(DEVELOPMENT), "methods": methods,
               # what stridelab.pipeline.stages.activity runs: stridelab.pipeline.activity_model.classify_recording
               "default": "default",
               "best_balanced_accuracy": max(scored, key=scored.get) if scored else None,
               "reference_random_forest_loso_balanced_accuracy": 0.59, "skipped_files": skipped, **out_extra}
        if parts:
            out["label_consistency"] = consistency
        if speed:
            cb("speed: 24 h at 100 Hz")
            out["seconds_24h_100hz"] = speed_24h()
            out["seconds_24h_100hz_rules_only"] = speed_24h(window_model=None)
        if simulated > 0:
            out["simulated"] = simulated_days(simulated, progress_cb=cb)
    return out


@click.command("activity")
@click.option("--uci-chest", "uci", type=click.Path(path_type=Path), default=DEFAULT_UCI, show_default=True,
              help="folder of the UCI chest CSV files (<n>.csv: seq,x,y,z,label)")
@click.option("--no-speed", is_flag=True, help="skip the 24 h x 100 Hz speed measurement")
@click.option("--no-uci", is_flag=True, help="skip the UCI chest part (e.g. only the simulated days)")
@click.option("--simulated", type=click.IntRange(min=0), default=4, show_default=True,
              help="simulated 24 h free-living days of the demo study to score (0 = skip)")
@click.option("--no-tuned-rf", is_flag=True, help="skip the nested-LOPO random-forest baseline (rf_tuned, the slow part)")
@click.option("--fit-model", "fit_model", type=click.Path(path_type=Path), default=None,
              help="refit the default's window model on the UCI participants given and write it to this file "
                   "(the shipped one: pipeline/models/activity_window_lr.json)")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(uci: Path, no_speed: bool, no_uci: bool, simulated: int, no_tuned_rf: bool, fit_model: Path | None,
            as_json: bool) -> None:
    """Daily-activity classes (sitting/standing/walking/stairs) on the UCI chest set, thesis vs default vs a
    learned classifier evaluated leave-one-subject-out (learned_loso), and
    per-second agreement / step error on simulated 24 h days with reference labels.

    \b
    Examples:
      stridelab bench activity
      stridelab bench activity --uci-chest ../shared/data/uci_chest --json
      stridelab bench activity --no-uci --no-speed --simulated 2
    """
    if not no_uci and not uci.is_dir():
        raise UserError(f"UCI chest data not found at {uci}; pass --uci-chest DIR (see DESIGN.md 'Real data') "
                        "or --no-uci")
    if fit_model is not None and no_uci:
        raise UserError("--fit-model needs the UCI participants (drop --no-uci)")
    result = run_benchmark(None if no_uci else uci, show_progress=not as_json or err_console.is_terminal,
                           speed=not no_speed, simulated=simulated, tuned_rf=not no_tuned_rf,
                           fit_model_path=fit_model)
    if as_json:
        emit_json(result)
        return
    for name, m in result["methods"].items():
        ho = m.get("held_out", {}).get("balanced_accuracy")
        err_console.print(f"{name}: accuracy {m['accuracy']:.3f}, balanced accuracy {m['balanced_accuracy']:.3f}"
                          + (f" (held out {ho:.3f})" if ho is not None else ""))
        for row, c in zip(BENCH_CLASSES, m["confusion"]):
            err_console.print(f"  {row:9s} {c}")
    if "label_consistency" in result:
        lc = result["label_consistency"]
        err_console.print(f"labels contradicted by the signal (sitting/standing/walking/stairs): {lc['contradicted']} "
                          f"of {lc['windows']} windows; balanced accuracy ceiling {lc['ceiling_balanced_accuracy']:.3f}"
                          + (f" (held out {lc['held_out']['ceiling_balanced_accuracy']:.3f})" if "held_out" in lc else ""))
    for x in result.get("skipped_files", []):
        err_console.print(f"skipped {x['file']}: {x['reason']}", markup=False)
    if "seconds_24h_100hz" in result:
        err_console.print(f"24 h at 100 Hz: {result['seconds_24h_100hz']:.2f} s")
    if "simulated" in result:
        err_console.print("simulated 24 h days (default params): participant, agreement, steps error, seconds")
        for pid, v in result["simulated"]["per_participant"].items():
            err_console.print(f"  {pid}: agreement {100 * v['agreement']:.1f} %, steps {v['steps_error_pct']:+.1f} % "
                              f"({v['steps']} / {v['steps_reference']}), {v['seconds']:.2f} s")
