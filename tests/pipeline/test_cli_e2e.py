"""The real CLI end to end on a simulated study: simulate -> run -> every IMU has an orientation."""
from __future__ import annotations

import pytest

from tests.pipeline.test_runner import cli
from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
from stridelab.warehouse.catalog import first
from stridelab.warehouse.read import connect_snapshot


@pytest.mark.slow
def test_simulate_then_run_gives_orientation_for_every_imu(cli_study):
    # one participant (tests/pipeline/conftest.py): its two visits are two lab sessions and two chest days, run in
    # parallel like a study's (a second participant took the same paths again at twice the CPU; demo_wh of the
    # dashboard tests has two)
    files, summary = cli_study["files"], cli_study["summary"]
    visits = load_manifest(DEFAULT_MANIFEST).visits          # the demo study is a programme: each visit = lab + chest day
    assert len(files) >= 2 * visits                # per visit: lab trials + one free-living day
    assert summary["ingested"] == len(files) and not summary["quarantined"] and not summary["failed"]
    con = connect_snapshot(cli_study["root"] / "wh")
    assert first(con.execute("SELECT count(*) FROM participants"))[0] == 1
    kinds = dict(con.execute("SELECT kind, count(*) FROM sessions GROUP BY 1").fetchall())
    assert kinds == {"lab": visits, "free_living": visits}
    # orientation of every lab IMU; none of the free-living chest days (nothing reads it: opt-in per study)
    n_imu = first(con.execute("SELECT count(*) FROM sensors JOIN recordings USING (content_hash) "
                              "JOIN sessions USING (session_id) WHERE sensors.kind = 'imu' AND sessions.kind = 'lab'"))[0]
    assert n_imu == first(con.execute("SELECT count(*) FROM orientation"))[0] > 0
    placements = {p for (p,) in con.execute("SELECT DISTINCT placement FROM sensors WHERE kind = 'imu'").fetchall()}
    assert placements == {"pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left",
                          "foot_right", "chest", "lower_back"}       # the demo study wears a lower-back IMU too
    # every registered stage ran on every session it applies to, and wrote its tables
    ok = dict(con.execute("SELECT stage, count(*) FROM stage_runs WHERE status = 'ok' GROUP BY 1").fetchall())
    n = visits
    assert {k: v for k, v in ok.items() if k != "clinical"} == {"orientation": n, "gait": n, "calibration": n,
                                                               "joint_angles": n, "activity": n,
                                                               "trunk_gait": 2 * n}   # lab and home: lower_back
    done = dict(con.execute("SELECT stage, count(*) FROM stage_runs WHERE status IN ('ok', 'skipped') "
                            "GROUP BY 1").fetchall())
    assert done.get("clinical") == n                          # every lab visit: measures, or skipped with a reason
    for table in ("gait_events", "strides", "calibration", "joint_angles", "activity_bouts", "activity_daily",
                  "walking_bouts", "daily_gait_outcomes"):
        assert first(con.execute(f"SELECT count(*) FROM {table}"))[0] > 0, table
    day = con.execute("SELECT session_id, sum(end_ns - start_ns) / 1e9 FROM activity_bouts GROUP BY 1").fetchall()
    assert all(abs(sec - 360.0) < 2 for _, sec in day)       # every second of the 0.1 h recording has a class
    # the simulator's reference is in the warehouse too
    assert first(con.execute("SELECT count(*) FROM reference_events WHERE type = 'IC'"))[0] > 10
    assert first(con.execute("SELECT count(*) FROM sensors WHERE kind = 'reference_pose'"))[0] > 0
    # ... and scored: orientation against the optical segment poses (7 lab placements + chest per lab session; n lab sessions)
    acc = con.execute("SELECT placement, value FROM accuracy_metrics WHERE stage = 'orientation' "
                      "AND producer = 'orientation' AND metric = 'inclination_rmse_deg'").fetchall()
    assert len(acc) == n * 8 and all(0.0 < v < 10.0 for _, v in acc)
    assert first(con.execute("SELECT count(*) FROM accuracy_metrics WHERE producer = 'gait'"))[0] > 0
    # calibration (helical angle vs the optical mounting) and joint angles (RMSE per plane, ROM pairs)
    cal = con.execute("SELECT value FROM accuracy_metrics WHERE producer = 'calibration' "
                      "AND metric = 'calibration_error_deg'").fetchall()
    assert len(cal) == n * 7 and sorted(v for (v,) in cal)[len(cal) // 2] < 5.0
    ja = con.execute("SELECT value FROM accuracy_metrics WHERE producer = 'joint_angles' "
                     "AND metric = 'sagittal_rmse_deg'").fetchall()
    assert len(ja) == n * 6 and sorted(v for (v,) in ja)[len(ja) // 2] < 4.0
    rom = con.execute("SELECT estimate, reference FROM accuracy_pairs WHERE producer = 'joint_angles' "
                      "AND quantity = 'knee_sagittal_rom'").fetchall()
    assert rom and all(abs(e - r) < 20.0 and r > 30.0 for e, r in rom)


def test_simulate_refuses_a_bad_manifest_with_one_line(tmp_path):
    bad = tmp_path / "study.toml"
    bad.write_text("[study]\nname = 'x'\nseed = 'not a number'\n")
    r = cli("simulate", tmp_path / "inbox", "--manifest", bad)
    assert r.returncode == 2
    assert r.stderr.strip().startswith("error:") and len(r.stderr.strip().splitlines()) == 1
