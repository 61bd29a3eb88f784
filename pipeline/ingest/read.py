"""Ingest, phase 1 of 3: read. A recording (MCAP file, rosbag2 bag directory) streamed once into per-topic series.

One decode path per container: :func:`stridelab.pipeline.formats.mcap_read.iter_blocks` for an MCAP file (CRCs and record
structure verified on the way), :func:`stridelab.pipeline.formats.rosbag2.iter_bag_blocks` for a bag (its MCAP or SQLite
storage files), and, for a file whose messages are compressed one by one, the rosbag2 reader's
:func:`~stridelab.pipeline.formats.rosbag2.iter_message_compressed_blocks`. The per-block checks
(:func:`stridelab.pipeline.ingest.series.check_block`) run on the reader's threads; every block goes to its topic's
:class:`~stridelab.pipeline.ingest.series.TopicSeries`, which applies the clock policy and streams the rows into a staging
Parquet file (memory stays bounded whatever the recording's length). Refusals of what cannot be read are
:class:`~stridelab.pipeline.ingest.model.IngestRejected` / ``McapFormatError`` / ``SeriesRejected`` with a one-line reason.
"""
from __future__ import annotations

import gc
import hashlib
from contextlib import contextmanager
from pathlib import Path

from stridelab.pipeline.formats.mcap_read import McapFormatError, ReadResult, iter_blocks
from stridelab.pipeline.formats.rosbag2 import (bag_info, iter_bag_blocks, iter_message_compressed_blocks, message_compression,
                                      split_bag_parts)
from stridelab.pipeline.ingest.model import IngestOptions, IngestRejected, Prepared
from stridelab.pipeline.ingest.block_checks import check_block
from stridelab.pipeline.ingest.series import TopicSeries


def read_recording(path: Path, res: ReadResult, out: Prepared, states: dict[str, TopicSeries],
                   options: IngestOptions, series_root) -> dict | None:
    """Stream ``path`` into ``states`` (topic -> series) and ``out.events``; fills ``res`` (topics, metadata, hashes,
    CRC coverage). Returns the rosbag2 custom data of a bag (None for an MCAP file)."""
    blocks, custom = _blocks(path, res)
    try:
        _consume(blocks, out, states, options, series_root)
    except McapFormatError:
        fmt = _message_compressed(path)
        if fmt is None:
            raise
        for s in states.values():
            s.abort()
        states.clear()
        out.events = []
        res.__dict__.update(ReadResult().__dict__)          # a fresh result, the same object for the caller
        _consume(iter_message_compressed_blocks(path, res, fmt), out, states, options, series_root)
    out.content_hash = res.sha256
    out.crc_verified = res.crc_verified
    return custom


def stat_signature(path: Path) -> tuple[int, int]:
    """(size, mtime) of a file, or of the data files of a bag directory (sum, newest)."""
    if path.is_dir():
        files = [p for p in path.iterdir() if p.is_file()]
        return sum(p.stat().st_size for p in files), max((p.stat().st_mtime_ns for p in files), default=0)
    st = path.stat()
    return st.st_size, st.st_mtime_ns


def _blocks(path: Path, res: ReadResult):
    """(block iterator, rosbag2 custom data) of a recording file or bag directory."""
    if path.is_dir():
        info = bag_info(path)
        return iter_bag_blocks(info, res, on_block=check_block), info.custom_data
    if path.suffix == ".db3":
        raise IngestRejected("a .db3 file is read with its bag directory: ingest the directory that holds "
                             "metadata.yaml")
    if path.name == "metadata.yaml":
        raise IngestRejected("metadata.yaml is the index of a rosbag2 bag, not a recording: ingest the bag folder "
                             "that holds it instead")
    with open(path, "rb") as f:
        head = f.read(13)
    if head.startswith(b"#ROSBAG V"):
        raise IngestRejected("a ROS 1 bag, not MCAP: convert it to ROS 2 (`rosbags-convert --src FILE --dst FOLDER`) "
                             "and ingest the folder")
    split = split_bag_parts(path)
    if split:
        raise IngestRejected(split)
    return iter_blocks(path, res, on_block=check_block), None


def _message_compressed(path: Path) -> str | None:
    """After the fast reader refused a single file: its format when its messages are compressed one by one
    (rosbags/rosbag2 ``compression_mode: message``: the reader took compressed bytes for CDR), else None. Asked
    only then, so the common path reads no summary twice."""
    if path.is_dir() or path.suffix == ".db3":
        return None
    from mcap.reader import make_reader
    try:                        # the summary's metadata index only: a file without one (truncated, damaged) is
        with open(path, "rb") as f:    # never scanned again here (the mcap library would, in pure Python)
            r = make_reader(f)
            if r.get_summary() is None:
                return None
            return message_compression({m.name: dict(m.metadata) for m in r.iter_metadata()})
    except Exception:  # noqa: BLE001 - no readable summary: not this case; the first error stands
        return None


@contextmanager
def without_gc_pauses():
    """The cyclic garbage collector off while a recording streams through. Each chunk allocates a few
    dozen small objects, which triggered a collection every ~15 chunks, each one walking every object of
    the process (numba and pyarrow bring about a million): 3-5 % of an ingest's CPU in ``perf``. The
    reading path makes no reference cycles, so nothing accumulates; the collector resumes afterwards."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _consume(blocks, out: Prepared, states: dict, options: IngestOptions, series_root) -> None:
    for b in blocks:
        if b.kind == "events":
            out.events += [dict(v) for v in b.values]
            continue
        s = states.get(b.topic)
        if s is None:
            s = states[b.topic] = TopicSeries(b.topic, b.kind, Path(series_root), options.legacy_sample_hash)
        s.add(b)


def content_hash(path: Path) -> str:
    """SHA-256 of a file; for a bag directory, of its files' SHA-256 in name order."""
    if path.is_dir():

        files = sorted(p for p in path.iterdir() if p.is_file())
        return hashlib.sha256("\n".join(sha256(p) for p in files).encode()).hexdigest()
    return sha256(path)


def sha256(path: Path) -> str:

    if path.is_dir():
        return content_hash(path)
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for b in iter(lambda: f.read(1 << 22), b""):
            h.update(b)
    return h.hexdigest()


