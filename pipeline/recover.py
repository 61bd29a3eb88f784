"""``stridelab repair FILE`` / ``stridelab ingest --recover``: keep what is intact of a truncated or damaged MCAP.

A logger that loses power leaves an MCAP without its summary and footer, its last chunk cut; a copy with a bad
sector leaves a chunk whose CRC no longer matches. The records are walked in file order (the mcap library parses
each one); every record that lies wholly inside the file is kept, a chunk only when it decompresses to its
declared size and its CRC matches (a chunk written without a CRC is kept and the file stays "unverified"). A chunk
that fails is skipped and the walk goes on; where the framing itself is broken (a record running past the end of
the file, an unknown opcode where a record should start) the rest of the file is lost. What was kept is written
with the mcap library's writer as a new file; :class:`Recovery` says what was lost: the chunks, their time range
(from their headers when readable) and the samples, counted where the chunk could be opened and estimated from the
kept rate otherwise.
"""
from __future__ import annotations

import io
import struct
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
_KNOWN = set(range(0x01, 0x10))


@dataclass
class Recovery:
    source: str
    size: int
    output: str | None = None
    chunks_kept: int = 0
    chunks_lost: int = 0
    messages_kept: int = 0
    messages_lost: int | None = 0         # None: not countable (the lost part could not be opened)
    lost_ranges: list[tuple[int | None, int | None, str]] = field(default_factory=list)   # (start_ns, end_ns, why)
    broken_at: int | None = None          # byte offset where the framing broke (the rest is lost)
    kept_start_ns: int | None = None
    kept_end_ns: int | None = None
    unverified_chunks: int = 0

    @property
    def complete(self) -> bool:
        return not self.lost_ranges and self.broken_at is None

    def summary(self, name: str | None = None) -> str:
        """One line: what was kept and what was lost, starting with ``name`` (default: the file's name; a stored
        note gets another, stridelab.pipeline.privacy)."""
        name = Path(self.source).name if name is None else name
        if self.complete:
            return f"{name}: intact, {self.messages_kept:,} messages; nothing to recover"
        lost = []
        for a, b, why in self.lost_ranges:
            lost.append(f"{why} ({_when(a)} to {_when(b)})")
        n = "an unknown number of" if self.messages_lost is None else f"{self.messages_lost:,}"
        return (f"{name}: kept {self.chunks_kept} chunks, {self.messages_kept:,} messages ({_when(self.kept_start_ns)} "
                f"to {_when(self.kept_end_ns)}); lost {self.chunks_lost} chunks, {n} messages: " + "; ".join(lost))

    def as_dict(self) -> dict:
        return {"source": self.source, "output": self.output, "chunks_kept": self.chunks_kept,
                "chunks_lost": self.chunks_lost, "messages_kept": self.messages_kept,
                "messages_lost": self.messages_lost, "broken_at": self.broken_at,
                "kept_start_ns": self.kept_start_ns, "kept_end_ns": self.kept_end_ns,
                "lost_ranges": [{"start_ns": a, "end_ns": b, "why": w} for a, b, w in self.lost_ranges],
                "unverified_chunks": self.unverified_chunks, "summary": self.summary()}


def _when(t: int | None) -> str:
    if t is None:
        return "?"
    return datetime.fromtimestamp(t / 1e9, tz=timezone.utc).isoformat(timespec="seconds")


def _chunk_header(body: bytes) -> tuple[int, int] | None:
    """(message_start_time, message_end_time) of a chunk record body, if its fixed fields are there."""
    if len(body) < 16:
        return None
    return struct.unpack_from("<QQ", body, 0)


def scan(path: str | Path) -> tuple[Recovery, list, dict]:
    """Walk the records of ``path``: (report, kept records in file order, metadata by name)."""
    from mcap.records import Channel, Chunk, Message, Metadata, Schema
    from mcap.data_stream import ReadDataStream
    from mcap.stream_reader import breakup_chunk
    path = Path(path)
    data = path.read_bytes()
    rep = Recovery(str(path), len(data))
    kept: list = []
    metadata: dict = {}
    if not data.startswith(MAGIC):
        rep.broken_at = 0
        rep.lost_ranges.append((None, None, "no MCAP magic at the start"))
        rep.messages_lost = None
        return rep, kept, metadata
    p = len(MAGIC)
    while True:
        if p + 9 > len(data):
            if p < len(data) or not kept:
                rep.broken_at = p
            break
        op = data[p]
        length = int.from_bytes(data[p + 1:p + 9], "little")
        if op not in _KNOWN and op < 0x80:
            rep.broken_at = p
            rep.lost_ranges.append((None, None, f"unreadable from byte {p:,} on"))
            rep.messages_lost = None
            break
        body = data[p + 9:p + 9 + length]
        if p + 9 + length > len(data):                       # cut: the file ends inside this record
            rep.broken_at = p
            hdr = _chunk_header(body) if op == OP_CHUNK else None
            rep.lost_ranges.append((hdr[0] if hdr else None, None,
                                    f"the file ends inside a record at byte {p:,} (truncated)"))
            rep.messages_lost = None
            if op == OP_CHUNK:
                rep.chunks_lost += 1
            break
        stream = ReadDataStream(io.BytesIO(body))
        try:
            if op == OP_CHUNK:
                chunk = Chunk.read(stream)
                try:
                    recs = breakup_chunk(chunk, validate_crc=True)
                except Exception as e:  # noqa: BLE001 - any failure of one chunk loses that chunk only
                    rep.chunks_lost += 1
                    n = _count_messages(chunk)
                    rep.messages_lost = None if (n is None or rep.messages_lost is None) else rep.messages_lost + n
                    why = "CRC mismatch" if "CRC" in type(e).__name__ or "crc" in str(e).lower() else "undecodable"
                    rep.lost_ranges.append((chunk.message_start_time, chunk.message_end_time,
                                            f"a chunk at byte {p:,}: {why}"))
                else:
                    rep.chunks_kept += 1
                    if not chunk.uncompressed_crc:
                        rep.unverified_chunks += 1
                    kept += recs
            elif op == OP_SCHEMA:
                kept.append(Schema.read(stream))
            elif op == OP_CHANNEL:
                kept.append(Channel.read(stream))
            elif op == OP_MESSAGE:
                kept.append(Message.read(stream, length))
            elif op == OP_METADATA:
                md = Metadata.read(stream)
                metadata.setdefault(md.name, dict(md.metadata))
            elif op in (OP_DATA_END, OP_FOOTER):
                break
        except Exception:  # noqa: BLE001 - a record that does not parse: the framing can no longer be trusted
            rep.broken_at = p
            rep.lost_ranges.append((None, None, f"a malformed record at byte {p:,}; the rest is unreadable"))
            rep.messages_lost = None
            break
        p += 9 + length
    return rep, kept, metadata


def _count_messages(chunk) -> int | None:
    """Messages of a chunk that failed its CRC (its data still decompress), None when not countable."""
    from mcap.records import Message
    from mcap.stream_reader import breakup_chunk
    try:
        return sum(isinstance(r, Message) for r in breakup_chunk(chunk, validate_crc=False))
    except Exception:  # noqa: BLE001
        return None


def recovered_name(src: str | Path) -> str:
    """``NAME.recovered.mcap`` for ``NAME.mcap``, the name shortened to stay within 255 bytes."""
    stem = Path(src).stem
    while len(stem.encode()) > 255 - len(".recovered.mcap"):
        stem = stem[:-1]
    return f"{stem}.recovered.mcap"


def recover(src: str | Path, dst: str | Path) -> Recovery:
    """Write the intact records of ``src`` to ``dst`` (the mcap library's writer, zstd chunks with CRCs)."""
    from mcap.records import Channel, Message, Schema
    from mcap.writer import CompressionType, Writer
    rep, kept, metadata = scan(src)
    schemas, channels = {}, {}
    dst = Path(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{dst.name}.tmp")
    with open(tmp, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="stridelab-recover")
        sch_def: dict[int, Schema] = {}
        ch_def: dict[int, Channel] = {}
        for r in kept:
            if isinstance(r, Schema):
                sch_def.setdefault(r.id, r)
            elif isinstance(r, Channel):
                ch_def.setdefault(r.id, r)
            elif isinstance(r, Message):
                ch = ch_def.get(r.channel_id)
                if ch is None:
                    continue                      # its channel was defined in a lost part
                if ch.id not in channels:
                    sid = 0
                    if ch.schema_id:
                        s = sch_def.get(ch.schema_id)
                        if s is None:
                            continue
                        if s.id not in schemas:
                            schemas[s.id] = w.register_schema(s.name, s.encoding, s.data)
                        sid = schemas[s.id]
                    channels[ch.id] = w.register_channel(ch.topic, ch.message_encoding, sid, ch.metadata)
                w.add_message(channels[ch.id], r.log_time, r.data, r.publish_time, r.sequence)
                rep.messages_kept += 1
                t = r.log_time
                rep.kept_start_ns = t if rep.kept_start_ns is None else min(rep.kept_start_ns, t)
                rep.kept_end_ns = t if rep.kept_end_ns is None else max(rep.kept_end_ns, t)
        for name, md in metadata.items():
            w.add_metadata(name, md)
        w.finish()
    tmp.replace(dst)
    rep.output = str(dst)
    return rep


# ---- a damaged catalog ---------------------------------------------------------------------------------------

def rebuild_catalog(root: str | Path) -> str:
    """Replace a damaged ``catalog.duckdb`` by a copy of the newest snapshot that opens (under the run lock); the
    damaged file (and its WAL) are kept beside it as ``catalog.damaged-<time>.duckdb``. What was committed after
    that snapshot is no longer in the catalog: the next ``stridelab run`` ingests again the inbox files it does not
    know (their series files are written again; orphans are garbage-collected) and recomputes what is stale.
    Returns the one-line account."""
    import shutil
    import time as _time

    from stridelab.warehouse.catalog import CATALOG, Warehouse
    from stridelab.warehouse.lock import RunLock
    from stridelab.warehouse.read import snapshot_status
    root = Path(root)
    with RunLock(root, "repair-catalog"):
        snap, problem = snapshot_status(root)
        if snap is None:
            raise RuntimeError(f"no snapshot of {root} opens ({problem or 'none published'}); the catalog cannot be "
                               f"rebuilt from one: start a new warehouse and ingest the inbox again")
        cat = root / CATALOG
        stamp = _time.strftime("%Y%m%dT%H%M%S", _time.gmtime())
        kept = []
        for p in (cat, cat.with_name(cat.name + ".wal")):
            if p.exists():
                dst = p.with_name(p.name.replace("catalog", f"catalog.damaged-{stamp}", 1))
                p.replace(dst)
                kept.append(dst.name)
        tmp = root / f".{CATALOG}.rebuild"
        shutil.copyfile(snap, tmp)
        tmp.replace(cat)
        with Warehouse.open(root) as wh:
            n = wh.con.execute("SELECT count(*) FROM recordings WHERE status = 'ingested'").fetchall()[0][0]
            wh.publish_snapshot()
    return (f"catalog rebuilt from snapshot {snap.name} ({n} ingested recordings); the damaged file is kept as "
            f"{', '.join(kept) or 'nothing (it was missing)'}; run `stridelab run` to ingest again what arrived after "
            f"that snapshot")
