"""Gait events, strides, foot trajectories and the session gait summary of every lab session:
warehouse -> estimators.gait -> warehouse.

For each walking trial (recording whose trial is not ``calibration``) and each foot IMU (``foot_left``,
``foot_right``) the stage calls :func:`estimators.gait.foot_kinematics` per contiguous segment of samples
and :func:`estimators.gait.gait_session_pooled` over the whole session. When the recording carries the
shoe distance sensors (``/range/<foot>/<A|B>``) and ``distance_sensors`` is on, the foot's vertical
trajectory comes from the Duong & Suh filter (:func:`estimators.trajectory.duong_suh_trajectory`).
Where the session holds reference gait events (``reference_events`` IC/TC) the stage writes accuracy
rows (``accuracy_metrics``, ``accuracy_pairs``) scored by :func:`estimators.gait.evaluation.event_accuracy`.

Tables (migration 004): ``gait_events``, ``strides``, ``gait_summary``, ``foot_trajectories`` (+ Parquet
``t_ns, px, py, pz, vx, vy, vz, stance``), ``accuracy_metrics``, ``accuracy_pairs``. A session without
stance or strides gets a summary row with that status and a note, never invented strides.
The only arithmetic here is int64 ns <-> sample index / seconds (STYLE.md §4).
"""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pyarrow as pa

from estimators.timebase import contiguous_segments
from pipeline.stages import SessionInput, Stage, StageOutput, params_hash
from warehouse.read import read_imu_files
from warehouse.store import read_table, series_relpath, write_table

SIDES = ("left", "right")
CALIBRATION_TRIAL = "calibration"
ESTIMATOR = "eskf_zupt_rts+thesis_icd"
TABLES = ("gait_events", "strides", "gait_summary", "foot_trajectories", "accuracy_metrics", "accuracy_pairs")


def default_params() -> dict:
    """``foot``: FootParams; ``distance_sensors``: use (bool), the Duong & Suh params (no ruler baseline: unknown
    for a study), ``geometry`` {placement: {r_a, r_b, n_a, n_b}} in IMU coordinates when measured (else guessed
    from the first stance, :func:`estimators.trajectory.geometry_from_stance`, with ``unknown_geometry_calib_var``)."""
    from estimators.gait import FootParams
    from estimators.gait.evaluation import EVENT_TOLERANCE_S
    from estimators.trajectory import UNKNOWN_GEOMETRY_CALIB_VAR, DuongSuhParams
    return {"foot": dataclasses.asdict(FootParams()), "event_tolerance_s": EVENT_TOLERANCE_S,
            "min_segment_s": 2.0,
            "distance_sensors": {"use": True, "filter": dataclasses.asdict(DuongSuhParams(baseline_m=None)),
                                 "geometry": {}, "unknown_geometry_calib_var": UNKNOWN_GEOMETRY_CALIB_VAR}}


_RANGE_NAME = re.compile(r"range-([A-Za-z0-9]+)-")


def read_ranges(inp: SessionInput, rec: dict, placement: str, t_ns: np.ndarray) -> np.ndarray | None:
    """(N, 2) m on the IMU grid (columns A, B; NaN where no reading falls on that sample; +inf kept: beyond the
    maximum, REP-117), or None when the foot has no distance sensor. A reading goes to the nearest IMU sample
    within half a sample period."""
    keys = sorted(k for k in rec["sensors"].get(placement, {}) if k.startswith("range:"))
    if not keys or len(t_ns) < 2:
        return None
    out = np.full((len(t_ns), 2), np.nan)
    half = (t_ns[-1] - t_ns[0]) / (len(t_ns) - 1) / 2
    for j, key in enumerate(keys[:2]):
        m = _RANGE_NAME.search(key)
        col = {"A": 0, "B": 1}.get(m.group(1).upper(), j) if m else j
        t = read_table(inp.root, rec["sensors"][placement][key]["series_path"], columns=["t_ns", "range_m"])
        tr, rv = t.column("t_ns").to_numpy(), t.column("range_m").to_numpy()
        i = np.clip(np.searchsorted(t_ns, tr), 1, len(t_ns) - 1)
        i = np.where(np.abs(t_ns[i - 1] - tr) <= np.abs(t_ns[i] - tr), i - 1, i)
        ok = np.abs(t_ns[i] - tr) <= half
        out[i[ok], col] = rv[ok]
    return out


def range_trajectory(gyr, acc, ranges, fs: float, placement: str, dp: dict):
    """The Duong & Suh filter of one foot segment with the configured or guessed geometry."""
    from estimators.trajectory import (RangeGeometry, detect_zupt, duong_suh_params_from_dict,
                                       duong_suh_trajectory, geometry_from_stance)
    fp = duong_suh_params_from_dict(dp["filter"])
    g = (dp.get("geometry") or {}).get(placement)
    if g is not None:
        geo = RangeGeometry(**{k: tuple(v) for k, v in g.items()})
    else:
        geo = geometry_from_stance(acc, detect_zupt(gyr, acc, sampling_rate_hz=fs, params=fp.zupt))
        fp = dataclasses.replace(fp, init_calib_var=float(dp["unknown_geometry_calib_var"]))
        if geo is None:
            return duong_suh_trajectory(gyr, acc, ranges, sampling_rate_hz=fs, params=fp), "unknown"
    return duong_suh_trajectory(gyr, acc, ranges, sampling_rate_hz=fs, geometry=geo, params=fp), \
        "configured" if g is not None else "guessed"


def _num(x) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def walking_recordings(recordings: list[dict]) -> list[dict]:
    return [r for r in recordings if (r.get("trial") or "").lower() != CALIBRATION_TRIAL]


def _ns(t_ns: np.ndarray, idx) -> list[int]:
    """Sample indices -> int64 ns of that sample."""
    return [int(t_ns[int(i)]) for i in idx]


def foot_segments(t_ns: np.ndarray, fs: float, min_segment_s: float) -> list[tuple[int, int]]:
    return [(a, b) for a, b in contiguous_segments(t_ns) if b - a >= min_segment_s * fs]


def _foot_rows(sid: str, rec: dict, placement: str, side: str, t_ns: np.ndarray, fk, rel: str | None) -> dict:
    """Catalog rows of one foot segment (events and strides in ns)."""
    from estimators.gait import PARAM_COLUMNS
    h, trial = rec["content_hash"], rec["trial"]
    ev = [{"session_id": sid, "content_hash": h, "trial": trial, "placement": placement, "side": side,
           "type": typ, "t_ns": t} for typ, idx in (("IC", fk.events.ic_idx), ("TC", fk.events.tc_idx))
          for t in _ns(t_ns, idx)]
    st = fk.strides
    strides = []
    for k in range(len(st)):
        a, b, tc, ic, pre = (int(x) for x in st.idx[k])
        v = dict(zip(PARAM_COLUMNS, st.values[k]))
        strides.append({"session_id": sid, "content_hash": h, "trial": trial, "placement": placement, "side": side,
                        "start_ns": int(t_ns[a]), "end_ns": int(t_ns[b]), "tc_ns": int(t_ns[tc]),
                        "ic_ns": int(t_ns[ic]), "pre_ic_ns": int(t_ns[pre]) if pre >= 0 else None,
                        "stride_time_s": _num(v["stride_time_s"]), "stance_pct": _num(v["stance_pct"]),
                        "swing_pct": _num(v["swing_pct"]), "stance_time_s": _num(v["stance_time_s"]),
                        "swing_time_s": _num(v["swing_time_s"]), "stride_length_m": _num(v["stride_length_m"]),
                        "speed_m_s": _num(v["gait_speed_m_s"]), "clearance_m": _num(v["clearance_m"]),
                        "turning_deg": _num(v["turning_angle_deg"]), "stride_length_ref_m": None,
                        "status": "ok"})
    return {"gait_events": ev, "strides": strides}


def _trajectory_table(t_ns: np.ndarray, fks: list[tuple[int, int, object]], ds: list | None) -> pa.Table:
    n = len(t_ns)
    pos, vel = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    stance = np.zeros(n, bool)
    for a, b, fk in fks:
        pos[a:b], vel[a:b], stance[a:b] = fk.trajectory.pos, fk.trajectory.vel, fk.trajectory.zupt
    cols = {"t_ns": t_ns, "px": pos[:, 0], "py": pos[:, 1], "pz": pos[:, 2], "vx": vel[:, 0], "vy": vel[:, 1],
            "vz": vel[:, 2], "stance": stance}
    if ds is not None:
        hz, used = np.full(n, np.nan), np.zeros((n, 2), bool)
        for a, b, r in ds:
            hz[a:b], used[a:b] = r.pos[:, 2], r.range_used
        cols.update({"pz_floor": hz, "range_used_a": used[:, 0], "range_used_b": used[:, 1]})
    return pa.table(cols)


def _reference_pose(inp: SessionInput, rec: dict, placement: str):
    ref = rec["sensors"].get(placement, {}).get("reference_pose")
    if ref is None:
        return None
    t = read_table(inp.root, ref["series_path"], columns=["t_ns", "px", "py", "pz"])
    return t.column("t_ns").to_numpy(), np.column_stack([t.column(c).to_numpy() for c in ("px", "py", "pz")])


def _summary_rows(sid: str, sess, n_strides: dict, status: str, note: str) -> list[dict]:
    """gait_summary rows (left, right, both) of a :class:`SessionGait`; symmetry indices on the 'both' row."""
    names = {"cadence_steps_min": "cadence_steps_min", "speed_m_s": "gait_speed_m_s",
             "stride_length_m": "stride_length_m", "stride_time_s": "stride_time_s", "stance_pct": "stance_pct",
             "swing_pct": "swing_pct", "clearance_m": "clearance_m", "double_support_pct": "double_support_pct"}
    both = dict(sess.pooled, cadence_steps_min=sess.cadence_steps_min, double_support_pct=sess.double_support_pct)
    rows = []
    for side, vals in (("left", sess.per_foot["left"]), ("right", sess.per_foot["right"]), ("both", both)):
        row = {"session_id": sid, "side": side, **{col: _num(vals.get(k, np.nan)) for col, k in names.items()},
               "n_strides": int(sum(n_strides.values()) if side == "both" else n_strides[side]),
               "status": status, "note": note or None}
        for k, v in sess.symmetry_index_pct.items():
            col = f"si_{k.removesuffix('_m').removesuffix('_s').removesuffix('_pct')}_pct"
            row[col] = _num(v) if side == "both" else None
        rows.append(row)
    return rows


def _accuracy_rows(sid: str, det: dict, ref: dict, spans: dict, tol_s: float,
                   origin_ns: int) -> tuple[list[dict], list[dict]]:
    """det/ref: (side, type) -> list over trials of int64 ns arrays; spans: side -> list over trials of the span
    the reference annotates ((lo, hi) ns, or None). Rows for accuracy_metrics/accuracy_pairs, scored by
    :func:`estimators.gait.evaluation.event_accuracy` as ``stridelab bench gait`` scores them (``spans_s``)."""
    from estimators.gait.evaluation import event_accuracy
    metrics, pairs = [], []
    units = {"sensitivity": "fraction", "precision": "fraction", "timing_mae_ms": "ms", "timing_mean_ms": "ms"}
    sec = lambda x: (np.asarray(x, np.int64) - origin_ns) / 1e9          # noqa: E731
    for typ in ("IC", "TC"):
        groups = {f"foot_{s}": [s] for s in SIDES}
        groups["both"] = list(SIDES)
        for placement, sides in groups.items():
            d = [sec(x) for s in sides for x in det.get((s, typ), [])]
            r = [sec(x) for s in sides for x in ref.get((s, typ), [])]
            if not any(len(x) for x in r):
                continue
            # a trial without an annotated span: event_accuracy's own default, [first - tol, last + tol] reference
            trial_spans = [sp for s in sides for sp in spans.get(s, [])]
            sp = [tuple(sec(np.array(span))) if span is not None else
                  ((x.min() - tol_s, x.max() + tol_s) if len(x) else (0.0, 0.0))
                  for span, x in zip(trial_spans, r)]
            acc = event_accuracy(d, r, tolerance_s=tol_s, spans_s=sp)
            for name, unit in units.items():
                v = _num(getattr(acc, name))
                if v is not None:
                    metrics.append({"session_id": sid, "stage": "gait_events", "estimator": ESTIMATOR,
                                    "placement": placement, "metric": f"{typ.lower()}_{name}", "value": v,
                                    "unit": unit})
            if placement != "both":
                pairs += [{"session_id": sid, "stage": "gait_events", "estimator": ESTIMATOR, "placement": placement,
                           "quantity": typ, "estimate": float(a + origin_ns / 1e9), "reference": float(b + origin_ns / 1e9),
                           "unit": "s"} for a, b in acc.pairs_s]
    return metrics, pairs


def compute(inp: SessionInput, params: dict) -> StageOutput:
    from estimators.gait import foot_kinematics, foot_params_from_dict, gait_session_pooled
    from estimators.gait.evaluation import stride_length_reference
    fp = foot_params_from_dict(params["foot"])
    s = inp.session
    sid = s["session_id"]
    out = {t: [] for t in TABLES}
    notes: list[str] = []
    statuses: dict[str, list[str]] = {side: [] for side in SIDES}
    pairs_for_session = []
    det_ev: dict = {}
    ref_ev: dict = {}
    spans: dict = {}
    traj_rows: list[dict] = []
    recs = walking_recordings(inp.recordings)
    if not recs:
        notes.append("no walking trial in this session")
    elif not any(f"foot_{side}" in r["sensors"] and "imu" in r["sensors"][f"foot_{side}"] for r in recs for side in SIDES):
        have = sorted({p for r in recs for p, k in r["sensors"].items() if "imu" in k})
        return StageOutput.skipped(f"gait skipped: no foot_left/foot_right IMU (session has "
                                   f"{', '.join(have) or 'no IMU'})")
    for rec in recs:
        fk_by_side = {}
        for side in SIDES:
            placement = f"foot_{side}"
            imu = rec["sensors"].get(placement, {}).get("imu")
            if imu is None:
                notes.append(f"{rec['trial']}: no {placement} IMU")
                statuses[side].append("missing_sensor")
                continue
            data = read_imu_files(inp.root, imu["series_path"], None, imu["sampling_rate_hz"])
            fs, t_ns = float(data.sampling_rate_hz), data.t_ns
            segs = foot_segments(t_ns, fs, params.get("min_segment_s", 2.0))
            fks = []
            for a, b in segs:
                fk = foot_kinematics(data.gyr[a:b], data.acc[a:b], sampling_rate_hz=fs, params=fp)
                fks.append((a, b, fk))
                statuses[side].append(fk.status)
                notes += [f"{rec['trial']} {placement}: {n}" for n in fk.notes]
                rows = _foot_rows(sid, rec, placement, side, t_ns[a:b], fk, None)
                out["gait_events"] += rows["gait_events"]
                out["strides"] += rows["strides"]
            if not segs:
                notes.append(f"{rec['trial']} {placement}: no stretch of samples ≥ {params.get('min_segment_s', 2.0)} s")
                statuses[side].append("too_short")
            fk_by_side[side] = (t_ns, fks)
            dp = params.get("distance_sensors") or {}
            ranges = read_ranges(inp, rec, placement, t_ns) if dp.get("use") else None
            ds, ds_status, geo_src = None, None, None
            if ranges is not None:
                ds = []
                for a, b in segs:
                    r, geo_src = range_trajectory(data.gyr[a:b], data.acc[a:b], ranges[a:b], fs, placement, dp)
                    ds.append((a, b, r))
                    notes += [f"{rec['trial']} {placement} distance sensors: {n}" for n in r.notes]
                st = [r.status for *_, r in ds]
                ds_status = "ok" if "ok" in st else (st[0] if st else "too_short")
            key = f"foot-trajectory-{rec['content_hash'][:12]}-{params_hash(params)[:12]}"
            rel = series_relpath(s["study"], s["participant_id"], sid, placement, key)
            write_table(inp.root, rel, _trajectory_table(t_ns, fks, ds))
            traj_status = "ok" if any(fk.status != "no_stance" for *_, fk in fks) else "no_stance"
            out["foot_trajectories"].append({
                "session_id": sid, "content_hash": rec["content_hash"], "trial": rec["trial"], "placement": placement,
                "side": side, "estimator": ESTIMATOR, "n_samples": len(t_ns), "sampling_rate_hz": fs,
                "status": traj_status, "range_estimator": None if ds is None else (
                    "duong_suh_21" if dp["filter"].get("estimate_calibration", True) else "duong_suh_9"),
                "range_status": ds_status, "range_geometry": geo_src,
                "range_used_fraction": _num(ds[0][2].used_fraction) if ds else None,
                "series_path": rel})
            ref = _reference_pose(inp, rec, placement)
            if ref is not None:
                traj_rows += _trajectory_accuracy_rows(sid, placement, t_ns, fks, ref, notes, rec["trial"])
            if ref is not None:
                mine = [r for r in out["strides"] if r["content_hash"] == rec["content_hash"] and r["side"] == side]
                if mine:
                    t0 = int(ref[0][0]) if len(ref[0]) else 0
                    labelled = [(e["t_ns"], e["end_ns"]) for e in _rec_events(inp.events, rec, ("stride",))
                                if _event_side(e) == side and e.get("end_ns") is not None]
                    lens = stride_length_reference(
                        (np.array([[r["start_ns"], r["end_ns"]] for r in mine]) - t0) / 1e9, (ref[0] - t0) / 1e9,
                        ref[1], (np.array(labelled, np.int64) - t0) / 1e9 if labelled else None)
                    for r, v in zip(mine, lens):
                        r["stride_length_ref_m"] = _num(v)
            spans.setdefault(side, []).append(_annotated_span(inp.events, rec, placement))
            for typ in ("IC", "TC"):      # one entry per recording and foot in both lists (scored per trial)
                idx = [(t_ns[a:b][fk.events.ic_idx if typ == "IC" else fk.events.tc_idx]) for a, b, fk in fks]
                det_ev.setdefault((side, typ), []).append(np.concatenate(idx) if idx else np.zeros(0, np.int64))
                ref_ev.setdefault((side, typ), []).append(np.array(
                    [e["t_ns"] for e in _rec_events(inp.events, rec, (typ,)) if _event_side(e) == side], np.int64))
        # both feet on one grid: pair their segments for double support; otherwise each foot alone
        if "left" in fk_by_side and "right" in fk_by_side and np.array_equal(fk_by_side["left"][0],
                                                                            fk_by_side["right"][0]):
            for (_, _, fl), (_, _, fr) in zip(fk_by_side["left"][1], fk_by_side["right"][1]):
                pairs_for_session.append((fl, fr))
        else:
            if len(fk_by_side) == 2:
                notes.append(f"{rec['trial']}: feet on different sample grids, no double support")
            for side, (_, fks) in fk_by_side.items():
                pairs_for_session += [(fk, None) if side == "left" else (None, fk) for *_, fk in fks]
    sess = gait_session_pooled(pairs_for_session)
    n_strides = {side: sum(1 for r in out["strides"] if r["side"] == side) for side in SIDES}
    status = _session_status(statuses, n_strides)
    note = "; ".join(dict.fromkeys(notes))
    out["gait_summary"] = _summary_rows(sid, sess, n_strides, status, note)
    if any(len(x) for v in ref_ev.values() for x in v):
        m, p = _accuracy_rows(sid, det_ev, ref_ev, spans, float(params["event_tolerance_s"]),
                              int(s.get("start_ns") or 0))
        out["accuracy_metrics"], out["accuracy_pairs"] = m, p
    out["accuracy_metrics"] += _stride_accuracy_rows(sid, out["strides"]) + traj_rows
    return StageOutput(rows=out, note=f"gait {status}" + (f": {note}" if note and status != "ok" else ""))


def _trajectory_accuracy_rows(sid: str, placement: str, t_ns: np.ndarray, fks: list, ref, notes: list,
                              trial) -> list[dict]:
    """Foot trajectory vs the optical foot position (PyShoe's Vicon): 2-D Euclidean ARMSE after PyShoe's alignment,
    :func:`estimators.trajectory.evaluation.armse_2d_aligned` (the scorer of ``stridelab bench trajectory
    --pyshoe``), per segment with a reference on at least half its samples, pooled weighted by length; and the 3-D
    error after the same alignment (``armse_3d_aligned``, metric ``armse_3d_m``; issue 43)."""
    from estimators.trajectory.evaluation import armse_2d_aligned, armse_3d_aligned
    rt, rp = ref
    if len(rt) < 2:
        return []
    half = 0.5 * float(np.median(np.diff(rt)))
    parts = []
    for a, b, fk in fks:
        if fk.status == "no_stance":
            continue
        t = t_ns[a:b]
        j = np.clip(np.searchsorted(rt, t), 1, len(rt) - 1)
        j -= (t - rt[j - 1]) < (rt[j] - t)
        on = np.where((np.abs(rt[j] - t) <= half)[:, None], rp[j], np.nan)
        if np.all(np.isfinite(on), axis=1).mean() < 0.5:
            continue
        try:
            e, _ = armse_2d_aligned(fk.trajectory.pos, on)
            e3 = armse_3d_aligned(fk.trajectory.pos, on)
        except ValueError as err:
            notes.append(f"{trial} {placement}: trajectory not scored ({err})")
            continue
        if np.isfinite(e):
            parts.append((e, b - a, e3))
    if not parts:
        return []
    v = float(np.average([p[0] for p in parts], weights=[p[1] for p in parts]))
    rows = [{"session_id": sid, "stage": "foot_trajectory", "estimator": ESTIMATOR, "placement": placement,
             "metric": "armse_2d_m", "value": v, "unit": "m"}]
    if all(np.isfinite(p[2]) for p in parts):
        rows.append({**rows[0], "metric": "armse_3d_m",
                     "value": float(np.average([p[2] for p in parts], weights=[p[1] for p in parts]))})
    return rows


def _stride_accuracy_rows(sid: str, strides: list[dict]) -> list[dict]:
    from estimators.gait.evaluation import paired_errors
    rows = []
    for placement, sides in (("foot_left", ("left",)), ("foot_right", ("right",)), ("both", SIDES)):
        sel = [r for r in strides if r["side"] in sides and r["stride_length_ref_m"] is not None
               and r["stride_length_m"] is not None]
        if not sel:
            continue
        e = paired_errors([r["stride_length_m"] for r in sel], [r["stride_length_ref_m"] for r in sel])
        rows += [{"session_id": sid, "stage": "strides", "estimator": ESTIMATOR, "placement": placement,
                  "metric": f"stride_length_{k}_m", "value": _num(e[k]), "unit": "m"} for k in ("mae", "mean", "rmse")
                 if _num(e[k]) is not None]
    return rows


def _rec_events(events: list[dict], rec: dict, types: tuple[str, ...]) -> list[dict]:
    """The session's reference annotations of these types that start inside the recording."""
    return [e for e in events if e["type"] in types and rec["start_ns"] <= e["t_ns"] <= rec["end_ns"]]


def _annotated_span(events: list[dict], rec: dict, placement: str) -> tuple[int, int] | None:
    """(lo, hi) ns of the part of the recording the reference annotates for this foot: the hull of its ``score``
    spans (Voisard's TrialBoundaries) and ``annotated`` spans (gaitmap's labelled strides); None when it marks none."""
    sp = [(int(e["t_ns"]), int(e["end_ns"])) for e in _rec_events(events, rec, ("score", "annotated"))
          if e.get("end_ns") is not None and e.get("placement") in (None, placement)]
    return (min(a for a, _ in sp), max(b for _, b in sp)) if sp else None


def _event_side(e: dict) -> str:
    return e.get("side") or (e.get("placement") or "").removeprefix("foot_")


def _session_status(statuses: dict, n_strides: dict) -> str:
    """ok (strides on both feet) | partial (one foot) | no_strides | no_stance | missing_sensor | no_walking_trial."""
    if not any(statuses.values()):
        return "no_walking_trial"
    if all(n_strides[s] > 0 for s in SIDES):
        return "ok"
    if any(n_strides[s] > 0 for s in SIDES):
        return "partial"
    flat = [x for v in statuses.values() for x in v]
    for st in ("no_strides", "no_stance", "too_short", "missing_sensor"):
        if st in flat:
            return st
    return "no_strides"


STAGE = Stage(name="gait", version="5", needs=(), tables=TABLES, session_kinds=("lab",), compute=compute,
              default_params=default_params)
