"""What ingest passes between its phases: the options of a run, what a worker hands the writer, the refusal."""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field


class IngestRejected(ValueError):
    """The file is quarantined; ``str(err)`` is the one-line reason."""


@dataclass
class Prepared:
    """What a worker hands back to the writer for one file."""
    source_path: str                         # stored: a keyed hash of the path (stridelab.pipeline.privacy.stored_path)
    file_name: str                           # stored: a keyed hash of the name (stridelab.pipeline.privacy.stored_name)
    size_bytes: int
    mtime_ns: int
    content_hash: str = ""
    status: str = "ingested"                 # ingested | quarantined
    reason: str = ""
    metadata: dict = field(default_factory=dict)
    sensors: list[dict] = field(default_factory=list)
    issues: list[dict] = field(default_factory=list)
    events: list[dict] = field(default_factory=list)
    start_ns: int | None = None
    end_ns: int | None = None
    n_samples: int = 0
    ignored_topics: list[str] = field(default_factory=list)
    skipped_topics: list[dict] = field(default_factory=list)   # every topic not ingested: {topic, reason}
    #: every topic of the file for the ingest ledger (``ingest_topics``, migration 015): {topic, outcome, placement,
    #: n_samples, reason}, topic names as the catalog keeps them; the outcome as if the file is ingested (commit()
    #: turns every row into the file's outcome when it is refused or a re-export)
    topics: list[dict] = field(default_factory=list)
    crc_verified: bool | None = None         # every message covered by a checked CRC (False: "unverified")
    settings_hash: str = ""                  # with content_hash, the idempotency key (:func:`settings_hash`)
    settings: dict = field(default_factory=dict)
    sample_hash: str = ""                    # XXH3-128 over the decoded samples of every topic (re-export check)
    legacy_sample_hash: str = ""             # their SHA-256 identity of before, when asked for (IngestOptions)
    display_name: str = ""                   # the file's own name, for the console only (never stored)
    console_reason: str = ""                 # the refusal as the operator needs it (topic names as in the file,
                                             # e.g. for --skip-topic); console only, never stored (``reason`` is)
    live_outputs: list[dict] = field(default_factory=list)   # a `stridelab live` recording's live outputs (014)
    live_topics: list[str] = field(default_factory=list)     # its /live/* topics, stored as live outputs


@dataclass
class IngestOptions:
    """Per-run choices: ``session`` fields (``--session FIELD=VALUE``) and ``topic_map`` (``--topic-map
    TOPIC=PLACEMENT``) applied to every recording of the run."""
    session: dict[str, str] = field(default_factory=dict)
    topic_map: dict[str, str] = field(default_factory=dict)
    #: topics the user agrees to leave out (``--skip-topic``): listed as skipped, never an error
    skip_topics: list[str] = field(default_factory=list)
    #: refuse a file not covered by CRCs (``--require-crc``, for strict studies)
    require_crc: bool = False
    #: warnings to record with every recording of the run (what ``--recover`` lost, pipeline/recover.py)
    notes: list[str] = field(default_factory=list)
    #: also compute the samples' SHA-256 identity that recordings ingested before the XXH3 one carry (set by
    #: the coordinator, :func:`stridelab.pipeline.runner.ingest_files`, when the warehouse holds any)
    legacy_sample_hash: bool = False


def as_options(options: "IngestOptions | dict | None") -> IngestOptions:
    """``options`` as :class:`IngestOptions` (a dict crosses process boundaries; None: the defaults)."""
    if isinstance(options, dict):
        options = IngestOptions(**options)
    return options or IngestOptions()


def ingest_settings(options: "IngestOptions | dict | None") -> dict:
    """The ingest settings that change what a file becomes in the warehouse (docs/integrity.md): the topic map and
    session fields given on the command line and the topics skipped on request. With the file's content they are
    the idempotency key: the same file ingested with other settings is ingested again (superseding)."""
    options = as_options(options)
    return {"topic_map": dict(sorted(options.topic_map.items())), "session": dict(sorted(options.session.items())),
            "skip_topics": sorted(set(options.skip_topics))}


def settings_hash(options: "IngestOptions | dict | None") -> str:
    """SHA-256 (hex) of :func:`ingest_settings`; recordings ingested before it was kept count as the default."""
    return hashlib.sha256(json.dumps(ingest_settings(options), sort_keys=True).encode()).hexdigest()


DEFAULT_SETTINGS_HASH = settings_hash(None)
