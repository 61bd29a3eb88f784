"""Gait stage: equal to the estimators on the same arrays, idempotent, clear status on bad input, accuracy rows
against the simulator's reference events, and the CLI end to end."""
from __future__ import annotations


import numpy as np
import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.stages import gait as gait_stage
from stridelab.pipeline.stages import orientation as ori_stage
from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
from stridelab.warehouse.catalog import Warehouse
from stridelab.warehouse.read import connect_snapshot, read_imu
from stridelab.warehouse.store import read_table

from tests.pipeline._lab import df as _df
from tests.pipeline._lab import run_with, use_registry, write_lab_session

pytestmark = pytest.mark.slow


def _registry():
    return [ori_stage.STAGE, gait_stage.STAGE]


def _patch(mp):
    use_registry(mp, _registry())


@pytest.fixture(scope="module")
def lab_files(tmp_path_factory):
    """One simulated lab session (calibration trial + one 30-s walking trial with distance sensors)."""
    return write_lab_session(tmp_path_factory.mktemp("inbox"), distance_sensors=True, optical_reference=True)


@pytest.fixture(scope="module")
def warehouse(lab_files, tmp_path_factory):
    files, _ = lab_files
    root = tmp_path_factory.mktemp("wh") / "wh"
    mp = pytest.MonkeyPatch()
    try:
        run_with(mp, root, files, _registry())
    finally:
        mp.undo()
    return root


def test_rows_equal_the_estimator_on_the_same_arrays(warehouse):
    from stridelab.estimators.gait import foot_kinematics, foot_params_from_dict, foot_trajectory
    params = gait_stage.STAGE.default_params()
    traj = _df(warehouse, "SELECT * FROM foot_trajectories ORDER BY placement")
    assert list(traj["placement"]) == ["foot_left", "foot_right"] and set(traj["trial"]) == {"walk-1"}
    con = connect_snapshot(warehouse)
    try:
        for _, r in traj.iterrows():
            s = read_imu(con, warehouse, r["content_hash"], r["placement"])
            fp = foot_params_from_dict(params["foot"])
            fk = foot_kinematics(s.gyr, s.acc, sampling_rate_hz=s.sampling_rate_hz, params=fp)
            tr = foot_trajectory(s.gyr, s.acc, fk, sampling_rate_hz=s.sampling_rate_hz, params=fp)   # K4
            t = read_table(warehouse, r["series_path"])
            got = np.column_stack([t.column(c).to_numpy() for c in ("px", "py", "pz", "vx", "vy", "vz")])
            np.testing.assert_array_equal(got, np.hstack([tr.pos, tr.vel]))
            np.testing.assert_array_equal(t.column("stance").to_numpy(), tr.zupt)
            np.testing.assert_array_equal(t.column("t_ns").to_numpy(), s.t_ns)
            for typ, idx in (("IC", fk.events.ic_idx), ("TC", fk.events.tc_idx)):
                ev = [x for (x,) in con.execute("SELECT t_ns FROM gait_events WHERE placement = ? AND type = ? "
                                                "ORDER BY t_ns", [r["placement"], typ]).fetchall()]
                assert ev == list(s.t_ns[idx])
            st = con.execute("SELECT start_ns, end_ns, tc_ns, ic_ns, stride_length_m, stride_time_s, clearance_m "
                             "FROM strides WHERE placement = ? ORDER BY start_ns", [r["placement"]]).fetchall()
            assert len(st) == len(fk.strides) > 10
            got = np.array(st, dtype=float)
            np.testing.assert_array_equal(got[:, :4], s.t_ns[fk.strides.idx[:, :4]].astype(float))
            np.testing.assert_allclose(got[:, 4:], np.column_stack([fk.strides.column(c) for c in (
                "stride_length_m", "stride_time_s", "clearance_m")]), rtol=0, atol=1e-12, equal_nan=True)
    finally:
        con.close()


def test_summary_and_accuracy_against_the_simulated_reference(warehouse):
    summ = _df(warehouse, "SELECT * FROM gait_summary ORDER BY side").set_index("side")
    assert list(summ.index) == ["both", "left", "right"] and set(summ["status"]) == {"ok"}
    both = summ.loc["both"]
    assert 80 < both["cadence_steps_min"] < 140 and 0.6 < both["speed_m_s"] < 1.8
    assert np.isfinite(both["si_stride_length_pct"]) and both["double_support_pct"] > 0
    assert both["n_strides"] == summ.loc["left", "n_strides"] + summ.loc["right", "n_strides"]
    acc = _df(warehouse, "SELECT * FROM accuracy_metrics")
    m = {(r.placement, r.metric): r.value for r in acc.itertuples()}
    for typ in ("ic", "tc"):
        assert m[("both", f"{typ}_sensitivity")] > 0.9 and m[("both", f"{typ}_precision")] > 0.9
        assert m[("both", f"{typ}_timing_mae_ms")] < 150       # sanity; see docs/gait.md for the measured figure
    assert m[("both", "stride_length_mae_m")] < 0.1
    pairs = _df(warehouse, "SELECT * FROM accuracy_pairs")
    assert set(pairs["quantity"]) == {"IC", "TC"} and len(pairs) > 40
    ref = _df(warehouse, "SELECT count(*) AS n FROM strides WHERE stride_length_ref_m IS NOT NULL")
    assert ref["n"][0] > 10


def test_a_second_run_changes_nothing(warehouse, lab_files):
    mp = pytest.MonkeyPatch()
    try:
        _patch(mp)
        with Warehouse.open(warehouse) as wh:
            before = wh.fingerprint()
        s = runner.run(warehouse, None, files=lab_files[0])
        assert s.stage_runs == 0 and not s.failed and s.skipped_fresh >= 2
        with Warehouse.open(warehouse) as wh:
            assert wh.fingerprint() == before
            # forcing the stage to recompute gives identical rows and files
            wh.con.execute("DELETE FROM stage_state WHERE stage = 'gait'")
        s = runner.run(warehouse, None, files=lab_files[0])
        assert s.stage_runs == 1 and not s.failed
        with Warehouse.open(warehouse) as wh:
            assert wh.fingerprint() == before
    finally:
        mp.undo()


def _session(sid="S-1", kind="lab"):
    return {"session_id": sid, "study": "t", "participant_id": "P1", "kind": kind, "start_ns": 0}


def _write_imu(root, gyr, acc, fs=100.0, placement="foot_left", t0=0):
    import pyarrow as pa
    from stridelab.warehouse.store import write_table
    n = len(gyr)
    t = t0 + np.round(np.arange(n) * 1e9 / fs).astype(np.int64)
    rel = f"series/imu-{placement}-{n}.parquet"
    write_table(root, rel, pa.table({"t_ns": t, **{f"acc_{a}": acc[:, k] for k, a in enumerate("xyz")},
                                     **{f"gyr_{a}": gyr[:, k] for k, a in enumerate("xyz")}}))
    return {"series_path": rel, "sampling_rate_hz": fs, "n_samples": n}, t


def test_no_stance_and_no_walking_trial_give_a_clear_status(tmp_path):
    from stridelab.pipeline.stages import SessionInput
    rng = np.random.default_rng(0)
    n = 3000
    gyr = rng.normal(0, 3.0, (n, 3))                   # never still: running / sensor on a swinging segment
    acc = np.tile([0, 0, 9.81], (n, 1)) + rng.normal(0, 4.0, (n, 3))
    imu, t = _write_imu(tmp_path, gyr, acc)
    rec = {"content_hash": "a" * 64, "trial": "walk-1", "start_ns": int(t[0]), "end_ns": int(t[-1]),
           "sensors": {"foot_left": {"imu": imu}}}
    out = gait_stage.STAGE.compute(SessionInput(root=str(tmp_path), session=_session(), recordings=[rec]),
                             gait_stage.STAGE.default_params())
    assert out.rows["strides"] == [] and out.rows["gait_events"] == []
    summ = {r["side"]: r for r in out.rows["gait_summary"]}
    assert summ["both"]["status"] == "no_stance" and summ["both"]["n_strides"] == 0
    assert "no stance" in summ["both"]["note"] and "no foot_right IMU" in summ["both"]["note"]
    assert out.rows["foot_trajectories"][0]["status"] == "no_stance"
    out = gait_stage.STAGE.compute(SessionInput(root=str(tmp_path), session=_session(),
                                          recordings=[dict(rec, trial="calibration")]), gait_stage.STAGE.default_params())
    assert {r["status"] for r in out.rows["gait_summary"]} == {"no_walking_trial"}
    assert all(out.rows[t] == [] for t in ("strides", "gait_events", "foot_trajectories"))


def test_standing_still_gives_no_strides(tmp_path):
    from stridelab.pipeline.stages import SessionInput
    rng = np.random.default_rng(1)
    n = 2000
    gyr = rng.normal(0, 0.005, (n, 3))
    acc = np.tile([0.5, 0.2, 9.79], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    recs = []
    sensors = {}
    for p in ("foot_left", "foot_right"):
        sensors[p] = {"imu": _write_imu(tmp_path, gyr, acc, placement=p)[0]}
    recs.append({"content_hash": "b" * 64, "trial": "walk-1", "start_ns": 0, "end_ns": int(20e9), "sensors": sensors})
    out = gait_stage.STAGE.compute(SessionInput(root=str(tmp_path), session=_session(), recordings=recs),
                             gait_stage.STAGE.default_params())
    assert out.rows["strides"] == []
    assert {r["status"] for r in out.rows["gait_summary"]} == {"no_strides"}


@pytest.mark.slow
def test_cli_simulate_then_run_fills_the_gait_tables(cli_study):
    """``stridelab simulate`` then ``stridelab run`` (tests/pipeline/conftest.py): the gait tables of every lab visit."""
    wh = cli_study["root"] / "wh"
    summ = _df(wh, "SELECT * FROM gait_summary WHERE side = 'both'")
    visits = load_manifest(DEFAULT_MANIFEST).visits          # one lab session per visit of the programme
    assert len(summ) == visits and set(summ["status"]) == {"ok"} and (summ["n_strides"] > 40).all()
    assert _df(wh, "SELECT count(*) AS n FROM foot_trajectories")["n"][0] == 4 * visits   # 2 trials x 2 feet
    assert _df(wh, "SELECT count(*) AS n FROM accuracy_metrics WHERE stage = 'gait_events'")["n"][0] > 0


def test_distance_sensors_feed_the_duong_suh_height(warehouse):
    """The stage's pz_floor equals the Duong & Suh filter called directly on the same arrays (geometry guessed)."""
    from stridelab.pipeline.stages import SessionInput
    traj = _df(warehouse, "SELECT * FROM foot_trajectories ORDER BY placement")
    assert set(traj["range_estimator"]) == {"duong_suh_21"} and set(traj["range_status"]) == {"ok"}
    assert set(traj["range_geometry"]) == {"guessed"} and (traj["range_used_fraction"] > 0.5).all()
    con = connect_snapshot(warehouse)
    try:
        r = traj.iloc[0]
        s = read_imu(con, warehouse, r["content_hash"], r["placement"])
        sensors = {}
        for pl, kind, path, rate, n in con.execute(
                "SELECT placement, kind, series_path, sampling_rate_hz, n_samples FROM sensors WHERE content_hash = ?",
                [r["content_hash"]]).fetchall():
            sensors.setdefault(pl, {})[kind if kind != "range" else f"range:{path}"] = {
                "series_path": path, "sampling_rate_hz": rate, "n_samples": n}
    finally:
        con.close()
    rec = {"content_hash": r["content_hash"], "trial": "walk-1", "sensors": sensors}
    from stridelab.pipeline.stages._shape import StageContext
    ctx = StageContext(SessionInput(root=str(warehouse), session={}, recordings=[rec]), gait_stage.TABLES, ())
    ranges = gait_stage.read_ranges(ctx, rec, r["placement"], s.t_ns)
    assert ranges.shape == (len(s.t_ns), 2) and 0.3 < np.isfinite(ranges).mean() < 0.34     # 33.3 of 100 Hz
    res, src = gait_stage.range_trajectory(s.gyr, s.acc, ranges, s.sampling_rate_hz, r["placement"],
                                           gait_stage.GaitParams().distance_sensors)
    t = read_table(warehouse, r["series_path"])
    np.testing.assert_array_equal(t.column("pz_floor").to_numpy(), res.pos[:, 2])
    assert src == "guessed" and res.status == "ok"


def test_saturated_distance_sensors_give_a_clear_status(tmp_path):
    import pyarrow as pa
    from stridelab.validation.simulator.duong_suh_walk import simulate_ds_walk
    from stridelab.pipeline.stages import SessionInput
    from stridelab.warehouse.store import write_table
    w = simulate_ds_walk(0, n_strides=4)
    imu, t = _write_imu(tmp_path, w.gyr, w.acc)
    sensors = {"imu": imu}
    for k, name in enumerate("AB"):
        rel = f"series/range-{name}-x.parquet"
        write_table(tmp_path, rel, pa.table({"t_ns": t[::3], "range_m": np.full(len(t[::3]), np.inf)}))
        sensors[f"range:{rel}"] = {"series_path": rel, "sampling_rate_hz": 33.3, "n_samples": len(t[::3])}
    rec = {"content_hash": "c" * 64, "trial": "walk-1", "start_ns": int(t[0]), "end_ns": int(t[-1]),
           "sensors": {"foot_left": sensors}}
    out = gait_stage.STAGE.compute(SessionInput(root=str(tmp_path), session=_session(), recordings=[rec]),
                             gait_stage.STAGE.default_params())
    row = out.rows["foot_trajectories"][0]
    assert row["range_status"] == "no_valid_range" and row["range_used_fraction"] == 0.0
    assert "distance sensors" in out.rows["gait_summary"][0]["note"]
