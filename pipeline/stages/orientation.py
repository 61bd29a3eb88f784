"""Orientation for every IMU of every session: warehouse -> stridelab.estimators.orientation -> warehouse.

``compute``: each IMU with a gyroscope of each recording, per contiguous stretch of samples, through the chosen
offline estimator (:data:`stridelab.estimators.orientation.ESTIMATORS`) in blocks (:func:`stridelab.estimators.orientation.blockwise.
blockwise`: bounded memory per worker on long recordings); one ``orientation`` row and one quaternion series each.
``score`` (separate step): where the recording holds an optical pose of that segment, the RMS errors by the
scorer of ``stridelab bench orientation`` (:mod:`stridelab.estimators.orientation.evaluation`) into ``accuracy_metrics``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from stridelab.estimators.orientation.blockwise import blockwise
from stridelab.estimators.orientation.evaluation import align_reference, orientation_rmse_deg, pooled_rmse
from stridelab.estimators.timebase import contiguous_segments
from stridelab.pipeline.stages import scored_mask
from stridelab.pipeline.stages._shape import StageContext, shaped_stage

TABLES = ("orientation", "accuracy_metrics")


def _default_estimator() -> str:
    from stridelab.estimators.orientation import DEFAULT_OFFLINE
    return DEFAULT_OFFLINE


@dataclass(frozen=True)
class OrientationParams:
    """estimator: name in :data:`stridelab.estimators.orientation.ESTIMATORS` (default the shipped offline one).
    use_magnetometer: fuse the magnetometer when the recording has one.
    block_s: long recordings are estimated in blocks of this many seconds (0 = each recording in one piece).
    block_margin_s: seconds of context each side of a block (the fade between blocks is min(60 s, this))."""
    estimator: str = _default_estimator()
    use_magnetometer: bool = True
    block_s: float = 3600.0
    block_margin_s: float = 300.0


def compute(ctx: StageContext, p: OrientationParams) -> None:
    from stridelab.estimators.orientation import ESTIMATORS
    if p.estimator not in ESTIMATORS:
        raise ValueError(f"unknown orientation estimator '{p.estimator}'; choose one of {', '.join(sorted(ESTIMATORS))}")
    estimate, notes = ESTIMATORS[p.estimator], []
    for rec in ctx.recordings:
        meta = rec.get("metadata") or {}
        no_gyro = {x.strip() for x in str(meta.get("accelerometer_only", "")).split(",") if x.strip()}
        for placement, kinds in sorted(rec["sensors"].items()):
            if "imu" not in kinds:
                continue
            if placement in no_gyro:
                notes.append(f"{placement}: orientation skipped: accelerometer-only sensor (no gyroscope)")
                continue
            data = ctx.read_imu_files(rec, placement, with_mag=p.use_magnetometer)
            quat = np.full((len(data.t_ns), 4), np.nan)
            for a, b in contiguous_segments(data.t_ns):
                if b - a < data.sampling_rate_hz:      # < 1 s between gaps: too short to converge
                    continue
                res = blockwise(estimate, data.gyr[a:b], data.acc[a:b], None if data.mag is None else data.mag[a:b],
                                sampling_rate_hz=data.sampling_rate_hz, block_s=p.block_s, margin_s=p.block_margin_s,
                                fade_s=min(60.0, p.block_margin_s))
                quat[a:b] = res.quat
            rel = ctx.write_series(placement, f"orientation-{rec['content_hash'][:12]}-{ctx.params_key[:12]}",
                                   pa.table({"t_ns": data.t_ns, "qw": quat[:, 0], "qx": quat[:, 1],
                                             "qy": quat[:, 2], "qz": quat[:, 3]}))
            ctx.emit("orientation", [{
                "session_id": ctx.session_id, "content_hash": rec["content_hash"], "placement": placement,
                "estimator": p.estimator, "estimator_version": STAGE.version, "params": ctx.params_json,
                "n_samples": len(data.t_ns), "sampling_rate_hz": data.sampling_rate_hz,
                "mag_used": data.mag is not None, "series_path": rel}])
            if "reference_pose" in kinds:
                ctx.found.append((rec, placement, data.t_ns, quat, data.sampling_rate_hz))
            if np.isnan(quat[:, 0]).any():
                notes.append(f"{placement}: {int(np.isnan(quat[:, 0]).sum())} samples without orientation")
    if not ctx.rows.get("orientation"):
        return ctx.skip("orientation skipped: " + ("; ".join(notes) or "no IMU with a gyroscope"))
    ctx.set_note("; ".join(notes))


def score(ctx: StageContext, p: OrientationParams) -> None:
    """Per placement, RMS errors pooled over the session's recordings (each scored by ``orientation_rmse_deg``
    over the reference's score spans, after the per-recording alignment of a segment pose)."""
    errors: dict[str, list] = {}
    for rec, placement, t_ns, quat, fs in ctx.found:
        q_ref = ctx.reference_orientation(rec, placement, t_ns)
        ok = np.isfinite(q_ref[:, 0]) & np.isfinite(quat[:, 0]) & scored_mask(ctx.inp.events, rec, placement, t_ns)
        if ok.sum() >= fs:
            # BROAD (reference_frame = sensor_enu): the sensor's own frame in ENU, scored as it stands;
            # else a segment pose in the lab frame: mounting and lab heading aligned first
            if (rec.get("metadata") or {}).get("reference_frame") != "sensor_enu":
                q_ref = q_ref.copy()
                q_ref[ok] = align_reference(quat[ok], q_ref[ok])
            errors.setdefault(placement, []).append(orientation_rmse_deg(quat, q_ref, ok))
    for placement, parts in sorted(errors.items()):
        e = pooled_rmse(parts)
        base = {"session_id": ctx.session_id, "stage": "orientation", "estimator": p.estimator, "placement": placement}
        ctx.emit("accuracy_metrics", [{**base, "metric": m, "value": getattr(e, m), "unit": "deg"}
                                      for m in ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg")]
                 + [{**base, "metric": "n_scored", "value": float(e.n_scored), "unit": "samples"}])


STAGE = shaped_stage("orientation", "5", OrientationParams, compute, score=score, tables=TABLES,
                     session_kinds=("lab", "free_living", "calibration"),
                     # a free-living chest day's orientation is read by no stage, page or report (half of a night's
                     # compute went to it): computed only for studies that ask ([compute.orientation] free_living = true)
                     opt_in_kinds=("free_living",))
