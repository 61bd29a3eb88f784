"""Sensor-to-segment calibration per lab session: warehouse -> stridelab.estimators.calibration -> warehouse.

``compute``: the session's calibration trial (recording whose trial is ``calibration``) is read with the sensor
orientations of the orientation stage (:func:`stridelab.pipeline.stages._lab_read.read_recording`);
:func:`stridelab.estimators.calibration.calibrate_session` finds the windows (or takes them from the study manifest,
``[stages.calibration.windows]``) and returns one calibration and QC status per IMU. A session without a
calibration trial gets a ``fail`` row per lower-limb IMU ("calibration trial missing"), never an exception:
joint angles then carry that status. ``score`` (separate step): the calibration error against the optical
reference (:func:`stridelab.estimators.calibration.evaluation.helical_angle_deg`).

Manifest form (seconds from the start of the calibration trial; a table keyed by a session id
applies to that session only)::

    [stages.calibration]
    method = "hip_fe"
    [stages.calibration.windows]
    standing = [0.0, 4.0]
    walking = [42.3, 47.3]
    hip_fe = { right = [4.0, 21.6], left = [23.2, 40.8] }
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field

import numpy as np

from stridelab.estimators.calibration import CalibrationParams
from stridelab.pipeline.stages import canonical_json
from stridelab.pipeline.stages._lab_read import find_calibration_recording, read_recording
from stridelab.pipeline.stages._shape import StageContext, shaped_stage

TABLES = ("calibration", "accuracy_metrics")
WINDOW_KEYS = ("standing", "hip_fe", "walking")


@dataclass(frozen=True)
class CalibrationStageParams(CalibrationParams):
    """The estimator's :class:`stridelab.estimators.calibration.CalibrationParams` (units in their names) and ``windows``:
    the calibration windows in seconds from the start of the calibration trial ({} = detected), or per session id
    a table of them (see the module docstring)."""
    windows: dict = field(default_factory=dict)


def calibration_params(p: CalibrationStageParams) -> CalibrationParams:
    """The estimator's frozen params from the stage params (manifest overrides included)."""
    return CalibrationParams(**{f.name: getattr(p, f.name) for f in dataclasses.fields(CalibrationParams)})


def manual_windows(p: CalibrationStageParams, session_id: str, sampling_rate_hz: float):
    """CalibrationWindows from the manifest (``None`` = detect automatically)."""
    from stridelab.estimators.calibration import CalibrationWindows
    w = p.windows or {}
    if session_id in w:
        w = w[session_id]
    w = {k: v for k, v in w.items() if k in WINDOW_KEYS}
    if not w:
        return None
    return CalibrationWindows.from_seconds(sampling_rate_hz=sampling_rate_hz, **w)


def _num(x: float) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def _windows_s(win, fs: float) -> dict:
    def s(w):
        return None if w is None else [round(w[0] / fs, 3), round(w[1] / fs, 3)]
    return {"standing": s(win.standing), "hip_fe": {k: s(v) for k, v in sorted(win.hip_fe.items())},
            "walking": s(win.walking), "source": win.source}


def calibration_rows(ctx: StageContext, content_hash: str | None, cal, fs: float | None) -> list[dict]:
    """Catalog rows of a :class:`SessionCalibration` (one per IMU)."""
    rows = []
    for p, c in sorted(cal.imus.items()):
        d = c.as_dict()
        quality = {k: _num(d[k]) for k in ("planarity", "gamma_deg", "standing_s", "gravity_m_s2",
                                           "gravity_spread_deg", "axis_tilt_deg", "x_vertical_deg")}
        rows.append({"session_id": ctx.session_id, "placement": p, "content_hash": content_hash, "status": c.status,
                     "reasons": json.dumps(list(c.reasons)), "method": c.method, "quality": canonical_json(quality),
                     "n_reps": int(c.n_cycles), **{f"q{k}": _num(v) for k, v in zip("wxyz", c.quat_sensor_af)},
                     "session_status": cal.status, "session_reasons": json.dumps(list(cal.reasons)),
                     "windows": canonical_json(_windows_s(cal.windows, fs) if fs else {"source": "none"}),
                     "params": ctx.params_json, "stage_version": STAGE.version})
    return rows


def compute(ctx: StageContext, p: CalibrationStageParams) -> None:
    from stridelab.estimators.calibration import calibrate_session, missing_calibration
    from stridelab.estimators.calibration._session import DEFAULT_PLACEMENTS
    cp = calibration_params(p)
    have = {pl for r in ctx.recordings for pl, kinds in r["sensors"].items() if "imu" in kinds}
    if not have & (set(DEFAULT_PLACEMENTS) - {"foot_left", "foot_right"}):
        # sessions as they come (feet only, chest or lower back only, a hand-held sensor): nothing to calibrate
        return ctx.skip(f"calibration skipped: no pelvis/thigh/shank sensors (session has "
                        f"{', '.join(sorted(have)) or 'no IMU'})")
    rec = find_calibration_recording(ctx.recordings)
    if rec is None:       # QC rows for the sensors the session has, not for placements it never had
        cal = missing_calibration(tuple(pl for pl in DEFAULT_PLACEMENTS if pl in have), params=cp)
        ctx.emit("calibration", calibration_rows(ctx, None, cal, None))
        return ctx.set_note("calibration trial missing")
    data = read_recording(ctx, rec, ctx.upstream.get("orientation", []), DEFAULT_PLACEMENTS)
    fs = data["sampling_rate_hz"]
    if fs is None or len(data["t_ns"]) < 2:
        why = ("calibration trial has no lower-limb IMU" if fs is None else
               "the IMUs of the calibration trial do not overlap in time")
        cal = missing_calibration(DEFAULT_PLACEMENTS, reason=why, params=cp)
        ctx.emit("calibration", calibration_rows(ctx, rec["content_hash"], cal, None))
        return ctx.set_note(why)
    cal = calibrate_session(data["acc"], data["gyr"], sampling_rate_hz=fs, windows=manual_windows(p, ctx.session_id, fs),
                            params=cp, quats=data["quat"] or None, placements=DEFAULT_PLACEMENTS)
    ctx.emit("calibration", calibration_rows(ctx, rec["content_hash"], cal, fs))
    ctx.found.append((rec, data, cal))
    bad = sorted(pl for pl, c in cal.imus.items() if c.status != "pass")
    ctx.set_note(f"calibration {cal.status}" + (f" ({', '.join(bad)})" if bad else ""))


def score(ctx: StageContext, p: CalibrationStageParams) -> None:
    """Calibration error (thesis Eq. 19, helical angle) against the optical reference, per IMU with a segment
    pose in the calibration trial: the reference sensor-to-segment rotation is the constant rotation between
    the IMU orientation and the optical segment orientation over the trial
    (:func:`stridelab.estimators.orientation.evaluation.segment_alignment`), so it carries the orientation error too."""
    from stridelab.estimators.calibration.evaluation import helical_angle_deg
    from stridelab.estimators.orientation.evaluation import segment_alignment
    from stridelab.estimators.quaternion import quat_to_matrix
    ori = ctx.upstream.get("orientation", [])
    estimator = ori[0]["estimator"] if ori else None
    for rec, data, cal in ctx.found:
        for pl, c in sorted(cal.imus.items()):
            q = data["quat"].get(pl)
            if q is None or c.status == "fail" or not np.all(np.isfinite(c.quat_sensor_af)):
                continue
            q_ref = ctx.reference_orientation(rec, pl, data["t_ns"])
            if q_ref is None:
                continue
            ok = np.all(np.isfinite(q_ref), axis=1) & np.all(np.isfinite(q), axis=1)
            if ok.sum() < (data["sampling_rate_hz"] or 0):
                continue
            _, mount = segment_alignment(q[ok], q_ref[ok])
            # mount: sensor→segment; quat_sensor_af: anatomical frame→sensor (q_AF = q_sensor ⊗ quat_sensor_af)
            err = float(np.ravel(helical_angle_deg(quat_to_matrix(mount).T, quat_to_matrix(c.quat_sensor_af)))[0])
            ctx.emit("accuracy_metrics", [{"session_id": ctx.session_id, "stage": "calibration",
                                           "estimator": estimator, "placement": pl,
                                           "metric": "calibration_error_deg", "value": err, "unit": "deg"}])


STAGE = shaped_stage("calibration", "4", CalibrationStageParams, compute, score=score, tables=TABLES,
                     needs=("orientation",), session_kinds=("lab", "calibration"))
