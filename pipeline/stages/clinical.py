"""Clinical gait measures of every lab session: the gait stage's events, strides and foot trajectories ->
estimators.gait.clinical -> warehouse.

A stage of its own after ``gait`` (it reads only the gait stage's outputs): the clinical definitions can change
and be recomputed without rerunning the foot filters. Per walking recording, the step and phase measures of each
stride come from the other foot's events (``clinical_steps``, one row per stride of ``strides``); the session
table ``clinical_measures`` holds both sides, the paretic / non-paretic ratio, the symmetry ratio and the
within-session uncertainty. Step lengths need the two feet in one frame: each foot's trajectory is turned to the
initial walking direction and both start side by side (:func:`estimators.gait.clinical.common_walking_frame`);
a segment whose trajectory does not start in stance gets no step lengths (a note says so). Where the optical
reference of both feet exists, the same step lengths from it are stored and scored (``accuracy_metrics``).

The paretic side comes from the recordings' session metadata (``paretic_side``), else from the study manifest's
participant entry; unknown = no paretic ratios (symmetry ratios still).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from estimators.timebase import contiguous_segments
from pipeline.stages import SessionInput, Stage, StageOutput
from warehouse.store import read_table

SIDES = ("left", "right")
TABLES = ("clinical_steps", "clinical_measures", "accuracy_metrics")
ESTIMATOR = "clinical_v1"


def default_params() -> dict:
    from estimators.gait.clinical import ClinicalParams
    return dataclasses.asdict(ClinicalParams())


def paretic_side(inp: SessionInput) -> tuple[str | None, str]:
    """(side, where it came from) from the session metadata, else the study manifest, else (None, '')."""
    sides = {str(r.get("metadata", {}).get("paretic_side")).lower() for r in inp.recordings
             if r.get("metadata", {}).get("paretic_side")}
    if len(sides) == 1 and sides <= set(SIDES):
        return sides.pop(), "session metadata"
    if len(sides) > 1:
        return None, "recordings disagree on paretic_side"
    from pipeline.config import study_manifest
    for p in study_manifest(inp.session.get("study") or "").get("participants", []):
        if str(p.get("id")) == str(inp.session.get("participant_id")) and p.get("paretic_side") in SIDES:
            return p["paretic_side"], "study manifest"
    return None, ""


def _s(ns, t0: int) -> np.ndarray:
    return (np.asarray([np.nan if v is None else v for v in ns], float) - t0) / 1e9


def _lookup(t_ns: np.ndarray, xy: np.ndarray, q_ns) -> np.ndarray:
    """Positions at the samples ``q_ns`` (exact sample times of events, nearest sample otherwise)."""
    q = np.asarray(q_ns, np.int64)
    if not len(t_ns) or not len(q):
        return np.full((len(q), 2), np.nan)
    i = np.clip(np.searchsorted(t_ns, q), 0, len(t_ns) - 1)
    return xy[i]


def _aligned_xy(t_ns, xy, stance, strides: list[dict], max_turn_deg: float, min_stance_s: float = 0.3):
    """One foot's trajectory in the walking frame: (N, 2) positions per contiguous segment, up to the first
    turning stride; NaN elsewhere and in segments that do not start standing or have no straight stride; notes."""
    from estimators.gait.clinical import common_walking_frame
    out = np.full_like(xy, np.nan)
    notes = []
    fs = 1e9 / float(np.median(np.diff(t_ns))) if len(t_ns) > 1 else 100.0
    for a, b in contiguous_segments(t_ns):
        seg = sorted((r for r in strides if t_ns[a] <= r["start_ns"] <= t_ns[b - 1]), key=lambda r: r["start_ns"])
        if not seg:
            continue
        if not stance[a:a + max(1, int(min_stance_s * fs))].all():
            notes.append("trajectory does not start standing: no step lengths for that stretch")
            continue
        turn = [r["turning_deg"] or 0.0 for r in seg]
        M = common_walking_frame(_lookup(t_ns, xy, [r["start_ns"] for r in seg]),
                                 _lookup(t_ns, xy, [r["end_ns"] for r in seg]), turn, max_turn_deg=max_turn_deg)
        if M is None:
            notes.append("no straight stride to find the walking direction: no step lengths for that stretch")
            continue
        first_turn = next((r["start_ns"] for r, d in zip(seg, turn) if abs(d) > max_turn_deg), None)
        stop = b if first_turn is None else int(np.searchsorted(t_ns, first_turn, side="right"))
        out[a:stop] = (xy[a:stop] - xy[a]) @ M.T
    return out, notes


def _ref_xy(inp: SessionInput, rec: dict, placement: str):
    ref = rec["sensors"].get(placement, {}).get("reference_pose")
    if ref is None:
        return None
    t = read_table(inp.root, ref["series_path"], columns=["t_ns", "px", "py"])
    return t.column("t_ns").to_numpy(), np.column_stack([t.column("px").to_numpy(), t.column("py").to_numpy()])


def _foot_inputs(strides: list[dict], events: list[dict], xy_at, t0: int):
    """(FootStrides, FootEvents) of one foot of one recording; ``xy_at(ns list) -> (n, 2)``."""
    from estimators.gait.clinical import FootEvents, FootStrides
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


def _concat(parts: list):
    from estimators.gait.clinical import StepPhases
    if not parts:
        z = np.zeros(0)
        return StepPhases(*([z] * 12), used=np.zeros(0, bool), reason=np.zeros(0, str))
    return StepPhases(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                         for f in dataclasses.fields(StepPhases)})


def _num(x):
    x = float(x)
    return x if np.isfinite(x) else None


def compute(inp: SessionInput, params: dict) -> StageOutput:
    from estimators.gait.clinical import ClinicalParams, clinical_summary, equal_stride_scale, step_phases
    from estimators.gait.evaluation import paired_errors
    cp = ClinicalParams(**params)
    sid = inp.session["session_id"]
    up = inp.upstream
    if not up.get("strides"):
        return StageOutput.skipped("clinical skipped: the gait stage found no strides in this session")
    side_p, source = paretic_side(inp)
    notes: list[str] = [] if side_p or not source else [source]
    rows, phases = [], {s: [] for s in SIDES}
    ref_pairs = []
    recs = {r["content_hash"]: r for r in inp.recordings}
    for h in sorted({r["content_hash"] for r in up.get("strides", [])}):
        rec = recs.get(h)
        if rec is None:
            continue
        t0 = int(rec["start_ns"] or 0)
        xy_at, ref_at, scale = {}, {}, {}
        k = {"left": 1.0, "right": 1.0}                      # equal_stride_scale, filled once both feet are read
        for side in SIDES:
            tr = [r for r in up.get("foot_trajectories", []) if r["content_hash"] == h and r["side"] == side]
            sd = [r for r in up["strides"] if r["content_hash"] == h and r["side"] == side]
            if tr:
                t = read_table(inp.root, tr[0]["series_path"], columns=["t_ns", "px", "py", "stance"])
                t_ns = t.column("t_ns").to_numpy()
                xy = np.column_stack([t.column("px").to_numpy(), t.column("py").to_numpy()])
                axy, n = _aligned_xy(t_ns, xy, t.column("stance").to_numpy(zero_copy_only=False), sd,
                                     cp.max_turn_deg)
                notes += [f"{rec['trial']} foot_{side}: {x}" for x in n]
                # steady straight strides: a previous IC, not a turn, not the first stride (gait initiation)
                # steady strides of the stretch whose steps are measured: a previous IC, before the first turn,
                # not the first stride (gait initiation)
                steady = sorted(sd, key=lambda r: r["ic_ns"])
                stop = next((i for i, r in enumerate(steady) if abs(r["turning_deg"] or 0.0) > cp.max_turn_deg),
                            len(steady))
                scale[side] = [r["stride_length_m"] for r in steady[1:stop]
                               if r["stride_length_m"] is not None and r["pre_ic_ns"] is not None]
                xy_at[side] = (lambda q, t_ns=t_ns, axy=axy, side=side: _lookup(t_ns, axy, q) * k[side])
            else:
                xy_at[side] = lambda q: np.full((len(q), 2), np.nan)
            ref = _ref_xy(inp, rec, f"foot_{side}")
            if ref is not None:
                ref_at[side] = (lambda q, ref=ref: _lookup(ref[0], ref[1], q))
        if len(scale) == 2:
            for side, other in (("left", "right"), ("right", "left")):
                k[side] = equal_stride_scale(scale[side], scale[other])
        feet = {}
        for side in SIDES:
            sd = [r for r in up["strides"] if r["content_hash"] == h and r["side"] == side]
            ev = [e for e in up.get("gait_events", []) if e["content_hash"] == h and e["side"] == side]
            feet[side] = _foot_inputs(sd, ev, xy_at[side], t0)
            if len(ref_at) == 2:
                feet[side] = feet[side] + (_foot_inputs(sd, ev, ref_at[side], t0),)
        for side, other in (("left", "right"), ("right", "left")):
            sd, st, _ = feet[side][:3]
            ph = step_phases(st, feet[other][2], params=cp)
            ref_len = (step_phases(feet[side][3][1], feet[other][3][2], params=cp).step_length_m
                       if len(ref_at) == 2 else np.full(len(ph), np.nan))
            phases[side].append(ph)
            ns = lambda x: None if not np.isfinite(x) else int(round(x * 1e9)) + t0     # noqa: E731
            for k, r in enumerate(sd):
                rows.append({"session_id": sid, "content_hash": h, "trial": r["trial"], "side": side,
                             "paretic": None if side_p is None else side == side_p,
                             "pre_ic_ns": r["pre_ic_ns"], "tc_ns": r["tc_ns"], "ic_ns": r["ic_ns"],
                             "contra_ic_ns": ns(ph.contra_ic_s[k]), "contra_tc_ns": ns(ph.contra_tc_s[k]),
                             **{c: _num(getattr(ph, c)[k]) for c in (
                                 "stride_time_s", "stance_time_s", "swing_time_s", "step_time_s", "step_length_m",
                                 "single_support_s", "ds_initial_s", "ds_terminal_s", "double_support_pct",
                                 "stride_length_m")},
                             "step_length_ref_m": _num(ref_len[k]), "turning_deg": r["turning_deg"],
                             "used": bool(ph.used[k]), "reason": str(ph.reason[k])})
                if ph.used[k] and np.isfinite(ph.step_length_m[k]) and np.isfinite(ref_len[k]):
                    ref_pairs.append((side, ph.step_length_m[k], ref_len[k]))
    summ = clinical_summary(_concat(phases["left"]), _concat(phases["right"]), paretic_side=side_p, params=cp)
    note = "; ".join(dict.fromkeys(notes + list(summ.notes))) or None
    measures = []
    for name, m in summ.measures.items():
        measures.append({"session_id": sid, "measure": name, "unit": m.unit, "value": _num(m.value),
                         "left_value": _num(m.left), "right_value": _num(m.right), "sd_left": _num(m.sd_left),
                         "sd_right": _num(m.sd_right), "n_left": m.n_left, "n_right": m.n_right,
                         "cv_left_pct": _num(m.cv_left_pct), "cv_right_pct": _num(m.cv_right_pct),
                         "paretic_side": side_p, "paretic_value": _num(m.paretic),
                         "non_paretic_value": _num(m.non_paretic), "paretic_ratio": _num(m.paretic_ratio),
                         "symmetry_ratio": _num(m.symmetry_ratio), "sem": _num(m.sem), "mdc95": _num(m.mdc95),
                         "sem_symmetry_ratio": _num(m.sem_symmetry_ratio),
                         "mdc95_symmetry_ratio": _num(m.mdc95_symmetry_ratio), "flag": m.flag, "note": note})
    acc = []
    for placement, sel in (("foot_left", ("left",)), ("foot_right", ("right",)), ("both", SIDES)):
        p = [(a, b) for s, a, b in ref_pairs if s in sel]
        if p:
            e = paired_errors([a for a, _ in p], [b for _, b in p])
            acc += [{"session_id": sid, "stage": "steps", "estimator": ESTIMATOR, "placement": placement,
                     "metric": f"step_length_{k}_m", "value": _num(e[k]), "unit": "m"}
                    for k in ("mae", "mean", "rmse") if _num(e[k]) is not None]
    status = "ok" if rows else "no_strides"
    return StageOutput(rows={"clinical_steps": rows, "clinical_measures": measures if rows else [],
                             "accuracy_metrics": acc},
                       note=f"clinical {status}" + (f" (paretic side: {side_p}, {source})" if side_p else ""))


STAGE = Stage(name="clinical", version="1", needs=("gait",), tables=TABLES, session_kinds=("lab",), compute=compute,
              default_params=default_params)
