"""Live against offline on one recorded live session: the agreement the nightly's outputs and the live ones show.

Reads the live outputs the recorder stored in the recording (``/live/joint_angles``, ``/live/events``) and
recomputes from the raw topics what the nightly computes: orientation by the nightly's offline estimator
(``DEFAULT_OFFLINE``), joint angles as the joint-angle stage does (``compute_joint_angles`` with the first quiet
standing of the trial), gait events as the gait stage does (``foot_kinematics``: ESKF + smoother, toe-off
refinement). Scored with the project's scorers: ``stridelab.estimators.joints.angle_errors`` (RMSE per plane) and
``stridelab.estimators.gait.evaluation.match_events`` (± ``EVENT_TOLERANCE_S``). ``stridelab live --compare REC``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def read_live_outputs(path: str | Path) -> tuple[dict, list]:
    """(frame -> {joint: [FE, AA, IE]} as arrays per joint over frames, events) stored in a live recording."""
    from mcap.reader import make_reader

    from stridelab.pipeline.live.recorder import decode_string
    k, ang, events = [], {}, []
    with open(path, "rb") as fh:
        r = make_reader(fh)
        for _s, ch, m in r.iter_messages(topics=["/live/joint_angles", "/live/events"], log_time_order=True):
            doc = json.loads(decode_string(m.data))
            if ch.topic == "/live/events":
                events.append(doc)
                continue
            n = len(doc["t_ns"])
            k.extend(range(doc["k0"], doc["k0"] + n))
            for key, rows in doc["angles_deg"].items():
                ang.setdefault(key, []).extend(rows)
    if not k:
        raise ValueError(f"{path}: no /live/joint_angles messages: not a recording of `stridelab live` "
                         f"with a calibration")
    order = np.argsort(k, kind="stable")
    out = {key: np.array([[np.nan if v is None else v for v in row] for row in rows], float)[order]
           for key, rows in ang.items()}
    return out, events


def live_vs_offline(path: str | Path, calibration) -> dict:
    """Agreement per joint (RMSE per plane, degrees) and per foot (events matched, mean/SD of live − offline, ms)."""
    from stridelab.estimators.calibration import first_quiet_standing
    from stridelab.estimators.gait import foot_kinematics
    from stridelab.estimators.gait.evaluation import EVENT_TOLERANCE_S, match_events
    from stridelab.estimators.joints import angle_errors, compute_joint_angles
    from stridelab.estimators.orientation import DEFAULT_OFFLINE, ESTIMATORS
    from stridelab.pipeline.live.engine import LEG_PLACEMENTS
    from stridelab.pipeline.live.streams import read_streams
    live_ang, live_ev = read_live_outputs(path)
    st = read_streams(path)
    fs = st.sampling_rate_hz
    pl = [p for p in LEG_PLACEMENTS if p in st.sensors]
    n = min(len(st.sensors[p].t_ns) for p in pl)
    est = ESTIMATORS[DEFAULT_OFFLINE]
    quats = {p: est(st.sensors[p].gyr[:n], st.sensors[p].acc[:n],
                    None if st.sensors[p].mag is None else st.sensors[p].mag[:n], sampling_rate_hz=fs).quat for p in pl}
    standing = first_quiet_standing({p: st.sensors[p].acc[:n] for p in pl}, {p: st.sensors[p].gyr[:n] for p in pl},
                                    sampling_rate_hz=fs, params=calibration.params)
    off = compute_joint_angles(quats, calibration, standing=standing)
    joints = {}
    for key, a in sorted(off.angles_deg.items()):
        if key not in live_ang:
            continue
        m = min(len(a), len(live_ang[key]))
        e = angle_errors(a[:m], live_ang[key][:m])
        joints[key] = {"rmse_deg": [round(float(x), 2) for x in e.rmse_deg],
                       "sd_error_deg": [round(float(x), 2) for x in e.sd_error_deg]}
    feet = {}
    tol = int(round(EVENT_TOLERANCE_S * fs))
    for side in ("left", "right"):
        p = f"foot_{side}"
        if p not in st.sensors:
            continue
        fk = foot_kinematics(st.sensors[p].gyr[:n], st.sensors[p].acc[:n], sampling_rate_hz=fs)
        res = {}
        for typ, ref in (("IC", fk.events.ic_idx), ("TC", fk.events.tc_idx)):
            det = np.array([e["k"] for e in live_ev if e["side"] == side and e["type"] == typ], np.int64)
            mt = match_events(det, np.asarray(ref, np.int64), tolerance_samples=tol)
            err_ms = mt.error_samples * 1000.0 / fs
            res[typ] = {"live": int(len(det)), "offline": int(len(ref)), "matched": int(mt.tp),
                        "mean_ms": round(float(err_ms.mean()), 1) if len(err_ms) else None,
                        "sd_ms": round(float(err_ms.std(ddof=1)), 1) if len(err_ms) > 1 else None}
        feet[side] = res
    return {"recording": Path(path).name, "offline_orientation": DEFAULT_OFFLINE, "joints": joints, "events": feet,
            "standing": None if standing is None else [int(standing[0]), int(standing[1])]}
