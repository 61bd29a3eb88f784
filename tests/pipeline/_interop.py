"""Writers of the ROS 2 ecosystem (mcap_ros2, rosbags, the mcap library) for the interoperability tests,
and a reader of what the warehouse stored (through the documented layout: catalog ``sensors`` rows ->
Parquet series)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from stridelab.pipeline.formats import ros2_cdr

IMU_DEF = ros2_cdr.SCHEMAS["sensor_msgs/msg/Imu"]
MAG_DEF = ros2_cdr.SCHEMAS["sensor_msgs/msg/MagneticField"]


def _stamp(t):
    return {"sec": int(t // 1_000_000_000), "nanosec": int(t % 1_000_000_000)}


def imu_dict(t, acc, gyr, frame="imu"):
    return {"header": {"stamp": _stamp(t), "frame_id": frame},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, "orientation_covariance": [-1.0] + [0.0] * 8,
            "angular_velocity": dict(zip("xyz", map(float, gyr))), "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": dict(zip("xyz", map(float, acc))), "linear_acceleration_covariance": [0.0] * 9}


def mag_dict(t, mag_t, frame="imu"):
    return {"header": {"stamp": _stamp(t), "frame_id": frame}, "magnetic_field": dict(zip("xyz", map(float, mag_t))),
            "magnetic_field_covariance": [0.0] * 9}


def write_mcap_ros2(path: Path, rec, *, topics=None, compression="zstd", chunk_size=64 * 1024,
                    session=True, log_offset_ns=0, interleave=True, mag=True, metadata=None):
    """IMU (and magnetometer) messages of ``rec`` with mcap_ros2's writer (Schema/Channel inside chunks)."""
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer
    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
    topics = topics or {}
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=comp)
        s_imu = w.register_msgdef("sensor_msgs/msg/Imu", IMU_DEF)
        s_mag = w.register_msgdef("sensor_msgs/msg/MagneticField", MAG_DEF)
        msgs = []
        for pl, x in rec.imu.items():
            ti = topics.get(f"/imu/{pl}", f"/imu/{pl}")
            tm = topics.get(f"/mag/{pl}", f"/mag/{pl}")
            for i, t in enumerate(x.t_ns.tolist()):
                msgs.append((t + log_offset_ns, ti, s_imu, imu_dict(t, x.acc[i], x.gyr[i], pl)))
                if mag and x.mag is not None:
                    msgs.append((t + log_offset_ns, tm, s_mag, mag_dict(t, x.mag[i] * 1e-6, pl)))
        if interleave:
            msgs.sort(key=lambda m: m[0])
        for k, (lt, topic, schema, msg) in enumerate(msgs):
            w.write_message(topic, schema, msg, log_time=lt, publish_time=lt, sequence=k)
        if session:
            w.add_metadata("session", dict(rec.metadata))
        for name, md in (metadata or {}).items():
            w.add_metadata(name, md)
        w.finish()
    return path


def rosbags_write(bag: Path, rec, *, storage="mcap", custom_data=None, topics=None, parts=1, compression=None):
    """A rosbag2 bag written with rosbags; ``parts`` > 1 splits it into that many storage files
    (one metadata.yaml listing them all, as ``ros2 bag record --max-bag-duration`` leaves it)."""
    import yaml
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    topics = topics or {}
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    n = len(next(iter(rec.imu.values())).t_ns)
    bounds = np.linspace(0, n, parts + 1).astype(int)
    dirs = []
    for k in range(parts):
        d = bag.with_name(f"{bag.name}.part{k}") if parts > 1 else bag
        w = Writer(d, version=9, storage_plugin=plugin)
        if compression:                                   # "message" or "file" (zstd), as rosbags writes them
            from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
            w.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
        with w:
            for key, v in (custom_data or {}).items():
                w.set_custom_data(key, v)
            for pl, x in rec.imu.items():
                ci = w.add_connection(topics.get(f"/imu/{pl}", f"/imu/{pl}"), "sensor_msgs/msg/Imu", typestore=ts)
                for i in range(bounds[k], bounds[k + 1]):
                    t = int(x.t_ns[i])
                    hdr = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](**_stamp(t)), frame_id=pl)
                    v3 = T["geometry_msgs/msg/Vector3"]
                    msg = T["sensor_msgs/msg/Imu"](
                        header=hdr, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                        orientation_covariance=np.array([-1.0] + [0.0] * 8),
                        angular_velocity=v3(*map(float, x.gyr[i])), angular_velocity_covariance=np.zeros(9),
                        linear_acceleration=v3(*map(float, x.acc[i])), linear_acceleration_covariance=np.zeros(9))
                    w.write(ci, t, ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))
        dirs.append(d)
    if parts == 1:
        return bag
    bag.mkdir()
    metas = [yaml.safe_load((d / "metadata.yaml").read_text())["rosbag2_bagfile_information"] for d in dirs]
    files = []
    for k, d in enumerate(dirs):
        src = next(d.glob(f"*.{'mcap' if storage == 'mcap' else 'db3'}"))
        dst = bag / f"{bag.name}_{k}{src.suffix}"
        src.rename(dst)
        files.append(dst.name)
        (d / "metadata.yaml").unlink()
        d.rmdir()
    m = metas[0]
    m["relative_file_paths"] = files
    m["message_count"] = sum(x["message_count"] for x in metas)
    m["files"] = [dict(x["files"][0], path=f) for x, f in zip(metas, files)]
    for tw in m["topics_with_message_count"]:
        tw["message_count"] = sum(t["message_count"] for x in metas for t in x["topics_with_message_count"]
                                  if t["topic_metadata"]["name"] == tw["topic_metadata"]["name"])
    start = min(x["starting_time"]["nanoseconds_since_epoch"] for x in metas)
    end = max(x["starting_time"]["nanoseconds_since_epoch"] + x["duration"]["nanoseconds"] for x in metas)
    m["starting_time"] = {"nanoseconds_since_epoch": start}
    m["duration"] = {"nanoseconds": end - start}
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": m}))
    return bag


def rewrite_with_mcap(src: Path, dst: Path, *, compression="lz4", chunked=True, reverse=False, chunk_size=32 * 1024):
    """Copy every record of ``src`` with the mcap library's own writer (another order/compression)."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer
    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
    with open(src, "rb") as f:
        r = make_reader(f)
        msgs = list(r.iter_messages())
        meta = list(r.iter_metadata())
    if reverse:
        msgs = msgs[::-1]
    with open(dst, "wb") as f:
        w = Writer(f, compression=comp, use_chunking=chunked, chunk_size=chunk_size)
        w.start(profile="ros2", library="test-rewrite")
        sids, cids = {}, {}
        for sch, ch, m in msgs:
            if sch.id not in sids:
                sids[sch.id] = w.register_schema(sch.name, sch.encoding, sch.data)
            if ch.id not in cids:
                cids[ch.id] = w.register_channel(ch.topic, ch.message_encoding, sids[sch.id], ch.metadata)
            w.add_message(cids[ch.id], m.log_time, m.data, m.publish_time, m.sequence)
        for md in meta:
            w.add_metadata(md.name, md.metadata)
        w.finish()
    return dst


def stored(wh: Path, placement: str, kind: str = "imu"):
    """The Parquet table the catalog points to for one placement and kind (single recording)."""
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(wh)
    try:
        rows = con.execute("SELECT series_path FROM sensors WHERE placement = ? AND kind = ?", [placement, kind]).fetchall()
    finally:
        con.close()
    assert len(rows) == 1, rows
    return pq.read_table(wh / rows[0][0])


def assert_bit_equal(table, t_ns, acc=None, gyr=None, mag_ut=None):
    assert np.array_equal(table.column("t_ns").to_numpy(), np.asarray(t_ns, np.int64))
    cols = []
    if acc is not None:
        cols += [("acc_" + a, acc[:, k]) for k, a in enumerate("xyz")] + [("gyr_" + a, gyr[:, k]) for k, a in enumerate("xyz")]
    if mag_ut is not None:
        cols += [("mag_" + a, mag_ut[:, k]) for k, a in enumerate("xyz")]
    for name, want in cols:
        got = table.column(name).to_numpy()
        assert np.array_equal(got.view(np.int64), np.ascontiguousarray(want, dtype=np.float64).view(np.int64)), name
