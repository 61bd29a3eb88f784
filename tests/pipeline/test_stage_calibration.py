"""Calibration and joint-angle stages: equal to the estimators on the same arrays, idempotent, QC for a
missing calibration trial, gait-cycle curves from an upstream gait_events table, the CLI end to end."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.stages import Stage, StageOutput
from stridelab.pipeline.stages import calibration as cal_stage
from stridelab.pipeline.stages import joint_angles as ja_stage
from stridelab.pipeline.stages import orientation as ori_stage
from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
from stridelab.warehouse.catalog import Warehouse, first
from stridelab.warehouse.read import connect_snapshot, read_imu, read_orientation
from stridelab.warehouse.store import read_table

from tests.pipeline._lab import df as _df
from tests.pipeline._lab import run_with, use_registry, write_lab_session

pytestmark = pytest.mark.slow

LOWER = {"pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left", "foot_right"}


def _fake_gait(inp, params):
    """Stands in for the gait stage (built elsewhere): initial contacts per foot, here from the reference."""
    return StageOutput(rows={"gait_events": [
        {"session_id": inp.session["session_id"], "side": e["side"], "type": "IC", "t_ns": e["t_ns"]}
        for e in inp.events if e["type"] == "IC"]})


GAIT = Stage(name="gait", version="1", needs=("orientation",), tables=("gait_events",),
             session_kinds=("lab", "calibration"), compute=_fake_gait, default_params=dict)


def _registry(with_gait: bool):
    if not with_gait:
        return [ori_stage.STAGE, cal_stage.STAGE,
                replace(ja_stage.STAGE, needs=tuple(n for n in ja_stage.STAGE.needs if n != "gait"))]
    return [ori_stage.STAGE, cal_stage.STAGE, GAIT, ja_stage.STAGE]


_patch = use_registry


@pytest.fixture(scope="module")
def lab_files(tmp_path_factory):
    """One simulated lab session (calibration trial + one 30-s walking trial) as MCAP files."""
    return write_lab_session(tmp_path_factory.mktemp("inbox"), distance_sensors=False, optical_reference=False)


@pytest.fixture(scope="module")
def warehouse(lab_files, tmp_path_factory):
    files, _ = lab_files
    root = tmp_path_factory.mktemp("wh") / "wh"
    mp = pytest.MonkeyPatch()
    try:
        with Warehouse.open(root) as wh:
            wh.con.execute("CREATE TABLE IF NOT EXISTS gait_events (session_id VARCHAR, side VARCHAR, type VARCHAR, t_ns BIGINT)")
        run_with(mp, root, files, _registry(with_gait=True))
    finally:
        mp.undo()
    return root


def test_calibration_rows_equal_the_estimator_on_the_same_arrays(warehouse):
    from stridelab.estimators.calibration import calibrate_session
    from stridelab.estimators.calibration._session import DEFAULT_PLACEMENTS
    rows = _df(warehouse, "SELECT * FROM calibration ORDER BY placement")
    assert set(rows["placement"]) == LOWER
    h = rows["content_hash"].iloc[0]
    con = connect_snapshot(warehouse)
    acc, gyr, quats = {}, {}, {}
    for p in DEFAULT_PLACEMENTS:
        s = read_imu(con, warehouse, h, p)
        acc[p], gyr[p] = s.acc, s.gyr
        quats[p] = read_orientation(con, warehouse, h, p)[1]
    con.close()
    cal = calibrate_session(acc, gyr, sampling_rate_hz=100.0, quats=quats,
                            params=cal_stage.calibration_params(cal_stage.CalibrationStageParams()))
    for _, r in rows.iterrows():
        c = cal.imus[r["placement"]]
        assert r["status"] == c.status and json.loads(r["reasons"]) == list(c.reasons)
        assert r["n_reps"] == c.n_cycles and r["method"] == c.method
        np.testing.assert_allclose([r["qw"], r["qx"], r["qy"], r["qz"]], c.quat_sensor_af, rtol=0, atol=1e-12)
    assert (rows["status"] != "fail").all(), rows[["placement", "status", "reasons"]]
    assert json.loads(rows["windows"].iloc[0])["source"] == "auto"


def test_joint_angles_equal_the_estimator_on_the_same_arrays(warehouse):
    from stridelab.estimators.calibration import first_quiet_standing
    from stridelab.estimators.joints import compute_joint_angles
    rows = _df(warehouse, "SELECT * FROM joint_angles ORDER BY joint, side")
    assert len(rows) == 6 and set(rows["trial"]) == {"walk-1"} and (rows["status"] != "fail").all()
    h = rows["content_hash"].iloc[0]
    con = connect_snapshot(warehouse)
    cal = ja_stage.session_calibration(
        [dict(zip([d[0] for d in con.execute("SELECT * FROM calibration").description], r))
         for r in con.execute("SELECT * FROM calibration").fetchall()])
    acc, gyr, quats = {}, {}, {}
    for p in LOWER:
        s = read_imu(con, warehouse, h, p)
        acc[p], gyr[p] = s.acc, s.gyr
        quats[p] = read_orientation(con, warehouse, h, p)[1]
    con.close()
    standing = first_quiet_standing(acc, gyr, sampling_rate_hz=100.0)
    assert standing is not None and standing[0] == 0
    ja = compute_joint_angles(quats, cal, standing=standing)
    for _, r in rows.iterrows():
        key = f"{r['joint']}_{r['side']}"
        t = read_table(warehouse, r["series_path"])
        got = np.column_stack([t.column(c).to_numpy() for c in ("sagittal_deg", "frontal_deg", "transverse_deg")])
        np.testing.assert_allclose(got, ja.angles_deg[key], rtol=0, atol=1e-9)
        np.testing.assert_allclose([r["offset_sagittal_deg"], r["offset_frontal_deg"], r["offset_transverse_deg"]],
                                   ja.offsets_deg[key], atol=1e-9)


def test_joint_angles_are_close_to_the_simulated_truth(warehouse, lab_files):
    """Sanity, not the benchmark: sagittal knee RMSE after offset removal within a few degrees."""
    from stridelab.estimators.joints import remove_standing_offset
    truth = lab_files[1][1]
    rows = _df(warehouse, "SELECT * FROM joint_angles WHERE joint = 'knee'")
    for _, r in rows.iterrows():
        est = read_table(warehouse, r["series_path"]).column("sagittal_deg").to_numpy()
        ref, _ = remove_standing_offset(truth.joint_angles_deg[f"knee_{r['side']}"], (0, 200))
        rmse = float(np.sqrt(np.nanmean((est - ref[:, 0]) ** 2)))
        assert rmse < 5.0, (r["side"], rmse)


def test_gait_cycle_curves_and_rom_from_upstream_contacts(warehouse):
    curves = _df(warehouse, "SELECT * FROM joint_angle_curves")
    assert set(curves["pct"]) == set(range(101))
    assert set(zip(curves["joint"], curves["side"])) == {(j, s) for j in ("hip", "knee", "ankle")
                                                         for s in ("left", "right")}
    assert set(curves["plane"]) == {"sagittal", "frontal", "transverse"}
    assert (curves["n_cycles"] >= 5).all()
    rom = _df(warehouse, "SELECT * FROM joint_rom WHERE plane = 'sagittal' AND joint = 'knee'")
    assert len(rom) == 2 and (rom["rom_deg"].between(40, 80)).all(), rom


def test_a_second_run_changes_nothing(warehouse, lab_files, monkeypatch):
    tables = ("calibration", "joint_angles", "joint_angle_curves", "joint_rom")
    before = {t: _df(warehouse, f"SELECT * FROM {t} ORDER BY ALL") for t in tables}
    _patch(monkeypatch, _registry(with_gait=True))
    s = runner.run(warehouse, None, files=lab_files[0])
    assert s.stage_runs == 0 and not s.failed and len(s.duplicates) == len(lab_files[0])
    for t in tables:
        after = _df(warehouse, f"SELECT * FROM {t} ORDER BY ALL")
        assert after.equals(before[t]), t


def test_a_session_without_calibration_trial_gets_the_qc_status(lab_files, tmp_path, monkeypatch):
    _patch(monkeypatch, _registry(with_gait=False))
    walk = [f for f in lab_files[0] if "calibration" not in f.name]
    s = runner.run(tmp_path / "wh", None, files=walk)
    assert not s.failed
    cal = _df(tmp_path / "wh", "SELECT * FROM calibration")
    assert set(cal["placement"]) == LOWER and (cal["status"] == "fail").all()
    assert all(json.loads(r) == ["calibration trial missing"] for r in cal["reasons"])
    assert cal["qw"].isna().all()
    ja = _df(tmp_path / "wh", "SELECT * FROM joint_angles")
    assert len(ja) == 6 and (ja["status"] == "fail").all()
    for p in ja["series_path"]:                         # marked and not produced: no numbers without calibration
        assert np.isnan(read_table(tmp_path / "wh", p).column("sagittal_deg").to_numpy()).all()
    assert _df(tmp_path / "wh", "SELECT count(*) AS n FROM joint_angle_curves")["n"][0] == 0
    note = _df(tmp_path / "wh", "SELECT note FROM stage_runs WHERE stage = 'calibration'")["note"][0]
    assert note == "calibration trial missing"


def test_manual_windows_from_the_manifest_override_detection(warehouse, lab_files):
    truth = lab_files[1][0]
    w = {lab: (a, b) for lab, a, b, side in truth.windows if side is None}
    fe = {side: [a, b] for lab, a, b, side in truth.windows if side is not None}
    params = dict(cal_stage.STAGE.default_params(), windows={"standing": list(w["quiet_standing"]), "hip_fe": fe,
                                                         "walking": list(w["straight_walking"])})
    with Warehouse.open(warehouse) as wh:
        sid = first(wh.con.execute("SELECT session_id FROM sessions"))[0]
        inp = runner._session_inputs(wh, sid, cal_stage.STAGE)
    out = cal_stage.STAGE.compute(inp, params)
    rows = out.rows["calibration"]
    win = json.loads(rows[0]["windows"])
    assert win["source"] == "manual" and win["standing"] == [0.0, 4.0]
    assert {r["placement"] for r in rows} == LOWER and all(r["status"] != "fail" for r in rows)


@pytest.mark.slow
def test_cli_simulate_then_run_gives_calibration_and_joint_angles(cli_study):
    """``stridelab simulate`` then ``stridelab run`` (tests/pipeline/conftest.py): calibration of every lower-limb
    placement and the joint angles of every lab visit's walking trials."""
    wh = cli_study["root"] / "wh"
    cal = _df(wh, "SELECT placement, status FROM calibration")
    assert set(cal["placement"]) == LOWER and set(cal["status"]) <= {"pass", "warn", "fail"}
    ja = _df(wh, "SELECT joint, side, status, series_path FROM joint_angles")
    # per lab visit of the programme: two walking trials × hip/knee/ankle × left/right
    assert len(ja) == load_manifest(DEFAULT_MANIFEST).visits * 2 * 6
    assert set(ja["status"]) <= {"pass", "warn"}
