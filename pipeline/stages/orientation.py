"""Orientation for every IMU of every session: warehouse -> estimators.orientation -> warehouse."""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from estimators.orientation.blockwise import blockwise
from estimators.orientation.evaluation import align_reference, orientation_rmse_deg, pooled_rmse
from estimators.timebase import contiguous_segments
from pipeline.stages import SessionInput, Stage, StageOutput, canonical_json, params_hash, scored_mask
from warehouse.read import read_imu_files, reference_orientation_on
from warehouse.store import series_relpath, write_table


def _accuracy_rows(sid: str, name: str, errors: dict) -> list[dict]:
    """Per placement, RMS errors pooled over the session's recordings (each scored by ``orientation_rmse_deg``,
    the scorer of ``stridelab bench orientation``, after its per-recording alignment if any)."""
    rows = []
    for placement, parts in sorted(errors.items()):
        e = pooled_rmse(parts)
        for metric in ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg"):
            rows.append({"session_id": sid, "stage": "orientation", "estimator": name, "placement": placement,
                         "metric": metric, "value": getattr(e, metric), "unit": "deg"})
        rows.append({"session_id": sid, "stage": "orientation", "estimator": name, "placement": placement,
                     "metric": "n_scored", "value": float(e.n_scored), "unit": "samples"})
    return rows


def default_params() -> dict:
    from estimators.orientation import DEFAULT_OFFLINE
    # long recordings in 1-h blocks with 5 min of context each side: bounded memory per worker
    # (estimators/orientation/blockwise.py); block_s = 0 estimates every recording in one piece
    return {"estimator": DEFAULT_OFFLINE, "use_magnetometer": True, "block_s": 3600.0, "block_margin_s": 300.0}


def compute(inp: SessionInput, params: dict) -> StageOutput:
    from estimators.orientation import ESTIMATORS
    name = params["estimator"]
    if name not in ESTIMATORS:
        raise ValueError(f"unknown orientation estimator '{name}'; choose one of {', '.join(sorted(ESTIMATORS))}")
    estimate = ESTIMATORS[name]
    block_s, margin_s = float(params.get("block_s", 0.0)), float(params.get("block_margin_s", 300.0))
    s = inp.session
    rows, notes, errors = [], [], {}
    for rec in inp.recordings:
        meta = rec.get("metadata") or {}
        no_gyro = {p.strip() for p in str(meta.get("accelerometer_only", "")).split(",") if p.strip()}
        for placement, kinds in sorted(rec["sensors"].items()):
            if "imu" not in kinds:
                continue
            if placement in no_gyro:
                notes.append(f"{placement}: orientation skipped: accelerometer-only sensor (no gyroscope)")
                continue
            imu = kinds["imu"]
            mag = kinds.get("mag") if params.get("use_magnetometer", True) else None
            data = read_imu_files(inp.root, imu["series_path"], mag["series_path"] if mag else None,
                                  imu["sampling_rate_hz"])
            quat = np.full((len(data.t_ns), 4), np.nan)
            for a, b in contiguous_segments(data.t_ns):
                if b - a < data.sampling_rate_hz:      # < 1 s between gaps: too short to converge
                    continue
                res = blockwise(estimate, data.gyr[a:b], data.acc[a:b], None if data.mag is None else data.mag[a:b],
                                sampling_rate_hz=data.sampling_rate_hz, block_s=block_s, margin_s=margin_s,
                                fade_s=min(60.0, margin_s))
                quat[a:b] = res.quat
            key = f"orientation-{rec['content_hash'][:12]}-{params_hash(params)[:12]}"
            rel = series_relpath(s["study"], s["participant_id"], s["session_id"], placement, key)
            write_table(inp.root, rel, pa.table({"t_ns": data.t_ns, "qw": quat[:, 0], "qx": quat[:, 1],
                                                 "qy": quat[:, 2], "qz": quat[:, 3]}))
            rows.append({"session_id": s["session_id"], "content_hash": rec["content_hash"], "placement": placement,
                         "estimator": name, "estimator_version": STAGE.version, "params": canonical_json(params),
                         "n_samples": len(data.t_ns), "sampling_rate_hz": data.sampling_rate_hz,
                         "mag_used": data.mag is not None, "series_path": rel})
            ref = kinds.get("reference_pose")
            if ref is not None:          # optical reference: the bench's scorer over the reference's score spans
                q_ref = reference_orientation_on(inp.root, ref["series_path"], data.t_ns)
                ok = np.isfinite(q_ref[:, 0]) & np.isfinite(quat[:, 0]) & scored_mask(inp.events, rec, placement,
                                                                                      data.t_ns)
                if ok.sum() >= data.sampling_rate_hz:
                    # BROAD (reference_frame = sensor_enu): the sensor's own frame in ENU, scored as it stands;
                    # else a segment pose in the lab frame: mounting and lab heading aligned first
                    if meta.get("reference_frame") != "sensor_enu":
                        q_ref = q_ref.copy()
                        q_ref[ok] = align_reference(quat[ok], q_ref[ok])
                    errors.setdefault(placement, []).append(orientation_rmse_deg(quat, q_ref, ok))
            if np.isnan(quat[:, 0]).any():
                notes.append(f"{placement}: {int(np.isnan(quat[:, 0]).sum())} samples without orientation")
    if not rows:
        return StageOutput.skipped("orientation skipped: " + ("; ".join(notes) or "no IMU with a gyroscope"))
    return StageOutput(rows={"orientation": rows, "accuracy_metrics": _accuracy_rows(s["session_id"], name, errors)},
                       note="; ".join(notes))


STAGE = Stage(name="orientation", version="5", needs=(), tables=("orientation", "accuracy_metrics"),
              session_kinds=("lab", "free_living", "calibration"), compute=compute, default_params=default_params,
              # a free-living chest day's orientation is read by no stage, page or report (half of a night's
              # compute went to it): computed only for studies that ask ([compute.orientation] free_living = true)
              opt_in_kinds=("free_living",))
