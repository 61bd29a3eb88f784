"""The live session written to recording-format MCAP as it arrives, crash-safe.

Layout: magic, Header, Schemas, Channels, the ``session`` Metadata record, then one zstd chunk (+ its message
indexes) per ``chunk_s`` of samples. After every chunk the file is closed off with DataEnd + an empty-summary
Footer + magic written in the same ``pwrite`` as the chunk, at the offset where the previous DataEnd stood: a
session killed at any moment (``kill -9``, power loss after the fsync) leaves a valid MCAP holding every
complete chunk (a write the kernel cut short at the kill leaves half a chunk: :func:`repair`). ``close`` writes
the full summary (chunk indexes, statistics) and moves the file from
``<inbox>/.live/`` into the inbox, where the nightly run picks it up; a file left in ``.live/`` by a crash is
moved in by :func:`recover` (``stridelab live --recover``), after checking it with the ingest's reader.

Topics: the recording format's ``/imu/<placement>`` and ``/mag/<placement>`` (ROS 2 CDR, stamps = sensor
time, log time = host time), plus the live outputs as JSON for the nightly comparison (docs/live.md):
``/live/joint_angles`` (one message per second of frames: t_ns, per joint [FE, AA, IE] deg lists) and
``/live/events`` (one message per gait event), ``/live/calibration`` (once: the session calibration the live
angles used, as the calibration stage's rows) and ``/live/standing`` (once, when found: the standing offsets
subtracted from the live angles and the frame they apply from), each a ``std_msgs/msg/String`` holding JSON: any
MCAP or ROS 2 tool reads them; the ingest stores them beside the raw data (:mod:`stridelab.pipeline.live.stored`, table
``live_outputs``) and the nightly ``live_agreement`` stage compares them with its own outputs.
"""
from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, ChunkIndex, DataEnd, Footer, Header, Metadata, MetadataIndex, Schema,
                          Statistics)

from stridelab.pipeline.formats import ros2_cdr
from stridelab.pipeline.formats.mcap_read import crc32
from stridelab.pipeline.formats.mcap_write import (MAGIC, _message_index, in_log_time, _message_records, _record,
                                         summary_and_footer)

LIVE_DIR = ".live"
#: live outputs: ``std_msgs/msg/String`` (CDR) holding one JSON document each, readable by every ROS 2 / MCAP
#: tool; the ingest decodes no String topic, so they never mix with the raw data
JSON_TOPICS = ("/live/joint_angles", "/live/events", "/live/calibration", "/live/standing")
STRING_SCHEMA = "std_msgs/msg/String"


def encode_string(text: str) -> bytes:
    """One ``std_msgs/msg/String`` in CDR (little endian): encapsulation header, uint32 length with the NUL."""
    b = text.encode() + b"\0"
    return b"\x00\x01\x00\x00" + len(b).to_bytes(4, "little") + b


def decode_string(raw: bytes) -> str:
    """The text of one ``std_msgs/msg/String`` in little-endian CDR (as :func:`encode_string` writes it and any
    ROS 2 writer does); raises ValueError when the message is malformed."""
    if len(raw) < 9 or raw[:2] != b"\x00\x01":
        raise ValueError("not a little-endian CDR message")
    n = int.from_bytes(raw[4:8], "little")
    if n < 1 or 8 + n > len(raw) or raw[7 + n] != 0:
        raise ValueError("string runs past the message")
    return raw[8:7 + n].decode()


class McapRecorder:
    """Append-only, crash-safe MCAP writer for one live session (thread-safe ``add_*``, ``flush``, ``close``)."""

    def __init__(self, inbox: str | Path, name: str, placements, metadata: dict[str, str], *, chunk_s: float = 1.0,
                 with_mag: bool = True):
        self.inbox = Path(inbox)
        (self.inbox / LIVE_DIR).mkdir(parents=True, exist_ok=True)
        self.path = self.inbox / LIVE_DIR / f"{name}.mcap"
        self.final_path = self.inbox / f"{name}.mcap"
        if self.final_path.exists() or self.path.exists():
            raise ValueError(f"{self.final_path}: a recording of that name exists already; choose another --name")
        self.chunk_ns = int(chunk_s * 1e9)
        self._lock = threading.Lock()
        self._comp = zstandard.ZstdCompressor(level=1)
        self._fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        self.channels: dict[str, int] = {}
        schemas, recs = {}, []
        for p in placements:
            for kind, schema in (("imu", "sensor_msgs/msg/Imu"), ("mag", "sensor_msgs/msg/MagneticField")):
                if kind == "mag" and not with_mag:
                    continue
                self._channel(f"/{kind}/{p}", schema, ros2_cdr.SCHEMAS[schema].encode(), "ros2msg", "cdr", schemas,
                              recs)
        for topic in JSON_TOPICS:
            self._channel(topic, STRING_SCHEMA, b"string data", "ros2msg", "cdr", schemas, recs)
        self._schema_recs = [r for r in recs if isinstance(r, Schema)]
        self._channel_recs = [r for r in recs if isinstance(r, Channel)]
        head = MAGIC + _record(Header(profile="ros2", library="stridelab-live"))
        head += b"".join(_record(r) for r in recs)
        meta = _record(Metadata(name="session", metadata={k: str(v) for k, v in metadata.items()}))
        self._meta_index = MetadataIndex(offset=len(head), length=len(meta), name="session")
        head += meta
        self._crc = crc32(head)
        self._pos = len(head)
        self._pending: dict[int, list] = {}         # channel id -> [(log_ns, payload bytes)]
        self._pending_t0 = None
        self._pending_t1 = -1
        self._chunks: list[ChunkIndex] = []
        self._counts = {c.id: 0 for c in self._channel_recs}
        self._seq = {c.id: 0 for c in self._channel_recs}
        self._t_min = self._t_max = None
        self.closed = False
        os.pwrite(self._fd, head + self._tail(), 0)
        os.fsync(self._fd)

    def _channel(self, topic, schema, data, sch_enc, msg_enc, schemas, recs):
        if schema not in schemas:
            schemas[schema] = len(schemas) + 1
            recs.append(Schema(id=schemas[schema], name=schema, encoding=sch_enc, data=data))
        cid = len(self.channels) + 1
        self.channels[topic] = cid
        recs.append(Channel(id=cid, schema_id=schemas[schema], topic=topic, message_encoding=msg_enc, metadata={}))

    def _tail(self) -> bytes:
        """DataEnd + Footer (no summary) + magic: what makes the file valid at this point."""
        return _record(DataEnd(data_section_crc=self._crc)) + \
            _record(Footer(summary_start=0, summary_offset_start=0, summary_crc=0)) + MAGIC

    # ---- adding messages -------------------------------------------------------------------------------
    def add_imu(self, placement: str, t_ns: np.ndarray, log_ns: np.ndarray, gyr, acc, mag=None) -> None:
        """Samples of one sensor (arrays of n rows); log time = host receive time."""
        t_ns = np.asarray(t_ns, np.int64)
        if not len(t_ns):
            return
        enc = ros2_cdr.encode_imu(t_ns, np.asarray(acc, float), np.asarray(gyr, float), placement)
        with self._lock:
            self._queue(self.channels[f"/imu/{placement}"], log_ns, enc)
            if mag is not None and f"/mag/{placement}" in self.channels:
                m = ros2_cdr.encode_mag(t_ns, np.asarray(mag, float), placement)
                self._queue(self.channels[f"/mag/{placement}"], log_ns, m)
            self._maybe_chunk()

    def add_json(self, topic: str, log_ns: int, obj: dict) -> None:
        data = encode_string(json.dumps(obj, separators=(",", ":"), allow_nan=False, default=_plain))
        with self._lock:
            self._queue(self.channels[topic], np.array([log_ns], np.int64), [data])
            self._maybe_chunk()

    def _queue(self, cid: int, log_ns, payload) -> None:
        """Keep a block of messages of one channel: ``payload`` an (n, L) uint8 array or a list of bytes."""
        log_ns = np.asarray(log_ns, np.int64)
        self._pending.setdefault(cid, []).append((log_ns, payload))
        t0 = int(log_ns.min())
        self._pending_t0 = t0 if self._pending_t0 is None else min(self._pending_t0, t0)
        self._pending_t1 = max(self._pending_t1, int(log_ns.max()))

    def _maybe_chunk(self) -> None:
        if self._pending_t0 is not None and self._pending_t1 - self._pending_t0 >= self.chunk_ns:
            self._write_chunk()

    # ---- chunks ----------------------------------------------------------------------------------------
    def flush(self) -> None:
        with self._lock:
            self._write_chunk()

    def _write_chunk(self) -> None:
        """The pending messages as one chunk, in log-time order (ties: channel order), vectorised per channel as
        ``mcap_write.write_mcap`` assembles its chunks."""
        if not self._pending:
            return
        parts, sizes_l, times_l, ids_l = [], [], [], []
        for cid in sorted(self._pending):
            blocks = self._pending[cid]
            t = np.concatenate([b[0] for b in blocks])
            if all(isinstance(b[1], np.ndarray) for b in blocks):
                pay = np.concatenate([b[1] for b in blocks])
            else:
                pay = [bytes(x) for b in blocks for x in b[1]]
            order = np.argsort(t, kind="stable")
            t = t[order]
            pay = pay[order] if isinstance(pay, np.ndarray) else [pay[i] for i in order.tolist()]
            data, sizes = _message_records(cid, t, self._seq[cid], pay)
            self._seq[cid] += len(t)
            self._counts[cid] += len(t)
            parts.append(data)
            sizes_l.append(sizes)
            times_l.append(t)
            ids_l.append(np.full(len(t), cid, dtype=np.int64))
        self._pending, self._pending_t0, self._pending_t1 = {}, None, -1
        raw, times, ids, dst_off = in_log_time(parts, sizes_l, times_l, ids_l)
        index = {int(cid): (times[ids == cid], dst_off[ids == cid]) for cid in np.unique(ids)}
        c_start, c_end = int(times.min()), int(times.max())
        self._t_min = c_start if self._t_min is None else min(self._t_min, c_start)
        self._t_max = c_end if self._t_max is None else max(self._t_max, c_end)
        compressed = self._comp.compress(raw)
        head = RecordBuilder()
        head.start_record(Opcode.CHUNK)
        for v in (c_start, c_end, len(raw)):
            head.write8(v)
        head.write4(crc32(raw))
        head.write_prefixed_string("zstd")
        head.write8(len(compressed))
        head.finish_record()
        hb = bytearray(head.end())
        hb[1:9] = (len(hb) - 9 + len(compressed)).to_bytes(8, "little")
        chunk = bytes(hb) + compressed
        mi_offsets, mis = {}, bytearray()
        for cid in sorted(index):
            mi_offsets[cid] = self._pos + len(chunk) + len(mis)
            mis += _message_index(cid, *index[cid])
        body = chunk + bytes(mis)
        self._chunks.append(ChunkIndex(
            message_start_time=c_start, message_end_time=c_end, chunk_start_offset=self._pos,
            chunk_length=len(chunk), message_index_offsets=mi_offsets, message_index_length=len(mis),
            compression="zstd", compressed_size=len(compressed), uncompressed_size=len(raw)))
        pos = self._pos
        self._crc = crc32(body, self._crc)
        self._pos += len(body)
        # one write: the chunk and the new tail; before it returns the old tail still closes the file
        os.pwrite(self._fd, body + self._tail(), pos)
        os.fsync(self._fd)

    def close(self) -> Path:
        """Last chunk, the full summary, then the file moves into the inbox."""
        with self._lock:
            if self.closed:
                return self.final_path
            self._write_chunk()
            data_end = _record(DataEnd(data_section_crc=self._crc))
            summary_start = self._pos + len(data_end)
            groups = [(Opcode.SCHEMA, self._schema_recs), (Opcode.CHANNEL, self._channel_recs),
                      (Opcode.STATISTICS, [Statistics(
                          message_count=sum(self._counts.values()), schema_count=len(self._schema_recs),
                          channel_count=len(self._channel_recs), attachment_count=0, metadata_count=1,
                          chunk_count=len(self._chunks), message_start_time=self._t_min or 0,
                          message_end_time=self._t_max or 0, channel_message_counts=dict(self._counts))]),
                      (Opcode.CHUNK_INDEX, self._chunks), (Opcode.METADATA_INDEX, [self._meta_index])]
            tail = data_end + summary_and_footer(groups, summary_start) + MAGIC
            os.pwrite(self._fd, tail, self._pos)
            os.ftruncate(self._fd, self._pos + len(tail))
            os.fsync(self._fd)
            os.close(self._fd)
            self.closed = True
            os.replace(self.path, self.final_path)
            return self.final_path


def _plain(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


_KEEP = {int(Opcode.HEADER), int(Opcode.SCHEMA), int(Opcode.CHANNEL), int(Opcode.METADATA), int(Opcode.CHUNK),
         int(Opcode.MESSAGE_INDEX)}


def repair(path: str | Path) -> bool:
    """Cut a recorder file after its last complete record and close it off (DataEnd + footer + magic).

    For the rare file a kill left mid-write (a short ``pwrite``: the new chunk's record runs past the end of
    the file): the records are walked from the start and the file is cut where the first incomplete or
    foreign record begins; the chunks before it are intact (each carries its CRC). False when the file does
    not start like a recorder file."""
    path = Path(path)
    data = path.read_bytes()
    if not data.startswith(MAGIC):
        return False
    p, cut = len(MAGIC), None
    while p + 9 <= len(data):
        op, n = data[p], int.from_bytes(data[p + 1:p + 9], "little")
        if op not in _KEEP or p + 9 + n > len(data):
            break
        p += 9 + n
        cut = p
    if cut is None:
        return False
    crc = crc32(data[:cut])
    tail = _record(DataEnd(data_section_crc=crc)) + \
        _record(Footer(summary_start=0, summary_offset_start=0, summary_crc=0)) + MAGIC
    with open(path, "r+b") as f:
        f.seek(cut)
        f.write(tail)
        f.truncate(cut + len(tail))
        f.flush()
        os.fsync(f.fileno())
    return True


def recover(inbox: str | Path) -> list[tuple[Path, str]]:
    """Move recordings a crashed live session left in ``<inbox>/.live/`` into the inbox once the ingest's reader
    accepts them (a file cut mid-write is first :func:`repair` ed to its last complete chunk); returns (file,
    outcome) pairs. A file the reader still refuses stays where it is, with the reason."""
    from stridelab.pipeline.formats.mcap_read import McapFormatError, ReadResult, iter_blocks

    def readable(p):
        try:
            for _ in iter_blocks(p, ReadResult()):
                pass
            return None
        except McapFormatError as e:
            return str(e)
    out = []
    for p in sorted((Path(inbox) / LIVE_DIR).glob("*.mcap")):
        err = readable(p)
        if err is not None and repair(p):
            err = readable(p)
        if err is not None:
            out.append((p, f"left in place: {err}"))
            continue
        dest = Path(inbox) / p.name
        if dest.exists():
            out.append((p, f"left in place: {dest} exists"))
            continue
        os.replace(p, dest)
        out.append((dest, "moved into the inbox"))
    return out
