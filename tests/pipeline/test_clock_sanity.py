"""Clock sanity (issue #47, docs/clocks.md "Implausible stamps"): never a silent 1970 or a 56-year gap. Files by
mcap_ros2's writer, stamps and log times chosen per case."""
from __future__ import annotations

import numpy as np

from stridelab.pipeline import runner
from stridelab.pipeline.clock_policy import EARLIEST_NS
from tests.corpus import T0_NS, small_recording
from tests.pipeline._interop import IMU_DEF, imu_dict, stored
from stridelab.warehouse.read import connect_snapshot


def _write(path, rec, stamps, log):
    from mcap_ros2.writer import Writer
    x = rec.imu["foot_left"]
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=32 * 1024)
        s = w.register_msgdef("sensor_msgs/msg/Imu", IMU_DEF)
        for i in range(len(stamps)):
            w.write_message("/imu/foot_left", s, imu_dict(int(stamps[i]), x.acc[i], x.gyr[i], "foot_left"),
                            log_time=int(log[i]), publish_time=int(log[i]), sequence=i)
        w.add_metadata("session", dict(rec.metadata))
        w.finish()
    return path


def _ingest(tmp_path, f):
    s = runner.run(tmp_path / "wh", None, files=[f], stages=False, command="ingest")
    con = connect_snapshot(tmp_path / "wh")
    msgs = [r[0] for r in con.execute("SELECT message FROM recording_issues").fetchall()] if con else []
    if con:
        con.close()
    return s, msgs


def _rec():
    return small_recording(seconds=10.0, placements=("foot_left",))


def test_simulation_time_stamps_with_wall_clock_log_times_use_the_log_time(tmp_path):
    rec = _rec()
    wall = rec.imu["foot_left"].t_ns
    sim = wall - wall[0]                                 # seconds since the start: 1970
    f = _write(tmp_path / "sim.mcap", rec, sim, wall)
    s, msgs = _ingest(tmp_path, f)
    assert s.ingested == ["sim.mcap"], s.quarantined
    t = stored(tmp_path / "wh", "foot_left").column("t_ns").to_numpy()
    assert t.min() >= EARLIEST_NS and np.array_equal(t, wall)
    assert any("header.stamp is not wall-clock time" in m and "log_time used" in m for m in msgs), msgs


def test_one_stamp_of_zero_with_a_non_wall_clock_log_time_is_dropped_not_a_56_year_gap(tmp_path):
    rec = _rec()
    wall = rec.imu["foot_left"].t_ns
    stamps = wall.copy()
    stamps[300] = 0
    log = wall - wall[0] + 1_000_000                     # the recorder's clock is simulation time
    f = _write(tmp_path / "zero.mcap", rec, stamps, log)
    s, msgs = _ingest(tmp_path, f)
    assert s.ingested == ["zero.mcap"], s.quarantined
    t = stored(tmp_path / "wh", "foot_left").column("t_ns").to_numpy()
    assert len(t) == len(wall) - 1 and t.min() == wall[0] and np.diff(t).max() < 1e9
    assert any("1 samples with a time before 2000 or in the future" in m for m in msgs), msgs


def test_stamps_in_the_future_are_outliers_and_no_wall_clock_at_all_is_refused(tmp_path):
    rec = _rec()
    wall = rec.imu["foot_left"].t_ns
    stamps = wall.copy()
    stamps[10] = T0_NS + 8 * 365 * 86_400 * 10**9        # 8 years ahead (CDR seconds are int32: before 2038)
    (tmp_path / "a").mkdir()
    s, msgs = _ingest(tmp_path / "a", _write(tmp_path / "future.mcap", rec, stamps, wall))
    assert s.ingested == ["future.mcap"] and any("1 samples with a time" in m for m in msgs), msgs
    sim = wall - wall[0] + 1
    (tmp_path / "b").mkdir()
    s, _ = _ingest(tmp_path / "b", _write(tmp_path / "allsim.mcap", rec, sim, sim))
    assert s.ingested == [] and "no time base" in s.quarantined[0] and "wall-clock" in s.quarantined[0]
