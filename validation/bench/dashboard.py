"""``stridelab bench dashboard``: page render times (cold and warm cache) and report build time.

Measured on the demo warehouse (``--demo-warehouse``, e.g. the one ``stridelab demo --no-serve``
leaves; when absent, a synthetic 4-participant warehouse is built) and on a synthetic
100-participant warehouse. Pages are rendered server-side by Streamlit's AppTest (the script run
that a browser session triggers); targets: < 2 s per page on the demo warehouse, < 3 s with 100
participants, < 5 s per report (HTML + PDF).

The synthetic warehouse has the catalog of a real study (participants, sessions, recordings,
sensors, run ledger) plus results of the later stages in the tables the dashboard reads
(``stridelab.warehouse.queries.DATASETS``): strides, calibration QC, joint-angle cycles, activity bouts,
accuracy metrics and pairs, foot trajectories. It is written through :class:`Warehouse`, the
pipeline's writer, and published as a snapshot like a nightly run.
"""
from __future__ import annotations

import json
import tempfile
import time
import uuid
from datetime import datetime, timedelta, timezone
from pathlib import Path
from zoneinfo import ZoneInfo

import click
import numpy as np
import pyarrow as pa

from stridelab.pipeline.console import UserError, emit_json, err_console, progress

DAY_NS = 86_400 * 10**9
T0 = datetime(2026, 3, 2, 7, 0, tzinfo=timezone.utc)
PAGES = ("overview", "accuracy", "participant", "activity", "runs")

#: the result tables a stage would create (only where the warehouse has none yet)
#: stage output tables written by :func:`add_synthetic_results`: the migrations' own tables (warehouse/migrations)
RESULT_TABLES = ("strides", "gait_summary", "calibration", "joint_angle_curves", "activity_bouts", "accuracy_metrics",
                 "accuracy_pairs", "foot_trajectories")


def _ns(dt: datetime) -> int:
    return int(dt.timestamp()) * 10**9


def _insert(wh, table: str, rows: list[dict]) -> None:
    """Insert by column name into a table the migrations define; a column the table lacks is an error."""
    if not rows:
        return
    have = {r[0] for r in wh.con.execute("SELECT column_name FROM information_schema.columns WHERE table_name = ?",
                                         [table]).fetchall()}
    extra = sorted({k for r in rows for k in r} - have)
    if extra:
        raise ValueError(f"{table} has no column(s) {extra} (warehouse/migrations)")
    wh.insert(table, pa.Table.from_pylist(rows))


def _knee_curve(pct: np.ndarray, amp: float) -> np.ndarray:
    return 5 + 12 * np.exp(-((pct - 15) / 8) ** 2) + amp * np.exp(-((pct - 72) / 11) ** 2)


def _gait_summary_rows(sid: str, per_side: dict) -> list[dict]:
    """``gait_summary`` rows (left, right, both) of synthetic strides, as the gait stage's table holds them."""
    out, means = [], {}
    for side, st in list(per_side.items()) + [("both", [r for v in per_side.values() for r in v])]:
        m = {k: float(np.mean([r[k] for r in st])) for k in ("stride_time_s", "stride_length_m", "stance_pct",
                                                           "speed_m_s", "clearance_m")}
        means[side] = m
        row = {"session_id": sid, "side": side, "cadence_steps_min": 120.0 / m["stride_time_s"],
               "speed_m_s": m["speed_m_s"], "stride_length_m": m["stride_length_m"],
               "stride_time_s": m["stride_time_s"], "stance_pct": m["stance_pct"], "swing_pct": 100 - m["stance_pct"],
               "clearance_m": m["clearance_m"], "n_strides": len(st), "status": "ok"}
        if side == "both":
            l, r = means["left"], means["right"]
            for k, col in (("stride_length_m", "si_stride_length_pct"), ("stride_time_s", "si_stride_time_pct"),
                           ("stance_pct", "si_stance_pct"), ("clearance_m", "si_clearance_pct")):
                row[col] = 200.0 * abs(l[k] - r[k]) / (l[k] + r[k])
        out.append(row)
    return out


def add_synthetic_results(wh, sessions: list[dict], seed: int = 0, with_trajectories: bool = True) -> None:
    """Write plausible stage results for ``sessions`` (dicts of the ``sessions`` table) into ``wh``.

    Lab sessions get strides, calibration QC, joint-angle cycles, accuracy metrics/pairs, foot
    trajectories; free-living sessions get activity bouts with matching reference labels.
    """
    from stridelab.warehouse.store import series_relpath, write_table
    rng = np.random.default_rng(seed)
    rows: dict[str, list[dict]] = {t: [] for t in RESULT_TABLES}
    ref_events: list[dict] = []
    pct = np.arange(0, 101, 2)
    for s in sessions:
        sid, t0 = s["session_id"], s["start_ns"]
        paretic = str(s["participant_id"]).endswith(("2", "6"))     # some participants walk asymmetrically
        if s["kind"] == "lab":
            speed = rng.normal(1.2, 0.1) * (0.7 if paretic else 1.0)
            per_side = {}
            for side in ("left", "right"):
                t = t0 + int(5e9)
                asym = 1.12 if (paretic and side == "left") else 1.0
                first = len(rows["strides"])
                for k in range(40):
                    st_s = rng.normal(1.1, 0.03) * (1.0 if not paretic else 1.15)
                    sl = speed * st_s / asym + rng.normal(0, 0.02)
                    rows["strides"].append({"session_id": sid, "placement": f"foot_{side}", "side": side, "ic_ns": t,
                                            "tc_ns": t + int(0.62 * st_s * 1e9), "stride_time_s": st_s,
                                            "stance_pct": rng.normal(61, 1.5) * asym, "stride_length_m": sl,
                                            "speed_m_s": sl / st_s, "clearance_m": abs(rng.normal(0.12, 0.01)),
                                            "turning_deg": rng.normal(0, 2), "stride_length_ref_m": sl + rng.normal(0.004, 0.015)})
                    rows["accuracy_pairs"].append({"session_id": sid, "stage": "gait_events", "estimator": "thesis_icd",
                                                   "placement": f"foot_{side}", "quantity": "IC", "unit": "s",
                                                   "estimate": t / 1e9 + rng.normal(0.005, 0.012), "reference": t / 1e9})
                    t += int(st_s * 1e9)
                per_side[side] = rows["strides"][first:]
            rows["gait_summary"] += _gait_summary_rows(sid, per_side)
            for pl in ("pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left", "foot_right"):
                bad = rng.random() < 0.05 or (paretic and pl == "shank_left")    # a paretic leg's FE is less planar
                rows["calibration"].append({"session_id": sid, "placement": pl, "status": "warn" if bad else "pass",
                                            "reasons": json.dumps(["planarity 0.71 < 0.85"] if bad else []),
                                            "method": "hip_fe", "n_reps": 10})
            for joint, amp in (("hip", 40), ("knee", 58), ("ankle", 25)):
                for side in ("left", "right"):
                    a = amp * (0.75 if paretic and side == "left" else 1.0)
                    for plane, scale in (("sagittal", 1.0), ("frontal", 0.15), ("transverse", 0.1)):
                        mean = _knee_curve(pct, a) * scale if joint == "knee" else \
                            scale * (a / 2 * np.cos(2 * np.pi * (pct - (0 if joint == "hip" else 60)) / 100))
                        rows["joint_angle_curves"] += [{"session_id": sid, "joint": joint, "side": side, "plane": plane,
                                                        "pct": int(p), "mean_deg": float(m), "n_cycles": 10,
                                                        "sd_deg": 2.5 + 2 * scale} for p, m in zip(pct, mean)]
                    rom = float(np.ptp(_knee_curve(pct, a))) if joint == "knee" else a
                    rows["accuracy_pairs"].append({"session_id": sid, "stage": "joint_angles", "estimator": "jcs",
                                                   "placement": f"{joint}_{side}", "quantity": f"{joint}_rom_deg",
                                                   "unit": "deg", "estimate": rom + rng.normal(0.5, 1.5), "reference": rom})
            for est, base in (("yun_fqa_cf", 2.5), ("madgwick", 3.2), ("vqf", 1.8)):
                for pl in ("foot_left", "shank_left", "thigh_left", "pelvis"):
                    rows["accuracy_metrics"].append({"session_id": sid, "stage": "orientation", "estimator": est,
                                                     "placement": pl, "metric": "rmse_deg", "unit": "deg",
                                                     "value": abs(rng.normal(base, 0.5))})
            for m, v, u in (("stride_length_mae_m", 0.015, "m"), ("ic_timing_mae_ms", 12, "ms"), ("tc_timing_mae_ms", 16, "ms")):
                rows["accuracy_metrics"].append({"session_id": sid, "stage": "strides" if "stride" in m else "gait_events",
                                                 "estimator": "zupt_eskf" if "stride" in m else "thesis_icd",
                                                 "placement": "both", "metric": m, "unit": u, "value": abs(rng.normal(v, v / 5))})
            rows["accuracy_metrics"].append({"session_id": sid, "stage": "calibration", "estimator": "thesis_pca",
                                             "placement": "thigh_left", "metric": "helical_error_deg", "unit": "deg",
                                             "value": abs(rng.normal(1.5, 0.4))})
            if with_trajectories:
                for side in ("left", "right"):
                    n = 600
                    x = np.linspace(0, 10, n)
                    y = (0.1 if side == "left" else -0.1) + 0.01 * np.sin(x)
                    z = np.clip(0.12 * np.sin(np.pi * x / 1.3) ** 8, 0, None)
                    rel = series_relpath(s["study"], s["participant_id"], sid, f"foot_{side}",
                                         f"trajectory-{uuid.uuid5(uuid.NAMESPACE_URL, sid).hex[:12]}")
                    write_table(wh.root, rel, pa.table({"t_ns": t0 + np.arange(n, dtype=np.int64) * 10**7,
                                                        "px": x, "py": y, "pz": z}))
                    rows["foot_trajectories"].append({"session_id": sid, "placement": f"foot_{side}", "series_path": rel})
        elif s["kind"] == "free_living":
            tz = ZoneInfo(s.get("timezone") or "UTC")
            t = s["start_ns"]
            end = s["end_ns"]
            while t < end:
                local = datetime.fromtimestamp(t / 1e9, tz)
                if local.hour >= 23 or local.hour < 7:
                    cls, dur = "lying", 3600 * rng.uniform(0.5, 2)
                else:
                    cls = rng.choice(["sitting", "standing", "level_walking", "stairs_up", "stairs_down", "non_wear"],
                                     p=[0.45, 0.2, 0.25, 0.04, 0.04, 0.02])
                    dur = {"sitting": 1800, "standing": 300, "level_walking": 400, "stairs_up": 40, "stairs_down": 40,
                           "non_wear": 1200}[cls] * rng.uniform(0.3, 1.7)
                b_end = min(end, t + int(dur * 1e9))
                steps = int((b_end - t) / 1e9 * rng.uniform(1.6, 1.9)) if cls in ("level_walking", "stairs_up", "stairs_down") else 0
                rows["activity_bouts"].append({"session_id": sid, "start_ns": t, "end_ns": b_end, "class": str(cls),
                                               "steps": steps})
                ref = cls if rng.random() > 0.08 else ("standing" if cls == "sitting" else "sitting")
                ref_events.append({"content_hash": s.get("content_hash", sid), "session_id": sid, "t_ns": t,
                                   "end_ns": b_end, "type": "activity", "label": str(ref)})
                t = b_end
    sids = [s["session_id"] for s in sessions]
    for t, r in rows.items():             # the synthetic results replace what real stages wrote for these sessions
        wh.con.execute(f"DELETE FROM {t} WHERE list_contains(?::VARCHAR[], session_id)", [sids])
        _insert(wh, t, r)
    _insert(wh, "reference_events", ref_events)


def build_synthetic_warehouse(root: Path, participants: int = 100, seed: int = 0, lab_sessions: int = 3,
                              free_living_days: int = 7, study: str = "synthetic", on_step=lambda m: None) -> Path:
    """A complete synthetic warehouse (catalog + stage results + run ledger), published as a snapshot."""
    from stridelab.warehouse.catalog import Warehouse
    rng = np.random.default_rng(seed)
    root = Path(root)
    with Warehouse.open(root) as wh:
        with wh.transaction():
            sessions, recs, sensors, runs, stage_runs, issues = [], [], [], [], [], []
            for i in range(participants):
                pid = f"P{i + 1:03d}"
                for k in range(lab_sessions):
                    start = T0 + timedelta(days=7 * k + i % 5, hours=i % 6)
                    sid = f"{study}-{pid}-lab{k + 1}"
                    sessions.append({"session_id": sid, "study": study, "participant_id": pid, "kind": "lab",
                                     "protocol": "10m-walk", "timezone": "Europe/Zurich", "start_ns": _ns(start),
                                     "end_ns": _ns(start + timedelta(minutes=40))})
                    for trial in ("calibration", "walk-1", "walk-2"):
                        h = uuid.uuid5(uuid.NAMESPACE_URL, f"{sid}/{trial}").hex * 2
                        recs.append({"content_hash": h, "file_name": f"{pid}_{sid}_{trial}.mcap", "status": "ingested",
                                     "session_id": sid, "trial": trial, "start_ns": _ns(start),
                                     "end_ns": _ns(start + timedelta(minutes=2)), "n_samples": 7 * 12000,
                                     "ingested_at": datetime(2026, 4, 1)})
                        for pl in ("pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left",
                                   "foot_right"):
                            sensors.append({"content_hash": h, "topic": f"/imu/{pl}", "placement": pl, "kind": "imu",
                                            "n_samples": 12000, "sampling_rate_hz": 100.0, "start_ns": _ns(start),
                                            "end_ns": _ns(start + timedelta(minutes=2)),
                                            "series_path": f"series/missing/{h[:8]}-{pl}.parquet"})
                fl_start = (T0 + timedelta(days=1 + i % 5)).replace(hour=7)
                sid = f"{study}-{pid}-home"
                sessions.append({"session_id": sid, "study": study, "participant_id": pid, "kind": "free_living",
                                 "protocol": "free-living", "timezone": "Europe/Zurich", "start_ns": _ns(fl_start),
                                 "end_ns": _ns(fl_start + timedelta(days=free_living_days))})
                h = uuid.uuid5(uuid.NAMESPACE_URL, sid).hex * 2
                recs.append({"content_hash": h, "file_name": f"{pid}_home.mcap", "status": "ingested", "session_id": sid,
                             "trial": "free-living", "start_ns": _ns(fl_start),
                             "end_ns": _ns(fl_start + timedelta(days=free_living_days)),
                             "n_samples": 8_640_000 * free_living_days, "ingested_at": datetime(2026, 4, 1)})
                if rng.random() < 0.1:
                    issues.append({"content_hash": h, "severity": "warning", "topic": "/imu/chest",
                                   "message": "gap of 612.0 s at 2026-03-05T14:03:11Z"})
            for j in range(max(1, participants // 20)):
                recs.append({"content_hash": uuid.uuid4().hex * 2, "file_name": f"broken_{j}.mcap", "status": "quarantined",
                             "reason": "truncated MCAP: chunk at byte 4096 ends after the file end",
                             "ingested_at": datetime(2026, 4, 1)})
            for n in range(14):
                rid = f"2026040{1 + n // 10}T0{n % 10}0000Z-{n:06x}"
                started = datetime(2026, 4, 1, 2) + timedelta(days=n)
                runs.append({"run_id": rid, "command": "run", "started_at": started,
                             "finished_at": started + timedelta(seconds=float(rng.uniform(60, 600))),
                             "status": "failed" if n == 5 else "ok", "jobs": 2, "n_ingested": int(rng.integers(0, 20)),
                             "n_quarantined": 0, "n_stage_runs": len(sessions), "n_failed": 1 if n == 5 else 0,
                             "version": "0.1.0", "host": "bench", "pid": 1000 + n})
            for s in sessions:
                for stage in ("orientation", "calibration", "gait", "joint_angles", "activity", "accuracy"):
                    fail = stage == "gait" and s["session_id"].endswith("lab2") and s["participant_id"] == "P002"
                    stage_runs.append({"run_id": runs[-1]["run_id"], "session_id": s["session_id"], "stage": stage,
                                       "stage_version": "1", "status": "failed" if fail else "ok",
                                       "started_at": runs[-1]["started_at"], "duration_s": float(rng.uniform(0.1, 3)),
                                       "error": "ValueError: no stance phase detected (gait.py:88)" if fail else None})
            participants_rows = [{"study": study, "participant_id": f"P{i + 1:03d}"} for i in range(participants)]
            for t, r in (("participants", participants_rows), ("sessions", sessions), ("recordings", recs),
                         ("sensors", sensors), ("recording_issues", issues), ("pipeline_runs", runs),
                         ("stage_runs", stage_runs)):
                _insert(wh, t, r)
            on_step(f"catalog: {participants} participants, {len(sessions)} sessions")
            rec_of = {r["session_id"]: r["content_hash"] for r in recs if r.get("session_id")}
            add_synthetic_results(wh, [dict(s, content_hash=rec_of[s["session_id"]]) for s in sessions], seed=seed)
        wh.publish_snapshot()
    return root


# ---- timing ---------------------------------------------------------------------------------

def time_pages(root: Path, repeats: int = 2, timeout: float = 60.0) -> dict[str, dict]:
    """Render every page with AppTest (fresh caches first, then warm); seconds per page."""
    import os
    import streamlit as st
    from streamlit.logger import set_log_level
    from streamlit.testing.v1 import AppTest
    set_log_level("error")            # AppTest outside a server warns about a missing runtime on every run
    app = Path(__file__).resolve().parents[2] / "dashboard" / "app.py"
    old = os.environ.get("STRIDELAB_WAREHOUSE")
    os.environ["STRIDELAB_WAREHOUSE"] = str(root)
    out = {}
    try:
        st.cache_data.clear()
        st.cache_resource.clear()
        for page in PAGES:
            times = []
            at = AppTest.from_file(str(app), default_timeout=timeout)
            for k in range(repeats):
                t0 = time.perf_counter()
                if k == 0:
                    at.run()
                    if page != "overview":
                        at.switch_page(f"views/{page}.py")
                        t0 = time.perf_counter()
                        at.run()
                else:
                    at.run()
                times.append(time.perf_counter() - t0)
                if at.exception:
                    raise RuntimeError(f"page {page} raised: {at.exception[0].value}")
            out[page] = {"cold_s": round(times[0], 3), "warm_s": round(min(times[1:]) if len(times) > 1 else times[0], 3)}
    finally:
        if old is None:
            os.environ.pop("STRIDELAB_WAREHOUSE", None)
        else:
            os.environ["STRIDELAB_WAREHOUSE"] = old
    return out


def time_report(root: Path, out_dir: Path) -> dict:
    from stridelab.reports.participant import build_report
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(root)
    try:
        pid, study = con.execute("SELECT participant_id, study FROM sessions GROUP BY ALL "
                                 "ORDER BY count(*) DESC, participant_id LIMIT 1").fetchall()[0]
    finally:
        con.close()
    t0 = time.perf_counter()
    paths = build_report(root, pid, out_dir, study=study)
    return {"participant": pid, "seconds": round(time.perf_counter() - t0, 3),
            "pdf_kb": round(Path(paths["pdf"]).stat().st_size / 1024, 1),
            "html_kb": round(Path(paths["html"]).stat().st_size / 1024, 1)}


@click.command("dashboard")
@click.option("--demo-warehouse", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Warehouse of the demo study [default: $STRIDELAB_HOME/warehouse if it has a snapshot, "
                   "else a synthetic 4-participant warehouse].")
@click.option("--participants", "-n", type=click.IntRange(1, 10000), default=100, show_default=True,
              help="Size of the synthetic large warehouse.")
@click.option("--repeats", type=click.IntRange(2, 20), default=3, show_default=True,
              help="Renders per page (the first with cold caches).")
@click.option("--workdir", type=click.Path(file_okay=False, path_type=Path), default=None)
@click.option("--json", "as_json", is_flag=True, help="Print the timings as JSON.")
def command(demo_warehouse, participants, repeats, workdir, as_json) -> None:
    """Dashboard page render times and report build time (targets: < 2 s demo, < 3 s 100 participants, report < 5 s).

    \b
    Examples:
      stridelab bench dashboard --json
      stridelab bench dashboard --demo-warehouse stridelab-home/warehouse -n 100
    """
    from stridelab.pipeline.config import default_warehouse
    from stridelab.warehouse.read import latest_snapshot
    if demo_warehouse is not None and latest_snapshot(demo_warehouse) is None:
        raise UserError(f"{demo_warehouse} has no published snapshot; run `stridelab demo --no-serve` first")
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tmp = Path(tmp)
        targets = {}
        demo = demo_warehouse
        demo_kind = "given"
        if demo is None:
            if latest_snapshot(default_warehouse()) is not None:
                demo, demo_kind = default_warehouse(), "STRIDELAB_HOME demo"
            else:
                demo, demo_kind = build_synthetic_warehouse(tmp / "demo", participants=4, study="demo"), "synthetic 4 participants"
        with progress() as bar:
            task = bar.add_task("building the large synthetic warehouse", total=None)
            t0 = time.perf_counter()
            big = build_synthetic_warehouse(tmp / "big", participants=participants,
                                            on_step=lambda m: bar.update(task, description=m))
            build_s = time.perf_counter() - t0
        err_console.print(f"synthetic warehouse with {participants} participants built in {build_s:.1f} s")
        res = {"demo": {"warehouse": str(demo), "kind": demo_kind}, "large": {"participants": participants,
                                                                              "build_s": round(build_s, 2)}}
        for key, root, limit in (("demo", demo, 2.0), ("large", big, 3.0)):
            err_console.print(f"rendering the pages on the {key} warehouse …")
            pages = time_pages(root, repeats)
            res[key]["pages"] = pages
            res[key]["max_page_s"] = max(max(v["cold_s"], v["warm_s"]) for v in pages.values())
            res[key]["target_s"] = limit
            res[key]["within_target"] = res[key]["max_page_s"] < limit
            res[key]["report"] = time_report(root, tmp / f"reports-{key}")
            targets[key] = res[key]["within_target"] and res[key]["report"]["seconds"] < 5.0
        res["report_target_s"] = 5.0
        res["all_within_targets"] = all(targets.values())
    if as_json:
        emit_json(res)
    else:
        err_console.print_json(json.dumps(res))
