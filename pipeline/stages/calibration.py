"""Sensor-to-segment calibration per lab session: warehouse -> estimators.calibration -> warehouse.

The session's calibration trial (recording whose trial is ``calibration``) is read with the sensor
orientations of the orientation stage; :func:`estimators.calibration.calibrate_session` finds the
windows (or takes them from the study manifest, ``[stages.calibration.windows]``) and returns one
calibration and QC status per IMU. A session without a calibration trial gets a ``fail`` row per
lower-limb IMU ("calibration trial missing"), never an exception: joint angles then carry that status.

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

import numpy as np

from pipeline.stages import SessionInput, Stage, StageOutput, canonical_json
from warehouse.read import read_imu_files, reference_orientation_on
from warehouse.store import read_table

CALIBRATION_TRIAL = "calibration"
WINDOW_KEYS = ("standing", "hip_fe", "walking")


def default_params() -> dict:
    from estimators.calibration import CalibrationParams
    return {**dataclasses.asdict(CalibrationParams()), "windows": {}}


def calibration_params(params: dict):
    """The estimator's frozen params from the stage params (manifest overrides included)."""
    from estimators.calibration import CalibrationParams
    names = {f.name for f in dataclasses.fields(CalibrationParams)}
    return CalibrationParams(**{k: v for k, v in params.items() if k in names})


def find_calibration_recording(recordings: list[dict]) -> dict | None:
    """The session's calibration trial (the last one if it was repeated), or None."""
    cands = [r for r in recordings if (r.get("trial") or "").lower() == CALIBRATION_TRIAL]
    return cands[-1] if cands else None


def common_grid(t_by_placement: dict[str, np.ndarray]) -> np.ndarray:
    """Timestamps (int64 ns) present in every sensor of a recording: one time grid for the estimators."""
    grid = None
    for t in t_by_placement.values():
        grid = t if grid is None else np.intersect1d(grid, t, assume_unique=True)
    return np.asarray(grid if grid is not None else [], np.int64)


#: when the stamps shared by every sensor are fewer than this share of the shortest sensor's, the
#: sensors run on independent clocks and are resampled onto one grid (see :func:`read_recording`)
EXACT_GRID_SHARE = 0.9


def read_recording(inp: SessionInput, rec: dict, orientation_rows: list[dict], placements) -> dict:
    """acc, gyr, quat (placement -> (N, ·) on the common grid), t_ns and sampling_rate_hz of one recording.

    Placements without an IMU are left out; ``quat`` only holds placements with orientation rows.
    Sensors sharing one clock meet on the stamps they all have (no interpolation). Sensors on
    independent clocks (offsets up to seconds, jitter, slightly different rates: the shared stamps are
    fewer than :data:`EXACT_GRID_SHARE` of the shortest sensor's) are aligned through the host clock:
    each sensor's ``log_time - header.stamp`` is fitted by a straight line (offset and rate), which maps
    every stamp into the clock of the first placement, and the others are interpolated (linearly; the
    orientation by normalised linear interpolation) onto that sensor's stamps where all overlap.
    ``resampled`` tells which case applied; the grid is empty when the sensors do not overlap.
    """
    series, quat_t = {}, {}
    ori = {r["placement"]: r for r in orientation_rows if r["content_hash"] == rec["content_hash"]}
    rate = None
    for p in placements:
        imu = rec["sensors"].get(p, {}).get("imu")
        if imu is None:
            continue
        series[p] = read_imu_files(inp.root, imu["series_path"], None, imu["sampling_rate_hz"])
        rate = rate or float(imu["sampling_rate_hz"])
        if p in ori:
            t = read_table(inp.root, ori[p]["series_path"])
            quat_t[p] = (t.column("t_ns").to_numpy(),
                         np.column_stack([t.column(c).to_numpy() for c in ("qw", "qx", "qy", "qz")]))
    grid = common_grid({p: s.t_ns for p, s in series.items()})
    shortest = min((len(s.t_ns) for s in series.values()), default=0)
    if len(series) > 1 and len(grid) < EXACT_GRID_SHARE * shortest:
        return _resampled(inp, rec, series, quat_t, rate)

    def on_grid(t, x):
        return x[np.searchsorted(t, grid)]

    out = {"t_ns": grid, "sampling_rate_hz": rate, "acc": {}, "gyr": {}, "quat": {}, "resampled": False}
    for p, s in series.items():
        out["acc"][p], out["gyr"][p] = on_grid(s.t_ns, s.acc), on_grid(s.t_ns, s.gyr)
        if p in quat_t and np.isin(grid, quat_t[p][0]).all():
            out["quat"][p] = on_grid(*quat_t[p])
    return out


def _clock_fit(t: np.ndarray, log: np.ndarray) -> tuple[float, float, float]:
    """(t0, offset at t0, rate) of the straight line log - t = offset + rate * (t - t0), in ns and ns/ns."""
    k = max(1, len(t) // 20000)
    tt, off = t[::k].astype(np.float64), (log[::k] - t[::k]).astype(np.float64)
    t0 = float(tt[0])
    if len(tt) < 3 or np.ptp(tt) == 0:
        return t0, float(np.median(off)), 0.0
    b, a = np.polyfit(tt - t0, off, 1)
    return t0, float(a), float(b)


def _nlerp(t_src: np.ndarray, q: np.ndarray, t_dst: np.ndarray) -> np.ndarray:
    q = q.copy()
    flip = np.cumsum(np.r_[False, (q[1:] * q[:-1]).sum(axis=1) < 0]) % 2 == 1
    q[flip] *= -1                                   # sign continuity before interpolating
    out = np.column_stack([np.interp(t_dst, t_src, q[:, k]) for k in range(4)])
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def _resampled(inp: SessionInput, rec: dict, series: dict, quat_t: dict, rate: float) -> dict:
    """The independent-clock case of :func:`read_recording`."""
    fits = {}
    for p in series:
        tab = read_table(inp.root, rec["sensors"][p]["imu"]["series_path"], columns=["t_ns", "log_ns"])
        fits[p] = _clock_fit(tab.column("t_ns").to_numpy(), tab.column("log_ns").to_numpy())
    ref = next(iter(series))
    r0, ra, rb = fits[ref]

    def to_ref(p, t):
        t0, a, b = fits[p]
        host = t.astype(np.float64) + a + b * (t.astype(np.float64) - t0)
        return (host - ra + rb * r0) / (1.0 + rb)     # solve host = t_r + ra + rb (t_r - r0)

    mapped = {p: to_ref(p, s.t_ns) for p, s in series.items()}
    lo = max(m[0] for m in mapped.values())
    hi = min(m[-1] for m in mapped.values())
    t_ref = series[ref].t_ns
    keep = (t_ref >= lo) & (t_ref <= hi)
    grid = t_ref[keep]
    out = {"t_ns": grid, "sampling_rate_hz": rate, "acc": {}, "gyr": {}, "quat": {}, "resampled": True}
    g = grid.astype(np.float64)
    for p, s in series.items():
        if p == ref:
            out["acc"][p], out["gyr"][p] = s.acc[keep], s.gyr[keep]
        else:
            out["acc"][p] = np.column_stack([np.interp(g, mapped[p], s.acc[:, k]) for k in range(3)])
            out["gyr"][p] = np.column_stack([np.interp(g, mapped[p], s.gyr[:, k]) for k in range(3)])
        if p in quat_t and len(quat_t[p][0]) >= 2 and len(grid):
            out["quat"][p] = _nlerp(to_ref(p, quat_t[p][0]), quat_t[p][1], g)
    return out


def manual_windows(params: dict, session_id: str, sampling_rate_hz: float):
    """CalibrationWindows from the manifest (``None`` = detect automatically)."""
    from estimators.calibration import CalibrationWindows
    w = params.get("windows") or {}
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


def calibration_rows(session_id: str, content_hash: str | None, cal, fs: float | None, params: dict) -> list[dict]:
    """Catalog rows of a :class:`SessionCalibration` (one per IMU)."""
    rows = []
    for p, c in sorted(cal.imus.items()):
        q = c.quat_sensor_af
        d = c.as_dict()
        quality = {k: _num(d[k]) for k in ("planarity", "gamma_deg", "standing_s", "gravity_m_s2",
                                           "gravity_spread_deg", "axis_tilt_deg", "x_vertical_deg")}
        rows.append({"session_id": session_id, "placement": p, "content_hash": content_hash, "status": c.status,
                     "reasons": json.dumps(list(c.reasons)), "method": c.method, "quality": canonical_json(quality),
                     "n_reps": int(c.n_cycles), **{f"q{k}": _num(v) for k, v in zip("wxyz", q)},
                     "session_status": cal.status, "session_reasons": json.dumps(list(cal.reasons)),
                     "windows": canonical_json(_windows_s(cal.windows, fs) if fs else {"source": "none"}),
                     "params": canonical_json(params), "stage_version": STAGE.version})
    return rows


def compute(inp: SessionInput, params: dict) -> StageOutput:
    from estimators.calibration import calibrate_session, missing_calibration
    from estimators.calibration._session import DEFAULT_PLACEMENTS
    cp = calibration_params(params)
    sid = inp.session["session_id"]
    have = {p for r in inp.recordings for p, kinds in r["sensors"].items() if "imu" in kinds}
    if not have & (set(DEFAULT_PLACEMENTS) - {"foot_left", "foot_right"}):
        # sessions as they come (feet only, chest or lower back only, a hand-held sensor): nothing to calibrate
        return StageOutput.skipped(f"calibration skipped: no pelvis/thigh/shank sensors (session has "
                                   f"{', '.join(sorted(have)) or 'no IMU'})")
    rec = find_calibration_recording(inp.recordings)
    if rec is None:       # QC rows for the sensors the session has, not for placements it never had
        cal = missing_calibration(tuple(p for p in DEFAULT_PLACEMENTS if p in have), params=cp)
        return StageOutput(rows={"calibration": calibration_rows(sid, None, cal, None, params)},
                           note="calibration trial missing")
    data = read_recording(inp, rec, inp.upstream.get("orientation", []), DEFAULT_PLACEMENTS)
    fs = data["sampling_rate_hz"]
    if fs is None or len(data["t_ns"]) < 2:
        why = ("calibration trial has no lower-limb IMU" if fs is None else
               "the IMUs of the calibration trial do not overlap in time")
        cal = missing_calibration(DEFAULT_PLACEMENTS, reason=why, params=cp)
        return StageOutput(rows={"calibration": calibration_rows(sid, rec["content_hash"], cal, None, params)},
                           note=why)
    cal = calibrate_session(data["acc"], data["gyr"], sampling_rate_hz=fs,
                            windows=manual_windows(params, sid, fs), params=cp,
                            quats=data["quat"] or None, placements=DEFAULT_PLACEMENTS)
    bad = sorted(p for p, c in cal.imus.items() if c.status != "pass")
    note = f"calibration {cal.status}" + (f" ({', '.join(bad)})" if bad else "")
    return StageOutput(rows={"calibration": calibration_rows(sid, rec["content_hash"], cal, fs, params),
                             "accuracy_metrics": accuracy_rows(inp, rec, data, cal)}, note=note)


def accuracy_rows(inp: SessionInput, rec: dict, data: dict, cal) -> list[dict]:
    """Calibration error (thesis Eq. 19, helical angle) against the optical reference, per IMU with a segment
    pose in the calibration trial: the reference sensor-to-segment rotation is the constant rotation between
    the IMU orientation and the optical segment orientation over the trial
    (:func:`estimators.orientation.evaluation.segment_alignment`), so it carries the orientation error too."""
    from estimators.calibration.evaluation import helical_angle_deg
    from estimators.orientation.evaluation import segment_alignment
    from estimators.quaternion import quat_to_matrix
    rows = []
    ori = inp.upstream.get("orientation", [])
    estimator = ori[0]["estimator"] if ori else None
    for p, c in sorted(cal.imus.items()):
        ref = rec["sensors"].get(p, {}).get("reference_pose")
        q = data["quat"].get(p)
        if ref is None or q is None or c.status == "fail" or not np.all(np.isfinite(c.quat_sensor_af)):
            continue
        q_ref = reference_orientation_on(inp.root, ref["series_path"], data["t_ns"])
        ok = np.all(np.isfinite(q_ref), axis=1) & np.all(np.isfinite(q), axis=1)
        if ok.sum() < (data["sampling_rate_hz"] or 0):
            continue
        _, mount = segment_alignment(q[ok], q_ref[ok])
        # mount: sensor→segment; quat_sensor_af: anatomical frame→sensor (q_AF = q_sensor ⊗ quat_sensor_af)
        err = float(np.ravel(helical_angle_deg(quat_to_matrix(mount).T, quat_to_matrix(c.quat_sensor_af)))[0])
        rows.append({"session_id": inp.session["session_id"], "stage": "calibration", "estimator": estimator,
                     "placement": p, "metric": "calibration_error_deg", "value": err, "unit": "deg"})
    return rows


STAGE = Stage(name="calibration", version="4", needs=("orientation",), tables=("calibration", "accuracy_metrics"),
              session_kinds=("lab", "calibration"), compute=compute, default_params=default_params)
