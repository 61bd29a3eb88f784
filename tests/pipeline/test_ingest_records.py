"""Nothing dropped without a record, re-ingest on purpose, files without CRCs (issue #47). Files by real writers:
mcap_ros2's (with and without CRCs)."""
from __future__ import annotations

import json

import numpy as np

import pytest

from stridelab.pipeline.privacy import shown_topic, stored_name as N    # what the catalog keeps of a topic / a file name
from tests.corpus import small_recording
from tests.pipeline._interop import IMU_DEF, MAG_DEF, imu_dict, mag_dict
from tests.pipeline.test_runner import cli
from stridelab.warehouse.read import connect_snapshot


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


@pytest.mark.slow
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


@pytest.mark.slow
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
    from stridelab.warehouse import queries as Q                  # what the dashboard's runs page lists
    con = connect_snapshot(wh)
    page = Q.skipped_topics(con)
    con.close()
    page = page[page["status"] == "skipped"]           # (the first, refused try lists the file's topics too)
    assert page[["file_name", "topic"]].values.tolist() == [[N("walk.mcap"), shown_topic("/spare/imu")]]


@pytest.mark.slow
def test_a_magnetometer_mapped_to_a_placement_without_imu_is_an_error(tmp_path):
    f = write_ros2(tmp_path / "walk.mcap", _rec(), {"/imu/foot_left": ("foot_left", "imu"),
                                                    "/foot/mag": ("foot_left", "mag")})
    r = cli("ingest", f, "--warehouse", tmp_path / "wh", "--topic-map", "/foot/mag=foot_right")
    assert r.returncode == 1 and "has no IMU" in r.stderr, r.stderr
    assert _series_files(tmp_path / "wh") == []
    # a typo of a placement is refused first by the placement vocabulary (stridelab.pipeline.privacy), naming the fix
    r = cli("ingest", f, "--warehouse", tmp_path / "wh2", "--topic-map", "/foot/mag=foot_rigth")
    assert r.returncode == 1 and "not in the study's vocabulary" in r.stderr and "--topic-map" in r.stderr, r.stderr
    assert _series_files(tmp_path / "wh2") == []


@pytest.mark.slow
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


@pytest.mark.slow
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
    from stridelab.warehouse import queries as Q                  # the dashboard's recordings table flags it
    con = connect_snapshot(wh)
    page = Q.recordings(con, "P001")
    con.close()
    assert dict(zip(page["file_name"], page["crc"])) == {N("a.mcap"): "", N("b.mcap"): "unverified"}
    r = cli("ingest", without, "--warehouse", tmp_path / "strict", "--require-crc")
    assert r.returncode == 1 and "no CRCs" in r.stderr, r.stderr


@pytest.mark.slow
def test_reference_events_written_twice_are_stored_once(tmp_path):
    """A chunk (here: its messages) written twice by the mcap library's writer: the IMU duplicates are dropped,
    and so are the reference events (they were stored twice)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer
    from stridelab.pipeline.formats.mcap_write import write_recording
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


@pytest.mark.slow
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


def _with_string_topic(path, rec, topics):
    """Like :func:`write_ros2`, plus a ``std_msgs/msg/String`` topic (a schema StrideLab does not read)."""
    from mcap_ros2.writer import Writer
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=64 * 1024)
        s_imu = w.register_msgdef("sensor_msgs/msg/Imu", IMU_DEF)
        s_str = w.register_msgdef("std_msgs/msg/String", "string data")
        for topic, (pl, _kind) in topics.items():
            x = rec.imu[pl]
            for i, t in enumerate(x.t_ns.tolist()):
                w.write_message(topic, s_imu, imu_dict(t, x.acc[i], x.gyr[i], pl), log_time=t, publish_time=t)
        t0 = int(rec.imu[next(iter(topics.values()))[0]].t_ns[0])
        w.write_message("/operator/notes", s_str, {"data": "start"}, log_time=t0, publish_time=t0)
        w.add_metadata("session", dict(rec.metadata))
        w.finish()
    return path


@pytest.mark.slow
def test_every_topic_of_every_file_is_in_the_ingest_ledger_with_its_outcome(tmp_path):
    """Issue #47 point 3: each topic ingested or listed as skipped with the reason in the report (the command's
    summary), the ledger (``ingest_topics`` of the run) and the runs page; a refused file's topics too."""
    rec = _rec()
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    _with_string_topic(inbox / "walk.mcap", rec, {"/imu/foot_left": ("foot_left", "imu"),
                                                   "/spare/imu": ("shank_left", "imu")})
    other = small_recording(seconds=5.0, seed=3, session="S02", trial="walk-2")
    write_ros2(inbox / "nocrc.mcap", other, {"/imu/foot_left": ("foot_left", "imu")}, crcs=False)
    wh = tmp_path / "wh"
    r = cli("ingest", inbox, "--warehouse", wh, "--skip-topic", "/spare/imu", "--require-crc", "--json")
    assert r.returncode == 1, r.stderr                                   # nocrc.mcap refused (--require-crc)
    summary = json.loads(r.stdout)
    assert summary["skipped_topics"] == ["walk.mcap: /operator/notes: std_msgs/msg/String in cdr encoding is not "
                                         "read by StrideLab", "walk.mcap: /spare/imu: skipped on request (--skip-topic)"]
    (run_id,) = _rows(wh, "SELECT run_id FROM pipeline_runs WHERE command = 'ingest'")[0]
    ledger = _rows(wh, "SELECT file_name, topic, outcome, placement, n_samples, reason FROM ingest_topics "
                       f"WHERE run_id = '{run_id}' ORDER BY file_name, topic")
    n = len(rec.imu["foot_left"].t_ns)
    walk = [x[1:] for x in ledger if x[0] == N("walk.mcap")]
    assert walk == sorted([("/imu/foot_left", "ingested", "foot_left", n, None),
                           (shown_topic("/operator/notes"), "skipped", None, None,
                            "std_msgs/msg/String in cdr encoding is not read by StrideLab"),
                           (shown_topic("/spare/imu"), "skipped", None, None, "skipped on request (--skip-topic)")])
    nocrc = [x[1:] for x in ledger if x[0] == N("nocrc.mcap")]
    assert [x[:2] for x in nocrc] == [("/imu/foot_left", "quarantined")] and "--require-crc" in nocrc[0][4]
    from stridelab.warehouse import queries as Q                  # what the dashboard's runs page lists
    con = connect_snapshot(wh)
    try:
        page = Q.skipped_topics(con)
        full = Q.ingest_topics(con, run_id)
    finally:
        con.close()
    assert sorted(map(tuple, page[["run_id", "file_name", "topic", "status"]].values.tolist())) == sorted([
        (run_id, N("walk.mcap"), shown_topic("/operator/notes"), "skipped"),
        (run_id, N("walk.mcap"), shown_topic("/spare/imu"), "skipped"),
        (run_id, N("nocrc.mcap"), "/imu/foot_left", "quarantined")])
    assert len(full) == 4 and set(full["outcome"]) == {"ingested", "skipped", "quarantined"}


@pytest.mark.slow
def test_run_takes_skip_topic_and_require_crc_like_ingest(tmp_path):
    """``stridelab run`` ingests the inbox with the same --skip-topic / --require-crc semantics as ``ingest``."""
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    write_ros2(inbox / "walk.mcap", _rec(), {"/imu/foot_left": ("foot_left", "imu"),
                                             "/spare/imu": ("shank_left", "imu")})
    wh = tmp_path / "wh"
    r = cli("run", "--inbox", inbox, "--warehouse", wh, "--no-reports", "--jobs", "1", "--json")
    assert r.returncode == 1 and "--skip-topic /spare/imu" in r.stderr + r.stdout     # refused, naming the fix
    r = cli("run", "--inbox", inbox, "--warehouse", wh, "--no-reports", "--jobs", "1", "--skip-topic", "/spare/imu",
            "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["skipped_topics"] == ["walk.mcap: /spare/imu: skipped on request (--skip-topic)"]
    assert _rows(wh, "SELECT status, json_extract_string(ingest_settings, '$.skip_topics[0]') FROM recordings") == [
        ("ingested", "/spare/imu")]
    other = small_recording(seconds=5.0, seed=3, session="S02", trial="walk-2")
    write_ros2(inbox / "nocrc.mcap", other, {"/imu/foot_left": ("foot_left", "imu")}, crcs=False)
    r = cli("run", "--inbox", inbox, "--warehouse", wh, "--no-reports", "--jobs", "1", "--skip-topic", "/spare/imu",
            "--require-crc", "--json")
    assert r.returncode == 1
    (q,) = json.loads(r.stdout)["quarantined"]
    assert q.startswith("nocrc.mcap: ") and "--require-crc" in q
    assert _rows(wh, "SELECT status FROM recordings WHERE status = 'ingested'") == [("ingested",)]   # walk.mcap kept
    # a refused file is not read again by the next run (same content, same settings) unless named with --replace
    r = cli("run", "--inbox", inbox, "--warehouse", wh, "--no-reports", "--jobs", "1", "--skip-topic", "/spare/imu",
            "--replace", inbox / "nocrc.mcap", "--json")
    assert r.returncode == 0, r.stderr                                   # without --require-crc: stored, unverified
    assert _rows(wh, "SELECT crc_verified FROM recordings WHERE status = 'ingested' ORDER BY crc_verified") == [
        (False,), (True,)]
