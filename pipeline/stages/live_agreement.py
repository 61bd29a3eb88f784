"""Live outputs beside the nightly's: how a `stridelab live` session's computations agree with the offline ones.

Runs on sessions holding a live recording (``live_outputs`` rows, stored by the ingest: :mod:`stridelab.pipeline.live.stored`).
The live angles and events are compared with two offline computations on the same raw samples (the warehouse's)
and the same calibration (the one the recording carries, i.e. the one the live angles used):

* ``online_filter``: the online estimators the live session ran (its orientation filter, JCS angles minus the
  standing offsets it chose, Algorithm 1 on the foot pitch), run by the nightly over the whole recording at
  once. They are causal, so the two agree up to floating-point rounding (the magnetometer goes through tesla on
  the wire and back); anything more is a bug (a look-ahead, a dropped or reordered sample);
* ``offline_smoothed``: the nightly's own outputs: the orientation stage's offline estimator, the joint-angle
  stage's definition (offsets from the first quiet standing of the trial), the gait stage's events (ESKF +
  smoother, toe-off refinement). Their difference is the price of computing live, measured.

Per stride (live IC to the next, per side) and joint plane: max |live − each|, RMSE vs offline
(``live_agreement_strides``); per live event: the matching event of each (one-to-one, ± 0.5 s,
``stridelab.estimators.gait.evaluation.match_events``) (``live_agreement_events``); per recording: the summary
(``live_agreement``). Scorers: ``stridelab.estimators.joints.angle_errors``, ``match_events``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from stridelab.pipeline.stages._lab_read import read_recording, session_calibration
from stridelab.pipeline.stages._shape import StageContext, shaped_stage

PLANES = ("sagittal", "frontal", "transverse")
TABLES = ("live_agreement", "live_agreement_strides", "live_agreement_events")


@dataclass(frozen=True)
class LiveAgreementParams:
    """event_tolerance_s: a live event and an offline one further apart than this (s) do not match."""
    event_tolerance_s: float = 0.5


def _applies(con, session_id: str) -> bool:
    return con.execute("SELECT count(*) FROM live_outputs WHERE session_id = ?", [session_id]).fetchone()[0] > 0


def _sensor_data(ctx: StageContext, rec: dict, ori_rows: list[dict]) -> dict:
    """Raw acc/gyr/mag and offline orientation of the leg IMUs on the recording's common grid."""
    from stridelab.estimators.calibration._session import DEFAULT_PLACEMENTS
    data = read_recording(ctx, rec, ori_rows, DEFAULT_PLACEMENTS)
    data["mag"] = {}
    for p in data["acc"]:
        if "mag" not in rec["sensors"][p]:
            continue
        s = ctx.read_imu_files(rec, p, with_mag=True)
        data["mag"][p] = s.mag[np.searchsorted(s.t_ns, data["t_ns"])]
    return data


def _nearest(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Index of the grid sample nearest to each time (a live event's stamp is computed in float: ± a few 100 ns)."""
    i = np.clip(np.searchsorted(t, x), 1, max(1, len(t) - 1))
    return np.where(np.abs(t[i - 1] - x) <= np.abs(t[np.minimum(i, len(t) - 1)] - x), i - 1, i)


def _num(x) -> float | None:
    return float(x) if x is not None and np.isfinite(x) else None


def compare_recording(ctx: StageContext, rec: dict, live_rows: list[dict], params: LiveAgreementParams) -> dict:
    """The three tables' rows for one live recording."""
    from stridelab.estimators.calibration import first_quiet_standing
    from stridelab.estimators.gait import IcTcParams, detect_ic_tc, pitch_signal
    from stridelab.estimators.gait.evaluation import match_events
    from stridelab.estimators.joints import JOINTS, angle_errors, calibrated_joint_angles_deg, compute_joint_angles
    from stridelab.pipeline.live.engine import ONLINE_FILTERS
    sid, h = ctx.session_id, rec["content_hash"]
    by_kind = {r["kind"]: r for r in live_rows}
    meta = json.loads(by_kind["angles"]["meta"]) if "angles" in by_kind and by_kind["angles"]["meta"] else {}
    calmsg = meta.get("calibration") or {}
    cal = session_calibration(calmsg.get("rows") or [])
    standing_live = meta.get("standing")
    data = _sensor_data(ctx, rec, ctx.upstream.get("orientation", []))
    t, fs = data["t_ns"], data["sampling_rate_hz"]
    if fs is None or len(t) < 2:
        return {"note": f"{rec['trial']}: the IMUs share no time grid"}
    est = ONLINE_FILTERS[calmsg.get("estimator", "dcf")]
    use_mag = calmsg.get("use_magnetometer", True)
    q_on = {p: est(sampling_rate_hz=fs).update_batch(data["gyr"][p], data["acc"][p],
                                                      data["mag"].get(p) if use_mag else None).quat
            for p in data["acc"]}
    out = {t_: [] for t_ in TABLES}
    summary = out["live_agreement"]

    def add(comparison, quantity, key, metric, value, unit):
        summary.append({"session_id": sid, "content_hash": h, "comparison": comparison, "quantity": quantity,
                        "key": key, "metric": metric, "value": _num(value), "unit": unit})

    # ---- events --------------------------------------------------------------------------------------
    ev = ctx.read_table(by_kind["events"]["series_path"]).to_pylist() if "events" in by_kind else []
    tol = int(round(params.event_tolerance_s * fs))
    offline_ev = [r for r in ctx.upstream.get("gait_events", []) if r["content_hash"] == h]
    ic_live = {}
    for side in ("left", "right"):
        p = f"foot_{side}"
        if p not in q_on:
            continue
        c = cal.imus.get(p) if cal is not None else None
        u = np.asarray(c.R_sensor_af[:, 0], float) if c is not None and c.valid else np.array([1.0, 0.0, 0.0])
        on = detect_ic_tc(pitch_signal(q_on[p], u), sampling_rate_hz=fs, params=IcTcParams())
        for typ, on_idx in (("IC", on.ic_idx), ("TC", on.tc_idx)):
            live_ns = np.array(sorted(e["t_ns"] for e in ev if e["side"] == side and e["type"] == typ), np.int64)
            live_idx = _nearest(t, live_ns)
            if typ == "IC":
                ic_live[side] = live_ns
            off_ns = np.array(sorted(r["t_ns"] for r in offline_ev if r["side"] == side and r["type"] == typ),
                              np.int64)
            off_idx = _nearest(t, off_ns)
            m_on = match_events(live_idx, on_idx, tolerance_samples=tol)
            m_off = match_events(live_idx, off_idx, tolerance_samples=tol)
            pair_on = {int(a): int(b) for a, b in m_on.pairs}
            pair_off = {int(a): int(b) for a, b in m_off.pairs}
            for i, k in zip(live_ns, live_idx):
                ko, kf = pair_on.get(int(k)), pair_off.get(int(k))
                out["live_agreement_events"].append({
                    "session_id": sid, "content_hash": h, "side": side, "type": typ, "live_ns": int(i),
                    "online_ns": int(t[ko]) if ko is not None else None,
                    "offline_ns": int(t[kf]) if kf is not None else None,
                    "online_diff_ms": (k - ko) * 1000.0 / fs if ko is not None else None,
                    "offline_diff_ms": (k - kf) * 1000.0 / fs if kf is not None else None})
            key = f"{side}_{typ}"
            for comp, m, n_ref in (("online_filter", m_on, len(on_idx)), ("offline_smoothed", m_off, len(off_idx))):
                err = m.error_samples * 1000.0 / fs
                add(comp, "event", key, "n_live", len(live_idx), "count")
                add(comp, "event", key, "n_other", n_ref, "count")
                add(comp, "event", key, "matched", m.tp, "count")
                add(comp, "event", key, "mean_diff_ms", err.mean() if len(err) else None, "ms")
                add(comp, "event", key, "sd_diff_ms", err.std(ddof=1) if len(err) > 1 else None, "ms")
                add(comp, "event", key, "max_abs_diff_ms", np.abs(err).max() if len(err) else None, "ms")
    # ---- joint angles --------------------------------------------------------------------------------
    if "angles" not in by_kind or cal is None:
        return out
    la = ctx.read_table(by_kind["angles"]["series_path"])
    lt = la.column("t_ns").to_numpy()
    idx = np.searchsorted(t, lt)
    ok = (idx < len(t)) & (t[np.minimum(idx, len(t) - 1)] == lt)       # live frames with a sample on the grid
    idx, lrow = idx[ok], np.flatnonzero(ok)
    q_af = {p: c.quat_sensor_af for p, c in cal.imus.items() if c.valid}
    standing = first_quiet_standing(data["acc"], data["gyr"], sampling_rate_hz=fs, params=cal.params)
    q_off = {p: q for p, q in data["quat"].items()}
    offline = compute_joint_angles(q_off, cal, standing=standing).angles_deg if q_off else {}
    offset_from = standing_live["offset_frame"] if standing_live else None
    kcol = la.column("k").to_numpy()[lrow]
    for joint, (prox, dist) in JOINTS.items():
        for side in ("left", "right"):
            key = f"{joint}_{side}"
            pp, dd = (prox if prox == "pelvis" else f"{prox}_{side}"), f"{dist}_{side}"
            cols = [f"{key}_{pl}_deg" for pl in PLANES]
            if pp not in q_af or dd not in q_af or pp not in q_on or dd not in q_on or cols[0] not in la.column_names:
                continue
            live = np.column_stack([la.column(c).to_numpy()[lrow] for c in cols])
            on = calibrated_joint_angles_deg(q_on[pp][idx], q_on[dd][idx], q_af[pp], q_af[dd], joint=joint, side=side)
            if offset_from is not None:
                off = np.array([np.nan if v is None else v for v in standing_live["offset_deg"][key]], float)
                on[kcol >= offset_from] -= off
            d_on = live - on
            add("online_filter", "joint_angle", key, "max_abs_diff_deg", np.nanmax(np.abs(d_on)), "deg")
            off_a = offline.get(key)
            if off_a is not None:
                off_a = off_a[idx]
                e = angle_errors(off_a, live)
                for j, pl in enumerate(PLANES):
                    add("offline_smoothed", "joint_angle", key, f"rmse_deg_{pl}", e.rmse_deg[j], "deg")
                    add("offline_smoothed", "joint_angle", key, f"max_abs_diff_deg_{pl}",
                        np.nanmax(np.abs(live[:, j] - off_a[:, j])), "deg")
            ics = ic_live.get(side, np.array([], np.int64))
            for a, b in zip(ics[:-1], ics[1:]):
                sel = (lt[lrow] >= a) & (lt[lrow] < b)
                if not sel.any():
                    continue
                for j, pl in enumerate(PLANES):
                    dn = np.abs(d_on[sel, j])
                    df = np.abs(live[sel, j] - off_a[sel, j]) if off_a is not None else None
                    out["live_agreement_strides"].append({
                        "session_id": sid, "content_hash": h, "side": side, "joint": joint, "plane": pl,
                        "start_ns": int(a), "end_ns": int(b), "n_frames": int(sel.sum()),
                        "max_abs_diff_online_deg": _num(np.nanmax(dn)) if np.isfinite(dn).any() else None,
                        "max_abs_diff_offline_deg": _num(np.nanmax(df)) if df is not None and np.isfinite(df).any()
                        else None,
                        "rmse_offline_deg": _num(np.sqrt(np.nanmean(df ** 2))) if df is not None and
                        np.isfinite(df).any() else None})
    return out


def compute(ctx: StageContext, p: LiveAgreementParams) -> None:
    by_rec: dict[str, list] = {}
    for r in ctx.upstream.get("live_outputs", []):
        by_rec.setdefault(r["content_hash"], []).append(r)
    notes = []
    for rec in ctx.recordings:
        if rec["content_hash"] not in by_rec:
            continue
        res = compare_recording(ctx, rec, by_rec[rec["content_hash"]], p)
        if "note" in res:
            notes.append(res.pop("note"))
        for t_, v in res.items():
            ctx.emit(t_, v)
    if not any(ctx.rows.values()):
        return ctx.skip("no live outputs to compare" + (f" ({'; '.join(notes)})" if notes else ""))
    ctx.set_note("; ".join(notes))


STAGE = shaped_stage("live_agreement", "1", LiveAgreementParams, compute, tables=TABLES, needs=("orientation", "gait"),
                     session_kinds=("lab",), applies=_applies, reads=("live_outputs",))
