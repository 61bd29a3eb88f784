"""Ingest: an MCAP file or rosbag2 bag -> validated series in the Parquet store + catalog rows (one transaction).

Three phases, one module each:

1. :mod:`stridelab.pipeline.ingest.read`: stream the recording once (decode, per-block checks, hashes, CRCs) into one
   :class:`~stridelab.pipeline.ingest.series.TopicSeries` per topic, which applies the clock policy
   (:mod:`stridelab.pipeline.clock_policy`) and streams its rows into a staging Parquet file;
2. :mod:`stridelab.pipeline.ingest.check`: session metadata, personal data, topic placements and skips, units, rates;
3. :mod:`stridelab.pipeline.ingest.write`: the series files to their final paths, then (in the writing process)
   :func:`commit` of the catalog rows and the run's ingest ledger.

:func:`prepare` runs phases 1-3 (up to the catalog) in a worker process and never raises for a bad recording: a
file that fails any check is quarantined with a one-line reason and nothing of it reaches the catalog.
:func:`commit` runs in the single writing process. What passes between them: :mod:`stridelab.pipeline.ingest.model`.
"""
from __future__ import annotations

import os
from pathlib import Path

from stridelab.pipeline import privacy
from stridelab.pipeline.formats.mcap_read import McapFormatError, ReadResult
from stridelab.pipeline.ingest.check import (REFERENCE_FRAMES, check_session_metadata, check_recording, looks_like_imu,
                                   redacted)
from stridelab.pipeline.ingest.model import (DEFAULT_SETTINGS_HASH, IngestOptions, IngestRejected, Prepared,
                                   as_options, ingest_settings, settings_hash)
from stridelab.pipeline.ingest.read import content_hash, read_recording, sha256, stat_signature, without_gc_pauses
from stridelab.pipeline.ingest.series import SeriesRejected, TopicSeries
from stridelab.pipeline.ingest.write import (SAMPLE_HASH_PREFIX, WHOLE_FILE, CommitResult, commit, has_legacy_sample_hashes,
                                   known_hash, legacy_sample_hash, sample_hash, stored_settings_hash, write_series)
from stridelab.pipeline.session_sources import SessionSourceError

__all__ = ["CommitResult", "DEFAULT_SETTINGS_HASH", "IngestOptions", "IngestRejected", "Prepared", "REFERENCE_FRAMES",
           "SAMPLE_HASH_PREFIX", "WHOLE_FILE", "check_session_metadata", "commit", "content_hash",
           "has_legacy_sample_hashes", "ingest_settings", "known_hash", "legacy_sample_hash", "looks_like_imu",
           "prepare", "redacted", "sample_hash", "settings_hash", "sha256", "stored_settings_hash"]


def prepare(path: str | os.PathLike, root: str | os.PathLike, options: IngestOptions | dict | None = None,
            series_root: str | os.PathLike | None = None) -> Prepared:
    """Read, check and store the series of one recording (MCAP file or rosbag2 bag directory); never raises for a
    bad recording (quarantines it). ``series_root``: where the series files go if not under ``root`` (a
    repair's scratch folder, pipeline/verify.py)."""
    with without_gc_pauses():
        return _prepare(Path(path), root, as_options(options), series_root or root)


def _prepare(path: Path, root, options: IngestOptions, series_root) -> Prepared:
    size, mtime = stat_signature(path)
    out = Prepared(source_path=privacy.stored_path(path), file_name=privacy.stored_name(path), size_bytes=size,
                   mtime_ns=mtime, display_name=path.name, settings_hash=settings_hash(options),
                   settings=ingest_settings(options))
    states: dict[str, TopicSeries] = {}
    res = ReadResult()
    try:
        custom = read_recording(path, res, out, states, options, series_root)                  # 1. read
        session, mapped, placement_of = check_recording(path, root, res, custom, states, options, out)   # 2. check
        if path.is_file() and any(t.startswith("/live/") for t in res.ignored_topics):
            from stridelab.pipeline.live import stored as _live          # a `stridelab live` recording: its live outputs (014)
            out.live_outputs = _live.store_live_outputs(path, series_root, session, res.sha256, out.settings_hash)
            out.live_topics = [t for t in _live.JSON_TOPICS if t in res.ignored_topics]
            out.skipped_topics = [d for d in out.skipped_topics if d["topic"] not in _live.JSON_TOPICS]
        write_series(out, session, mapped, placement_of, res, options)                         # 3. write
    except (IngestRejected, McapFormatError, SeriesRejected, SessionSourceError, ValueError) as e:
        for s in states.values():
            s.abort()
        out.status = "quarantined"
        out.console_reason = str(e).splitlines()[0] if str(e) else type(e).__name__
        out.reason = redacted(out.console_reason, path, list(states) + list(res.found_topics()))
        out.sensors, out.events = [], []
        out.topics = [{"topic": privacy.shown_topic(t), "outcome": "quarantined"} for t in sorted(
            set(states) | {t.topic for t in res.topics.values()} | {d["topic"] for d in out.skipped_topics})]
        if not out.content_hash:
            out.content_hash = content_hash(path)
    except BaseException:
        for s in states.values():
            s.abort()
        raise
    return out
