"""Inputs of the clinical stage (:mod:`stridelab.pipeline.stages.clinical`) from the gait stage's rows and series: each
foot's strides and events as the estimator's :class:`FootStrides` / :class:`FootEvents`, its trajectory in the
walking frame, and the paretic side."""
from __future__ import annotations

import dataclasses

import numpy as np

from stridelab.pipeline.stages._context import StageContext

SIDES = ("left", "right")


def paretic_side(ctx: StageContext) -> tuple[str | None, str]:
    """(side, where it came from) from the session metadata, else the study manifest, else (None, '')."""
    sides = {str(r.get("metadata", {}).get("paretic_side")).lower() for r in ctx.recordings
             if r.get("metadata", {}).get("paretic_side")}
    if len(sides) == 1 and sides <= set(SIDES):
        return sides.pop(), "session metadata"
    if len(sides) > 1:
        return None, "recordings disagree on paretic_side"
    from stridelab.pipeline.config import study_manifest
    for p in study_manifest(ctx.session.get("study") or "").get("participants", []):
        if str(p.get("id")) == str(ctx.session.get("participant_id")) and p.get("paretic_side") in SIDES:
            return p["paretic_side"], "study manifest"
    return None, ""


def _s(ns, t0: int) -> np.ndarray:
    return (np.asarray([np.nan if v is None else v for v in ns], float) - t0) / 1e9


def foot_inputs(strides: list[dict], events: list[dict], xy_at, t0: int):
    """(strides sorted by IC, FootStrides, FootEvents) of one foot of one recording; ``xy_at(ns list) -> (n, 2)``."""
    from stridelab.estimators.gait.clinical import FootEvents, FootStrides
    strides = sorted(strides, key=lambda r: r["ic_ns"])
    mids = sorted({r["start_ns"] for r in strides} | {r["end_ns"] for r in strides})
    st = FootStrides(pre_ic_s=_s([r["pre_ic_ns"] for r in strides], t0), tc_s=_s([r["tc_ns"] for r in strides], t0),
                     ic_s=_s([r["ic_ns"] for r in strides], t0),
                     stride_length_m=np.array([np.nan if r["stride_length_m"] is None else r["stride_length_m"]
                                               for r in strides], float),
                     turning_deg=np.array([r["turning_deg"] or 0.0 for r in strides], float),
                     start_xy=xy_at([r["start_ns"] for r in strides]), end_xy=xy_at([r["end_ns"] for r in strides]))
    ev = FootEvents(ic_s=np.sort(_s([e["t_ns"] for e in events if e["type"] == "IC"], t0)),
                    tc_s=np.sort(_s([e["t_ns"] for e in events if e["type"] == "TC"], t0)),
                    mid_s=_s(mids, t0), mid_xy=xy_at(mids))
    return strides, st, ev


def concat_phases(parts: list):
    from stridelab.estimators.gait.clinical import StepPhases
    if not parts:
        z = np.zeros(0)
        return StepPhases(*([z] * 12), used=np.zeros(0, bool), reason=np.zeros(0, str))
    return StepPhases(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                         for f in dataclasses.fields(StepPhases)})


def foot_xy(ctx: StageContext, rec: dict, side: str, sd: list[dict], cp, k: dict, notes: list):
    """``xy_at`` of one foot (its trajectory in the walking frame, scaled by ``k[side]`` when called) and the
    lengths of its steady straight strides (:func:`equal_stride_scale`), or (NaN lookup, None) without one."""
    from stridelab.estimators.gait.clinical import positions_at, straight_stride_lengths, walking_frame_xy
    tr = [r for r in ctx.upstream.get("foot_trajectories", []) if r["content_hash"] == rec["content_hash"]
          and r["side"] == side]
    if not tr:
        return (lambda q: np.full((len(q), 2), np.nan)), None
    t = ctx.read_table(tr[0]["series_path"], ["t_ns", "px", "py", "stance"])
    t_ns = t.column("t_ns").to_numpy()
    xy = np.column_stack([t.column("px").to_numpy(), t.column("py").to_numpy()])
    axy, n = walking_frame_xy(t_ns, xy, t.column("stance").to_numpy(zero_copy_only=False),
                              [r["start_ns"] for r in sd], [r["end_ns"] for r in sd],
                              [r["turning_deg"] or 0.0 for r in sd], max_turn_deg=cp.max_turn_deg)
    notes += [f"{rec['trial']} foot_{side}: {x}" for x in n]
    lengths = straight_stride_lengths(np.array([r["ic_ns"] for r in sd], np.int64),
                                      [np.nan if r["stride_length_m"] is None else r["stride_length_m"] for r in sd],
                                      [r["turning_deg"] or 0.0 for r in sd], [r["pre_ic_ns"] is not None for r in sd],
                                      max_turn_deg=cp.max_turn_deg)
    return (lambda q: positions_at(t_ns, axy, q) * k[side]), lengths
