"""Clinical joint angles per walking trial, gait-cycle curves and ROM per session:
warehouse (orientation, calibration[, gait_events]) -> stridelab.estimators.joints -> warehouse.

``compute``: every recording of a lab session except the calibration trial is a walking trial. Its sensor
orientations (orientation stage) and the session's calibration rows (calibration stage) go to
:func:`stridelab.estimators.joints.compute_joint_angles` with the quiet standing at the start of the trial
(:func:`stridelab.estimators.calibration.first_quiet_standing`) for the offset removal of thesis ch. 8. The
status of each joint is the worse calibration of its two segments: a failed calibration gives
``fail`` (and NaN angles when no rotation exists), never silently produced angles, and no curves.
Gait-cycle curves need initial contacts: the upstream ``gait_events`` cut the cycles
(:func:`stridelab.pipeline.stages._lab_read.ic_times_by_side`); without them the curves are left empty with a note.
Reference events (the truth) are never used.

``score`` (separate step): when the trial carries optical segment poses (``reference_pose``) for both segments of
a joint, the reference joint angles (same joint coordinate system and standing-offset removal,
:func:`stridelab.estimators.joints.evaluation.reference_angles_deg`) give the session's RMSE per plane (pooled over its
walking trials) in ``accuracy_metrics`` and each trial's range of motion (IMU vs reference) in ``accuracy_pairs``.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from stridelab.pipeline.stages import canonical_json
from stridelab.pipeline.stages._lab_read import (find_calibration_recording, ic_times_by_side, read_recording,
                                                 session_calibration)
from stridelab.pipeline.stages._shape import StageContext, shaped_stage

TABLES = ("joint_angles", "joint_angle_curves", "joint_rom", "accuracy_metrics", "accuracy_pairs")
PLANES = ("sagittal", "frontal", "transverse")
STATUS_ORDER = ["pass", "warn", "fail"]


@dataclass(frozen=True)
class JointAnglesParams:
    """offset_removal: subtract the angles of the quiet standing at the start of each trial (thesis ch. 8).
    max_cycle_s: gait cycles longer than this (s) are left out of the curves."""
    offset_removal: bool = True
    max_cycle_s: float = 2.5


def _key(*parts) -> str:
    return hashlib.sha256(canonical_json(parts).encode()).hexdigest()[:16]


def _opt(x) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def compute(ctx: StageContext, p: JointAnglesParams) -> None:
    from stridelab.estimators.calibration import first_quiet_standing
    from stridelab.estimators.calibration._session import DEFAULT_PLACEMENTS
    from stridelab.estimators.joints import ANGLE_NAMES, JOINTS, compute_joint_angles, pool_cycles, session_gait_curves
    sid, cal_rows = ctx.session_id, ctx.upstream.get("calibration", [])
    have = {pl for r in ctx.recordings for pl, k in r["sensors"].items() if "imu" in k}
    cal = session_calibration(cal_rows)
    if cal is None:
        if not have & (set(DEFAULT_PLACEMENTS) - {"foot_left", "foot_right"}):
            return ctx.skip(f"joint angles skipped: no pelvis/thigh/shank sensors (session has "
                            f"{', '.join(sorted(have)) or 'no IMU'})")
        return ctx.set_note("no calibration rows for this session")
    if not any({prox if prox == "pelvis" else f"{prox}_{side}", f"{dist}_{side}"} <= have
               for prox, dist in JOINTS.values() for side in ("left", "right")):
        return ctx.skip(f"joint angles skipped: no joint has sensors on both its segments (session has "
                        f"{', '.join(sorted(have))})")
    cal_rec = find_calibration_recording(ctx.recordings)
    ics = ic_times_by_side(ctx.upstream)
    cal_key = _key([(r["placement"], r["status"], r["qw"], r["qx"], r["qy"], r["qz"]) for r in
                    sorted(cal_rows, key=lambda r: r["placement"])])
    ori_rows = ctx.upstream.get("orientation", [])
    notes, per_trial_curves, status_of = [], {}, {}
    for rec in ctx.recordings:
        if cal_rec is not None and rec["content_hash"] == cal_rec["content_hash"]:
            continue
        data = read_recording(ctx, rec, ori_rows, DEFAULT_PLACEMENTS)
        fs, t = data["sampling_rate_hz"], data["t_ns"]
        if fs is None or not data["quat"]:
            notes.append(f"{rec['trial']}: no lower-limb orientation")
            continue
        if len(t) < 2:
            notes.append(f"{rec['trial']}: the IMUs do not overlap in time")
            continue
        if data.get("resampled"):
            notes.append(f"{rec['trial']}: IMUs on independent clocks, resampled onto one grid")
        standing = None
        if p.offset_removal:
            standing = first_quiet_standing(data["acc"], data["gyr"], sampling_rate_hz=fs, params=cal.params)
            if standing is None:
                notes.append(f"{rec['trial']}: no quiet standing, standing offsets not removed")
        ja = compute_joint_angles(data["quat"], cal, standing=standing)
        ori_key = _key(sorted(r["series_path"] for r in ori_rows if r["content_hash"] == rec["content_hash"]))
        name = f"joint_angles-{rec['content_hash'][:12]}-{_key(STAGE.version, ctx.params_key, cal_key, ori_key)}"
        for key, a in sorted(ja.angles_deg.items()):
            joint, side = key.rsplit("_", 1)
            rel = ctx.write_series(key, name, pa.table({"t_ns": t, "sagittal_deg": a[:, 0], "frontal_deg": a[:, 1],
                                                        "transverse_deg": a[:, 2]}))
            off = ja.offsets_deg[key] if standing is not None else [None] * 3
            ctx.emit("joint_angles", [{
                "session_id": sid, "content_hash": rec["content_hash"], "trial": rec["trial"], "joint": joint,
                "side": side, "status": ja.status[key], "reasons": json.dumps(list(ja.notes.get(key, ()))),
                "angle_names": json.dumps(list(ANGLE_NAMES[joint])),
                **{f"offset_{pl}_deg": _opt(o) for pl, o in zip(PLANES, off)},
                "standing_start_ns": int(t[standing[0]]) if standing is not None else None,
                "standing_end_ns": int(t[standing[1] - 1]) if standing is not None else None,
                "n_samples": int(len(t)), "series_path": rel}])
            status_of[key] = max(status_of.get(key, "pass"), ja.status[key], key=STATUS_ORDER.index)
        ctx.found.append((rec, t, fs, standing, ja))
        if ics is not None:
            ic_idx = {side: np.searchsorted(t, v[(v >= t[0]) & (v <= t[-1])]) for side, v in ics.items()}
            for key, c in session_gait_curves(ja, ic_idx, sampling_rate_hz=fs, max_cycle_s=p.max_cycle_s).items():
                per_trial_curves.setdefault(key, []).append(c)
    if ics is None:
        notes.append("no gait_events upstream: gait-cycle curves not computed")
    for key, cs in sorted(per_trial_curves.items()):
        joint, side = key.rsplit("_", 1)
        if status_of.get(key) == "fail":
            notes.append(f"{key}: calibration failed, no curves")
            continue
        c = pool_cycles(cs)
        if c.n_cycles == 0:
            continue
        for k, plane in enumerate(PLANES):
            base = {"session_id": sid, "joint": joint, "side": side, "plane": plane,
                    "angle": ANGLE_NAMES[joint][k], "n_cycles": c.n_cycles, "status": status_of[key]}
            ctx.emit("joint_angle_curves", [dict(base, pct=i, mean_deg=float(c.mean[i, k]), sd_deg=_opt(c.sd[i, k]))
                                            for i in range(c.mean.shape[0])])
            ctx.emit("joint_rom", [dict(base, rom_deg=float(c.rom_mean[k]), rom_sd_deg=_opt(c.rom_sd[k]))])
    failed = sorted(k for k, v in status_of.items() if v == "fail")
    if failed:
        notes.insert(0, f"calibration failed for {', '.join(failed)}: angles marked fail")
    ctx.set_note("; ".join(notes))


def score(ctx: StageContext, p: JointAnglesParams) -> None:
    from stridelab.estimators.calibration._session import DEFAULT_PLACEMENTS
    from stridelab.estimators.joints import JOINTS, angle_errors
    from stridelab.estimators.joints.evaluation import pooled_rmse_deg, reference_angles_deg
    ori_rows = ctx.upstream.get("orientation", [])
    estimator = ori_rows[0]["estimator"] if ori_rows else None
    base = {"session_id": ctx.session_id, "stage": "joint_angles", "estimator": estimator}
    errors: dict[str, list] = {}
    for rec, t, fs, standing, ja in ctx.found:
        ref_q = {pl: ctx.reference_orientation(rec, pl, t)
                 for pl in DEFAULT_PLACEMENTS if "reference_pose" in rec["sensors"].get(pl, {})}
        for key, a in sorted(ja.angles_deg.items()):
            joint, side = key.rsplit("_", 1)
            prox, dist = (s_ if s_ == "pelvis" else f"{s_}_{side}" for s_ in JOINTS[joint])
            if prox not in ref_q or dist not in ref_q or ja.status[key] == "fail":
                continue
            ref = reference_angles_deg(ref_q[prox], ref_q[dist], joint=joint, side=side, standing=standing)
            ok = np.all(np.isfinite(ref), axis=1) & np.all(np.isfinite(a), axis=1)
            if ok.sum() < fs:
                continue
            errors.setdefault(key, []).append(ref[ok] - a[ok])
            e = angle_errors(ref[ok], a[ok])
            ctx.emit("accuracy_pairs", [{**base, "placement": key, "quantity": f"{joint}_{plane}_rom",
                                         "estimate": float(e.rom_est_deg[k]), "reference": float(e.rom_ref_deg[k]),
                                         "unit": "deg"} for k, plane in enumerate(PLANES)])
    for key, errs in sorted(errors.items()):
        ctx.emit("accuracy_metrics", [{**base, "placement": key, "metric": f"{plane}_rmse_deg", "value": float(v),
                                       "unit": "deg"} for plane, v in zip(PLANES, pooled_rmse_deg(errs))])


STAGE = shaped_stage("joint_angles", "2", JointAnglesParams, compute, score=score, tables=TABLES,
                     needs=("orientation", "calibration", "gait"), session_kinds=("lab", "calibration"))
