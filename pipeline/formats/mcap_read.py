"""Vectorised reader for any valid MCAP file (spec v0) carrying the recording format's messages.

What it accepts: Schema and Channel records anywhere (top level, inside chunks, or only in the
summary), chunked or unchunked files, zstd, lz4 or uncompressed chunks, messages in any order and
overlapping chunks. What it verifies: the magic at both ends, the summary CRC (footer), the
data-section CRC (DataEnd), every chunk's CRC, the declared sizes of every record, the payload size of
every message of a fixed-size schema, channels that are defined twice with different content, and the
per-channel message counts of the Statistics record. Every failure is a :class:`McapFormatError` with
a one-line reason (what is wrong and what to do); no low-level exception leaks out.

How it is fast: the file is read in large blocks; a numba kernel splits a block (or a decompressed
chunk) into records, so Python runs once per chunk, never once per message; chunks are decompressed,
checked and decoded by a small thread pool (zstandard, lz4, the CRC and the numba kernels release the
GIL). Consecutive chunks (up to :data:`GROUP_BYTES`) form one task, so the consumer runs once per ~8 MiB
whatever chunk size the writer chose. Every chunk of every file takes the one decode path,
:mod:`stridelab.pipeline.formats.mcap_decode`: one kernel pass per chunk right after its decompression, each message
decoded straight into the group's arrays (definitions inside chunks, messages on channels defined later,
annotations and ranges handled inside that walk), and its errors say what is wrong. Messages outside chunks
(unchunked files) and those whose channel is defined in a later group are decoded per channel by the same CDR
decoders of :mod:`stridelab.pipeline.formats.ros2_cdr` (:func:`_decode_records`). Blocks are yielded
in file order while at most a bounded number of chunks is in flight, so memory does not grow with the
length of the recording. The file's SHA-256 and the data-section CRC
are computed on the same pass, on a separate thread.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import struct
import threading
from collections import deque
from contextlib import ExitStack
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.records import Channel, Metadata, Schema, Statistics
from numba import njit

from stridelab.pipeline.formats import mcap_decode, ros2_cdr
from stridelab.pipeline.formats.direct_read import SequentialReader

try:                                   # ISA-L's CRC32 is ~4x faster than zlib's; same polynomial
    from isal.isal_zlib import crc32
except ImportError:                    # pragma: no cover - isal is a dependency; zlib is the fallback
    from zlib import crc32

MAGIC = b"\x89MCAP0\r\n"
#: largest uncompressed chunk accepted (a chunk must fit in memory; standard writers use 1-8 MiB)
MAX_CHUNK_BYTES = 256 << 20
#: largest record outside chunks that is read into memory (attachments, metadata, schemas)
MAX_RECORD_BYTES = 256 << 20
READ_BLOCK = 8 << 20
#: uncompressed bytes of chunks decoded ahead of the consumer (bounds memory)
MAX_IN_FLIGHT_BYTES = 96 << 20
#: consecutive chunks handed to one decoding task, up to this many uncompressed bytes; each chunk is still
#: decompressed, scanned and decoded on its own (in the core's cache), but a channel's messages of the whole
#: group leave as one block, so everything downstream runs in Python once per ~8 MiB instead of once per
#: 1 MiB chunk (the default of the ROS 2 writers)
GROUP_BYTES = 8 << 20

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_METADATA, OP_DATA_END, OP_STATISTICS = 0x0C, 0x0F, 0x0B

#: schema -> kind of decoded block
SCHEMA_KINDS = {"sensor_msgs/msg/Imu": "imu", "sensor_msgs/msg/MagneticField": "mag",
                "sensor_msgs/msg/Range": "range", "geometry_msgs/msg/PoseStamped": "reference_pose",
                ros2_cdr.ANNOTATION: "events"}
#: schema expected on each topic family of the recording format
TOPIC_SCHEMAS = {"/imu/": "sensor_msgs/msg/Imu", "/mag/": "sensor_msgs/msg/MagneticField",
                 "/range/": "sensor_msgs/msg/Range", "/reference/pose/": "geometry_msgs/msg/PoseStamped"}
_FIELDS = {"imu": ros2_cdr.IMU_FIELDS, "mag": ros2_cdr.MAG_FIELDS, "reference_pose": ros2_cdr.POSE_FIELDS}
_N_DOUBLES = {"imu": 37, "mag": 12, "reference_pose": 7}
_FIX = "the file is corrupt: export or copy it again"


def read_threads() -> int:
    """Threads decoding chunks (env ``STRIDELAB_READ_THREADS``; default: the CPUs this process may use)."""
    env = os.environ.get("STRIDELAB_READ_THREADS")
    if env:
        return max(1, int(env))
    try:
        return max(1, min(4, len(os.sched_getaffinity(0))))
    except AttributeError:          # pragma: no cover - not Linux
        return max(1, min(4, os.cpu_count() or 1))


class McapFormatError(ValueError):
    """The file is not a readable recording; ``str(err)`` is a one-line reason."""


@dataclass
class Block:
    """Decoded messages of one channel from one chunk (or one block of unchunked messages).

    ``values`` columns: imu ``gyr xyz, acc xyz``; mag ``xyz`` (tesla); pose ``pos xyz, quat wxyz``;
    range ``fov, min, max, range``; events: ``values`` is a list of dicts.
    """
    topic: str
    kind: str                     # imu | mag | range | reference_pose | events
    t_ns: np.ndarray              # header.stamp (sensor time)
    log_ns: np.ndarray
    values: np.ndarray | list
    checks: object = None         # what a consumer's ``on_block`` attached on the decoding thread


@dataclass
class TopicInfo:
    topic: str
    schema_name: str
    message_encoding: str
    kind: str | None              # None: a topic StrideLab does not decode
    range_variance: bool = False  # sensor_msgs/Range with the ``variance`` field (ROS 2 Jazzy and later)


@dataclass
class ReadResult:
    """What a full pass over a file produced besides the blocks."""
    sha256: str = ""
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    topics: dict[int, TopicInfo] = field(default_factory=dict)
    ignored_topics: list[str] = field(default_factory=list)
    n_bytes: int = 0
    message_counts: dict[int, int] = field(default_factory=dict)
    statistics: Statistics | None = None
    # CRC coverage (docs/integrity.md): chunks seen, of them with CRC 0 (the writer computed none), messages
    # outside chunks, and whether the DataEnd record carries a data-section CRC
    chunks: int = 0
    chunks_without_crc: int = 0
    unchunked_messages: bool = False
    data_crc: bool = False

    @property
    def crc_verified(self) -> bool:
        """Every message was covered by a CRC that was checked (its chunk's, or the data section's)."""
        if self.chunks_without_crc:
            return False
        if self.unchunked_messages or not self.chunks:
            return self.data_crc
        return True

    def found_topics(self) -> list[str]:
        """``topic (schema)`` of every channel of the file, for messages that list what was found."""
        return sorted({f"{t.topic} ({t.schema_name or 'no schema'})" for t in self.topics.values()})


# ---- record scanning kernels -----------------------------------------------------------------

@njit(cache=True, nogil=True)
def _u64(buf, p):
    q = np.uint64(p)                     # unsigned: no wraparound per byte, one 8-byte load (mcap_decode._u64)
    v = np.uint64(0)
    for b in range(8):
        v |= np.uint64(buf[q + np.uint64(b)]) << np.uint64(8 * b)
    return v


@njit(cache=True, nogil=True)
def _count_records(buf, p, end, stop_at_footer):
    """(records, messages, position after the last complete record, status) from ``p`` up to ``end``.

    status 0: stopped at ``end`` or at an incomplete record; 2: a footer record was passed;
    -1: a record declares a length that runs past 2**62 (garbage).
    """
    n_rec = 0
    n_msg = 0
    while p + 9 <= end:
        length = _u64(buf, p + 1)
        if length > np.uint64(1) << np.uint64(62):
            return n_rec, n_msg, p, -1
        if p + 9 + np.int64(length) > end:
            break
        op = buf[p]
        n_rec += 1
        if op == 5:
            n_msg += 1
        p += 9 + np.int64(length)
        if stop_at_footer and op == 2:
            return n_rec, n_msg, p, 2
    return n_rec, n_msg, p, 0


@njit(cache=True, nogil=True)
def _split_records(buf, p, end, stop_at_footer, o_op, o_start, o_len, m_ch, m_log, m_start, m_len):
    """Fill record tables (non-message records and message records separately); returns 0 or the
    index + 1 of the first message record shorter than its fixed header (corrupt)."""
    i = 0
    k = 0
    while p + 9 <= end:
        length = np.int64(_u64(buf, p + 1))
        if p + 9 + length > end:
            break
        op = buf[p]
        if op == 5:
            if length < 22:
                return k + 1
            q = p + 9
            m_ch[k] = np.int64(buf[q]) | (np.int64(buf[q + 1]) << 8)
            m_log[k] = np.int64(_u64(buf, q + 6))
            m_start[k] = q + 22
            m_len[k] = length - 22
            k += 1
        else:
            o_op[i] = op
            o_start[i] = p + 9
            o_len[i] = length
            i += 1
        p += 9 + length
        if stop_at_footer and op == 2:
            break
    return 0


@dataclass
class _Records:
    """Records of one buffer: non-message records (op, body start, body length) and message records."""
    buf: np.ndarray
    ops: np.ndarray
    starts: np.ndarray
    lengths: np.ndarray
    m_ch: np.ndarray
    m_log: np.ndarray
    m_start: np.ndarray
    m_len: np.ndarray
    end: int                       # position after the last complete record
    footer: bool


def _scan(buf: np.ndarray, p: int, end: int, stop_at_footer: bool) -> _Records:
    n_rec, n_msg, stop, status = _count_records(buf, p, end, stop_at_footer)
    if status < 0:
        raise McapFormatError(f"a record declares an impossible length; {_FIX}")
    n_oth = n_rec - n_msg
    o = [np.empty(n_oth, np.uint8), np.empty(n_oth, np.int64), np.empty(n_oth, np.int64)]
    m = [np.empty(n_msg, np.int64) for _ in range(4)]
    bad = _split_records(buf, p, stop, stop_at_footer, *o, *m)
    if bad:
        raise McapFormatError(f"a Message record is shorter than its fixed fields; {_FIX}")
    return _Records(buf, *o, *m, end=int(stop), footer=status == 2)


def _parse(cls, body, what: str):
    """Parse one record body with the mcap library; any failure becomes a readable reason."""
    try:
        return cls.read(ReadDataStream(io.BytesIO(bytes(body))))
    except UnicodeDecodeError:
        raise McapFormatError(f"a {what} record holds text that is not UTF-8; {_FIX}") from None
    except Exception:  # noqa: BLE001 - EndOfFile, struct errors: all mean a corrupt record
        raise McapFormatError(f"a {what} record is malformed (its fields run past its length); {_FIX}") from None


# ---- channel registry ------------------------------------------------------------------------

def _normalise_schema(name: str) -> str:
    """``sensor_msgs/Imu`` (ROS 1 style name) -> ``sensor_msgs/msg/Imu``."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def encoding_fix(encoding: str) -> str:
    """What to do about messages in an encoding StrideLab does not read (it reads ROS 2 CDR)."""
    e = (encoding or "").lower()
    if e in ("ros1", "ros1msg"):
        return "ROS 1 messages: convert the bag to ROS 2 (`rosbags-convert --src BAG --dst FOLDER`) and ingest that"
    if e in ("json", "protobuf", "flatbuffer", "cbor"):
        return (f"{e} messages: StrideLab reads ROS 2 CDR; record with `ros2 bag record` (CDR by default) or write "
                f"the file with the mcap_ros2 writer")
    return f"'{e[:20]}' messages: StrideLab reads ROS 2 CDR; re-export with CDR encoding"


def _topic_info(ch: Channel, sch: Schema | None) -> TopicInfo:
    name = _normalise_schema(sch.name) if sch else ""
    kind = SCHEMA_KINDS.get(name)
    if ch.topic == "/reference/events" and (ch.message_encoding == "json" or kind == "events"):
        kind = "events"
    for prefix, expected in TOPIC_SCHEMAS.items():
        if ch.topic.startswith(prefix) and name != expected:
            if ch.message_encoding != "cdr":
                raise McapFormatError(f"topic {ch.topic} holds {encoding_fix(ch.message_encoding)}")
            raise McapFormatError(f"topic {ch.topic} has schema '{name or '(none)'}', expected {expected}; "
                                  f"fix the exporter or rename the topic")
    if kind is not None and kind != "events" and ch.message_encoding != "cdr":
        raise McapFormatError(f"topic {ch.topic} ({name}) holds {encoding_fix(ch.message_encoding)}")
    variance = bool(kind == "range" and sch is not None and b"float32 variance" in
                    bytes(sch.data).split(b"=" * 80)[0])
    return TopicInfo(ch.topic, name, ch.message_encoding, kind, variance)


class _Registry:
    """Schemas and channels as defined so far; a second definition must repeat the first exactly."""

    def __init__(self, schemas: dict[int, Schema] | None = None):
        self.schemas: dict[int, Schema] = dict(schemas or {})
        self.channels: dict[int, Channel] = {}
        self.topics: dict[int, TopicInfo] = {}
        self._snap = None

    def add_schema(self, s: Schema) -> None:
        old = self.schemas.get(s.id)
        if old is None:
            if s.id == 0:
                raise McapFormatError(f"a Schema record uses the reserved id 0; {_FIX}")
            self.schemas[s.id] = s
            self._snap = None
        elif (old.name, old.encoding, bytes(old.data)) != (s.name, s.encoding, bytes(s.data)):
            raise McapFormatError(f"schema id {s.id} is defined twice with different content; {_FIX}")

    def add_channel(self, c: Channel) -> None:
        old = self.channels.get(c.id)
        if old is not None:
            if (old.topic, old.schema_id, old.message_encoding, dict(old.metadata)) != \
                    (c.topic, c.schema_id, c.message_encoding, dict(c.metadata)):
                raise McapFormatError(f"channel id {c.id} is defined twice with different content "
                                      f"({old.topic} / {c.topic}); {_FIX}")
            return
        if c.schema_id and c.schema_id not in self.schemas:
            raise McapFormatError(f"channel {c.topic} refers to schema id {c.schema_id}, which no Schema "
                                  f"record defines; {_FIX}")
        if any(t.topic == c.topic for t in self.topics.values()):
            raise McapFormatError(f"topic {c.topic} appears on two channels; re-export with one channel per topic")
        self.channels[c.id] = c
        self.topics[c.id] = _topic_info(c, self.schemas.get(c.schema_id))
        self._snap = None

    def snapshot(self) -> "_Snapshot":
        """Copies of the definitions so far (shared read-only by the chunk tasks until the next change)."""
        if self._snap is None:
            self._snap = _Snapshot((dict(self.schemas), dict(self.topics)))
        return self._snap


class _Snapshot(tuple):
    """(schemas, topics) of a registry at one moment; carries the decoder's slots for them once made
    (:func:`_slots`)."""


# ---- decoding --------------------------------------------------------------------------------

_STATUS = {1: "big-endian or unknown CDR encapsulation", 2: "message shorter than its schema",
           3: "payload size does not match the schema (a message of another type on this channel?)",
           4: "header.stamp nanoseconds out of range"}


def _decode(ti: TopicInfo, buf: np.ndarray, starts, lengths, log_ns) -> Block:
    if ti.kind == "events":
        vals = []
        for s, n in zip(starts.tolist(), lengths.tolist()):
            raw = bytes(buf[s:s + n])
            try:
                vals.append(ros2_cdr.decode_annotation(raw) if ti.message_encoding == "cdr" else json.loads(raw))
            except (ValueError, UnicodeDecodeError, IndexError, struct.error):
                raise McapFormatError(f"{ti.topic}: an annotation message cannot be decoded; {_FIX}") from None
            if not isinstance(vals[-1], dict):
                raise McapFormatError(f"{ti.topic}: an annotation message is not a JSON object")
        try:
            t = np.array([int(v.get("t_ns", lt)) for v, lt in zip(vals, log_ns.tolist())], dtype=np.int64)
        except (TypeError, ValueError, OverflowError):
            raise McapFormatError(f"{ti.topic}: an annotation has a 't_ns' that is not an integer") from None
        return Block(ti.topic, "events", t, log_ns, vals)
    if ti.kind == "range":
        t, vals, status = ros2_cdr.decode_range(buf, starts, lengths, ti.range_variance)
    else:
        t, vals, status = ros2_cdr.decode_doubles(buf, starts, lengths, _FIELDS[ti.kind], _N_DOUBLES[ti.kind])
    if status.any():
        i = int(np.flatnonzero(status)[0])
        raise McapFormatError(f"{ti.topic} ({ti.schema_name}): {_STATUS[int(status[i])]} "
                              f"(message {i} of a chunk); {_FIX}")
    return Block(ti.topic, ti.kind, t, log_ns, vals)


@dataclass
class _Piece:
    """Result of one chunk (or block of top-level messages): decoded blocks, the records that define
    schemas/channels (to be registered in file order), and messages whose channel was not known yet."""
    blocks: list[Block]
    defs: list[tuple[int, object]]
    counts: dict[int, int]
    pending: list = field(default_factory=list)   # [(buf, ch, log, start, len)] of unresolved messages


def _decode_records(recs: _Records, snap, on_block=None) -> _Piece:
    """Decode message records found outside chunks (or left unresolved by a group), per channel."""
    _, known = snap
    blocks, counts, pend = [], {}, []
    if len(recs.m_ch):
        if recs.m_ch[0] == recs.m_ch.min() == recs.m_ch.max():      # one channel: no grouping needed
            ids, bounds, order = [int(recs.m_ch[0])], [0, len(recs.m_ch)], None
        else:
            order = np.argsort(recs.m_ch, kind="stable")
            ids, first = np.unique(recs.m_ch[order], return_index=True)
            ids, bounds = ids.tolist(), list(first) + [len(order)]
        missing = []
        for j, cid in enumerate(ids):
            sel = slice(None) if order is None else order[bounds[j]:bounds[j + 1]]
            counts[cid] = bounds[j + 1] - bounds[j]
            ti = known.get(cid)
            if ti is None:
                missing.append(sel)
                continue
            if ti.kind is None:
                continue
            blk = _decode(ti, recs.buf, recs.m_start[sel], recs.m_len[sel], recs.m_log[sel])
            blocks.append(on_block(blk) if on_block is not None else blk)
        if missing:
            sel = np.sort(np.concatenate([np.arange(len(recs.m_ch))[m] for m in missing]))
            pend = [(recs.buf, recs.m_ch[sel], recs.m_log[sel], recs.m_start[sel], recs.m_len[sel])]
    return _Piece(blocks, [], counts, pend)


_LOCAL = threading.local()


def _zstd() -> zstandard.ZstdDecompressor:
    """This thread's zstd decompressor (a new one per chunk re-initialised its context every time)."""
    d = getattr(_LOCAL, "zstd", None)
    if d is None:
        d = _LOCAL.zstd = zstandard.ZstdDecompressor()
    return d


def _decompress(compression: str, data, size: int) -> bytes:
    """Decompress at most ``size`` bytes (a zip bomb cannot make it allocate more)."""
    if compression == "zstd":
        declared = zstandard.frame_content_size(data)
        if declared not in (-1, size):
            raise McapFormatError(f"a zstd chunk declares {declared} bytes but its header says {size}; {_FIX}")
        return _zstd().decompress(data, max_output_size=size)
    if compression == "lz4":
        d = lz4.frame.LZ4FrameDecompressor()
        return d.decompress(data, max_length=size + 1)
    if compression == "":
        return bytes(data)
    raise McapFormatError(f"unsupported chunk compression '{compression[:20]}'; rewrite the file with "
                          f"`mcap compress --compression zstd`")


def _chunk_raw(body: memoryview) -> bytes:
    """The decompressed records of one chunk record, its sizes and CRC verified."""
    if len(body) < 40:
        raise McapFormatError(f"a Chunk record is shorter than its fixed fields; {_FIX}")
    size, crc = struct.unpack_from("<QI", body, 16)
    clen = struct.unpack_from("<I", body, 28)[0]
    if 32 + clen + 8 > len(body):
        raise McapFormatError(f"a Chunk record's compression field runs past the record; {_FIX}")
    try:
        compression = bytes(body[32:32 + clen]).decode()
    except UnicodeDecodeError:
        raise McapFormatError(f"a Chunk record's compression name is not text; {_FIX}") from None
    rlen = struct.unpack_from("<Q", body, 32 + clen)[0]
    data = body[40 + clen:]
    if rlen != len(data):
        raise McapFormatError(f"a Chunk record's data length disagrees with the record length; {_FIX}")
    try:
        raw = _decompress(compression, data, size)
    except McapFormatError:
        raise
    except (zstandard.ZstdError, RuntimeError, ValueError, MemoryError) as e:
        raise McapFormatError(f"a {compression} chunk cannot be decompressed ({type(e).__name__}); {_FIX}") from None
    if len(raw) != size:
        raise McapFormatError(f"a chunk decompresses to a size other than the one its header declares; {_FIX}")
    if crc and crc32(raw) != crc:
        raise McapFormatError(f"chunk CRC mismatch (data changed after writing); {_FIX}")
    return raw


def _chunk_size(body: memoryview) -> int:
    """Uncompressed size a chunk record declares (0 for a record too short to say)."""
    return struct.unpack_from("<Q", body, 16)[0] if len(body) >= 24 else 0


def _merge_blocks(blocks: list[Block]) -> Block:
    """One topic's consecutive blocks as one (values stay column-contiguous, as the decoders give them)."""
    if len(blocks) == 1:
        return blocks[0]
    b0 = blocks[0]
    t = np.concatenate([b.t_ns for b in blocks])
    log = np.concatenate([b.log_ns for b in blocks])
    if b0.kind == "events":
        return Block(b0.topic, b0.kind, t, log, [v for b in blocks for v in b.values])
    vals = np.empty((len(t), b0.values.shape[1]), dtype=b0.values.dtype, order="F")
    for k in range(vals.shape[1]):
        np.concatenate([b.values[:, k] for b in blocks], out=vals[:, k])
    return Block(b0.topic, b0.kind, t, log, vals)


def _spec(ti: TopicInfo):
    """How the decoder takes a channel's messages (:class:`~stridelab.pipeline.formats.mcap_decode.GroupDecoder`)."""
    if ti.kind is None:
        return None
    if ti.kind in _FIELDS:
        return _N_DOUBLES[ti.kind], _FIELDS[ti.kind]
    return mcap_decode.LOCATE


def _slots(snap: "_Snapshot") -> mcap_decode.Slots:
    """The decoder's slots of a registry snapshot, made once per snapshot and kept with it (a file has one or a few
    snapshots; no cache outlives the file's read)."""
    slots = getattr(snap, "slots", None)
    if slots is None:               # two threads may both make it: the same tables
        slots = snap.slots = mcap_decode.Slots({cid: _spec(ti) for cid, ti in snap[1].items()})
    return slots


def _walk_error(status: int, pos: int, dec: mcap_decode.GroupDecoder, buf: np.ndarray, known: dict) -> str:
    if status == mcap_decode.SHORT_MESSAGE:
        return f"a Message record is shorter than its fixed fields; {_FIX}"
    if status == mcap_decode.IMPOSSIBLE_LENGTH:
        return f"a record declares an impossible length; {_FIX}"
    if status == mcap_decode.NOT_FILLED:
        return f"the records inside a chunk do not fill it exactly; {_FIX}"
    ti = known[dec.slot_channel(int(dec.slot_of[int(buf[pos + 9]) | (int(buf[pos + 10]) << 8)]))]
    return (f"{ti.topic} ({ti.schema_name}): {_STATUS[status - mcap_decode.BAD_MESSAGE]} (the message at byte {pos} "
            f"of a chunk); {_FIX}")


def _group_task(bodies: list[memoryview], snap, on_block=None) -> list[_Piece]:
    """Decompress, verify and decode consecutive chunks (on a pool thread), each channel's messages of the group
    leaving as one block.

    Each chunk is walked by :class:`~stridelab.pipeline.formats.mcap_decode.GroupDecoder` right after its
    decompression. Schema and Channel records inside the chunks are checked here and returned with the piece, to be
    registered in file order before its blocks (a channel they define is decoded from its definition on); messages
    on a channel that neither the snapshot nor the group defines are located and returned as ``pending``, decoded
    once the definitions before them are registered (:func:`_iter_blocks`)."""
    schemas, topics = snap
    dec = mcap_decode.GroupDecoder(_slots(snap), sum(_chunk_size(b) for b in bodies))
    local: _Registry | None = None           # definitions met inside this group's chunks
    defs: list = []
    pending_slots: set[int] = set()
    known = topics
    for body in bodies:                      # each chunk decoded right after its decompression, still in the cache
        buf = dec.begin(_chunk_raw(body))
        p = 0
        while (stop := dec.walk(buf, p)) is not None:
            status, p = stop
            if status == mcap_decode.DEFINE:
                op, n = int(buf[p]), int.from_bytes(buf[p + 1:p + 9].tobytes(), "little")
                if local is None:
                    local = _Registry(schemas)
                if op == OP_SCHEMA:
                    rec = _parse(Schema, buf[p + 9:p + 9 + n], "Schema")
                    local.add_schema(rec)
                else:
                    rec = _parse(Channel, buf[p + 9:p + 9 + n], "Channel")
                    local.add_channel(rec)
                    known = {**topics, **local.topics}
                    if dec.slot_of[rec.id] == mcap_decode.NO_SLOT:
                        dec.add_slot(rec.id, _spec(local.topics[rec.id]))
                defs.append((op, rec))
                p += 9 + n
            elif status == mcap_decode.UNKNOWN_CHANNEL:
                cid = int(buf[p + 9]) | (int(buf[p + 10]) << 8)
                pending_slots.add(len(dec.channel_ids))
                dec.add_slot(cid, mcap_decode.LOCATE)
            else:
                raise McapFormatError(_walk_error(status, p, dec, buf, known))
    decoded, located = dec.result()
    by_topic: dict[str, list[Block]] = {}
    for slot, (t, log, vals) in decoded.items():
        ti = known[dec.slot_channel(slot)]
        by_topic[ti.topic] = [Block(ti.topic, ti.kind, t, log, vals)]
    pending = []
    for buf, slots, starts, lengths, logs in located:       # annotations, ranges: decoded per layout
        held = np.zeros(len(slots), dtype=bool)
        for slot in np.unique(slots).tolist():
            sel = slots == slot
            if slot in pending_slots:
                held |= sel
                continue
            ti = known[dec.slot_channel(slot)]
            by_topic.setdefault(ti.topic, []).append(_decode(ti, buf, starts[sel], lengths[sel], logs[sel]))
        if held.any():
            ch = np.asarray(dec.channel_ids, dtype=np.int64)[slots[held]]
            pending.append((buf, ch, logs[held], starts[held], lengths[held]))
    blocks = [_merge_blocks(v) for v in by_topic.values()]
    counts = {c: n for c, n in zip(dec.channel_ids, dec.counts.tolist()) if n}
    return [_Piece([on_block(b) if on_block is not None else b for b in blocks], defs, counts, pending)]


# ---- hashing thread --------------------------------------------------------------------------

class _Hasher:
    """SHA-256 of the whole file and CRC32 of its data section, fed in order on one thread."""

    def __init__(self):
        self.sha = hashlib.sha256()
        self.crc = 0
        self.n = 0
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="mcap-hash")
        self._last: Future | None = None
        self._queue: deque[Future] = deque()

    def feed(self, view, crc_upto: int | None) -> None:
        """``view`` starts at file offset ``self.n``; CRC covers bytes before ``crc_upto`` (None: all).
        At most 4 blocks wait for the hashing thread (bounded memory when hashing is the slower side)."""
        start = self.n
        self.n += len(view)
        while len(self._queue) >= 4:
            self._queue.popleft().result()
        self._last = self._pool.submit(self._work, view, start, crc_upto)
        self._queue.append(self._last)

    def _work(self, view, start, crc_upto):
        self.sha.update(view)
        if crc_upto is None:
            self.crc = crc32(view, self.crc)
        elif crc_upto > start:
            self.crc = crc32(view[:crc_upto - start], self.crc)

    def finish(self) -> None:
        if self._last is not None:
            self._last.result()
        self._pool.shutdown(wait=True)


# ---- the pass over the file ------------------------------------------------------------------

@dataclass
class _Summary:
    start: int = 0
    registry_defs: list = field(default_factory=list)
    statistics: Statistics | None = None


def _read_summary(f, size: int) -> _Summary:
    """Check both magics and the footer; read and CRC-check the summary section if there is one."""
    if size < 8 + 9 + 4 + 29 + 8:
        raise McapFormatError("not an MCAP recording (file too short)" if size else "empty file (0 bytes)")
    if f.read(8) != MAGIC:
        raise McapFormatError("not an MCAP file (bad magic bytes at the start)")
    f.seek(size - 37)
    tail = f.read(37)
    if tail[29:] != MAGIC or tail[0] != OP_FOOTER or int.from_bytes(tail[1:9], "little") != 20:
        raise McapFormatError("truncated MCAP: the file does not end with a footer and the closing magic "
                              "(copy interrupted? try `mcap recover`, or copy it again)")
    s_start, s_off, s_crc = struct.unpack_from("<QQI", tail, 9)
    out = _Summary(start=s_start)
    if s_start == 0:
        return out
    if not (8 < s_start <= size - 37) or (s_off and not (s_start <= s_off <= size - 37)):
        raise McapFormatError(f"the footer points outside the file; {_FIX}")
    f.seek(s_start)
    summary = f.read(size - 37 - s_start)
    if s_crc and crc32(tail[:25], crc32(summary)) != s_crc:
        raise McapFormatError(f"summary CRC mismatch (channel list, index or statistics changed after "
                              f"writing); {_FIX}")
    buf = np.frombuffer(summary, dtype=np.uint8)
    recs = _scan(buf, 0, len(buf), False)
    if recs.end != len(buf) or len(recs.m_ch):
        raise McapFormatError(f"the summary section holds malformed records; {_FIX}")
    for op, s, n in zip(recs.ops.tolist(), recs.starts.tolist(), recs.lengths.tolist()):
        if op == OP_SCHEMA:
            out.registry_defs.append((op, _parse(Schema, buf[s:s + n], "Schema")))
        elif op == OP_CHANNEL:
            out.registry_defs.append((op, _parse(Channel, buf[s:s + n], "Channel")))
        elif op == OP_STATISTICS:
            out.statistics = _parse(Statistics, buf[s:s + n], "Statistics")
    return out


def iter_blocks(path: str | Path, result: ReadResult, threads: int | None = None,
                on_block=None) -> Iterator[Block]:
    """Stream decoded blocks of every decodable channel of ``path``; fills ``result`` along the way.

    ``on_block(block) -> block``, if given, runs on the decoding thread for every block (a consumer's
    per-block checks, off the consuming thread; it must be thread-safe and should release the GIL).

    Raises McapFormatError (one-line reason) for empty, truncated or corrupt files, CRC mismatches,
    payloads that do not fit their schema and unexpected schemas on recording-format topics.
    """
    path = Path(path)
    size = path.stat().st_size
    threads = threads or read_threads()
    reg = _Registry()
    hasher = _Hasher()
    pool = ThreadPoolExecutor(threads, thread_name_prefix="mcap-chunk")
    inflight: deque[tuple[Future, int]] = deque()
    held = [0]
    dataend_crc: list[int] = []
    try:
        yield from _iter_blocks(path, size, threads, reg, hasher, pool, inflight, held, dataend_crc, result,
                                on_block)
    except McapFormatError:
        raise
    except MemoryError:
        raise McapFormatError("a record needs more memory than this machine has; rewrite the file with smaller "
                              "chunks (`mcap compress`)") from None
    except (struct.error, IndexError, KeyError, OverflowError, UnicodeDecodeError, ValueError, EOFError) as e:
        raise McapFormatError(f"corrupt MCAP ({type(e).__name__} while parsing a record); {_FIX}") from None
    finally:
        for fut, _ in inflight:
            fut.cancel()
        pool.shutdown(wait=True, cancel_futures=True)
        hasher.finish()


def _iter_blocks(path, size, threads, reg, hasher, pool, inflight, held, dataend_crc, result,
                 on_block=None) -> Iterator[Block]:
    with open(path, "rb") as f, ExitStack() as stack:
        summ = _read_summary(f, size)
        for op, rec in summ.registry_defs:
            (reg.add_schema if op == OP_SCHEMA else reg.add_channel)(rec)
        result.statistics = summ.statistics
        f.seek(0)
        seq = SequentialReader(path, size)
        stack.callback(seq.close)

        def finish(piece: _Piece) -> Iterator[Block]:
            for op, rec in piece.defs:
                (reg.add_schema if op == OP_SCHEMA else reg.add_channel)(rec)
            for cid, n in piece.counts.items():
                result.message_counts[cid] = result.message_counts.get(cid, 0) + n
            yield from piece.blocks
            for buf, ch, log, st, ln in piece.pending:
                unknown = sorted(set(ch.tolist()) - set(reg.topics))
                if unknown:
                    raise McapFormatError(f"messages on channel id {unknown[0]}, which no Channel record "
                                          f"defines; {_FIX}")
                recs = _Records(buf, np.empty(0, np.uint8), np.empty(0, np.int64), np.empty(0, np.int64),
                                ch, log, st, ln, 0, False)
                p = _decode_records(recs, reg.snapshot(), on_block)
                yield from p.blocks

        def drain(limit_bytes: int) -> Iterator[Block]:
            while inflight and (held[0] > limit_bytes or inflight[0][0].done()):
                fut, nb = inflight.popleft()
                held[0] -= nb
                res = fut.result()
                for piece in (res if isinstance(res, list) else [res]):
                    yield from finish(piece)

        group: list = []
        group_bytes = [0]

        def submit_group() -> None:
            if group:
                inflight.append((pool.submit(_group_task, list(group), reg.snapshot(), on_block), group_bytes[0]))
                held[0] += group_bytes[0]
                group.clear()
                group_bytes[0] = 0

        for kind, payload, nbytes in _top_level(seq, size, summ, hasher, reg, result, dataend_crc):
            if kind == "chunk":
                group.append(payload)
                group_bytes[0] += nbytes
                if group_bytes[0] < GROUP_BYTES:
                    continue
                submit_group()
            else:
                submit_group()
                inflight.append((pool.submit(_decode_records, payload, reg.snapshot(), on_block), nbytes))
                held[0] += nbytes
            yield from drain(MAX_IN_FLIGHT_BYTES)
        submit_group()
        yield from drain(-1)
    hasher.finish()
    if dataend_crc and dataend_crc[0] and dataend_crc[0] != hasher.crc:
        raise McapFormatError(f"data-section CRC mismatch (the file changed after writing); {_FIX}")
    _check_statistics(result, reg)
    result.topics = dict(reg.topics)
    result.ignored_topics = sorted(t.topic for t in reg.topics.values() if t.kind is None)
    result.sha256 = hasher.sha.hexdigest()
    result.n_bytes = hasher.n


def _check_statistics(result: ReadResult, reg: _Registry) -> None:
    st = result.statistics
    if st is None or not st.channel_message_counts:
        return
    for cid, ti in reg.topics.items():
        declared = st.channel_message_counts.get(cid, 0)
        seen = result.message_counts.get(cid, 0)
        if declared != seen:
            raise McapFormatError(f"{ti.topic}: the Statistics record counts {declared} messages but the file "
                                  f"holds {seen} (truncated or corrupt file); copy or export it again")


def _top_level(f, size: int, summ: _Summary, hasher: _Hasher, reg: _Registry, result: ReadResult,
               dataend_crc: list[int]) -> Iterator[tuple[str, object, int]]:
    """Walk the top-level records in file order; registers definitions and metadata inline and
    yields ("chunk", body, uncompressed bytes) and ("messages", _Records, bytes) work items."""
    data_end = summ.start or (size - 37)
    rest = b""
    offset = 0                              # file offset of rest[0]
    first = True
    crc_upto: int | None = None
    while True:
        need = READ_BLOCK
        if len(rest) >= 9:
            length = int.from_bytes(rest[1:9], "little")
            if rest[0] == OP_CHUNK and length > MAX_CHUNK_BYTES + (1 << 16):
                raise McapFormatError(f"a chunk of {length} bytes exceeds the {MAX_CHUNK_BYTES >> 20} MiB "
                                      f"limit; rewrite the file with smaller chunks (`mcap compress`)")
            if length > MAX_RECORD_BYTES + (1 << 16):
                raise McapFormatError(f"a record of {length} bytes exceeds the {MAX_RECORD_BYTES >> 20} MiB "
                                      f"limit; {_FIX}")
            if offset + 9 + length > size:
                raise McapFormatError(f"a record at byte {offset} runs past the end of the file "
                                      f"(truncated or corrupt file); copy or export it again")
            need = max(need, 9 + length - len(rest))
        # read straight behind the carried-over bytes (one copy of ``rest``, none of the new data; was
        # ``rest + f.read(need)``: a second full copy of every block on the reading thread)
        need = max(0, min(need, size - f.tell()))
        arr = np.empty(len(rest) + need, dtype=np.uint8)
        arr[:len(rest)] = np.frombuffer(rest, dtype=np.uint8)
        got = f.readinto(memoryview(arr)[len(rest):]) or 0
        if not got and len(rest) < 9 + (int.from_bytes(rest[1:9], "little") if len(rest) >= 9 else 0):
            raise McapFormatError("truncated MCAP: the file ends inside a record "
                                  "(copy interrupted? try `mcap recover`)")
        buf = arr[:len(rest) + got]
        buf_bytes = memoryview(buf)
        p = 0
        if first:
            p, first = 8, False
            hasher.feed(buf_bytes[:8], None)
            offset += 8
        recs = _scan(buf, p, len(buf), True)
        consumed = recs.end
        # chunks: check the declared size before any allocation; definitions and metadata inline
        for op, s, n in zip(recs.ops.tolist(), recs.starts.tolist(), recs.lengths.tolist()):
            if offset + (s - 9 - p) >= data_end:
                continue                   # summary section: already read
            if op == OP_CHUNK:
                if n < 40:
                    raise McapFormatError(f"a Chunk record is shorter than its fixed fields; {_FIX}")
                usize = int.from_bytes(buf_bytes[s + 16:s + 24], "little")
                if usize > MAX_CHUNK_BYTES:
                    raise McapFormatError(f"a chunk declares {usize} bytes uncompressed, above the "
                                          f"{MAX_CHUNK_BYTES >> 20} MiB limit; rewrite the file with smaller "
                                          f"chunks (`mcap compress`) if it is genuine")
                result.chunks += 1
                if not int.from_bytes(buf_bytes[s + 24:s + 28], "little"):
                    result.chunks_without_crc += 1
                yield "chunk", buf_bytes[s:s + n], usize
            elif op == OP_SCHEMA:
                reg.add_schema(_parse(Schema, buf[s:s + n], "Schema"))
            elif op == OP_CHANNEL:
                reg.add_channel(_parse(Channel, buf[s:s + n], "Channel"))
            elif op == OP_METADATA:
                md = _parse(Metadata, buf[s:s + n], "Metadata")
                if md.name in result.metadata:
                    raise McapFormatError(f"two Metadata records are named '{md.name[:40]}'; re-export with one")
                result.metadata[md.name] = dict(md.metadata)
            elif op == OP_DATA_END:
                if n < 4:
                    raise McapFormatError(f"the DataEnd record is malformed; {_FIX}")
                dataend_crc.append(int.from_bytes(buf_bytes[s:s + 4], "little"))
                result.data_crc = bool(dataend_crc[-1])
                crc_upto = offset + (s - 9 - p)
        if len(recs.m_ch):
            result.unchunked_messages = True
            yield "messages", recs, int(recs.m_len.sum())
        hasher.feed(buf_bytes[p:consumed], crc_upto)
        offset += consumed - p
        if recs.footer:
            tail = f.read()
            tail = bytes(buf_bytes[consumed:]) + tail
            if tail != MAGIC:
                raise McapFormatError(f"unexpected bytes after the footer; {_FIX}")
            hasher.feed(tail, crc_upto)
            return
        rest = bytes(buf_bytes[consumed:])         # a copy: must not keep this block alive
        if not got and not rest:
            raise McapFormatError("truncated MCAP: the file ends before its footer "
                                  "(copy interrupted? try `mcap recover`)")


def read_metadata(path: str | Path) -> dict[str, dict[str, str]]:
    """Metadata records via the summary index (cheap); empty dict if the file has no index."""
    from mcap.reader import make_reader
    try:
        with open(path, "rb") as f:
            return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    except Exception:  # noqa: BLE001 - a broken index is reported by the full pass
        return {}
