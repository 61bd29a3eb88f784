"""Daily activity for every free-living chest recording: warehouse -> estimators.activity -> warehouse.

Only the accelerometer is read (the method ignores the gyroscope). A recording longer than
``DAY_PIECES_ABOVE_S`` (a week-long free-living recording: 60 M samples) is classified one local calendar
day at a time (midnight to midnight, the days the daily summaries report), so a worker holds one day of
samples, never the week; the per-second classes of the days are joined before the bouts are cut, so a bout
crossing midnight stays one bout. Recordings up to that length are classified in one piece, as before.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.stages import SessionInput, Stage, StageOutput
from warehouse.read import read_column_range, series_rows

#: longer recordings are classified per local day (bounded memory); a 24-25 h day stays one piece
DAY_PIECES_ABOVE_S = 26 * 3600.0
#: samples whose reference labels are scored at once (accuracy rows; about a day at 100 Hz)
SCORE_SLICE_SAMPLES = 1 << 23


def default_params() -> dict:
    # window_model: "default" = the shipped UCI-fitted window model refines the rule timeline
    # (pipeline.activity_model; docs/activity.md); None = rules only
    return {"preset": "default", "placement": "chest", "window_model": "default"}


def _runs(classes: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index ranges of constant class."""
    if classes.size == 0:
        return []
    cut = np.flatnonzero(np.diff(classes)) + 1
    edges = np.concatenate([[0], cut, [classes.size]])
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def _pieces(root: str, path: str, n: int, fs: float, tz: str) -> list[tuple[int, int]]:
    """[start, stop) sample ranges: the whole recording, or its local calendar days when it is long."""
    if n / fs <= DAY_PIECES_ABOVE_S:
        return [(0, n)]
    from estimators.activity._daily import local_midnights_ns
    t = read_column_range(root, path, ("t_ns",), dtype=np.int64)
    cuts = [int(np.searchsorted(t, b)) for _, _, b in local_midnights_ns(int(t[0]), int(t[-1]), tz)[:-1]]
    del t
    edges = [0] + [c for c in cuts if 0 < c < n] + [n]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def compute(inp: SessionInput, params: dict) -> StageOutput:
    # imported here, in the worker: the coordinator reads the stage's declaration only (this module is in its
    # registry), and estimators.activity brings SciPy's signal package (~0.7 CPU-s of imports per run)
    from estimators.activity import CLASSES, PRESETS, TRANSITIONS, daily_summaries
    from pipeline.activity_model import classify_recording
    if params["preset"] not in PRESETS:
        raise ValueError(f"unknown activity preset '{params['preset']}'; choose one of {', '.join(PRESETS)}")
    s = inp.session
    tz = s.get("timezone") or "UTC"
    bouts, transitions, daily, notes, accuracy = [], [], [], [], []
    for rec in inp.recordings:
        imu = rec["sensors"].get(params["placement"], {}).get("imu")
        if imu is None:
            notes.append(f"{rec.get('trial')}: no {params['placement']} IMU")
            continue
        p = PRESETS[params["preset"]]
        thigh = rec.get("metadata", {}).get("thigh_length_m")
        if thigh:
            p = replace(p, thigh_length_m=float(thigh))
        path, fs = imu["series_path"], float(imu["sampling_rate_hz"])
        secs, sec_t, sec_steps = [], [], []
        for a, b in _pieces(inp.root, path, series_rows(inp.root, path), fs, tz):
            t0_ns = int(read_column_range(inp.root, path, ("t_ns",), a, a + 1, dtype=np.int64)[0])
            acc = read_column_range(inp.root, path, ("acc_x", "acc_y", "acc_z"), a, b)
            res = classify_recording(acc, sampling_rate_hz=fs, t0_ns=t0_ns, timezone=tz, params=p,
                                     window_model=params.get("window_model", "default"), overwrite_input=True)
            del acc
            sec = res.second_class
            step_sec = np.floor(res.step_times_s).astype(np.int64)
            secs.append(sec)
            sec_t.append(res.second_t_ns)
            sec_steps.append(np.bincount(step_sec[(step_sec >= 0) & (step_sec < sec.size)], minlength=sec.size))
            for t, k, dy in zip(res.transitions.t_s, res.transitions.kind, res.transitions.dy_m):
                transitions.append({"session_id": s["session_id"], "t_ns": int(res.t0_ns + round(t * 1e9)),
                                    "kind": TRANSITIONS[int(k)], "dy_m": None if np.isnan(dy) else float(dy)})
            for d in daily_summaries(res, tz):
                for cls in CLASSES:
                    daily.append({"session_id": s["session_id"], "date": d.date, "day_length_s": d.day_length_s,
                                  "recorded_s": d.recorded_s, "wear_s": d.wear_s, "class": cls,
                                  "seconds": int(d.seconds.get(cls, 0)), "steps": int(d.steps.get(cls, 0)),
                                  "n_transitions": int(sum(d.transitions.values())), "n_bouts": d.n_bouts,
                                  "bout_s_median": float(d.bout_s_median), "bout_s_max": float(d.bout_s_max)})
            notes += list(res.warnings)
            del res
        sec, sec_t, steps_per_sec = np.concatenate(secs), np.concatenate(sec_t), np.concatenate(sec_steps)
        for a, b in _runs(sec):
            bouts.append({"session_id": s["session_id"], "content_hash": rec["content_hash"],
                          "start_ns": int(sec_t[a]), "end_ns": int(sec_t[b - 1]) + 1_000_000_000,
                          "class": CLASSES[int(sec[a])], "steps": int(steps_per_sec[a:b].sum())})
        accuracy += accuracy_rows(s["session_id"], inp.events, rec, inp.root, path, fs, sec, sec_t, params)
    if not bouts and not daily and all(params["placement"] not in r["sensors"] for r in inp.recordings):
        have = sorted({p for r in inp.recordings for p in r["sensors"]})
        return StageOutput.skipped(f"activity skipped: no {params['placement']} IMU (session has "
                                   f"{', '.join(have) or 'no IMU'})")
    return StageOutput(rows={"activity_bouts": bouts, "activity_transitions": transitions, "activity_daily": daily,
                             "accuracy_metrics": accuracy}, note="; ".join(notes)[:500])


def accuracy_rows(sid: str, events: list[dict], rec: dict, root, path: str, fs: float, sec: np.ndarray,
                  sec_t: np.ndarray, params: dict) -> list[dict]:
    """Window accuracy against the recording's labelled ``activity`` intervals (each annotation is one label run;
    labels outside :data:`estimators.activity.evaluation.SCORED_CLASSES` are not scored), by the one scorer
    :func:`estimators.activity.evaluation.window_confusion` that ``stridelab bench activity`` uses."""
    from estimators.activity.evaluation import SCORED_CLASSES, scores, window_confusion, window_samples
    act = [e for e in events if e.get("type") == "activity" and e.get("end_ns") is not None
           and rec["start_ns"] <= e["t_ns"] <= rec["end_ns"]]
    if not any(e.get("label") in SCORED_CLASSES for e in act):
        return []
    n = series_rows(root, path)
    t_first = int(read_column_range(root, path, ("t_ns",), 0, 1, dtype=np.int64)[0])
    k = (np.asarray(sec_t, np.int64) - t_first) // 1_000_000_000      # seconds from the first sample
    second_class = np.zeros(int(k.max()) + 1 if len(k) else 1, np.int64)
    second_class[k[k >= 0]] = np.asarray(sec)[k >= 0]
    code_to_class = {i: SCORED_CLASSES.index(e["label"]) for i, e in enumerate(act) if e.get("label") in SCORED_CLASSES}
    # sample-level labels a slice at a time (whole windows, about a day): a week is 60 M samples, whose stamps,
    # label codes and second indices held at once took ~1.5 GB
    w = window_samples(fs)
    step = max(1, SCORE_SLICE_SAMPLES // w) * w
    C = 0
    for a in range(0, n, step):
        t_ns = read_column_range(root, path, ("t_ns",), a, min(n, a + step), dtype=np.int64).ravel()
        codes = np.full(len(t_ns), -1, np.int64)
        for i, e in enumerate(act):
            codes[np.searchsorted(t_ns, e["t_ns"]):np.searchsorted(t_ns, e["end_ns"])] = i
        C = C + window_confusion(second_class, codes, fs, code_to_class, first_sample=a)
        del t_ns, codes
    sc = scores(C)
    wm = params.get("window_model", "default")
    est = f"activity:{params['preset']}" + (f"+window_model:{wm}" if wm else "")
    rows = [{"session_id": sid, "stage": "activity", "estimator": est, "placement": params["placement"],
             "metric": m, "value": sc[m], "unit": "fraction"} for m in ("balanced_accuracy", "accuracy")
            if sc[m] is not None]
    rows.append({"session_id": sid, "stage": "activity", "estimator": est, "placement": params["placement"],
                 "metric": "n_windows", "value": float(sc["windows"]), "unit": "windows"})
    return rows


STAGE = Stage(name="activity", version="5", needs=(),
              tables=("activity_bouts", "activity_transitions", "activity_daily", "accuracy_metrics"),
              session_kinds=("free_living",), compute=compute, default_params=default_params)
