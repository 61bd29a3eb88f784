"""The reader refuses corrupt files with one readable line (issue 17 point 1, the reader's part):
every CRC checked, payload sizes of fixed-size schemas, bounded chunk memory."""
from __future__ import annotations

import re
import struct
from pathlib import Path

import pytest
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Metadata, Schema

from stridelab.pipeline import runner
from stridelab.pipeline.formats import ros2_cdr
from stridelab.pipeline.formats.mcap_read import MAGIC, McapFormatError, ReadResult, iter_blocks
from stridelab.pipeline.formats.mcap_write import write_recording
from tests.corpus import small_recording

ACTION = re.compile(r"(copy|export|re-export|rewrite|fix|convert|try|map|sort|name them|add)", re.I)


def _records(*recs) -> bytes:
    out = bytearray(MAGIC)
    for r in recs:
        b = RecordBuilder()
        r.write(b)
        out += b.end()
    b = RecordBuilder()
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(b)
    return bytes(out + b.end() + MAGIC)


def _read(path: Path) -> str:
    with pytest.raises(McapFormatError) as e:
        for _ in iter_blocks(path, ReadResult()):
            pass
    msg = str(e.value)
    assert msg and "\n" not in msg and len(msg) < 300 and ACTION.search(msg), msg
    return msg


def _ingest_reason(tmp_path, f) -> str:
    s = runner.run(tmp_path / "wh", None, files=[f], stages=False, command="ingest")
    assert s.ingested == [] and len(s.quarantined) == 1
    r = s.quarantined[0]
    assert r.startswith(f"{f.name}: quarantined: ") and "\n" not in r and ACTION.search(r), r
    return r


def _find(buf: bytes, op: int, start: int = 8) -> int:
    p = start
    while p < len(buf) - 8:
        if buf[p] == op:
            return p
        p += 9 + int.from_bytes(buf[p + 1:p + 9], "little")
    raise AssertionError(f"no record {op:#x}")


def _schema_channel(name="sensor_msgs/msg/MagneticField", topic="/mag/foot_left"):
    return [Header(profile="ros2", library="test"),
            Schema(id=1, name=name, encoding="ros2msg", data=ros2_cdr.SCHEMAS[name].encode()),
            Channel(id=1, schema_id=1, topic=topic, message_encoding="cdr", metadata={})]


def test_imu_payload_on_a_magnetic_field_channel_is_refused(tmp_path):
    from mcap.writer import Writer
    rec = small_recording(seconds=2.0, placements=("foot_left",))
    x = rec.imu["foot_left"]
    payload = ros2_cdr.encode_imu(x.t_ns, x.acc, x.gyr, "foot_left")
    f = tmp_path / "wrong_payload.mcap"
    with open(f, "wb") as fh:
        w = Writer(fh)
        w.start("ros2", "test")
        sid = w.register_schema("sensor_msgs/msg/MagneticField", "ros2msg",
                                ros2_cdr.SCHEMAS["sensor_msgs/msg/MagneticField"].encode())
        cid = w.register_channel("/mag/foot_left", "cdr", sid)
        for t, p in zip(x.t_ns.tolist(), payload):
            w.add_message(cid, t, p.tobytes(), t)
        w.finish()
    assert "payload size does not match the schema" in _read(f)


def test_chunk_declaring_a_terabyte_is_refused_before_any_allocation(tmp_path):
    buf = bytearray(write_recording(small_recording(seconds=3.0), tmp_path / "ok.mcap").read_bytes())
    i = _find(buf, 0x06)
    buf[i + 9 + 16:i + 9 + 24] = (1 << 40).to_bytes(8, "little")
    f = tmp_path / "huge_chunk.mcap"
    f.write_bytes(bytes(buf))
    assert "above the 256 MiB limit" in _read(f)
    assert "above the 256 MiB limit" in _ingest_reason(tmp_path, f)


@pytest.mark.parametrize("content_size", [True, False])
def test_zip_bomb_chunk_is_refused_without_inflating(tmp_path, content_size):
    """200 MB of zeros in a ~6 kB zstd frame, declared as a 1 MB chunk."""
    bomb = zstandard.ZstdCompressor(level=3, write_content_size=content_size).compress(bytes(200 << 20))
    f = tmp_path / "bomb.mcap"
    f.write_bytes(_records(*_schema_channel(), Chunk(message_start_time=0, message_end_time=0,
                                                     uncompressed_size=1 << 20, uncompressed_crc=0,
                                                     compression="zstd", data=bomb), DataEnd(data_section_crc=0)))
    msg = _read(f)
    assert "zstd" in msg or "decompress" in msg, msg


def test_data_section_crc_catches_a_changed_metadata_value(tmp_path):
    f = write_recording(small_recording(seconds=3.0), tmp_path / "ok.mcap")
    buf = bytearray(f.read_bytes())
    i = buf.index(b"P001", _find(buf, 0x0C))
    buf[i:i + 4] = b"P003"
    bad = tmp_path / "flipped.mcap"
    bad.write_bytes(bytes(buf))
    assert "data-section CRC mismatch" in _read(bad)


def test_summary_crc_catches_a_changed_channel_record(tmp_path):
    f = write_recording(small_recording(seconds=3.0), tmp_path / "ok.mcap")
    buf = bytearray(f.read_bytes())
    footer = len(buf) - 8 - 29
    summary_start = int.from_bytes(buf[footer + 9:footer + 17], "little")
    i = buf.index(b"/imu/shank_left", summary_start)
    buf[i + 5] ^= 0x01                              # /imu/shank_left -> /imu/rhank_left
    bad = tmp_path / "summary.mcap"
    bad.write_bytes(bytes(buf))
    assert "summary CRC mismatch" in _read(bad)


def test_chunk_crc_is_checked(tmp_path):
    f = write_recording(small_recording(seconds=3.0), tmp_path / "ok.mcap")
    buf = bytearray(f.read_bytes())
    i = _find(buf, 0x06)
    buf[i + 9 + 24] ^= 0xFF
    bad = tmp_path / "chunk_crc.mcap"
    bad.write_bytes(bytes(buf))
    assert "chunk CRC mismatch" in _read(bad)


def test_two_channels_sharing_an_id_are_refused(tmp_path):
    recs = _schema_channel() + [Channel(id=1, schema_id=1, topic="/mag/thigh_left", message_encoding="cdr", metadata={}),
                                DataEnd(data_section_crc=0)]
    f = tmp_path / "shared_id.mcap"
    f.write_bytes(_records(*recs))
    assert "channel id 1 is defined twice" in _read(f)


@pytest.mark.parametrize("cut", [0.3, 0.999])
def test_truncation_and_garbage_lengths_give_readable_reasons(tmp_path, cut):
    f = write_recording(small_recording(seconds=3.0), tmp_path / "ok.mcap")
    buf = f.read_bytes()
    t = tmp_path / "cut.mcap"
    t.write_bytes(buf[:int(len(buf) * cut)])
    assert "truncated" in _read(t)
    g = bytearray(buf)
    i = _find(g, 0x0C)                               # a Metadata record's length -> 2**63
    g[i + 1:i + 9] = (1 << 63).to_bytes(8, "little")
    t.write_bytes(bytes(g))
    msg = _read(t)
    assert "EndOfFile" not in msg and "UTF" not in msg


def test_metadata_that_is_not_utf8_is_a_readable_reason(tmp_path):
    b = RecordBuilder()
    Metadata(name="session", metadata={"study": "x"}).write(b)
    rec = bytearray(b.end())
    rec[-1] = 0xFF                                    # last byte of the value: invalid UTF-8
    data = bytearray(_records(Header(profile="", library="t"), DataEnd(data_section_crc=0)))
    i = _find(data, 0x0F)
    data[i:i] = rec
    f = tmp_path / "utf.mcap"
    f.write_bytes(bytes(data))
    assert "not UTF-8" in _read(f)


def test_statistics_disagreeing_with_the_messages_is_refused(tmp_path):
    """A chunk removed from the data section (and its index): the Statistics record still counts it."""
    f = write_recording(small_recording(seconds=3.0), tmp_path / "ok.mcap", chunk_bytes=64 * 1024)
    buf = bytearray(f.read_bytes())
    i = _find(buf, 0x06)
    n = 9 + int.from_bytes(buf[i + 1:i + 9], "little")
    j = i + n
    while buf[j] == 0x07:                            # its message indexes
        j += 9 + int.from_bytes(buf[j + 1:j + 9], "little")
    cut = bytes(buf[:i] + buf[j:])
    footer = len(cut) - 37
    s_start = int.from_bytes(cut[footer + 9:footer + 17], "little") - (j - i)
    s_off = int.from_bytes(cut[footer + 17:footer + 25], "little") - (j - i)
    out = bytearray(cut)
    out[footer + 9:footer + 25] = struct.pack("<QQ", s_start, s_off)
    out[footer + 25:footer + 29] = b"\0\0\0\0"       # no summary CRC (its offsets moved)
    d = _find(out, 0x0F)
    out[d + 9:d + 13] = b"\0\0\0\0"                  # and no data-section CRC: only the counts can tell
    bad = tmp_path / "missing_chunk.mcap"
    bad.write_bytes(bytes(out))
    assert "the Statistics record counts" in _read(bad)
