"""rosbag2 bag directories (``metadata.yaml`` + one or more ``.mcap`` or ``.db3`` files) as one recording.

MCAP storage is read file by file with the vectorised reader of :mod:`stridelab.pipeline.formats.mcap_read`;
sqlite3 storage (``.db3``) and file-compressed bags go through ``rosbags`` (a maintained pure-Python
rosbag2 reader), whose raw CDR messages are decoded in batches by the same vectorised decoders.
The content hash of a bag is the SHA-256 of its data files' SHA-256 (in the order metadata.yaml lists
them), so a bag copied elsewhere is still the same recording.
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Iterator

import numpy as np
import yaml

from stridelab.pipeline.formats.mcap_read import (Block, McapFormatError, ReadResult, TopicInfo, _decode, _normalise_schema,
                                        SCHEMA_KINDS, iter_blocks)

BATCH = 1 << 16           # messages per channel decoded at once from a .db3 bag


@dataclass
class BagInfo:
    path: Path
    storage: str                       # mcap | sqlite3
    files: list[Path]
    compression_mode: str
    custom_data: dict[str, str] = field(default_factory=dict)


def is_bag(path: Path) -> bool:
    return path.is_dir() and (path / "metadata.yaml").is_file()


def bag_info(path: Path) -> BagInfo:
    """Parse ``metadata.yaml`` (raises McapFormatError with a one-line reason)."""
    meta = path / "metadata.yaml"
    if not meta.is_file():
        raise McapFormatError("a directory without metadata.yaml is not a rosbag2 bag; ingest the .mcap files "
                              "themselves or copy the whole bag directory")
    try:
        doc = yaml.safe_load(meta.read_text(encoding="utf-8"))
        info = doc["rosbag2_bagfile_information"]
        files = [path / PurePath(x).name for x in info["relative_file_paths"]]
        storage = str(info["storage_identifier"])
    except (yaml.YAMLError, UnicodeDecodeError, KeyError, TypeError) as e:
        raise McapFormatError(f"metadata.yaml is not rosbag2 bag metadata ({type(e).__name__}); "
                              f"recreate it with `ros2 bag reindex`") from None
    missing = [f.name for f in files if not f.is_file()]
    if missing:
        raise McapFormatError(f"the bag lists {missing[0]} but it is missing; copy the whole bag directory")
    if not files:
        raise McapFormatError("the bag's metadata.yaml lists no storage files; recreate it with `ros2 bag reindex`")
    if storage not in ("mcap", "sqlite3"):
        raise McapFormatError(f"rosbag2 storage '{storage[:20]}' is not supported; convert the bag to mcap "
                              f"(`ros2 bag convert`)")
    custom = info.get("custom_data") or {}
    return BagInfo(path, storage, files, str(info.get("compression_mode") or "").lower(),
                   {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else {})


def custom_data_of_mcap(metadata: dict[str, dict[str, str]]) -> dict[str, str]:
    """custom_data of the ``rosbag2`` metadata record that rosbag2 writes into each MCAP file."""
    text = metadata.get("rosbag2", {}).get("serialized_metadata")
    if not text:
        return {}
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError:
        raise McapFormatError("the 'rosbag2' metadata record is not valid YAML; re-export the bag") from None
    if isinstance(doc, dict) and "rosbag2_bagfile_information" in doc:
        doc = doc["rosbag2_bagfile_information"]
    custom = doc.get("custom_data") if isinstance(doc, dict) else None
    return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else {}


def iter_bag_blocks(info: BagInfo, result: ReadResult, on_block=None) -> Iterator[Block]:
    """Blocks of every decodable topic of the bag, file after file; fills ``result``."""
    # MESSAGE-compressed bags (each message zstd-compressed, as rosbags and rosbag2 write them) go through rosbags,
    # which decompresses them; the vectorised reader would take the compressed bytes for CDR (issue #47)
    if info.storage == "mcap" and info.compression_mode in ("", "none"):
        shas = []
        for f in info.files:
            part = ReadResult()
            try:
                yield from iter_blocks(f, part, on_block=on_block)
            except McapFormatError as e:
                raise McapFormatError(f"{f.name}: {e}") from None
            for name, md in part.metadata.items():
                if name in result.metadata and name != "rosbag2" and result.metadata[name] != md:
                    raise McapFormatError(f"the split files disagree on the '{name[:40]}' metadata record; "
                                          f"re-export the bag")
                result.metadata.setdefault(name, md)
            for t in part.topics.values():
                if t.topic not in {x.topic for x in result.topics.values()}:
                    result.topics[len(result.topics) + 1] = t
            result.n_bytes += part.n_bytes
            result.chunks += part.chunks
            result.chunks_without_crc += part.chunks_without_crc + (0 if part.crc_verified else 1)
            shas.append(part.sha256)
        result.ignored_topics = sorted({t.topic for t in result.topics.values() if t.kind is None})
        result.sha256 = hashlib.sha256("\n".join(shas).encode()).hexdigest()
        return
    yield from _rosbags_blocks(info, result)


def _rosbags_blocks(info: BagInfo, result: ReadResult) -> Iterator[Block]:
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.errors import ReaderError
    shas = []
    for f in info.files:
        h = hashlib.sha256()
        with open(f, "rb") as fh:
            for b in iter(lambda: fh.read(1 << 22), b""):
                h.update(b)
        shas.append(h.hexdigest())
        result.n_bytes += f.stat().st_size
    try:
        with Reader(info.path) as reader:
            infos: dict[int, TopicInfo] = {}
            for c in reader.connections:
                name = _normalise_schema(c.msgtype)
                kind = SCHEMA_KINDS.get(name)
                if kind == "events" and c.topic != "/reference/events":
                    kind = None
                variance = bool(kind == "range" and "float32 variance" in str(c.msgdef.data).split("=" * 80)[0])
                infos[c.id] = TopicInfo(c.topic, name, "cdr", kind, variance)
            result.topics = dict(infos)
            wanted = [c for c in reader.connections if infos[c.id].kind is not None]
            batches: dict[int, list] = {}
            for conn, stamp, raw in (reader.messages(connections=wanted) if wanted else ()):
                b = batches.setdefault(conn.id, [])
                b.append((stamp, bytes(raw)))
                if len(b) >= BATCH:
                    yield _decode_batch(infos[conn.id], b)
                    batches[conn.id] = []
            for cid, b in batches.items():
                if b:
                    yield _decode_batch(infos[cid], b)
    except ReaderError as e:
        raise McapFormatError(f"rosbag2 bag cannot be read ({str(e).splitlines()[0][:120]}); "
                              f"check it with `ros2 bag info`") from None
    result.ignored_topics = sorted(t.topic for t in result.topics.values() if t.kind is None)
    result.sha256 = hashlib.sha256("\n".join(shas).encode()).hexdigest()


def _decode_batch(ti: TopicInfo, batch: list[tuple[int, bytes]]) -> Block:
    lengths = np.array([len(r) for _, r in batch], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    buf = np.frombuffer(b"".join(r for _, r in batch), dtype=np.uint8)
    log = np.array([s for s, _ in batch], dtype=np.int64)
    try:
        return _decode(ti, buf, starts, lengths, log)
    except McapFormatError:
        if ti.kind != "range":
            raise
        # older bags carry no message definition: sensor_msgs/Range before or after Jazzy's ``variance``
        ti.range_variance = not ti.range_variance
        return _decode(ti, buf, starts, lengths, log)


def message_compression(metadata: dict[str, dict[str, str]]) -> str | None:
    """The compression format of an MCAP file whose messages are compressed one by one (rosbag2 / rosbags
    ``compression_mode: message``, said by the file's ``rosbag2`` metadata record), else None."""
    text = metadata.get("rosbag2", {}).get("serialized_metadata")
    if not text:
        return None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError:
        return None
    if isinstance(doc, dict) and "rosbag2_bagfile_information" in doc:
        doc = doc["rosbag2_bagfile_information"]
    if not isinstance(doc, dict) or str(doc.get("compression_mode") or "").lower() != "message":
        return None
    return str(doc.get("compression_format") or "zstd").lower()


def iter_message_compressed_blocks(path: Path, result: ReadResult, fmt: str) -> Iterator[Block]:
    """Blocks of one MCAP file whose messages are compressed one by one (read with the mcap library, each
    message decompressed, then decoded in batches by the vectorised decoders); fills ``result``."""
    import zstandard
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    if fmt != "zstd":
        raise McapFormatError(f"messages compressed with '{fmt[:20]}' one by one are not supported; re-export the "
                              f"bag with zstd or without compression (`ros2 bag convert`)")
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for b in iter(lambda: fh.read(1 << 22), b""):
            h.update(b)
    dctx = zstandard.ZstdDecompressor()
    infos: dict[int, TopicInfo] = {}
    batches: dict[int, list] = {}
    try:
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
            for sch, ch, msg in reader.iter_messages(log_time_order=False):
                ti = infos.get(ch.id)
                if ti is None:
                    name = _normalise_schema(sch.name) if sch is not None else ""
                    kind = SCHEMA_KINDS.get(name) if ch.message_encoding == "cdr" else None
                    if kind == "events" and ch.topic != "/reference/events":
                        kind = None
                    ti = infos[ch.id] = TopicInfo(ch.topic, name, ch.message_encoding, kind)
                if ti.kind is None:
                    continue
                try:
                    raw = dctx.decompress(msg.data, max_output_size=1 << 24)
                except zstandard.ZstdError:
                    raise McapFormatError(f"{ti.topic}: a message does not decompress (the file says its messages "
                                          f"are zstd-compressed one by one); export the bag again") from None
                b = batches.setdefault(ch.id, [])
                b.append((msg.log_time, raw))
                if len(b) >= BATCH:
                    yield _decode_batch(ti, b)
                    batches[ch.id] = []
            for cid, b in batches.items():
                if b:
                    yield _decode_batch(infos[cid], b)
            result.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            for c in (summary.chunk_indexes if summary else []):
                f.seek(c.chunk_start_offset + 9 + 24)
                result.chunks += 1
                result.chunks_without_crc += int.from_bytes(f.read(4), "little") == 0
            if summary is not None:
                for ch in summary.channels.values():
                    if ch.id not in infos:
                        infos[ch.id] = TopicInfo(ch.topic, _normalise_schema(summary.schemas[ch.schema_id].name)
                                                 if ch.schema_id in summary.schemas else "", ch.message_encoding, None)
    except McapError as e:
        raise McapFormatError(f"corrupt MCAP ({type(e).__name__}); copy or export it again") from None
    result.topics = dict(infos)
    result.ignored_topics = sorted(t.topic for t in infos.values() if t.kind is None)
    result.sha256 = h.hexdigest()
    result.n_bytes = path.stat().st_size


#: rosbag2's names of the parts of a split bag
_PART = re.compile(r"^(?P<base>.+)_(?P<k>\d+)\.mcap$")


def split_bag_parts(path: Path) -> str | None:
    """The refusal of one part of a split rosbag2 bag whose metadata.yaml is missing, else None.

    Recognised by the names rosbag2 gives the parts (``<bag>_0.mcap``, ``<bag>_1.mcap``, … all present, from 0)
    and by their time continuity (each part starts within :data:`SPLIT_GAP_S` of the previous one's end, by the
    files' Statistics records). Ingested one by one, the parts would become unrelated recordings (strides cut at
    every split); files merely named alike but apart in time are left alone."""
    m = _PART.match(path.name)
    if m is None or (path.parent / "metadata.yaml").exists():
        return None
    base = m.group("base")
    parts = {}
    for p in path.parent.iterdir():
        q = _PART.match(p.name)
        if q is not None and q.group("base") == base and p.is_file():
            parts[int(q.group("k"))] = p
    n = len(parts)
    if n < 2 or sorted(parts) != list(range(n)):
        return None
    spans = [_span(parts[k]) for k in range(n)]
    if any(s is None for s in spans):
        return None
    for (a0, a1), (b0, b1) in zip(spans, spans[1:]):
        if not (-SPLIT_GAP_S * 1e9 <= b0 - a1 <= SPLIT_GAP_S * 1e9):
            return None
    return (f"part {m.group('k')} of a split rosbag2 bag ({base}_0.mcap to {base}_{n - 1}.mcap, one continuous "
            f"recording) without its metadata.yaml: ingested alone it would be a recording of its own; move the "
            f"{n} parts into one folder, recreate metadata.yaml with `ros2 bag reindex FOLDER mcap`, and ingest the "
            f"folder")


#: most seconds between one part's last message and the next part's first for a split bag
SPLIT_GAP_S = 2.0


def _span(path: Path) -> tuple[int, int] | None:
    """(first, last) message log time of an MCAP file from its Statistics record, None without one."""
    from mcap.reader import make_reader
    try:
        with open(path, "rb") as f:
            s = make_reader(f).get_summary()
    except Exception:  # noqa: BLE001 - no readable summary: continuity unknown
        return None
    st = s.statistics if s is not None else None
    if st is None or not st.message_count:
        return None
    return st.message_start_time, st.message_end_time
