"""Ingest, phase 3 of 3: write. Checked series into the store, then the catalog rows in one transaction.

:func:`write_series` (in the worker) gives the series files their final paths and prepares the rows;
:func:`commit` (in the single writing process) writes a prepared file's rows, idempotent by content hash and
ingest settings: a re-export is recorded, not ingested again; ``--replace`` or other settings supersede the earlier
ingest (:mod:`stridelab.pipeline.supersede`); every topic of the file goes into the run's ingest ledger (``ingest_topics``).
A file refused by any check is recorded as quarantined with its one-line reason and nothing else.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import xxhash

from stridelab.pipeline import privacy, supersede
from stridelab.pipeline.formats.mcap_read import ReadResult
from stridelab.pipeline.ingest.check import unique_events
from stridelab.pipeline.ingest.model import DEFAULT_SETTINGS_HASH, IngestOptions, Prepared
from stridelab.pipeline.ingest.read import stat_signature
from stridelab.warehouse.catalog import first, Warehouse
from stridelab.warehouse.store import commit_all, series_relpath


def write_series(out: Prepared, session: dict, mapped: dict, placement_of: dict, res: ReadResult,
                 options: IngestOptions) -> None:
    """Move the checked series from their staging files to their final paths (flushed to the disk side by side) and
    fill ``out`` with what the catalog will hold: sensors, warnings, span, sample hash, the ledger's topics."""
    imu = [s for s in mapped.values() if s.kind == "imu"]
    ordered = sorted(mapped.items(), key=lambda kv: kv[1].topic)
    rels = commit_all([s.writer for _, s in ordered],
                      [series_relpath(session["study"], session["participant"], session["session"], placement,
                                      _series_name(prefix, res.sha256, out.settings_hash))
                       for (placement, prefix), _ in ordered])
    for ((placement, prefix), s), rel in zip(ordered, rels):
        for m in s.warnings():
            out.issues.append({"severity": "warning", "topic": _stored_topic(s.topic, placement, prefix),
                               "message": m})
        s.writer = None
        out.sensors.append({"topic": _stored_topic(s.topic, placement, prefix), "placement": placement, "kind": s.kind, "n_samples": s.n,
                            "sampling_rate_hz": s.rate_hz, "start_ns": s.t0, "end_ns": s.last_t,
                            "series_path": rel})
        if s.kind == "imu":
            out.n_samples += s.n
    out.start_ns = min(s.t0 for s in imu)
    out.end_ns = max(s.last_t for s in imu)
    out.ignored_topics = sorted({privacy.shown_topic(t) for t in set(out.ignored_topics) | set(res.ignored_topics)})
    by_key = {placement_of[t]: s for t, s in ((s.topic, s) for s in mapped.values())}
    out.sample_hash = sample_hash(by_key)
    if options.legacy_sample_hash:
        out.legacy_sample_hash = legacy_sample_hash(by_key)
    out.events = unique_events(out.events, out.issues)
    out.topics = _topic_rows(out, res)


#: the ledger's topic for a file of which no topic could be read (refused before its channels were known)
WHOLE_FILE = "(whole file)"


def _topic_rows(out: Prepared, res: ReadResult) -> list[dict]:
    """Every topic of an ingested file for the ledger: each ingested series, the reference events, each skipped
    topic with its reason, and any other channel of the file (none is left out without a row)."""
    rows = [{"topic": d["topic"], "outcome": "ingested", "placement": d["placement"], "n_samples": d["n_samples"]}
            for d in out.sensors]
    if out.events:
        rows.append({"topic": "/reference/events", "outcome": "ingested", "n_samples": len(out.events)})
    rows += [{"topic": t, "outcome": "ingested", "placement": None, "n_samples": None} for t in out.live_topics]
    rows += [{"topic": privacy.shown_topic(d["topic"]), "outcome": "skipped", "reason": d["reason"]}
             for d in out.skipped_topics]
    listed = {d["topic"] for d in out.skipped_topics} | {r["topic"] for r in rows}
    for ti in res.topics.values():
        if ti.topic not in listed and privacy.shown_topic(ti.topic) not in listed:
            rows.append({"topic": privacy.shown_topic(ti.topic), "outcome": "skipped", "reason": "no messages"})
    return sorted(rows, key=lambda r: (r["outcome"] != "ingested", r["topic"]))


def _record_topics(wh: Warehouse, p: Prepared, run_id: str | None, status: str, reason: str = "") -> None:
    """The file's rows of the ingest ledger (migration 015), in the commit's transaction: as prepared when the file
    is ingested, else every topic with the file's outcome and reason."""
    if run_id is None or not wh.has_column("ingest_topics", "outcome"):
        return
    if status == "ingested":
        rows = p.topics
    else:
        rows = [{"topic": r["topic"], "outcome": status, "reason": reason} for r in p.topics] or \
               [{"topic": WHOLE_FILE, "outcome": status, "reason": reason}]
    wh.insert("ingest_topics", [{"run_id": run_id, "content_hash": p.content_hash, "file_name": p.file_name,
                                 "topic": r["topic"], "outcome": r["outcome"], "placement": r.get("placement"),
                                 "n_samples": r.get("n_samples"), "reason": r.get("reason")} for r in rows])


def _stored_topic(topic: str, placement: str, prefix: str) -> str:
    """The topic as the catalog keeps it: a standard name as it is, any other (a mapped topic, which may carry a
    device label or a name) as the standard name of its placement."""
    if privacy.shown_topic(topic) == topic:
        return topic
    if prefix.startswith("range-"):
        return f"/range/{placement}/{prefix[len('range-'):]}"
    return f"/{prefix.replace('reference_pose', 'reference/pose')}/{placement}"


def _series_name(prefix: str, sha256: str, settings: str) -> str:
    """A series file's name: kind and content hash, and the settings hash when the settings are not the default
    (a re-ingest of the file with other settings writes new files; the old ones stay for the old snapshots)."""
    name = f"{prefix}-{sha256[:16]}"
    return name if settings in ("", DEFAULT_SETTINGS_HASH) else f"{name}-{settings[:8]}"


#: prefix of the sample hashes (``recordings.sample_hash``) by :func:`sample_hash`; the earlier ones are 64 hex
#: digits of SHA-256 without a prefix (:func:`legacy_sample_hash`)
SAMPLE_HASH_PREFIX = "xxh3-128:"


def sample_hash(series: dict) -> str:
    """Identity of a recording by content: the same samples exported again (another file name, writer,
    chunking, compression or topic names) give the same hash. ``series``: (placement, series name) ->
    TopicSeries; hashed in key order over each series' header stamps and values (XXH3-128 digests).

    It finds re-exports, nothing more: the file's identity (``content_hash``) stays SHA-256 of its bytes,
    which anyone can check with ``sha256sum``. A non-cryptographic 128-bit hash cannot collide by accident
    (2^-128 per pair); a file made to collide on purpose would only be reported as a re-export, not ingested."""
    return SAMPLE_HASH_PREFIX + _combined(xxhash.xxh3_128(), series, lambda s: (s.stamp_digest, s.value_digest))


def legacy_sample_hash(series: dict) -> str:
    """The samples' identity as recordings ingested before :data:`SAMPLE_HASH_PREFIX` carry it (SHA-256 over
    the same fields); needs series created with ``legacy_digest=True``."""
    return _combined(hashlib.sha256(), series, lambda s: s.legacy)


def _combined(h, series: dict, digests) -> str:
    """``h`` over each series' key, kind and its (stamps, values) digests, in key order."""
    for key in sorted(series):
        s = series[key]
        stamps, values = digests(s)
        h.update(f"{key[0]}\0{key[1]}\0{s.kind}\0".encode() + stamps.digest() + values.digest())
    return h.hexdigest()


def has_legacy_sample_hashes(con) -> bool:
    """Whether the catalog holds recordings with a sample hash of before :data:`SAMPLE_HASH_PREFIX`."""
    return first(con.execute("SELECT 1 FROM recordings WHERE sample_hash IS NOT NULL AND NOT starts_with("
                             "sample_hash, ?) LIMIT 1", [SAMPLE_HASH_PREFIX])) is not None


def _console(p: Prepared) -> str:
    """How the console names a file: its own name (the operator's; the catalog keeps only a keyed hash of it)."""
    return p.display_name or p.file_name


def stored_settings_hash(con, content_hash: str) -> str:
    """The settings hash a recording was ingested with (the default for recordings from before migration 013)."""
    r = first(con.execute("SELECT settings_hash FROM recordings WHERE content_hash = ?", [content_hash]))
    return (r[0] if r else None) or DEFAULT_SETTINGS_HASH


def _integrity_columns(wh: Warehouse, p: Prepared) -> dict:
    """The recordings columns of migration 013 (none on an older catalog)."""
    if not wh.has_column("recordings", "settings_hash"):
        return {}
    return {"crc_verified": p.crc_verified, "settings_hash": p.settings_hash or DEFAULT_SETTINGS_HASH,
            "ingest_settings": json.dumps(p.settings, sort_keys=True),
            # topic names as the catalog may keep them (a non-standard topic may carry a name: stridelab.pipeline.privacy)
            "skipped_topics": json.dumps([{**d, "topic": privacy.shown_topic(d["topic"])} for d in p.skipped_topics])
            if p.skipped_topics else None}


def _supersede_same_file(con, p: Prepared, why: str, now) -> str:
    """The same file ingested again (``--replace``, or other ingest settings): the earlier ingest is kept in
    ``superseded_ingests``, its rows go, and its session's stages rerun. Returns the phrase for the report."""
    old = first(con.execute("SELECT settings_hash, ingest_settings, file_name, session_id, n_samples, ingested_at, "
                            "status FROM recordings WHERE content_hash = ?", [p.content_hash]))
    sensors = [dict(zip(("topic", "placement", "kind", "n_samples"), r)) for r in con.execute(
        "SELECT topic, placement, kind, n_samples FROM sensors WHERE content_hash = ? ORDER BY topic",
        [p.content_hash]).fetchall()]
    con.execute("INSERT INTO superseded_ingests VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [p.content_hash, old[0] or DEFAULT_SETTINGS_HASH, old[1], old[2], old[3], old[4],
                 json.dumps(sensors), old[5], now, f"ingested again with {why}"])
    for t in ("sensors", "recording_issues", "reference_events", "recordings", "live_outputs"):
        con.execute(f'DELETE FROM "{t}" WHERE content_hash = ?', [p.content_hash])
    sid = old[3]
    if sid is not None:
        left = first(con.execute("SELECT count(*) FROM recordings WHERE session_id = ? AND status = 'ingested'",
                                 [sid]))[0]
        if left == 0 and sid != p.metadata.get("session"):
            supersede.supersede(con, [], p, {sid})               # the session held only this file
        else:
            con.execute("DELETE FROM stage_state WHERE session_id = ?", [sid])   # same inputs' hash: rerun
            if left:
                supersede.refresh_session_span(con, sid)
    return f"superseding its earlier ingest ({old[6]}, {why})"


@dataclass
class CommitResult:
    status: str          # ingested | duplicate | quarantined
    message: str


def known_hash(wh: Warehouse, path: Path) -> str | None:
    """Content hash of a file (or bag directory) seen before with the same path, size and mtime (no read needed)."""
    size, mtime = stat_signature(path)
    r = first(wh.con.execute("SELECT content_hash FROM inbox_seen WHERE source_path = ? AND size_bytes = ? AND mtime_ns = ?",
                       [privacy.stored_path(path), size, mtime]))
    return r[0] if r else None


def commit(wh: Warehouse, p: Prepared, replace: bool = False, run_id: str | None = None) -> CommitResult:
    """Write one prepared file's catalog rows in a single transaction (idempotent by content hash); with
    ``run_id``, also the file's topics in the run's ingest ledger (``ingest_topics``).

    A file with the samples of an ingested recording is a re-export: recorded, not ingested again. With
    ``replace`` the file supersedes the recordings with its samples or its file name (pipeline/supersede.py)."""
    con = wh.con
    now = datetime.now(timezone.utc).replace(tzinfo=None)
    with wh.transaction():
        con.execute("INSERT OR IGNORE INTO inbox_seen VALUES (?, ?, ?, ?)",
                    [p.source_path, p.size_bytes, p.mtime_ns, p.content_hash])
        prev = first(con.execute("SELECT status, reason FROM recordings WHERE content_hash = ?", [p.content_hash]))
        if prev is not None and replace and prev[0] == "reexport":
            con.execute("DELETE FROM recordings WHERE content_hash = ?", [p.content_hash])   # now deliberate
            prev = None
        again = ""
        if prev is not None and wh.has_column("recordings", "settings_hash"):
            if replace or stored_settings_hash(con, p.content_hash) != (p.settings_hash or DEFAULT_SETTINGS_HASH):
                if p.status != "ingested":
                    _record_topics(wh, p, run_id, "quarantined", p.reason)
                    return CommitResult("quarantined", f"{_console(p)}: ingesting it again failed, the earlier "
                                                       f"ingest ({prev[0]}) stays: {p.reason}")
                again = _supersede_same_file(con, p, "--replace" if replace else "other ingest settings", now)
                prev = None
        if prev is not None:
            _record_topics(wh, p, run_id, "duplicate", f"already {prev[0]} (same content and ingest settings)")
            return CommitResult("duplicate", f"{_console(p)}: already {prev[0]} (same content), nothing changed")
        if not wh.has_column("recordings", "sample_hash"):
            p.sample_hash = p.legacy_sample_hash = ""   # a catalog before migration 009 (only tests open one
            #                                             without migrating)
        old = supersede.previous_versions(con, p) if p.status == "ingested" and replace else []
        if p.status == "ingested" and not replace and p.sample_hash:
            same = first(con.execute("SELECT file_name, session_id FROM recordings WHERE sample_hash IN (?, ?) "
                                     "AND status = 'ingested'", [p.sample_hash,
                                                                 p.legacy_sample_hash or p.sample_hash]))
            if same is not None:
                reason = (f"same samples as {same[0]} (session {same[1]}), ingested before: a re-export, not "
                          f"ingested again; to correct that recording, rerun with --replace and this file")
                wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                          "source_path": p.source_path, "size_bytes": p.size_bytes,
                                          "status": "reexport", "reason": reason, "sample_hash": p.sample_hash,
                                          "ingested_at": now}])
                _record_topics(wh, p, run_id, "reexport", reason)
                return CommitResult("reexport", f"{_console(p)}: {reason}")
        emptied = supersede.sessions_emptied(con, old)
        shown = p.console_reason if p.status == "quarantined" and p.console_reason else None   # refused by prepare
        if p.status == "ingested" and not old:
            clash = first(con.execute("SELECT content_hash, session_id FROM recordings WHERE file_name = ? "
                                "AND status = 'ingested'", [p.file_name]))
            if clash is not None:
                p.status = "quarantined"
                p.reason = (f"a different file with the same name was ingested before (sha256 {clash[0][:12]}…, "
                            f"session {clash[1]}); rename the file if it is a new recording")
        if p.status == "ingested":
            owner = first(con.execute("SELECT study, participant_id, kind FROM sessions WHERE session_id = ?",
                                      [p.metadata["session"]]))
            if p.metadata["session"] in emptied:
                owner = None              # the session goes away with the recordings this file supersedes
            if owner is not None and tuple(owner[:2]) != (p.metadata["study"], p.metadata["participant"]):
                p.status = "quarantined"
                p.reason = (f"session id {p.metadata['session']} already belongs to {owner[0]}/{owner[1]}, not "
                            f"{p.metadata['study']}/{p.metadata['participant']}; session ids must be unique")
            elif owner is not None and owner[2] != p.metadata["kind"]:
                p.status = "quarantined"
                p.reason = (f"session {p.metadata['session']} is a '{owner[2]}' session but this recording says kind "
                            f"'{p.metadata['kind']}'; all recordings of a session need the same kind")
        extra = _integrity_columns(wh, p)
        if p.status == "quarantined":
            wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                      "source_path": p.source_path, "size_bytes": p.size_bytes,
                                      "status": "quarantined", "reason": p.reason, "ingested_at": now, **extra}])
            _record_topics(wh, p, run_id, "quarantined", p.reason)
            return CommitResult("quarantined", f"{_console(p)}: quarantined: {shown or p.reason}")
        superseded = supersede.supersede(con, old, p, emptied)
        s = p.metadata
        con.execute("INSERT OR IGNORE INTO participants VALUES (?, ?)", [s["study"], s["participant"]])
        row = first(con.execute("SELECT study, participant_id, start_ns, end_ns FROM sessions WHERE session_id = ?",
                          [s["session"]]))
        if row is None:
            con.execute("INSERT INTO sessions VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                        [s["session"], s["study"], s["participant"], s["kind"], s.get("protocol"), s["timezone"],
                         p.start_ns, p.end_ns])
        else:
            con.execute("UPDATE sessions SET start_ns = least(start_ns, ?), end_ns = greatest(end_ns, ?) "
                        "WHERE session_id = ?", [p.start_ns, p.end_ns, s["session"]])
        wh.insert("recordings", [{"content_hash": p.content_hash, "file_name": p.file_name,
                                  "source_path": p.source_path, "size_bytes": p.size_bytes, "status": "ingested",
                                  "session_id": s["session"], "trial": s.get("trial"),
                                  "metadata": json.dumps(s, sort_keys=True), "start_ns": p.start_ns,
                                  "end_ns": p.end_ns, "n_samples": p.n_samples, "ingested_at": now, **extra,
                                  **({"sample_hash": p.sample_hash} if p.sample_hash else {})}])
        wh.insert("sensors", [dict(r, content_hash=p.content_hash) for r in p.sensors])
        if p.live_outputs and wh.has_column("live_outputs", "series_path"):
            wh.insert("live_outputs", [dict(r, content_hash=p.content_hash, session_id=s["session"])
                                       for r in p.live_outputs])
        wh.insert("recording_issues", [dict(r, content_hash=p.content_hash) for r in p.issues])
        wh.insert("reference_events", [{
            "content_hash": p.content_hash, "session_id": s["session"], "t_ns": int(e["t_ns"]),
            "end_ns": int(e["end_ns"]) if e.get("end_ns") is not None else None, "type": str(e["type"]),
            "side": e.get("side"), "placement": e.get("placement"), "label": e.get("label"),
            "payload": json.dumps(e, sort_keys=True)} for e in p.events])
        _record_topics(wh, p, run_id, "ingested")
        if superseded or again:
            supersede.refresh_session_span(con, s["session"])
    msg = f"{_console(p)}: ingested {p.n_samples:,} IMU samples into session {s['session']}"
    if again:
        msg += f", {again}"
    if superseded:
        msg += f", superseding {', '.join(superseded)}"
    if p.skipped_topics:
        msg += (f"; {len(p.skipped_topics)} topic{'s' if len(p.skipped_topics) > 1 else ''} skipped: "
                + "; ".join(f"{d['topic']}: {d['reason']}" for d in p.skipped_topics))   # every one (issue #47)
    if p.issues:
        msg += f" ({len(p.issues)} warning{'s' if len(p.issues) > 1 else ''}: {p.issues[0]['message']})"
    return CommitResult("ingested", msg)
