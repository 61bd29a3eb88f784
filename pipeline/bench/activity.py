"""``stridelab bench activity``: chest-accelerometer activity classes on the UCI chest set, and the speed of a
24 h, 100 Hz day.

UCI "Activity Recognition from a Single Chest-Mounted Accelerometer" (uncalibrated 12-bit counts, 52 Hz,
unknown sensor orientation; reader ``pipeline.formats.uci_chest``). Each participant file is classified as one
continuous recording by ``estimators.activity.classify_day``; the per-second classes are mapped to four classes
(lying/sitting -> sitting, standing/non-wear -> standing, level walking -> walking, stairs up/down -> stairs)
and scored on non-overlapping 10-s windows lying wholly inside one reference label (majority of the window's
seconds). Reference: label 1 sitting, 3 and 7 standing, 4 and 6 walking, 5 stairs; 2 and 0 excluded.

Protocol (``thesis`` and ``default``): no component is learned from UCI labels. Parameters are the thesis values and defaults set on
synthetic data; participants 1-4 were looked at while developing (``development``), 5 and above were not
(``held_out``). Both groups are reported separately, plus all participants together.

Method ``learned_loso`` (project extension, UCI benchmark only): a random forest on per-window features
(``estimators.activity.windows``: per-participant auto-calibration, lean to the participant's own walking
posture and to its two still-posture clusters, motion / sway / gait features, ±1-window context), evaluated
leave-one-subject-out: each participant's windows are classified by a model trained only on the other
participants' labelled windows; the participant's own normalisation uses only its unlabelled signal.
Hyper-parameters are fixed (``LEARNED``), chosen before the run over all participants; the feature design was
explored with LOSO inside participants 1-4 only. ``default`` names the pipeline's own method (the rule-based
preset); ``best_balanced_accuracy`` the method that scored best.

Label consistency (key ``label_consistency``, ``label_consistency``): windows whose UCI label the chest signal
contradicts (labelled walking/stairs but still for most seconds, labelled sitting/standing but walking
throughout) and the balanced accuracy this leaves at most to any classifier that answers what the chest did.
Speed: ``classify_day`` + ``daily_summaries`` on a synthetic 24 h, 100 Hz chest day (8.64 M samples), after a
warm-up call (numba JIT).

Simulated free-living days (``--simulated N``, key ``simulated``): the demo study's first N participants, one
24 h day each from ``studies.simulator.simulate_chest_day`` (its reference labels and scripted step counts),
classified with the project default and the participant's thigh length. ``agreement`` = per-second agreement
over the seconds whose reference is a class (``transition`` seconds are not scored; a labelled interval covers
its whole seconds, same definition as docs/activity.md); ``steps_error_pct`` = 100 (detected − scripted) /
scripted; ``seconds`` = classify_day + daily_summaries on that day.
"""
from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np

from pipeline.console import UserError, emit_json, err_console, progress

PROJECT_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_UCI = PROJECT_ROOT.parent / "shared" / "data" / "uci_chest"
from estimators.activity.evaluation import CLASS_MAP, SCORED_CLASSES as BENCH_CLASSES, WINDOW_S, scores  # noqa: E402,F401
from estimators.activity.evaluation import window_confusion as _window_confusion  # noqa: E402
from pipeline.formats.uci_chest import LABEL_TO_CLASS  # noqa: E402
DEVELOPMENT = ("1", "2", "3", "4")


def window_confusion(second_class: np.ndarray, labels: np.ndarray, fs: float, window_s: float = WINDOW_S) -> np.ndarray:
    """The one activity scorer (:func:`estimators.activity.evaluation.window_confusion`) with the UCI label codes."""
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
    from estimators.activity.windows import window_features
    return {u.participant: window_features(u.acc, u.sampling_rate_hz, WINDOW_S) for u in parts}


def learned_loso(parts, progress_cb=None, features: dict | None = None) -> dict:
    """Leave-one-subject-out scores of the learned window classifier (see module docstring) over ``parts``
    (``UciParticipant`` list, ≥ 2). Same keys as the other methods plus ``protocol`` and, per participant,
    the unlabelled normalisation it used (gait-like windows, still-posture cluster separation)."""
    from estimators.activity.windows import add_context
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
    from estimators.activity.windows import moving_fraction
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


def speed_24h(fs: float = 100.0) -> float:
    """Seconds for classify_day + daily_summaries on a synthetic 24 h day at ``fs`` (after a JIT warm-up)."""
    from estimators.activity import classify_day, daily_summaries
    acc = synthetic_day(24.0, fs)
    classify_day(acc[: int(600 * fs)], sampling_rate_hz=fs, t0_ns=0, timezone="Europe/Zurich")
    t0 = time.perf_counter()
    r = classify_day(acc, sampling_rate_hz=fs, t0_ns=1_700_000_000_000_000_000, timezone="Europe/Zurich")
    daily_summaries(r)
    return time.perf_counter() - t0


def reference_seconds(events, t0_ns: int, n_sec: int) -> tuple[np.ndarray, int]:
    """Per-second reference class index (−1 = not scored, e.g. transitions) and the scripted step total from a
    simulated recording's activity events (whole seconds inside each labelled interval)."""
    from estimators.activity import CLASSES
    ref = np.full(n_sec, -1, dtype=np.int64)
    steps = 0
    for e in events:
        if e.get("label") in CLASSES:
            a = int(np.ceil((e["t_ns"] - t0_ns) / 1e9))
            b = int((e["end_ns"] - t0_ns) // 1_000_000_000)
            ref[max(a, 0):max(min(b, n_sec), 0)] = CLASSES.index(e["label"])
        steps += int(e.get("steps", 0))
    return ref, steps


def simulated_days(n: int, *, preset: str = "default", progress_cb=None) -> dict:
    """Per-second agreement and step error of ``preset`` on N simulated 24 h days of the demo study."""
    import dataclasses

    from estimators.activity import CLASSES, PRESETS, classify_day, daily_summaries
    from studies.manifest import load_manifest
    from studies.simulator import simulate_chest_day, study_participants
    m = load_manifest(None)
    m = dataclasses.replace(m, free_living=dataclasses.replace(m.free_living, hours=24.0))
    per = {}
    for i, part in enumerate(study_participants(m, n)):
        if progress_cb:
            progress_cb(f"simulated day {part.id}")
        rec, _ = simulate_chest_day(m, part, i)
        imu = rec.imu["chest"]
        t0 = int(imu.t_ns[0])
        params = dataclasses.replace(PRESETS[preset], thigh_length_m=float(rec.metadata["thigh_length_m"]))
        tic = time.perf_counter()
        r = classify_day(imu.acc, sampling_rate_hz=m.sampling_rate_hz, t0_ns=t0, timezone=m.timezone, params=params)
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
    return {"preset": preset, "hours": 24.0, "classes": list(CLASSES), "per_participant": per,
            "min_agreement": min(ag) if ag else None,
            "max_abs_steps_error_pct": max((abs(v["steps_error_pct"]) for v in per.values()
                                            if v["steps_error_pct"] is not None), default=None),
            "goal": {"agreement": 0.95, "abs_steps_error_pct": 3.0}}


def run_benchmark(directory: Path | None, *, show_progress: bool = True, speed: bool = True,
                  simulated: int = 0) -> dict:
    """Run the benchmark; returns the JSON-able result (see module docstring). ``directory`` None skips UCI."""
    from estimators.activity import PRESETS, classify_day
    from pipeline.formats.uci_chest import load_uci_chest
    parts = []
    if directory is not None:
        try:
            parts = load_uci_chest(directory)
        except ValueError as e:
            raise UserError(str(e)) from e
    methods = {}
    with progress(show_progress) as p:
        task = p.add_task("activity", total=len(parts) * (3 if len(parts) >= 2 else 2) + (1 if speed else 0) + simulated)
        for name in (("thesis", "default") if parts else ()):
            params = PRESETS[name]
            per, groups = {}, {"all": np.zeros((4, 4), np.int64), "development": np.zeros((4, 4), np.int64),
                               "held_out": np.zeros((4, 4), np.int64)}
            for u in parts:
                p.update(task, description=f"{name}: participant {u.participant}")
                r = classify_day(u.acc, sampling_rate_hz=u.sampling_rate_hz, params=params)
                C = window_confusion(r.second_class, u.labels, u.sampling_rate_hz)
                per[u.participant] = {**scores(C), "calibration": r.calibration.status, "bouts": len(r.bouts),
                                      "transitions": len(r.transitions)}
                groups["all"] += C
                groups["development" if u.participant in DEVELOPMENT else "held_out"] += C
                p.advance(task)
            overall = scores(groups["all"])
            methods[name] = {**overall, "development": scores(groups["development"]),
                             "held_out": scores(groups["held_out"]), "per_participant": per}

        features = participant_features(parts) if parts else {}

        def cb(desc):
            if desc:
                p.update(task, description=desc)
            else:
                p.advance(task)
        if len(parts) >= 2:
            methods["learned_loso"] = learned_loso(parts, progress_cb=cb, features=features)
        if parts:
            p.update(task, description="label consistency")
            consistency = label_consistency(parts, features)
        scored = {k: v["balanced_accuracy"] for k, v in methods.items() if v.get("balanced_accuracy") is not None}
        out = {"dataset": str(directory) if directory is not None else None, "classes": list(BENCH_CLASSES),
               "window_s": WINDOW_S,
               "protocol": ("thesis/default: no parameter learned from UCI labels; thesis values + defaults set on "
                            "synthetic data; participants 1-4 inspected during development, the others held out. "
                            "learned_loso: leave-one-subject-out (see its own 'protocol')"),
               "development_participants": list(DEVELOPMENT), "methods": methods,
               # the pipeline's activity stage runs the rule-based preset "default" (a model trained on UCI's
               # uncalibrated 52 Hz counts does not transfer to calibrated 100 Hz recordings)
               "default": "default",
               "best_balanced_accuracy": max(scored, key=scored.get) if scored else None,
               "reference_random_forest_loso_balanced_accuracy": 0.59}
        if parts:
            out["label_consistency"] = consistency
        if speed:
            p.update(task, description="speed: 24 h at 100 Hz")
            out["seconds_24h_100hz"] = speed_24h()
            p.advance(task)
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
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(uci: Path, no_speed: bool, no_uci: bool, simulated: int, as_json: bool) -> None:
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
    result = run_benchmark(None if no_uci else uci, show_progress=not as_json or err_console.is_terminal,
                           speed=not no_speed, simulated=simulated)
    if as_json:
        emit_json(result)
        return
    for name, m in result["methods"].items():
        err_console.print(f"{name}: accuracy {m['accuracy']:.3f}, balanced accuracy {m['balanced_accuracy']:.3f} "
                          f"(held out {m['held_out']['balanced_accuracy']:.3f})")
        for row, c in zip(BENCH_CLASSES, m["confusion"]):
            err_console.print(f"  {row:9s} {c}")
    if "label_consistency" in result:
        lc = result["label_consistency"]
        err_console.print(f"labels contradicted by the signal (sitting/standing/walking/stairs): {lc['contradicted']} "
                          f"of {lc['windows']} windows; balanced accuracy ceiling {lc['ceiling_balanced_accuracy']:.3f}"
                          + (f" (held out {lc['held_out']['ceiling_balanced_accuracy']:.3f})" if "held_out" in lc else ""))
    if "seconds_24h_100hz" in result:
        err_console.print(f"24 h at 100 Hz: {result['seconds_24h_100hz']:.2f} s")
    if "simulated" in result:
        err_console.print("simulated 24 h days (default params): participant, agreement, steps error, seconds")
        for pid, v in result["simulated"]["per_participant"].items():
            err_console.print(f"  {pid}: agreement {100 * v['agreement']:.1f} %, steps {v['steps_error_pct']:+.1f} % "
                              f"({v['steps']} / {v['steps_reference']}), {v['seconds']:.2f} s")
