"""Clinical joint angles per walking trial, gait-cycle curves and ROM per session:
warehouse (orientation, calibration[, gait_events]) -> estimators.joints -> warehouse.

Every recording of a lab session except the calibration trial is a walking trial. Its sensor
orientations (orientation stage) and the session's calibration rows (calibration stage) go to
:func:`estimators.joints.compute_joint_angles` with the quiet standing at the start of the trial
(:func:`estimators.calibration.first_quiet_standing`) for the offset removal of thesis ch. 8. The
status of each joint is the worse calibration of its two segments: a failed calibration gives
``fail`` (and NaN angles when no rotation exists), never silently produced angles, and no curves.

Accuracy: when the trial carries optical segment poses (``reference_pose``) for both segments of a joint,
the reference joint angles are computed from them with the same joint coordinate system and standing-offset
removal, and the session's RMSE per plane (pooled over its walking trials) goes to ``accuracy_metrics`` and
each trial's range of motion (IMU vs reference) to ``accuracy_pairs`` (dashboard Bland–Altman).

Gait-cycle curves need initial contacts: when an upstream ``gait_events`` table exists (rows with
``side`` or a ``foot_<side>`` placement and either ``type`` = IC and ``t_ns``, or ``ic_ns``), its
contacts cut the cycles; otherwise the curves are left empty with a note. Reference events (the
truth) are never used.
"""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pyarrow as pa

from pipeline.stages import SessionInput, Stage, StageOutput, canonical_json, params_hash
from pipeline.stages.calibration import find_calibration_recording, read_recording
from warehouse.read import reference_orientation_on
from warehouse.store import series_relpath, write_table

PLANES = ("sagittal", "frontal", "transverse")
IC_TYPES = {"ic", "initial_contact"}


def default_params() -> dict:
    return {"offset_removal": True, "max_cycle_s": 2.5}


def session_calibration(rows: list[dict]):
    """:class:`SessionCalibration` rebuilt from the calibration stage's rows (None when there are none)."""
    from estimators.calibration import CalibrationParams, CalibrationWindows, ImuCalibration, SessionCalibration
    from estimators.quaternion import quat_to_matrix
    if not rows:
        return None
    imus = {}
    for r in rows:
        q = [r[f"q{k}"] for k in "wxyz"]
        R = quat_to_matrix(np.asarray(q, float)) if all(v is not None for v in q) else np.full((3, 3), np.nan)
        imus[r["placement"]] = ImuCalibration(r["placement"], R, r["method"] or "none", r["status"],
                                              tuple(json.loads(r["reasons"] or "[]")), n_cycles=int(r["n_reps"] or 0))
    p = json.loads(rows[0]["params"] or "{}")
    fields = CalibrationParams.__dataclass_fields__
    cp = CalibrationParams(**{k: v for k, v in p.items() if k in fields})
    return SessionCalibration(imus=imus, windows=CalibrationWindows(), status=rows[0]["session_status"],
                              reasons=tuple(json.loads(rows[0]["session_reasons"] or "[]")), params=cp)


def ic_times_by_side(upstream: dict) -> dict[str, np.ndarray] | None:
    """Initial contacts (int64 ns) per side from an upstream ``gait_events`` table, or None if absent."""
    rows = upstream.get("gait_events")
    if rows is None:
        return None
    out: dict[str, list[int]] = {"left": [], "right": []}
    for r in rows:
        side = r.get("side") or (r.get("placement") or r.get("foot") or "").removeprefix("foot_")
        if side not in out:
            continue
        if r.get("ic_ns") is not None:
            out[side].append(int(r["ic_ns"]))
        elif str(r.get("type", "")).lower() in IC_TYPES and r.get("t_ns") is not None:
            out[side].append(int(r["t_ns"]))
    return {s: np.unique(np.asarray(v, np.int64)) for s, v in out.items()}


def _key(*parts) -> str:
    return hashlib.sha256(canonical_json(parts).encode()).hexdigest()[:16]


def compute(inp: SessionInput, params: dict) -> StageOutput:
    from estimators.calibration import first_quiet_standing
    from estimators.calibration._session import DEFAULT_PLACEMENTS
    from estimators.joints import (ANGLE_NAMES, JOINTS, angle_errors, compute_joint_angles, joint_angles_deg,
                                   pool_cycles, session_gait_curves)
    s = inp.session
    sid = s["session_id"]
    cal_rows = inp.upstream.get("calibration", [])
    cal = session_calibration(cal_rows)
    if cal is None:
        have = sorted({p for r in inp.recordings for p, k in r["sensors"].items() if "imu" in k})
        if not set(have) & (set(DEFAULT_PLACEMENTS) - {"foot_left", "foot_right"}):
            return StageOutput.skipped(f"joint angles skipped: no pelvis/thigh/shank sensors (session has "
                                       f"{', '.join(have) or 'no IMU'})")
        return StageOutput(note="no calibration rows for this session")
    have = {p for r in inp.recordings for p, k in r["sensors"].items() if "imu" in k}
    if not any({prox if prox == "pelvis" else f"{prox}_{side}", f"{dist}_{side}"} <= have
               for prox, dist in JOINTS.values() for side in ("left", "right")):
        return StageOutput.skipped(f"joint angles skipped: no joint has sensors on both its segments (session has "
                                   f"{', '.join(sorted(have))})")
    cal_rec = find_calibration_recording(inp.recordings)
    trials = [r for r in inp.recordings if cal_rec is None or r["content_hash"] != cal_rec["content_hash"]]
    ics = ic_times_by_side(inp.upstream)
    cal_key = _key([(r["placement"], r["status"], r["qw"], r["qx"], r["qy"], r["qz"]) for r in
                    sorted(cal_rows, key=lambda r: r["placement"])])
    ori_rows = inp.upstream.get("orientation", [])
    rows, notes = [], []
    per_trial_curves: dict[str, list] = {}
    status_of: dict[str, str] = {}
    errors: dict[str, list] = {}
    pairs: list[dict] = []
    estimator = ori_rows[0]["estimator"] if ori_rows else None
    for rec in trials:
        data = read_recording(inp, rec, ori_rows, DEFAULT_PLACEMENTS)
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
        if params["offset_removal"]:
            standing = first_quiet_standing(data["acc"], data["gyr"], sampling_rate_hz=fs, params=cal.params)
            if standing is None:
                notes.append(f"{rec['trial']}: no quiet standing, standing offsets not removed")
        ja = compute_joint_angles(data["quat"], cal, standing=standing)
        ori_key = _key(sorted(r["series_path"] for r in ori_rows if r["content_hash"] == rec["content_hash"]))
        for key, a in sorted(ja.angles_deg.items()):
            joint, side = key.rsplit("_", 1)
            name = f"joint_angles-{rec['content_hash'][:12]}-{_key(STAGE.version, params_hash(params), cal_key, ori_key)}"
            rel = series_relpath(s["study"], s["participant_id"], sid, key, name)
            write_table(inp.root, rel, pa.table({"t_ns": t, "sagittal_deg": a[:, 0], "frontal_deg": a[:, 1],
                                                 "transverse_deg": a[:, 2]}))
            off = ja.offsets_deg[key] if standing is not None else [None] * 3
            rows.append({"session_id": sid, "content_hash": rec["content_hash"], "trial": rec["trial"],
                         "joint": joint, "side": side, "status": ja.status[key],
                         "reasons": json.dumps(list(ja.notes.get(key, ()))),
                         "angle_names": json.dumps(list(ANGLE_NAMES[joint])),
                         **{f"offset_{pl}_deg": (None if o is None or not np.isfinite(o) else float(o))
                            for pl, o in zip(PLANES, off)},
                         "standing_start_ns": int(t[standing[0]]) if standing is not None else None,
                         "standing_end_ns": int(t[standing[1] - 1]) if standing is not None else None,
                         "n_samples": int(len(t)), "series_path": rel})
            status_of[key] = max(status_of.get(key, "pass"), ja.status[key], key=["pass", "warn", "fail"].index)
        ref_q = {p: reference_orientation_on(inp.root, rec["sensors"][p]["reference_pose"]["series_path"], t)
                 for p in DEFAULT_PLACEMENTS if "reference_pose" in rec["sensors"].get(p, {})}
        for key, a in sorted(ja.angles_deg.items()):
            joint, side = key.rsplit("_", 1)
            prox, dist = (s_ if s_ == "pelvis" else f"{s_}_{side}" for s_ in JOINTS[joint])
            if prox not in ref_q or dist not in ref_q or ja.status[key] == "fail":
                continue
            ref = joint_angles_deg(ref_q[prox], ref_q[dist], joint=joint, side=side)
            if standing is not None:
                ref = ref - np.nanmean(ref[standing[0]:standing[1]], axis=0)
            ok = np.all(np.isfinite(ref), axis=1) & np.all(np.isfinite(a), axis=1)
            if ok.sum() < fs:
                continue
            errors.setdefault(key, []).append(ref[ok] - a[ok])
            e = angle_errors(ref[ok], a[ok])
            for k, plane in enumerate(PLANES):
                pairs.append({"session_id": sid, "stage": "joint_angles", "estimator": estimator, "placement": key,
                              "quantity": f"{joint}_{plane}_rom", "estimate": float(e.rom_est_deg[k]),
                              "reference": float(e.rom_ref_deg[k]), "unit": "deg"})
        if ics is not None:
            ic_idx = {side: np.searchsorted(t, v[(v >= t[0]) & (v <= t[-1])]) for side, v in ics.items()}
            for key, c in session_gait_curves(ja, ic_idx, sampling_rate_hz=fs,
                                              max_cycle_s=params["max_cycle_s"]).items():
                per_trial_curves.setdefault(key, []).append(c)
    curve_rows, rom_rows = [], []
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
            curve_rows += [dict(base, pct=i, mean_deg=float(c.mean[i, k]),
                                sd_deg=float(c.sd[i, k]) if np.isfinite(c.sd[i, k]) else None)
                           for i in range(c.mean.shape[0])]
            rom_rows.append(dict(base, rom_deg=float(c.rom_mean[k]),
                                 rom_sd_deg=float(c.rom_sd[k]) if np.isfinite(c.rom_sd[k]) else None))
    metrics = []
    for key, errs in sorted(errors.items()):
        err = np.concatenate(errs)
        for k, plane in enumerate(PLANES):
            metrics.append({"session_id": sid, "stage": "joint_angles", "estimator": estimator, "placement": key,
                            "metric": f"{plane}_rmse_deg", "value": float(np.sqrt(np.mean(err[:, k] ** 2))),
                            "unit": "deg"})
    failed = sorted(k for k, v in status_of.items() if v == "fail")
    if failed:
        notes.insert(0, f"calibration failed for {', '.join(failed)}: angles marked fail")
    return StageOutput(rows={"joint_angles": rows, "joint_angle_curves": curve_rows, "joint_rom": rom_rows,
                             "accuracy_metrics": metrics, "accuracy_pairs": pairs},
                       note="; ".join(notes))


STAGE = Stage(name="joint_angles", version="2", needs=("orientation", "calibration", "gait"),
              tables=("joint_angles", "joint_angle_curves", "joint_rom", "accuracy_metrics", "accuracy_pairs"),
              session_kinds=("lab", "calibration"), compute=compute, default_params=default_params)
