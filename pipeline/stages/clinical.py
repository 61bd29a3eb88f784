"""Clinical gait measures of every lab session: the gait stage's events, strides and foot trajectories ->
stridelab.estimators.gait.clinical -> warehouse.

A stage of its own after ``gait`` (it reads only the gait stage's outputs): the clinical definitions can change
and be recomputed without rerunning the foot filters. ``compute``: per walking recording, the step and phase
measures of each stride come from the other foot's events (``clinical_steps``, one row per stride of ``strides``);
the session table ``clinical_measures`` holds both sides, the paretic / non-paretic ratio, the symmetry ratio and
the within-session uncertainty. Step lengths need the two feet in one frame: each foot's trajectory is turned to
the initial walking direction and both start side by side (:func:`stridelab.estimators.gait.clinical.walking_frame_xy`).
``score`` (separate step): where the optical reference of both feet exists, the same step lengths from it are
stored (``step_length_ref_m``) and scored (``accuracy_metrics``, :func:`stridelab.estimators.gait.evaluation.paired_errors`).

The paretic side comes from the recordings' session metadata (``paretic_side``), else from the study manifest's
participant entry; unknown = no paretic ratios (symmetry ratios still).
"""
from __future__ import annotations

import numpy as np

from stridelab.estimators.gait.clinical import ClinicalParams   # the stage's parameters are the estimator's (units in names)
from stridelab.pipeline.stages._clinical_inputs import SIDES, concat_phases, foot_inputs, foot_xy, paretic_side
from stridelab.pipeline.stages._shape import StageContext, shaped_stage

TABLES = ("clinical_steps", "clinical_measures", "accuracy_metrics")
ESTIMATOR = "clinical_v1"
PHASE_COLUMNS = ("stride_time_s", "stance_time_s", "swing_time_s", "step_time_s", "step_length_m", "single_support_s",
                 "ds_initial_s", "ds_terminal_s", "double_support_pct", "stride_length_m")


def _num(x):
    x = float(x)
    return x if np.isfinite(x) else None


def compute(ctx: StageContext, cp: ClinicalParams) -> None:
    from stridelab.estimators.gait.clinical import clinical_summary, equal_stride_scale, step_phases
    sid, up = ctx.session_id, ctx.upstream
    if not up.get("strides"):
        return ctx.skip("clinical skipped: the gait stage found no strides in this session")
    side_p, source = paretic_side(ctx)
    notes: list[str] = [] if side_p or not source else [source]
    phases = {s: [] for s in SIDES}
    recs = {r["content_hash"]: r for r in ctx.recordings}
    for h in sorted({r["content_hash"] for r in up.get("strides", [])}):
        rec = recs.get(h)
        if rec is None:
            continue
        t0 = int(rec["start_ns"] or 0)
        k = {"left": 1.0, "right": 1.0}                      # equal_stride_scale, filled once both feet are read
        sd = {side: [r for r in up["strides"] if r["content_hash"] == h and r["side"] == side] for side in SIDES}
        ev = {side: [e for e in up.get("gait_events", []) if e["content_hash"] == h and e["side"] == side]
              for side in SIDES}
        xy_at, scale = {}, {}
        for side in SIDES:
            xy_at[side], lengths = foot_xy(ctx, rec, side, sd[side], cp, k, notes)
            if lengths is not None:
                scale[side] = lengths
        if len(scale) == 2:
            for side, other in (("left", "right"), ("right", "left")):
                k[side] = equal_stride_scale(scale[side], scale[other])
        feet = {side: foot_inputs(sd[side], ev[side], xy_at[side], t0) for side in SIDES}
        for side, other in (("left", "right"), ("right", "left")):
            rows_sd, st, _ = feet[side]
            ph = step_phases(st, feet[other][2], params=cp)
            phases[side].append(ph)
            ns = lambda x: None if not np.isfinite(x) else int(round(x * 1e9)) + t0     # noqa: E731
            rows = [{"session_id": sid, "content_hash": h, "trial": r["trial"], "side": side,
                     "paretic": None if side_p is None else side == side_p,
                     "pre_ic_ns": r["pre_ic_ns"], "tc_ns": r["tc_ns"], "ic_ns": r["ic_ns"],
                     "contra_ic_ns": ns(ph.contra_ic_s[i]), "contra_tc_ns": ns(ph.contra_tc_s[i]),
                     **{c: _num(getattr(ph, c)[i]) for c in PHASE_COLUMNS},
                     "step_length_ref_m": None, "turning_deg": r["turning_deg"],
                     "used": bool(ph.used[i]), "reason": str(ph.reason[i])} for i, r in enumerate(rows_sd)]
            ctx.emit("clinical_steps", rows)
            ctx.found.append((rec, side, t0, sd, ev, ph, rows))
    summ = clinical_summary(concat_phases(phases["left"]), concat_phases(phases["right"]), paretic_side=side_p, params=cp)
    note = "; ".join(dict.fromkeys(notes + list(summ.notes))) or None
    if ctx.rows.get("clinical_steps"):
        ctx.emit("clinical_measures", [{
            "session_id": sid, "measure": name, "unit": m.unit, "value": _num(m.value), "left_value": _num(m.left),
            "right_value": _num(m.right), "sd_left": _num(m.sd_left), "sd_right": _num(m.sd_right),
            "n_left": m.n_left, "n_right": m.n_right, "cv_left_pct": _num(m.cv_left_pct),
            "cv_right_pct": _num(m.cv_right_pct), "paretic_side": side_p, "paretic_value": _num(m.paretic),
            "non_paretic_value": _num(m.non_paretic), "paretic_ratio": _num(m.paretic_ratio),
            "symmetry_ratio": _num(m.symmetry_ratio), "sem": _num(m.sem), "mdc95": _num(m.mdc95),
            "sem_symmetry_ratio": _num(m.sem_symmetry_ratio), "mdc95_symmetry_ratio": _num(m.mdc95_symmetry_ratio),
            "flag": m.flag, "note": note} for name, m in summ.measures.items()])
    status = "ok" if ctx.rows.get("clinical_steps") else "no_strides"
    ctx.set_note(f"clinical {status}" + (f" (paretic side: {side_p}, {source})" if side_p else ""))


def score(ctx: StageContext, cp: ClinicalParams) -> None:
    """Step lengths from the optical positions of both feet (same definitions, C6) beside the IMU ones."""
    from stridelab.estimators.gait.clinical import positions_at, step_phases
    from stridelab.estimators.gait.evaluation import paired_errors
    pairs, refs = [], {}
    for rec, side, t0, sd, ev, ph, rows in ctx.found:
        if rec["content_hash"] not in refs:
            ref = {s: ctx.reference_pose(rec, f"foot_{s}", ("px", "py")) for s in SIDES}
            refs[rec["content_hash"]] = None if any(v is None for v in ref.values()) else {
                s: foot_inputs(sd[s], ev[s], lambda q, r=r: positions_at(r[0], r[1], q), t0) for s, r in ref.items()}
        feet = refs[rec["content_hash"]]
        if feet is None:
            continue
        other = "right" if side == "left" else "left"
        ref_len = step_phases(feet[side][1], feet[other][2], params=cp).step_length_m
        for i, r in enumerate(rows):
            r["step_length_ref_m"] = _num(ref_len[i])
            if ph.used[i] and np.isfinite(ph.step_length_m[i]) and np.isfinite(ref_len[i]):
                pairs.append((side, ph.step_length_m[i], ref_len[i]))
    for placement, sel in (("foot_left", ("left",)), ("foot_right", ("right",)), ("both", SIDES)):
        p = [(a, b) for s, a, b in pairs if s in sel]
        if p:
            e = paired_errors([a for a, _ in p], [b for _, b in p])
            ctx.emit("accuracy_metrics", [{"session_id": ctx.session_id, "stage": "steps", "estimator": ESTIMATOR,
                                           "placement": placement, "metric": f"step_length_{k}_m", "value": _num(e[k]),
                                           "unit": "m"} for k in ("mae", "mean", "rmse") if _num(e[k]) is not None])


STAGE = shaped_stage("clinical", "1", ClinicalParams, compute, score=score, tables=TABLES, needs=("gait",),
                     session_kinds=("lab",))
