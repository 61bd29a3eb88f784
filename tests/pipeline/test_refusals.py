"""Inputs StrideLab cannot take are refused in one line naming what they are and what to do (issue #47);
a split rosbag2 bag without metadata.yaml is recognised, never three unrelated recordings. Files by real writers:
the mcap library, rosbags (ROS 1 and ROS 2), mcap_ros2."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tests.corpus import small_recording
from tests.pipeline._interop import rosbags_write, write_mcap_ros2
from tests.pipeline.test_runner import cli


def _quarantined(tmp_path, path, *extra):
    r = cli("ingest", path, "--warehouse", tmp_path / "wh", "--json", *extra)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    (reason,) = json.loads(r.stdout)["quarantined"]
    assert "\n" not in reason
    return reason


def _foreign_encoding(path, encoding, schema_name, schema_encoding, topic="/imu/foot_left"):
    from mcap.writer import Writer
    rec = small_recording(seconds=2.0)
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="test-foreign")
        sid = w.register_schema(schema_name, schema_encoding, b"{}")
        cid = w.register_channel(topic, encoding, sid)
        for t in rec.imu["foot_left"].t_ns[:50].tolist():
            w.add_message(cid, t, json.dumps({"t": t}).encode(), t)
        w.add_metadata("session", dict(rec.metadata))
        w.finish()
    return path


@pytest.mark.parametrize("encoding,schema,schema_enc,topic", [
    ("json", "sensor_msgs/msg/Imu", "jsonschema", "/imu/foot_left"),
    ("protobuf", "foxglove.Imu", "protobuf", "/imu/foot_left"),
    ("json", "sensor_msgs/msg/Imu", "jsonschema", "/sensors/imu0"),
])
@pytest.mark.slow
def test_json_and_protobuf_mcap_are_refused_with_the_fix(tmp_path, encoding, schema, schema_enc, topic):
    f = _foreign_encoding(tmp_path / "foreign.mcap", encoding, schema, schema_enc, topic)
    reason = _quarantined(tmp_path, f)
    assert f"{encoding} messages: StrideLab reads ROS 2 CDR" in reason and "mcap_ros2" in reason, reason


@pytest.mark.slow
def test_a_ros1_bag_is_refused_with_the_conversion(tmp_path):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS1_NOETIC)
    p = tmp_path / "walk.bag"
    with Writer(p) as w:
        c = w.add_connection("/imu", "std_msgs/msg/String", typestore=ts)
        w.write(c, 1_772_438_400_000_000_000, ts.serialize_ros1(ts.types["std_msgs/msg/String"](data="x"),
                                                                 "std_msgs/msg/String"))
    reason = _quarantined(tmp_path, p)
    assert "a ROS 1 bag" in reason and "rosbags-convert" in reason


@pytest.mark.slow
def test_metadata_yaml_instead_of_the_bag_folder_is_refused_with_the_fix(tmp_path):
    bag = rosbags_write(tmp_path / "bag", small_recording(seconds=2.0))
    reason = _quarantined(tmp_path, bag / "metadata.yaml")
    assert "ingest the bag folder" in reason


@pytest.mark.slow
def test_gyro_in_deg_s_is_refused_with_the_factor(tmp_path):
    rec = small_recording(seconds=5.0)
    x = rec.imu["foot_left"]
    x.gyr[:] = np.rad2deg(x.gyr * 4.0)              # a brisk rotation, exported in deg/s
    f = write_mcap_ros2(tmp_path / "degs.mcap", rec, mag=False)
    reason = _quarantined(tmp_path, f)
    assert "looks like deg/s" in reason and "pi/180" in reason


@pytest.mark.slow
@pytest.mark.parametrize("writer", ["mcap_ros2", "rosbags"])
def test_a_slow_rotation_in_deg_s_is_refused_although_its_size_looks_like_rad_s(tmp_path, writer):
    """The magnitude check misses a slow turn exported in deg/s (here peak 30 deg/s, below its 35 threshold): the
    gyroscope then predicts 57 times the turn of gravity the accelerometer measures, and the file is refused."""
    rec = small_recording(seconds=8.0, placements=("foot_left",))
    for x in rec.imu.values():
        x.gyr[:] = np.rad2deg(x.gyr)               # the same turn (about 36 deg/s about a tilted axis) in deg/s
    assert max(float(np.abs(x.gyr).max()) for x in rec.imu.values()) < 35.0
    name = "slow_degs.mcap" if writer == "mcap_ros2" else "slow_degs"
    f = (write_mcap_ros2(tmp_path / name, rec, mag=False) if writer == "mcap_ros2"
         else rosbags_write(tmp_path / name, rec, custom_data={f"session.{k}": v for k, v in rec.metadata.items()}))
    r = cli("ingest", f, "--warehouse", tmp_path / "wh", "--json")
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    (line,) = json.loads(r.stdout)["quarantined"]
    assert line.startswith(f"{name}: quarantined: /imu/") and "\n" not in line, line    # names the file
    assert "looks like deg/s" in line and "pi/180" in line and "57" in line
    # the same recording in rad/s is ingested (the check refuses the unit, not the motion)
    ok = small_recording(seconds=8.0, placements=("foot_left",))
    g = (write_mcap_ros2(tmp_path / f"rad_{name}", ok, mag=False) if writer == "mcap_ros2"
         else rosbags_write(tmp_path / f"rad_{name}", ok, custom_data={f"session.{k}": v for k, v in ok.metadata.items()}))
    r = cli("ingest", g, "--warehouse", tmp_path / "wh2", "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["ingested"] == 1, r.stderr


@pytest.mark.slow
def test_a_split_bag_without_metadata_is_recognised_and_refused_with_the_fix(tmp_path):
    rec = small_recording(seconds=12.0)
    bag = rosbags_write(tmp_path / "walk", rec, parts=3)
    (bag / "metadata.yaml").unlink()
    r = cli("ingest", bag, "--warehouse", tmp_path / "wh", "--json")
    out = json.loads(r.stdout)
    assert r.returncode == 1 and out["ingested"] == 0 and len(out["quarantined"]) == 3, r.stderr
    assert all("split rosbag2 bag" in q and "ros2 bag reindex" in q for q in out["quarantined"])
    # files named alike but apart in time are separate recordings, not parts
    other = tmp_path / "trials"
    other.mkdir()
    for k in range(2):
        r2 = small_recording(seconds=3.0, seed=k, session=f"S{k}", trial=f"t{k}")
        r2.imu = {pl: type(x)(x.t_ns + k * 3_600_000_000_000, x.acc, x.gyr, x.mag) for pl, x in r2.imu.items()}
        write_mcap_ros2(other / f"trial_{k}.mcap", r2, mag=False)
    r = cli("ingest", other, "--warehouse", tmp_path / "wh2", "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["ingested"] == 2, r.stderr
