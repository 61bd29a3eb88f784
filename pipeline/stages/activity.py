"""Daily activity for every free-living chest recording: warehouse -> stridelab.estimators.activity -> warehouse.

``compute``: only the accelerometer is read (the method ignores the gyroscope). A recording longer than
``DAY_PIECES_ABOVE_S`` (a week-long free-living recording: 60 M samples) is classified one local calendar
day at a time (midnight to midnight, the days the daily summaries report), so a worker holds one day of
samples, never the week; the per-second classes of the days are joined before the bouts are cut, so a bout
crossing midnight stays one bout. Recordings up to that length are classified in one piece.
``score`` (separate step): window accuracy against the recording's labelled ``activity`` intervals by the one
scorer :func:`stridelab.estimators.activity.evaluation.window_confusion` that ``stridelab bench activity`` uses.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from stridelab.pipeline.stages._shape import StageContext, shaped_stage

TABLES = ("activity_bouts", "activity_transitions", "activity_daily", "accuracy_metrics")
#: longer recordings are classified per local day (bounded memory); a 24-25 h day stays one piece
DAY_PIECES_ABOVE_S = 26 * 3600.0
#: samples whose reference labels are scored at once (accuracy rows; about a day at 100 Hz)
SCORE_SLICE_SAMPLES = 1 << 23


@dataclass(frozen=True)
class ActivityParams:
    """preset: name in :data:`stridelab.estimators.activity.PRESETS`. placement: the IMU classified.
    window_model: "default" = the shipped UCI-fitted window model refines the rule timeline
    (stridelab.pipeline.activity_model; docs/activity.md); None = rules only."""
    preset: str = "default"
    placement: str = "chest"
    window_model: str | None = "default"


def _runs(classes: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index ranges of constant class (one ``activity_bouts`` row each)."""
    if classes.size == 0:
        return []
    edges = np.concatenate([[0], np.flatnonzero(np.diff(classes)) + 1, [classes.size]])
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def _day_pieces(ctx: StageContext, imu, tz: str) -> list[tuple[int, int]]:
    """[start, stop) sample ranges: the whole recording, or its local calendar days when it is long."""
    from stridelab.estimators.activity._daily import local_midnights_ns
    n = imu.n_samples
    if n / imu.fs_hz <= DAY_PIECES_ABOVE_S:
        return [(0, n)]
    t = ctx.read_times(imu)
    cuts = [int(np.searchsorted(t, b)) for _, _, b in local_midnights_ns(int(t[0]), int(t[-1]), tz)[:-1]]
    edges = [0] + [c for c in cuts if 0 < c < n] + [n]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def compute(ctx: StageContext, p: ActivityParams) -> None:
    # imported here, in the worker: the coordinator reads the stage's declaration only (this module is in its
    # registry), and stridelab.estimators.activity brings SciPy's signal package (~0.7 CPU-s of imports per run)
    from stridelab.estimators.activity import CLASSES, PRESETS, TRANSITIONS, daily_summaries
    from stridelab.pipeline.activity_model import classify_recording
    if p.preset not in PRESETS:
        raise ValueError(f"unknown activity preset '{p.preset}'; choose one of {', '.join(PRESETS)}")
    if all(p.placement not in r["sensors"] for r in ctx.recordings):
        have = sorted({x for r in ctx.recordings for x in r["sensors"]})
        return ctx.skip(f"activity skipped: no {p.placement} IMU (session has {', '.join(have) or 'no IMU'})")
    sid, tz, notes = ctx.session_id, ctx.session.get("timezone") or "UTC", []
    for rec in ctx.recordings:
        desc = next(iter(ctx.imus(read=False, placements=(p.placement,), recordings=[rec])), None)
        if desc is None:
            notes.append(f"{rec.get('trial')}: no {p.placement} IMU")
            continue
        est = PRESETS[p.preset]
        if rec.get("metadata", {}).get("thigh_length_m"):
            est = replace(est, thigh_length_m=float(rec["metadata"]["thigh_length_m"]))
        secs, sec_t, sec_steps = [], [], []
        for a, b in _day_pieces(ctx, desc, tz):
            t0_ns = int(ctx.read_times(desc, a, a + 1)[0])
            res = classify_recording(ctx.read_acc(desc, a, b), sampling_rate_hz=desc.fs_hz, t0_ns=t0_ns, timezone=tz,
                                     params=est, window_model=p.window_model, overwrite_input=True)
            sec = res.second_class
            step_sec = np.floor(res.step_times_s).astype(np.int64)
            secs.append(sec)
            sec_t.append(res.second_t_ns)
            sec_steps.append(np.bincount(step_sec[(step_sec >= 0) & (step_sec < sec.size)], minlength=sec.size))
            ctx.emit("activity_transitions", [
                {"session_id": sid, "t_ns": int(res.t0_ns + round(t * 1e9)), "kind": TRANSITIONS[int(k)],
                 "dy_m": None if np.isnan(dy) else float(dy)}
                for t, k, dy in zip(res.transitions.t_s, res.transitions.kind, res.transitions.dy_m)])
            ctx.emit("activity_daily", [
                {"session_id": sid, "date": d.date, "day_length_s": d.day_length_s, "recorded_s": d.recorded_s,
                 "wear_s": d.wear_s, "class": cls, "seconds": int(d.seconds.get(cls, 0)),
                 "steps": int(d.steps.get(cls, 0)), "n_transitions": int(sum(d.transitions.values())),
                 "n_bouts": d.n_bouts, "bout_s_median": float(d.bout_s_median), "bout_s_max": float(d.bout_s_max)}
                for d in daily_summaries(res, tz) for cls in CLASSES])
            notes += list(res.warnings)
            del res
        sec, sec_t, steps_per_sec = np.concatenate(secs), np.concatenate(sec_t), np.concatenate(sec_steps)
        ctx.emit("activity_bouts", [
            {"session_id": sid, "content_hash": rec["content_hash"], "start_ns": int(sec_t[a]),
             "end_ns": int(sec_t[b - 1]) + 1_000_000_000, "class": CLASSES[int(sec[a])],
             "steps": int(steps_per_sec[a:b].sum())} for a, b in _runs(sec)])
        ctx.found.append((rec, desc, sec, sec_t))
    ctx.set_note("; ".join(notes)[:500])


def score(ctx: StageContext, p: ActivityParams) -> None:
    """Per recording with labelled ``activity`` intervals (each annotation one label run; labels outside
    :data:`stridelab.estimators.activity.evaluation.SCORED_CLASSES` not scored): balanced accuracy and accuracy of windows."""
    from stridelab.estimators.activity.evaluation import SCORED_CLASSES, scores, window_confusion, window_samples
    est = f"activity:{p.preset}" + (f"+window_model:{p.window_model}" if p.window_model else "")
    for rec, imu, sec, sec_t in ctx.found:
        act = [e for e in ctx.inp.events if e.get("type") == "activity" and e.get("end_ns") is not None
               and rec["start_ns"] <= e["t_ns"] <= rec["end_ns"]]
        if not any(e.get("label") in SCORED_CLASSES for e in act):
            continue
        n, t_first = imu.n_samples, int(ctx.read_times(imu, 0, 1)[0])
        k = (np.asarray(sec_t, np.int64) - t_first) // 1_000_000_000      # seconds from the first sample
        second_class = np.zeros(int(k.max()) + 1 if len(k) else 1, np.int64)
        second_class[k[k >= 0]] = np.asarray(sec)[k >= 0]
        code_to_class = {i: SCORED_CLASSES.index(e["label"]) for i, e in enumerate(act)
                         if e.get("label") in SCORED_CLASSES}
        # sample-level labels a slice at a time (whole windows, about a day): a week is 60 M samples, whose
        # stamps, label codes and second indices held at once took ~1.5 GB
        w = window_samples(imu.fs_hz)
        step = max(1, SCORE_SLICE_SAMPLES // w) * w
        C = 0
        for a in range(0, n, step):
            t_ns = ctx.read_times(imu, a, min(n, a + step)).ravel()
            codes = np.full(len(t_ns), -1, np.int64)
            for i, e in enumerate(act):
                codes[np.searchsorted(t_ns, e["t_ns"]):np.searchsorted(t_ns, e["end_ns"])] = i
            C = C + window_confusion(second_class, codes, imu.fs_hz, code_to_class, first_sample=a)
            del t_ns, codes
        sc = scores(C)
        base = {"session_id": ctx.session_id, "stage": "activity", "estimator": est, "placement": p.placement}
        ctx.emit("accuracy_metrics", [{**base, "metric": m, "value": sc[m], "unit": "fraction"}
                                      for m in ("balanced_accuracy", "accuracy") if sc[m] is not None]
                 + [{**base, "metric": "n_windows", "value": float(sc["windows"]), "unit": "windows"}])


STAGE = shaped_stage("activity", "5", ActivityParams, compute, score=score, tables=TABLES,
                     session_kinds=("free_living",))
