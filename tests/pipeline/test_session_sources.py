"""Session metadata sources and their precedence, topic mapping (issue 13 points 3 and 4)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from stridelab.pipeline import runner
from stridelab.cli import main
from tests.corpus import small_recording
from tests.pipeline._interop import assert_bit_equal, rosbags_write, stored, write_mcap_ros2
from stridelab.warehouse.read import connect_snapshot

ROS_TOPICS = {"/imu/foot_left": "/foot_left/imu/data_raw", "/mag/foot_left": "/foot_left/imu/mag"}


def _ingest(wh, files, **opts):
    return runner.run(wh, None, files=[Path(f) for f in files], stages=False, command="ingest",
                      ingest_options=opts or None)


def _session_of(wh):
    con = connect_snapshot(wh)
    try:
        return json.loads(con.execute("SELECT metadata FROM recordings WHERE status = 'ingested'").fetchone()[0])
    finally:
        con.close()


def test_sidecar_completes_a_file_without_session_record(tmp_path):
    rec = small_recording(seconds=5.0, placements=("foot_left",))
    f = write_mcap_ros2(tmp_path / "walk.mcap", rec, session=False)
    lines = [f'{k} = "{v}"' for k, v in rec.metadata.items()]
    (tmp_path / "walk.session.toml").write_text("[session]\n" + "\n".join(lines) + "\n")
    s = _ingest(tmp_path / "wh", [f])
    assert s.ingested == ["walk.mcap"], s.quarantined
    assert _session_of(tmp_path / "wh")["participant"] == rec.metadata["participant"]


def test_custom_data_bag_session_toml_and_cli_are_merged(tmp_path):
    rec = small_recording(seconds=5.0, placements=("foot_left",))
    md = rec.metadata
    bag = rosbags_write(tmp_path / "bag", rec, storage="mcap",
                        custom_data={"session.study": md["study"], "session.participant": md["participant"]})
    (bag / "session.toml").write_text(f'session = "{md["session"]}"\nkind = "lab"\n')
    s = _ingest(tmp_path / "wh", [bag], session={"trial": "walk-7", "timezone": "Europe/Zurich"})
    assert s.ingested == ["bag"], s.quarantined
    got = _session_of(tmp_path / "wh")
    assert (got["study"], got["participant"], got["session"], got["kind"], got["trial"]) == \
        (md["study"], md["participant"], md["session"], "lab", "walk-7")


def test_disagreeing_sources_are_refused_without_echoing_values(tmp_path):
    rec = small_recording(seconds=5.0, placements=("foot_left",))
    f = write_mcap_ros2(tmp_path / "walk.mcap", rec)
    s = _ingest(tmp_path / "wh", [f], session={"participant": "P777"})
    assert s.ingested == []
    reason = s.quarantined[0]
    assert reason.startswith("walk.mcap: quarantined: session field 'participant' differs between the MCAP "
                             "'session' record and --session; make the sources agree"), reason
    assert "P777" not in reason and rec.metadata["participant"] not in reason
    # custom data against the session record, inside one file
    f2 = write_mcap_ros2(tmp_path / "walk2.mcap", rec, metadata={"rosbag2": {"serialized_metadata":
                         "rosbag2_bagfile_information:\n  custom_data:\n    session.kind: free_living\n"}})
    s = _ingest(tmp_path / "wh", [f2])
    assert "session field 'kind' differs between the MCAP 'session' record and rosbag2 custom data" in s.quarantined[0]


def test_no_session_anywhere_says_where_it_can_come_from(tmp_path):
    f = write_mcap_ros2(tmp_path / "anon.mcap", small_recording(seconds=5.0, placements=("foot_left",)), session=False)
    s = _ingest(tmp_path / "wh", [f])
    r = s.quarantined[0]
    assert r.startswith("anon.mcap: quarantined: no session metadata") and "--session" in r and "custom-data" in r


def test_topic_map_from_the_command_line_and_refusal_listing_topics(tmp_path):
    rec = small_recording(seconds=5.0, placements=("foot_left",))
    f = write_mcap_ros2(tmp_path / "ros.mcap", rec, topics=ROS_TOPICS)
    s = _ingest(tmp_path / "wh", [f])
    r = s.quarantined[0]
    assert "ros.mcap: quarantined: no IMU topic" in r and "/foot_left/imu/data_raw (sensor_msgs/msg/Imu)" in r
    assert "--topic-map" in r
    s = _ingest(tmp_path / "wh2", [f], topic_map={"/foot_left/imu/data_raw": "foot_left",
                                                   "/foot_left/imu/mag": "foot_left"})
    assert s.ingested == ["ros.mcap"], s.quarantined
    x = rec.imu["foot_left"]
    assert_bit_equal(stored(tmp_path / "wh2", "foot_left", "imu"), x.t_ns, x.acc, x.gyr)
    assert_bit_equal(stored(tmp_path / "wh2", "foot_left", "mag"), x.t_ns, mag_ut=(x.mag * 1e-6) * 1e6)


def test_topic_map_from_the_study_manifest(tmp_path, monkeypatch):
    from stridelab.pipeline import config
    rec = small_recording(seconds=5.0, placements=("foot_left",), study="mapped")
    studies = tmp_path / "studies"
    (studies / "mapped").mkdir(parents=True)
    (studies / "mapped" / "study.toml").write_text(
        '[topics]\n"/foot_left/imu/data_raw" = "foot_left"\n"/foot_left/imu/mag" = "foot_left"\n')
    monkeypatch.setenv("STRIDELAB_STUDIES", str(studies))
    config.study_manifest.cache_clear()
    try:
        f = write_mcap_ros2(tmp_path / "ros.mcap", rec, topics=ROS_TOPICS)
        s = _ingest(tmp_path / "wh", [f])
        assert s.ingested == ["ros.mcap"], s.quarantined
        assert stored(tmp_path / "wh", "foot_left", "mag").num_rows == len(rec.imu["foot_left"].t_ns)
    finally:
        config.study_manifest.cache_clear()


def test_cli_session_and_topic_map_options(tmp_path):
    rec = small_recording(seconds=5.0, placements=("foot_left",))
    f = write_mcap_ros2(tmp_path / "ros.mcap", rec, topics=ROS_TOPICS, session=False)
    args = ["ingest", str(f), "--warehouse", str(tmp_path / "wh"), "--json",
            "--topic-map", "/foot_left/imu/data_raw=foot_left",
            "--skip-topic", "/foot_left/imu/mag"]        # unmapped magnetometer: skipped on request (issue #47)
    for k, v in rec.metadata.items():
        args += ["--session", f"{k}={v}"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["ingested"] == 1
    bad = CliRunner().invoke(main, ["ingest", str(f), "--warehouse", str(tmp_path / "wh"), "--session", "study"])
    assert bad.exit_code == 2 and "--session expects KEY=VALUE" in bad.output


def test_manifest_topics_table_is_validated(tmp_path):
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    text = DEFAULT_MANIFEST.read_text()
    p = tmp_path / "study.toml"
    p.write_text(text + '\n[topics]\n"/foot_left/imu/data_raw" = "foot_left"\n')
    assert dict(load_manifest(p).topics) == {"/foot_left/imu/data_raw": "foot_left"}
    p.write_text(text + '\n[topics]\n"no_slash" = "foot_left"\n')
    with pytest.raises(ValueError, match=r"\[topics.no_slash\]"):
        load_manifest(p)


@pytest.mark.parametrize("field,value,needle", [("thigh_length_m", "8.41", "'thigh_length_m' = 8.41 is outside"),
                                                ("height_m", "tall", "'height_m' is not a number"),
                                                ("sampling_rate_hz", "200", "declares 200 Hz but the stamps give 100.00 Hz")])
def test_implausible_session_numbers_are_refused(tmp_path, field, value, needle):
    rec = small_recording(seconds=5.0, placements=("foot_left",))
    f = write_mcap_ros2(tmp_path / "walk.mcap", rec, session=False)
    s = _ingest(tmp_path / "wh", [f], session={**rec.metadata, field: value})
    assert s.ingested == [] and needle in s.quarantined[0], s.quarantined
