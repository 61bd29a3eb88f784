"""The MCAP reader's one decode path (pipeline/formats/mcap_decode.py) decodes what an independent reader decodes:
the mcap library's record reader with mcap_ros2's per-message CDR decoder, message by message, on files of our
writer and of mcap_ros2 (definitions inside chunks, with and without a summary), and reports what is wrong."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stridelab.pipeline.formats import mcap_decode, mcap_read, ros2_cdr
from tests.corpus import small_recording
from tests.pipeline._interop import IMU_DEF, write_mcap_ros2
from tests.pipeline._lab import write_lab_session


def _read(path) -> tuple[dict, mcap_read.ReadResult]:
    """Per topic: concatenated stamps, log times and values (events: their dicts), and the read result."""
    res = mcap_read.ReadResult()
    parts: dict[str, list] = {}
    for b in mcap_read.iter_blocks(path, res):
        parts.setdefault(b.topic, []).append(b)
    out = {}
    for topic, bs in parts.items():
        if bs[0].kind == "events":
            out[topic] = [v for b in bs for v in b.values]
        else:
            out[topic] = (np.concatenate([b.t_ns for b in bs]), np.concatenate([b.log_ns for b in bs]),
                          np.concatenate([b.values for b in bs]))
    return out, res


def _stamp(m) -> int:
    return m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec


def _xyz(v) -> list[float]:
    return [v.x, v.y, v.z]


#: what StrideLab keeps of each type, from mcap_ros2's decoded message object (Block.values columns)
_VALUES = {
    "sensor_msgs/msg/Imu": lambda m: _xyz(m.angular_velocity) + _xyz(m.linear_acceleration),
    "sensor_msgs/msg/MagneticField": lambda m: _xyz(m.magnetic_field),
    "geometry_msgs/msg/PoseStamped": lambda m: _xyz(m.pose.position) + [m.pose.orientation.w, m.pose.orientation.x,
                                                                         m.pose.orientation.y, m.pose.orientation.z],
    "sensor_msgs/msg/Range": lambda m: [m.field_of_view, m.min_range, m.max_range, m.range],
}


def _reference(path: Path) -> dict:
    """The same per-topic arrays from the mcap library's reader and mcap_ros2's per-message decoder."""
    import json

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    per: dict[str, list] = {}
    with open(path, "rb") as f:
        for schema, channel, message, ros in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                log_time_order=False):
            if schema.name.endswith("Annotation"):
                per.setdefault(channel.topic, []).append(json.loads(ros.json))
            elif schema.name in _VALUES:
                per.setdefault(channel.topic, []).append((_stamp(ros), message.log_time, _VALUES[schema.name](ros)))
    out = {}
    for topic, rows in per.items():
        if isinstance(rows[0], dict):
            out[topic] = rows
        else:
            out[topic] = (np.array([r[0] for r in rows], dtype=np.int64), np.array([r[1] for r in rows], dtype=np.int64),
                          np.array([r[2] for r in rows], dtype=np.float64))
    return out


def _assert_same(ours: dict, ref: dict) -> None:
    assert ours.keys() == ref.keys()
    for topic in ours:
        if isinstance(ours[topic], list):
            assert ours[topic] == ref[topic], topic
            continue
        for x, y in zip(ours[topic], ref[topic]):          # bit for bit
            assert x.shape == y.shape and x.dtype == y.dtype, topic
            assert np.ascontiguousarray(x).tobytes() == np.ascontiguousarray(y).tobytes(), topic


@pytest.mark.slow
def test_lab_files_with_imu_mag_poses_events_and_ranges_decode_as_the_mcap_library_and_mcap_ros2(tmp_path):
    files, _ = write_lab_session(tmp_path, distance_sensors=True, optical_reference=True)
    kinds = set()
    for f in files:
        ours, res = _read(f)
        _assert_same(ours, _reference(f))
        kinds |= {t.kind for t in res.topics.values()}
    assert {"imu", "mag", "reference_pose", "events", "range"} <= kinds, kinds


@pytest.mark.parametrize("chunk_size", [16 * 1024, 64 * 1024])
def test_a_mcap_ros2_file_with_definitions_inside_chunks_decodes_as_the_reference(tmp_path, monkeypatch, chunk_size):
    """mcap_ros2 puts Schema and Channel records inside the chunks (the walk stops at each, the reader registers
    it, the walk resumes); one group in flight at a time, as in a large file."""
    monkeypatch.setattr(mcap_read, "GROUP_BYTES", 4 * chunk_size)
    monkeypatch.setattr(mcap_read, "MAX_IN_FLIGHT_BYTES", 1)
    f = write_mcap_ros2(tmp_path / "ros2.mcap", small_recording(seconds=30.0), chunk_size=chunk_size)
    ours, res = _read(f)
    _assert_same(ours, _reference(f))
    assert sum(res.message_counts.values()) == sum(len(v[0]) for v in ours.values())


def _write_without_summary(path: Path, n: int, chunk_size: int) -> Path:
    """Imu messages on two channels whose only definitions are inside the first chunk (the mcap library's writer
    without a summary and without repeated definitions): later groups start before those are registered."""
    from mcap.writer import CompressionType, IndexType, Writer
    rng = np.random.default_rng(3)
    with open(path, "wb") as fh:
        w = Writer(fh, chunk_size=chunk_size, compression=CompressionType.ZSTD, index_types=IndexType.NONE,
                   repeat_channels=False, repeat_schemas=False, use_statistics=False, use_summary_offsets=False)
        w.start(profile="ros2", library="test")
        schema = w.register_schema("sensor_msgs/msg/Imu", "ros2msg", IMU_DEF.encode())
        channels = [w.register_channel(topic, "cdr", schema) for topic in ("/imu/chest", "/imu/foot_left")]
        t = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 10_000_000
        for ch in channels:
            msgs = ros2_cdr.encode_imu(t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), "imu")
            for i in range(n):
                w.add_message(ch, log_time=int(t[i]), data=msgs[i].tobytes(), publish_time=int(t[i]))
        w.finish()
    return path


def _chunk_bodies(path: Path) -> list[memoryview]:
    data = memoryview(path.read_bytes())
    p, out = 8, []
    while data[p] != 2:                                     # up to the footer
        n = int.from_bytes(data[p + 1:p + 9], "little")
        if data[p] == 6:
            out.append(data[p + 9:p + 9 + n])
        p += 9 + n
    return out


def test_messages_of_channels_defined_in_a_group_not_yet_registered_are_decoded_in_file_order(tmp_path, monkeypatch):
    """A group decoded before the definitions of an earlier group are registered (the only ones are inside the
    first chunk) keeps those channels' messages located, and the reader decodes them once they are known."""
    monkeypatch.setattr(mcap_read, "GROUP_BYTES", 8 * 1024)
    f = _write_without_summary(tmp_path / "nosummary.mcap", 2000, 4 * 1024)
    ours, _ = _read(f)
    _assert_same(ours, _reference(f))
    assert len(ours["/imu/chest"][0]) == 2000
    first, second = _chunk_bodies(f)[:2]
    (defining,) = mcap_read._group_task([first], mcap_read._Snapshot(({}, {})))
    assert [op for op, _ in defining.defs] == [3, 4, 4] and not defining.pending and defining.blocks
    (waiting,) = mcap_read._group_task([second], mcap_read._Snapshot(({}, {})))
    assert not waiting.blocks and not waiting.defs and sum(len(x[1]) for x in waiting.pending) == waiting.counts[1]


def _message(payload: bytes, channel: int = 1) -> bytes:
    return bytes([5]) + (22 + len(payload)).to_bytes(8, "little") + channel.to_bytes(2, "little") + \
        (0).to_bytes(4, "little") + (123).to_bytes(8, "little") * 2 + payload


def _imu_payload(sec: int, nsec: int, doubles: np.ndarray) -> bytes:
    return b"\x00\x01\x00\x00" + sec.to_bytes(4, "little") + nsec.to_bytes(4, "little") + \
        (1).to_bytes(4, "little") + b"\x00" + b"\x00" * 3 + doubles.astype("<f8").tobytes()


def test_a_message_that_does_not_fit_its_schema_stops_the_walk_with_the_decoders_status():
    slots = {1: (37, np.array([13, 14, 15, 25, 26, 27]))}
    short = _message(_imu_payload(5, 7, np.zeros(36)))                      # one double short
    dec = mcap_decode.GroupDecoder(slots, len(short))
    assert dec.walk(dec.begin(short)) == (mcap_decode.BAD_MESSAGE + 2, 0)
    ok = _message(_imu_payload(5, 7, np.arange(37.0)))
    dec = mcap_decode.GroupDecoder(slots, len(ok))
    assert dec.walk(dec.begin(ok)) is None
    (t, log, v), = dec.result()[0].values()
    assert t.tolist() == [5_000_000_007] and log.tolist() == [123] and v.tolist() == [[13, 14, 15, 25, 26, 27]]


def test_a_channel_that_outgrows_its_rows_and_a_channel_added_mid_chunk_keep_every_message():
    """Arrays sized from a chunk of one message: the rest of the group grows them; a channel given a slot after
    the walk stopped at its first message is decoded from there on, the rows decoded before moved intact."""
    slots = {1: (37, np.array([13, 14, 15, 25, 26, 27]))}
    first = _message(_imu_payload(0, 0, np.full(37, -1.0)))
    later = b"".join(_message(_imu_payload(i, 0, np.full(37, float(i))), channel=1 if i % 2 else 2) for i in range(1, 3001))
    dec = mcap_decode.GroupDecoder(slots, len(first))
    assert dec.walk(dec.begin(first)) is None
    buf = dec.begin(later)
    status, pos = dec.walk(buf)
    assert (status, pos) == (mcap_decode.UNKNOWN_CHANNEL, len(_message(_imu_payload(1, 0, np.zeros(37))))), status
    dec.add_slot(2, (37, np.array([0, 1, 2])))
    assert dec.walk(buf, pos) is None
    out = {dec.slot_channel(s): v for s, v in dec.result()[0].items()}
    assert out[1][0].tolist() == [0] + [i * 1_000_000_000 for i in range(1, 3001, 2)]
    assert out[1][2][:, 0].tolist() == [-1.0] + [float(i) for i in range(1, 3001, 2)]
    assert out[2][2].tolist() == [[float(i)] * 3 for i in range(2, 3001, 2)]
    assert dec.counts.tolist() == [1501, 1500]


def test_messages_outside_chunks_decode_as_the_same_messages_inside_chunks(tmp_path):
    """An unchunked copy (messages outside chunks: the list decoder of ros2_cdr) and the chunked original (the
    walk) give the same samples bit for bit, and both the reference's."""
    from tests.pipeline._interop import rewrite_with_mcap
    src = write_mcap_ros2(tmp_path / "ros2.mcap", small_recording(seconds=10.0), chunk_size=16 * 1024)
    flat = rewrite_with_mcap(src, tmp_path / "flat.mcap", chunked=False)
    (chunked, _), (unchunked, res) = _read(src), _read(flat)
    assert res.unchunked_messages and not res.chunks
    _assert_same(unchunked, chunked)
    _assert_same(unchunked, _reference(flat))
