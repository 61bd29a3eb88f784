"""Nothing dropped without a record, re-ingest on purpose, files without CRCs (issue #47). Files by real writers:
mcap_ros2's (with and without CRCs)."""
from __future__ import annotations

import json

import numpy as np

from pipeline.privacy import shown_topic, stored_name as N    # what the catalog keeps of a topic / a file name
from tests.corpus import small_recording
from tests.pipeline._interop import IMU_DEF, MAG_DEF, imu_dict, mag_dict
from tests.pipeline.test_runner import cli
from warehouse.read import connect_snapshot


def write_ros2(path, rec, topics: dict[str, tuple[str, str]], *, crcs: bool = True, chunk_size=64 * 1024):
    """``topics``: topic -> (placement of ``rec``, "imu" | "mag"), written with mcap_ros2's writer."""
    from mcap_ros2.writer import Writer
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, enable_crcs=crcs)
        s_imu = w.register_msgdef("sensor_msgs/msg/Imu", IMU_DEF)
        s_mag = w.register_msgdef("sensor_msgs/msg/MagneticField", MAG_DEF)
        msgs = []
        for topic, (pl, kind) in topics.items():
            x = rec.imu[pl]
            for i, t in enumerate(x.t_ns.tolist()):
                msgs.append((t, topic, s_imu, imu_dict(t, x.acc[i], x.gyr[i], pl)) if kind == "imu" else
                            (t, topic, s_mag, mag_dict(t, x.mag[i] * 1e-6, pl)))
        msgs.sort(key=lambda m: m[0])
        for k, (lt, topic, schema, msg) in enumerate(msgs):
            w.write_message(topic, schema, msg, log_time=lt, publish_time=lt, sequence=k)
        w.add_metadata("session", dict(rec.metadata))
        w.finish()
    return path


def _rec(seconds=5.0):
    return small_recording(seconds=seconds)


def _rows(wh, sql):
    con = connect_snapshot(wh)
    try:
        return con.execute(sql).fetchall()
    finally:
        con.close()


def _series_files(wh):
    return sorted(p for p in (wh / "series").rglob("*.parquet") if "_staging" not in p.parts) \
        if (wh / "series").exists() else []


def test_a_typo_in_the_topic_map_is_an_error_and_the_right_map_ingests_the_file_again(tmp_path):
    f = write_ros2(tmp_path / "walk.mcap", _rec(), {"/foot_left/imu/data_raw": ("foot_left", "imu"),
                                                    "/shank_left/imu/data_raw": ("shank_left", "imu")})
    wh = tmp_path / "wh"
    r = cli("ingest", f, "--warehouse", wh, "--topic-map", "/foot_left/imu/data_raw=foot_left",
            "--topic-map", "/shank_left/imu/data_rw=shank_left")            # typo: data_rw
    assert r.returncode == 1, r.stderr
    assert "/shank_left/imu/data_rw" in r.stderr and "Traceback" not in r.stderr
    assert _series_files(wh) == []                                         # nothing written
    # the right map: not a no-op although the file's content is known
    r = cli("ingest", f, "--warehouse", wh, "--topic-map", "/foot_left/imu/data_raw=foot_left",
            "--topic-map", "/shank_left/imu/data_raw=shank_left", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["ingested"] == 1
    assert sorted(_rows(wh, "SELECT placement FROM sensors WHERE kind = 'imu'")) == [("foot_left",), ("shank_left",)]
    assert _rows(wh, "SELECT status FROM recordings") == [("ingested",)]
    assert _rows(wh, "SELECT count(*) FROM superseded_ingests") == [(1,)]       # the quarantined try, kept


def test_an_unmapped_imu_topic_refuses_the_file_unless_skipped_on_request(tmp_path):
    f = write_ros2(tmp_path / "walk.mcap", _rec(), {"/imu/foot_left": ("foot_left", "imu"),
                                                    "/spare/imu": ("shank_left", "imu")})
    wh = tmp_path / "wh"
    r = cli("ingest", f, "--warehouse", wh)
    assert r.returncode == 1 and "--skip-topic /spare/imu" in r.stderr, r.stderr     # the console: the name to pass
    (reason,) = _rows(wh, "SELECT reason FROM recordings WHERE status = 'quarantined'")[0]
    assert "/spare/imu" not in reason and shown_topic("/spare/imu") in reason and "--skip-topic" in reason
    r = cli("ingest", f, "--warehouse", wh, "--skip-topic", "/spare/imu")
    assert r.returncode == 0, r.stderr
    assert "/spare/imu: skipped on request" in r.stderr
    (skipped,) = _rows(wh, "SELECT skipped_topics FROM recordings WHERE status = 'ingested'")[0]
    assert json.loads(skipped) == [{"topic": shown_topic("/spare/imu"), "reason": "skipped on request (--skip-topic)"}]
    from warehouse import queries as Q                  # what the dashboard's runs page lists
    con = connect_snapshot(wh)
    page = Q.skipped_topics(con)
    con.close()
    assert page[["file_name", "topic"]].values.tolist() == [[N("walk.mcap"), shown_topic("/spare/imu")]]


def test_a_magnetometer_mapped_to_a_placement_without_imu_is_an_error(tmp_path):
    f = write_ros2(tmp_path / "walk.mcap", _rec(), {"/imu/foot_left": ("foot_left", "imu"),
                                                    "/foot/mag": ("foot_left", "mag")})
    r = cli("ingest", f, "--warehouse", tmp_path / "wh", "--topic-map", "/foot/mag=foot_right")
    assert r.returncode == 1 and "has no IMU" in r.stderr, r.stderr
    assert _series_files(tmp_path / "wh") == []
    # a typo of a placement is refused first by the placement vocabulary (pipeline.privacy), naming the fix
    r = cli("ingest", f, "--warehouse", tmp_path / "wh2", "--topic-map", "/foot/mag=foot_rigth")
    assert r.returncode == 1 and "not in the study's vocabulary" in r.stderr and "--topic-map" in r.stderr, r.stderr
    assert _series_files(tmp_path / "wh2") == []


def test_replace_ingests_the_same_file_again_and_keeps_the_earlier_ingest(tmp_path):
    f = write_ros2(tmp_path / "walk.mcap", _rec(), {"/imu/foot_left": ("foot_left", "imu")})
    wh = tmp_path / "wh"
    assert cli("ingest", f, "--warehouse", wh).returncode == 0
    r = cli("ingest", f, "--warehouse", wh, "--json")
    assert json.loads(r.stdout)["duplicates"] == 1                          # same file, same settings: a no-op
    r = cli("ingest", f, "--warehouse", wh, "--replace")
    assert r.returncode == 0 and "superseding its earlier ingest" in r.stderr, r.stderr
    assert _rows(wh, "SELECT reason FROM superseded_ingests") == [("ingested again with --replace",)]
    assert _rows(wh, "SELECT count(*) FROM recordings WHERE status = 'ingested'") == [(1,)]


def test_files_without_crcs_are_marked_unverified_and_refused_on_request(tmp_path):
    rec = _rec()
    with_crc = write_ros2(tmp_path / "a.mcap", rec, {"/imu/foot_left": ("foot_left", "imu")})
    rec2 = small_recording(seconds=5.0, seed=1, session="S02", trial="walk-2")
    without = write_ros2(tmp_path / "b.mcap", rec2, {"/imu/foot_left": ("foot_left", "imu")}, crcs=False)
    wh = tmp_path / "wh"
    r = cli("ingest", with_crc, without, "--warehouse", wh)
    assert r.returncode == 0, r.stderr
    assert dict(_rows(wh, "SELECT file_name, crc_verified FROM recordings")) == {N("a.mcap"): True,
                                                                                  N("b.mcap"): False}
    from warehouse import queries as Q                  # the dashboard's recordings table flags it
    con = connect_snapshot(wh)
    page = Q.recordings(con, "P001")
    con.close()
    assert dict(zip(page["file_name"], page["crc"])) == {N("a.mcap"): "", N("b.mcap"): "unverified"}
    r = cli("ingest", without, "--warehouse", tmp_path / "strict", "--require-crc")
    assert r.returncode == 1 and "no CRCs" in r.stderr, r.stderr


def test_reference_events_written_twice_are_stored_once(tmp_path):
    """A chunk (here: its messages) written twice by the mcap library's writer: the IMU duplicates are dropped,
    and so are the reference events (they were stored twice)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer
    from pipeline.formats.mcap_write import write_recording
    (tmp_path / "in").mkdir()
    src = write_recording(small_recording(seconds=5.0), tmp_path / "in" / "src.mcap")
    with open(src, "rb") as f:
        r = make_reader(f)
        msgs = list(r.iter_messages())
        meta = list(r.iter_metadata())
    dst = tmp_path / "dup.mcap"
    with open(dst, "wb") as f:
        w = Writer(f, chunk_size=16 * 1024)
        w.start(profile="ros2", library="test-duplicate")
        sids, cids = {}, {}
        for sch, ch, m in msgs:
            if sch.id not in sids:
                sids[sch.id] = w.register_schema(sch.name, sch.encoding, sch.data)
            if ch.id not in cids:
                cids[ch.id] = w.register_channel(ch.topic, ch.message_encoding, sids[sch.id], ch.metadata)
            for _ in range(2 if ch.topic == "/reference/events" or m.sequence < 50 else 1):
                w.add_message(cids[ch.id], m.log_time, m.data, m.publish_time, m.sequence)
        for md in meta:
            w.add_metadata(md.name, md.metadata)
        w.finish()
    wh = tmp_path / "wh"
    r = cli("ingest", dst, "--warehouse", wh)
    assert r.returncode == 0, r.stderr
    assert _rows(wh, "SELECT count(*) FROM reference_events") == [(2,)]
    msgs = [m for (m,) in _rows(wh, "SELECT message FROM recording_issues")]
    assert "2 exact duplicate reference events dropped" in msgs


def test_message_compressed_mcap_by_rosbags_is_read_as_a_bag_and_as_a_file(tmp_path):
    """rosbags writes MESSAGE-level compression (each message zstd-compressed): it was refused as corrupt."""
    import shutil

    from tests.pipeline._interop import rosbags_write, stored
    rec = small_recording(seconds=5.0)
    bag = rosbags_write(tmp_path / "bag", rec, compression="message")
    session = [a for k in ("study", "participant", "session", "kind") for a in ("--session", f"{k}={rec.metadata[k]}")]
    r = cli("ingest", bag, "--warehouse", tmp_path / "wh1", *session)
    assert r.returncode == 0, r.stderr
    x = rec.imu["foot_left"]
    t = stored(tmp_path / "wh1", "foot_left")
    assert np.array_equal(t.column("t_ns").to_numpy(), x.t_ns)
    assert np.array_equal(t.column("acc_x").to_numpy(), x.acc[:, 0])
    single = tmp_path / "single.mcap"
    shutil.copyfile(next(bag.glob("*.mcap")), single)
    r = cli("ingest", single, "--warehouse", tmp_path / "wh2", *session)
    assert r.returncode == 0, r.stderr
    t = stored(tmp_path / "wh2", "foot_left")
    assert np.array_equal(t.column("gyr_z").to_numpy(), x.gyr[:, 2])
