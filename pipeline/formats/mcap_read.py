"""Vectorised reader for StrideLab MCAP recordings.

Records are streamed in file order with the ``mcap`` library (one Python step per *chunk*, not per
message); inside a chunk a numba kernel locates the message records and the CDR decoders of
:mod:`pipeline.formats.ros2_cdr` turn a whole channel into arrays at once. The file's SHA-256 is
computed on the same pass. Errors are raised as :class:`McapFormatError` with a one-line reason.
"""
from __future__ import annotations

import hashlib
import io
import json
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Metadata, Schema
from numba import njit

from pipeline.formats import ros2_cdr

#: schema expected on each topic family of the recording format
TOPIC_SCHEMAS = {"/imu/": "sensor_msgs/msg/Imu", "/mag/": "sensor_msgs/msg/MagneticField",
                 "/range/": "sensor_msgs/msg/Range", "/reference/pose/": "geometry_msgs/msg/PoseStamped"}


MAGIC = b"\x89MCAP0\r\n"
_WANTED = {Opcode.SCHEMA, Opcode.CHANNEL, Opcode.CHUNK, Opcode.MESSAGE, Opcode.METADATA}


class McapFormatError(ValueError):
    """The file is not a readable recording; ``str(err)`` is a one-line reason."""


@dataclass
class Block:
    """Decoded messages of one channel from one chunk.

    ``values`` columns: imu ``gyr xyz, acc xyz``; mag ``xyz`` (tesla); pose ``pos xyz, quat wxyz``;
    range ``fov, min, max, range``; events: ``values`` is a list of dicts.
    """
    topic: str
    kind: str                     # imu | mag | range | reference_pose | events
    t_ns: np.ndarray              # header.stamp (sensor time)
    log_ns: np.ndarray
    values: np.ndarray | list


@dataclass
class TopicInfo:
    topic: str
    schema_name: str
    message_encoding: str
    kind: str


@dataclass
class ReadResult:
    """What a full pass over a file produced besides the blocks."""
    sha256: str = ""
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    topics: dict[int, TopicInfo] = field(default_factory=dict)
    ignored_topics: list[str] = field(default_factory=list)
    n_bytes: int = 0


class _HashingReader:
    """File wrapper that feeds every byte read into SHA-256."""

    def __init__(self, f):
        self._f = f
        self.h = hashlib.sha256()
        self.n = 0

    def read(self, n=-1):
        b = self._f.read(n)
        self.h.update(b)
        self.n += len(b)
        return b

    def readinto(self, buf):                 # pragma: no cover - used by some BufferedReader paths
        n = self._f.readinto(buf)
        self.h.update(memoryview(buf)[:n])
        self.n += n
        return n


@njit(cache=True)
def _scan_messages(buf, ch_out, log_out, start_out, len_out):
    """Locate Message records (opcode 0x05) in uncompressed chunk bytes; returns count or -1 if malformed."""
    p = 0
    k = 0
    n = buf.shape[0]
    while p < n:
        if p + 9 > n:
            return -1
        op = buf[p]
        length = np.int64(0)
        for b in range(8):
            length |= np.int64(buf[p + 1 + b]) << (8 * b)
        if length < 0 or p + 9 + length > n:
            return -1
        if op == 5:
            if length < 22:
                return -1
            q = p + 9
            ch_out[k] = np.int64(buf[q]) | (np.int64(buf[q + 1]) << 8)
            t = np.int64(0)
            for b in range(8):
                t |= np.int64(buf[q + 6 + b]) << (8 * b)
            log_out[k] = t
            start_out[k] = q + 22
            len_out[k] = length - 22
            k += 1
        p += 9 + length
    return k


def _kind_of(topic: str, schema_name: str) -> str | None:
    """Kind of a topic in the recording format, None for topics StrideLab does not use."""
    if topic == "/reference/events":
        return "events"
    for prefix, expected in TOPIC_SCHEMAS.items():
        if topic.startswith(prefix):
            if schema_name != expected:
                raise McapFormatError(f"topic {topic} has schema '{schema_name or '(none)'}', expected {expected}")
            return {"/imu/": "imu", "/mag/": "mag", "/range/": "range", "/reference/pose/": "reference_pose"}[prefix]
    return None


def _decompress(chunk: Chunk) -> bytes:
    if chunk.compression == "zstd":
        return zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    if chunk.compression == "lz4":
        return lz4.frame.decompress(chunk.data)
    if chunk.compression == "":
        return chunk.data
    raise McapFormatError(f"unsupported chunk compression '{chunk.compression}'")


def _decode(topic: TopicInfo, buf: np.ndarray, starts, lengths, log_ns) -> Block:
    if topic.kind == "events":
        vals = []
        for s, n in zip(starts.tolist(), lengths.tolist()):
            try:
                vals.append(json.loads(bytes(buf[s:s + n])))
            except ValueError as e:
                raise McapFormatError(f"{topic.topic}: message is not valid JSON ({e})") from None
        t = np.array([int(v.get("t_ns", lt)) for v, lt in zip(vals, log_ns.tolist())], dtype=np.int64)
        return Block(topic.topic, "events", t, log_ns, vals)
    if topic.kind == "range":
        t, vals, status = ros2_cdr.decode_range(buf, starts, lengths)
    else:
        fields = {"imu": ros2_cdr.IMU_FIELDS, "mag": ros2_cdr.MAG_FIELDS,
                  "reference_pose": ros2_cdr.POSE_FIELDS}[topic.kind]
        t, vals, status = ros2_cdr.decode_doubles(buf, starts, lengths, fields)
    if status.any():
        i = int(np.flatnonzero(status)[0])
        why = "big-endian or unknown CDR encapsulation" if status[i] == 1 else "message shorter than its schema"
        raise McapFormatError(f"{topic.topic}: {why} (message {i} of a chunk)")
    return Block(topic.topic, topic.kind, t, log_ns, vals)


def iter_blocks(path: str | Path, result: ReadResult) -> Iterator[Block]:
    """Stream decoded blocks of every StrideLab topic of ``path``; fills ``result`` along the way.

    Raises McapFormatError (one-line reason) for empty, truncated or corrupt files, CRC mismatches
    and unexpected schemas on recording-format topics.
    """
    path = Path(path)
    size = path.stat().st_size
    if size == 0:
        raise McapFormatError("empty file (0 bytes)")
    schemas: dict[int, Schema] = {}
    with open(path, "rb") as raw:
        f = _HashingReader(raw)
        try:
            for op, body in _records(f):
                if op == Opcode.SCHEMA:
                    rec = Schema.read(ReadDataStream(io.BytesIO(body)))
                    schemas[rec.id] = rec
                elif op == Opcode.CHANNEL:
                    rec = Channel.read(ReadDataStream(io.BytesIO(body)))
                    if rec.id in result.topics or rec.topic in result.ignored_topics:
                        continue
                    sch = schemas.get(rec.schema_id)
                    name = sch.name if sch else ""
                    kind = _kind_of(rec.topic, name)
                    if kind is None:
                        result.ignored_topics.append(rec.topic)
                        continue
                    if kind != "events" and rec.message_encoding != "cdr":
                        raise McapFormatError(f"topic {rec.topic} uses message encoding "
                                              f"'{rec.message_encoding}', expected cdr")
                    result.topics[rec.id] = TopicInfo(rec.topic, name, rec.message_encoding, kind)
                elif op == Opcode.CHUNK:
                    rec = Chunk.read(ReadDataStream(io.BytesIO(body)))
                    data = _decompress(rec)
                    if len(data) != rec.uncompressed_size:
                        raise McapFormatError("chunk size does not match its header (corrupt chunk)")
                    if rec.uncompressed_crc and zlib.crc32(data) != rec.uncompressed_crc:
                        raise McapFormatError(f"chunk CRC mismatch at chunk starting "
                                              f"{rec.message_start_time} ns (corrupt file)")
                    yield from _blocks_from_records(np.frombuffer(data, dtype=np.uint8), result)
                elif op == Opcode.MESSAGE:
                    buf = np.frombuffer(b"\x05" + len(body).to_bytes(8, "little") + body, dtype=np.uint8)
                    yield from _blocks_from_records(buf, result)
                elif op == Opcode.METADATA:
                    rec = Metadata.read(ReadDataStream(io.BytesIO(body)))
                    result.metadata[rec.name] = dict(rec.metadata)
        except McapFormatError:
            raise
        except (McapError, ValueError, KeyError, UnicodeDecodeError, struct.error, zstandard.ZstdError) as e:
            msg = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise McapFormatError(f"corrupt MCAP: {msg}") from None
    result.sha256 = f.h.hexdigest()
    result.n_bytes = f.n


def _records(f) -> Iterator[tuple[int, bytes]]:
    """(opcode, body) of every record up to the footer; index records are read (for the hash) but skipped."""
    if f.read(8) != MAGIC:
        raise McapFormatError("not an MCAP file (bad magic bytes at the start)")
    while True:
        head = f.read(9)
        if len(head) < 9:
            raise McapFormatError("truncated MCAP: the file ends before its footer "
                                  "(copy interrupted? try `mcap recover`)")
        op, length = struct.unpack("<BQ", head)
        if length > (4 << 30):
            raise McapFormatError(f"corrupt MCAP: record of {length} bytes")
        body = f.read(length)
        if len(body) < length:
            raise McapFormatError("truncated MCAP: the file ends inside a record "
                                  "(copy interrupted? try `mcap recover`)")
        if op == Opcode.FOOTER:
            if f.read(8) != MAGIC:
                raise McapFormatError("truncated MCAP: no closing magic after the footer")
            return
        if op in _WANTED:
            yield op, body


def _blocks_from_records(buf: np.ndarray, result: ReadResult) -> Iterator[Block]:
    cap = len(buf) // 31 + 1
    ch = np.empty(cap, np.int64)
    log = np.empty(cap, np.int64)
    st = np.empty(cap, np.int64)
    ln = np.empty(cap, np.int64)
    n = _scan_messages(buf, ch, log, st, ln)
    if n < 0:
        raise McapFormatError("malformed records inside a chunk (corrupt file)")
    ch, log, st, ln = ch[:n], log[:n], st[:n], ln[:n]
    for cid in np.unique(ch):
        ti = result.topics.get(int(cid))
        if ti is None:
            continue
        m = ch == cid
        yield _decode(ti, buf, st[m], ln[m], log[m])


def read_metadata(path: str | Path) -> dict[str, dict[str, str]]:
    """Metadata records via the summary index (cheap); empty dict if the file has no index."""
    from mcap.reader import make_reader
    try:
        with open(path, "rb") as f:
            return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    except Exception:  # noqa: BLE001 - a broken index is reported by the full pass
        return {}
