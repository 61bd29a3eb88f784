"""Real clocks (issue 13 point 5): the documented policy, a warning each time, refusal only without a time base."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.formats import ros2_cdr
from stridelab.pipeline.formats.mcap_write import ChannelData, recording_channels, write_mcap
from tests.corpus import small_recording
from tests.pipeline._interop import stored
from stridelab.warehouse.read import connect_snapshot


def _imu_channel(topic, stamps, log, acc, gyr):
    return ChannelData(topic, "sensor_msgs/msg/Imu", "ros2msg", ros2_cdr.SCHEMAS["sensor_msgs/msg/Imu"].encode(),
                       "cdr", np.asarray(log, np.int64), ros2_cdr.encode_imu(np.asarray(stamps, np.int64), acc, gyr,
                                                                              topic.rsplit("/", 1)[1]))


def _write(path, rec, chans):
    return write_mcap(path, chans, {"session": dict(rec.metadata)})


def _ingest_one(tmp_path, f):
    s = runner.run(tmp_path / "wh", None, files=[f], stages=False, command="ingest")
    con = connect_snapshot(tmp_path / "wh")
    msgs = [r[0] for r in con.execute("SELECT message FROM recording_issues").fetchall()]
    con.close()
    return s, msgs


def _rec():
    return small_recording(seconds=12.0, placements=("foot_left",))


def test_exact_duplicates_dropped_and_conflicting_stamps_keep_the_first(tmp_path):
    rec = _rec()
    x = rec.imu["foot_left"]
    idx = np.r_[np.arange(0, 301), 300, 300, np.arange(301, 700), 699, np.arange(700, len(x.t_ns))]
    acc, gyr = x.acc[idx].copy(), x.gyr[idx].copy()
    conflict = 301 + 2 + 399                           # the second copy of sample 699: other values
    acc[conflict] += 1.0
    t = x.t_ns[idx]
    f = _write(tmp_path / "dups.mcap", rec, [_imu_channel("/imu/foot_left", t, t, acc, gyr)])
    s, msgs = _ingest_one(tmp_path, f)
    assert s.ingested == ["dups.mcap"], s.quarantined
    tab = stored(tmp_path / "wh", "foot_left")
    assert np.array_equal(tab.column("t_ns").to_numpy(), x.t_ns)
    assert np.array_equal(tab.column("acc_x").to_numpy(), x.acc[:, 0])     # the first of each stamp kept
    assert any("2 exact duplicate samples dropped" in m for m in msgs), msgs
    assert any("1 samples repeat an earlier header.stamp with different values" in m for m in msgs), msgs


def test_zero_stamps_fall_back_to_log_time(tmp_path):
    rec = _rec()
    x = rec.imu["foot_left"]
    stamps = x.t_ns.copy()
    stamps[100:150] = 0
    f = _write(tmp_path / "zero.mcap", rec, [_imu_channel("/imu/foot_left", stamps, x.t_ns, x.acc, x.gyr)])
    s, msgs = _ingest_one(tmp_path, f)
    assert s.ingested == ["zero.mcap"], s.quarantined
    assert np.array_equal(stored(tmp_path / "wh", "foot_left").column("t_ns").to_numpy(), x.t_ns)
    assert any("50 samples with an unset (zero) header.stamp" in m for m in msgs), msgs


def test_batched_host_stamping_is_respaced_at_the_nominal_rate(tmp_path):
    """4 samples per packet, stamped 10 µs apart at packet arrival (every 40 ms)."""
    rec = _rec()
    x = rec.imu["foot_left"]
    n = len(x.t_ns) // 4 * 4
    k = np.arange(n)
    stamps = x.t_ns[k // 4 * 4] + (k % 4) * 10_000
    f = _write(tmp_path / "batched.mcap", rec, [_imu_channel("/imu/foot_left", stamps, stamps, x.acc[:n], x.gyr[:n])])
    s, msgs = _ingest_one(tmp_path, f)
    assert s.ingested == ["batched.mcap"], s.quarantined
    t = stored(tmp_path / "wh", "foot_left").column("t_ns").to_numpy()
    assert np.abs(t - x.t_ns[:n]).max() <= 1                    # back on the 100 Hz grid (ns rounding)
    assert any("batches of about 4 samples" in m and "100.00 Hz" in m for m in msgs), msgs


def test_messages_in_any_order_are_sorted_bit_equal(tmp_path):
    rec = _rec()
    x = rec.imu["foot_left"]
    perm = np.random.default_rng(3).permutation(len(x.t_ns))
    # log_time in file order (a host that received them shuffled), header.stamp the sensor's
    log = x.t_ns[0] + np.arange(len(perm)) * 10_000_000
    f = _write(tmp_path / "shuffled.mcap", rec,
               [_imu_channel("/imu/foot_left", x.t_ns[perm], log, x.acc[perm], x.gyr[perm])])
    s, msgs = _ingest_one(tmp_path, f)
    assert s.ingested == ["shuffled.mcap"], s.quarantined
    tab = stored(tmp_path / "wh", "foot_left")
    assert np.array_equal(tab.column("t_ns").to_numpy(), x.t_ns)
    assert np.array_equal(tab.column("gyr_z").to_numpy(), x.gyr[:, 2])
    assert any("not in header.stamp order: sorted" in m for m in msgs), msgs


def test_no_time_base_is_refused(tmp_path):
    rec = _rec()
    x = rec.imu["foot_left"]
    zeros = np.zeros_like(x.t_ns)
    f = _write(tmp_path / "notime.mcap", rec, [_imu_channel("/imu/foot_left", zeros, zeros, x.acc, x.gyr)])
    s, _ = _ingest_one(tmp_path, f)
    assert s.ingested == [] and "notime.mcap: quarantined:" in s.quarantined[0]
    assert "no time base" in s.quarantined[0]


# ---- independent clocks through every stage -----------------------------------------------------

CLOCKS = {"thigh_left": (1.7e9, 40e-6), "shank_left": (-0.4e9, -25e-6)}    # offset ns, rate error


def _independent_clock_files(directory: Path, files: list[Path], clocks=CLOCKS, jitter_ns=2e5) -> list[Path]:
    """Rewrite a lab session so that thigh_left and shank_left each stamp with their own clock
    (offset, rate error, 0.2 ms jitter) while log_time is the host's (true time + 0-2 ms delay)."""
    from mcap.reader import make_reader
    from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks
    from stridelab.estimators.recording import ImuData, Recording
    rng = np.random.default_rng(7)
    out = []
    for f in files:
        res = ReadResult()
        blocks = list(iter_blocks(f, res))
        with open(f, "rb") as fh:
            meta = {m.name: dict(m.metadata) for m in make_reader(fh).iter_metadata()}
        imu = {}
        for pl in clocks:
            b = [x for x in blocks if x.topic == f"/imu/{pl}"]
            t = np.concatenate([x.t_ns for x in b])
            v = np.concatenate([x.values for x in b])
            imu[pl] = ImuData(t, v[:, 3:], v[:, :3], None)
        rec = Recording(meta["session"], imu=imu, name=f.stem)
        chans = []
        for ch in recording_channels(rec):
            pl = ch.topic.split("/")[-1]
            off, drift = clocks[pl]
            true = imu[pl].t_ns
            stamps = (true + off + drift * (true - true[0]) + rng.normal(0, jitter_ns, len(true))).astype(np.int64)
            stamps = np.maximum.accumulate(stamps)
            host = true + rng.integers(0, 2_000_000, len(true))
            chans.append(_imu_channel(ch.topic, stamps, np.sort(host), imu[pl].acc, imu[pl].gyr))
        out.append(write_mcap(directory / f.name, chans, {"session": meta["session"]}))
    return out


@pytest.mark.slow
def test_two_imus_on_independent_clocks_go_through_every_stage(tmp_path):
    from tests.pipeline._lab import write_lab_session
    (tmp_path / "orig").mkdir()
    (tmp_path / "indep").mkdir()
    files, _truths = write_lab_session(tmp_path / "orig", distance_sensors=False, optical_reference=False)
    indep = _independent_clock_files(tmp_path / "indep", files)
    s = runner.run(tmp_path / "wh", None, files=indep)
    assert not s.failed, s.failed
    assert len(s.ingested) == len(indep), s.quarantined
    con = connect_snapshot(tmp_path / "wh")
    try:
        warn = [r[0] for r in con.execute("SELECT message FROM recording_issues").fetchall()]
        assert any("independent clocks" in m for m in warn), warn
        runs = con.execute("SELECT stage, status, count(*) FROM stage_runs GROUP BY 1, 2").fetchall()
        # a thigh/shank session has no feet and no trunk sensor: gait, the clinical measures and trunk gait are
        # 'skipped' with a reason (by design: the stage does not apply), not failed; every other stage is ok
        assert runs and all(st == "ok" or (st == "skipped" and s in ("gait", "clinical", "trunk_gait"))
                            for s, st, _n in runs), runs
        assert {s for s, st, _n in runs if st == "ok"} >= {"orientation", "calibration", "joint_angles"}, runs
        trunk = con.execute("SELECT note FROM stage_runs WHERE stage = 'trunk_gait'").fetchall()
        assert trunk and all("skipped: no" in n and "lower_back" in n for (n,) in trunk), trunk
        cal = dict(con.execute("SELECT placement, status FROM calibration").fetchall())
        assert set(CLOCKS) <= set(cal), cal
        knee = con.execute("SELECT series_path, status, n_samples FROM joint_angles WHERE joint = 'knee' "
                           "AND side = 'left'").fetchall()
    finally:
        con.close()
    assert knee and all(n > 1000 for _p, _s, n in knee), knee
    # the same trials on one shared clock: the aligned angles agree with them
    (tmp_path / "shared").mkdir()
    shared = _independent_clock_files(tmp_path / "shared", files, {pl: (0.0, 0.0) for pl in CLOCKS}, 0.0)
    s2 = runner.run(tmp_path / "wh2", None, files=shared)
    assert not s2.failed
    import pyarrow.parquet as pq
    con2 = connect_snapshot(tmp_path / "wh2")
    ref = con2.execute("SELECT series_path FROM joint_angles WHERE joint = 'knee' AND side = 'left'").fetchall()
    con2.close()
    a = pq.read_table(tmp_path / "wh" / knee[0][0]).to_pandas()
    b = pq.read_table(tmp_path / "wh2" / ref[0][0]).to_pandas()
    off = CLOCKS["thigh_left"][0]                # the grid is the first placement's clock (thigh)
    bt = b["t_ns"].to_numpy() + int(off)
    common = np.interp(bt, a["t_ns"].to_numpy(), a["sagittal_deg"].to_numpy(), left=np.nan, right=np.nan)
    ok = np.isfinite(common) & np.isfinite(b["sagittal_deg"].to_numpy())
    assert ok.sum() > 1000
    rmse = float(np.sqrt(np.mean((common[ok] - b["sagittal_deg"].to_numpy()[ok]) ** 2)))
    assert rmse < 3.0, rmse
