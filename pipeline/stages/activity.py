"""Daily activity for every free-living chest recording: warehouse -> estimators.activity -> warehouse."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from estimators.activity import CLASSES, PRESETS, TRANSITIONS, classify_day, daily_summaries
from pipeline.stages import SessionInput, Stage, StageOutput
from warehouse.read import read_imu_files


def default_params() -> dict:
    return {"preset": "default", "placement": "chest"}


def _runs(classes: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index ranges of constant class."""
    if classes.size == 0:
        return []
    cut = np.flatnonzero(np.diff(classes)) + 1
    edges = np.concatenate([[0], cut, [classes.size]])
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def compute(inp: SessionInput, params: dict) -> StageOutput:
    if params["preset"] not in PRESETS:
        raise ValueError(f"unknown activity preset '{params['preset']}'; choose one of {', '.join(PRESETS)}")
    s = inp.session
    tz = s.get("timezone") or "UTC"
    bouts, transitions, daily, notes = [], [], [], []
    for rec in inp.recordings:
        imu = rec["sensors"].get(params["placement"], {}).get("imu")
        if imu is None:
            notes.append(f"{rec.get('trial')}: no {params['placement']} IMU")
            continue
        data = read_imu_files(inp.root, imu["series_path"], None, imu["sampling_rate_hz"])
        p = PRESETS[params["preset"]]
        thigh = rec.get("metadata", {}).get("thigh_length_m")
        if thigh:
            p = replace(p, thigh_length_m=float(thigh))
        res = classify_day(data.acc, sampling_rate_hz=data.sampling_rate_hz, t0_ns=int(data.t_ns[0]), timezone=tz,
                           params=p)
        sec = res.second_class
        step_sec = np.floor(res.step_times_s).astype(np.int64)
        steps_per_sec = np.bincount(step_sec[(step_sec >= 0) & (step_sec < sec.size)], minlength=sec.size)
        for a, b in _runs(sec):
            bouts.append({"session_id": s["session_id"], "content_hash": rec["content_hash"],
                          "start_ns": int(res.second_t_ns[a]), "end_ns": int(res.second_t_ns[b - 1]) + 1_000_000_000,
                          "class": CLASSES[int(sec[a])], "steps": int(steps_per_sec[a:b].sum())})
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
    return StageOutput(rows={"activity_bouts": bouts, "activity_transitions": transitions, "activity_daily": daily},
                       note="; ".join(notes)[:500])


STAGE = Stage(name="activity", version="3", needs=(), tables=("activity_bouts", "activity_transitions", "activity_daily"),
              session_kinds=("free_living",), compute=compute, default_params=default_params)
