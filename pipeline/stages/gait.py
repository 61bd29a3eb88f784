"""Gait events, strides, foot trajectories and the session gait summary of every lab session:
warehouse -> stridelab.estimators.gait -> warehouse.

``compute``: for each walking trial (recording whose trial is not ``calibration``) and each foot IMU
(``foot_left``, ``foot_right``), :func:`stridelab.estimators.gait.foot_kinematics` (events, strides) and
:func:`stridelab.estimators.gait.foot_trajectory` (the stored foot trajectory, on the trajectory's own stance
detector ``TRAJECTORY_ZUPT``: what ``stridelab bench trajectory`` scores) per contiguous segment of samples; when
the recording carries the shoe distance sensors (``/range/<foot>/<A|B>``) and ``distance_sensors.use`` is on, the
foot's vertical trajectory from the Duong & Suh filter (:func:`stridelab.estimators.trajectory.duong_suh_trajectory`);
:func:`stridelab.estimators.gait.gait_session_pooled` over the whole session. ``score`` (separate step,
:mod:`stridelab.pipeline.stages._gait_score`): events, stride lengths and trajectories against the session's references.
``finish``: the session summary (``gait_summary``), whose note carries the notes of both steps.

Tables (migration 004): ``gait_events``, ``strides``, ``gait_summary``, ``foot_trajectories`` (+ Parquet
``t_ns, px, py, pz, vx, vy, vz, stance``), ``accuracy_metrics``, ``accuracy_pairs``. A session without
stance or strides gets a summary row with that status and a note, never invented strides.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stridelab.estimators.gait import FootParams
from stridelab.estimators.gait.evaluation import EVENT_TOLERANCE_S
from stridelab.estimators.timebase import contiguous_segments
from stridelab.estimators.trajectory import UNKNOWN_GEOMETRY_CALIB_VAR, DuongSuhParams
from stridelab.pipeline.stages import _gait_score as sc
from stridelab.pipeline.stages._gait_ranges import range_trajectory, read_ranges
from stridelab.pipeline.stages._gait_rows import SIDES, foot_rows, num, session_status, summary_rows, trajectory_table
from stridelab.pipeline.stages._shape import StageContext, shaped_stage

CALIBRATION_TRIAL = "calibration"
ESTIMATOR = sc.ESTIMATOR
TABLES = ("gait_events", "strides", "gait_summary", "foot_trajectories", "accuracy_metrics", "accuracy_pairs")


@dataclass(frozen=True)
class DistanceSensorParams:
    """use: run the Duong & Suh filter where the shoes carry distance sensors. filter: its parameters (no ruler
    baseline: unknown for a study). geometry: {placement: {r_a, r_b, n_a, n_b}} in IMU coordinates (m, unit
    vectors) when measured, else guessed from the first stance (:func:`stridelab.estimators.trajectory.geometry_from_stance`)
    with the calibration-state variance ``unknown_geometry_calib_var``."""
    use: bool = True
    filter: DuongSuhParams = field(default_factory=lambda: DuongSuhParams(baseline_m=None))
    geometry: dict = field(default_factory=dict)
    unknown_geometry_calib_var: float = UNKNOWN_GEOMETRY_CALIB_VAR


@dataclass(frozen=True)
class GaitParams:
    """foot: :class:`stridelab.estimators.gait.FootParams`. event_tolerance_s: detected and reference events further apart
    than this (s) do not match (scoring). min_segment_s: stretches of samples shorter than this (s) are not
    analysed. distance_sensors: :class:`DistanceSensorParams`."""
    foot: FootParams = field(default_factory=FootParams)
    event_tolerance_s: float = EVENT_TOLERANCE_S
    min_segment_s: float = 2.0
    distance_sensors: DistanceSensorParams = field(default_factory=DistanceSensorParams)


@dataclass
class _Found:
    """What compute hands to score and finish: per foot (rec, side, t_ns, fks, note position, its stride rows)."""
    feet: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    statuses: dict = field(default_factory=lambda: {side: [] for side in SIDES})
    session: object = None


def walking_recordings(recordings: list[dict]) -> list[dict]:
    return [r for r in recordings if (r.get("trial") or "").lower() != CALIBRATION_TRIAL]


def compute(ctx: StageContext, p: GaitParams) -> None:
    from stridelab.estimators.gait import foot_kinematics, foot_trajectory, gait_session_pooled
    sid, f, pairs = ctx.session_id, _Found(), []
    notes, dp = f.notes, p.distance_sensors
    recs = walking_recordings(ctx.recordings)
    if not recs:
        notes.append("no walking trial in this session")
    elif not any(f"foot_{s}" in r["sensors"] and "imu" in r["sensors"][f"foot_{s}"] for r in recs for s in SIDES):
        have = sorted({pl for r in recs for pl, k in r["sensors"].items() if "imu" in k})
        return ctx.skip(f"gait skipped: no foot_left/foot_right IMU (session has {', '.join(have) or 'no IMU'})")
    for rec in recs:
        fk_by_side = {}
        for side in SIDES:
            placement = f"foot_{side}"
            data = ctx.read_imu_files(rec, placement)
            if data is None:
                notes.append(f"{rec['trial']}: no {placement} IMU")
                f.statuses[side].append("missing_sensor")
                continue
            fs, t_ns = float(data.sampling_rate_hz), data.t_ns
            segs = [(a, b) for a, b in contiguous_segments(t_ns) if b - a >= p.min_segment_s * fs]
            fks, trajs, mine = [], [], []
            for a, b in segs:
                fk = foot_kinematics(data.gyr[a:b], data.acc[a:b], sampling_rate_hz=fs, params=p.foot)
                fks.append((a, b, fk))
                trajs.append((a, b, foot_trajectory(data.gyr[a:b], data.acc[a:b], fk, sampling_rate_hz=fs,
                                                    params=p.foot)))
                f.statuses[side].append(fk.status)
                notes += [f"{rec['trial']} {placement}: {n}" for n in fk.notes]
                rows = foot_rows(sid, rec, placement, side, t_ns[a:b], fk)
                ctx.emit("gait_events", rows["gait_events"])
                ctx.emit("strides", rows["strides"])
                mine += rows["strides"]
            if not segs:
                notes.append(f"{rec['trial']} {placement}: no stretch of samples ≥ {p.min_segment_s} s")
                f.statuses[side].append("too_short")
            fk_by_side[side] = (t_ns, fks)
            ranges = read_ranges(ctx, rec, placement, t_ns) if dp.use else None
            ds, ds_status, geo_src = None, None, None
            if ranges is not None:
                ds = []
                for a, b in segs:
                    r, geo_src = range_trajectory(data.gyr[a:b], data.acc[a:b], ranges[a:b], fs, placement, dp)
                    ds.append((a, b, r))
                    notes += [f"{rec['trial']} {placement} distance sensors: {n}" for n in r.notes]
                st = [r.status for *_, r in ds]
                ds_status = "ok" if "ok" in st else (st[0] if st else "too_short")
            rel = ctx.write_series(placement, f"foot-trajectory-{rec['content_hash'][:12]}-{ctx.params_key[:12]}",
                                   trajectory_table(t_ns, trajs, ds))
            ctx.emit("foot_trajectories", [{
                "session_id": sid, "content_hash": rec["content_hash"], "trial": rec["trial"], "placement": placement,
                "side": side, "estimator": ESTIMATOR, "n_samples": len(t_ns), "sampling_rate_hz": fs,
                "status": "ok" if any(tr.status == "ok" for *_, tr in trajs) else "no_stance",
                "range_estimator": None if ds is None else (
                    "duong_suh_21" if dp.filter.estimate_calibration else "duong_suh_9"),
                "range_status": ds_status, "range_geometry": geo_src,
                "range_used_fraction": num(ds[0][2].used_fraction) if ds else None, "series_path": rel}])
            f.feet.append((rec, side, t_ns, fks, trajs, len(notes), mine))
        # both feet on one grid: pair their segments for double support; otherwise each foot alone
        if "left" in fk_by_side and "right" in fk_by_side and np.array_equal(fk_by_side["left"][0],
                                                                            fk_by_side["right"][0]):
            pairs += [(fl, fr) for (_, _, fl), (_, _, fr) in zip(fk_by_side["left"][1], fk_by_side["right"][1])]
        else:
            if len(fk_by_side) == 2:
                notes.append(f"{rec['trial']}: feet on different sample grids, no double support")
            for side, (_, fks) in fk_by_side.items():
                pairs += [(fk, None) if side == "left" else (None, fk) for *_, fk in fks]
    f.session = gait_session_pooled(pairs)
    ctx.found.append(f)


def score(ctx: StageContext, p: GaitParams) -> None:
    f, sid, events = ctx.found[0], ctx.session_id, ctx.inp.events
    det_ev, ref_ev, spans, traj, inserts = {}, {}, {}, [], []
    for rec, side, t_ns, fks, trajs, note_at, mine in f.feet:
        placement = f"foot_{side}"
        ref = ctx.reference_pose(rec, placement, ("px", "py", "pz"))
        if ref is not None:
            extra = []
            traj += sc.trajectory_rows(sid, placement, t_ns, trajs, ref, extra, rec["trial"])
            inserts.append((note_at, extra))
            sc.stride_reference_lengths(mine, ref, events, rec, side)
        spans.setdefault(side, []).append(sc.annotated_span(events, rec, placement))
        for typ in ("IC", "TC"):      # one entry per recording and foot in both lists (scored per trial)
            idx = [(t_ns[a:b][fk.events.ic_idx if typ == "IC" else fk.events.tc_idx]) for a, b, fk in fks]
            det_ev.setdefault((side, typ), []).append(np.concatenate(idx) if idx else np.zeros(0, np.int64))
            ref_ev.setdefault((side, typ), []).append(np.array(
                [e["t_ns"] for e in sc.rec_events(events, rec, (typ,)) if sc.event_side(e) == side], np.int64))
    for at, extra in reversed(inserts):          # the score's notes where the foot's own notes end
        f.notes[at:at] = extra
    if any(len(x) for v in ref_ev.values() for x in v):
        m, pairs = sc.event_rows(sid, det_ev, ref_ev, spans, float(p.event_tolerance_s),
                                 int(ctx.session.get("start_ns") or 0))
        ctx.emit("accuracy_metrics", m)
        ctx.emit("accuracy_pairs", pairs)
    ctx.emit("accuracy_metrics", sc.stride_rows(sid, ctx.rows.get("strides", [])) + traj)


def finish(ctx: StageContext, p: GaitParams) -> None:
    f = ctx.found[0]
    strides = ctx.rows.get("strides", [])
    n_strides = {side: sum(1 for r in strides if r["side"] == side) for side in SIDES}
    status = session_status(f.statuses, n_strides)
    note = "; ".join(dict.fromkeys(f.notes))
    ctx.emit("gait_summary", summary_rows(ctx.session_id, f.session, n_strides, status, note))
    ctx.set_note(f"gait {status}" + (f": {note}" if note and status != "ok" else ""))


STAGE = shaped_stage("gait", "7", GaitParams, compute, score=score, finish=finish, tables=TABLES,
                     session_kinds=("lab",))
