"""Table rows of the gait stage (:mod:`stridelab.pipeline.stages.gait`): estimator results -> catalog rows and the foot
trajectory series. No estimation here; the only arithmetic is int64 ns <-> sample index (STYLE.md §4)."""
from __future__ import annotations

import numpy as np
import pyarrow as pa

SIDES = ("left", "right")


def num(x) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def foot_rows(sid: str, rec: dict, placement: str, side: str, t_ns: np.ndarray, fk) -> dict:
    """``gait_events`` and ``strides`` rows of one foot segment (events and strides in ns)."""
    from stridelab.estimators.gait import PARAM_COLUMNS
    h, trial = rec["content_hash"], rec["trial"]
    ev = [{"session_id": sid, "content_hash": h, "trial": trial, "placement": placement, "side": side,
           "type": typ, "t_ns": int(t_ns[int(i)])} for typ, idx in (("IC", fk.events.ic_idx), ("TC", fk.events.tc_idx))
          for i in idx]
    st = fk.strides
    strides = []
    for k in range(len(st)):
        a, b, tc, ic, pre = (int(x) for x in st.idx[k])
        v = dict(zip(PARAM_COLUMNS, st.values[k]))
        strides.append({"session_id": sid, "content_hash": h, "trial": trial, "placement": placement, "side": side,
                        "start_ns": int(t_ns[a]), "end_ns": int(t_ns[b]), "tc_ns": int(t_ns[tc]),
                        "ic_ns": int(t_ns[ic]), "pre_ic_ns": int(t_ns[pre]) if pre >= 0 else None,
                        "stride_time_s": num(v["stride_time_s"]), "stance_pct": num(v["stance_pct"]),
                        "swing_pct": num(v["swing_pct"]), "stance_time_s": num(v["stance_time_s"]),
                        "swing_time_s": num(v["swing_time_s"]), "stride_length_m": num(v["stride_length_m"]),
                        "speed_m_s": num(v["gait_speed_m_s"]), "clearance_m": num(v["clearance_m"]),
                        "turning_deg": num(v["turning_angle_deg"]), "stride_length_ref_m": None,
                        "status": "ok"})
    return {"gait_events": ev, "strides": strides}


def trajectory_table(t_ns: np.ndarray, trajs: list[tuple[int, int, object]], ds: list | None) -> pa.Table:
    """The foot trajectory series (``t_ns, px, py, pz, vx, vy, vz, stance`` [+ ``pz_floor, range_used_a/b``]) from
    the segments' ``TrajectoryResult`` (``(a, b, result)``; ``stance`` = the trajectory's zero-velocity samples)."""
    n = len(t_ns)
    pos, vel = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    stance = np.zeros(n, bool)
    for a, b, tr in trajs:
        pos[a:b], vel[a:b], stance[a:b] = tr.pos, tr.vel, tr.zupt
    cols = {"t_ns": t_ns, "px": pos[:, 0], "py": pos[:, 1], "pz": pos[:, 2], "vx": vel[:, 0], "vy": vel[:, 1],
            "vz": vel[:, 2], "stance": stance}
    if ds is not None:
        hz, used = np.full(n, np.nan), np.zeros((n, 2), bool)
        for a, b, r in ds:
            hz[a:b], used[a:b] = r.pos[:, 2], r.range_used
        cols.update({"pz_floor": hz, "range_used_a": used[:, 0], "range_used_b": used[:, 1]})
    return pa.table(cols)


def summary_rows(sid: str, sess, n_strides: dict, status: str, note: str) -> list[dict]:
    """gait_summary rows (left, right, both) of a :class:`SessionGait`; symmetry indices on the 'both' row."""
    names = {"cadence_steps_min": "cadence_steps_min", "speed_m_s": "gait_speed_m_s",
             "stride_length_m": "stride_length_m", "stride_time_s": "stride_time_s", "stance_pct": "stance_pct",
             "swing_pct": "swing_pct", "clearance_m": "clearance_m", "double_support_pct": "double_support_pct"}
    both = dict(sess.pooled, cadence_steps_min=sess.cadence_steps_min, double_support_pct=sess.double_support_pct)
    rows = []
    for side, vals in (("left", sess.per_foot["left"]), ("right", sess.per_foot["right"]), ("both", both)):
        row = {"session_id": sid, "side": side, **{col: num(vals.get(k, np.nan)) for col, k in names.items()},
               "n_strides": int(sum(n_strides.values()) if side == "both" else n_strides[side]),
               "status": status, "note": note or None}
        for k, v in sess.symmetry_index_pct.items():
            col = f"si_{k.removesuffix('_m').removesuffix('_s').removesuffix('_pct')}_pct"
            row[col] = num(v) if side == "both" else None
        rows.append(row)
    return rows


def session_status(statuses: dict, n_strides: dict) -> str:
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
